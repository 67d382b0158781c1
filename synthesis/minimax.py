"""One engine for every finite-horizon law: a quadratic minimax game (thesis (3.17)–(3.31)).

Each control law of Ch. 3 is a performance map

    z = M_d d + M_u u + M_x x,

with ``d`` the disturbances the adversary picks (future references ``r``, uncertainty
signals ``s``), ``u`` the future controls and ``x`` the known data / weight states.  The
game is ``min_u sup_d J`` with ``J = ‖z‖² − γ²‖d‖²`` (3.18).

Saddle condition (3.25)–(3.29).  The (half) Hessian in ``(d, u)`` is

    [M_dᵀM_d − γ²I   M_dᵀM_u]
    [M_uᵀM_d          M_uᵀM_u].

It has exactly ``dim u`` positive and ``dim d`` negative eigenvalues iff
``M_uᵀM_u > 0`` and the Schur complement ``M_dᵀ(I − P_u)M_d < γ²I``, ``P_u`` the
orthogonal projector on range(M_u).  Hence the exact threshold

    γ_min = ‖(I − P_u) M_d‖₂,

computed here from a QR factorisation of ``M_u`` and one SVD (no bisection, no
explicit normal equations).

Saddle point (3.31).  ``[d_wc; u_opt] = −Hess⁻¹ [M_d M_u]ᵀ M_x x``, evaluated stably:
with ``M_u = Q R`` and ``M̃ = (I − QQᵀ)M``,

    d_wc  = (γ²I − M̃_dᵀM̃_d)⁻¹ M̃_dᵀ M̃_x x      (SVD of M̃_d),
    u_opt = −R⁻¹ Qᵀ (M_d d_wc + M_x x).
"""
from __future__ import annotations

import numbers
import warnings
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_triangular

from ._validation import DataError

__all__ = [
    "InfeasibleGammaError",
    "MinimaxSolution",
    "NearGammaMinWarning",
    "NEAR_GAMMA_MIN_RATIO",
    "minimax_gamma_min",
    "solve_minimax",
]

#: Below ``1.03 γ_min`` the §5.4.4 design example went unstable.
NEAR_GAMMA_MIN_RATIO = 1.03


class InfeasibleGammaError(ValueError):
    """γ ≤ γ_min: no saddle point, the level-γ problem has no solution (3.29)."""

    def __init__(self, gamma: float, gamma_min: float):
        self.gamma = float(gamma)
        self.gamma_min = float(gamma_min)
        super().__init__(
            f"gamma = {self.gamma:.6g} is not above gamma_min = {self.gamma_min:.6g}: the level-gamma "
            f"problem has no saddle point (3.29). Choose gamma > gamma_min, e.g. gamma = 1.1 * gamma_min = "
            f"{1.1 * self.gamma_min:.6g} (§5.1 comment 4)")


class NearGammaMinWarning(UserWarning):
    """γ < 1.03 γ_min: gains are huge and the loop went unstable there in §5.4.4."""


@dataclass(frozen=True, eq=False)
class MinimaxSolution:
    """Saddle point of ``min_u sup_d ‖M_d d + M_u u + M_x x‖² − γ²‖d‖²``.

    Attributes
    ----------
    gamma, gamma_min : float
        Level used and the exact threshold ``‖(I − P_u)M_d‖₂``.
    u_gain : ndarray, shape (n_u, n_x)
        ``u_opt = u_gain @ x``.
    d_gain : ndarray, shape (n_d, n_x)
        Worst-case disturbance ``d_wc = d_gain @ x``.
    """

    gamma: float
    gamma_min: float
    u_gain: np.ndarray
    d_gain: np.ndarray


def _check_maps(Md, Mu, Mx=None):
    Mu = np.asarray(Mu, dtype=float)
    if Mu.ndim != 2 or Mu.shape[1] == 0:
        raise DataError(f"M_u must be a 2-D matrix with at least one column, got shape {Mu.shape}")
    rows = Mu.shape[0]
    Md = _rows_like(Md, rows, "M_d")
    arrays = [("M_d", Md), ("M_u", Mu)]
    if Mx is not None:
        Mx = _rows_like(Mx, rows, "M_x")
        arrays.append(("M_x", Mx))
    for name, a in arrays:
        if not np.all(np.isfinite(a)):
            raise DataError(f"{name} contains NaN or infinite values (check the predictor and the weights)")
    return Md, Mu, Mx


