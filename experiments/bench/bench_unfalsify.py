"""Benchmark: Chapter 7 unfalsification LMIs -- solve time and status against problem size.

``python -m experiments bench-unfalsify [--quick] [--out DIR] [--backend cvxpy|structured|both]`` writes
``<out>/bench_unfalsify.md`` and ``<out>/bench_unfalsify.json``; with ``--backend structured`` or
``both`` also ``bench_unfalsify_structured.csv`` and the scaling plot ``bench_unfalsify_scaling.png``
(time against size, log-log, with fitted exponents).

Series (servo data of §5.4: PRBS ±1, process and sensor noise σ = 0.05; σ of the program =
half the least-squares residual rms so that δ > 0):

* ARX (7.4), na = nb = 2, ``form="conditioned"`` and ``form="thesis"``, growing n;
* subspace (7.5), ``form="conditioned"`` (L optimised, and L eliminated analytically) and
  ``form="thesis"``, growing j at fixed i;
* subspace (7.5) with two inputs and two outputs (issue 28), ``form="conditioned"``, at (i, j) = (10, 200):
  two servo channels with input coupling ``[[1, 0.3], [0.2, 1]]``, independent PRBS ±1 inputs, the same
  noise levels (:func:`_mimo_data`).  (20, 400) is a structured row only: Clarabel's child passed 19 GB of
  resident memory after 3.5 CPU-minutes there and was stopped.

Each solve runs in a child process with a wall-clock budget (120 s; 30 s with ``--quick``);
a series stops growing at the first solve that exceeds it (recorded as ``timeout``).  Every
row carries the solver status, δ, the independent certificate (``δ_certified`` recomputed from
the returned variables, ``max_violation``) and cond T(u).  Clarabel, explicitly.

``--backend structured`` times the structured backends on large sizes instead: ARX (7.4)
n = 80 … 10⁴ (solver ``"arx_barrier"``, :mod:`unfalsify.solvers.arx_barrier`; n = 1000 and 3000 with a 1800 s
limit, n = 10⁴ with 1800 s and the front end's solve only: about 20 minutes; the former route up to n = 1000;
``--quick``: ``method="bracket"``, solver ``"bracket"``, :mod:`unfalsify.solvers.bracket`, at n = 100) and
subspace (7.5) (solver ``"column_barrier"``, :mod:`unfalsify.solvers.column_barrier`, 600 s limit) with L
fixed (the least-squares predictor) and with L optimised at (i, j) = (10, 200) … (100, 1000) (``--series
arx`` / ``--series subspace``: those rows only); each row carries the certified bracket [lower, upper]
(:class:`unfalsify.Certificate`, recomputed from the data), its relative gap, ``verify()`` and the child's
peak RSS.  ARX n = 80 is also solved by cvxpy/Clarabel in the same run
(δ difference and speed ratio; Clarabel's child gets 900 s).  ``both`` runs the cvxpy series and the
structured series.

``--series arx-pd`` (also part of ``all``) times the primal–dual solver ``"arx_pd"``
(:mod:`unfalsify.solvers.arx_pd`, ``method="primal_dual"``) against ``"arx_barrier"`` on the same ARX problem in
the same child process: ``repeats`` × both solvers through the registry (``unfalsify.solvers.run``), the order
alternating between repeats (barrier first, then primal–dual first, …), tol 1e-4, n = 200, 400, 1000 (``--sizes``
overrides, e.g. ``--sizes 200,400,1000,3000``; ``--quick``: 30, 60); medians, the ratio barrier/primal–dual,
iteration counts, both certified brackets recomputed from the data (``evaluate_primal`` / ``evaluate_dual``) and
the 1-min load average before and after every solve.

``--baseline-rev REV`` (structured series) times every row a third way in the same run: the code of git revision
REV (:func:`export_revision`: ``git archive`` into a temporary directory), its own front end in a subprocess on the
row's data, alternating with today's route; the table adds its solver time, the speed-up against it, its Newton
steps and the δ difference.  This is the baseline an issue's "today's route, kept privately" means: the route as it
was, not a switch inside today's code (``former_routes`` shares what changed around the switched part).

``--series subspace-pd`` (also part of ``all``) does the same for (7.5): the primal–dual solver ``"column_pd"``
(:mod:`unfalsify.solvers.column_pd`, ``method="primal_dual"``) against ``"column_barrier"``, both with ``workers=None``,
at (i, j) = (10, 200), (20, 400), (50, 500), each with L fixed and with L optimised (``--sizes 10x200,100x1000``
overrides; ``--quick``: (4, 30)).

Each structured row (issue 27, item 6) runs in a fresh child process, so its peak RSS (``ru_maxrss``) is that
row's: the front end's solve (bracket, certificate, ``verify()``), then ``repeats`` (3; ``--quick``: 1) × the
registry solver alone (``unfalsify.solvers.run`` on the certificate's problem; the subspace solvers with the front
end's ``workers=None``, every core, where the registry's default is one) by today's route and, alternating,
by the former route (:func:`unfalsify.solvers.baselines.former_routes`: the FFT Hessian before issue 27's
pruning and, in ``arx_barrier``, the Newton-step algebra before its BLAS-3 rewrite; in ``column_barrier`` the FFT
Hessian, the Gram by products, K⁻¹ at every trial point and the path steps from the centred point itself) for
``arx_barrier`` and ``column_barrier``; medians.  The row reports
the solve time, the baseline's time in the same run and their ratio, the relative δ difference of the two routes,
the Newton steps and trial factorisations (Cholesky stacks tried, line search and path steps included), the **arithmetic-limit time** and the ratio to it, the peak RSS and the 1-min load at the row's start and
end; the table notes the load before and after the series.

Arithmetic limit: the flops the method needs at its measured counts, divided by the matmul rate measured in the
same child (a numpy matmul of the row's size, timed: an n × n product for ARX, a (j, i, i) stack for the subspace
rows, BLAS as in the solve).  Counted from the sizes (m = n for ARX, j = 1; m = i for the subspace rows), per
column and Newton step: the blocks of F⁻¹ and the gradient's products (``K⁻¹`` from its Cholesky factor,
⅔m³, and the two triangular products ``T K⁻¹``, ``(T K⁻¹) Tᵀ``, m³ each), the Hessian (the displacement route's
~60m²) and the Cholesky of the Newton system (ARX) or of its block (subspace), m³/3; per trial
factorisation the Cholesky of K (m³/3), and for the subspace rows the Gram's O(m²) recursion (~2m²).  (Until
the subspace rows' displacement Hessian their count was 8m³ and the FFT's four real 2-D transforms of 2m × 2m,
``2.5 N² log₂ N²`` each, per step, and (10/3) m³ per trial.)  ARX from n = 400 (:data:`ARX_STRUCTURED_FROM`): per step the Newton system's m³/3, the
Hessian's ~60m² and the blocks of F⁻¹ from generators ~90m²; per trial the Schur algorithm's ~3m².  (Before the ARX step's BLAS-3 rewrite the ARX count was the subspace rows' 8m³.)  The CG of L optimised, the certificate and the set-up
are not counted, so the limit is a lower bound and the ratio an upper one.  Not defined for the bracket row
and the 2×2 rows (blank).  The **warm-start table** (``--backend structured``, series ``all``
or ``--series warm`` alone; issue 27, item 4) times a cold solve and a warm re-solve
(``subspace_unfalsify(..., warm_start=...)``) of the same new problem at (i, j) = (20, 400), tol 1e-4: the window
advanced by k ∈ {1, 10, 50} samples with L optimised and with L fixed (the first window's least-squares predictor),
and the same window at σ × 1.05 (L optimised); median of 3 repeats, load average noted.
"""
from __future__ import annotations

import contextlib
import csv
import io
import multiprocessing as mp
import os
import resource
import sys
import time
import warnings
from pathlib import Path

import numpy as np
from tqdm import tqdm

from synthesis import DataError

from ..lab.report import LiveTable, Report, write_json

__all__ = ["run"]

BUDGET_S = 120.0
QUICK_BUDGET_S = 30.0

#: earlier measurements on this 2-core machine class (Clarabel 0.11, cvxpy 1.9), for comparison
EARLIER_TIMINGS = "ARX conditioned n = 20 → 0.2 s, 40 → 3.2 s, 80 → 78 s, 100 → 138 s; subspace (10, 200) → 5.9 s, (20, 400) → 97 s."


