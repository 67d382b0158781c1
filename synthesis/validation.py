"""Input checks shared by the whole toolkit (:mod:`synthesis`, :mod:`unfalsify`, :mod:`experiments`).

The public home of the checks the packages on synthesis funnel user data through, so that bad input
fails early with an exception that names the problem and the fix.  :class:`DataError` and
:class:`InputTypeError` are defined in :mod:`synthesis.exceptions`.
"""
from ._validation import (as_discrete_system, as_real_array, as_signal, check_count, check_flag, check_horizon,
                          check_inputs_move, check_instance, check_level, check_nonnegative, check_output_moves,
                          check_predictor_dt, check_same_dt, check_sample_time)
from .exceptions import DataError, InputTypeError

__all__ = ["DataError", "InputTypeError", "as_real_array", "as_signal", "as_discrete_system", "check_horizon",
           "check_sample_time", "check_same_dt", "check_flag", "check_count", "check_nonnegative",
           "check_predictor_dt", "check_level", "check_instance", "check_output_moves", "check_inputs_move"]
