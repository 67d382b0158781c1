"""
Plants, signals, simulations and the thesis experiments (Ch. 5–7)
=================================================================

The building blocks of the thesis's experiments, and the experiments themselves as a command line,
``python -m experiments NAME [--quick] [--json] [--out DIR] [--seed N]`` (one subcommand per experiment or
benchmark; each writes a markdown report, a JSON summary, figures and CSV tables under
``results/<name>/``). The subcommands and their common options are listed in ``experiments/README.md`` of
the source tree; each kind below documents its own runs beside its code.

Layout
------

``experiments/lab/``
    the library the runs use: ``plants``, ``signals``, ``simulate``, ``records`` (lab records), ``report``
    (tables, figures, markdown reports), and the shared set-ups ``servo_setup`` (§5.4) and ``torsional_setup``
    (Ch. 6). The public names of the first four are re-exported here (below); ``experiments.lab`` re-exports
    those and the set-ups' names (``help(experiments.lab)``).
``experiments/studies/``
    the thesis experiments and studies, one module per subcommand (``design_example``, ``chapter7``,
    ``robust_pipeline``, ``adversarial``, ``noncollocated``, ``adaptive``, ``compare``, ``sweep``, ``demo``,
    ``design_cli``, ``cd_player``); what each runs and writes: ``studies/README.md``, measured results:
    ``studies/RESULTS.md``.
``experiments/bench/``
    the benchmarks (``bench_predictor``, ``bench_adaptive``, ``bench_unfalsify``, ``bench_norms``,
    ``bench_split``); ``bench/README.md`` and the measurement log ``bench/BENCHMARKS.md``.
``experiments/cli.py``, ``experiments/data/``
    the command line (``COMMANDS``: subcommand → module) and the shipped CD-player record.

The library modules' former paths ``experiments.plants``, ``experiments.signals``, ``experiments.simulate``,
``experiments.records`` and ``experiments.report`` are aliases of the same module objects in ``lab``.

Plants
------

   servo                  -- servo actuator (5.5) ``1/(s(s+1))``, ZOH at 10 Hz (``SERVO_DT``)
   three_disk             -- three-disk torsional plant of §6.1 (output ``y1``/``y3``), ZOH at 64 Hz
   ThreeDiskParameters    -- parameters of the §6.1 three-disk models
   THREE_DISK             -- the §6.1 parameter values
   THREE_DISK_DT          -- 1/64 s
   SERVO_DT               -- 0.1 s
   third_order            -- stable ``6/((s+1)(s+2)(s+3))``
   resonant               -- lightly damped ``ω²/(s² + 2ζωs + ω²)``
   nonminimum_phase       -- ``2(1 − s)/((s+1)(s+2))``
   PLANT_CATALOGUE        -- name → (factory, description) of the plants of the sweeps
   plant_catalogue        -- those plants, built
   modal_ss               -- real modal realisation of ``N(s)/Π(s − p)``, how the plants are built
   damped_pair            -- the complex pole pair of ``s² + 2ζωs + ω²``
   zoh                    -- zero-order-hold discretisation as the plants use it

Signals
-------

   prbs                   -- maximum-length PRBS ±amplitude
   white_noise            -- zero-mean white Gaussian noise
   step                   -- unit (or scaled) step
   step_sequence          -- a series of steps

Simulation
----------

   collect_data           -- open-loop experiment ``y = P(u + w) + v`` (§5.4)
   OpenLoopData           -- its result (``u``, ``y``, ``y_clean``, ``x_final``)
   closed_loop            -- a plant (plus an optional additive perturbation) under an LTI, receding-horizon
                             or adaptive controller
   closed_loop_adaptive   -- closed loop with an adaptive controller, keeping its γ history
   closed_loop_system     -- the LTI closed loop ``r → [y; u]`` as a ``StateSpace``
   ClosedLoopResult       -- result of ``closed_loop`` (``t``, ``r``, ``y``, ``u``, ``e``)
   AlgebraicLoopError     -- plant and controller both have feedthrough
   lsim                   -- ``(y, x_n)`` of discrete state-space matrices driven by ``u`` (SLICOT TF01MD)

Lab records
-----------

   load_record            -- read ``u``, ``y`` and ``dt`` from CSV, NPZ or MATLAB ``.mat``
   Record                 -- result of ``load_record``
   RECORD_FORMATS         -- the file suffixes ``load_record`` reads
   record_columns         -- column names and count of a record file, before choosing ``u`` and ``y``
   text_columns           -- the columns of a CSV record that hold text, no number (a status): not signals
   time_unit              -- a column name's unit in brackets (``time [ms]``), in seconds where it is one of time
   RecordError            -- a record that cannot be read as asked (the message names the fix)

Tour
----

An open-loop experiment on the servo, then the loop closed by a proportional controller on ``e = r − y``:

>>> import numpy as np
>>> import control
>>> from experiments import closed_loop, collect_data, prbs, servo
>>> P = servo()
>>> P.dt
0.1
>>> data = collect_data(P, prbs(1000, seed=0), process_noise=0.05, sensor_noise=0.05, seed=1)
>>> data.u.shape, data.y.shape
((1000, 1), (1000, 1))
>>> res = closed_loop(P, control.ss([], [], [], [[2.0]], P.dt), np.ones(200))
>>> round(float(res.y[-1, 0]), 3)
1.0

The command line (``python -m experiments --help``):

>>> from experiments.cli import COMMANDS
>>> list(COMMANDS)  # doctest: +NORMALIZE_WHITESPACE
['demo', 'design-example', 'noncollocated', 'adaptive', 'chapter7', 'robust-pipeline', 'robust-adversarial',
 'mimo-pipeline', 'bench-predictor', 'bench-adaptive', 'bench-unfalsify', 'bench-norms', 'bench-split', 'sweep', 'design',
 'cd-player', 'compare']
"""
import sys as _sys

