"""Plants, signals, simulations and the thesis experiments (Ch. 5–7)."""
from .plants import (
    PLANT_CATALOGUE,
    SERVO_DT,
    THREE_DISK,
    THREE_DISK_DT,
    ThreeDiskParameters,
    nonminimum_phase,
    plant_catalogue,
    resonant,
    servo,
    third_order,
    three_disk,
)
from .records import RECORD_FORMATS, Record, RecordError, load_record
from .signals import prbs, step, step_sequence, white_noise
from .simulate import (
    AlgebraicLoopError,
    ClosedLoopResult,
    OpenLoopData,
    closed_loop,
    closed_loop_adaptive,
    closed_loop_system,
    collect_data,
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
    "RECORD_FORMATS",
    "Record",
    "RecordError",
    "load_record",
]

from synthesis import __version__  # noqa: E402 - one distribution, one version
