"""The thesis experiments and studies, one module per ``python -m experiments`` subcommand.

   design_example   -- ``design-example``: §5.4, Tables 5.1–5.5
   chapter7         -- ``chapter7``: §7.4, δ by ARX and subspace unfalsification, robust design
   robust_pipeline  -- ``robust-pipeline``: §7.4 on plants it was not designed on, checked on the true plant
   adversarial      -- ``robust-adversarial``: the certificate against adversarial data
   noncollocated    -- ``noncollocated``: §6.2 non-collocated three-disk design
   adaptive         -- ``adaptive``: §6.3 adaptive simulation
   compare          -- ``compare``: model-free against identify-then-design
   sweep            -- ``sweep``: Monte Carlo sweeps of the §7.4 pipeline (local processes or Dask)
   demo             -- ``demo``: the quick Chapter 7 pipeline and Table 5.1
   design_cli       -- ``design``: the §7.4 workflow on a measured record
   cd_player        -- ``cd-player``: that workflow on the CD-player arm record (``experiments/data/``)

What each writes: ``README.md`` beside this file; the measured results: ``RESULTS.md``.
"""
