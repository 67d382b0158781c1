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

computed here from a Householder QR of ``M_u`` (``X = Qcᵀ M_d``, ``Qc`` an orthonormal basis
of range(M_u)^⊥, so ``(I − P_u) M_d = Qc X``) and the largest eigenvalue of ``XᵀX``
(``γ_min² = λ_max(XᵀX)``; no bisection on γ, no normal equations of ``M_u``).  The same
factorisation decides feasibility and gives the gains: a level is accepted only above :func:`feasibility_threshold` (γ_min plus the
accuracy of its computation), so ``solve_minimax(..., gamma=minimax_gamma_min(...))``
always raises instead of returning gains from a numerically singular saddle.

Saddle point (3.31).  ``[d_wc; u_opt] = −Hess⁻¹ [M_d M_u]ᵀ M_x x``, evaluated stably:
with ``M_u = Q R`` and ``M̃ = (I − QQᵀ)M``,

    d_wc  = (γ²I − XᵀX)⁻¹ Xᵀ Qcᵀ M_x x         (Cholesky of γ²I − XᵀX; SVD of X near γ_min),
    u_opt = −R⁻¹ Qᵀ (M_d d_wc + M_x x).
"""
from __future__ import annotations

import numbers
import warnings
from dataclasses import dataclass

import numpy as np
from scipy.linalg import blas, lapack

from .exceptions import InfeasibleGammaError, NearGammaMinWarning

from ._validation import DataError, as_real_array, check_nonnegative
from ._repr import result

__all__ = [
    "InfeasibleGammaError",
    "MinimaxSolution",
    "NearGammaMinWarning",
    "NEAR_GAMMA_MIN_RATIO",
    "feasibility_threshold",
    "minimax_gamma_min",
    "solve_minimax",
]

#: Below ``1.03 γ_min`` the §5.4.4 design example went unstable.
NEAR_GAMMA_MIN_RATIO = 1.03


@result
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
    route : str
        How ``d_gain`` was solved: ``"cholesky"`` (``γ²I − M̃_dᵀM̃_d`` factored, ``γ ≥ 1.03 γ_min``),
        ``"svd"`` (the SVD of ``M̃_d``, nearer γ_min) or ``"none"`` (``γ = ∞`` or no disturbance).
    """

    gamma: float
    gamma_min: float
    u_gain: np.ndarray
    d_gain: np.ndarray
    route: str = "svd"


#: entries at or above this make the maps' Gram matrices overflow (about sqrt of the largest float, over the
#: rows' count allowance): refused with a DataError instead of LAPACK's failure
_ENTRY_LIMIT = 1e150


def _check_maps(Md, Mu, Mx=None):
    # as_real_array: a complex map had lost its imaginary part with only a ComplexWarning
    Mu = as_real_array(Mu, "M_u")
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
        if a.size and not float(np.max(np.abs(a))) < _ENTRY_LIMIT:  # its Gram would overflow (LinAlgError)
            raise DataError(f"{name} holds entries near {np.max(np.abs(a)):.3g}, whose squares overflow: scale the "
                            "performance outputs (the weights) so the maps are of moderate size")
    return Md, Mu, Mx


def _rows_like(M, rows: int, name: str) -> np.ndarray:
    """``M`` as a 2-D array with ``rows`` rows (a 1-D array of that length is one column)."""
    M = as_real_array(M, name)
    if M.ndim == 1 and M.size == rows:
        M = M[:, None]
    if M.ndim != 2 or M.shape[0] != rows:
        raise DataError(
            f"{name} has shape {M.shape} but the performance map has {rows} rows (those of M_u): "
            "M_d, M_u and M_x must have the same number of rows")
    return M


def _qr_u(Mu):
    """Householder QR of M_u (LAPACK ``dgeqrf``) with a check that M_uᵀM_u > 0 (the ``im`` positive eigenvalues).

    Returns the reflectors ``(qr, tau)`` of ``M_u = Q_full [R; 0]`` and ``R`` as the leading square
    block of ``qr`` (its upper triangle; the reflectors below are not read by the upper-triangular
    solve of :func:`_gains`); the first ``dim u`` columns of ``Q_full`` span range(M_u), the others
    (``Qc``) its orthogonal complement.  ``Q_full`` is never formed: :func:`_apply_qt` applies
    ``Q_fullᵀ`` to the other blocks.
    """
    k = Mu.shape[1]
    qr, tau, _, info = lapack.dgeqrf(Mu)
    if info != 0:  # pragma: no cover - an argument error, not a property of the data
        raise ValueError(f"LAPACK dgeqrf: illegal argument {-info}")
    R = qr[:k, :k]
    d = np.abs(np.diagonal(R))
    scale = max(np.linalg.norm(Mu), np.finfo(float).tiny)  # Frobenius: cheap upper bound on ‖M_u‖₂
    if Mu.shape[0] < Mu.shape[1] or d.min() <= max(Mu.shape) * np.finfo(float).eps * scale:
        raise DataError(
            "M_u does not have full column rank, so M_uᵀM_u is singular and the minimisation over u has no "
            "unique solution; check that W2 has a full-rank feedthrough (relative degree 0)")
    return qr, tau, R


