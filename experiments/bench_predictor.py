"""Benchmark: QR vs Cholesky subspace predictor (thesis §2.2–2.3, Table 2.1) and recursive updates (§2.3.1).

``python -m experiments bench-predictor [--quick] [--out DIR]`` prints and writes
``<out>/bench_predictor.md`` and ``<out>/bench_predictor.json``:

* wall time (median of repeats, same run) of ``fit_predictor(method="qr")`` and
  ``fit_predictor(method="cholesky")`` at (i, j) = (20, 1000) (Table 2.1), (64, 2048) (§6.2) and
  (20, 100000), with the ratio qr/cholesky and the largest relative difference of ``[Lw Lu]``;
* peak traced memory (tracemalloc) of each method at the largest size;
* :class:`synthesis.RecursivePredictor` at i = 64: time per pushed sample (growing and sliding
  window, both summaries) and ``predictor()`` time, for j = 1000 and 20000 columns of history.

SISO data (m = l = 1) as in the thesis: white-noise input through a lightly damped second-order
plant plus white sensor noise.  Targets: cholesky ≥ 3× faster than qr at (64, 2048) and ≥ 10× at
(20, 100000); push < 5 ms at i = 64, flat in j.

On a shared, busy machine multi-threaded BLAS makes timings erratic (threads spin while waiting
for cores); run with ``OPENBLAS_NUM_THREADS=1`` (recorded in the output) for stable numbers.
"""
from __future__ import annotations

import os
import time
import tracemalloc
import warnings

import numpy as np
from scipy.signal import lfilter
from tqdm import tqdm

from synthesis import PersistenceWarning, RecursivePredictor, fit_predictor

from .report import Report, format_table, median_time, write_json

__all__ = ["run"]

TARGETS = {"speedup_64_2048": 3.0, "speedup_20_100000": 10.0, "push_ms_i64": 5.0}


def _siso_data(n: int, rng) -> tuple[np.ndarray, np.ndarray]:
    u = rng.standard_normal(n)
    # lightly damped resonance (poles 0.95 e^{±0.3j}) with a one-step delay
    r, th = 0.95, 0.3
    y = lfilter([0.0, 0.5, 0.3], [1.0, -2 * r * np.cos(th), r * r], u)
    return u, y + 0.05 * rng.standard_normal(n)


def _fit(u, y, i, method):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PersistenceWarning)
        return fit_predictor(u, y, i, method=method)


def _blas_threads() -> str:
    return os.environ.get("OPENBLAS_NUM_THREADS", "unset")


