"""Solver ``"cvxpy"``: the reference LMI models of (7.4) and (7.5), solved by a conic solver through cvxpy.

The generic route (``backend="cvxpy"``): the programs written as they are stated, the conditioned form
``[δI T(h)ᵀ; T(h) δI] ⪰ 0`` per column with the noise cone, or the literal LMIs of the thesis
(``form="thesis"``), handed to the solver named explicitly (Clarabel by default; cvxpy would otherwise
choose).  Each model is solved in rms-scaled units and its answer, with the dual point read off the
solver's multipliers (``W = −2 Z21``, V from the noise cone), handed back in data units.  Like cvxpy's
own ``SOLVER_MAP_CONIC``, this is one entry of :data:`unfalsify.solvers.SOLVERS`.
"""
from __future__ import annotations

import time
import warnings
from functools import lru_cache

import cvxpy as cp
import numpy as np
import scipy.linalg
import scipy.sparse as sp

from ..exceptions import SolverWarning, UnfalsificationError
from .base import SolverOutput, SolverStatus
from .columns import ColumnForm
from .toeplitz import adjoint, block_conv_cols, conv_cols, deconvolve, toeplitz_matrix

__all__ = ["solve"]


def solve(problem, *, form: str = "conditioned", solver: str = "CLARABEL", solver_options: dict | None = None,
          eliminate_L: bool = False) -> SolverOutput:
    """Registered solver ``"cvxpy"``: the model of ``problem.program`` (``"arx"`` (7.4) or ``"subspace"``
    (7.5)) in the form ``form``, solved by ``solver``; the answer in data units.

    Raises :class:`~unfalsify.UnfalsificationError` on a solver failure or an infeasible/unbounded
    status; warns :class:`~unfalsify.SolverWarning` for any other status but ``optimal``.
    """
    if problem.program == "arx":
        return _arx_model(problem, form, solver, solver_options)
    if not getattr(problem, "siso", True):
        return _subspace_channels_model(problem, solver, solver_options, eliminate_L=eliminate_L)
    return _subspace_model(problem, form, solver, solver_options, eliminate_L=eliminate_L)


def _conic_solve(problem: cp.Problem, solver: str, solver_options: dict | None, what: str) -> tuple[str, float]:
    """Solve ``problem`` with an explicit solver; return (status, wall time).

    Raises :class:`UnfalsificationError` on solver failure or infeasible/unbounded status;
    warns :class:`SolverWarning` for any other non-optimal status.
    """
    opts = dict(solver_options or {})
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            # cvxpy's own "Solution may be inaccurate" warning: replaced by our SolverWarning below
            warnings.filterwarnings("ignore", message="Solution may be inaccurate", category=UserWarning)
            problem.solve(solver=solver, **opts)
    except cp.error.SolverError as exc:
        raise UnfalsificationError(f"{what}: solver {solver} failed ({exc}); try another solver or smaller data") from exc
    except BaseException as exc:
        # a Rust solver's crash reaches Python as pyo3's PanicException, a BaseException that `except Exception`
        # lets through (measured: CLARABEL's equilibration at sigma = 1e20 on data of unit size)
        if type(exc).__name__ != "PanicException":
            raise
        raise UnfalsificationError(
            f"{what}: solver {solver} crashed ({exc}); check that sigma is in the units of y (a noise level far "
            "above the data explains every output as noise, δ = 0), or use backend='structured' or another "
            "solver (e.g. solver='SCS')") from None
    elapsed = time.perf_counter() - t0
    status = problem.status
    if status in (cp.INFEASIBLE, cp.INFEASIBLE_INACCURATE, cp.UNBOUNDED, cp.UNBOUNDED_INACCURATE):
        raise UnfalsificationError(
            f"{what}: solver {solver} reports '{status}', which is impossible for this problem in exact "
            "arithmetic (it is always feasible and δ ≥ 0): the data are too ill-conditioned for the solver; "
            "use form='conditioned', fewer samples or rescale the data"
        )
    if status != cp.OPTIMAL:
        warnings.warn(
            f"{what}: solver {solver} returned status '{status}'; check the result's certificate",
            SolverWarning,
            stacklevel=6,
        )
    return status, elapsed


def _solved_value(status: str, value) -> float:
    """δ from a solve: NaN unless the status is optimal or optimal_inaccurate; at least 0 (δ bounds a norm: a
    solver's −7e-11 at an optimum δ = 0, measured with Clarabel, is its feasibility tolerance, not a δ)."""
    if status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) or value is None:
        return float("nan")
    return max(float(value), 0.0)


