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

import time
import warnings
from dataclasses import dataclass, field

import cvxpy as cp
import numpy as np
import scipy.linalg
import scipy.sparse as sp

from synthesis import Predictor, block_hankel
from synthesis._validation import DataError, check_horizon

from ._columns import ColumnForm, _conv_cols
from ._common import (
    COND_WARN,
    Certificate,
    IllConditionedWarning,
    check_backend,
    check_form,
    check_sigma,
    rms_or_one,
    siso_signal,
    solve,
    solved_value,
)
from ._lmi import toeplitz_expr, toeplitz_norm_lmi
from ._toeplitz import deconvolve, toeplitz_cond, toeplitz_matrix, toeplitz_norm
from synthesis._repr import result

__all__ = ["SubspaceProblem", "SubspaceResult", "subspace_unfalsify", "subspace_data"]


@result
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
    problem : cvxpy.Problem or None
        The problem as solved (in rms-scaled units, see ``scale``); None for the structured and split
        backends.  A by-product: not compared by ``==``, and stored as None when the result is
        pickled (a cvxpy problem holds a solver object that does not pickle); everything else, the
        certificate included, survives.
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
    problem: cp.Problem | None = field(compare=False)
    form: str
    eliminate_L: bool
    sigma: float
    horizon: int
    n_columns: int
    cond_Tu: float
    certificate: Certificate
    scale: tuple
    regressor_singular_values: np.ndarray
    backend: str = "cvxpy"

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


@result
@dataclass(frozen=True, eq=False)
class SubspaceProblem:
    """Program (7.5) on given data: validation, scaling, the fixed predictor and the bounds.

    Build with :meth:`from_data`.  ``evaluate_primal(H, L)`` / ``evaluate_dual(V, W)`` are the two
    sides of :class:`Certificate` (data units); ``column_form`` is what the backends solve.
    """

    u: np.ndarray
    y: np.ndarray
    horizon: int
    sigma: float
    L_fixed: np.ndarray | None
    scale: tuple
    cond_Tu: float
    A: np.ndarray
    Uf: np.ndarray
    Yf: np.ndarray

    @property
    def n_columns(self) -> int:
        """j."""
        return int(self.Uf.shape[1])

    @classmethod
    def from_data(cls, u, y, horizon, sigma, predictor=None) -> "SubspaceProblem":
        """Validate (raises :class:`DataError`) and scale."""
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
        L_fixed = None
        if predictor is not None:
            L_fixed = np.hstack([np.asarray(predictor.Lw, float), np.asarray(predictor.Lu, float)])
            if int(predictor.horizon) != i or L_fixed.shape != (i, 3 * i) or not np.all(np.isfinite(L_fixed)):
                raise DataError(
                    f"predictor must be a finite SISO predictor of horizon {i} (Lw {i}×{2 * i}, Lu {i}×{i}); "
                    f"got horizon {predictor.horizon}, [Lw Lu] of shape {L_fixed.shape}"
                )
        cond = max(toeplitz_cond(Uf[:, k]) for k in range(j))
        # u to unit rms; y so that the residual of the predictor (least squares, or the fixed one)
        # has unit rms: that is the error the program splits between Ξ and Δ̄U_f
        su = rms_or_one(u)
        Lref = L_fixed if L_fixed is not None else np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T
        sy = rms_or_one(Yf - Lref @ A)
        if not sy > 1e-12 * rms_or_one(y):
            sy = rms_or_one(y)
        return cls(u=u, y=y, horizon=i, sigma=sigma, L_fixed=L_fixed, scale=(su, sy), cond_Tu=float(cond),
                   A=A, Uf=Uf, Yf=Yf)

    def scaled_A(self) -> np.ndarray:
        """``A`` with rows scaled as the data (``u/s_u``, ``y/s_y``)."""
        i = self.horizon
        su, sy = self.scale
        As = self.A.copy()
        As[:i] /= su
        As[i : 2 * i] /= sy
        As[2 * i :] /= su
        return As

    def column_form(self, scaled: bool = True) -> ColumnForm:
        """(7.5) as the column form (C) (𝓛 = {L A}, or {0} with the predictor fixed)."""
        su, sy = self.scale if scaled else (1.0, 1.0)
        i, j = self.Uf.shape
        rho = self.sigma / sy * np.sqrt(i * j)
        if self.L_fixed is not None:
            return ColumnForm(self.Uf / su, (self.Yf - self.L_fixed @ self.A) / sy, rho)
        As = self.scaled_A() if scaled else self.A
        Vt, sv = np.linalg.svd(As, full_matrices=False)[2], np.linalg.svd(As, compute_uv=False)
        rank = int(np.count_nonzero(sv > max(As.shape) * np.finfo(float).eps * (sv[0] if sv.size else 1.0)))
        return ColumnForm(self.Uf / su, self.Yf / sy, rho, basis_right=Vt[:rank].T)

    def evaluate_primal(self, H, L) -> tuple[float, float]:
        """``(max_k ‖T(h_k)‖₂, ‖Y_f − L A − H̃‖_F)`` recomputed from the data."""
        H = np.asarray(H, float)
        L = np.asarray(L, float)
        if not (np.all(np.isfinite(H)) and np.all(np.isfinite(L))):
            return float("inf"), float("nan")
        Xi = self.Yf - L @ self.A - _conv_cols(self.Uf, H)
        d = max(toeplitz_norm(H[:, k]) for k in range(H.shape[1]))
        return float(d), float(np.linalg.norm(Xi))

    def evaluate_dual(self, V, W, sigma=None) -> float:
        """The weak-duality lower bound of :class:`Certificate` for any ``V`` (i, j) and ``W``."""
        sigma = self.sigma if sigma is None else float(sigma)
        return self.column_form(scaled=False).lower_bound(V, W, rho=sigma * np.sqrt(self.Uf.size))


