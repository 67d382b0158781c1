"""The library the experiments and benchmarks use: plants, signals, simulation, lab records, reports.

   plants           -- the thesis's plants (§5.4 servo, §6.1 three-disk), the catalogue of the sweeps and how
                       they are built (``modal_ss``, ``damped_pair``, ``zoh``)
   signals          -- PRBS, white noise, steps
   simulate         -- open-loop experiments, closed loops (LTI, receding-horizon, adaptive controllers), ``lsim``
   records          -- ``load_record``: measured ``u``, ``y``, ``dt`` from CSV, NPZ or MAT; ``record_columns``,
                       ``text_columns``
   report           -- markdown reports, CSV/JSON files and checked figures under ``--out``
   servo_setup      -- the §5.4 servo set-up shared by several studies (data, weights, step responses and plots)
   torsional_setup  -- the Ch. 6 three-disk weights (chosen: the thesis gives them only as plots)

The public names of ``plants``, ``signals``, ``simulate``, ``records``, ``servo_setup`` and ``torsional_setup``
are re-exported here; those of the first four also by :mod:`experiments`, where ``experiments.plants`` (and the
other four) are the same modules under their former paths. The studies and benchmarks import only these public
names (tests/test_unfalsify_solvers.py checks that no module imports a private name from another subpackage).

>>> from experiments.lab import design_weights, servo_data, torsional_weights
>>> servo_data(100).n, sorted(design_weights()), torsional_weights("collocated")[0].dt
(100, ['W11', 'W12', 'W21', 'W22'], 0.015625)
"""
from . import plants, records, report, servo_setup, signals, simulate, torsional_setup
from .plants import *  # noqa: F401,F403 - the modules' __all__ are this package's public names
from .records import *  # noqa: F401,F403
from .servo_setup import *  # noqa: F401,F403
from .signals import *  # noqa: F401,F403
from .simulate import *  # noqa: F401,F403
from .torsional_setup import *  # noqa: F401,F403

__all__: list[str] = [name for module in (plants, signals, simulate, records, servo_setup, torsional_setup)
                      for name in module.__all__]