@lru_cache(maxsize=32)
def _selector(n: int) -> sp.csr_matrix:
    """Sparse ``S`` (n² × n) with ``vec_F(T(x)) = S x``: entry (r, c), r ≥ c, is ``x[r-c]``."""
    r, c = np.tril_indices(n)
    rows = r + c * n
    cols = r - c
    return sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(n * n, n))


def _toeplitz_expr(x: cp.Expression, n: int) -> cp.Expression:
    """``T(x)`` (lower-triangular Toeplitz, first column ``x``) as an affine cvxpy expression."""
    return cp.reshape(_selector(n) @ x, (n, n), order="F")


def _toeplitz_norm_lmi(h: cp.Expression, delta: cp.Expression, n: int) -> cp.Constraint:
    """``‖T(h)‖₂ ≤ δ`` as the 2n×2n LMI ``[δI T(h)ᵀ; T(h) δI] ⪰ 0``."""
    T = _toeplitz_expr(h, n)
    eye = np.eye(n)
    return cp.bmat([[delta * eye, T.T], [T, delta * eye]]) >> 0


def _best_scaled_dual(form: ColumnForm, v, W) -> tuple[np.ndarray, object]:
    """A solver's (v, W) with the relative scale and sign of W chosen to maximise the bound.

    Any (v, W) gives a valid bound; solvers' sign and scaling conventions for duals differ, so the
    relative scale α of ``v`` is picked by a coarse search (small problems only).
    """
    best = (-1.0, v, W)
    for sgn in (1.0, -1.0):
        Ws = sgn * np.asarray(W, float)
        grid = np.logspace(-6, 6, 49)
        vals = [form.lower_bound(a * v, Ws) for a in grid]
        k = int(np.nanargmax(vals))
        lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
        for a in np.geomspace(lo, hi, 17):
            val = form.lower_bound(a * v, Ws)
            if val > best[0]:
                best = (val, a * v, Ws)
    return best[1], best[2]


def _data_units_dual(P, V, W, su: float):
    """A model's (V, W) with the best relative scale (:func:`_best_scaled_dual`), W in data units (only W is
    rescaled, by s_u: ``M(u)ᵀv = s_u M(u/s_u)ᵀv``); ``(None, None)`` when the solver gave no finite dual
    point.  Every cvxpy model of (7.4) and (7.5) ends with it."""
    if V is None or not (np.all(np.isfinite(V)) and np.all(np.isfinite(W))):
        return None, None
    V, W = _best_scaled_dual(P.column_form(scaled=True), V, W)
    return V, W * su