def _solve_cvxpy(P: SubspaceProblem, form, eliminate_L, solver, solver_options) -> dict:
    """The reference cvxpy models (unchanged), in scaled units; returns a dict in data units."""
    A, Uf, Yf = P.A, P.Uf, P.Yf
    i, j = Uf.shape
    su, sy = P.scale
    L_fixed = P.L_fixed
    As = P.scaled_A()
    Ufs, Yfs, sig_s = Uf / su, Yf / sy, P.sigma / sy
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
        lmis = [toeplitz_norm_lmi(H[:, k], delta, i) for k in range(j)]
        cons = noise_con + lmis
    else:
        L = cp.Variable((i, 3 * i), name="L") if L is None else L
        Xi = cp.Variable((i, j), name="Xi")
        G = Yfs - L @ As - Xi
        xv = cp.reshape(cp.vec(Xi, order="F"), (i * j, 1), order="F") / np.sqrt(i * j)
        cons = [cp.bmat([[np.array([[sig_s]]), xv.T], [xv, sig_s * np.eye(i * j)]]) >> 0]
        lmis = []
        for k in range(j):
            Tk = toeplitz_matrix(Ufs[:, k])
            Gk = toeplitz_expr(G[:, k], i)
            lmis.append(cp.bmat([[delta * (Tk.T @ Tk), Gk.T], [Gk, delta * np.eye(i)]]) >> 0)
        cons += lmis
    prob = cp.Problem(cp.Minimize(delta), cons)
    status, elapsed = solve(prob, solver, solver_options, f"subspace unfalsification (form={form}, i={i}, j={j})")
    d_s = solved_value(status, delta.value)

    # --- back to original units --------------------------------------------------------------
    V = W = None
    if form == "conditioned":
        Hv = np.asarray(H.value, float) * (sy / su) if H.value is not None else np.full((i, j), np.nan)
        Htil = _conv_cols(Uf, Hv)
        if eliminate_L:
            L_out = (Yf - Htil) @ np.linalg.pinv(A)
        else:
            L_out = _l_value(L, L_fixed, Lscale, i)
        impulses = Hv
        Zs = [c.dual_value for c in lmis]
        lam = noise_con[0].dual_value if noise_con else None
        Xi_s = (Yf - L_out @ A - Htil) / sy
        if lam is not None and all(Z is not None for Z in Zs) and np.linalg.norm(Xi_s) > 0:
            V = float(lam) * Xi_s / np.linalg.norm(Xi_s)
            W = np.stack([-2.0 * np.asarray(Z, float)[i:, :i] for Z in Zs])
    else:
        L_out = _l_value(L, L_fixed, Lscale, i)
        Xi_out = np.asarray(Xi.value, float) * sy if Xi.value is not None else np.full((i, j), np.nan)
        G_out = Yf - L_out @ A - Xi_out
        if np.all(np.isfinite(G_out)):
            with np.errstate(over="ignore", invalid="ignore"):
                impulses = np.column_stack([deconvolve(Uf[:, k], G_out[:, k], exact=True) for k in range(j)])
        else:
            impulses = np.full((i, j), np.nan)
        Zs = [c.dual_value for c in lmis]
        if all(Z is not None for Z in Zs):
            Z21 = np.stack([np.asarray(Z, float)[i:, :i] for Z in Zs])
            V = -2.0 * np.stack([np.trace(Z21, offset=-d, axis1=1, axis2=2) for d in range(i)])
            W = np.stack([-2.0 * Z21[k] @ toeplitz_matrix(Ufs[:, k]).T for k in range(j)])
    if V is not None and np.all(np.isfinite(V)) and np.all(np.isfinite(W)):
        from .arx import _best_scaled_dual

        V, W = _best_scaled_dual(P.column_form(scaled=True), V, W)
        W = W * su
    else:
        V = W = None
    return dict(delta=d_s * sy / su, H=impulses, L=L_out, status=status, time=elapsed, problem=prob, v=V, W=W)


