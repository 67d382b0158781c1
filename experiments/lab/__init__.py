"""The library the experiments and benchmarks use: plants, signals, simulation, lab records, reports.

   plants       -- the thesis's plants (§5.4 servo, §6.1 three-disk) and the catalogue of the sweeps
   signals      -- PRBS, white noise, steps
   simulate     -- open-loop experiments and closed loops (LTI, receding-horizon, adaptive controllers)
   records      -- ``load_record``: measured ``u``, ``y``, ``dt`` from CSV, NPZ or MAT
   report       -- markdown reports, CSV/JSON files and checked figures under ``--out``
   _servo       -- the §5.4 servo set-up shared by several studies (data, weights, step plots)
   _torsional   -- the Ch. 6 three-disk weights and sample time

The public names of ``plants``, ``signals``, ``simulate`` and ``records`` are re-exported by
:mod:`experiments`; ``experiments.plants`` (and the other four) are the same modules under their former paths.
"""