def _apply_qt(qr, tau, M):
    """``Q_fullᵀ M`` (LAPACK ``dormqr``): rows ``:dim u`` are ``Qᵀ M``, the rest ``Qcᵀ M``."""
    if M.shape[1] == 0:
        return np.zeros(M.shape)
    out, _, info = lapack.dormqr("L", "T", qr, tau, M, max(1, 64 * M.shape[1]))
    if info != 0:  # pragma: no cover
        raise ValueError(f"LAPACK dormqr: illegal argument {-info}")
    return out


#: Safety factor of :func:`feasibility_threshold` over the first-order error estimate.
_THRESHOLD_SAFETY = 8.0


@dataclass(frozen=True, eq=False)
class _Saddle:
    """The factorisations every γ decision and every gain is computed from (computed once)."""

    R: np.ndarray  # upper triangle: R of M_u = Q R (below it: Householder vectors)
    QtMd: np.ndarray  # Qᵀ M_d (Q: orthonormal basis of range(M_u))
    QtMx: np.ndarray | None  # Qᵀ M_x  (None when only γ_min is wanted)
    QcMx: np.ndarray | None  # Qcᵀ M_x (Qc: orthonormal basis of range(M_u)^⊥)
    X: np.ndarray  # Qcᵀ M_d: (I − P_u) M_d = Qc X
    XtX: np.ndarray | None  # Xᵀ X, lower triangle (None when X has no entries)
    gamma_min: float
    threshold: float


def feasibility_threshold(Md, Mu, gamma_min: float) -> float:
    """Smallest level this engine accepts: ``γ_min + τ``, ``τ = 8 · max(r, c) · eps · ‖M_d‖_F``.

    The computed ``γ_min`` is the square root of the largest eigenvalue of ``XᵀX``, ``X = Qcᵀ M_d``
    the computed ``(I − Q Qᵀ) M_d`` in the basis ``Qc``.  Householder QR and its application are
    backward stable, so ``X`` is exact for maps perturbed by ``O(max(r, c) · eps)`` relative to their
    size (``r`` rows, ``c`` columns of ``[M_d M_u]``); forming ``XᵀX`` and the symmetric eigensolver
    add an error ``O(dim d · eps · ‖X‖₂²)`` to ``λ_max = ‖X‖₂²``, i.e. ``O(dim d · eps · ‖X‖₂)`` to its
    square root.  By Weyl's inequality the computed ``γ_min`` is within about
    ``max(r, c) · eps · ‖M_d‖₂ ≤ max(r, c) · eps · ‖M_d‖_F`` of the true one.  A level closer to
    the computed ``γ_min`` than that (times the safety factor 8) cannot be told apart from
    ``γ_min`` itself: the saddle Hessian ``γ²I − M̃_dᵀM̃_d`` is then numerically singular and its
    inertia (3.29) is not decided by the data, so :func:`solve_minimax` refuses it.

    Parameters
    ----------
    Md, Mu : ndarray
        The performance map's disturbance and control blocks.
    gamma_min : float
        The computed ``γ_min`` (:func:`minimax_gamma_min`), a finite number ``≥ 0``.

    Returns
    -------
    float
        ``γ_min + τ``, i.e. ``γ_min (1 + k eps)`` with ``k = 8 max(r, c) ‖M_d‖_F / γ_min``.

    Raises
    ------
    DataError
        Maps that are not real finite matrices with the same number of rows; ``gamma_min`` not a finite
        number ``≥ 0`` (NaN had given a NaN threshold, which no level passes).

    Examples
    --------
    The margin is a few units of rounding above ``γ_min = 2``:

    >>> import numpy as np
    >>> Md, Mu = np.array([[1.0], [2.0]]), np.array([[1.0], [0.0]])
    >>> t = feasibility_threshold(Md, Mu, minimax_gamma_min(Md, Mu))
    >>> 2.0 < t < 2.0 + 1e-12
    True
    """
    Md, Mu, _ = _check_maps(Md, Mu)
    return _threshold(Md, Mu, check_nonnegative(gamma_min, "gamma_min"))


