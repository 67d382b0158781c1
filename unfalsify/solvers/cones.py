"""The two cones of the primal–dual methods: Nesterov–Todd scalings and Jordan algebra.

The primal–dual solvers (:mod:`~unfalsify.solvers.arx_pd` for (7.4), :mod:`~unfalsify.solvers.column_pd` for
(7.5)) work on ``K = S₊^{2n} × … × Q^{N+1}``: positive semidefinite blocks (the LMIs ``[δI T(h)ᵀ; T(h) δI] ⪰ 0``)
and one second-order cone (the noise ball).  What they share is written here once (Vandenberghe, *The CVXOPT
linear and quadratic cone program solvers*, 2010, §§ 4–5):

* the NT scaling of a pair of positive definite matrices (:func:`nt_scaling`, and :func:`nt_scaling_stack` for a
  stack of pairs), and of a pair of interior points of the second-order cone (:func:`soc_scaling`);
* the second-order cone's products with its scaling ``W_Q = β(2vvᵀ − J)`` and its inverse, the Jordan product and
  division, and the largest step to its boundary;
* the largest step to the boundary of the semidefinite cone in the scaled space (one block, or a stack).
"""
from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.sparse.linalg

__all__ = ["nt_scaling", "nt_scaling_stack", "soc_scaling", "sdp_step_stack"]


def nt_scaling(S: np.ndarray, Z: np.ndarray):
    """Nesterov–Todd scaling of the pair ``(S, Z)`` of positive definite matrices.

    Returns ``(Rinv, lam, Winv)``: ``R⁻¹ = Λ^{-1/2}QᵀLᵀ`` with ``Z = LLᵀ`` and ``LᵀSL = QΛ²Qᵀ``, so that
    ``R⁻¹ S R⁻ᵀ = Rᵀ Z R = diag(lam)``; and ``W⁻¹ = R⁻ᵀR⁻¹`` with ``W⁻¹ S W⁻¹ = Z`` (the NT point's inverse,
    whose blocks give the Schur complement).  Raises ``LinAlgError`` if either matrix is not positive definite.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> X, Y = rng.standard_normal((2, 4, 4))
    >>> S, Z = X @ X.T + np.eye(4), Y @ Y.T + np.eye(4)
    >>> Rinv, lam, Winv = nt_scaling(S, Z)
    >>> bool(np.allclose(Winv @ S @ Winv, Z)), bool(np.allclose(Rinv @ S @ Rinv.T, np.diag(lam)))
    (True, True)
    """
    L = scipy.linalg.cholesky(Z, lower=True, check_finite=False)
    G = L.T @ (S @ L)
    G = 0.5 * (G + G.T)
    lam2, Q = scipy.linalg.eigh(G, check_finite=False, driver="evd")
    if not lam2[0] > 0.0:
        raise np.linalg.LinAlgError("the NT scaling needs S ≻ 0 and Z ≻ 0")
    lam = np.sqrt(lam2)
    Rinv = (Q / np.sqrt(lam)).T @ L.T
    return Rinv, lam, Rinv.T @ Rinv


def soc_scaling(s: np.ndarray, z: np.ndarray):
    """Nesterov–Todd scaling ``W = β(2vvᵀ − J)`` of two interior points of the second-order cone.

    Returns ``(beta, v)`` with ``W = β(2vvᵀ − J)`` and ``W z = W⁻¹ s`` (CVXOPT's ``compute_scaling``: normalise
    s and z to unit J-norm, ``γ = √((1 + s̄ᵀz̄)/2)``, ``w̄ = (s̄ + Jz̄)/(2γ)`` (the scaling point),
    ``v = (w̄ + e)/√(2(w̄₀ + 1))``, ``β = (sᵀJs / zᵀJz)^{1/4}``); ``vᵀJv = 1``.
    """
    sn, zn = _jnorm(s), _jnorm(z)
    if not (sn > 0.0 and zn > 0.0 and s[0] > 0.0 and z[0] > 0.0):
        raise np.linalg.LinAlgError("the SOC scaling needs interior points")
    sb, zb = s / sn, z / zn
    gamma = np.sqrt(0.5 * (1.0 + float(sb @ zb)))
    wbar = sb.copy()
    wbar[0] += zb[0]
    wbar[1:] -= zb[1:]
    wbar /= 2.0 * gamma
    v = wbar
    v[0] += 1.0
    v /= np.sqrt(2.0 * v[0])  # v = (w̄ + e)/√(2(w̄₀ + 1)): vᵀJv = 1 and β(2vvᵀ − J) the NT matrix
    return np.sqrt(sn / zn), v


def _jnorm(x):
    """``√(x₀² − ‖x₁‖²)`` (0 outside the cone's interior)."""
    q = float(x[0] * x[0] - x[1:] @ x[1:])
    return np.sqrt(q) if q > 0.0 else 0.0


def _soc_w(beta, w, v):
    """``W_Q x = β(2v(vᵀx) − Jx)`` (``w`` the v of :func:`soc_scaling`)."""
    out = 2.0 * float(w @ v) * w
    out[0] -= v[0]
    out[1:] += v[1:]
    return beta * out


