"""Subspace uncertainty-model unfalsification, thesis §7.3 and program (7.5) (SISO).

Error model: ``Y_f − [L_w L_u][W_p; U_f] = E = Ξ + Δ̄(q) U_f``, where ``Δ̄`` is a set of j
causal LTI operators, operator k acting on column k of ``U_f`` (system at rest at the
start of each column), and ``(1/(ij))‖Ξ‖_F² ≤ σ²``.  The smallest common bound δ on
``‖Δ_k‖∞`` that unfalsifies the data is (7.5):

    δ = min δ  s.t.  T((E − Ξ)_{:,k})ᵀ T(·) ⪯ δ² T((U_f)_{:,k})ᵀ T((U_f)_{:,k})   ∀k.

``form="conditioned"`` (default)
    Per column ``(E − Ξ)_{:,k} = T((U_f)_{:,k}) h_k`` with ``‖T(h_k)‖₂ ≤ δ`` (an exact
    reformulation when ``(U_f)_{0,k} ≠ 0``, by Theorem 7.1), and ``‖Ξ‖_F ≤ σ√(ij)``.
    With ``eliminate_L=True`` the predictor is eliminated analytically: for given impulses
    the smallest ``‖Ξ‖_F`` over ``L`` is ``‖(Y_f − H̃) N‖_F`` with ``N`` an orthonormal basis
    of the null space of ``A = [W_p; U_f]`` (``NNᵀ = I − P_A``), ``H̃_{:,k} = T((U_f)_{:,k}) h_k``.
    ``L = (Y_f − H̃) A⁺`` is recovered afterwards (then ``Ξ = (Y_f − H̃)(I − P_A)``).
``form="thesis"``
    The literal LMIs of §7.3: ``[σ vec(Ξ)ᵀ/√(ij); vec(Ξ)/√(ij) σI] ⪰ 0`` and, per column,
    ``[δ T(U_f,k)ᵀT(U_f,k)  T((E−Ξ)_k)ᵀ; T((E−Ξ)_k)  δI] ⪰ 0``.  Tiny sizes only.

Layout follows :class:`synthesis.Predictor`: ``W_p = [U_p; Y_p]``, ``L_w`` is ``i × 2i`` and
``L_u`` is ``i × i`` (SISO); column k of ``U_f`` is ``[u_{i+k} … u_{2i−1+k}]`` (0-based k).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import cvxpy as cp
import numpy as np
import scipy.linalg
import scipy.sparse as sp

from synthesis import Predictor, block_hankel
from synthesis._validation import DataError, check_horizon

from ._common import (
    COND_WARN,
    Certificate,
    IllConditionedWarning,
    check_form,
    check_sigma,
    rms_or_one,
    siso_signal,
    solve,
    solved_value,
)
from ._lmi import toeplitz_expr, toeplitz_norm_lmi
from ._toeplitz import deconvolve, toeplitz_cond, toeplitz_matrix, toeplitz_norm

__all__ = ["SubspaceResult", "subspace_unfalsify", "subspace_data"]


@dataclass(frozen=True, eq=False)
class SubspaceResult:
    """Solution of the subspace unfalsification program (7.5).

    Attributes
    ----------
    delta : float
        δ_unf (NaN if the solve failed).
    Lw : ndarray, shape (i, 2i)
    Lu : ndarray, shape (i, i)
        Predictor of the unfalsified model, same layout as :class:`synthesis.Predictor`.
    noise : ndarray, shape (i, j)
        Ξ.
    impulses : ndarray, shape (i, j)
        Column k is h_k, the first i Markov parameters of Δ_k:
        ``(E − Ξ)_{:,k} = T((U_f)_{:,k}) h_k``.
    status : str
    solve_time : float
        Wall time of ``problem.solve`` (includes cvxpy compilation).
    problem : cvxpy.Problem
        The problem as solved (in rms-scaled units, see ``scale``).
    form : str
    eliminate_L : bool
        Whether the predictor was eliminated analytically (conditioned form).
    sigma : float
    horizon, n_columns : int
        i and j.
    cond_Tu : float
        ``max_k cond₂ T((U_f)_{:,k})``.
    certificate : Certificate
        δ recomputed as ``max_k ‖T(h_k)‖₂`` from the returned Ξ and L, and ``‖Ξ‖_F/√(ij)``.
    scale : tuple of float
        ``(s_u, s_y)``: the problem was posed on ``u/s_u``, ``y/s_y`` (``s_u`` = rms of u,
        ``s_y`` = rms of the predictor residual).
    regressor_singular_values : ndarray
        Singular values of ``A = [W_p; U_f]``.
    """

    delta: float
    Lw: np.ndarray
    Lu: np.ndarray
    noise: np.ndarray
    impulses: np.ndarray
    status: str
    solve_time: float
    problem: cp.Problem
    form: str
    eliminate_L: bool
    sigma: float
    horizon: int
    n_columns: int
    cond_Tu: float
    certificate: Certificate
    scale: tuple
    regressor_singular_values: np.ndarray

    @property
    def max_violation(self) -> float:
        """Shortcut for ``certificate.max_violation``."""
        return self.certificate.max_violation

    @property
    def predictor(self) -> Predictor:
        """``(L_w, L_u)`` as a :class:`synthesis.Predictor` (e.g. for :func:`synthesis.hinf_design`)."""
        s = self.regressor_singular_values
        tol = max(3 * self.horizon, self.n_columns) * np.finfo(float).eps * (s[0] if s.size else 1.0)
        return Predictor(
            Lw=self.Lw,
            Lu=self.Lu,
            horizon=self.horizon,
            m=1,
            l=1,
            n_columns=self.n_columns,
            singular_values=s,
            rank=int(np.count_nonzero(s > tol)),
            method=f"unfalsified-{self.form}",
        )


def subspace_data(u, y, horizon: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A, U_f, Y_f)`` with ``A = [U_p; Y_p; U_f]`` (3i × j), SISO, j = n − 2i + 1 (§2.1)."""
    u = siso_signal(u, "u")
    y = siso_signal(y, "y", n=u.size)
    i = check_horizon(horizon, u.size)
    j = u.size - 2 * i + 1
    Up = block_hankel(u, i, j, 0)
    Yp = block_hankel(y, i, j, 0)
    Uf = block_hankel(u, i, j, i)
    Yf = block_hankel(y, i, j, i)
    return np.vstack([Up, Yp, Uf]), Uf, Yf


