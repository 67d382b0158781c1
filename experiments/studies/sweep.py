"""Monte Carlo sweep of the §7.4 pipeline: plants × noise seeds × (i, j) × σ ratio, one case per task.

Each case is :func:`experiments.studies.robust_pipeline.run_case` -- data, δ by (7.5), robust design with its
certificate, and the independent check on the true plant -- for one (plant, seed, i, j, σ ratio).
The cases run as tasks on a ``concurrent.futures.Executor``:

* ``--workers N`` (default: the number of cores): N local worker processes -- a Dask ``LocalCluster``
  (``processes=True``, one thread each, loopback only) when ``dask[distributed]`` is installed
  (``pip install -e ".[distributed]"``), otherwise a ``ProcessPoolExecutor``;
* ``--scheduler ADDRESS``: a running Dask scheduler (``dask scheduler`` / ``dask worker ADDRESS``,
  dask-jobqueue on HPC) through ``Client.get_executor()``; unreachable within ``--timeout`` seconds
  (default 30) it is a :class:`synthesis.DataError` naming the address.

Worker processes run with ``OPENBLAS_NUM_THREADS=1`` (and the OMP/MKL equivalents) so that workers do
not fight over BLAS threads.  A case is seeded by its own seed (``run_case``), never by the worker, so
the results are identical whatever the executor and the number of workers (apart from the wall times
``seconds``).  Each finished case is written to ``sweep.json`` and ``sweep.md`` at once (an
interrupted sweep keeps what it finished; ``--resume`` skips the finished cases and runs the rest,
failed ones included).  A case that raises is recorded with its error and the sweep goes on; a case
whose worker is lost is retried by Dask (``distributed.scheduler.allowed-failures``) and otherwise
recorded as failed -- never silently missing.  The summary counts done / failed / certified.

The plants are :data:`experiments.plants.PLANT_CATALOGUE`: the integrating §5.4 servo, a stable third-
order plant, a lightly damped resonance (ζ = 0.05), a non-minimum-phase plant (zero at s = +1), all at
10 Hz with the §5.4 weights, and the three-disk plant (collocated y1, two lightly damped modes and an
integrator) at 64 Hz with the §6.3 weights of :mod:`experiments.lab.torsional_setup`.
"""
from __future__ import annotations

import concurrent.futures as cf
import contextlib
import json
import multiprocessing
import os
import sys
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

from synthesis.validation import DataError

from ..lab.plants import PLANT_CATALOGUE
from ..lab.report import Report, save_figure, write_json

__all__ = ["SweepConfig", "Case", "run", "run_sweep", "sweep_cases", "make_executor", "case_task",
           "load_finished", "strip_timing", "summary_line", "WORKER_ENV"]

#: Environment of the worker processes: one BLAS thread each.
WORKER_ENV = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}

#: Fields of a case record that depend on the machine, not on the case (left out when comparing runs).
TIMING_FIELDS = ("seconds",)


@dataclass(frozen=True)
class Case:
    """One pipeline case: the key of a task and of a report row."""

    plant: str
    seed: int
    i: int
    j: int
    sigma_ratio: float

    def key(self) -> tuple:
        return (self.plant, int(self.seed), int(self.i), int(self.j), float(self.sigma_ratio))


@dataclass(frozen=True)
class SweepConfig:
    """The grid of a sweep (its product is the list of cases)."""

    plants: tuple = tuple(PLANT_CATALOGUE)
    seeds: tuple = (0, 1)
    sizes: tuple = ((10, 30),)
    sigma_ratios: tuple = (0.5, 0.8)  # σ must stay below the residual rms (ratio < 1)

    @classmethod
    def quick(cls) -> "SweepConfig":
        """2 plants × 2 seeds at (i, j) = (10, 30), σ ratio 0.5 (under 2 minutes on 2 cores)."""
        return cls(plants=("servo", "third_order"), seeds=(0, 1), sizes=((10, 30),), sigma_ratios=(0.5,))


