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

import warnings
from dataclasses import dataclass

import cvxpy as cp
import numpy as np

from synthesis._validation import DataError

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

__all__ = ["ArxResult", "arx_unfalsify", "arx_regressor", "arx_least_squares"]


@dataclass(frozen=True, eq=False)
class ArxResult:
    """Solution of the ARX unfalsification program (7.4).

    Attributes
    ----------
    delta : float
        δ_unf, the smallest ``‖Δ‖∞`` (NaN if the solve failed).
    theta : ndarray, shape (na + nb,)
        ``[a₁ … a_na, b₁ … b_nb]`` (§7.2.1).
    noise : ndarray, shape (n,)
        ξ.  For the conditioned form ``ξ = Φθ + Y − T(u) h`` exactly.
    impulse : ndarray, shape (n,)
        h, the first n Markov parameters of Δ: ``e − ξ = T(u) h`` (for the thesis form
        recomputed from ξ in exact rational arithmetic).
    status : str
        cvxpy status (``"optimal"``, ``"optimal_inaccurate"``, ...).
    solve_time : float
        Wall time of ``problem.solve`` in seconds (includes cvxpy compilation).
    problem : cvxpy.Problem
        The problem as solved, to inspect or extend (in scaled units, see ``scale``).
    form : str
        ``"conditioned"`` or ``"thesis"``.
    sigma : float
        Admissible rms noise level σ.
    na, nb : int
        Orders of ``A(q)`` and ``B(q)``.
    cond_Tu : float
        cond₂ ``T(u)``.
    certificate : Certificate
        Independent recomputation of δ and the noise rms from ``(theta, noise, impulse)``.
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
    problem: cp.Problem
    form: str
    sigma: float
    na: int
    nb: int
    cond_Tu: float
    certificate: Certificate
    scale: tuple

    @property
    def a(self) -> np.ndarray:
        """``[a₁ … a_na]``."""
        return self.theta[: self.na]

    @property
    def b(self) -> np.ndarray:
        """``[b₁ … b_nb]``."""
        return self.theta[self.na :]

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
        ``"thesis"`` is the literal §7.2.2 LMI (small n only).
    solver : str
        cvxpy solver name, passed explicitly (cvxpy may otherwise choose SCS).
    solver_options : dict, optional
        Extra keyword arguments for ``Problem.solve``.

    Returns
    -------
    ArxResult
        With ``certificate``: δ recomputed as ``‖T(h)‖₂`` from the returned h (exact
        Theorem 7.1 value of the left side of (7.4) for the returned ξ) and the noise rms.

    Raises
    ------
    DataError
        Bad data (NaN, lengths, MIMO, ``u[0] = 0``, too few samples), bad orders, σ ≤ 0.
    UnfalsificationError
        Solver failure or an infeasible/unbounded status (impossible in exact arithmetic).

    Warns
    -----
    SolverWarning
        Status other than optimal (δ is NaN unless ``optimal_inaccurate``).
    IllConditionedWarning
        ``form="thesis"`` with ``cond T(u) > COND_WARN``.
    """
    form = check_form(form)
    u = siso_signal(u, "u")
    y = siso_signal(y, "y", n=u.size)
    na, nb = _order(na, "na"), _order(nb, "nb")
    sigma = check_sigma(sigma)
    n = u.size
    if n <= na + nb:
        raise DataError(f"need more samples than parameters: n = {n} <= na + nb = {na + nb}")
    if u[0] == 0.0:
        raise DataError(
            "u[0] == 0: T(u) is singular, so no causal Δ(q)u can explain a non-zero error at t = 0 and the "
            "substitution e − ξ = T(u)h is not available; start the record at the first non-zero input sample"
        )
    cond = toeplitz_cond(u)
    if form == "thesis" and not cond <= COND_WARN:
        warnings.warn(
            f"form='thesis' with cond T(u) = {cond:.3g}: T(u)ᵀT(u) is numerically singular; the solver's δ "
            "is not certified by its own variables (see certificate); prefer form='conditioned'",
            IllConditionedWarning,
            stacklevel=2,
        )
    # scale u to unit rms and y so that the least-squares equation error has unit rms: the
    # program splits exactly that error between ξ and Δu (measured: fewer 'optimal_inaccurate')
    su = rms_or_one(u)
    sy = arx_least_squares(u, y, na, nb)[1]
    if not sy > 1e-12 * rms_or_one(y):
        sy = rms_or_one(y)
    us, ys = u / su, y / sy
    Phi_s, Y_s = arx_regressor(us, ys, na, nb)
    sig_s = sigma / sy
    Tu_s = toeplitz_matrix(us)

    p = na + nb
    theta = cp.Variable(p, name="theta")
    delta = cp.Variable(name="delta")
    e = (Phi_s @ theta + Y_s) if p else cp.Constant(Y_s)
    if form == "conditioned":
        h = cp.Variable(n, name="h")
        xi = e - Tu_s @ h
        cons = [cp.norm(xi, 2) <= sig_s * np.sqrt(n), toeplitz_norm_lmi(h, delta, n)]
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
    theta_out[na:] *= sy / su
    Phi, Y = arx_regressor(u, y, na, nb)
    e_out = Phi @ theta_out + Y if p else Y
    if form == "conditioned":
        h_out = np.asarray(h.value, dtype=float) * (sy / su) if h.value is not None else np.full(n, np.nan)
        xi_out = e_out - toeplitz_matrix(u) @ h_out
    else:
        xi_out = np.asarray(xi_v.value, dtype=float) * sy if xi_v.value is not None else np.full(n, np.nan)
        if np.all(np.isfinite(xi_out)):
            with np.errstate(over="ignore", invalid="ignore"):
                h_out = deconvolve(u, e_out - xi_out, exact=n <= 400)
        else:
            h_out = np.full(n, np.nan)
    delta_out = d_s * sy / su
    d_cert = toeplitz_norm(h_out) if np.all(np.isfinite(h_out)) else float("inf")
    cert = Certificate(
        delta=delta_out,
        delta_certified=d_cert,
        noise_rms=float(np.linalg.norm(xi_out) / np.sqrt(n)),
        sigma=sigma,
    )
    return ArxResult(
        delta=delta_out,
        theta=theta_out,
        noise=xi_out,
        impulse=h_out,
        status=status,
        solve_time=elapsed,
        problem=prob,
        form=form,
        sigma=sigma,
        na=na,
        nb=nb,
        cond_Tu=cond,
        certificate=cert,
        scale=(su, sy),
    )
