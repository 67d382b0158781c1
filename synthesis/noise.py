"""The noise level σ of a record, estimated from the data (input to the unfalsification (7.4)/(7.5)).

The admissible rms noise σ of the unfalsification programs is the engineer's choice; this module
gives the number to start from and says how it was obtained: the residual of the least-squares
subspace predictor (2.5) on the record, corrected for the degrees of freedom the fit used.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._repr import result
from ._validation import DataError, as_signal, check_horizon, check_level
from .predictor import _data_matrices, fit_predictor

__all__ = ["NoiseEstimate", "estimate_noise"]


@result
@dataclass(frozen=True, eq=False)
class NoiseEstimate:
    """σ from the data, with how it was obtained (see :func:`estimate_noise`).

    Attributes
    ----------
    sigma : float
        The estimated rms noise level: ``residual_rms · sqrt(j / (j − n_regressors))``.
    residual_rms : float
        ``‖Y_f − [L_w L_u][W_p; U_f]‖_F / sqrt(i·l·j)``: rms of the residual of the least-squares
        predictor on the record, all ``i`` prediction steps and ``l`` outputs (uncorrected).
    per_output : ndarray, shape (l,)
        ``sigma`` per output channel (corrected the same way).
    first_step : ndarray, shape (l,)
        The corrected rms of the one-step-ahead rows only (an estimate of the innovation's
        standard deviation, per output).
    dof_factor : float
        ``sqrt(j / (j − n_regressors))``, the degrees-of-freedom correction.
    suggested_sigma : float
        ``fraction · residual_rms``: a σ for (7.5) on this record that leaves room for an
        uncertainty (σ at or above ``residual_rms`` lets the least-squares predictor explain the
        data as noise alone, so δ = 0).
    fraction : float
        The fraction used for ``suggested_sigma``.
    horizon, n_columns, n_regressors : int
        ``i``, ``j = n − 2i + 1`` and ``i(2m + l)`` of the fit.
    method : str
        The predictor fit (``fit_predictor``'s ``method``).
    """

    sigma: float
    residual_rms: float
    per_output: np.ndarray
    first_step: np.ndarray
    dof_factor: float
    suggested_sigma: float
    fraction: float
    horizon: int
    n_columns: int
    n_regressors: int
    method: str

    @property
    def how(self) -> str:
        """One sentence: how :attr:`sigma` was obtained (for reports)."""
        return (f"σ = {self.sigma:.4g}: rms {self.residual_rms:.4g} of the residual of the least-squares subspace "
                f"predictor (i = {self.horizon}, j = {self.n_columns}, {self.n_regressors} regressors, method "
                f"{self.method!r}) times the degrees-of-freedom factor sqrt(j/(j − {self.n_regressors})) = "
                f"{self.dof_factor:.4g}; suggested σ for (7.5): {self.fraction:g} × {self.residual_rms:.4g} = "
                f"{self.suggested_sigma:.4g}")


def estimate_noise(u, y, horizon: int, *, fraction: float = 0.5, method: str = "cholesky",
                   rcond: float | None = None) -> NoiseEstimate:
    """Estimate the rms noise level σ of a record from the residual of the subspace predictor.

    The least-squares predictor ``[L_w L_u]`` (:func:`synthesis.fit_predictor`) is fitted on the
    record and its residual ``E = Y_f − [L_w L_u][W_p; U_f]`` formed on the explicit block Hankel
    matrices.  Each of the ``i·l`` rows of ``E`` is a least-squares residual of ``j``
    observations on ``n_regressors = i(2m + l)`` regressors, so ``E E^T`` underestimates the noise
    power by ``(j − n_regressors)/j``; the estimate is

    ``σ = rms(E) · sqrt(j / (j − n_regressors))``.

    What it measures: for white measurement noise on the outputs and a horizon that covers the
    plant's memory, the noise's standard deviation.  For noise that enters through the dynamics
    the ``k``-step prediction error accumulates and ``σ`` is larger than the innovation's standard
    deviation; :attr:`NoiseEstimate.first_step` (the one-step rows) estimates the latter.

    For the unfalsification (7.5) σ is the *admissible* rms noise: with ``σ ≥ residual_rms`` (on
    the window unfalsified) the least-squares predictor explains the data with noise alone and
    δ = 0.  A σ below the residual rms is needed for a non-trivial δ; the split between noise and
    uncertainty is the engineer's choice, and :attr:`NoiseEstimate.suggested_sigma` is
    ``fraction · residual_rms`` (default one half, as in the §7.4 examples).

    Parameters
    ----------
    u : array_like, shape (n,) or (n, m)
        Inputs, time along axis 0.
    y : array_like, shape (n,) or (n, l)
        Outputs.
    horizon : int
        Prediction horizon ``i`` (use the one of the unfalsification).
    fraction : float
        In (0, 1]: ``suggested_sigma = fraction · residual_rms``.
    method : str
        Passed to :func:`synthesis.fit_predictor`.
    rcond : float, optional
        Passed to :func:`synthesis.fit_predictor`.

    Returns
    -------
    NoiseEstimate
        The value and how it was obtained.

    Raises
    ------
    DataError
        Bad signals or horizon (as :func:`synthesis.fit_predictor`); too few columns to estimate
        anything (``j <= n_regressors``: the fit interpolates the data); ``fraction`` outside (0, 1].

    Examples
    --------
    >>> import numpy as np
    >>> import synthesis
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(3000)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5, 0.25])[:3000] + 0.1 * rng.standard_normal(3000)
    >>> est = synthesis.estimate_noise(u, y, 5)
    >>> round(est.sigma, 2), round(est.suggested_sigma, 2)
    (0.1, 0.05)
    >>> est.how.split(":")[0]
    'σ = 0.09968'
    """
    fraction = check_level(fraction, "fraction")
    if fraction > 1:
        raise DataError(f"fraction must be in (0, 1], got {fraction!r}: σ at or above the residual rms gives δ = 0")
    u = as_signal(u, "u")
    y = as_signal(y, "y", n=u.shape[0])
    n, m = u.shape
    l = y.shape[1]
    i = check_horizon(horizon, n)
    n_reg = i * (2 * m + l)
    j = n - 2 * i + 1
    if j <= n_reg:
        raise DataError(
            f"j = {j} columns for {n_reg} regressors: the least-squares fit interpolates the data and leaves no "
            f"residual to estimate the noise from; collect more than {n_reg + 2 * i - 1} samples (several times "
            "that for a useful estimate) or reduce the horizon")
    pred = fit_predictor(u, y, i, method=method, rcond=rcond)
    Up, Uf, Yp, Yf, _ = _data_matrices(u, y, i)
    E = Yf - pred.Lw @ np.vstack([Up, Yp]) - pred.Lu @ Uf  # rows: (step k, output c) = k·l + c
    factor = float(np.sqrt(j / (j - n_reg)))
    rms = float(np.linalg.norm(E) / np.sqrt(E.size))
    per_output = np.sqrt(np.mean(E.reshape(i, l, j) ** 2, axis=(0, 2))) * factor
    first = np.sqrt(np.mean(E[:l] ** 2, axis=1)) * factor
    return NoiseEstimate(sigma=rms * factor, residual_rms=rms, per_output=per_output, first_step=first,
                         dof_factor=factor, suggested_sigma=fraction * rms, fraction=fraction, horizon=i,
                         n_columns=j, n_regressors=n_reg, method=method)