#: wall-clock limit handed to the structured solver (it then returns its certified bracket)
STRUCTURED_LIMIT_S = 240.0
QUICK_STRUCTURED_LIMIT_S = 30.0
#: ARX: the limit of the n = 1000 and 3000 rows, and the child's budget for the cvxpy/Clarabel solve of the same-run comparison
ARX_1000_LIMIT_S = 1800.0
#: ARX n = 10⁴ by the barrier method (issue 27, item 3: certified to 1e-4 within 30 minutes); the front end's solve only
ARX_10K_LIMIT_S = 1800.0
#: ARX rows above this n run no former route (at n = 1000 it already takes 46 s a solve, 14× today's)
ARX_BASELINE_UPTO = 1000
ARX_CLARABEL_BUDGET_S = 900.0
#: subspace (7.5) rows, up to the thesis's (100, 1000), the target being a certified δ within 10 minutes
SUBSPACE_LIMIT_S = 600.0
#: From this n ``arx_barrier`` (one channel) factorises K by the generalised Schur algorithm and builds the blocks of
#: F⁻¹ from displacement generators, both O(n²) (its ``_STRUCTURED_FROM``): the arithmetic limit counts those.
ARX_STRUCTURED_FROM = 400


def _structured_series(quick: bool) -> list[dict]:
    if quick:
        return [
            dict(name="ARX structured", kind="arx", sizes=[20, 40], tol=1e-6),
            dict(name="ARX structured, bracket", kind="arx", method="bracket", sizes=[100], tol=float("nan")),
            dict(name="subspace structured, L fixed", kind="subspace", fixed=True, sizes=[(3, 12), (4, 20)], tol=1e-6),
            dict(name="subspace structured, L optimised", kind="subspace", fixed=False, sizes=[(3, 12), (4, 20)],
                 tol=1e-6),
            dict(name="subspace structured 2×2, L optimised", kind="subspace", fixed=False, channels=2,
                 sizes=[(3, 40)], tol=1e-6),
        ]
    return [
        # n = 1000 gets a 30-minute limit (no time target there, only the gap)
        dict(name="ARX structured", kind="arx", sizes=[80, 200, 400, 1000, 3000, 10_000], tol=1e-4,
             limits={1000: ARX_1000_LIMIT_S, 3000: ARX_1000_LIMIT_S, 10_000: ARX_10K_LIMIT_S},
             front_end_only_from=10_000),
        dict(name="subspace structured, L fixed", kind="subspace", fixed=True,
             sizes=[(10, 200), (20, 400), (50, 500), (100, 1000)], tol=1e-4, limit_s=SUBSPACE_LIMIT_S),
        dict(name="subspace structured, L optimised", kind="subspace", fixed=False,
             sizes=[(10, 200), (20, 400), (50, 500), (100, 1000)], tol=1e-4, limit_s=SUBSPACE_LIMIT_S),
        # several channels (issue 28): solver block_barrier
        dict(name="subspace structured 2×2, L optimised", kind="subspace", fixed=False, channels=2,
             sizes=[(10, 200), (20, 400)], tol=1e-4, limit_s=SUBSPACE_LIMIT_S),
    ]


def _series(quick: bool) -> list[dict]:
    if quick:
        return [
            dict(name="ARX conditioned", kind="arx", form="conditioned", sizes=[8, 12]),
            dict(name="ARX thesis", kind="arx", form="thesis", sizes=[8, 12]),
            dict(name="subspace conditioned i=3", kind="subspace", form="conditioned", i=3, sizes=[12, 16]),
            dict(name="subspace conditioned, L eliminated, i=3", kind="subspace", form="conditioned", eliminate=True,
                 i=3, sizes=[12, 16]),
            dict(name="subspace thesis i=3", kind="subspace", form="thesis", i=3, sizes=[12, 16]),
            dict(name="subspace 2×2 conditioned i=3", kind="subspace", form="conditioned", i=3, sizes=[40],
                 channels=2),  # j > i(2m + l) = 18 regressors: the least-squares residual is not zero
        ]
    return [
        dict(name="ARX conditioned", kind="arx", form="conditioned", sizes=[10, 20, 30, 40, 60, 80, 100, 120]),
        dict(name="ARX thesis", kind="arx", form="thesis", sizes=[10, 20, 30, 40, 60, 80]),
        dict(name="subspace conditioned i=5", kind="subspace", form="conditioned", i=5, sizes=[20, 50, 100, 200, 400, 800]),
        dict(name="subspace conditioned i=10", kind="subspace", form="conditioned", i=10, sizes=[50, 100, 200, 400, 800]),
        dict(name="subspace conditioned i=20", kind="subspace", form="conditioned", i=20, sizes=[50, 100, 200, 400]),
        dict(name="subspace conditioned, L eliminated, i=10", kind="subspace", form="conditioned", eliminate=True, i=10,
             sizes=[50, 100, 200, 400]),
        dict(name="subspace thesis i=3", kind="subspace", form="thesis", i=3, sizes=[10, 20, 40, 80, 160]),
        dict(name="subspace thesis i=5", kind="subspace", form="thesis", i=5, sizes=[20, 40, 80, 160]),
        dict(name="subspace 2×2 conditioned i=10", kind="subspace", form="conditioned", i=10, sizes=[200],
             channels=2),
    ]


def _data(n: int, seed: int):
    from ..lab.servo_setup import servo_data

    d = servo_data(n, seed=seed)
    return d.u, d.y


def _mimo_data(n: int, seed: int):
    """Two inputs, two outputs: two servo channels (§5.4) behind the input coupling ``[[1, 0.3], [0.2, 1]]``,
    independent PRBS ±1 inputs, process and sensor noise as :func:`~experiments.lab.servo_setup.servo_data`."""
    import control as ct

    from ..lab.servo_setup import SIGMA_PROCESS, SIGMA_SENSOR
    from ..lab.plants import servo
    from ..lab.signals import prbs
    from ..lab.simulate import collect_data

    s1 = servo()
    plant = ct.append(s1, servo()) * ct.ss([], [], [], np.array([[1.0, 0.3], [0.2, 1.0]]), s1.dt)
    streams = np.random.SeedSequence(seed).spawn(3)
    u = np.column_stack([prbs(n, seed=np.random.default_rng(s)) for s in streams[:2]])
    d = collect_data(plant, u, process_noise=SIGMA_PROCESS, sensor_noise=SIGMA_SENSOR,
                     seed=np.random.default_rng(streams[2]))
    return d.u, d.y


def _half_ls_sigma(u, y, i=None):
    """σ of the structured rows: half the least-squares residual rms; ARX (7.4) with na = nb = 2 (``i`` None), or
    (7.5) at horizon i, where it is that of the least-squares predictor, returned with it: ``(predictor, σ)``."""
    import synthesis as sy
    import unfalsify as uf

    if i is None:
        return 0.5 * uf.arx_least_squares(u, y, 2, 2)[1]
    pred = sy.fit_predictor(u, y, i)
    A, _, Yf = uf.subspace_data(u, y, i)
    return pred, 0.5 * float(np.linalg.norm(Yf - np.hstack([pred.Lw, pred.Lu]) @ A) / np.sqrt(Yf.size))


def _solve_one(spec: dict, size: int, seed: int) -> dict:
    """One solve (runs in the child process)."""
    import unfalsify as uf

    warnings.simplefilter("ignore")
    if spec["kind"] == "arx":
        n = size
        u, y = _data(n, seed)
        _, rms = uf.arx_least_squares(u, y, 2, 2)
        sigma = 0.5 * rms
        t0 = time.perf_counter()
        res = uf.arx_unfalsify(u, y, 2, 2, sigma, form=spec["form"])
        wall = time.perf_counter() - t0
        label = _label(spec, size)
    else:
        i, j = spec["i"], size
        n = 2 * i + j - 1
        u, y = _mimo_data(n, seed) if spec.get("channels", 1) > 1 else _data(n, seed)
        A, _, Yf = uf.subspace_data(u, y, i)
        L = np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T
        sigma = 0.5 * float(np.linalg.norm(Yf - L @ A) / np.sqrt(Yf.size))
        t0 = time.perf_counter()
        res = uf.subspace_unfalsify(u, y, i, sigma, form=spec["form"], eliminate_L=spec.get("eliminate", False))
        wall = time.perf_counter() - t0
        label = _label(spec, size)
    p = res.problem
    stats = p.solver_stats
    cert = res.certificate
    return {
        "size": size,
        "label": label,
        "n_samples": n,
        "status": res.status,
        "delta": res.delta,
        "delta_certified": cert.delta_certified,
        "max_violation": cert.max_violation,
        "noise_rms_over_sigma": cert.noise_rms / cert.sigma,
        "wall_s": wall,
        "solver_s": float(stats.solve_time) if stats.solve_time is not None else float("nan"),
        "compile_s": float(p.compilation_time) if p.compilation_time is not None else float("nan"),
        "iterations": stats.num_iters,
        "n_variables": int(sum(v.size for v in p.variables())),
        "cond_Tu": res.cond_Tu,
    }


def _child(conn, spec, size, seed, worker=None):
    try:
        conn.send(("ok", (worker or _solve_one)(spec, size, seed)))
    except Exception as exc:  # reported in the table, not raised
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
    finally:
        conn.close()