def _arx_model(P, form: str, solver: str, solver_options) -> SolverOutput:
    """The reference cvxpy models (unchanged), in scaled units; returns a dict in data units."""
    if not P.siso:
        return _arx_channels_model(P, solver, solver_options)
    n, na, nb = P.n, P.na, P.nb
    su, sy = P.scale
    us = P.u / su
    Phi_s, Y_s = P.regressor(scaled=True)
    sig_s = P.sigma / sy
    Tu_s = toeplitz_matrix(us)
    p = Phi_s.shape[1]
    theta = cp.Variable(p, name="theta") if p else None  # cvxpy 1.7 (pip's choice on Python 3.10) refuses shape (0,)
    delta = cp.Variable(name="delta")
    e = (Phi_s @ theta + Y_s) if p else cp.Constant(Y_s)
    if form == "conditioned":
        h = cp.Variable(n, name="h")
        xi = e - Tu_s @ h
        cons = [cp.norm(xi, 2) <= sig_s * np.sqrt(P.n_noise), _toeplitz_norm_lmi(h, delta, n)]
    else:
        xi_v = cp.Variable(n, name="xi")
        g = e - xi_v
        G = _toeplitz_expr(g, n)
        xc = cp.reshape(xi_v, (n, 1), order="F") / np.sqrt(n)
        noise_lmi = cp.bmat([[np.array([[sig_s]]), xc.T], [xc, sig_s * np.eye(n)]]) >> 0
        gram = Tu_s.T @ Tu_s
        main_lmi = cp.bmat([[delta * gram, G.T], [G, delta * np.eye(n)]]) >> 0
        cons = [noise_lmi, main_lmi]
    prob = cp.Problem(cp.Minimize(delta), cons)
    status, elapsed = _conic_solve(prob, solver, solver_options, f"ARX unfalsification (form={form}, n={n})")
    d_s = _solved_value(status, delta.value)

    # back to original units: a unchanged, b scaled by sy/su, h by sy/su, ξ by sy, δ by sy/su
    if p == 0:
        th_s = np.zeros(0)
    elif theta.value is None:
        th_s = np.full(p, np.nan)
    else:
        th_s = np.asarray(theta.value, dtype=float).reshape(-1)
    theta_out = th_s.copy()
    theta_out[na:na + nb] *= sy / su
    theta_out[na + nb:] *= sy  # free rows: equation errors, in y units
    Phi, Y = P.regressor()
    e_out = Phi @ theta_out + Y if p else Y
    v = W = None
    if form == "conditioned":
        h_out = np.asarray(h.value, dtype=float) * (sy / su) if h.value is not None else np.full(n, np.nan)
        lam, Z = cons[0].dual_value, cons[1].dual_value
        xi_s = np.asarray(xi.value, float) if xi.value is not None else None
        if lam is not None and Z is not None and xi_s is not None and np.linalg.norm(xi_s) > 0:
            v = float(lam) * xi_s / np.linalg.norm(xi_s)
            W = -2.0 * np.asarray(Z, float)[n:, :n]
    else:
        xi_out = np.asarray(xi_v.value, dtype=float) * sy if xi_v.value is not None else np.full(n, np.nan)
        if np.all(np.isfinite(xi_out)):
            h_out = deconvolve(P.u, e_out - xi_out, exact=n <= 400, overflow="return")
        else:
            h_out = np.full(n, np.nan)
        Z = cons[1].dual_value
        if Z is not None:
            Z21 = np.asarray(Z, float)[n:, :n]
            v = -2.0 * adjoint(Z21)
            W = -2.0 * Z21 @ Tu_s.T
    v, W = _data_units_dual(P, v, W, su)
    return SolverOutput(delta=d_s * sy / su, impulses=h_out, params=theta_out, status=SolverStatus(status),
                        solve_time=elapsed, dual_v=v, dual_W=W, problem=prob)


def _column_toeplitz_operator(Uf: np.ndarray) -> sp.csr_matrix:
    """Block-diagonal sparse matrix mapping ``vec_F(H)`` to ``vec_F(H̃)``, ``H̃_{:,k} = T(U_f[:,k]) h_k``."""
    return sp.block_diag([sp.csr_matrix(np.tril(toeplitz_matrix(Uf[:, k]))) for k in range(Uf.shape[1])], format="csr")


def _l_value(L, L_fixed, Lscale, i) -> np.ndarray:
    if L_fixed is not None:
        return L_fixed.copy()
    if L.value is None:
        return np.full((i, 3 * i), np.nan)
    return np.asarray(L.value, float) * Lscale


def _subspace_model(P, form, solver, solver_options, eliminate_L=False) -> SolverOutput:
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
        lmis = [_toeplitz_norm_lmi(H[:, k], delta, i) for k in range(j)]
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
            Gk = _toeplitz_expr(G[:, k], i)
            lmis.append(cp.bmat([[delta * (Tk.T @ Tk), Gk.T], [Gk, delta * np.eye(i)]]) >> 0)
        cons += lmis
    prob = cp.Problem(cp.Minimize(delta), cons)
    what = f"subspace unfalsification (form={form}, i={i}, j={j})"
    status, elapsed = _conic_solve(prob, solver, solver_options, what)
    d_s = _solved_value(status, delta.value)

    # --- back to original units --------------------------------------------------------------
    V = W = None
    if form == "conditioned":
        Hv = np.asarray(H.value, float) * (sy / su) if H.value is not None else np.full((i, j), np.nan)
        Htil = conv_cols(Uf, Hv)
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
            impulses = np.column_stack([deconvolve(Uf[:, k], G_out[:, k], exact=True, overflow="return")
                                        for k in range(j)])
        else:
            impulses = np.full((i, j), np.nan)
        Zs = [c.dual_value for c in lmis]
        if all(Z is not None for Z in Zs):
            Z21 = np.stack([np.asarray(Z, float)[i:, :i] for Z in Zs])
            V = -2.0 * adjoint(Z21)
            W = np.stack([-2.0 * Z21[k] @ toeplitz_matrix(Ufs[:, k]).T for k in range(j)])
    V, W = _data_units_dual(P, V, W, su)
    return SolverOutput(delta=d_s * sy / su, impulses=impulses, params=L_out, status=SolverStatus(status),
                        solve_time=elapsed, dual_v=V, dual_W=W, problem=prob)