def _rows_like(M, rows: int, name: str) -> np.ndarray:
    """``M`` as a 2-D array with ``rows`` rows (a 1-D array of that length is one column)."""
    M = np.asarray(M, dtype=float)
    if M.ndim == 1 and M.size == rows:
        M = M[:, None]
    if M.ndim != 2 or M.shape[0] != rows:
        raise DataError(
            f"{name} has shape {M.shape} but the performance map has {rows} rows (those of M_u): "
            "M_d, M_u and M_x must have the same number of rows")
    return M


def _qr_u(Mu):
    """Thin QR of M_u with a check that M_uᵀM_u > 0 (the ``im`` positive eigenvalues)."""
    Q, R = np.linalg.qr(Mu, mode="reduced")
    d = np.abs(np.diag(R))
    scale = max(np.linalg.norm(Mu), np.finfo(float).tiny)  # Frobenius: cheap upper bound on ‖M_u‖₂
    if Mu.shape[0] < Mu.shape[1] or d.min() <= max(Mu.shape) * np.finfo(float).eps * scale:
        raise DataError(
            "M_u does not have full column rank, so M_uᵀM_u is singular and the minimisation over u has no "
            "unique solution; check that W2 has a full-rank feedthrough (relative degree 0)")
    return Q, R


def _project_out(Q, M):
    return M - Q @ (Q.T @ M)


def minimax_gamma_min(Md, Mu) -> float:
    """Exact threshold ``γ_min = ‖(I − P_u) M_d‖₂`` of the saddle condition (3.29).

    Returns 0 when there are no disturbances.
    """
    Md, Mu, _ = _check_maps(Md, Mu)
    Q, _ = _qr_u(Mu)
    if Md.shape[1] == 0:
        return 0.0
    return float(np.linalg.norm(_project_out(Q, Md), 2))


def solve_minimax(Md, Mu, Mx, gamma: float) -> MinimaxSolution:
    """Saddle-point gains of the game (3.31) for a level ``gamma > γ_min``.

    Parameters
    ----------
    Md, Mu, Mx : array_like
        Performance map ``z = M_d d + M_u u + M_x x`` (same number of rows).
    gamma : float
        Level; ``numpy.inf`` gives the LQ limit (``d_wc = 0``).

    Raises
    ------
    InfeasibleGammaError
        If ``gamma <= γ_min`` (the message states γ_min).

    Warns
    -----
    NearGammaMinWarning
        If ``gamma < 1.03 γ_min`` (§5.4.4).
    """
    Md, Mu, Mx = _check_maps(Md, Mu, Mx)
    Q, R = _qr_u(Mu)
    Mdt = _project_out(Q, Md)
    Mxt = _project_out(Q, Mx)
    if Md.shape[1]:
        U, s, Vt = np.linalg.svd(Mdt, full_matrices=False)
        gmin = float(s[0]) if s.size else 0.0
    else:
        U, s, Vt = np.zeros((Md.shape[0], 0)), np.zeros(0), np.zeros((0, 0))
        gmin = 0.0
    if isinstance(gamma, bool) or not isinstance(gamma, numbers.Real):
        raise DataError(f"gamma must be a real number above gamma_min = {gmin:.6g}, got {gamma!r}")
    gamma = float(gamma)
    if not (gamma > gmin) or np.isnan(gamma):
        raise InfeasibleGammaError(gamma, gmin)
    if gamma < NEAR_GAMMA_MIN_RATIO * gmin:
        warnings.warn(
            f"gamma = {gamma:.6g} is within 3% of gamma_min = {gmin:.6g}: the gains are close to singular and "
            "the loop went unstable there in §5.4.4; prefer gamma >= 1.1 gamma_min",
            NearGammaMinWarning, stacklevel=3)
    if np.isinf(gamma) or Md.shape[1] == 0:
        d_gain = np.zeros((Md.shape[1], Mx.shape[1]))
    else:
        # (γ²I − VS²Vᵀ)⁻¹ V S Uᵀ = V diag(s / (γ² − s²)) Uᵀ, with γ² − s² = (γ − s)(γ + s) kept accurate.
        coef = s / ((gamma - s) * (gamma + s))
        d_gain = Vt.T @ (coef[:, None] * (U.T @ Mxt))
    u_gain = -solve_triangular(R, Q.T @ (Md @ d_gain + Mx), lower=False)
    return MinimaxSolution(gamma=gamma, gamma_min=gmin, u_gain=u_gain, d_gain=d_gain)
