"""ARX uncertainty-model unfalsification, thesis §7.2 and program (7.4).

Model (7.3): ``A(q) y − B(q) u = e(θ) = ξ + Δ(q) u`` with ``e(θ) = Φθ + Y`` (§7.2.1, system at
rest before t = 0), noise ``‖ξ‖_rms = ‖ξ‖₂/√n ≤ σ`` and ``Δ`` causal LTI.  By Theorem 7.1 the
smallest ``‖Δ‖∞`` that unfalsifies the data is

    δ = min_{δ, θ, ξ} δ   s.t.   T(e(θ) − ξ)ᵀ T(e(θ) − ξ) ⪯ δ² T(u)ᵀ T(u).            (7.4)

Two cvxpy formulations of the same program:

``form="conditioned"`` (default)
    Substitute ``e − ξ = T(u) h`` (exact when ``u₀ ≠ 0``: ``T(e − ξ) = T(h) T(u)`` because
    lower-triangular Toeplitz matrices commute, so the inequality is ``‖T(h)‖₂ ≤ δ``).
    Variables θ, h, δ; constraints ``[δI T(h)ᵀ; T(h) δI] ⪰ 0`` (2n×2n) and the cone
    ``‖Φθ + Y − T(u) h‖₂ ≤ σ√n``.  Only multiplies by ``T(u)``; never inverts it.
``form="thesis"``
    The literal LMIs of §7.2.2, ``[σ ξᵀ/√n; ξ/√n σI] ⪰ 0`` and
    ``[δ T(u)ᵀT(u) T(e−ξ)ᵀ; T(e−ξ) δI] ⪰ 0``.  Kept for fidelity; ``T(u)ᵀT(u)`` has condition
    number ``cond(T(u))²`` (≈ 1e17 at n = 40 for a ±1 PRBS) so the solver's answer cannot be
    trusted in the near-null directions of ``T(u)`` -- see the result's ``certificate``.

The tempting substitution ``h = T(u)⁻¹(e − ξ)`` is not offered: it inverts ``T(u)`` and is
wrong by orders of magnitude for n ≥ 40 (measured: Clarabel δ = 1.31 instead of 0.0861 at n = 80,
SCS δ = 6.3 instead of 0.170 at n = 40).
"""
from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

import cvxpy as cp
import numpy as np
import scipy.linalg

from synthesis._validation import DataError

from ._columns import CirculantDual, ColumnForm, _conv_cols
from ._common import (
    COND_WARN,
    NotAtRestWarning,
    Certificate,
    IllConditionedWarning,
    SolverWarning,
    check_backend,
    check_form,
    check_sigma,
    rms_or_one,
    siso_signal,
    solve,
    solved_value,
)
from ._lmi import toeplitz_expr, toeplitz_norm_lmi
from ._toeplitz import _toeplitz_gram, deconvolve, toeplitz_cond, toeplitz_matrix, toeplitz_norm
from synthesis._repr import result

__all__ = ["ArxProblem", "ArxResult", "arx_unfalsify", "arx_regressor", "arx_least_squares"]