def _threshold(Md: np.ndarray, Mu: np.ndarray, gamma_min: float) -> float:
    """:func:`feasibility_threshold` of checked maps (``_saddle``'s, already checked by its caller)."""
    rows, cols = Md.shape[0], Md.shape[1] + Mu.shape[1]
    tau = _THRESHOLD_SAFETY * max(rows, cols) * np.finfo(float).eps * float(np.linalg.norm(Md))
    return float(gamma_min + tau)


def _largest_eigenvalue(S: np.ndarray) -> float:
    """Largest eigenvalue of the symmetric ``S`` (lower triangle read; LAPACK ``dsyevr``, that one only).

    Householder tridiagonalisation then bisection: backward stable, so the computed value is the
    exact one of ``S + E`` with ``‖E‖₂ = O(n·eps·‖S‖₂)`` — for ``S = XᵀX`` a relative error of
    ``O(n·eps)`` in ``λ_max = ‖X‖₂²`` (squaring loses accuracy only in the *small* singular values).
    """
    n = S.shape[0]
    w, _, _, _, info = lapack.dsyevr(S, compute_v=0, range="I", il=n, iu=n, lower=1)
    if info != 0:  # pragma: no cover - bisection does not fail on finite input
        raise np.linalg.LinAlgError(f"LAPACK dsyevr failed (info = {info})")
    return float(w[0])


def _saddle(Md, Mu, Mx=None) -> _Saddle:
    """QR of ``M_u`` and ``γ_min = ‖(I − P_u) M_d‖₂``, with its threshold, from one computation.

    ``(I − P_u) M_d = Qc X`` with ``X = Qcᵀ M_d`` and ``Qc`` orthonormal, so
    ``γ_min = ‖X‖₂ = √λ_max(XᵀX)`` (3.29): the largest eigenvalue of the ``dim d``-square ``XᵀX``
    (:func:`_largest_eigenvalue`, about 5× cheaper here than the SVD of ``X`` and as accurate for
    the *largest* singular value).  The Householder reflectors are applied to ``M_d`` and (for the
    gains) ``M_x`` separately, so that γ_min does not depend on whether ``M_x`` is given
    (:func:`minimax_gamma_min` equals the γ_min of :func:`solve_minimax` to the last bit).
    """
    qr, tau, R = _qr_u(Mu)
    k = Mu.shape[1]
    T = _apply_qt(qr, tau, Md)
    TX = None if Mx is None else _apply_qt(qr, tau, Mx)
    X = T[k:]
    if X.size:
        XtX = blas.dsyrk(1.0, X, trans=1, lower=1)  # lower triangle of XᵀX (upper left zero)
        gmin = float(np.sqrt(max(_largest_eigenvalue(XtX), 0.0)))
    else:
        XtX, gmin = None, 0.0
    return _Saddle(R=R, QtMd=T[:k], QtMx=None if TX is None else TX[:k],
                   QcMx=None if TX is None else TX[k:], X=X, XtX=XtX, gamma_min=gmin,
                   threshold=_threshold(Md, Mu, gmin))


def minimax_gamma_min(Md, Mu) -> float:
    """Exact threshold ``γ_min = ‖(I − P_u) M_d‖₂`` of the saddle condition (3.29).

    Computed by the same QR and eigenvalue problem as :func:`solve_minimax`, so passing the value returned
    here back as ``gamma`` always raises :class:`InfeasibleGammaError`.  Returns 0 when there
    are no disturbances.

    Examples
    --------
    ``z = [d + u; 2d]``: ``u`` cancels the first row, the second leaves ``γ_min = 2``:

    >>> import numpy as np
    >>> round(minimax_gamma_min(np.array([[1.0], [2.0]]), np.array([[1.0], [0.0]])), 6)
    2.0

    The same as the norm of the projected map ``(I − P_u) M_d``:

    >>> rng = np.random.default_rng(0)
    >>> Md, Mu = rng.standard_normal((6, 2)), rng.standard_normal((6, 3))
    >>> Pu = Mu @ np.linalg.pinv(Mu)
    >>> bool(np.isclose(minimax_gamma_min(Md, Mu), np.linalg.norm(Md - Pu @ Md, 2)))
    True
    """
    Md, Mu, _ = _check_maps(Md, Mu)
    return _saddle(Md, Mu).gamma_min