@lru_cache(maxsize=32)
def _block_selector(i: int, l: int, m: int) -> sp.csr_matrix:
    """Sparse ``S`` ((il·im) × ilm) with ``vec_F(T(h)) = S vec_C(h)`` for h (i, l, m): entry of block (s, q),
    s ≥ q, row a, column b is ``h[s−q, a, b]``."""
    s, q, a, b = (x.ravel() for x in np.meshgrid(np.arange(i), np.arange(i), np.arange(l), np.arange(m), indexing="ij"))
    keep = s >= q
    s, q, a, b = s[keep], q[keep], a[keep], b[keep]
    rows = (s * l + a) + (q * m + b) * (i * l)
    cols = (s - q) * l * m + a * m + b
    return sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(i * l * i * m, i * l * m))


def _block_column_operator(Uf: np.ndarray, l: int, m: int) -> sp.csr_matrix:
    """Block-diagonal sparse matrix mapping ``vec_F`` of the impulse matrix (ilm × j, column k = ``vec_C(h_k)``)
    to ``vec_F(H̃)``, ``H̃_{:,k} = T(h_k) (U_f)_{:,k}``: row (s, a), column (t, a, b) holds ``u_{k, s−t, b}``."""
    i = Uf.shape[0] // m
    s, t, a, b = (x.ravel() for x in np.meshgrid(np.arange(i), np.arange(i), np.arange(l), np.arange(m), indexing="ij"))
    keep = s >= t
    s, t, a, b = s[keep], t[keep], a[keep], b[keep]
    rows, cols = s * l + a, t * l * m + a * m + b
    blocks = [sp.csr_matrix((Uf[(s - t) * m + b, k], (rows, cols)), shape=(i * l, i * l * m)) for k in range(Uf.shape[1])]
    return sp.block_diag(blocks, format="csr")


def _subspace_channels_model(P, solver, solver_options, eliminate_L=False) -> SolverOutput:
    """(7.5) for l × m operators Δ_k, conditioned form (:class:`~unfalsify.solvers.columns.BlockColumnForm`):
    per column ``[δI_im T(h_k)ᵀ; T(h_k) δI_il] ⪰ 0`` and the noise cone ``‖Y_f − L A − H̃‖_F ≤ σ√(ilj)``, in
    rms-scaled units; the answer (impulses (i, l, m, j), ``[L_w L_u]``, the dual point) in data units."""
    A, Uf, Yf = P.A, P.Uf, P.Yf
    i, j, m, l = P.horizon, P.n_columns, P.n_inputs, P.n_outputs
    su, sy = P.scale
    As = P.scaled_A()
    Ufs, Yfs = Uf / su, Yf / sy
    bound = P.sigma / sy * np.sqrt(P.n_noise)
    p = i * l * m
    delta = cp.Variable(name="delta")
    Hv = cp.Variable((p, j), name="H")
    Ht = cp.reshape(_block_column_operator(Ufs, l, m) @ cp.vec(Hv, order="F"), (i * l, j), order="F")
    Lscale = np.concatenate([np.full(i * m, sy / su), np.ones(i * l), np.full(i * m, sy / su)])
    L = None
    if P.L_fixed is not None:
        resid = Yfs - (P.L_fixed / Lscale) @ As - Ht
    elif eliminate_L:
        N = scipy.linalg.null_space(As)
        resid = (Yfs - Ht) @ N if N.shape[1] else None
    else:
        L = cp.Variable((i * l, i * (2 * m + l)), name="L")
        resid = Yfs - L @ As - Ht
    noise_con = [cp.norm(cp.vec(resid, order="F"), 2) <= bound] if resid is not None else []
    S = _block_selector(i, l, m)
    lmis = []
    for k in range(j):
        T = cp.reshape(S @ Hv[:, k], (i * l, i * m), order="F")
        lmis.append(cp.bmat([[delta * np.eye(i * m), T.T], [T, delta * np.eye(i * l)]]) >> 0)
    prob = cp.Problem(cp.Minimize(delta), noise_con + lmis)
    status, elapsed = _conic_solve(prob, solver, solver_options,
                                   f"subspace unfalsification ({l}×{m}, i={i}, j={j})")
    d_s = _solved_value(status, delta.value)
    H = (np.asarray(Hv.value, float) * (sy / su)).reshape(i, l, m, j) if Hv.value is not None \
        else np.full((i, l, m, j), np.nan)
    Htil = block_conv_cols(Uf, H, m)
    if P.L_fixed is not None:
        L_out = P.L_fixed.copy()
    elif eliminate_L:
        L_out = (Yf - Htil) @ np.linalg.pinv(A)
    else:
        L_out = np.asarray(L.value, float) * Lscale if L.value is not None else np.full((i * l, A.shape[0]), np.nan)
    V = W = None
    Zs = [c.dual_value for c in lmis]
    lam = noise_con[0].dual_value if noise_con else None
    Xi_s = (Yf - L_out @ A - Htil) / sy
    if lam is not None and all(Z is not None for Z in Zs) and np.all(np.isfinite(Xi_s)) and np.linalg.norm(Xi_s) > 0:
        V = float(lam) * Xi_s / np.linalg.norm(Xi_s)
        W = np.stack([-2.0 * np.asarray(Z, float)[i * m:, : i * m] for Z in Zs])
    V, W = _data_units_dual(P, V, W, su)
    return SolverOutput(delta=d_s * sy / su, impulses=H, params=L_out, status=SolverStatus(status),
                        solve_time=elapsed, dual_v=V, dual_W=W, problem=prob)


