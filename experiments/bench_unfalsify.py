"""Benchmark: Chapter 7 unfalsification LMIs -- solve time and status against problem size.

``python -m experiments bench-unfalsify [--quick] [--out DIR]`` writes
``<out>/bench_unfalsify.md`` and ``<out>/bench_unfalsify.json``.

Series (servo data of §5.4: PRBS ±1, process and sensor noise σ = 0.05; σ of the program =
half the least-squares residual rms so that δ > 0):

* ARX (7.4), na = nb = 2, ``form="conditioned"`` and ``form="thesis"``, growing n;
* subspace (7.5), ``form="conditioned"`` (L optimised, and L eliminated analytically) and
  ``form="thesis"``, growing j at fixed i.

Each solve runs in a child process with a wall-clock budget (120 s; 30 s with ``--quick``);
a series stops growing at the first solve that exceeds it (recorded as ``timeout``).  Every
row carries the solver status, δ, the independent certificate (``δ_certified`` recomputed from
the returned variables, ``max_violation``) and cond T(u).  Clarabel, explicitly.
"""
from __future__ import annotations

import multiprocessing as mp
import os
import sys
import time
import warnings

import numpy as np
from tqdm import tqdm

from .report import LiveTable, Report, write_json

__all__ = ["run"]

BUDGET_S = 120.0
QUICK_BUDGET_S = 30.0

#: earlier measurements on this 2-core machine class (Clarabel 0.11, cvxpy 1.9), for comparison
EARLIER_TIMINGS = "ARX conditioned n = 20 → 0.2 s, 40 → 3.2 s, 80 → 78 s, 100 → 138 s; subspace (10, 200) → 5.9 s, (20, 400) → 97 s."


def _series(quick: bool) -> list[dict]:
    if quick:
        return [
            dict(name="ARX conditioned", kind="arx", form="conditioned", sizes=[8, 12]),
            dict(name="ARX thesis", kind="arx", form="thesis", sizes=[8, 12]),
            dict(name="subspace conditioned i=3", kind="subspace", form="conditioned", i=3, sizes=[12, 16]),
            dict(name="subspace conditioned, L eliminated, i=3", kind="subspace", form="conditioned", eliminate=True,
                 i=3, sizes=[12, 16]),
            dict(name="subspace thesis i=3", kind="subspace", form="thesis", i=3, sizes=[12, 16]),
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
    ]


def _data(n: int, seed: int):
    from ._servo import servo_data

    d = servo_data(n, seed=seed)
    return d.u, d.y


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
        u, y = _data(n, seed)
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


def _child(conn, spec, size, seed):
    try:
        conn.send(("ok", _solve_one(spec, size, seed)))
    except Exception as exc:  # reported in the table, not raised
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
    finally:
        conn.close()


def _label(spec: dict, size: int) -> str:
    return f"n={size}" if spec["kind"] == "arx" else f"(i, j)=({spec['i']}, {size})"


def _run_with_budget(spec: dict, size: int, seed: int, budget: float) -> dict:
    ctx = mp.get_context("fork")
    parent, child = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(child, spec, size, seed))
    t0 = time.perf_counter()
    proc.start()
    child.close()
    ready = parent.poll(budget)
    elapsed = time.perf_counter() - t0
    if not ready:
        proc.terminate()
        proc.join(5)
        if proc.is_alive():  # pragma: no cover
            proc.kill()
            proc.join()
        return {"size": size, "label": _label(spec, size), "status": f"timeout (> {budget:.0f} s)", "wall_s": elapsed}
    kind, payload = parent.recv()
    proc.join()
    if kind == "error":
        return {"size": size, "label": _label(spec, size), "status": "error", "error": payload, "wall_s": elapsed}
    return payload


def run(opts) -> dict:
    """Run the benchmark; write ``bench_unfalsify.md`` / ``.json`` under ``opts.out``; return the summary."""
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

    rep = Report("Chapter 7 unfalsification LMIs: solve time vs size")
    rep.text(
        f"Servo data (§5.4 noise), seed {opts.seed}; σ = ½ × least-squares residual rms; Clarabel; each solve in a "
        f"child process with a {budget:.0f} s budget (a series stops at the first solve over it). "
        "`wall` includes cvxpy compilation and the certificate. `δ_cert` is recomputed from the returned variables "
        "(max ‖T(h_k)‖₂, exact rational deconvolution for the literal form); `viol` = max(δ_cert − δ, rms(ξ) − σ). "
        f"{os.cpu_count()} CPU(s) visible, shared."
        + (" **Quick mode: tiny sizes, numbers not meaningful.**" if opts.quick else "")
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
    opts.out.mkdir(parents=True, exist_ok=True)
    md = rep.write(opts.out / "bench_unfalsify.md")
    summary = {"series": results, "budget_s": budget, "quick": opts.quick, "seed": opts.seed, "report": str(md)}
    write_json(opts.out / "bench_unfalsify.json", summary)
    print(md.read_text())
    return summary