def sweep_cases(cfg: SweepConfig, seed_offset: int = 0) -> list[Case]:
    """The cases of ``cfg`` in a fixed order (plant, seed, size, σ ratio)."""
    return [Case(p, s + seed_offset, i, j, r) for p in cfg.plants for s in cfg.seeds for (i, j) in cfg.sizes
            for r in cfg.sigma_ratios]


def case_task(case: Case) -> dict:
    """Run one case in a worker; an exception becomes an ``error`` record (the sweep goes on)."""
    from .robust_pipeline import run_case

    base = {"plant": case.plant, "seed": int(case.seed), "i": int(case.i), "j": int(case.j),
            "sigma_ratio": float(case.sigma_ratio)}
    t0 = time.perf_counter()
    try:
        out = run_case(case.plant, case.seed, case.i, case.j, case.sigma_ratio)
    except Exception as exc:  # noqa: BLE001 - recorded, not swallowed
        return {**base, "error": f"{type(exc).__name__}: {exc}", "traceback": traceback.format_exc(limit=4),
                "seconds": time.perf_counter() - t0}
    return {**base, **out, "sigma_ratio": float(case.sigma_ratio)}


def _failed(case: Case, exc: BaseException) -> dict:
    return {"plant": case.plant, "seed": int(case.seed), "i": int(case.i), "j": int(case.j),
            "sigma_ratio": float(case.sigma_ratio),
            "error": f"worker lost or task failed ({type(exc).__name__}: {exc})", "seconds": float("nan")}


def _have_distributed() -> bool:
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


@contextlib.contextmanager
def _worker_env():
    """Set :data:`WORKER_ENV` while worker processes are spawned (they inherit it); restore after."""
    old = {k: os.environ.get(k) for k in WORKER_ENV}
    os.environ.update(WORKER_ENV)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


@contextlib.contextmanager
def make_executor(workers: int | None = None, scheduler: str | None = None, timeout: float = 30.0):
    """``(executor, description)`` for a sweep; closes what it opened on exit.

    Parameters
    ----------
    workers : int, optional
        Local worker processes (default: ``os.cpu_count()``); ignored with ``scheduler``.
    scheduler : str, optional
        Address of a running Dask scheduler (needs ``dask[distributed]``).
    timeout : float
        Seconds to wait for the scheduler before raising :class:`DataError`.

    Yields
    ------
    (concurrent.futures.Executor, dict)
        The executor and a JSON-able description (``kind``, ``workers``, ``address``).
    """
    if scheduler is not None:
        if not _have_distributed():
            raise DataError(f"--scheduler {scheduler} needs dask.distributed, which is not installed: "
                            "pip install -e \".[distributed]\" (or use --workers N for local processes)")
        from distributed import Client

        if not (isinstance(timeout, (int, float)) and timeout > 0):
            raise DataError(f"timeout must be a positive number of seconds, got {timeout!r}")
        try:
            client = Client(scheduler, timeout=timeout, set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise DataError(f"could not reach the Dask scheduler at {scheduler} within {timeout:g} s ({exc}); "
                            "start one with `dask scheduler` and `dask worker ADDRESS`, or check the address") from exc
        try:
            n = len(client.scheduler_info().get("workers", {}))
            with client.get_executor() as ex:
                yield ex, {"kind": "dask-scheduler", "address": scheduler, "workers": n}
        finally:
            client.close()
        return
    n = (os.cpu_count() or 1) if workers is None else workers
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise DataError(f"--workers must be a positive number of processes, got {workers!r}")
    if _have_distributed():
        import dask
        from distributed import Client, LocalCluster

        env = {f"distributed.nanny.pre-spawn-environ.{k}": v for k, v in WORKER_ENV.items()}
        with _worker_env(), dask.config.set(env), \
                LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                             dashboard_address="127.0.0.1:0", env=dict(WORKER_ENV)) as cluster, \
                Client(cluster, set_as_default=False) as client, client.get_executor() as ex:
            yield ex, {"kind": "dask-local", "workers": n, "address": cluster.scheduler_address}
        return
    with _worker_env(), cf.ProcessPoolExecutor(n, mp_context=multiprocessing.get_context("spawn")) as ex:
        yield ex, {"kind": "process-pool", "workers": n}