def _peak_bytes(fn) -> int:
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def _batch(sizes, rng, repeats):
    rows = []
    for i, j in tqdm(sizes, desc="bench-predictor: batch fits", leave=False):
        u, y = _siso_data(j + 2 * i - 1, rng)
        reps = repeats if j <= 10_000 else max(3, repeats // 2)
        t_qr = median_time(lambda: _fit(u, y, i, "qr"), repeats=reps)
        t_ch = median_time(lambda: _fit(u, y, i, "cholesky"), repeats=reps)
        p_qr, p_ch = _fit(u, y, i, "qr"), _fit(u, y, i, "cholesky")
        Lq, Lc = np.hstack([p_qr.Lw, p_qr.Lu]), np.hstack([p_ch.Lw, p_ch.Lu])
        rows.append(
            {
                "i": i,
                "j": j,
                "qr_s": t_qr,
                "cholesky_s": t_ch,
                "ratio_qr_over_cholesky": t_qr / t_ch,
                "max_rel_diff": float(np.linalg.norm(Lq - Lc) / np.linalg.norm(Lq)),
                "rank": p_ch.rank,
            }
        )
    return rows


def _memory(i, j, rng):
    u, y = _siso_data(j + 2 * i - 1, rng)
    out = []
    for method in ("qr", "cholesky"):
        out.append({"i": i, "j": j, "method": method, "peak_MB": _peak_bytes(lambda: _fit(u, y, i, method)) / 1e6})
    # what the explicit Hankel data A = [W_p; U_f; Y_f] alone would take
    out.append({"i": i, "j": j, "method": "(size of A)", "peak_MB": 2 * i * 2 * j * 8 / 1e6})
    return out


def _recursive(i, js, rng, n_push, chunk):
    rows = []
    for j in tqdm(js, desc="bench-predictor: recursive updates", leave=False):
        n0 = j + 2 * i - 1
        u, y = _siso_data(n0 + n_push + chunk * 10, rng)
        for track, window in (("gram", None), ("gram", j), ("factor", None), ("factor", j)):
            rp = RecursivePredictor.from_data(u[:n0], y[:n0], i, window=window, track=track)
            times = []
            t = n0
            for _ in range(n_push):
                t0 = time.perf_counter()
                rp.push(u[t], y[t])
                times.append(time.perf_counter() - t0)
                t += 1
            push_s = float(np.median(times))
            # chunks of `chunk` samples at once (§6.3 pushes 50 at a time), per sample, median of 5
            ctimes = []
            for _ in range(5):
                t0 = time.perf_counter()
                rp.push(u[t : t + chunk], y[t : t + chunk])
                ctimes.append((time.perf_counter() - t0) / chunk)
                t += chunk
            chunk_s = float(np.median(ctimes))

            def pred(rp=rp):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", PersistenceWarning)
                    rp.predictor()

            rows.append(
                {
                    "i": i,
                    "j": j,
                    "track": track,
                    "window": "growing" if window is None else f"sliding {window}",
                    "push_ms": push_s * 1e3,
                    "push_chunk_ms_per_sample": chunk_s * 1e3,
                    "predictor_ms": median_time(pred, repeats=5) * 1e3,
                }
            )
    return rows


def run(opts) -> dict:
    """Run the benchmark; write ``bench_predictor.md`` / ``.json`` under ``opts.out``; return the summary."""
    rng = np.random.default_rng(opts.seed)
    if opts.quick:
        sizes, mem_size, rec_i, rec_js, repeats, n_push, chunk = [(3, 50), (5, 200)], (5, 2000), 4, (50, 200), 3, 20, 5
    else:
        sizes, mem_size, rec_i, rec_js, repeats, n_push, chunk = (
            [(20, 1000), (64, 2048), (20, 100_000)],
            (20, 100_000),
            64,
            (1000, 20_000),
            7,
            200,
            50,
        )
    batch = _batch(sizes, rng, repeats)
    memory = _memory(*mem_size, rng)
    recursive = _recursive(rec_i, rec_js, rng, n_push, chunk)

    checks = {}
    if not opts.quick:
        by = {(r["i"], r["j"]): r for r in batch}
        checks = {
            "cholesky >= 3x faster than qr at (64, 2048)": by[(64, 2048)]["ratio_qr_over_cholesky"] >= TARGETS["speedup_64_2048"],
            "cholesky >= 10x faster than qr at (20, 100000)": by[(20, 100_000)]["ratio_qr_over_cholesky"]
            >= TARGETS["speedup_20_100000"],
            "gram push < 5 ms at i = 64": all(r["push_ms"] < TARGETS["push_ms_i64"] for r in recursive if r["track"] == "gram"),
        }

    t_batch = format_table(
        ["i", "j", "qr [s]", "cholesky [s]", "qr/cholesky", "max rel diff [Lw Lu]", "rank"],
        [
            [r["i"], r["j"], r["qr_s"], r["cholesky_s"], r["ratio_qr_over_cholesky"], r["max_rel_diff"], r["rank"]]
            for r in batch
        ],
    )
    t_mem = format_table(["i", "j", "method", "peak memory [MB]"], [[r["i"], r["j"], r["method"], r["peak_MB"]] for r in memory])
    qr_mem = next(r["peak_MB"] for r in memory if r["method"] == "qr")
    ch_mem = next(r["peak_MB"] for r in memory if r["method"] == "cholesky")
    t_rec = format_table(
        ["i", "j", "track", "window", "push [ms/sample]", "push 50-chunk [ms/sample]" if not opts.quick else "push chunk [ms/sample]", "predictor() [ms]"],
        [
            [r["i"], r["j"], r["track"], r["window"], r["push_ms"], r["push_chunk_ms_per_sample"], r["predictor_ms"]]
            for r in recursive
        ],
    )
    rep = Report("Subspace predictor benchmark (thesis §2.2–2.3.1)")
    rep.text(
        f"SISO data, white-noise input through a lightly damped 2nd-order plant plus sensor noise; seed {opts.seed}; "
        f"median of {repeats} repeats (fewer for the largest j), all in the same run."
        + f" BLAS threads: OPENBLAS_NUM_THREADS={_blas_threads()}."
        + (" **Quick mode: tiny sizes, numbers not meaningful.**" if opts.quick else "")
    )
    rep.section("Batch fit: QR (2.7) vs Cholesky of the recursively built AAᵀ (2.8)–(2.9)")
    rep.text(t_batch)
    rep.section("Peak traced memory (tracemalloc)")
    rep.text(t_mem + f"\n\nqr/cholesky memory ratio: {qr_mem / ch_mem:.3g}")
    rep.section("Recursive predictor (§2.3.1)")
    rep.text(t_rec)
    if checks:
        rep.section("Targets")
        rep.text("\n".join(f"- {'PASS' if ok else 'MISS'}: {name}" for name, ok in checks.items()))
    opts.out.mkdir(parents=True, exist_ok=True)
    md = rep.write(opts.out / "bench_predictor.md")
    summary = {
        "batch": batch,
        "memory": memory,
        "recursive": recursive,
        "targets": {k: bool(v) for k, v in checks.items()},
        "quick": opts.quick,
        "seed": opts.seed,
        "openblas_num_threads": _blas_threads(),
        "report": str(md),
    }
    write_json(opts.out / "bench_predictor.json", summary)
    print(md.read_text())
    return summary