def _rss_mb() -> float:
    """Peak resident set size of this process in MB (Linux: ru_maxrss in kB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _structured_label(spec: dict, size) -> str:
    return f"n={size}" if spec["kind"] == "arx" else f"(i, j)=({size[0]}, {size[1]})"


#: repeats of the timed solves of a structured row (the row reports medians); ``--quick``: 1
STRUCTURED_REPEATS, QUICK_STRUCTURED_REPEATS = 3, 1


def _structured_repeats(opts) -> int:
    """``--repeats`` if given (at least 1), else :data:`STRUCTURED_REPEATS` (``--quick``: 1)."""
    given = (getattr(opts, "extra", None) or {}).get("repeats")
    if given is not None:
        if int(given) < 1:
            raise DataError(f"--repeats must be at least 1, got {given} (pass --repeats 1 or more, or omit it)")
        return int(given)
    return QUICK_STRUCTURED_REPEATS if opts.quick else STRUCTURED_REPEATS


def _matmul_peak(shape: tuple, min_seconds: float = 0.05) -> float:
    """Flops per second of a timed numpy matmul of ``shape`` (a stack (j, m, m) or a matrix (n, n)): the best of
    3 timings (a peak: on the shared machine the median followed the load, 24 against 7 GF/s in one run), each
    repeating the product until it has run ``min_seconds`` (BLAS threads as the solve has)."""
    rng = np.random.default_rng(0)
    a, b = rng.standard_normal(shape), rng.standard_normal(shape)
    flops = 2.0 * float(np.prod(shape)) * shape[-1]
    rates = []
    for _ in range(3):
        count, t0 = 0, time.perf_counter()
        while True:
            a @ b
            count += 1
            elapsed = time.perf_counter() - t0
            if elapsed >= min_seconds:
                break
        rates.append(count * flops / elapsed)
    return float(max(rates))


def _needed_flops(kind: str, m: int, j: int, newton, trials) -> float | None:
    """The flops the method needs at its measured counts (the bench docstring's arithmetic limit); None where
    not defined (no Newton count: the bracket route, the 2×2 rows)."""
    if newton is None:
        return None
    newton = int(newton)
    trials = newton if trials is None else int(trials)  # a solver without counts: one accepted point per step
    m3 = float(m) ** 3
    if kind == "arx" and m >= ARX_STRUCTURED_FROM:  # the Newton system's Cholesky m³/3, the displacement
        # Hessian ~60m², the blocks from generators ~90m² (two solves against m × 16, three rank-4 outer products,
        # three cumulative sums); per trial the generalised Schur algorithm ~3m² (unfalsify.solvers.displacement)
        return newton * (m3 / 3.0 + 150.0 * m * m) + trials * 3.0 * m * m
    if kind == "arx":  # j = 1, m = n: potri ⅔m³, two trmm m³ each, the Newton system's Cholesky m³/3,
        # the displacement Hessian ~60m²; per trial the Gram and LAPACK's Cholesky of K
        return newton * (3.0 * m3 + 60.0 * m * m) + trials * m3 / 3.0
    # subspace, per column: K⁻¹ from its Cholesky factor ⅔m³ (potri), T K⁻¹ and (T K⁻¹)Tᵀ m³ each (triangular),
    # the block's Newton system m³/3 (Cholesky), the displacement Hessian ~60m²; per trial the Cholesky of K and
    # the Gram's recursion ~2m²
    return j * (newton * (3.0 * m3 + 60.0 * m * m) + trials * (m3 / 3.0 + 2.0 * m * m))


#: The script a baseline revision's solve runs in (``--baseline-rev``): the revision's own front end on the data of
#: the row (an .npz written by today's code, so both routes solve the same problem), its solver time and counts as
#: JSON on the last line of stdout.  Only the front ends' long-standing arguments are used.
_REVISION_SCRIPT = r"""
import json, sys, warnings
import numpy as np
warnings.simplefilter("ignore")
import synthesis as sy
import unfalsify as uf
d = np.load(sys.argv[1])
spec = json.loads(sys.argv[2])
u, y, sigma = d["u"], d["y"], float(d["sigma"])
if spec["kind"] == "arx":
    res = uf.arx_unfalsify(u, y, 2, 2, sigma, backend="structured", tol=spec["tol"], time_limit=spec["limit"],
                           progress=False)
else:
    i = int(spec["i"])
    pred = sy.fit_predictor(u, y, i) if spec["fixed"] else None
    res = uf.subspace_unfalsify(u, y, i, sigma, backend="structured", predictor=pred, tol=spec["tol"],
                                time_limit=spec["limit"], progress=False)
stats = dict(getattr(res, "solver_stats", None) or {})
print(json.dumps(dict(solve=float(res.solve_time), delta=float(res.delta), status=str(res.status),
                      newton=stats.get("newton"), trials=stats.get("trials"))))
"""


def export_revision(rev: str) -> Path:
    """Export git revision ``rev`` of this checkout into a temporary directory (``git archive``); returns its path.

    Raises :class:`~synthesis.DataError` naming the fix when this is not a git checkout or ``rev`` is unknown."""
    import subprocess
    import tarfile
    import tempfile

    top = Path(__file__).resolve().parents[2]
    tree = Path(tempfile.mkdtemp(prefix=f"bench-baseline-{rev[:12]}-"))
    try:
        archive = subprocess.run(["git", "-C", str(top), "archive", "--format=tar", rev], check=True,
                                 capture_output=True).stdout
    except (OSError, subprocess.CalledProcessError) as exc:
        why = exc.stderr.decode(errors="replace").strip() if getattr(exc, "stderr", None) else str(exc)
        raise DataError(f"--baseline-rev {rev!r}: cannot export it from the git checkout at {top} ({why}); run the "
                        "benchmark from a git clone and name a commit, tag or branch (e.g. --baseline-rev HEAD~10)") \
            from None
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        tar.extractall(tree, filter="data")
    return tree


def _revision_solve(tree: str, data: Path, spec: dict) -> dict:
    """One solve by the exported revision at ``tree`` (a subprocess with that tree first on ``sys.path``)."""
    import json
    import subprocess

    env = dict(os.environ, PYTHONPATH=str(tree))
    args = json.dumps(dict(kind=spec["kind"], tol=spec["tol"], limit=spec["limit"], i=spec.get("i"),
                           fixed=bool(spec.get("fixed"))))
    done = subprocess.run([sys.executable, "-c", _REVISION_SCRIPT, str(data), args], cwd=tree, env=env,
                          capture_output=True, text=True, timeout=spec["limit"] * 2 + 300)
    if done.returncode != 0:
        raise RuntimeError(f"the baseline revision's solve failed: {done.stderr.strip()[-400:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def _solve_structured_one(spec: dict, size, seed: int) -> dict:
    """One structured row (runs in the child process): the front end's solve (bracket, certificate, verify), the
    matmul peak, then ``repeats`` × (the registry solver by today's route, the same solver by the former route
    of :mod:`unfalsify.solvers.baselines`), alternating; medians, counts and the δ agreement of the two routes."""
    import unfalsify as uf
    from unfalsify import solvers
    from unfalsify.solvers import baselines

    warnings.simplefilter("ignore")
    rss0 = _rss_mb()
    load0 = os.getloadavg()[0]
    limit = spec["limit"]
    channels = spec.get("channels", 1)
    if spec["kind"] == "arx":
        n = size
        u, y = _data(n, seed)
        sigma = _half_ls_sigma(u, y)
        t0 = time.perf_counter()
        res = uf.arx_unfalsify(u, y, 2, 2, sigma, backend="structured", tol=spec["tol"], time_limit=limit,
                               progress=False, method=spec.get("method", "barrier"))
        wall = time.perf_counter() - t0
        unknowns, i, j = n, None, None
        name = solvers.resolve("arx", "structured", spec.get("method", "barrier"))
        block, peak_shape = (n, 1), (n, n)
    else:
        i, j = size
        n = 2 * i + j - 1
        u, y = _mimo_data(n, seed) if channels > 1 else _data(n, seed)
        pred, sigma = _half_ls_sigma(u, y, i)
        t0 = time.perf_counter()
        res = uf.subspace_unfalsify(u, y, i, sigma, backend="structured", predictor=pred if spec["fixed"] else None,
                                    tol=spec["tol"], time_limit=limit, progress=False)
        wall = time.perf_counter() - t0
        unknowns = i * j * channels**2
        name = "block_barrier" if channels > 1 else solvers.resolve("subspace", "structured")
        block, peak_shape = (i, j), (j, i * channels, i * channels)
    cert = res.certificate
    # no arithmetic limit for the bracket row (no Newton steps), so no matmul probe: at n = 10⁴ its three
    # n × n arrays (2.4 GB) raised the row's peak RSS to 2.5 GB, above the front end's own 0.96 GB
    peak = None if name == "bracket" else _matmul_peak(peak_shape, 0.01 if spec.get("repeats", 1) == 1 else 0.05)
    # a former route exists for arx_barrier (one channel) and column_barrier (baselines.former_routes); the
    # bracket route has no Hessian, block_barrier forms its own dense blocks
    baseline = name in ("arx_barrier", "column_barrier") and channels == 1
    baseline = baseline and not (spec["kind"] == "arx" and n > ARX_BASELINE_UPTO)
    runs = {"current": [], "baseline": [], "revision": []}
    data = None
    if spec.get("baseline_tree") and channels == 1 and name != "bracket":
        import tempfile

        data = Path(tempfile.mkdtemp(prefix="bench-row-")) / "data.npz"
        np.savez(data, u=u, y=y, sigma=sigma)
    # the bracket route (FFT only, no Hessian, no former route) and ARX n = 10⁴ (about 20 minutes a solve): the
    # front end's solve alone
    front_end_only = name == "bracket" or n >= spec.get("front_end_only_from", np.inf)
    if front_end_only:
        stats = res.solver_stats
        runs["current"].append(dict(wall=float(res.solve_time), delta=res.delta, status=res.status,
                                    newton=stats.get("newton"), trials=stats.get("trials")))
    # the subspace solvers on the front end's threads (workers=None: every core); the registry's default is one
    # worker, which had made these repeats slower than the front end's own solve (59 against 43 s at (100, 1000))
    threads = {} if spec["kind"] == "arx" else dict(workers=None)
    routes = ("current", "baseline") if baseline else ("current",)
    routes += ("revision",) if data is not None else ()
    for _ in range(0 if front_end_only else spec.get("repeats", 1)):
        for route in routes:
            if route == "revision":  # the revision's own front end, in a subprocess: its solver time
                rev = _revision_solve(spec["baseline_tree"], data, dict(spec, i=i, fixed=spec.get("fixed")))
                runs[route].append(dict(wall=rev["solve"], delta=rev["delta"], status=rev["status"],
                                        newton=rev.get("newton"), trials=rev.get("trials")))
                continue
            context = baselines.former_routes() if route == "baseline" else contextlib.nullcontext()
            with context:
                t0 = time.perf_counter()
                out = solvers.run(name, cert.problem, tol=spec["tol"], time_limit=limit, progress=False, **threads)
                runs[route].append(dict(wall=time.perf_counter() - t0, delta=out.delta, status=str(out.status),
                                        newton=out.stats.get("newton"), trials=out.stats.get("trials")))
    cur = runs["current"]
    newton, trials = cur[-1]["newton"], cur[-1]["trials"]
    solve_s = float(np.median([r["wall"] for r in cur]))
    flops = _needed_flops(spec["kind"], block[0], block[1], newton, trials) if channels == 1 else None
    limit_s = flops / peak if flops is not None and peak else None
    row = {
        "label": _structured_label(spec, size), "size": unknowns, "i": i, "j": j, "n_samples": n,
        "status": res.status, "delta": res.delta, "lower": cert.lower_bound, "upper": cert.upper_bound,
        "relative_gap": cert.relative_gap, "verify": bool(cert.verify()), "wall_s": wall,
        "peak_rss_mb": _rss_mb(), "rss_start_mb": rss0, "cond_Tu": res.cond_Tu,
        # the registry solver's own counts (Newton steps, trial Cholesky stacks where the solver counts them)
        "newton": newton, "trials": trials, "solve_s": solve_s, "solve_walls": [r["wall"] for r in cur],
        "repeats": len(cur), "matmul_gflops": None if peak is None else peak / 1e9, "needed_gflop": None if flops is None else flops / 1e9,
        "limit_s": limit_s, "limit_ratio": None if limit_s is None else solve_s / limit_s,
        "load": (load0, os.getloadavg()[0]),
    }
    if runs["baseline"]:
        old = runs["baseline"]
        row.update(baseline_s=float(np.median([r["wall"] for r in old])), baseline_walls=[r["wall"] for r in old],
                   baseline_newton=old[-1]["newton"],
                   baseline_delta_rel=abs(old[-1]["delta"] - cur[-1]["delta"]) / max(abs(old[-1]["delta"]), 1e-300))
    if data is not None:
        import shutil

        shutil.rmtree(data.parent, ignore_errors=True)
    if runs["revision"]:
        rev = runs["revision"]
        row.update(revision=spec.get("baseline_rev"), revision_s=float(np.median([r["wall"] for r in rev])),
                   revision_walls=[r["wall"] for r in rev], revision_newton=rev[-1]["newton"],
                   revision_status=rev[-1]["status"],
                   revision_delta_rel=abs(rev[-1]["delta"] - cur[-1]["delta"]) / max(abs(rev[-1]["delta"]), 1e-300))
    return row


#: the primal–dual head-to-head (``--series arx-pd``): sizes, tolerance, limit per solve
PD_SIZES, QUICK_PD_SIZES, PD_TOL, PD_LIMIT_S = (200, 400, 1000), (30, 60), 1e-4, 1800.0
#: the same for (7.5) (``--series subspace-pd``): (i, j), each with L fixed and with L optimised
SUBSPACE_PD_SIZES, QUICK_SUBSPACE_PD_SIZES = ((10, 200), (20, 400), (50, 500)), ((4, 30),)
#: the solvers each head-to-head compares: (barrier, primal–dual)
PD_SOLVERS = {"arx": ("arx_barrier", "arx_pd"), "subspace": ("column_barrier", "column_pd")}


def _pd_problem(spec: dict, size, seed: int):
    """The problem of one head-to-head row: ARX (7.4) na = nb = 2 at n = size, or (7.5) at (i, j) = size with L
    fixed (the least-squares predictor) or optimised; σ = ½ the least-squares residual rms."""
    import unfalsify as uf

    if spec["program"] == "arx":
        u, y = _data(size, seed)
        return uf.ArxProblem.from_data(u, y, 2, 2, _half_ls_sigma(u, y))
    i, j = size
    u, y = _data(2 * i + j - 1, seed)
    pred, sigma = _half_ls_sigma(u, y, i)
    return uf.SubspaceProblem.from_data(u, y, i, sigma, predictor=pred if spec["fixed"] else None)


def _solve_pd_pair(spec: dict, size, seed: int) -> dict:
    """One row of a primal–dual head-to-head in the child process: ``repeats`` × (the barrier solver, the
    primal–dual solver of :data:`PD_SOLVERS`) on the same problem, the order alternating between repeats (the
    subspace solvers on every core, ``workers=None``, as the front end); every solve's wall time, status, δ, counts,
    certified bracket (recomputed from the data) and load."""
    from unfalsify import solvers

    warnings.simplefilter("ignore")
    P = _pd_problem(spec, size, seed)
    names = PD_SOLVERS[spec["program"]]
    threads = dict(workers=None) if spec["program"] == "subspace" else {}
    runs = {name: [] for name in names}
    for k in range(spec["repeats"]):
        for name in names if k % 2 == 0 else names[::-1]:
            load0 = os.getloadavg()[0]
            t0 = time.perf_counter()
            out = solvers.run(name, P, tol=spec["tol"], time_limit=spec["limit"], progress=False, **threads)
            wall = time.perf_counter() - t0
            load1 = os.getloadavg()[0]
            upper, _ = P.evaluate_primal(out.impulses, out.params)
            lower = P.evaluate_dual(out.dual_v, out.dual_W) if out.dual_W is not None else 0.0
            stats = {k: v for k, v in out.stats.items() if k != "state"}
            runs[name].append(dict(wall=wall, status=str(out.status.value), delta=out.delta, upper=upper,
                                   lower=lower, gap=(upper - lower) / upper, load=(load0, load1), **stats))
    row = {"size": list(size) if spec["program"] == "subspace" else size, "repeats": spec["repeats"],
           "peak_rss_mb": _rss_mb(), "barrier": names[0], "primal_dual": names[1]}
    if spec["program"] == "arx":
        row["n"] = size
    else:
        row["L_fixed"] = bool(spec["fixed"])
    for name, rs in runs.items():
        row[name] = dict(rs[-1], wall=float(np.median([r["wall"] for r in rs])), walls=[r["wall"] for r in rs],
                         loads=[r["load"] for r in rs])
    b, p = row[names[0]], row[names[1]]
    row["ratio"] = b["wall"] / p["wall"]
    row["delta_rel"] = abs(b["delta"] - p["delta"]) / max(abs(b["delta"]), 1e-300)
    row["overlap"] = bool(max(b["lower"], p["lower"]) <= min(b["upper"], p["upper"]) * (1 + 1e-9))
    return row


def _pd_sizes(opts, program: str) -> list:
    """``--sizes`` (ARX: ``200,400``; subspace: ``10x200,20x400``) or the defaults."""
    sizes = (getattr(opts, "extra", None) or {}).get("sizes")
    if program == "arx":
        return [int(x) for x in sizes.split(",")] if sizes else list(QUICK_PD_SIZES if opts.quick else PD_SIZES)
    if not sizes:
        return list(QUICK_SUBSPACE_PD_SIZES if opts.quick else SUBSPACE_PD_SIZES)
    try:
        pairs = [tuple(int(v) for v in x.lower().split("x")) for x in sizes.split(",")]
    except ValueError:
        pairs = []
    if not pairs or any(len(ij) != 2 or min(ij) < 1 for ij in pairs):
        raise DataError(f"--sizes for the subspace-pd table takes i×j pairs such as 10x200,20x400; got {sizes!r}")
    return pairs


def _run_pd(opts, program: str = "arx") -> dict:
    """A primal–dual head-to-head: each row in its own child process (:func:`_solve_pd_pair`); the subspace rows
    with L fixed and with L optimised."""
    repeats = _structured_repeats(opts)
    base = dict(program=program, tol=PD_TOL, limit=QUICK_STRUCTURED_LIMIT_S if opts.quick else PD_LIMIT_S,
                repeats=repeats)
    cases = [(dict(base), n) for n in _pd_sizes(opts, program)] if program == "arx" else \
        [(dict(base, fixed=fixed), ij) for fixed in (True, False) for ij in _pd_sizes(opts, program)]
    names = PD_SOLVERS[program]
    rows = []
    load_before = os.getloadavg()
    for spec, size in tqdm(cases, desc=f"bench-unfalsify: {names[1]} against {names[0]}", leave=False):
        label = f"n={size}" if program == "arx" else f"({size[0]}, {size[1]}), L {'fixed' if spec['fixed'] else 'optimised'}"
        row = _run_with_budget(spec, size, opts.seed, spec["limit"] * 2 * repeats + 120.0, worker=_solve_pd_pair,
                               label=label)
        row["label"] = label
        rows.append(row)
        if "ratio" in row:
            tqdm.write(f"[bench-unfalsify] {label}: {names[0]} {row[names[0]]['wall']:.2f} s, {names[1]} "
                       f"{row[names[1]]['wall']:.2f} s ({row['ratio']:.2f}×)", file=sys.stderr)
    return {"program": program, "rows": rows, "tol": base["tol"], "repeats": repeats, "time_limit_s": base["limit"],
            "load": {"before": list(load_before), "after": list(os.getloadavg())}}


def _report_pd(rep: Report, pd: dict) -> None:
    program = pd.get("program", "arx")
    barrier, primal_dual = PD_SOLVERS[program]
    what = "ARX (7.4)" if program == "arx" else "Subspace (7.5)"
    rep.section(f"{what}: primal–dual (`{primal_dual}`) against the barrier method (`{barrier}`), tol {pd['tol']:g}")
    rep.text(
        "Same problem, same child process, registry solvers alone (`unfalsify.solvers.run`"
        + ("" if program == "arx" else ", `workers=None`: every core") + "), "
        f"{pd['repeats']} repeat(s) each, the order alternating between repeats; medians. `×` = barrier/primal–dual "
        "(above 1: primal–dual faster). Iterations: barrier Newton steps; primal–dual predictor–corrector "
        "iterations (factorisations: its Cholesky, eigendecompositions and step-length computations"
        + (", dense" if program == "arx" else ", each a stack over the columns") + "). "
        "`gap`: the certified relative gap of each answer, both sides recomputed from the data; `overlap`: the two "
        "brackets intersect. `load`: 1-min load average, lowest → highest over the row's solves. Table load: "
        f"{pd['load']['before'][0]:.2f} → {pd['load']['after'][0]:.2f} (1-min); {os.cpu_count()} CPU(s)."
    )
    rows = []
    for r in pd["rows"]:
        if "ratio" not in r:
            rows.append([r.get("label"), r.get("status"), *[""] * 10])
            continue
        b, p = r[barrier], r[primal_dual]
        loads = [x for s in (b, p) for pair in s["loads"] for x in pair]
        rows.append([r.get("label", f"n={r.get('n')}"), b["wall"], p["wall"], f"{r['ratio']:.2f}",
                     _count(b.get("newton")), _count(p.get("newton")), _count(p.get("factorisations")),
                     f"{b['status']} / {p['status']}", f"{b['gap']:.1e} / {p['gap']:.1e}", f"{r['delta_rel']:.1e}",
                     str(r["overlap"]), f"{min(loads):.1f} → {max(loads):.1f}"])
    rep.table(["size", f"{barrier} [s]", f"{primal_dual} [s]", "×", "barrier Newton", "pd iterations", "pd fact.",
               "status", "gap", "|Δδ|/δ", "overlap", "load"], rows, floatfmt=".3g")


def _fmt(x, spec: str = ".3g") -> str:
    return "" if x is None else format(x, spec)


def _count(x):
    return "" if x is None else int(x)


#: warm-start table (issue 27, item 4): (i, j), window advances k, the σ factor of the same-window case, repeats
WARM_SIZE, WARM_SHIFTS, WARM_SIGMA_FACTOR, WARM_REPEATS = (20, 400), (1, 10, 50), 1.05, 3
QUICK_WARM_SIZE, QUICK_WARM_REPEATS = (6, 60), 1


def _solve_warm_case(spec: dict, case, seed: int) -> dict:
    """One warm-start case in the child process: the first window's cold solve (not timed), then ``repeats``
    × (cold solve of the new problem, warm solve of it from the first), each timed around the whole
    ``subspace_unfalsify`` call; medians, and the load average before and after."""
    import synthesis as sy
    import unfalsify as uf

    warnings.simplefilter("ignore")
    (i, j), (k, factor, fixed), repeats = spec["size"], case, spec["repeats"]
    n = 2 * i + j - 1
    u, y = _data(n + max(spec["shifts"]), seed)
    A, _, Yf = uf.subspace_data(u[:n], y[:n], i)
    L = np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T
    sigma = 0.5 * float(np.linalg.norm(Yf - L @ A) / np.sqrt(Yf.size))
    # L fixed: the first window's least-squares predictor, kept for the new window (δ of one model tracked online)
    pred = sy.fit_predictor(u[:n], y[:n], i) if fixed else None
    kw = dict(backend="structured", tol=spec["tol"], progress=False, workers=1, predictor=pred)
    first = uf.subspace_unfalsify(u[:n], y[:n], i, sigma, **kw)
    load0 = os.getloadavg()[0]
    runs = {"cold": [], "warm": []}
    for _ in range(repeats):
        for name, extra in (("cold", {}), ("warm", {"warm_start": first})):
            t0 = time.perf_counter()
            res = uf.subspace_unfalsify(u[k : n + k], y[k : n + k], i, sigma * factor, **kw, **extra)
            wall = time.perf_counter() - t0
            cert = res.certificate
            runs[name].append(dict(wall=wall, solve=res.solve_time, newton=res.solver_stats.get("newton"),
                                   outer=res.solver_stats.get("outer"), trials=res.solver_stats.get("trials"),
                                   gap=cert.relative_gap, delta=res.delta, verify=bool(cert.verify()),
                                   lower=cert.lower_bound, upper=cert.upper_bound, start=res.start))
    out = {"k": k, "sigma_factor": factor, "L_fixed": bool(fixed), "load": (load0, os.getloadavg()[0]),
           "peak_rss_mb": _rss_mb()}
    for name, rs in runs.items():
        out[name] = dict(rs[-1], wall=float(np.median([r["wall"] for r in rs])),
                         solve=float(np.median([r["solve"] for r in rs])), walls=[r["wall"] for r in rs],
                         verify=all(r["verify"] for r in rs))
    c, w = out["cold"], out["warm"]
    out["overlap"] = bool(max(c["lower"], w["lower"]) <= min(c["upper"], w["upper"]) * (1 + 1e-9))
    return out


def _run_warm(opts) -> dict:
    """The warm-start table: each case in its own child process (``_solve_warm_case``)."""
    spec = dict(size=QUICK_WARM_SIZE if opts.quick else WARM_SIZE, repeats=QUICK_WARM_REPEATS if opts.quick
                else WARM_REPEATS, shifts=WARM_SHIFTS, tol=1e-4)
    cases = [(k, 1.0, fixed) for fixed in (False, True) for k in WARM_SHIFTS] + [(0, WARM_SIGMA_FACTOR, False)]
    rows = []
    for case in tqdm(cases, desc="bench-unfalsify: warm starts", leave=False):
        row = _run_with_budget(spec, case, opts.seed, 1200.0, worker=_solve_warm_case, label=str(case))
        rows.append(row)
        if "cold" in row:
            tqdm.write(f"[bench-unfalsify] warm start {case}: cold {row['cold']['wall']:.2f} s, warm "
                       f"{row['warm']['wall']:.2f} s", file=sys.stderr)
    return {"size": spec["size"], "repeats": spec["repeats"], "tol": spec["tol"], "rows": rows}


def _report_warm(rep: Report, warm: dict) -> None:
    i, j = warm["size"]
    rep.section(f"Warm starts at (i, j) = ({i}, {j}), tol {warm['tol']:g}")
    rep.text(
        "`subspace_unfalsify(..., warm_start=first)`, `first` the cold solve of the first window; the new problem "
        f"is the window advanced by k samples (same σ) or the first window at σ × {WARM_SIGMA_FACTOR}; L optimised, "
        "or fixed to the first window's least-squares predictor (δ of one model tracked as the window slides). Cold and "
        f"warm alternate, {warm['repeats']} repeat(s) each, medians; `wall` is the whole call (problem set-up, "
        "solve, certificate), `solve` the solver's own time; `workers=1`. `overlap`: the two certified brackets "
        "intersect (the same δ to the certified gap). Load: 1-min load average before → after the case."
    )
    rows = []
    for r in warm["rows"]:
        if "cold" not in r:
            rows.append([r.get("label"), r.get("status"), *[""] * 12])
            continue
        c, w = r["cold"], r["warm"]
        case = f"k = {r['k']}" if r["sigma_factor"] == 1.0 else f"σ × {r['sigma_factor']:g}"
        case += ", L fixed" if r.get("L_fixed") else ", L optimised"
        rows.append([case, c["wall"], w["wall"], w["wall"] / c["wall"], c["solve"], w["solve"], _count(c["newton"]),
                     _count(w["newton"]), _count(c["trials"]), _count(w["trials"]), c["gap"], w["gap"],
                     f"{r['overlap']} / {c['verify'] and w['verify']}", f"{r['load'][0]:.1f} → {r['load'][1]:.1f}"])
    rep.table(["case", "cold wall [s]", "warm wall [s]", "warm/cold", "cold solve [s]", "warm solve [s]",
               "cold Newton", "warm Newton", "cold trials", "warm trials", "cold gap", "warm gap",
               "overlap / verify", "load"], rows, floatfmt=".3g")
    starts = sorted({r["warm"]["start"] for r in warm["rows"] if "warm" in r})
    rep.text("Warm starts: " + "; ".join(f"`{s}`" for s in starts) + ".")


#: the warm-start floor (issue 27, item 4): the window advance of the oracle resumes
WARM_FLOOR_SHIFT, QUICK_WARM_FLOOR_SHIFT = 50, 10


def _solve_warm_floor_case(spec: dict, fixed: bool, seed: int) -> dict:
    """The floor of any warm start that resumes on the central path, in the child process.

    The window advanced by ``shift`` samples is solved cold (timed), then re-solved from each of its *own* centred
    points (an oracle: the exact central point of the new problem at that gap, which no warm start from the old
    window has), timed.  What the tail of the path from gap g costs is a lower bound on the time of every warm start
    that re-enters the path at gap g.  Also the move of δ between the two windows: the distance a warm start has to
    cover.  Medians of ``repeats``; ``workers=1``."""
    import unfalsify as uf
    from unfalsify import solvers

    warnings.simplefilter("ignore")
    (i, j), shift, repeats, tol = spec["size"], spec["shift"], spec["repeats"], spec["tol"]
    n = 2 * i + j - 1
    u, y = _data(n + shift, seed)
    pred, sigma = _half_ls_sigma(u[:n], y[:n], i)
    pred = pred if fixed else None
    first = uf.SubspaceProblem.from_data(u[:n], y[:n], i, sigma, predictor=pred)
    new = uf.SubspaceProblem.from_data(u[shift:n + shift], y[shift:n + shift], i, sigma, predictor=pred)
    load0 = os.getloadavg()[0]

    def timed(problem, **kw):
        walls, out = [], None
        for _ in range(repeats):
            t0 = time.perf_counter()
            out = solvers.run("column_barrier", problem, tol=tol, progress=False, workers=1, **kw)
            walls.append(time.perf_counter() - t0)
        return out, float(np.median(walls))

    old, _ = timed(first)
    cold, cold_s = timed(new)
    up_cold, _ = new.evaluate_primal(cold.impulses, cold.params)
    lo_cold = new.evaluate_dual(cold.dual_v, cold.dual_W)
    rows = []
    for centre in cold.stats["state"]["path"]:
        out, wall = timed(new, warm_start=centre)
        upper, _ = new.evaluate_primal(out.impulses, out.params)  # both bounds recomputed from the data
        lower = new.evaluate_dual(out.dual_v, out.dual_W) if out.dual_W is not None else 0.0
        rows.append(dict(gap=float(centre["gap"]), wall=wall, ratio=wall / cold_s, newton=out.stats.get("newton"),
                         status=out.status.value, certified_gap=float((upper - lower) / upper),
                         overlap=bool(max(lower, lo_cold) <= min(upper, up_cold) * (1 + 1e-9)),
                         used=out.stats.get("warm") == "used"))
    return dict(L_fixed=bool(fixed), shift=shift, delta_old=float(old.delta), delta_new=float(cold.delta),
                cold=cold_s, cold_newton=cold.stats.get("newton"), rows=rows, load=(load0, os.getloadavg()[0]))


def _run_warm_floor(opts) -> dict:
    """The warm-start floor table: L optimised and L fixed, each in its own child process."""
    spec = dict(size=QUICK_WARM_SIZE if opts.quick else WARM_SIZE, repeats=QUICK_WARM_REPEATS if opts.quick
                else WARM_REPEATS, shift=QUICK_WARM_FLOOR_SHIFT if opts.quick else WARM_FLOOR_SHIFT, tol=1e-4)
    cases = []
    for fixed in tqdm((False, True), desc="bench-unfalsify: warm-start floor", leave=False):
        cases.append(_run_with_budget(spec, fixed, opts.seed, 1200.0, worker=_solve_warm_floor_case,
                                      label="L fixed" if fixed else "L optimised"))
    return {"size": spec["size"], "repeats": spec["repeats"], "tol": spec["tol"], "shift": spec["shift"],
            "cases": cases}


def _report_warm_floor(rep: Report, floor: dict) -> None:
    i, j = floor["size"]
    rep.section(f"The floor of a warm start at (i, j) = ({i}, {j}): resumed from the new problem's own centres")
    rep.text(
        f"The window advanced by {floor['shift']} samples, solved cold, then re-solved from each of its own centred "
        "points (`solvers.run(\"column_barrier\", ..., warm_start=centre)`): an oracle no warm start has, since it "
        "needs the new problem's path. A warm start that re-enters the path at gap g costs at least the row at g. "
        f"`warm/cold` = median wall of the resumed solve / the cold solve's ({floor['repeats']} repeat(s), "
        f"`workers=1`, tol {floor['tol']:g}); `δ move` = δ of the advanced window / δ of the first − 1, the way a warm "
        "start from the first window has to go. `certified gap`: the resumed solve's, both bounds recomputed from the "
        "data; `overlap`: its bracket meets the cold solve's (the same δ)."
    )
    rows = []
    for c in floor["cases"]:
        if "rows" not in c:
            rows.append([c.get("label"), c.get("status"), *[""] * 8])
            continue
        mode = "L fixed" if c["L_fixed"] else "L optimised"
        move = f"{c['delta_new'] / c['delta_old'] - 1:+.1%}"
        for r in c["rows"]:
            rows.append([mode, move, r["gap"], r["ratio"], _count(r["newton"]), _count(c["cold_newton"]),
                         f"{r['status']} / {r['used']}", r["certified_gap"], r["overlap"],
                         f"{c['load'][0]:.1f} → {c['load'][1]:.1f}"])
    rep.table(["L", "δ move", "resumed at gap", "warm/cold", "Newton", "cold Newton", "status / resumed",
               "certified gap", "overlap", "load"], rows, floatfmt=".3g")


def _label(spec: dict, size: int) -> str:
    return f"n={size}" if spec["kind"] == "arx" else f"(i, j)=({spec['i']}, {size})"


def _context():
    """A fork server: children are forked from a clean single-threaded process, never from this one.

    Forking a parent that already runs threads (BLAS pools, solver threads, tqdm's monitor) can
    leave a child waiting forever on a lock held by a thread that did not survive the fork:
    measured here as a Clarabel solve of 0.3 s timing out at 30 s inside the test suite.
    """
    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(["numpy", "scipy.linalg", "cvxpy", "unfalsify"])
    return ctx


def _run_with_budget(spec: dict, size, seed: int, budget: float, worker=None, label=None) -> dict:
    ctx = _context()
    parent, child = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(child, spec, size, seed, worker))
    t0 = time.perf_counter()
    proc.start()
    child.close()
    label = label or _label(spec, size)
    ready = parent.poll(budget)
    elapsed = time.perf_counter() - t0
    if not ready:
        proc.terminate()
        proc.join(5)
        if proc.is_alive():  # pragma: no cover
            proc.kill()
            proc.join()
        return {"size": size, "label": label, "status": f"timeout (> {budget:.0f} s)", "wall_s": elapsed}
    kind, payload = parent.recv()
    proc.join()
    if kind == "error":
        return {"size": size, "label": label, "status": "error", "error": payload, "wall_s": elapsed}
    return payload


def _run_cvxpy(opts, rep: Report) -> dict:
    """The cvxpy series (both forms, growing size); adds its sections to ``rep``."""
    budget = QUICK_BUDGET_S if opts.quick else BUDGET_S
    results = []
    # rewritten after every solve: an interrupted run keeps the rows it finished
    live = LiveTable(opts.out, "bench_unfalsify", "Chapter 7 unfalsification LMIs: solve time vs size (partial)",
                     ["series", "size", "status", "δ", "wall [s]"])
    for spec in _series(opts.quick):
        rows = []
        for size in tqdm(spec["sizes"], desc=f"bench-unfalsify: {spec['name']}", leave=False):
            row = _run_with_budget(spec, size, opts.seed, budget)
            rows.append(row)
            live.add([spec["name"], row.get("label", size), row.get("status"), row.get("delta", float("nan")),
                      row.get("wall_s", float("nan"))], record=dict(row, series=spec["name"]))
            tqdm.write(f"[bench-unfalsify] {spec['name']}: size {size}: {row.get('status')} "
                       f"{row.get('wall_s', float('nan')):.2f} s", file=sys.stderr)
            if row.get("status", "").startswith("timeout") or row.get("wall_s", 0.0) > budget or row.get("status") == "error":
                break
        finished = [r for r in rows if "delta" in r and r["wall_s"] <= budget]
        results.append({
            "series": spec["name"],
            "kind": spec["kind"],
            "form": spec["form"],
            "eliminate_L": bool(spec.get("eliminate", False)),
            "horizon": spec.get("i"),
            "rows": rows,
            "largest_within_budget": finished[-1]["size"] if finished else None,
        })

    rep.section("cvxpy backend (Clarabel)")
    rep.text(
        f"Each solve in a child process with a {budget:.0f} s budget (a series stops at the first solve over it). "
        "`wall` includes cvxpy compilation and the certificate. `δ_cert` is recomputed from the returned variables "
        "(max ‖T(h_k)‖₂, exact rational deconvolution for the literal form); `viol` = max(δ_cert − δ, rms(ξ) − σ)."
    )
    rep.text(f"Earlier measurements on the same machine class (Clarabel): {EARLIER_TIMINGS}")
    headers = ["series", "size", "status", "δ", "δ_cert", "viol", "wall [s]", "solver [s]", "iters", "cond T(u)"]
    table_rows = []
    for s in results:
        for r in s["rows"]:
            table_rows.append([
                s["series"], r.get("label", r["size"]), r["status"], r.get("delta", float("nan")),
                r.get("delta_certified", float("nan")), r.get("max_violation", float("nan")), r["wall_s"],
                r.get("solver_s", float("nan")), r.get("iterations", ""), r.get("cond_Tu", float("nan")),
            ])
    rep.section("Results")
    rep.table(headers, table_rows)
    rep.section("Largest size within budget")
    rep.table(["series", "largest size"], [[s["series"], s["largest_within_budget"]] for s in results])
    return {"series": results, "budget_s": budget}


def _fit_exponent(rows: list[dict]) -> float:
    """Least-squares slope of log(wall) against log(size) over the certified rows (NaN with < 2)."""
    pts = [(r["size"], r["wall_s"]) for r in rows if r.get("status") == "optimal" and r.get("wall_s", 0) > 0]
    if len(pts) < 2:
        return float("nan")
    x, t = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    return float(np.polyfit(x, t, 1)[0])


def _plot_scaling(series: list[dict], path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..lab.report import save_figure

    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for s in series:
        rows = [r for r in s["rows"] if "wall_s" in r and "upper" in r]
        if not rows:
            continue
        x = [r["size"] for r in rows]
        t = [r["wall_s"] for r in rows]
        ex = s["exponent"]
        lab = s["series"] + (f" (slope {ex:.2f})" if np.isfinite(ex) else "")
        line, = ax.loglog(x, t, "o-", label=lab)
        for r in rows:
            if r["status"] != "optimal":
                ax.annotate(r["status"], (r["size"], r["wall_s"]), fontsize=7, color=line.get_color())
    ax.set_xlabel("unknowns (ARX: n; subspace: i·j)")
    ax.set_ylabel("wall time [s]")
    ax.set_title("structured backend: time vs size")
    ax.grid(True, which="both", alpha=0.3)
    if ax.get_legend_handles_labels()[0]:  # none with --series warm (the warm-start table alone)
        ax.legend(fontsize=8)
    save_figure(fig, path)


def _compare_arx(opts, limit: float) -> dict:
    """ARX: the structured backend against cvxpy/Clarabel on the same data, in the same run."""
    n_cmp = 20 if opts.quick else 80
    cmp_budget = QUICK_BUDGET_S if opts.quick else ARX_CLARABEL_BUDGET_S
    c_row = _run_with_budget(dict(kind="arx", form="conditioned"), n_cmp, opts.seed, cmp_budget)
    s_row = _run_with_budget(dict(kind="arx", tol=1e-7, limit=limit), n_cmp, opts.seed, limit + 120.0,
                             worker=_solve_structured_one, label=f"n={n_cmp}")
    comparison = {"n": n_cmp, "cvxpy": c_row, "structured": s_row, "budget_s": cmp_budget}
    if "delta" in c_row and "delta" in s_row:
        comparison["delta_difference"] = abs(c_row["delta"] - s_row["delta"])
        comparison["speed_ratio"] = c_row["wall_s"] / s_row["wall_s"]
    return comparison


def _report_comparison(rep: Report, comparison: dict) -> None:
    c_row, s_row = comparison["cvxpy"], comparison["structured"]
    rep.section(f"ARX n = {comparison['n']}: structured against cvxpy/Clarabel, same data, same run")
    cmp_rows = []
    for name, r in (("cvxpy (Clarabel)", c_row), ("structured (tol 1e-7)", s_row)):
        cmp_rows.append([name, r.get("status"), r.get("delta", float("nan")), r["wall_s"]])
    rep.table(["backend", "status", "δ", "wall [s]"], cmp_rows, floatfmt=".8g")
    rep.text(f"Clarabel's child budget: {comparison['budget_s']:.0f} s; wall = the `arx_unfalsify` call (model, "
             "solve, certificate).")
    if "speed_ratio" in comparison:
        rep.text(f"|δ_cvxpy − δ_structured| = {comparison['delta_difference']:.2e} "
                 f"(relative {comparison['delta_difference'] / abs(c_row['delta']):.1e}); "
                 f"speed ratio cvxpy/structured = {comparison['speed_ratio']:.0f}×.")


def _run_structured(opts, rep: Report) -> dict:
    """The structured series, the ARX cvxpy comparison, CSV and scaling plot; adds sections to ``rep``."""
    limit = QUICK_STRUCTURED_LIMIT_S if opts.quick else STRUCTURED_LIMIT_S
    series = []
    only = (getattr(opts, "extra", None) or {}).get("series") or "all"
    load_before = os.getloadavg()
    repeats = _structured_repeats(opts)
    rev = (getattr(opts, "extra", None) or {}).get("baseline_rev")
    tree = str(export_revision(rev)) if rev else None
    for spec in _structured_series(opts.quick):
        if only != "all" and spec["kind"] != only:
            continue  # (--series warm / warm-floor / arx-pd / subspace-pd: that table alone)
        base = limit if opts.quick else spec.get("limit_s", limit)
        rows = []
        for size in tqdm(spec["sizes"], desc=f"bench-unfalsify: {spec['name']}", leave=False):
            spec = dict(spec, limit=spec.get("limits", {}).get(size, base), repeats=repeats, baseline_tree=tree,
                        baseline_rev=rev)
            # the front end's solve, then repeats × (today's route, the former route), each up to the limit
            row_budget = spec["limit"] * (1 + 2 * repeats) + 120.0
            row = _run_with_budget(spec, size, opts.seed, row_budget, worker=_solve_structured_one,
                                   label=_structured_label(spec, size))
            rows.append(row)
            tqdm.write(f"[bench-unfalsify] {spec['name']}: {row['label']}: {row.get('status')} "
                       f"{row.get('wall_s', float('nan')):.2f} s, gap {row.get('relative_gap', float('nan')):.2g}",
                       file=sys.stderr)
        series.append({"series": spec["name"], "kind": spec["kind"], "L_fixed": spec.get("fixed"), "tol": spec["tol"],
                       "rows": rows, "exponent": _fit_exponent(rows)})
    load_after = os.getloadavg()
    if tree is not None:
        import shutil

        shutil.rmtree(tree, ignore_errors=True)

    comparison = None if only in ("subspace", "warm", "warm-floor", "arx-pd", "subspace-pd") \
        else _compare_arx(opts, limit)
    warm = _run_warm(opts) if only in ("all", "warm") else None
    floor = _run_warm_floor(opts) if only in ("all", "warm-floor") else None
    pd = _run_pd(opts, "arx") if only in ("all", "arx-pd") else None
    subspace_pd = _run_pd(opts, "subspace") if only in ("all", "subspace-pd") else None

    rep.section("Structured backend")
    rep.text(
        f"`backend=\"structured\"` (Toeplitz-structured barrier methods: ARX solver `arx_barrier`, subspace "
        f"`column_barrier`, in `unfalsify.solvers`), each solve in a child process with "
        f"`time_limit={limit:.0f}` s (ARX "
        f"n = 1000: {ARX_1000_LIMIT_S:.0f} s; subspace rows: {limit if opts.quick else SUBSPACE_LIMIT_S:.0f} s) "
        "(then the best certified bracket is returned). The ARX n = 10⁴ row "
        f"(limit {ARX_10K_LIMIT_S:.0f} s) has the front end's solve only (`solve [s]` is its solver time), and ARX "
        f"rows above n = {ARX_BASELINE_UPTO} no former route. The bracket row (`method=\"bracket\"`, solver "
        "`bracket`, FFT only, `--quick` only) reports a certified bracket whose gap is not driven to a tolerance. "
        "`lower`, "
        "`upper` are the certificate's bounds recomputed from the data and the returned primal/dual points; "
        "`verify` re-checks them; `gap` = (upper − lower)/upper. Subspace: σ = ½ × rms residual of the "
        "least-squares predictor (`synthesis.fit_predictor`), which is also the fixed L. Peak RSS is that of "
        "the child process (it starts at `RSS₀`: the interpreter with numpy/scipy/cvxpy loaded), over all the "
        "row's solves (one problem size)."
    )
    rep.text(
        f"`solve [s]`: the registry solver alone (`unfalsify.solvers.run`; subspace: `workers=None`, as the front end), "
        f"median of {repeats} repeat(s); `wall [s]`: "
        "the first, front-end call (problem set-up, solve, certificate). `baseline [s]`: the same solver on the same "
        "problem by the former route (`unfalsify.solvers.baselines.former_routes`: FFT Hessian, and arx_barrier's "
        "step algebra), alternating with "
        "today's route in the same child, median; `×` = baseline/solve; `|Δδ|/δ` between the two routes (blank: "
        "the route has no FFT Hessian, so no former route). `limit [s]` = the flops the method needs at its "
        "measured Newton steps and trial factorisations (module docstring) / the matmul rate `GF/s` timed in the "
        "same child on a product of the row's size; `ratio` = solve / limit. `load`: 1-min load average at the "
        f"row's start → end. Table load: {load_before[0]:.2f} → {load_after[0]:.2f} (1-min), "
        f"{load_before[1]:.2f} → {load_after[1]:.2f} (5-min); {os.cpu_count()} CPU(s)."
    )
    if rev:
        rep.text(
            f"`rev [s]`: the same problem solved by the code of git revision `{rev}` (`--baseline-rev`, exported with "
            "`git archive`; its own front end in a subprocess, its solver time), alternating with today's route in "
            "the same run, median; `× rev` = rev/solve; `Newton rev` its Newton steps (blank where that revision "
            "did not report them)."
        )
    headers = ["series", "size", "status", "lower", "upper", "gap", "tol", "verify", "wall [s]", "solve [s]",
               "baseline [s]", "×", "|Δδ|/δ", "Newton", "trial fact.", "GF/s", "limit [s]", "ratio",
               "peak RSS [MB]", "RSS₀ [MB]", "load"] + (["rev [s]", "× rev", "Newton rev", "|Δδ|/δ rev"] if rev else [])
    rows_md, rows_csv = [], []
    for s in series:
        for r in s["rows"]:
            speed = r["baseline_s"] / r["solve_s"] if r.get("baseline_s") else None
            load = f"{r['load'][0]:.1f} → {r['load'][1]:.1f}" if "load" in r else ""
            vals = [r.get("status"), r.get("lower", float("nan")), r.get("upper", float("nan")),
                    r.get("relative_gap", float("nan")), s["tol"], r.get("verify", ""), r["wall_s"],
                    r.get("solve_s", float("nan")), _fmt(r.get("baseline_s")), _fmt(speed, ".2f"),
                    _fmt(r.get("baseline_delta_rel"), ".1e"), _count(r.get("newton")), _count(r.get("trials")),
                    _fmt(r.get("matmul_gflops"), ".1f"), _fmt(r.get("limit_s")), _fmt(r.get("limit_ratio"), ".1f"),
                    r.get("peak_rss_mb", float("nan")), r.get("rss_start_mb", float("nan")), load]
            if rev:
                vs_rev = r["revision_s"] / r["solve_s"] if r.get("revision_s") else None
                vals += [_fmt(r.get("revision_s")), _fmt(vs_rev, ".2f"), _count(r.get("revision_newton")),
                         _fmt(r.get("revision_delta_rel"), ".1e")]
            rows_md.append([s["series"], r["label"], *vals])
            rows_csv.append([s["series"], r["label"], r.get("size"), r.get("n_samples"), *vals[:19],
                             r.get("delta", float("nan")), r.get("error", ""), *vals[19:]])
    rep.table(headers, rows_md)
    rep.section("Fitted exponents (wall ∝ size^p over the certified rows)")
    rep.table(["series", "p"], [[s["series"], s["exponent"]] for s in series], floatfmt=".2f")
    if comparison is not None:
        _report_comparison(rep, comparison)
    if warm is not None:
        _report_warm(rep, warm)
    if floor is not None:
        _report_warm_floor(rep, floor)
    if pd is not None:
        _report_pd(rep, pd)
    if subspace_pd is not None:
        _report_pd(rep, subspace_pd)
    csv_path = opts.out / "bench_unfalsify_structured.csv"
    opts.out.mkdir(parents=True, exist_ok=True)
    with csv_path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["series", "label", "unknowns", "n_samples", "status", "lower", "upper", "relative_gap", "tol",
                    "verify", "wall_s", "solve_s", "baseline_s", "speedup", "baseline_delta_rel", "newton", "trials",
                    "matmul_gflops", "limit_s", "limit_ratio", "peak_rss_mb", "rss_start_mb", "load", "delta",
                    "error"] + (["revision_s", "speedup_vs_revision", "revision_newton", "revision_delta_rel"]
                                if rev else []))
        w.writerows(rows_csv)
    png = opts.out / "bench_unfalsify_scaling.png"
    _plot_scaling(series, png)
    rep.figure(png, "Structured backend: wall time against size (log-log), fitted slopes in the legend")
    return {"series": series, "baseline_rev": rev, "comparison": comparison, "warm": warm, "warm_floor": floor,
            "primal_dual": pd,
            "subspace_primal_dual": subspace_pd, "time_limit_s": limit,
            "csv": csv_path.name,
            "figure": png.name, "repeats": repeats, "load": {"before": list(load_before), "after": list(load_after)}}


def run(opts) -> dict:
    """Run the benchmark; write ``bench_unfalsify.md`` / ``.json`` (and, for the structured backend, ``.csv`` and
    the scaling PNG) under ``opts.out``; return the summary.

    ``opts.extra["backend"]`` (``--backend``): ``"cvxpy"`` (default), ``"structured"`` or ``"both"``.
    """
    backend = (getattr(opts, "extra", None) or {}).get("backend") or "cvxpy"
    if backend not in ("cvxpy", "structured", "both"):
        raise ValueError(f"unknown backend {backend!r}; use 'cvxpy', 'structured' or 'both'")
    rep = Report("Chapter 7 unfalsification LMIs: solve time vs size")
    rep.text(
        f"Servo data (§5.4 noise), seed {opts.seed}; σ = ½ × least-squares residual rms. "
        f"{os.cpu_count()} CPU(s) visible, shared. Backend(s): {backend}."
        + (" **Quick mode: tiny sizes, numbers not meaningful.**" if opts.quick else "")
    )
    summary: dict = {"backend": backend, "quick": opts.quick, "seed": opts.seed}
    if backend in ("cvxpy", "both"):
        summary.update(_run_cvxpy(opts, rep))
    if backend in ("structured", "both"):
        summary["structured"] = _run_structured(opts, rep)
    opts.out.mkdir(parents=True, exist_ok=True)
    md = rep.write(opts.out / "bench_unfalsify.md")
    summary["report"] = str(md)
    write_json(opts.out / "bench_unfalsify.json", summary)
    print(md.read_text())
    return summary