def _solve_structured(P: SubspaceProblem, tol, time_limit, progress, workers=1) -> dict:
    """The column barrier solver (:mod:`unfalsify._structured_columns`); returns a dict in data units."""
    from ._structured_columns import solve_columns_barrier

    su, sy = P.scale
    f = P.column_form(scaled=True)
    i, j = P.Uf.shape
    t0 = time.perf_counter()
    B0 = f.project(f.B)
    if np.linalg.norm(B0) <= f.rho:
        out = dict(status="optimal", H=np.zeros((i, j)), V=None, W=None, upper=0.0)
    else:
        out = solve_columns_barrier(f, B0, tol=tol, time_limit=time_limit, progress=progress, workers=workers)
    H = out["H"] * (sy / su)
    Htil = _conv_cols(P.Uf, H)
    L = P.L_fixed.copy() if P.L_fixed is not None else np.linalg.lstsq(P.A.T, (P.Yf - Htil).T, rcond=None)[0].T
    W = None if out["W"] is None else out["W"] * su
    return dict(delta=out["upper"] * sy / su, H=H, L=L, status=out["status"], time=time.perf_counter() - t0,
                problem=None, v=out["V"], W=W)


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
    backend: str = "cvxpy",
    tol: float = 1e-6,
    time_limit: float | None = None,
    progress: bool = True,
    executor=None,
    workers: int | None = None,
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
        See the module docstring (``"thesis"``: cvxpy backend only).
    eliminate_L : bool
        cvxpy conditioned form: eliminate ``[L_w L_u]`` analytically.  (The structured backend
        always eliminates L by projection.)
    predictor : synthesis.Predictor, optional
        Fix ``[L_w L_u]`` to a given SISO predictor of horizon i and compute the δ of that model:
        (7.5) with L a constant.  Default: L is optimised jointly, as in the thesis.
    solver, solver_options
        cvxpy backend: solver (passed explicitly) and extra ``Problem.solve`` arguments.
    backend : {"cvxpy", "structured"}
        See :func:`unfalsify.arx_unfalsify`.
    tol, time_limit, progress
        Structured backend, as for :func:`unfalsify.arx_unfalsify`.
    executor : concurrent.futures.Executor, optional
        With ``predictor`` fixed, (7.5) splits by columns: blocks of columns are solved as tasks
        on this executor (local processes, ``distributed.Client.get_executor()``, …) and the
        one-dimensional outer problem in δ here (:mod:`unfalsify.split`); ``backend`` is then
        ignored and the result's ``backend`` is ``"split"``.  Same δ and certificate as serial.
    workers : int or None
        Structured backend: threads over the column stack (default ``None``: every core,
        ``os.cpu_count()``).  BLAS is held to one thread per worker during the solve, so the
        threads do not compete with BLAS's own; the result equals the one-thread solve up to the
        order of floating-point sums.

    Returns
    -------
    SubspaceResult
        With a two-sided :class:`Certificate`.

    Raises
    ------
    DataError
        NaN/inf, lengths, MIMO, bad horizon / too few samples, σ ≤ 0, or a column of ``U_f``
        whose first entry ``u_{i+k}`` is 0 (``T((U_f)_{:,k})`` singular).
    ValueError
        Unknown form/backend; incompatible options.
    UnfalsificationError
        cvxpy: solver failure or infeasible/unbounded status.

    Warns
    -----
    SolverWarning, IllConditionedWarning
        As for :func:`unfalsify.arx_unfalsify`.
    """
    form = check_form(form)
    backend = check_backend(backend)
    if backend == "structured" and form != "conditioned":
        raise ValueError("backend='structured' solves the conditioned form; use form='conditioned'")
    if form == "thesis" and eliminate_L:
        raise ValueError("eliminate_L applies to form='conditioned' only")
    if predictor is not None and eliminate_L:
        raise ValueError("eliminate_L and a fixed predictor exclude each other")
    from ._structured_columns import _worker_count

    workers = _worker_count(workers)
    P = SubspaceProblem.from_data(u, y, horizon, sigma, predictor=predictor)
    i, j = P.Uf.shape
    if form == "thesis" and not P.cond_Tu <= COND_WARN:
        warnings.warn(
            f"form='thesis' with max_k cond T((U_f)_k) = {P.cond_Tu:.3g}: the literal LMI is numerically "
            "singular; prefer form='conditioned'",
            IllConditionedWarning,
            stacklevel=2,
        )
    if executor is not None:
        if predictor is None or form != "conditioned":
            raise DataError("executor= splits (7.5) by columns, which needs the predictor fixed and "
                            "form='conditioned': pass predictor=... (e.g. synthesis.fit_predictor(u, y, i))")
        from .split import solve_split_problem

        out, backend = solve_split_problem(P, executor), "split"
    elif backend == "cvxpy":
        out = _solve_cvxpy(P, form, eliminate_L, solver, solver_options)
    else:
        out = _solve_structured(P, float(tol), time_limit, progress, workers)
    from .arx import _finish_structured, certify

    cert = certify(P, out["delta"], out["H"], out["L"], out["v"], out["W"])
    delta = out["delta"]
    if backend == "structured":
        delta = _finish_structured(out["status"], f"subspace unfalsification (i={i}, j={j})", cert, delta)
    L_out = out["L"]
    return SubspaceResult(
        delta=delta,
        Lw=L_out[:, : 2 * i].copy(),
        Lu=L_out[:, 2 * i :].copy(),
        noise=P.Yf - L_out @ P.A - _conv_cols(P.Uf, out["H"]),
        impulses=out["H"],
        status=out["status"],
        solve_time=out["time"],
        problem=out["problem"],
        form=form,
        eliminate_L=bool(eliminate_L and form == "conditioned"),
        sigma=P.sigma,
        horizon=i,
        n_columns=j,
        cond_Tu=P.cond_Tu,
        certificate=cert,
        scale=P.scale,
        regressor_singular_values=np.linalg.svd(P.A, compute_uv=False),
        backend=backend,
    )