def _soc_winv(beta, w, v):
    """``W_Q⁻¹ x = (2Jv(vᵀJx) − Jx)/β``."""
    Jw = w.copy()
    Jw[1:] *= -1.0
    Jv = v.copy()
    Jv[1:] *= -1.0
    return (2.0 * float(w @ Jv) * Jw - Jv) / beta


def _soc_prod(x, y):
    """Jordan product ``x∘y = (xᵀy, x₀y₁ + y₀x₁)``."""
    return np.r_[x @ y, x[0] * y[1:] + y[0] * x[1:]]


def _soc_div(lam, r):
    """``x`` with ``lam∘x = r`` (lam in the cone's interior)."""
    l0, l1 = lam[0], lam[1:]
    x0 = (l0 * r[0] - l1 @ r[1:]) / (l0 * l0 - l1 @ l1)
    return np.r_[x0, (r[1:] - x0 * l1) / l0]


def _soc_step(x, d):
    """Largest α (inf if none) with ``x + αd`` in the second-order cone, x interior."""
    a = d[0] * d[0] - d[1:] @ d[1:]
    b = x[0] * d[0] - x[1:] @ d[1:]
    c = x[0] * x[0] - x[1:] @ x[1:]
    roots = np.roots([a, 2.0 * b, c]) if abs(a) > 1e-300 else ([-c / (2.0 * b)] if b != 0 else [])
    pos = [float(r.real) for r in np.atleast_1d(roots) if abs(np.imag(r)) <= 1e-12 * abs(r) and r.real > 0]
    if d[0] < 0:
        pos.append(-x[0] / d[0])
    return min(pos) if pos else np.inf


def _sdp_step(lam, dt, *, exact=False):
    """Largest α (inf if none) with ``diag(lam) + α dt ⪰ 0``: ``1/max(0, −λ_min(Λ^{-1/2} dt Λ^{-1/2}))``.

    λ_min by Lanczos (ARPACK, O(N²) per product) unless ``exact`` or it does not converge (then LAPACK's
    smallest eigenvalue, O(N³)).  A Lanczos value lies above λ_min by at most its tolerance, so the step can
    overshoot by a relative ~1e-8; the caller's fraction to the boundary (0.99) and its Cholesky check of the
    new point cover that."""
    r = 1.0 / np.sqrt(lam)
    D = dt * r[:, None]
    D *= r[None, :]
    low = None
    if not exact and D.shape[0] > 60:
        try:
            low = float(scipy.sparse.linalg.eigsh(D, k=1, which="SA", tol=1e-8, return_eigenvectors=False,
                                                  ncv=min(D.shape[0], 40))[0])
        except scipy.sparse.linalg.ArpackNoConvergence:
            low = None
    if low is None:
        low = float(scipy.linalg.eigvalsh(D, subset_by_index=[0, 0], driver="evr", check_finite=False)[0])
    return np.inf if low >= 0.0 else -1.0 / low


def nt_scaling_stack(S: np.ndarray, Z: np.ndarray):
    """:func:`nt_scaling` of every pair ``(S_k, Z_k)`` of a stack (j, N, N), by numpy's batched LAPACK.

    Returns ``(Rinv, lam, Winv)`` stacked: ``R⁻¹_k S_k R⁻ᵀ_k = Rᵀ_k Z_k R_k = diag(lam_k)``, ``W⁻¹_k S_k W⁻¹_k = Z_k``.
    Raises ``LinAlgError`` if some matrix is not positive definite.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> X, Y = rng.standard_normal((2, 3, 4, 4))
    >>> S, Z = X @ X.transpose(0, 2, 1) + np.eye(4), Y @ Y.transpose(0, 2, 1) + np.eye(4)
    >>> Rinv, lam, Winv = nt_scaling_stack(S, Z)
    >>> bool(np.allclose(Winv @ S @ Winv, Z)), bool(np.allclose(Winv[1], nt_scaling(S[1], Z[1])[2]))
    (True, True)
    """
    L = np.linalg.cholesky(Z)
    G = np.swapaxes(L, -1, -2) @ S @ L
    G = 0.5 * (G + np.swapaxes(G, -1, -2))
    lam2, Q = np.linalg.eigh(G)
    if not np.all(lam2[..., 0] > 0.0):
        raise np.linalg.LinAlgError("the NT scaling needs S ≻ 0 and Z ≻ 0")
    lam = np.sqrt(lam2)
    B = L @ (Q / np.sqrt(lam)[..., None, :])  # R⁻ᵀ
    return np.swapaxes(B, -1, -2), lam, B @ np.swapaxes(B, -1, -2)


def sdp_step_stack(lam: np.ndarray, dt: np.ndarray) -> float:
    """Largest α (inf if none) with ``diag(lam_k) + α dt_k ⪰ 0`` for every k of a stack (exact: LAPACK's
    eigenvalues of ``Λ^{-1/2} dt Λ^{-1/2}``, one batched call).

    Examples
    --------
    >>> import numpy as np
    >>> sdp_step_stack(np.array([[1.0, 4.0], [2.0, 2.0]]), np.array([np.diag([-2.0, 0.0]), np.diag([1.0, 1.0])]))
    0.5
    """
    r = 1.0 / np.sqrt(lam)
    D = dt * r[..., :, None]
    D *= r[..., None, :]
    low = float(np.min(np.linalg.eigvalsh(D)[..., 0]))
    return np.inf if low >= 0.0 else -1.0 / low