def _arx_channels_model(P, solver, solver_options) -> SolverOutput:
    """(7.4) for u (n, m), y (n, l), conditioned form, in rms-scaled units: variables Θ (na·l + nb·m +
    free_rows, l), h (n, l, m) and δ; ``[δI_nm T(h)ᵀ; T(h) δI_nl] ⪰ 0`` and the noise cone
    ``‖vec(ΦΘ + Y) − T(h)u‖₂ ≤ σ√((n − free_rows)·l)`` (the samples stacked).  The answer (h, Θ, the dual
    point ``v = λ ξ/‖ξ‖``, ``W = −2 Z21``) in data units."""
    n, l, m, na, nb = P.n, P.n_outputs, P.n_inputs, P.na, P.nb
    su, sy = P.scale
    Phi_s, Y_s = P.regressor(scaled=True)
    p = Phi_s.shape[1]
    delta = cp.Variable(name="delta")
    h = cp.Variable(n * l * m, name="h")  # C order (t, α, β)
    theta = cp.Variable((p, l), name="theta") if p else None
    e = (Phi_s @ theta + Y_s) if p else cp.Constant(Y_s)
    xi = cp.vec(e, order="C") - _block_column_operator((P.u / su).reshape(-1, 1), l, m) @ h
    T = cp.reshape(_block_selector(n, l, m) @ h, (n * l, n * m), order="F")
    cons = [cp.norm(xi, 2) <= P.sigma / sy * np.sqrt(P.n_noise),
            cp.bmat([[delta * np.eye(n * m), T.T], [T, delta * np.eye(n * l)]]) >> 0]
    prob = cp.Problem(cp.Minimize(delta), cons)
    status, elapsed = _conic_solve(prob, solver, solver_options, f"ARX unfalsification ({l}×{m}, n={n})")
    d_s = _solved_value(status, delta.value)
    # data units: A_k unchanged, B_k and h by s_y/s_u, the free rows' errors by s_y
    if p == 0:
        th = np.zeros((0, l))
    elif theta.value is None:
        th = np.full((p, l), np.nan)
    else:
        th = np.asarray(theta.value, float).copy()
        th[na * l : na * l + nb * m] *= sy / su
        th[na * l + nb * m :] *= sy
    H = np.asarray(h.value, float).reshape(n, l, m) * (sy / su) if h.value is not None \
        else np.full((n, l, m), np.nan)
    v = W = None
    lam, Z = cons[0].dual_value, cons[1].dual_value
    xi_s = np.asarray(xi.value, float) if xi.value is not None else None
    if lam is not None and Z is not None and xi_s is not None and np.linalg.norm(xi_s) > 0:
        v = float(lam) * xi_s / np.linalg.norm(xi_s)
        W = -2.0 * np.asarray(Z, float)[n * m :, : n * m]
    v, W = _data_units_dual(P, v, W, su)
    return SolverOutput(delta=d_s * sy / su, impulses=H, params=th, status=SolverStatus(status),
                        solve_time=elapsed, dual_v=v, dual_W=W, problem=prob)
