"""Benchmark: certified H∞ norms (synthesis.hinf_norm) and SLICOT simulation vs the former routes.

``python -m experiments bench-norms [--quick] [--out DIR]`` prints and writes
``<out>/bench_norms/bench_norms.md``, ``.json`` and ``.csv``.  Each row times the new and the
former route in the same run (median of repeats) and compares their results:

* ``additive_robustness`` on the §6.2 three-disk (y3) subspace design at i = 64 (closed loop of
  order ~136): certified bracket (:func:`synthesis.hinf_norm`) vs the former dense grid
  (:func:`synthesis.peak_gain`, 4096 points); target ≥ 20× faster;
* ``discrete_mixsyn`` on the three-disk (y3) with the §6.2 weights: levels decided by
  :func:`synthesis.norm_below` vs by the grid; target ≥ 8× faster and the same ``gamma_opt``;
* ``collect_data`` with 1e5 samples: SLICOT TF01MD vs the Python loop; target ≥ 15× faster and
  equal to 1e-12.

Quick mode (for the tests) uses the servo, i = 8 and 2000 samples: its numbers are not meaningful.
Run with ``OPENBLAS_NUM_THREADS=1`` (recorded in the output) for stable timings on a shared machine.
"""
from __future__ import annotations

import os

import numpy as np

from ..lab.report import Report, format_table, median_time, save_figure, write_csv, write_json

__all__ = ["run"]

TARGETS = {"additive_robustness": 20.0, "discrete_mixsyn": 8.0, "collect_data": 15.0}


def _old_additive(plant, controller):
    """The former ``additive_robustness``: poles by ``eigvals`` and the grid peak (4096 points)."""
    from synthesis import peak_gain
    from unfalsify import additive_channel

    M = additive_channel(plant, controller)
    rho = float(np.max(np.abs(np.linalg.eigvals(np.asarray(M.A, float)))))
    return rho, (peak_gain(M, n_grid=4096) if rho < 1 else float("inf")), M.nstates


def _setup(quick: bool, seed: int):
    import synthesis

    from ..lab import plants, signals, simulate
    from ..lab.plants import THREE_DISK_DT as DT
    from ..lab.torsional_setup import NONCOLLOCATED

    rng = np.random.default_rng(seed)
    if quick:
        P = plants.servo()
        dt = float(P.dt)
        s = __import__("control").tf("s")
        W1 = synthesis.tustin(100 * (0.01 / 5) * (s + 5) / (s + 0.01), dt)
        W2 = synthesis.tustin(0.05 * (10 / 0.5) * (s + 0.5) / (s + 10), dt)
        i, n = 20, 1000
    else:
        P = plants.three_disk("y3", dt=DT)
        W1, W2 = NONCOLLOCATED.discrete(DT)
        i, n = 64, 2048
    u = signals.prbs(n, 10 if not quick else 7, amplitude=1.0)[:n]
    data = simulate.collect_data(P, u, process_noise=0.05, sensor_noise=0.01, seed=int(rng.integers(2**31)))
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        design = synthesis.hinf_design(synthesis.fit_predictor(data.u, data.y, i), W1, W2, gamma_ratio=1.35)
    return P, W1, W2, i, design.controller


def _row(case, size, t_old, t_new, old, new, agree, target, ok_extra=True):
    ratio = t_old / t_new if t_new > 0 else float("inf")
    return {"case": case, "size": size, "old_s": t_old, "new_s": t_new, "speedup": ratio, "old": old, "new": new,
            "agreement": agree, "target": target, "met": bool(ratio >= target and ok_extra)}


