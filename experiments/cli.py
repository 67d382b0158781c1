"""Command-line entry point: one subcommand per experiment or benchmark.

Each subcommand is a function ``run(opts: Options) -> dict`` living in its own
module; it writes its files under ``opts.out`` and returns a JSON-serialisable
summary (printed with ``--json``, which then is the only thing on stdout: anything the
subcommand prints is sent to stderr).  Without ``--json``, :func:`main` ends every run with a short
summary on stdout naming the report (the summary's ``report`` key), the run time (``seconds``) and
the lines of the module's optional ``summary_lines(summary) -> list[str]``.

Threads: the studies (every subcommand but the ``bench-*`` ones) run with BLAS held to one thread
(:func:`blas_policy`) unless the environment names a thread count (``OPENBLAS_NUM_THREADS``,
``OMP_NUM_THREADS`` or ``MKL_NUM_THREADS``): their problems are small, where OpenBLAS's second thread
costs more in synchronisation than it brings.  Measured on 2 cores, one thread against two (wall time
of the whole command, imports included): ``chapter7 --quick`` 9.4 s against 19.1 s, ``cd-player --quick``
5.2 against 11.4 s, ``design`` of a 1500-sample record at i = 8 5.0 against 6.4 s.  The benchmarks keep
BLAS as configured: each states the thread policy it measures.
"""
from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path

from .lab.report import dumps_json

__all__ = ["Options", "COMMANDS", "main", "output_dir", "summary_text", "blas_policy", "BLAS_VARIABLES"]


@dataclass(frozen=True)
class Options:
    """Options common to every subcommand."""

    quick: bool = False
    json: bool = False
    out: Path = Path("results")
    seed: int = 0
    #: values of the subcommand's own options (the argparse specs of its ``COMMANDS`` entry), by ``dest``
    extra: dict = field(default_factory=dict)