def _level(gamma, sd: _Saddle) -> float:
    """The level to use: a number, or ``gamma(γ_min)`` for a policy; checked against the threshold."""
    if callable(gamma) and not isinstance(gamma, numbers.Real):
        gamma = gamma(sd.gamma_min)
        what = "gamma returned by the gamma policy"
    else:
        what = "gamma"
    if isinstance(gamma, bool) or not isinstance(gamma, numbers.Real):
        raise DataError(f"{what} must be a real number above gamma_min = {sd.gamma_min:.6g}, got {gamma!r}")
    gamma = float(gamma)
    if np.isnan(gamma) or not gamma > sd.threshold:
        raise InfeasibleGammaError(gamma, sd.gamma_min, sd.threshold)
    return gamma


#: Routes of the worst-case disturbance gain ``(γ²I − XᵀX)⁻¹ Xᵀ Qcᵀ M_x``: a Cholesky factor of
#: ``γ²I − XᵀX`` when ``γ ≥ NEAR_GAMMA_MIN_RATIO · γ_min`` (its condition number is then at most
#: ``1/(1 − 1/1.03²) ≈ 17``), the SVD of ``X`` closer to γ_min (where ``γ² − σ²`` must be formed as
#: ``(γ − σ)(γ + σ)`` to stay accurate).
_D_ROUTES = ("auto", "cholesky", "svd")


def _d_gain_cholesky(sd: _Saddle, gamma: float):
    """``(γ²I − XᵀX)⁻¹ Xᵀ (Qcᵀ M_x)`` by Cholesky (LAPACK ``dpotrf``/``dpotrs``); ``None`` if not definite."""
    H = -sd.XtX  # lower triangle of −XᵀX
    np.fill_diagonal(H, H.diagonal() + gamma * gamma)
    C, info = lapack.dpotrf(H, lower=1, overwrite_a=1, clean=0)
    if info != 0:
        return None
    D, info = lapack.dpotrs(C, sd.X.T @ sd.QcMx, lower=1, overwrite_b=1)
    return D if info == 0 else None


def _d_gain_svd(sd: _Saddle, gamma: float) -> np.ndarray:
    """``(γ²I − XᵀX)⁻¹ Xᵀ (Qcᵀ M_x) = V diag(s / ((γ − s)(γ + s))) Uᵀ Qcᵀ M_x`` from the SVD ``X = U S Vᵀ``."""
    U, s, Vt = np.linalg.svd(sd.X, full_matrices=False)
    coef = s / ((gamma - s) * (gamma + s))
    return Vt.T @ (coef[:, None] * (U.T @ sd.QcMx))


def _gains(sd: _Saddle, gamma: float, route: str = "auto"):
    """Saddle-point gains ``(u_gain, d_gain, route)`` (3.31) for an accepted level ``gamma``.

    ``d_wc = (γ²I − M̃_dᵀM̃_d)⁻¹ M̃_dᵀ M̃_x x``: the left vectors of ``M̃_d = Qc X`` are in
    range(Qc), so ``M̃_dᵀ M̃_x = Xᵀ Qcᵀ M_x`` (``Qcᵀ P_u = 0``); by :func:`_d_gain_cholesky` or, near
    γ_min or if ``γ²I − XᵀX`` is not numerically definite, :func:`_d_gain_svd` (``route`` forces one,
    for tests).  Then ``u_opt = −R⁻¹ Qᵀ (M_d d_wc + M_x x)``.
    """
    if route not in _D_ROUTES:
        raise DataError(f"unknown route {route!r}; use one of {_D_ROUTES}")
    nd, nx = sd.X.shape[1], sd.QtMx.shape[1]
    if np.isinf(gamma) or nd == 0:
        d_gain, route = np.zeros((nd, nx)), "none"
    else:
        d_gain = None
        if route == "cholesky" or (route == "auto" and gamma >= NEAR_GAMMA_MIN_RATIO * sd.gamma_min):
            d_gain = None if sd.XtX is None else _d_gain_cholesky(sd, gamma)
            route = "cholesky"
        if d_gain is None:
            d_gain, route = _d_gain_svd(sd, gamma), "svd"
    B = sd.QtMd @ d_gain
    B += sd.QtMx
    u_gain, info = lapack.dtrtrs(sd.R, B, lower=0, overwrite_b=1)
    if info != 0:  # pragma: no cover - _qr_u refuses a singular R
        raise np.linalg.LinAlgError(f"LAPACK dtrtrs: singular R (info = {info})")
    return np.negative(u_gain, out=u_gain), d_gain, route


