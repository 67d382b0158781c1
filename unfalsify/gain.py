"""Theorem 7.1: the smallest H∞ gain of a causal LTI operator that explains SISO data.

Data ``(u, y)`` of length n are explained by some LTI ``Δ`` with ``‖Δ‖∞ ≤ γ`` (system at
rest before t = 0) iff (7.1) ``T(y)ᵀT(y) ⪯ γ² T(u)ᵀT(u)``.  When ``u₀ ≠ 0``, ``T(u)`` is
invertible and, because lower-triangular Toeplitz matrices commute,
``T(y) = T(h) T(u)`` with ``h = T(u)⁻¹ y`` (the first n Markov parameters of the only
causal operator that maps u to y on the window).  (7.1) is then ``T(h)ᵀT(h) ⪯ γ² I``:

    γ_min = ‖T(h)‖₂,   h = T(u)⁻¹ y,

which by Carathéodory–Fejér is also the smallest H∞ norm of any causal LTI system with
Markov parameters h.  This never forms ``T(u)ᵀT(u)`` (whose condition number is
``cond(T(u))²``).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from synthesis import DataError
from synthesis.results import result

from ._common import COND_WARN, siso_signal
from .exceptions import IllConditionedWarning
from .solvers.toeplitz import deconvolve, toeplitz_cond, toeplitz_norm

__all__ = ["GainResult", "unfalsified_gain", "unfalsified_gain_result", "is_unfalsified"]


@result
@dataclass(frozen=True)
class GainResult:
    """Result of Theorem 7.1.

    Attributes
    ----------
    gamma : float
        Smallest γ satisfying (7.1), ``‖T(h)‖₂``.
    impulse : ndarray, shape (n,)
        ``h = T(u)⁻¹ y``: Markov parameters of the causal operator mapping u to y.
    cond_Tu : float
        2-norm condition number of ``T(u)``; above :data:`COND_WARN` the answer is flagged.
    exact : bool
        Whether ``h`` was computed in exact rational arithmetic.
    method : str
        How ``‖T(h)‖₂`` was computed (``"dense"`` or ``"lanczos"``).
    """

    gamma: float
    impulse: np.ndarray
    cond_Tu: float
    exact: bool
    method: str

    @property
    def well_conditioned(self) -> bool:
        """True when ``cond_Tu <= COND_WARN``."""
        return bool(self.cond_Tu <= COND_WARN)


def _checked_pair(u, y) -> tuple[np.ndarray, np.ndarray]:
    u = siso_signal(u, "u")
    y = siso_signal(y, "y", n=u.size)
    if u[0] == 0.0:
        raise DataError(
            "u[0] == 0: T(u) is singular, so Theorem 7.1 cannot be applied as stated (if y[0] != 0 no "
            "causal Δ explains the data at all). If the system was at rest and the input starts later, "
            "drop the leading samples where u is zero from both u and y"
        )
    return u, y


def unfalsified_gain_result(u, y, *, exact: bool | None = None, method: str = "auto", warn: bool = True) -> GainResult:
    """Theorem 7.1 with diagnostics: smallest γ for (7.1), ``h`` and cond ``T(u)``.

    Parameters
    ----------
    u, y : array_like, shape (n,) or (n, 1)
        SISO input/output data, system at rest before t = 0.
    exact : bool, optional
        Compute ``h = T(u)⁻¹ y`` in exact rational arithmetic (default: when n ≤ 400).
        Forward substitution in floating point is usually accurate too (triangular
        systems are), but the exact route needs no such argument.
    method : {"auto", "dense", "lanczos"}
        How ``‖T(h)‖₂`` is computed, see :func:`unfalsify.toeplitz_norm`.
    warn : bool
        Emit :class:`IllConditionedWarning` when ``cond T(u) > COND_WARN`` (1e8).

    Raises
    ------
    DataError
        On NaN/inf, length mismatch, more than one channel, or ``u[0] == 0``.
    """
    u, y = _checked_pair(u, y)
    n = u.size
    if exact is None:
        exact = n <= 400
    with np.errstate(over="ignore", invalid="ignore"):
        h = deconvolve(u, y, exact=exact)
    cond = toeplitz_cond(u)
    if warn and not cond <= COND_WARN:
        warnings.warn(
            f"cond T(u) = {cond:.3g} > {COND_WARN:.0e}: T(u)ᵀT(u) is numerically singular and the "
            "unfalsified gain is dominated by the unstable inverse of u(q); it may change completely under "
            "data perturbations far below sensor resolution (use shorter records or a minimum-phase input)",
            IllConditionedWarning,
            stacklevel=2,
        )
    if not np.all(np.isfinite(h)):
        gamma = float("inf")
        used = "overflow"
    else:
        used = method if method != "auto" else ("dense" if n <= 400 else "lanczos")
        gamma = toeplitz_norm(h, method=used)
    return GainResult(gamma=gamma, impulse=h, cond_Tu=cond, exact=bool(exact), method=used)


def unfalsified_gain(u, y, **kwargs) -> float:
    """Smallest γ such that an LTI ``Δ`` with ``‖Δ‖∞ ≤ γ`` maps u to y on the window (Thm 7.1).

    Computed as ``‖T(h)‖₂`` with ``h = T(u)⁻¹ y``; see :func:`unfalsified_gain_result`
    for the keyword arguments and the diagnostics (cond ``T(u)``, h).
    """
    return unfalsified_gain_result(u, y, **kwargs).gamma


def is_unfalsified(u, y, gamma: float, *, rtol: float = 1e-9, **kwargs) -> bool:
    """True if the data do not falsify "y = Δu with ‖Δ‖∞ ≤ gamma" (Thm 7.1), up to ``rtol``."""
    g = float(gamma)
    if not np.isfinite(g) or g < 0:
        raise DataError(f"gamma must be a finite number >= 0, got {gamma!r}")
    return bool(unfalsified_gain(u, y, **kwargs) <= g * (1.0 + rtol))
