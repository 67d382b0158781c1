"""Exceptions and warnings of :mod:`unfalsify` (as python-control's ``exception.py``).

Every class is also importable from ``unfalsify`` itself, where users find them.
"""
from __future__ import annotations

__all__ = [
    "UnfalsificationError",
    "UnknownSolverError",
    "NotAtRestWarning",
    "IllConditionedWarning",
    "SolverWarning",
    "FewDataWarning",
    "LongSolveWarning",
    "NotCertifiedWarning",
    "UntestedPremiseWarning",
    "NotCertifiedError",
]


class UnfalsificationError(ValueError):
    """The unfalsification problem could not be solved (infeasible/unbounded/solver failure)."""


class UnknownSolverError(ValueError):
    """A ``backend=``, ``method=`` or solver name that the solver registry does not know, or a solver
    that does not take the problem (another program, or several channels: the message names the fix).

    The message lists the valid names (:data:`unfalsify.solvers.SOLVERS` and the aliases).
    """


class NotAtRestWarning(UserWarning):
    """A program that assumes the system at rest before the record (7.3)/(7.4) got a record that starts mid-motion."""


class IllConditionedWarning(UserWarning):
    """cond T(u) is so large that the literal Chapter 7 quantities are numerically meaningless."""


class SolverWarning(UserWarning):
    """The conic solver returned a status other than ``optimal``."""


class FewDataWarning(UserWarning):
    """The (7.5) window has few columns for the predictor it estimates: δ is then optimistic (with no more columns than
    the rank of ``[W_p; U_f]``, and L optimised, it is 0 whatever the data)."""


class LongSolveWarning(UserWarning):
    """A (7.4) or (7.5) solve is estimated to take long (the message gives the estimate and how to shorten it)."""


class NotCertifiedWarning(UserWarning):
    """The §7.4 pipeline could not certify the loop it returns (the reason is in the message)."""


class UntestedPremiseWarning(UserWarning):
    """The loop is certified, but on a premise these data cannot test (``result.assumed``, with the fix: e.g. an input
    of two levels shows no saturation)."""


class NotCertifiedError(UnfalsificationError):
    """``require_certified=True`` and no design of the search certifies (the reason is in the message)."""