from .lab import plants, records, report, signals, simulate
from .lab.plants import (
    PLANT_CATALOGUE,
    SERVO_DT,
    THREE_DISK,
    THREE_DISK_DT,
    ThreeDiskParameters,
    damped_pair,
    modal_ss,
    nonminimum_phase,
    plant_catalogue,
    resonant,
    servo,
    third_order,
    three_disk,
    zoh,
)
from .lab.records import RECORD_FORMATS, Record, RecordError, load_record, record_columns, text_columns, time_unit
from .lab.signals import prbs, step, step_sequence, white_noise
from .lab.simulate import (
    AlgebraicLoopError,
    ClosedLoopResult,
    OpenLoopData,
    closed_loop,
    closed_loop_adaptive,
    closed_loop_system,
    collect_data,
    lsim,
)

__all__: list[str] = [
    "SERVO_DT",
    "THREE_DISK",
    "THREE_DISK_DT",
    "ThreeDiskParameters",
    "servo",
    "three_disk",
    "third_order",
    "resonant",
    "nonminimum_phase",
    "PLANT_CATALOGUE",
    "plant_catalogue",
    "modal_ss",
    "damped_pair",
    "zoh",
    "prbs",
    "step",
    "step_sequence",
    "white_noise",
    "AlgebraicLoopError",
    "ClosedLoopResult",
    "OpenLoopData",
    "closed_loop",
    "closed_loop_adaptive",
    "closed_loop_system",
    "collect_data",
    "lsim",
    "RECORD_FORMATS",
    "Record",
    "RecordError",
    "load_record",
    "record_columns",
    "text_columns",
    "time_unit",
]

# the library modules' paths before they moved into lab/: the same module objects under their old names
for _module in (plants, records, report, signals, simulate):
    _sys.modules[f"{__name__}.{_module.__name__.rsplit('.', 1)[1]}"] = _module
del _module

from synthesis import __version__  # noqa: E402 - one distribution, one version