def _column_toeplitz_operator(Uf: np.ndarray) -> sp.csr_matrix:
    """Block-diagonal sparse matrix mapping ``vec_F(H)`` to ``vec_F(H̃)``, ``H̃_{:,k} = T(U_f[:,k]) h_k``."""
    return sp.block_diag([sp.csr_matrix(np.tril(toeplitz_matrix(Uf[:, k]))) for k in range(Uf.shape[1])], format="csr")


def _l_value(L, L_fixed, Lscale, i) -> np.ndarray:
    if L_fixed is not None:
        return L_fixed.copy()
    if L.value is None:
        return np.full((i, 3 * i), np.nan)
    return np.asarray(L.value, float) * Lscale


def subspace_unfalsify(
    u,
    y,
    horizon: int,
    sigma: float,
    *,
    form: str = "conditioned",
    eliminate_L: bool = False,
    predictor=None,
    solver: str = "CLARABEL",
    solver_options: dict | None = None,
) -> SubspaceResult:
    """Smallest δ bounding the column operators ``Δ_k`` that unfalsify the subspace model: (7.5).

    Parameters
    ----------
    u, y : array_like, shape (n,) or (n, 1)
        SISO data; ``j = n − 2i + 1`` columns.
    horizon : int
        The prediction horizon i.
    sigma : float
        Admissible rms noise level σ > 0 of Ξ (units of y).
    form : {"conditioned", "thesis"}
        See the module docstring.
    eliminate_L : bool
        Conditioned form only: eliminate ``[L_w L_u]`` analytically (fewer variables, a denser
        noise cone; see ``experiments/bench_unfalsify.py`` for which is faster).
    predictor : synthesis.Predictor, optional
        Fix ``[L_w L_u]`` to a given SISO predictor of horizon i (e.g. a least-squares fit on a
        longer record) and compute the δ of that model: (7.5) with L a constant.  Default: L is
        optimised jointly with Ξ and the impulses, as in the thesis.
    solver : str
        cvxpy solver, passed explicitly.
    solver_options : dict, optional
        Extra keyword arguments for ``Problem.solve``.

    Returns
    -------
    SubspaceResult

    Raises
    ------
    DataError
        NaN/inf, lengths, MIMO, bad horizon / too few samples, σ ≤ 0, or a column of ``U_f``
        whose first entry ``u_{i+k}`` is 0 (``T((U_f)_{:,k})`` singular: the reformulation and
        Theorem 7.1 need it invertible; a ±1 PRBS never has zeros).
    UnfalsificationError
        Solver failure or infeasible/unbounded status.

    Warns
    -----
    SolverWarning, IllConditionedWarning
        As for :func:`unfalsify.arx_unfalsify`.
    """
    form = check_form(form)
    u = siso_signal(u, "u")
    y = siso_signal(y, "y", n=u.size)
    sigma = check_sigma(sigma)
    A, Uf, Yf = subspace_data(u, y, horizon)
    i, j = Uf.shape
    zero_cols = np.flatnonzero(Uf[0] == 0.0)
    if zero_cols.size:
        raise DataError(
            f"{zero_cols.size} column(s) of U_f start with a zero input (first: column {zero_cols[0]}, "
            f"u[{i + zero_cols[0]}] = 0): T((U_f)_{{:,k}}) is singular there; use an input with no zero "
            "samples (e.g. a ±1 PRBS)"
        )
    cond = max(toeplitz_cond(Uf[:, k]) for k in range(j))
    if form == "thesis" and not cond <= COND_WARN:
        warnings.warn(
            f"form='thesis' with max_k cond T((U_f)_k) = {cond:.3g}: the literal LMI is numerically "
            "singular; prefer form='conditioned'",
            IllConditionedWarning,
            stacklevel=2,
        )
    if form == "thesis" and eliminate_L:
        raise ValueError("eliminate_L applies to form='conditioned' only")
    L_fixed = None
    if predictor is not None:
        if eliminate_L:
            raise ValueError("eliminate_L and a fixed predictor exclude each other")
        L_fixed = np.hstack([np.asarray(predictor.Lw, float), np.asarray(predictor.Lu, float)])
        if int(predictor.horizon) != i or L_fixed.shape != (i, 3 * i) or not np.all(np.isfinite(L_fixed)):
            raise DataError(
                f"predictor must be a finite SISO predictor of horizon {i} (Lw {i}×{2 * i}, Lu {i}×{i}); "
                f"got horizon {predictor.horizon}, [Lw Lu] of shape {L_fixed.shape}"
            )

    # u to unit rms; y so that the residual of the predictor (least squares, or the fixed one)
    # has unit rms: that is the error the program splits between Ξ and Δ̄U_f
    su = rms_or_one(u)
    Lref = L_fixed if L_fixed is not None else np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T
    sy = rms_or_one(Yf - Lref @ A)
    if not sy > 1e-12 * rms_or_one(y):
        sy = rms_or_one(y)
    As = A.copy()
    As[:i] /= su
    As[i : 2 * i] /= sy
    As[2 * i :] /= su
    Ufs, Yfs, sig_s = Uf / su, Yf / sy, sigma / sy
    bound = sig_s * np.sqrt(i * j)

    delta = cp.Variable(name="delta")
    Lscale = np.concatenate([np.full(i, sy / su), np.ones(i), np.full(i, sy / su)])  # L_orig = L_s * sy/s_col
    L = None if L_fixed is None else cp.Constant(L_fixed / Lscale)
    if form == "conditioned":
        H = cp.Variable((i, j), name="H")
        Bop = _column_toeplitz_operator(Ufs)
        Ht = cp.reshape(Bop @ cp.vec(H, order="F"), (i, j), order="F")
        if eliminate_L:
            N = scipy.linalg.null_space(As)
            resid = (Yfs - Ht) @ N if N.shape[1] else None
            noise_con = [cp.norm(cp.vec(resid, order="F"), 2) <= bound] if resid is not None else []
        else:
            L = cp.Variable((i, 3 * i), name="L") if L is None else L
            resid = Yfs - L @ As - Ht
            noise_con = [cp.norm(cp.vec(resid, order="F"), 2) <= bound]
        cons = noise_con + [toeplitz_norm_lmi(H[:, k], delta, i) for k in range(j)]
    else:
        L = cp.Variable((i, 3 * i), name="L") if L is None else L
        Xi = cp.Variable((i, j), name="Xi")
        G = Yfs - L @ As - Xi
        xv = cp.reshape(cp.vec(Xi, order="F"), (i * j, 1), order="F") / np.sqrt(i * j)
        cons = [cp.bmat([[np.array([[sig_s]]), xv.T], [xv, sig_s * np.eye(i * j)]]) >> 0]
        for k in range(j):
            Tk = toeplitz_matrix(Ufs[:, k])
            Gk = toeplitz_expr(G[:, k], i)
            cons.append(cp.bmat([[delta * (Tk.T @ Tk), Gk.T], [Gk, delta * np.eye(i)]]) >> 0)
    prob = cp.Problem(cp.Minimize(delta), cons)
    status, elapsed = solve(prob, solver, solver_options, f"subspace unfalsification (form={form}, i={i}, j={j})")
    d_s = solved_value(status, delta.value)

    # --- back to original units and independent certificate --------------------------------
    if form == "conditioned":
        Hv = np.asarray(H.value, float) * (sy / su) if H.value is not None else np.full((i, j), np.nan)
        Htil = np.column_stack([toeplitz_matrix(Uf[:, k]) @ Hv[:, k] for k in range(j)])
        if eliminate_L:
            L_out = (Yf - Htil) @ np.linalg.pinv(A)
        else:
            L_out = _l_value(L, L_fixed, Lscale, i)
        Xi_out = Yf - L_out @ A - Htil
        impulses = Hv
    else:
        L_out = _l_value(L, L_fixed, Lscale, i)
        Xi_out = np.asarray(Xi.value, float) * sy if Xi.value is not None else np.full((i, j), np.nan)
        G_out = Yf - L_out @ A - Xi_out
        if np.all(np.isfinite(G_out)):
            with np.errstate(over="ignore", invalid="ignore"):
                impulses = np.column_stack([deconvolve(Uf[:, k], G_out[:, k], exact=True) for k in range(j)])
        else:
            impulses = np.full((i, j), np.nan)
    d_cert = (
        max(toeplitz_norm(impulses[:, k]) for k in range(j)) if np.all(np.isfinite(impulses)) else float("inf")
    )
    delta_out = d_s * sy / su
    cert = Certificate(
        delta=delta_out,
        delta_certified=float(d_cert),
        noise_rms=float(np.linalg.norm(Xi_out) / np.sqrt(i * j)),
        sigma=sigma,
    )
    return SubspaceResult(
        delta=delta_out,
        Lw=L_out[:, : 2 * i].copy(),
        Lu=L_out[:, 2 * i :].copy(),
        noise=Xi_out,
        impulses=impulses,
        status=status,
        solve_time=elapsed,
        problem=prob,
        form=form,
        eliminate_L=bool(eliminate_L and form == "conditioned"),
        sigma=sigma,
        horizon=i,
        n_columns=j,
        cond_Tu=float(cond),
        certificate=cert,
        scale=(su, sy),
        regressor_singular_values=np.linalg.svd(A, compute_uv=False),
    )