def load_finished(path: Path) -> dict[tuple, dict]:
    """Finished (error-free) cases of a previous report ``sweep.json``, by key; {} if none."""
    path = Path(path)
    if not path.exists():
        return {}
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise DataError(f"cannot resume from {path}: not a sweep report ({exc}); remove it or drop --resume") from exc
    done = {}
    for c in data.get("cases", []):
        if "error" not in c:
            done[(c["plant"], int(c["seed"]), int(c["i"]), int(c["j"]), float(c["sigma_ratio"]))] = c
    return done


def run_sweep(cases: list[Case], executor, out: Path | None = None, *, executor_info: dict | None = None,
              finished: dict | None = None, task=case_task, progress: bool = True) -> dict:
    """Run ``cases`` as tasks on ``executor``; write each finished case to ``out`` at once.

    Parameters
    ----------
    cases : list of Case
    executor : concurrent.futures.Executor
    out : Path, optional
        Folder of ``sweep.json`` / ``sweep.md`` (rewritten after every finished case).
    executor_info : dict, optional
        Description of the executor, stored in the report.
    finished : dict, optional
        Already finished case records by key (``--resume``): not run again.
    task : callable
        The task (picklable, top level); default :func:`case_task`.
    progress : bool
        tqdm progress bar on stderr as cases finish.

    Returns
    -------
    dict
        ``{"executor", "cases" (in the order of ``cases``), "done", "failed", "certified"}``.
    """
    from tqdm import tqdm

    finished = dict(finished or {})
    results: dict[tuple, dict] = {c.key(): finished[c.key()] for c in cases if c.key() in finished}
    todo = [c for c in cases if c.key() not in results]
    info = dict(executor_info or {"kind": type(executor).__name__})

    def flush():
        if out is not None:
            _write(Path(out), _summary(cases, results, info), partial=len(results) < len(cases))

    flush()
    # longest first (the 64 Hz three-disk cases, then larger windows): fewer idle workers at the end;
    # the report keeps the grid order whatever the order of completion
    todo.sort(key=lambda c: (c.plant.startswith("three_disk"), c.i * c.j), reverse=True)
    futures = {executor.submit(task, c): c for c in todo}
    bar = tqdm(total=len(cases), initial=len(results), desc="sweep", unit="case", disable=not progress,
               file=sys.stderr, leave=False)
    try:
        for fut in cf.as_completed(futures):
            c = futures[fut]
            try:
                rec = fut.result()
            except BaseException as exc:  # noqa: BLE001 - lost worker, cancelled, ...: recorded as failed
                if isinstance(exc, KeyboardInterrupt):
                    raise
                rec = _failed(c, exc)
            results[c.key()] = rec
            bar.update(1)
            flush()
    finally:
        bar.close()
    return _summary(cases, results, info)


def _summary(cases, results, info) -> dict:
    recs = [results[c.key()] for c in cases if c.key() in results]
    failed = sum("error" in r for r in recs)
    cert = sum(bool(r.get("certified")) for r in recs if "error" not in r)
    return {"executor": info, "cases": recs, "total": len(cases), "done": len(recs) - failed, "failed": failed,
            "certified": cert, "missing": len(cases) - len(recs)}


def summary_line(s: dict) -> str:
    return (f"{s['total']} cases: {s['done']} done, {s['failed']} failed, {s['certified']} certified"
            + (f", {s['missing']} not run" if s["missing"] else ""))


_HEADERS = ["plant", "seed", "i", "j", "σ ratio", "σ", "δ", "certified", "true: stable", "true: survives",
            "invariant", "s", "error"]