def _int_at_least(minimum: int, what: str):
    """An argparse type: an integer ≥ ``minimum``, refused at parsing with ``invalid <what>``."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"invalid {what} {text!r}: give an integer ≥ {minimum}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"invalid {what} {value}: give an integer ≥ {minimum}")
        return value
    return parse


#: ``--workers``, ``--repeats``: a negative count had reached the run and ended in a DataError traceback
_positive = _int_at_least(1, "count")
#: ``--seed``: numpy's generators take no negative seed
_seed = _int_at_least(0, "seed")


#: name -> ("module", "function", "one-line help"[, extra options]).  The optional fourth element is a
#: tuple of argparse specs ``(("--flag", ...), {add_argument kwargs, with "dest"})`` for options of that
#: subcommand only; their values reach ``run`` as ``opts.extra[dest]``.
COMMANDS: dict[str, tuple] = {
    "demo": ("experiments.studies.demo", "run", "quick Chapter 7 pipeline + Table 5.1, markdown report (the README's main job)"),
    "design-example": ("experiments.studies.design_example", "run", "§5.4 design example: Tables 5.1-5.5 and figures"),
    "noncollocated": ("experiments.studies.noncollocated", "run", "§6.2 non-collocated three-disk design"),
    "adaptive": ("experiments.studies.adaptive", "run", "§6.3 adaptive simulation"),
    "chapter7": ("experiments.studies.chapter7", "run", "§7.4 pipeline: δ by ARX and subspace unfalsification, robust design"),
    "robust-pipeline": ("experiments.studies.robust_pipeline", "run",
                        "§7.4 pipeline on plants it was not designed on: certified or not, checked on the true plant"),
    "robust-adversarial": ("experiments.studies.adversarial", "run",
                           "§7.4 certificate against an adversarial catalogue (band-limited, closed-loop, delayed, "
                           "drifting, nonlinear data), judged on the true plant",
                           ((("--only",), dict(dest="only", default=None, metavar="TEXT",
                                               help="run only the cases whose name contains TEXT "
                                                    "(comma-separated: any of them)")),
                            (("--untested",), dict(dest="untested", choices=("warn", "refuse"), default="warn",
                                                   help="CertificateOptions(untested=...): certify on a premise the "
                                                        "data cannot test (warn, the default) or refuse")),
                            (("--protocol",), dict(dest="protocol", choices=("validation", "record"), default="validation",
                                                   help="what the pipeline is given: the window, a predictor fitted "
                                                        "on the first 60 %% and the last 40 %% held out "
                                                        "(validation, the default), or the whole record with "
                                                        "window= (record)")))),
    "mimo-pipeline": ("experiments.studies.mimo_pipeline", "run",
                      "§7.4 certificate for plants with several inputs and outputs (2 × 2, 2 × 1, 1 × 2) under white, "
                      "low-pass, silent-channel and collinear excitation, judged on the true plant"),
    "bench-predictor": ("experiments.bench.bench_predictor", "run", "benchmark: QR vs Cholesky predictor, recursive updates"),
    "bench-adaptive": ("experiments.bench.bench_adaptive", "run", "benchmark: adaptive redesign time per update at i = 64 (§6.3)"),
    "bench-unfalsify": ("experiments.bench.bench_unfalsify", "run", "benchmark: LMI solve time vs problem size",
                        ((("--backend",), dict(dest="backend", choices=("cvxpy", "structured", "both"),
                                               default="cvxpy", help="unfalsification backend to time "
                                                                     "(default: cvxpy)")),
                         (("--series",), dict(dest="series", choices=("all", "arx", "subspace", "warm", "warm-floor",
                                                                        "arx-pd", "subspace-pd"),
                                              default="all",
                                              help="structured backend: all series, the ARX rows, the "
                                                   "subspace rows, the warm-start table, the warm-start floor "
                                                   "(resumed from the new problem's own centres) or one of the "
                                                   "primal-dual against barrier tables only")),
                         (("--sizes",), dict(dest="sizes", default=None, metavar="N,N,...",
                                             help="structured backend, arx-pd table: the ARX sizes "
                                                  "(default 200,400,1000); subspace-pd table: i×j pairs "
                                                  "(default 10x200,20x400,50x500)")),
                         (("--repeats",), dict(dest="repeats", type=_positive, default=None, metavar="R",
                                               help="structured backend: timed repeats of each row's solves "
                                                    "(default 3; --quick: 1)")),
                         (("--baseline-rev",), dict(dest="baseline_rev", default=None, metavar="REV",
                                                    help="structured backend: also solve each row with the code of "
                                                         "this git revision (git archive), alternating in the same "
                                                         "run")))),
    "bench-norms": ("experiments.bench.bench_norms", "run", "benchmark: certified H∞ norms and SLICOT simulation vs the former routes"),
    "bench-split": ("experiments.bench.bench_split", "run",
                    "benchmark: column split of (7.5) on 1 and N local workers vs the serial solve",
                    ((("--workers",), dict(dest="workers", type=_positive, default=2,
                                           help="worker processes of the parallel run (default: 2)")),)),
    "sweep": ("experiments.studies.sweep", "run",
              "Monte Carlo sweep of the §7.4 pipeline (plants × seeds × (i, j) × σ), one case per task on "
              "local processes or a Dask cluster",
              ((("--workers",), dict(dest="workers", type=_positive, default=None,
                                     help="local worker processes (default: the number of cores)")),
               (("--scheduler",), dict(dest="scheduler", default=None, metavar="ADDRESS",
                                       help="address of a running Dask scheduler, e.g. tcp://127.0.0.1:8786")),
               (("--timeout",), dict(dest="timeout", type=float, default=30.0,
                                     help="seconds to wait for the scheduler (default: 30)")),
               (("--resume",), dict(dest="resume", action="store_true",
                                    help="skip the cases already finished in the report under --out")))),
    "design": ("experiments.studies.design_cli", "run",
               "§7.4 workflow on a measured record (CSV/NPZ/MAT; one or several channels): δ, robust design, "
               "certificate or the reason for refusing, controller files", "experiments.studies.design_cli:OPTIONS"),
    "cd-player": ("experiments.studies.cd_player", "run",
                  "the design workflow on real data: the CD-player arm (DaISy), u1 → y1 at i = 10, 15, 20 and the "
                  "2 × 2 record at i = 10 (--quick: u1 → y1, i = 10)"),
    "compare": ("experiments.studies.compare", "run",
                "model-free vs identify-then-design (ARX, N4SID, physics model) and the ideal, judged on the true "
                "plant; thesis Figs 6.6/6.7"),
}


#: environment variables that name a BLAS thread count; any of them set leaves BLAS as the user configured it
BLAS_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def blas_policy(module: str):
    """The BLAS thread policy a subcommand runs under: a context manager.

    One thread (``threadpoolctl.threadpool_limits(1, user_api="blas")``, restored on exit) for the studies;
    BLAS as configured for the benchmarks (modules under ``experiments.bench``, which measure and state their
    own thread policy) and whenever one of :data:`BLAS_VARIABLES` is set (the user's choice wins).

    Parameters
    ----------
    module : str
        The subcommand's module (``COMMANDS[name][0]``).

    Returns
    -------
    context manager

    Examples
    --------
    >>> import os
    >>> from threadpoolctl import threadpool_info
    >>> from experiments.cli import blas_policy, BLAS_VARIABLES
    >>> saved = {v: os.environ.pop(v, None) for v in BLAS_VARIABLES}
    >>> with blas_policy("experiments.studies.design_cli"):
    ...     print({p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"})
    {1}
    >>> type(blas_policy("experiments.bench.bench_unfalsify")).__name__
    'nullcontext'
    >>> for v, value in saved.items():
    ...     if value is not None:
    ...         os.environ[v] = value
    """
    if module.startswith("experiments.bench.") or any(os.environ.get(v) for v in BLAS_VARIABLES):
        return contextlib.nullcontext()
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")


def _entry(name: str) -> tuple[str, str, str, tuple]:
    """``COMMANDS[name]`` as (module, function, help, extra option specs).

    The specs may be given as ``"module:NAME"``, a tuple living in that module (imported here: a
    subcommand with many options keeps them beside its code).
    """
    module, func, help_, *rest = COMMANDS[name]
    specs = rest[0] if rest else ()
    if isinstance(specs, str):
        mod, attr = specs.split(":")
        specs = getattr(importlib.import_module(mod), attr)
    return module, func, help_, tuple(specs)


def _add_option(parser: argparse.ArgumentParser, flags: tuple, kwargs: dict) -> None:
    """``parser.add_argument`` for one spec; a positional (no leading '-') takes its ``dest`` from its name."""
    if not flags[0].startswith("-"):
        kwargs = {k: v for k, v in kwargs.items() if k != "dest"}  # argparse refuses dest= for positionals
    parser.add_argument(*flags, **kwargs)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m experiments", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True, metavar="NAME")
    for name in COMMANDS:
        _, _, help_, extra = _entry(name)
        s = sub.add_parser(name, help=help_, description=help_)
        s.add_argument("--quick", action="store_true", help="small sizes, for tests and smoke runs")
        s.add_argument("--json", action="store_true", help="print the summary as JSON")
        s.add_argument("--out", type=Path, default=Path("results"), help="output folder (default: results/)")
        s.add_argument("--seed", type=_seed, default=0, help="random seed, an integer ≥ 0 (default: 0)")
        for flags, kwargs in extra:
            _add_option(s, flags, kwargs)
    return p


def output_dir(out: Path, command: str) -> Path:
    """Folder a subcommand writes into: ``<out>/<command with '-' → '_'>``."""
    return Path(out) / command.replace("-", "_")


def main(argv: list[str] | None = None) -> int:
    """Parse ``argv`` (default: ``sys.argv[1:]``), run the subcommand, return the exit status (0).

    A subcommand that reads user input lists in its module's ``INPUT_ERRORS`` the exceptions that mean
    bad input (a missing file, NaN, a bad window): they end the run like a bad option does, with
    ``python -m experiments NAME: error: <message>`` on stderr and exit status 2 (``SystemExit``).
    Other exceptions propagate with their traceback: they are bugs, not input.
    """
    parser = _parser()
    args = parser.parse_args(argv)
    module, func, _, extra = _entry(args.command)
    mod = importlib.import_module(module)
    run = getattr(mod, func)
    # one folder per subcommand: results/demo/, results/design_example/, ... (``run`` writes into opts.out)
    opts = Options(quick=args.quick, json=args.json, out=output_dir(args.out, args.command), seed=args.seed,
                   extra={kw["dest"]: getattr(args, kw["dest"]) for _, kw in extra})
    sub = parser._subparsers._group_actions[0].choices[args.command]  # the subcommand's own usage line
    try:
        opts.out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:  # a folder that cannot be made had ended every command in a traceback
        sub.error(f"cannot create the output folder {str(opts.out)!r} ({exc.strerror or exc}); pass --out a folder "
                  "you can write to")
    # with --json, stdout carries the JSON summary only: whatever a subcommand prints goes to stderr
    input_errors = tuple(getattr(mod, "INPUT_ERRORS", ()))
    try:
        with contextlib.redirect_stdout(sys.stderr) if args.json else contextlib.nullcontext(), blas_policy(module):
            summary = run(opts)
    except input_errors as exc:
        sub.error(str(exc))
    if args.json:
        sys.stdout.write(dumps_json(summary, strict=True) + "\n")
    else:
        print(summary_text(args.command, summary, getattr(mod, "summary_lines", None), opts.out), flush=True)
    return 0


def summary_text(command: str, summary: dict, lines=None, out: Path | None = None) -> str:
    """The closing summary of a run: where the report is, how long it took, then ``lines(summary)``.

    Parameters
    ----------
    command : str
        Subcommand name.
    summary : dict
        What ``run`` returned; ``report`` (path of the markdown report) and ``seconds`` are used if present.
    lines : callable, optional
        ``lines(summary) -> list[str]``: the subcommand's key numbers, one per line.
    out : pathlib.Path, optional
        Output folder, named when the summary has no ``report``.
    """
    report = summary.get("report") if isinstance(summary, dict) else None
    where = f"report: {report}" if report else f"output in {out}" if out is not None else "done"
    took = f" ({summary['seconds']:.1f} s)" if isinstance(summary, dict) and "seconds" in summary else ""
    text = [f"{command}: {where}{took}"]
    if lines is not None:
        text += [f"  {line}" for line in lines(summary)]
    return "\n".join(text)