def _warn_near(gamma: float, gmin: float, stacklevel: int) -> None:
    if gamma < NEAR_GAMMA_MIN_RATIO * gmin:
        warnings.warn(
            f"gamma = {gamma:.6g} is within 3% of gamma_min = {gmin:.6g}: the gains are close to singular and "
            "the loop went unstable there in §5.4.4; prefer gamma >= 1.1 gamma_min",
            NearGammaMinWarning, stacklevel=stacklevel + 1)


def solve_minimax(Md, Mu, Mx, gamma) -> MinimaxSolution:
    """Saddle-point gains of the game (3.31) for a level ``gamma > γ_min``.

    Parameters
    ----------
    Md, Mu, Mx : array_like
        Performance map ``z = M_d d + M_u u + M_x x`` (same number of rows).
    gamma : float or callable
        Level; ``numpy.inf`` gives the LQ limit (``d_wc = 0``).  A callable is a γ policy: it
        receives ``γ_min`` (computed once, from the same factorisation as the gains) and returns
        the level.

    Returns
    -------
    MinimaxSolution
        Its :attr:`~MinimaxSolution.route` names how the disturbance gain was solved.

    Raises
    ------
    InfeasibleGammaError
        If ``gamma`` is not above :func:`feasibility_threshold` (``γ_min`` plus the accuracy of its
        computation, relative ``O(max(r, c) eps)``); the message states γ_min.  ``gamma = γ_min``
        exactly and ``np.nextafter(γ_min, inf)`` always raise.
    DataError
        Non-numeric ``gamma``, NaN maps, rank-deficient ``M_u``, mismatched shapes.

    Warns
    -----
    NearGammaMinWarning
        If ``gamma < 1.03 γ_min`` (§5.4.4).

    Examples
    --------
    ``z = [d + u + x; 2d + x]`` at ``γ = 4``: ``u = −(d + x)`` cancels the first row, and the worst
    ``d`` maximises ``(2d + x)² − 16 d²``, i.e. ``d = x/6`` and ``u = −7x/6``:

    >>> import numpy as np
    >>> Md, Mu, Mx = np.array([[1.0], [2.0]]), np.array([[1.0], [0.0]]), np.array([[1.0], [1.0]])
    >>> sol = solve_minimax(Md, Mu, Mx, 4.0)
    >>> round(float(sol.u_gain[0, 0]), 4), round(float(sol.d_gain[0, 0]), 4), sol.route
    (-1.1667, 0.1667, 'cholesky')

    ``γ = ∞`` is the LQ limit (no disturbance); a policy receives ``γ_min``; ``γ_min`` itself is refused:

    >>> solve_minimax(Md, Mu, Mx, np.inf).u_gain
    array([[-1.]])
    >>> round(solve_minimax(Md, Mu, Mx, lambda gmin: 1.1 * gmin).gamma, 6)
    2.2
    >>> solve_minimax(Md, Mu, Mx, minimax_gamma_min(Md, Mu))
    Traceback (most recent call last):
    ...
    synthesis.exceptions.InfeasibleGammaError: gamma = 2 is not above gamma_min = 2: the level-gamma problem has no saddle point (3.29). Choose gamma > gamma_min, e.g. gamma = 1.1 * gamma_min = 2.2 (§5.1 comment 4)
    """
    if Mx is None:  # optional in _check_maps (γ_min needs no state map); here it had raised AttributeError
        raise DataError("solve_minimax needs M_x, the map of the state x (initial conditions, past data) in "
                        "z = M_d d + M_u u + M_x x; pass an array with no columns if the performance has no state term")
    Md, Mu, Mx = _check_maps(Md, Mu, Mx)
    sd = _saddle(Md, Mu, Mx)
    gamma = _level(gamma, sd)
    _warn_near(gamma, sd.gamma_min, stacklevel=3)
    u_gain, d_gain, route = _gains(sd, gamma)
    return MinimaxSolution(gamma=gamma, gamma_min=sd.gamma_min, u_gain=u_gain, d_gain=d_gain, route=route)
