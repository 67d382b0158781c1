"""The benchmarks, one module per ``python -m experiments bench-*`` subcommand.

   bench_predictor  -- ``bench-predictor``: QR vs Cholesky predictor, recursive updates
   bench_adaptive   -- ``bench-adaptive``: adaptive redesign time per update (§6.3)
   bench_unfalsify  -- ``bench-unfalsify``: (7.5) solve time against problem size, per solver
   bench_norms      -- ``bench-norms``: certified H∞ norms and SLICOT simulation against the former routes
   bench_split      -- ``bench-split``: the column split of (7.5) on 1 and N workers

What each writes: ``README.md`` beside this file; the measurement log: ``BENCHMARKS.md``.
"""