@result
@dataclass(frozen=True, eq=False)
class ArxResult:
    """Solution of the ARX unfalsification program (7.4).

    Attributes
    ----------
    delta : float
        δ_unf, the smallest ``‖Δ‖∞`` (NaN if the solve failed).
    theta : ndarray, shape (na + nb + free_rows,)
        ``[a₁ … a_na, b₁ … b_nb]`` (§7.2.1), followed by the free equation errors of the first
        ``free_rows`` rows when there are any.
    noise : ndarray, shape (n,)
        ξ.  For the conditioned form ``ξ = Φθ + Y − T(u) h`` exactly.
    impulse : ndarray, shape (n,)
        h, the first n Markov parameters of Δ: ``e − ξ = T(u) h`` (for the thesis form
        recomputed from ξ in exact rational arithmetic).
    status : str
        cvxpy status (``"optimal"``, ``"optimal_inaccurate"``, ...), or for the structured backend
        ``"optimal"``, ``"time_limit"``, ``"interrupted"``, ``"max_iter"``, ``"failed"``.
    solve_time : float
        Wall time of the solve in seconds (cvxpy: ``problem.solve``, incl. compilation).
    problem : cvxpy.Problem or None
        The cvxpy problem as solved (in scaled units, see ``scale``); None for the structured backend
        (the data are in ``certificate.problem``, an :class:`ArxProblem`).  A by-product: not
        compared by ``==``, and stored as None when the result is pickled (a cvxpy problem holds a
        solver object that does not pickle); everything else, the certificate included, survives.
    form : str
        ``"conditioned"`` or ``"thesis"``.
    sigma : float
        Admissible rms noise level σ.
    na, nb : int
        Orders of ``A(q)`` and ``B(q)``.
    cond_Tu : float
        cond₂ ``T(u)``.
    certificate : Certificate
        Two-sided certificate: ``upper_bound = ‖T(h)‖₂`` and the noise recomputed from
        ``(theta, impulse)``, ``lower_bound`` from the dual point; ``verify()`` recomputes both.
    scale : tuple of float
        ``(s_u, s_y)``: the problem was posed on ``u/s_u`` and ``y/s_y`` (``s_u`` = rms of u,
        ``s_y`` = rms of the least-squares equation error).
    """

    delta: float
    theta: np.ndarray
    noise: np.ndarray
    impulse: np.ndarray
    status: str
    solve_time: float
    problem: cp.Problem | None = field(compare=False)
    form: str
    sigma: float
    na: int
    nb: int
    cond_Tu: float
    certificate: Certificate
    scale: tuple
    backend: str = "cvxpy"

    @property
    def a(self) -> np.ndarray:
        """``[a₁ … a_na]``."""
        return self.theta[: self.na]

    @property
    def b(self) -> np.ndarray:
        """``[b₁ … b_nb]``."""
        return self.theta[self.na : self.na + self.nb]

    @property
    def max_violation(self) -> float:
        """Shortcut for ``certificate.max_violation``."""
        return self.certificate.max_violation


def _order(v, name: str) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
        raise DataError(f"{name} must be an integer >= 0, got {v!r}")
    return int(v)


def arx_regressor(u, y, na: int, nb: int) -> tuple[np.ndarray, np.ndarray]:
    """``(Φ, Y)`` of §7.2.1 with zero initial conditions, so that ``e(θ) = Φθ + Y``.

    Row t of Φ is ``[y_{t−1} … y_{t−na}, −u_{t−1} … −u_{t−nb}]`` (samples before t = 0 are zero).
    """
    u = siso_signal(u, "u")
    y = siso_signal(y, "y", n=u.size)
    na, nb = _order(na, "na"), _order(nb, "nb")
    n = u.size
    Phi = np.zeros((n, na + nb))
    for k in range(1, na + 1):
        Phi[k:, k - 1] = y[: n - k]
    for k in range(1, nb + 1):
        Phi[k:, na + k - 1] = -u[: n - k]
    return Phi, y.copy()


def arx_least_squares(u, y, na: int, nb: int) -> tuple[np.ndarray, float]:
    """Classical ARX (7.2): ``θ = −Φ⁺Y`` and the rms of the residual ``e(θ)``."""
    Phi, Y = arx_regressor(u, y, na, nb)
    if Phi.shape[1] == 0:
        return np.zeros(0), float(np.linalg.norm(Y) / np.sqrt(Y.size))
    theta = -np.linalg.lstsq(Phi, Y, rcond=None)[0]
    e = Phi @ theta + Y
    return theta, float(np.linalg.norm(e) / np.sqrt(Y.size))


def _warn_if_not_at_rest(u, y, na: int, nb: int, sigma: float) -> None:
    """(7.4) takes the samples before the record as zero (system at rest).  Warn when the first
    ``max(na, nb)`` equation errors of the least-squares model -- the rows that use those zeros --
    are an order of magnitude above both σ and the other rows' errors: the record starts mid-motion."""
    k0 = max(na, nb)
    if k0 == 0 or u.size <= 2 * k0:
        return
    Phi, Y = arx_regressor(u, y, na, nb)
    theta = -np.linalg.lstsq(Phi[k0:], Y[k0:], rcond=None)[0]
    e = Phi @ theta + Y
    head = float(np.sqrt(np.mean(e[:k0] ** 2)))
    rest = float(np.sqrt(np.mean(e[k0:] ** 2)))
    if head > 10.0 * max(rest, sigma):
        warnings.warn(
            f"the record does not start at rest: the first {k0} equation errors (rms {head:.3g}) use the zero "
            f"samples (7.4) assumes before the record and are {head / max(rest, sigma):.0f}× the others; δ will "
            "be inflated. Start the record at rest, or use the subspace program (7.5), which carries the past "
            "data in W_p", NotAtRestWarning, stacklevel=4)


