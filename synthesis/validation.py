"""Input checks shared by the whole toolkit (:mod:`synthesis`, :mod:`unfalsify`, :mod:`experiments`).

The public home of the checks every package funnels user data through, so that bad input fails early
with an exception that names the problem and the fix.  :class:`DataError` and :class:`InputTypeError`
are also ``synthesis.DataError`` and ``synthesis.InputTypeError``.
"""
from ._validation import (
    DataError,
    InputTypeError,
    as_discrete_system,
    as_signal,
    check_horizon,
    check_level,
    check_same_dt,
    check_sample_time,
    to_state_space,
)

__all__ = ["DataError", "InputTypeError", "as_signal", "as_discrete_system", "to_state_space", "check_same_dt",
           "check_horizon", "check_level", "check_sample_time"]
