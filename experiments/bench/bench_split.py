"""Benchmark: the column split of (7.5) (predictor fixed) on 1 and N local workers, against the serial solve.

Data: the §5.4 servo, PRBS ±1 with process and sensor noise σ = 0.05, the least-squares predictor of
horizon i on the whole record, σ = 0.05 in (7.5).  The same split runs on an executor of one worker
process and of ``--workers`` (default 2) processes (:func:`experiments.studies.sweep.make_executor`: Dask
``LocalCluster`` when installed, else ``ProcessPoolExecutor``; one BLAS thread per worker); the
serial reference is :func:`unfalsify.subspace_unfalsify` without an executor (cvxpy/Clarabel).  The
workers are started before the clock starts.  Full size (i, j) = (20, 400); ``--quick`` (6, 40).
"""
from __future__ import annotations

import time
from pathlib import Path

import synthesis
import unfalsify as uf

from ..lab.plants import servo
from ..lab.report import Report, finish_report
from ..lab.signals import prbs
from ..lab.simulate import collect_data
from ..studies.sweep import make_executor

__all__ = ["run"]


def _data(i: int, j: int, seed: int):
    n = 2 * i + j - 1
    d = collect_data(servo(), prbs(max(n, 1000), seed=seed), process_noise=0.05, sensor_noise=0.05, seed=seed + 100)
    pred = synthesis.fit_predictor(d.u[:, 0], d.y[:, 0], i)
    return d.u[:n, 0], d.y[:n, 0], pred


def _warm(ex, n: int) -> None:
    """Start every worker (and import numpy there) before timing."""
    for f in [ex.submit(_noop, k) for k in range(4 * n)]:
        f.result()


def _noop(k):
    import numpy  # noqa: F401

    return k


def run(opts) -> dict:
    """Time the split on 1 and N workers; check δ and the certificate against the serial solve."""
    i, j = (6, 40) if opts.quick else (20, 400)
    n_workers = int((getattr(opts, "extra", {}) or {}).get("workers") or 2)
    out = Path(opts.out)
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    u, y, pred = _data(i, j, opts.seed)
    sigma = 0.05
    t0 = time.perf_counter()
    ref = uf.subspace_unfalsify(u, y, i, sigma, predictor=pred)
    t_serial = time.perf_counter() - t0
    rows, res = [], {}
    for w in (1, n_workers):
        with make_executor(w) as (ex, info):
            _warm(ex, w)
            t0 = time.perf_counter()
            r = uf.subspace_unfalsify(u, y, i, sigma, predictor=pred, executor=ex)
            res[w] = dict(seconds=time.perf_counter() - t0, delta=r.delta, executor=info,
                          upper=r.certificate.upper_bound, lower=r.certificate.lower_bound,
                          verified=r.certificate.verify())
        rows.append([f"split, {w} worker(s) ({info['kind']})", res[w]["seconds"], r.delta,
                     res[w]["lower"], res[w]["verified"]])
    rows.insert(0, ["serial (cvxpy/Clarabel)", t_serial, ref.delta, ref.certificate.lower_bound,
                    ref.certificate.verify()])
    speedup = res[1]["seconds"] / res[n_workers]["seconds"]
    rel = abs(res[n_workers]["delta"] - ref.delta) / ref.delta
    rep = Report("Column split of (7.5) on local workers")
    rep.text(__doc__.split("\n\n", 1)[1].replace("\n", " "))
    rep.table(["solve", "seconds", "δ", "certified lower bound", "certificate verifies"], rows, floatfmt=".9g")
    rep.section("Result", f"(i, j) = ({i}, {j}): speed-up {speedup:.2f}× on {n_workers} workers over 1; "
                          f"|δ_split − δ_serial|/δ_serial = {rel:.2e}; δ identical on 1 and {n_workers} workers: "
                          f"{res[1]['delta'] == res[n_workers]['delta']}.")
    summary = {"i": i, "j": j, "serial_seconds": t_serial, "serial_delta": ref.delta, "split": res,
               "speedup": speedup, "relative_difference": rel}
    return finish_report(rep, summary, out, "bench_split", t_start=t_start)