@result
@dataclass(frozen=True, eq=False)
class ArxProblem:
    """Program (7.4) on given data: validation, scaling and the independent bounds.

    Build with :meth:`from_data`.  ``evaluate_primal`` and ``evaluate_dual`` are the two sides of
    :class:`Certificate` (data units); ``column_form`` is the scaled program the backends solve:
    ``u/s_u``, ``y/s_y`` with ``s_u`` = rms(u), ``s_y`` = rms of the least-squares equation error.

    ``free_rows`` (default 0): the first ``free_rows`` equation errors are free parameters (appended
    to θ as unit columns of Φ), and the noise budget counts the other rows only, ``σ√(n − free_rows)``.
    That is the program for a record that does not start at rest: whatever the samples before the
    record did to the first rows (Δ's own initial state) is not charged to Δ or to the noise.
    """

    u: np.ndarray
    y: np.ndarray
    na: int
    nb: int
    sigma: float
    scale: tuple
    cond_Tu: float
    free_rows: int = 0

    @classmethod
    def from_data(cls, u, y, na, nb, sigma, free_rows: int = 0) -> "ArxProblem":
        """Validate (raises :class:`DataError`) and scale."""
        u = siso_signal(u, "u")
        y = siso_signal(y, "y", n=u.size)
        na, nb = _order(na, "na"), _order(nb, "nb")
        free_rows = _order(free_rows, "free_rows")
        sigma = check_sigma(sigma)
        n = u.size
        if n <= na + nb + free_rows:
            raise DataError(f"need more samples than parameters: n = {n} <= na + nb + free_rows = "
                            f"{na + nb + free_rows}")
        if u[0] == 0.0 and free_rows == 0:
            raise DataError(
                "u[0] == 0: T(u) is singular, so no causal Δ(q)u can explain a non-zero error at t = 0 and the "
                "substitution e − ξ = T(u)h is not available; start the record at the first non-zero input sample"
            )
        # u to unit rms, y so that the least-squares equation error has unit rms: the program splits
        # exactly that error between ξ and Δu (measured: fewer 'optimal_inaccurate')
        su = rms_or_one(u)
        sy = arx_least_squares(u[free_rows:], y[free_rows:], na, nb)[1]
        if free_rows == 0:
            _warn_if_not_at_rest(u, y, na, nb, sigma)
        if not sy > 1e-12 * rms_or_one(y):
            sy = rms_or_one(y)
        return cls(u=u, y=y, na=na, nb=nb, sigma=sigma, scale=(su, sy), cond_Tu=toeplitz_cond(u), free_rows=free_rows)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.u.size)

    @property
    def n_noise(self) -> int:
        """Number of rows the noise budget ``σ√n_noise`` covers (the rows that are not free)."""
        return self.n - int(self.free_rows)

    def regressor(self, scaled: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """``(Φ, Y)`` with ``e(θ) = Φθ + Y``: :func:`arx_regressor` plus one unit column per free row."""
        su, sy = self.scale if scaled else (1.0, 1.0)
        Phi, Y = arx_regressor(self.u / su, self.y / sy, self.na, self.nb)
        if self.free_rows:
            Phi = np.hstack([Phi, np.eye(self.n, self.free_rows)])
        return Phi, Y

    def column_form(self, scaled: bool = True) -> ColumnForm:
        """(7.4) as the column form (C) of :mod:`unfalsify._columns` (j = 1, 𝓛 = range Φ)."""
        su, sy = self.scale if scaled else (1.0, 1.0)
        Phi, Y = self.regressor(scaled)
        Q = np.linalg.qr(Phi)[0] if Phi.shape[1] else None
        return ColumnForm((self.u / su)[:, None], Y[:, None], self.sigma / sy * np.sqrt(self.n_noise), basis_left=Q)

    def evaluate_primal(self, h, theta) -> tuple[float, float]:
        """``(‖T(h)‖₂, ‖Φθ + Y − T(u)h‖₂)`` recomputed from the data (inf/NaN for non-finite input)."""
        h = np.asarray(h, float).reshape(-1)
        theta = np.asarray(theta, float).reshape(-1)
        if not (np.all(np.isfinite(h)) and np.all(np.isfinite(theta))):
            return float("inf"), float("nan")
        Phi, Y = self.regressor()
        xi = (Phi @ theta if theta.size else 0.0) + Y - _conv_cols(self.u[:, None], h[:, None])[:, 0]
        return certified_norm(h), float(np.linalg.norm(xi))

    def evaluate_dual(self, v, W, sigma=None) -> float:
        """The weak-duality lower bound of :class:`Certificate` for any ``v`` (n,) and ``W``."""
        sigma = self.sigma if sigma is None else float(sigma)
        return self.column_form(scaled=False).lower_bound(v, W, rho=sigma * np.sqrt(self.n_noise))


#: up to this n, ``‖T(h)‖₂`` of a certificate is the largest singular value of the dense matrix (LAPACK)
DENSE_NORM_LIMIT = 4000


def certified_norm(h) -> float:
    """An upper bound on ``‖T(h)‖₂`` for a certificate's upper side (never an underestimate).

    Up to :data:`DENSE_NORM_LIMIT`: the largest singular value of the dense matrix (LAPACK; near the
    optimum of (7.4) most singular values of T(h) cluster at δ and ARPACK does not converge, measured
    at n = 1000).  Above it, the smaller of two proven bounds:

    * the symbol bound :func:`symbol_bound` (``‖T_n(h)‖₂ ≤ sup_ω |ĥ(e^{jω})|`` with Bernstein's
      inequality on the grid);
    * a Lanczos estimate s (FFT products) raised to ``c = s(1 + 1e-6)`` and *proven* by a Cholesky
      factorisation of ``c²I − T(h)ᵀT(h) − τI`` (:func:`_norm_below_by_cholesky`): if it succeeds,
      ``‖T(h)‖₂ ≤ c``.  A Lanczos value alone is only a lower estimate, so it is never returned
      unproven.
    """
    h = np.asarray(h, float).reshape(-1)
    if not np.all(np.isfinite(h)):
        return float("inf")
    if h.size <= DENSE_NORM_LIMIT:
        return toeplitz_norm(h, method="dense")
    bound = symbol_bound(h)
    try:
        estimate = toeplitz_norm(h, method="lanczos")
    except RuntimeError:  # ArpackNoConvergence
        return bound
    c = estimate * (1.0 + 1e-6)
    if c < bound and _norm_below_by_cholesky(h, c):
        return c
    return bound


def _norm_below_by_cholesky(h: np.ndarray, c: float) -> bool:
    """True only if ``‖T(h)‖₂ ≤ c`` is proven by a Cholesky factorisation of ``c²I − TᵀT − τI``.

    ``TᵀT`` is formed in O(n²) (:func:`unfalsify._toeplitz._toeplitz_gram`: each entry an FFT correlation
    minus a partial sum, absolute error ≲ 2n·u·‖h‖², so ‖ΔG‖₂ ≤ 2n²u‖h‖²; u the unit roundoff).  A
    floating-point Cholesky that runs to completion is the exact factorisation of the matrix plus E,
    ``‖E‖₂ ≤ γ_{n+1}·n·max_i a_ii ≤ 2n(n+1)u·c²`` (Demmel's componentwise backward error).  With the
    shift ``τ = 2n²u‖h‖² + 2n(n+1)u·c²`` success proves ``c²I − TᵀT ⪰ 0``.  (``‖h‖ > c`` already
    refutes the bound: h is the first column of T.)
    """
    n = h.size
    u = np.finfo(float).eps / 2
    hh = float(h @ h)
    if hh > c * c:
        return False
    tau = 2.0 * n * n * u * hh + 2.0 * n * (n + 1) * u * c * c
    if tau >= 0.5 * c * c:
        return False
    A = _toeplitz_gram(h)
    A *= -1.0
    A.flat[:: n + 1] += c * c - tau
    try:
        scipy.linalg.cholesky(A, lower=False, overwrite_a=True, check_finite=False)
    except np.linalg.LinAlgError:
        return False
    return True


def symbol_bound(h, oversample: int = 64) -> float:
    """``max_k |ĥ(2πk/M)| / (1 − π(n−1)/M)`` ≥ ``sup_ω |ĥ(e^{jω})|`` ≥ ``‖T_n(h)‖₂`` (M = oversample·n, power of 2)."""
    h = np.asarray(h, float).reshape(-1)
    n = h.size
    M = int(2 ** np.ceil(np.log2(oversample * max(n, 1))))
    peak = float(np.abs(np.fft.rfft(h, M)).max())
    return peak / (1.0 - np.pi * (n - 1) / M)


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


def _solve_cvxpy(P: ArxProblem, form: str, solver: str, solver_options) -> dict:
    """The reference cvxpy models (unchanged), in scaled units; returns a dict in data units."""
    n, na, nb = P.n, P.na, P.nb
    su, sy = P.scale
    us, ys = P.u / su, P.y / sy
    Phi_s, Y_s = P.regressor(scaled=True)
    sig_s = P.sigma / sy
    Tu_s = toeplitz_matrix(us)
    p = Phi_s.shape[1]
    theta = cp.Variable(p, name="theta")
    delta = cp.Variable(name="delta")
    e = (Phi_s @ theta + Y_s) if p else cp.Constant(Y_s)
    if form == "conditioned":
        h = cp.Variable(n, name="h")
        xi = e - Tu_s @ h
        cons = [cp.norm(xi, 2) <= sig_s * np.sqrt(P.n_noise), toeplitz_norm_lmi(h, delta, n)]
    else:
        xi_v = cp.Variable(n, name="xi")
        g = e - xi_v
        G = toeplitz_expr(g, n)
        xc = cp.reshape(xi_v, (n, 1), order="F") / np.sqrt(n)
        noise_lmi = cp.bmat([[np.array([[sig_s]]), xc.T], [xc, sig_s * np.eye(n)]]) >> 0
        gram = Tu_s.T @ Tu_s
        main_lmi = cp.bmat([[delta * gram, G.T], [G, delta * np.eye(n)]]) >> 0
        cons = [noise_lmi, main_lmi]
    prob = cp.Problem(cp.Minimize(delta), cons)
    status, elapsed = solve(prob, solver, solver_options, f"ARX unfalsification (form={form}, n={n})")
    d_s = solved_value(status, delta.value)

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
            with np.errstate(over="ignore", invalid="ignore"):
                h_out = deconvolve(P.u, e_out - xi_out, exact=n <= 400)
        else:
            h_out = np.full(n, np.nan)
        Z = cons[1].dual_value
        if Z is not None:
            Z21 = np.asarray(Z, float)[n:, :n]
            v = -2.0 * np.array([np.trace(Z21, offset=-k) for k in range(n)])
            W = -2.0 * Z21 @ Tu_s.T
    if v is not None and np.all(np.isfinite(v)) and np.all(np.isfinite(W)):
        v, W = _best_scaled_dual(P.column_form(scaled=True), v, W)
        W = W * su  # data units: T(u)ᵀv = s_u T(u/s_u)ᵀv
    else:
        v = W = None
    return dict(delta=d_s * sy / su, h=h_out, theta=theta_out, status=status, time=elapsed, problem=prob, v=v, W=W)


#: ``method=`` of the structured backend
METHODS = ("barrier", "bracket")


def _solve_structured(P: ArxProblem, tol: float, time_limit, progress: bool, method: str = "barrier") -> dict:
    """The Cholesky barrier solver (:mod:`unfalsify._arx_barrier`) or the FFT-only bracket
    (:mod:`unfalsify._bracket`); returns a dict in data units."""
    from ._arx_barrier import ridge_start, solve_arx_barrier
    from ._bracket import solve_bracket

    f = P.column_form(scaled=True)
    t0 = time.perf_counter()
    B0 = f.project(f.B)
    if np.linalg.norm(B0) <= f.rho:  # the least-squares model already explains the data: δ = 0
        h_s = np.zeros(P.n)
        out = dict(status="optimal", H=h_s[:, None], V=None, W=None, upper=0.0, lower=0.0)
    elif method == "bracket":
        out = solve_bracket(f, time_limit=time_limit, progress=progress)
        h_s = out["H"][:, 0] if out["H"] is not None else np.full(P.n, np.nan)
    else:
        out = solve_arx_barrier(f, ridge_start(f, B0), tol=tol, time_limit=time_limit, progress=progress)
        h_s = out["H"][:, 0]
    return _structured_out(P, out, h_s, time.perf_counter() - t0)


def _structured_out(P: ArxProblem, out: dict, h_s: np.ndarray, elapsed: float) -> dict:
    """A structured solver's scaled output as the backend dict in data units (θ refitted by least squares)."""
    su, sy = P.scale
    h = h_s * (sy / su)
    Phi, Y = P.regressor()
    if Phi.shape[1]:
        theta = -np.linalg.lstsq(Phi, Y - _conv_cols(P.u[:, None], h[:, None])[:, 0], rcond=None)[0]
    else:
        theta = np.zeros(0)
    W = out["W"]
    if W is not None:
        if isinstance(W, CirculantDual):
            W = W.scaled(su)
        else:
            W = (W[0] * su, W[1]) if isinstance(W, tuple) else W[0] * su  # W = P Qᵀ: scale P only
    v = out["V"]
    v = None if v is None else v[:, 0]
    return dict(delta=out["upper"] * sy / su, h=h, theta=theta, status=out["status"], time=elapsed,
                problem=None, v=v, W=W)


def _finish_structured(status: str, what: str, cert, delta: float) -> float:
    """δ of a structured solve (NaN unless it ended with a bracket) and the warning for a non-optimal status."""
    if status not in ("optimal", "bracket", "time_limit", "interrupted") or not np.isfinite(cert.upper_bound):
        delta = float("nan")
    if status != "optimal":
        gap = cert.relative_gap
        warnings.warn(
            f"{what}: structured backend stopped with status '{status}'"
            + (f"; the certified bracket has relative gap {gap:.3g}" if np.isfinite(gap) else ""),
            SolverWarning,
            stacklevel=3,
        )
    return delta


def arx_unfalsify(
    u,
    y,
    na: int,
    nb: int,
    sigma: float,
    *,
    form: str = "conditioned",
    solver: str = "CLARABEL",
    solver_options: dict | None = None,
    backend: str = "cvxpy",
    tol: float = 1e-6,
    time_limit: float | None = None,
    progress: bool = True,
    method: str = "barrier",
    free_rows: int = 0,
) -> ArxResult:
    """Smallest ``‖Δ‖∞`` unfalsifying the ARX model (7.3) with ``‖ξ‖_rms ≤ σ``: program (7.4).

    Parameters
    ----------
    u, y : array_like, shape (n,) or (n, 1)
        SISO data, system at rest before t = 0; ``u[0]`` must be non-zero.
    na, nb : int
        Orders of ``A(q) = 1 + a₁q⁻¹ + …`` and ``B(q) = b₁q⁻¹ + …``.
    sigma : float
        Admissible rms noise level σ > 0 (same units as y).
    form : {"conditioned", "thesis"}
        See the module docstring.  ``"conditioned"`` is exact and well conditioned;
        ``"thesis"`` is the literal §7.2.2 LMI (small n only, cvxpy backend only).
    solver : str
        cvxpy solver name, passed explicitly (cvxpy may otherwise choose SCS); cvxpy backend.
    solver_options : dict, optional
        Extra keyword arguments for ``Problem.solve``; cvxpy backend.
    backend : {"cvxpy", "structured"}
        ``"cvxpy"``: the generic LMI models above (the reference).  ``"structured"``: the barrier
        solver of :mod:`unfalsify._structured`, which exploits the Toeplitz structure (O(n²) memory,
        O(n³) per iteration; n = 400 in seconds).
    tol : float
        Structured backend: stop when the certified relative gap ``(upper − lower)/upper ≤ tol``.
    time_limit : float, optional
        Structured backend: wall-clock limit in seconds; on expiry (or Ctrl-C) the best certified
        bracket so far is returned with status ``"time_limit"`` (``"interrupted"``) and a warning.
    progress : bool
        Structured backend: a tqdm bar (outer iteration, bounds) for solves longer than ~2 s.
    method : {"barrier", "bracket"}
        Structured backend.  ``"barrier"``: the Cholesky barrier method of :mod:`unfalsify._arx_barrier`
        (O(n²) memory, O(n³) per Newton step), certified to the relative gap ``tol``.  ``"bracket"``:
        FFT-only bounds of :mod:`unfalsify._bracket` (O(n) memory, n = 10⁴ in minutes): a feasible h
        with a small spectral peak (upper) and a circulant dual point (lower); the result has status
        ``"bracket"``, δ = the certified upper bound and a :class:`SolverWarning` stating the relative
        gap, which is NOT small (measured 0.47–0.53 at n = 200 … 10⁴).
    free_rows : int
        The first ``free_rows`` equation errors are free (neither Δu nor noise): the program for a
        record that does not start at rest, whose first rows carry the response to samples before it.
        The noise budget is then ``σ√(n − free_rows)`` and ``u[0]`` may be zero.  Conditioned form only.

    Returns
    -------
    ArxResult
        With a two-sided ``certificate`` (:class:`Certificate`): ``upper_bound = ‖T(h)‖₂`` and the
        noise recomputed from ``(theta, impulse)``, ``lower_bound`` from the dual point.

    Raises
    ------
    DataError
        Bad data (NaN, lengths, MIMO, ``u[0] = 0``, too few samples), bad orders, σ ≤ 0.
    ValueError
        Unknown ``form``, ``backend`` or ``method``, ``form="thesis"`` with the structured backend, or
        ``method="bracket"`` with the cvxpy backend.
    UnfalsificationError
        cvxpy: solver failure or an infeasible/unbounded status (impossible in exact arithmetic).

    Warns
    -----
    SolverWarning
        Status other than optimal (δ is NaN unless ``optimal_inaccurate``, or, for the structured
        backend, ``bracket``/``time_limit``/``interrupted``, where δ is the certified upper bound).
    IllConditionedWarning
        ``form="thesis"`` with ``cond T(u) > COND_WARN``.
    """
    form = check_form(form)
    backend = check_backend(backend)
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; use one of {', '.join(repr(m) for m in METHODS)}")
    if method != "barrier" and backend != "structured":
        raise ValueError(f"method={method!r} needs backend='structured'")
    if backend == "structured" and form != "conditioned":
        raise ValueError("backend='structured' solves the conditioned form; use form='conditioned'")
    if free_rows and form != "conditioned":
        raise ValueError("free_rows needs form='conditioned'")
    P = ArxProblem.from_data(u, y, na, nb, sigma, free_rows=free_rows)
    if form == "thesis" and not P.cond_Tu <= COND_WARN:
        warnings.warn(
            f"form='thesis' with cond T(u) = {P.cond_Tu:.3g}: T(u)ᵀT(u) is numerically singular; the solver's δ "
            "is not certified by its own variables (see certificate); prefer form='conditioned'",
            IllConditionedWarning,
            stacklevel=2,
        )
    if backend == "cvxpy":
        out = _solve_cvxpy(P, form, solver, solver_options)
    else:
        out = _solve_structured(P, float(tol), time_limit, progress, method)
    cert = certify(P, out["delta"], out["h"], out["theta"], out["v"], out["W"])
    delta = out["delta"]
    if backend == "structured":
        delta = _finish_structured(out["status"], f"ARX unfalsification (n={P.n})", cert, delta)
    Phi, Y = P.regressor()
    xi = (Phi @ out["theta"] if Phi.shape[1] else 0.0) + Y - _conv_cols(P.u[:, None], out["h"][:, None])[:, 0]
    return ArxResult(
        delta=delta,
        theta=out["theta"],
        noise=xi,
        impulse=out["h"],
        status=out["status"],
        solve_time=out["time"],
        problem=out["problem"],
        form=form,
        sigma=P.sigma,
        na=P.na,
        nb=P.nb,
        cond_Tu=P.cond_Tu,
        certificate=cert,
        scale=P.scale,
        backend=backend,
    )


def certify(P, delta, impulses, params, v, W) -> Certificate:
    """The :class:`Certificate` of a primal point (impulses, params) and a dual point (v, W) for ``P``."""
    up, nn = P.evaluate_primal(impulses, params)
    lo = P.evaluate_dual(v, W) if v is not None else float("nan")
    n_noise = P.n_noise if isinstance(P, ArxProblem) else int(P.horizon * P.n_columns)
    return Certificate(
        delta=float(delta),
        upper_bound=float(up),
        lower_bound=float(lo),
        noise_norm=float(nn),
        noise_bound=float(P.sigma * np.sqrt(n_noise)),
        sigma=P.sigma,
        n_noise=n_noise,
        impulses=impulses,
        params=params,
        dual_v=v,
        dual_G=W,
        problem=P,
    )