def _figure(rows, path):
    """Bar chart of speed-ups (log scale) with each target marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 3.2))
    x = range(len(rows))
    ax.bar(x, [r["speedup"] for r in rows], color=["tab:green" if r["met"] else "tab:red" for r in rows],
           label="measured speed-up")
    ax.scatter(x, [r["target"] for r in rows], marker="_", s=900, color="k", zorder=3, label="target")
    ax.set_xticks(list(x), [r["case"] for r in rows])
    ax.set_yscale("log")
    ax.set_ylabel("speed-up (former time / new time)")
    ax.set_xlabel("routine")
    ax.legend()
    return save_figure(fig, path)


def run(opts) -> dict:
    """Run the benchmark; write ``bench_norms.md`` / ``.json`` / ``.csv`` under ``opts.out``; return the summary."""
    import synthesis
    from synthesis.baselines import discrete_mixsyn_grid
    from unfalsify import additive_robustness

    from ..lab import simulate

    quick = bool(opts.quick)
    reps_slow, reps_fast = (1, 1) if quick else (3, 7)
    P, W1, W2, i, K = _setup(quick, opts.seed)
    rows = []

    # 1. additive_robustness (small-gain certificate of §7.4)
    rob = additive_robustness(P, K)
    rho_old, peak_old, order = _old_additive(P, K)
    t_old = median_time(lambda: _old_additive(P, K), repeats=reps_slow)
    t_new = median_time(lambda: additive_robustness(P, K), repeats=reps_fast)
    br = rob.bracket
    inside = bool(br.lower * (1 - 1e-9) <= peak_old <= br.upper) if np.isfinite(br.upper) else not np.isfinite(peak_old)
    rows.append(_row("additive_robustness", f"i={i}, loop order {order}", t_old, t_new,
                     f"grid peak {peak_old:.10g}", f"bracket {br}", f"grid peak inside bracket: {inside}",
                     TARGETS["additive_robustness"], inside))

    # 2. discrete_mixsyn: level checks
    kw = dict(gamma_ratio=1.1 if quick else 1.35)
    res_new = synthesis.discrete_mixsyn(P, W1, W2, **kw)
    res_old = discrete_mixsyn_grid(P, W1, W2, **kw)
    t_old = median_time(lambda: discrete_mixsyn_grid(P, W1, W2, **kw), repeats=reps_slow)
    t_new = median_time(lambda: synthesis.discrete_mixsyn(P, W1, W2, **kw), repeats=reps_fast)
    same = res_old.gamma_opt == res_new.gamma_opt
    rows.append(_row("discrete_mixsyn", f"{'servo' if quick else 'three-disk y3'}, closed-loop order "
                     f"{res_new.closed_loop.nstates}", t_old, t_new,
                     f"gamma_opt {res_old.gamma_opt:.10g}, grid norm {res_old.norm:.10g}",
                     f"gamma_opt {res_new.gamma_opt:.10g}, bracket {res_new.bracket}",
                     f"same gamma_opt: {same}", TARGETS["discrete_mixsyn"], same))

    # 3. collect_data: TF01MD vs the Python loop
    n = 2000 if quick else 100_000
    u = np.random.default_rng(opts.seed).standard_normal((n, P.ninputs))
    A, B, C, D = (np.asarray(M, float) for M in (P.A, P.B, P.C, P.D))
    x0 = np.zeros(A.shape[0])
    y_new = simulate.collect_data(P, u).y
    y_old, _ = simulate.lsim(A, B, C, D, u, x0, route="loop")
    diff = float(np.max(np.abs(y_new - y_old)) / max(np.max(np.abs(y_old)), 1e-300))
    t_old = median_time(lambda: simulate.lsim(A, B, C, D, u, x0, route="loop"), repeats=reps_slow)
    t_new = median_time(lambda: simulate.collect_data(P, u), repeats=reps_fast)
    rows.append(_row("collect_data", f"{n} samples, plant order {A.shape[0]}", t_old, t_new, "Python loop",
                     "SLICOT TF01MD", f"max rel diff {diff:.2e}", TARGETS["collect_data"], diff <= 1e-12))

    headers = ["case", "size", "old [s]", "new [s]", "speedup", "target", "met", "old result", "new result", "check"]
    table = [[r["case"], r["size"], r["old_s"], r["new_s"], r["speedup"], r["target"], r["met"], r["old"], r["new"],
              r["agreement"]] for r in rows]
    threads = os.environ.get("OPENBLAS_NUM_THREADS", "unset")
    rep = Report("Certified H∞ norms and SLICOT simulation: new vs former routes")
    rep.text(f"Median of {reps_fast} (new) / {reps_slow} (old) repeats in the same run; seed {opts.seed}; "
             f"BLAS threads: OPENBLAS_NUM_THREADS={threads}."
             + (" **Quick mode: tiny sizes, numbers not meaningful.**" if quick else ""))
    rep.text("`old`: dense frequency grid (`peak_gain`, a lower bound) and the Python simulation loop; "
             "`new`: `hinf_norm` / `norm_below` (bracket with a proven upper side) and `slycot.tf01md`.")
    rep.text(format_table(headers, table, floatfmt=".4g"))
    out = opts.out
    fig_path = _figure(rows, out / "bench_norms_speedup.png")
    rep.figure(fig_path, "Speed-up of the new routes over the former ones (log scale), with the targets")
    print("\n".join(rep.parts))
    md = rep.write(out / "bench_norms.md")
    write_csv(out / "bench_norms.csv", headers, table)
    summary = {"quick": quick, "blas_threads": threads, "targets": TARGETS, "rows": rows,
               "all_met": all(r["met"] for r in rows), "report": str(md)}
    write_json(out / "bench_norms.json", summary)
    return summary
