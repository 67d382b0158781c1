"""Exceptions and warnings of :mod:`synthesis` (as python-control's ``exception.py``).

Every class is also importable from ``synthesis`` itself and from the module that raises it
(``synthesis.weights.WeightError``, ``synthesis.minimax.InfeasibleGammaError``, …), where users find them.
"""
from __future__ import annotations

import numpy as np

__all__ = [
    "DataError",
    "InputTypeError",
    "WeightError",
    "ControllerFileError",
    "PersistenceWarning",
    "OrderWarning",
    "DowndateError",
    "RefactorWarning",
    "InfeasibleGammaError",
    "NearGammaMinWarning",
    "HorizonWarning",
    "StageSaddleError",
]


class DataError(ValueError):
    """Invalid input data (shape, length, NaN/inf, too few samples, ...)."""


class InputTypeError(DataError, TypeError):
    """An argument of the wrong type (e.g. a string where an LTI system is expected).

    Both a :class:`DataError` (a ``ValueError``) and a ``TypeError``, so either ``except`` catches it.
    """


class WeightError(DataError):
    """A weighting filter is unusable (improper, continuous, wrong size, wrong dt, NaN)."""


class ControllerFileError(DataError):
    """A controller file cannot be written or read (unknown ending, missing or inconsistent variables)."""


class PersistenceWarning(UserWarning):
    """The input is not persistently exciting of order 2mi (§5.1, comment 1)."""


class OrderWarning(UserWarning):
    """An order criterion chose the largest order it considered: the plant's order may be higher."""


class DowndateError(np.linalg.LinAlgError):
    """``L Lᵀ − x xᵀ`` is not (numerically) positive definite: the downdate is impossible."""


class RefactorWarning(RuntimeWarning):
    """A Cholesky downdate lost positive definiteness; the factor was recomputed from the window."""


class InfeasibleGammaError(ValueError):
    """γ ≤ γ_min: no saddle point, the level-γ problem has no solution (3.29).

    Also raised by :func:`synthesis.discrete_mixsyn` for a level it cannot achieve; there ``gamma_min`` holds the
    least level proven by its bisection and ``message`` says so.
    """

    def __init__(self, gamma: float, gamma_min: float, threshold: float | None = None, message: str | None = None):
        self.gamma = float(gamma)
        self.gamma_min = float(gamma_min)
        #: smallest accepted level (γ_min plus the accuracy of its computation), when known
        self.threshold = self.gamma_min if threshold is None else float(threshold)
        # ``message`` lets a problem other than the finite-horizon game (3.29) say what its threshold is
        super().__init__(message if message is not None else
                         f"gamma = {self.gamma:.6g} is not above gamma_min = {self.gamma_min:.6g}: the level-gamma "
                         f"problem has no saddle point (3.29). Choose gamma > gamma_min, e.g. gamma = 1.1 * gamma_min "
                         f"= {1.1 * self.gamma_min:.6g} (§5.1 comment 4)")

    def __reduce__(self):
        # pickling rebuilds an exception from ``args`` (here the message alone), which this signature does not take:
        # unpickling had raised TypeError, and a process pool whose task raised this error broke ("terminated abruptly")
        return type(self), (self.gamma, self.gamma_min, self.threshold, str(self))


class NearGammaMinWarning(UserWarning):
    """γ < 1.03 γ_min: gains are huge and the loop went unstable there in §5.4.4."""


class HorizonWarning(UserWarning):
    """The data show no effect of the control on the predicted output over the horizon (``L_u`` is noise).

    The horizon ``i`` is not longer than the plant's delay (``i = 1`` on a strictly proper plant): the inputs
    ``u_k … u_{k+i-1}`` do not reach ``y_k … y_{k+i-1}``, so the law's control acts on estimation noise.  Raised by
    :func:`~synthesis.hinf_design`, :func:`~synthesis.gamma_min` and :func:`~synthesis.lqg_design`, and once per
    run by :class:`~synthesis.AdaptiveHinf`, when :attr:`~synthesis.Predictor.control_pvalue` exceeds 0.01.
    """


class HorizonChoiceWarning(HorizonWarning):
    """:func:`~synthesis.choose_horizon` found no candidate horizon passing its checks on the data-based models.

    The returned :class:`~synthesis.HorizonChoice` (``ok`` False) holds a fallback design, the largest candidate
    stable on ``P̂``, which may be unstable on the plant; the warning's text is the choice's ``reason``.
    """


class StageSaddleError(InfeasibleGammaError):
    """A stage of the H∞ Riccati recursion (4.17) has no saddle point: γ is too small."""

    def __init__(self, gamma: float, message: str):
        self.gamma = float(gamma)
        self.gamma_min = float("nan")
        self.threshold = self.gamma_min
        ValueError.__init__(self, message)

    def __reduce__(self):
        return type(self), (self.gamma, str(self))