def _row(c: dict) -> list:
    t = c.get("true") or {}
    if "error" in c:
        return [c["plant"], c["seed"], c["i"], c["j"], c["sigma_ratio"], "", "", "", "", "", "", "",
                c["error"].replace("|", "\\|").replace("\n", " ")]
    return [c["plant"], c["seed"], c["i"], c["j"], c["sigma_ratio"], c.get("sigma", ""), c.get("delta", ""),
            "yes" if c.get("certified") else "no", t.get("stable", ""), t.get("survives", ""),
            c.get("invariant_holds", ""), c.get("seconds", ""), ""]


def _write(out: Path, s: dict, partial: bool, figure: Path | None = None, seconds: float | None = None) -> None:
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "sweep.json", {**s, "partial": partial, **({"seconds": seconds} if seconds else {})})
    rep = Report("Monte Carlo sweep of the §7.4 pipeline" + (" (partial)" if partial else ""))
    ex = s["executor"]
    rep.text(f"Executor: {ex.get('kind')} ({ex.get('workers', '?')} workers"
             + (f", {ex['address']}" if ex.get("address") else "") + "). Each case: "
             "experiments.studies.robust_pipeline.run_case (1000-sample PRBS experiment with process and sensor noise "
             "σ = 0.05, least-squares predictor, δ by (7.5) with σ = ratio × residual rms, robust design with "
             "certificate, check on the true plant).")
    rep.section("Summary", summary_line(s) + "." + (f" Wall time {seconds:.1f} s." if seconds else ""))
    rep.table(_HEADERS, [_row(c) for c in s["cases"]])
    if figure is not None:
        rep.figure(figure, "δ per case and certified rate, per plant", relative_to=out)
    rep.write(out / "sweep.md")


def _figure(s: dict, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [c for c in s["cases"] if "error" not in c]
    plants = list(dict.fromkeys(c["plant"] for c in s["cases"]))
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.8))
    for k, p in enumerate(plants):
        ds = [c["delta"] for c in ok if c["plant"] == p]
        a1.scatter([k] * len(ds), ds, alpha=0.7)
        n = sum(c["plant"] == p for c in s["cases"])
        a2.bar(k, sum(bool(c["certified"]) for c in ok if c["plant"] == p) / max(n, 1), color="C0")
    for a in (a1, a2):
        a.set_xticks(range(len(plants)), plants, rotation=30, ha="right")
    a1.set_yscale("log")
    a1.set_ylabel("δ (7.5)")
    a2.set_ylabel("certified rate")
    a2.set_ylim(0, 1)
    fig.tight_layout()
    return save_figure(fig, path)


def run(opts) -> dict:
    """``python -m experiments sweep``: the grid of :class:`SweepConfig` on the chosen executor."""
    cfg = SweepConfig.quick() if opts.quick else SweepConfig()
    extra = dict(getattr(opts, "extra", {}) or {})
    out = Path(opts.out)
    out.mkdir(parents=True, exist_ok=True)
    cases = sweep_cases(cfg, seed_offset=opts.seed)
    finished = load_finished(out / "sweep.json") if extra.get("resume") else {}
    t0 = time.perf_counter()
    with make_executor(extra.get("workers"), extra.get("scheduler"), extra.get("timeout", 30.0)) as (ex, info):
        s = run_sweep(cases, ex, out, executor_info=info, finished=finished)
    seconds = time.perf_counter() - t0
    fig = _figure(s, out / "sweep.png")
    _write(out, s, partial=bool(s["missing"]), figure=fig, seconds=seconds)
    print(summary_line(s), file=sys.stderr)
    return {"executor": s["executor"], "cases": s["cases"], "total": s["total"], "done": s["done"],
            "failed": s["failed"], "certified": s["certified"], "seconds": seconds, "report": str(out / "sweep.md")}


def strip_timing(cases: list[dict]) -> list[dict]:
    """Case records without the machine-dependent fields (:data:`TIMING_FIELDS`), for comparing runs."""
    return [{k: v for k, v in c.items() if k not in TIMING_FIELDS} for c in cases]

