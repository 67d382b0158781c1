"""Model-based discrete infinite-horizon H∞ mixed-sensitivity design (comparator of §6.2–6.3).

Problem (3.1): find a discrete LTI ``K`` (error feedback ``u = K e``, ``e = r − y``) that
stabilises ``P`` and minimises ``‖[W1 S; W2 K S]‖∞`` with ``S = (I + P K)⁻¹``.

python-control's ``hinfsyn`` (SLICOT SB10AD) is continuous-time only and silently wrong
on discrete plants (it returns a controller with dt = 0 and a meaningless γ).  Here the discrete generalized plant is mapped to
continuous time by the bilinear transform ``z = (a + s)/(a − s)``, ``a = 2/dt``, which maps
the unit circle onto the imaginary axis and therefore preserves the H∞ norm of every
closed loop; SB10AD builds the central controller for a fixed level (``job=4``), the
controller is mapped back, and the level is bisected on the *discrete* closed loop
(stable and ``‖·‖∞ < γ(1 + 1e-8)``, *proven* on the discrete system by
:func:`~synthesis.norm_below`, the bounded-real test; the reported norm is the proven upper side
of :func:`~synthesis.hinf_norm`).

Plants with poles on the unit circle (the servo's and the three-disk's integrators)
violate the Riccati solvability assumption (A4): the reference enters only through
``e`` and cannot excite the plant modes.  A fictitious input disturbance of size ``ε``
(``u_plant = u + ε d``) is then added to the exogenous inputs.  The augmented norm bounds
the original one from above, so every controller returned still satisfies the original
specification at its level; the reported ``gamma_opt`` is an upper bound that tends to the
true infimum as ``ε → 0`` (the result records ``epsilon``).
"""
from __future__ import annotations

import numbers
import warnings
from dataclasses import dataclass

import control
import numpy as np

from ._validation import DataError, as_discrete_system, check_count, check_level
from .hinfnorm import NormBracket, _norm_below, hinf_norm
from .minimax import InfeasibleGammaError
from .riccati import generalized_plant
from .weights import _ss_parts, as_weight, common_dt
from ._repr import result

__all__ = ["MixsynResult", "discrete_mixsyn", "mixsyn_closed_loop", "peak_gain"]


@result
@dataclass(frozen=True, eq=False)
class MixsynResult:
    """Result of :func:`discrete_mixsyn`.

    Attributes
    ----------
    controller : control.StateSpace
        Discrete controller, input ``e = r − y`` (``l`` channels), output ``u`` (``m``),
        the plant's sample time: a standard error-feedback ``u = K(r − y)``.
        :meth:`controller_ry` gives the same law with inputs ``[r; y]``.
    gamma : float
        Level the controller was built for.
    gamma_opt : float
        Smallest feasible level found by bisection (within ``rtol``; an upper bound of the
        infimum, see ``epsilon``).
    norm : float
        Proven upper bound of ``‖[W1 S; W2 K S]‖∞`` for the discrete closed loop with
        :attr:`controller` (``bracket.upper``; below ``gamma·(1 + 1e-8)``).
    closed_loop : control.StateSpace
        Discrete map ``r → [z_w1; z_w2]``.
    epsilon : float
        Size of the fictitious plant-input disturbance (0 when not needed).
    bisection_steps : int
    bracket : NormBracket
        ``lower ≤ ‖[W1 S; W2 K S]‖∞ ≤ upper`` of :attr:`closed_loop` (:func:`~synthesis.hinf_norm`):
        ``lower`` attained at ``bracket.frequency``, ``upper`` (= :attr:`norm`) proven.
    """

    controller: control.StateSpace
    gamma: float
    gamma_opt: float
    norm: float
    closed_loop: control.StateSpace
    epsilon: float
    bisection_steps: int
    bracket: NormBracket | None = None

    def controller_ry(self) -> control.StateSpace:
        """The controller with inputs ``[r; y]`` (``u = K r − K y``), for the common interface."""
        K = self.controller
        return control.ss(K.A, np.hstack([K.B, -K.B]), K.C, np.hstack([K.D, -K.D]), K.dt)


def _d2c(A, B, C, D, a):
    """Bilinear map ``z = (a + s)/(a − s)``: discrete (A, B, C, D) → continuous."""
    n = A.shape[0]
    M = np.linalg.inv(A + np.eye(n))
    return a * M @ (A - np.eye(n)), np.sqrt(2 * a) * M @ B, np.sqrt(2 * a) * C @ M, D - C @ M @ B


def _c2d(A, B, C, D, a):
    """Inverse of :func:`_d2c`: continuous → discrete, ``s = a (z − 1)/(z + 1)``."""
    n = A.shape[0]
    M = np.linalg.inv(np.eye(n) - A / a)
    return M @ (np.eye(n) + A / a), np.sqrt(2 / a) * M @ B, np.sqrt(2 / a) * C @ M, D + C @ M @ B / a


def _lft(A, B1, B2, C1, C2, D11, D12, D21, D22, K):
    """Lower LFT of the plant with ``K`` (u = K y); raises if ill-posed."""
    Ak, Bk, Ck, Dk = K
    m = B2.shape[1]
    Z = np.eye(m) - Dk @ D22
    if np.linalg.cond(Z) > 1e12:
        raise DataError("closed loop is ill-posed (I - Dk D22 singular)")
    Zi = np.linalg.inv(Z)
    # u = Zi (Dk C2 x + Ck xk + Dk D21 w)
    Ux, Uk, Uw = Zi @ Dk @ C2, Zi @ Ck, Zi @ Dk @ D21
    Yx, Yk, Yw = C2 + D22 @ Ux, D22 @ Uk, D21 + D22 @ Uw
    Acl = np.block([[A + B2 @ Ux, B2 @ Uk], [Bk @ Yx, Ak + Bk @ Yk]])
    Bcl = np.vstack([B1 + B2 @ Uw, Bk @ Yw])
    Ccl = np.hstack([C1 + D12 @ Ux, D12 @ Uk])
    Dcl = D11 + D12 @ Uw
    return Acl, Bcl, Ccl, Dcl


def _problem(P, W1, W2):
    """Discrete generalized plant ``[r; (d); u] → [z1; z2; e]``, state ``[x_p; x_w1; x_w2]``.

    The ``[r; u] → z`` part is the §4.2.1 plant of :func:`~synthesis.generalized_plant`; the
    measured output is the error ``e = r − y = −C_p x_p + r − D_p u``.
    """
    gp = generalized_plant(P, W1, W2)
    l, m = gp.l, gp.m
    _, _, Cp, Dp = _ss_parts(P)
    Ce = np.hstack([-Cp, np.zeros((l, gp.n_w1 + gp.n_w2))])
    return dict(A=gp.A, Br=gp.B[:, :l], Bu=gp.B[:, l:], Cz=gp.C, Dzr=gp.D[:, :l], Dzu=gp.D[:, l:],
                Ce=Ce, Der=np.eye(l), Deu=-Dp, l=l, m=m)


def mixsyn_closed_loop(P, W1, W2, K) -> control.StateSpace:
    """Discrete closed loop ``r → [W1 S r; W2 K S r]`` for an error-feedback controller ``K``.

    Parameters
    ----------
    P, W1, W2 : discrete systems (weights as accepted by :func:`synthesis.as_weight`)
    K : control.StateSpace or control.TransferFunction
        Discrete controller ``u = K e`` (``l`` inputs, ``m`` outputs), the plant's sample time.

    Raises
    ------
    DataError
        Continuous-time or NaN systems, a controller with another sample time or the wrong
        number of inputs/outputs, an ill-posed loop.

    Examples
    --------
    ``P = 0.5/(z − 0.8)`` under the static controller ``K = 0.5``, ``W1 = 1``, ``W2 = 0.1``: at DC
    ``PK = 1.25`` and ``S = 1/2.25``.

    >>> import control, numpy as np
    >>> P = control.ss([[0.8]], [[1.0]], [[0.5]], [[0.0]], 0.1)
    >>> K = control.tf([0.5], [1], 0.1)
    >>> cl = mixsyn_closed_loop(P, 1.0, 0.1, K)
    >>> cl.ninputs, cl.noutputs, cl.nstates
    (1, 2, 1)
    >>> print(np.round(np.real(cl(1.0)).ravel(), 4))
    [0.4444 0.0222]

    The same as ``S = 1/(1 + PK)`` formed by :func:`control.feedback`:

    >>> S = control.feedback(1, P * K)
    >>> z = np.exp(0.3j)
    >>> np.allclose(np.squeeze(cl(z)), [np.squeeze(S(z)), 0.1 * 0.5 * np.squeeze(S(z))])
    True
    """
    P, W1, W2, dt = _check(P, W1, W2)
    K = as_discrete_system(K, "K", hint="discretise the controller at the plant's sample time")
    if K.dt is not True and not np.isclose(float(K.dt), dt, rtol=1e-9, atol=0):
        raise DataError(f"K has sample time {K.dt} but the plant has {dt}; use a controller sampled at the plant's dt")
    if (K.ninputs, K.noutputs) != (P.noutputs, P.ninputs):
        raise DataError(
            f"K has {K.ninputs} input(s) and {K.noutputs} output(s); an error-feedback controller u = K e for this "
            f"plant needs {P.noutputs} input(s) (e = r - y) and {P.ninputs} output(s) (u)")
    pr = _problem(P, W1, W2)
    Kd = _ss_parts(K)
    A, B, C, D = _lft(pr["A"], pr["Br"], pr["Bu"], pr["Cz"], pr["Ce"], pr["Dzr"], pr["Dzu"], pr["Der"],
                      pr["Deu"], Kd)
    return control.ss(A, B, C, D, P.dt)


def _check(P, W1, W2):
    P = as_discrete_system(P, "P", hint="discrete_mixsyn designs discrete controllers; use control.mixsyn "
                                        "for continuous time")
    W1 = as_weight(W1, "W1", inputs=P.noutputs, dt=P.dt)
    W2 = as_weight(W2, "W2", inputs=P.ninputs, dt=P.dt)
    dt = common_dt(P, W1, W2)
    if dt is True:
        raise DataError("P needs a numeric sample time (dt > 0) for the bilinear map")
    fix = lambda W: W if W.nstates else control.ss(W.A, W.B, W.C, W.D, dt)  # noqa: E731
    return P, fix(W1), fix(W2), float(dt)


def _gains(A, B, C, D, w):
    """Largest singular value of ``C (e^{jw} I − A)⁻¹ B + D`` at each frequency ``w`` (rad/sample)."""
    z = np.exp(1j * np.asarray(w, float))
    n = A.shape[0]
    if n == 0:
        return np.full(z.shape, np.linalg.norm(D, 2))
    M = z[:, None, None] * np.eye(n)[None] - A[None]
    H = C[None] @ np.linalg.solve(M, np.broadcast_to(B, (z.size,) + B.shape)) + D[None]
    return np.linalg.svd(H, compute_uv=False)[:, 0]


def peak_gain(sys, n_grid: int = 4000) -> float:
    """Dense-grid *estimate* of the H∞ norm of a discrete system: a lower bound, not a certificate.

    The grid is uniform and logarithmic on ``(0, π]`` rad/sample and contains the pole angles
    (lightly damped modes); the five highest grid peaks are refined by a bounded scalar search.
    The value is a gain actually attained, hence ``≤ ‖G‖∞``; a grid can miss a sharp peak, and
    it is slow (two dense solves per grid point).  For a proven bound use
    :func:`~synthesis.hinf_norm` (bracket with a proven upper side) or
    :func:`~synthesis.norm_below`.  (``control.norm`` is not used: it returns ∞ when a stable
    closed-loop pole lies within ~1e-5 of the unit circle.)

    Parameters
    ----------
    sys : control.StateSpace or control.TransferFunction
        Discrete-time system.
    n_grid : int
        Points of each of the two frequency grids, ≥ 2.

    Returns
    -------
    float
        ``sup_ω σ̄(G(e^{jω}))``, or ``inf`` when a pole lies on or outside the unit circle
        (spectral radius ``>= 1``): the H∞ norm of an unstable system is infinite; 0 for a
        system without inputs or outputs (as :func:`~synthesis.hinf_norm`).

    Raises
    ------
    DataError
        If ``sys`` is continuous-time (its discrete frequency response would be meaningless) or
        not a python-control system; ``n_grid`` not an integer ≥ 2.

    Examples
    --------
    ``1/(z − 0.5)`` peaks at DC with gain 2; an unstable system has an infinite norm:

    >>> import control
    >>> round(peak_gain(control.tf([1], [1, -0.5], 1)), 6)
    2.0
    >>> peak_gain(control.tf([1], [1, -1.5], 1))
    inf

    A lightly damped resonance, inside the certified bracket of :func:`~synthesis.hinf_norm`:

    >>> from synthesis import hinf_norm
    >>> G = control.tf([1], [1, -1.6, 0.9], 1)
    >>> peak, bracket = peak_gain(G), hinf_norm(G)
    >>> round(peak, 4), bracket.lower - 1e-9 <= peak <= bracket.upper
    (18.6052, True)
    """
    from scipy.optimize import minimize_scalar

    # numpy had refused -5 with a bare ValueError and 10.5 or "10" with a TypeError
    n_grid = check_count(n_grid, "n_grid", 2)
    sys = as_discrete_system(sys, "sys", hint="use control.norm(sys, 'inf') for continuous time")
    A, B, C, D = _ss_parts(sys)
    if A.size and np.max(np.abs(np.linalg.eigvals(A))) >= 1.0:
        return float("inf")
    if B.shape[1] == 0 or C.shape[0] == 0:  # no inputs or outputs: the norm is 0 (the SVD had an empty axis)
        return 0.0
    ang = np.abs(np.angle(np.linalg.eigvals(A))) if A.size else np.zeros(0)
    w = np.unique(np.concatenate([np.linspace(1e-7, np.pi, n_grid), np.geomspace(1e-7, np.pi, n_grid),
                                  ang[(ang > 0) & (ang <= np.pi)], [np.pi]]))
    g = _gains(A, B, C, D, w)
    best = float(g.max())
    order = np.argsort(g)[::-1][:5]
    for k in order:
        lo, hi = w[max(k - 1, 0)], w[min(k + 1, w.size - 1)]
        if hi <= lo:
            continue
        res = minimize_scalar(lambda x: -_gains(A, B, C, D, [x])[0], bounds=(lo, hi), method="bounded",
                              options={"xatol": 1e-12 * max(1.0, hi)})
        best = max(best, float(-res.fun))
    return best


def _on_unit_circle(A, tol=1e-8) -> bool:
    ev = np.linalg.eigvals(A) if A.size else np.zeros(0)
    return bool(np.any(np.abs(np.abs(ev) - 1.0) < tol))


def discrete_mixsyn(P, W1, W2, gamma: float | None = None, *, gamma_ratio: float = 1.1,
                    rtol: float = 1e-4, epsilon: float | None = None) -> MixsynResult:
    """Discrete ∞-horizon H∞ mixed-sensitivity design ``min ‖[W1 S; W2 K S]‖∞``.

    Parameters
    ----------
    P : control.StateSpace or TransferFunction
        Discrete plant (``m`` inputs, ``l`` outputs, numeric ``dt``).
    W1, W2 : discrete weights
        On ``e = r − y`` (``l`` inputs) and on ``u`` (``m`` inputs), relative degree 0.
    gamma : float, optional
        Level of the returned controller; must be feasible (> ``gamma_opt``).  Default
        ``gamma_ratio * gamma_opt``.
    gamma_ratio : float
        Used when ``gamma`` is None; 1.1 is the thesis's rule of thumb (as in
        :func:`~synthesis.hinf_design`), ``1.35`` the §6.2 choice.  Controllers very close
        to ``gamma_opt`` have huge gains.
    rtol : float
        Relative width of the final bisection bracket.
    epsilon : float, optional
        Fictitious plant-input disturbance size; default ``1e-4`` when the plant has poles
        on the unit circle, 0 otherwise.

    Returns
    -------
    MixsynResult
        ``norm`` is the proven upper bound of the closed-loop norm, ``bracket`` both sides.

    Raises
    ------
    DataError (ValueError)
        Continuous-time plant or weights, bad weights, unit-circle poles with ``epsilon = 0``,
        poles at ``z = −1``; ``gamma``, ``gamma_ratio`` (< 1), ``rtol`` or ``epsilon`` (< 0)
        not valid numbers (checked before any synthesis).
    InfeasibleGammaError
        If ``gamma`` is given and not above ``gamma_opt``.

    Notes
    -----
    A level ``g`` counts as achieved when SB10AD returns a controller whose discrete closed
    loop is stable and *proven* to have ``‖·‖∞ < g(1 + 1e-8)`` (:func:`~synthesis.norm_below`).

    Examples
    --------
    ``P = 0.5/(z − 0.8)`` at 10 Hz, a first-order performance weight and a static control weight:

    >>> import control
    >>> from synthesis import makeweight, mixsyn_closed_loop, norm_below
    >>> P = control.ss([[0.8]], [[1.0]], [[0.5]], [[0.0]], 0.1)
    >>> W1 = makeweight(10.0, (0.5, 1.0), 0.5, 0.1)
    >>> res = discrete_mixsyn(P, W1, 0.1)
    >>> round(res.gamma_opt, 2), round(res.gamma / res.gamma_opt, 6), res.norm < res.gamma
    (0.52, 1.1, True)
    >>> K = res.controller
    >>> K.ninputs, K.noutputs, K.dt
    (1, 1, 0.1)

    The closed loop rebuilt from the controller is proven below the level:

    >>> bool(norm_below(mixsyn_closed_loop(P, W1, 0.1, K), res.gamma))
    True
    """
    return _discrete_mixsyn(P, W1, W2, gamma, gamma_ratio=gamma_ratio, rtol=rtol, epsilon=epsilon)


def _mixsyn_options(gamma, gamma_ratio, rtol, epsilon, route: str):
    """Checked ``(gamma, gamma_ratio, rtol, epsilon)`` of :func:`discrete_mixsyn`."""
    if route not in ("certified", "grid"):
        raise DataError(f"route must be 'certified' or 'grid', got {route!r}")
    if gamma is not None:
        gamma = check_level(gamma, "gamma")
    gamma_ratio = check_level(gamma_ratio, "gamma_ratio")
    if gamma_ratio < 1:
        raise DataError(f"gamma_ratio must be >= 1 (the returned controller needs gamma >= gamma_opt), got {gamma_ratio!r}")
    rtol = check_level(rtol, "rtol")
    if rtol >= 1:
        raise DataError(f"rtol must lie in (0, 1), got {rtol!r}")
    if epsilon is not None:
        if isinstance(epsilon, bool) or not isinstance(epsilon, numbers.Real) or not (
                np.isfinite(epsilon) and epsilon >= 0):
            raise DataError(f"epsilon must be a finite number >= 0 (or None for the default), got {epsilon!r}")
        epsilon = float(epsilon)
    return gamma, gamma_ratio, rtol, epsilon


def _bisect_level(attempt, rtol: float) -> tuple[float, int]:
    """``(γ_opt, attempts)``: the least feasible level to relative ``rtol``, ``attempt(g)`` None when infeasible.

    Doubling from 1 finds a feasible level, halving finds an infeasible one below it, bisection closes the gap.
    """
    hi = 1.0
    best = attempt(hi)
    steps = 1
    while best is None:
        hi *= 2.0
        steps += 1
        if hi > 1e12:
            raise DataError("no stabilising controller found for gamma up to 1e12: check stabilisability/detectability")
        best = attempt(hi)
    lo = 0.0
    if hi == 1.0:
        lo = 0.5
        while attempt(lo) is not None and lo > 1e-9:
            hi, lo = lo, lo / 2.0
            steps += 1
    else:
        lo = hi / 2.0
    while hi - lo > rtol * hi:
        mid = 0.5 * (lo + hi)
        steps += 1
        if attempt(mid) is not None:
            hi = mid
        else:
            lo = mid
    return hi, steps


def _discrete_mixsyn(P, W1, W2, gamma=None, *, gamma_ratio=1.1, rtol=1e-4, epsilon=None,
                     route: str = "certified") -> MixsynResult:
    """:func:`discrete_mixsyn` with a choice of the level check.

    ``route="certified"`` (the public function): :func:`norm_below` in the bisection and
    :func:`hinf_norm` for the result.  ``route="grid"``: the former dense-grid check by
    :func:`peak_gain` (kept for the ``bench-norms`` comparison; ``bracket`` is then None and
    ``norm`` the grid estimate).
    """
    gamma, gamma_ratio, rtol, epsilon = _mixsyn_options(gamma, gamma_ratio, rtol, epsilon, route)
    P, W1, W2, dt = _check(P, W1, W2)
    pr = _problem(P, W1, W2)
    A = pr["A"]
    l, m = pr["l"], pr["m"]
    if A.size and np.min(np.abs(np.linalg.eigvals(A) + 1.0)) < 1e-8:
        raise DataError("the plant or a weight has a pole at z = -1: the bilinear map is singular there")
    Ap = _ss_parts(P)[0]
    if epsilon is None:
        epsilon = 1e-4 if _on_unit_circle(Ap) else 0.0
    if epsilon == 0 and _on_unit_circle(Ap):
        raise DataError("the plant has poles on the unit circle: pass epsilon > 0 (fictitious input disturbance)")
    # exogenous inputs [r; d]
    Bw, Dzw, Dew = pr["Br"], pr["Dzr"], pr["Der"]
    if epsilon > 0:
        Bw = np.hstack([Bw, epsilon * pr["Bu"]])
        Dzw = np.hstack([Dzw, epsilon * pr["Dzu"]])
        Dew = np.hstack([Dew, epsilon * pr["Deu"]])
    Bg = np.hstack([Bw, pr["Bu"]])
    Cg = np.vstack([pr["Cz"], pr["Ce"]])
    Dg = np.block([[Dzw, pr["Dzu"]], [Dew, pr["Deu"]]])
    a = 2.0 / dt
    Ac, Bc, Cc, Dc = _d2c(A, Bg, Cg, Dg, a)

    def attempt(g, n_grid=1000, final=False):
        """Discrete controller for level g, or None if infeasible."""
        import slycot

        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                out = slycot.sb10ad(A.shape[0], Bg.shape[1], Cg.shape[0], m, l, g, Ac, Bc, Cc, Dc, job=4)
        except slycot.exceptions.SlycotArithmeticError:  # infeasible level, rank or Riccati failure (info > 0)
            return None
        Kc = out[1:5]
        if any(not np.all(np.isfinite(M)) for M in Kc):
            return None
        try:
            Kd = _c2d(*Kc, a)
        except np.linalg.LinAlgError:  # a controller pole at s = 2/dt has no discrete image
            return None
        try:
            cl = _lft(A, pr["Br"], pr["Bu"], pr["Cz"], pr["Ce"], pr["Dzr"], pr["Dzu"], pr["Der"], pr["Deu"], Kd)
        except DataError:
            return None
        if cl[0].size and np.max(np.abs(np.linalg.eigvals(cl[0]))) >= 1 - 1e-10:
            return None
        sys = control.ss(*cl, dt)
        if route == "grid":
            nrm = peak_gain(sys, n_grid=n_grid)
            if not nrm <= g * (1 + 1e-8):
                return None
            return Kd, sys, nrm, None
        if not final:
            # inner bisection steps: the pencil test without the rounding allowance (half the cost); the
            # controller returned is built by a final attempt whose level is proven
            if not _norm_below(sys, g * (1 + 1e-8), n_grid=2, allowance=False):
                return None
            return Kd, sys, None, None
        br = hinf_norm(sys)  # proven upper side, with the allowance
        if not br.upper <= g * (1 + 1e-8):
            return None
        return Kd, sys, br.upper, br

    gamma_opt, steps = _bisect_level(attempt, rtol)
    if gamma is None:
        gamma = gamma_ratio * gamma_opt
    res = attempt(float(gamma), n_grid=4000, final=True)
    if res is None:
        raise InfeasibleGammaError(float(gamma), gamma_opt, message=(
            f"gamma = {float(gamma):.6g} is not achieved: no controller of this mixed-sensitivity problem was proven "
            f"to hold the closed-loop norm below it. The least level proven by bisection is gamma_opt = "
            f"{gamma_opt:.6g} (an upper bound of the optimum, within rtol = {rtol:g}). Choose gamma above gamma_opt, "
            f"e.g. gamma = {gamma_ratio:g} * gamma_opt = {gamma_ratio * gamma_opt:.6g}, or leave gamma=None"))
    Kd, cl, nrm, br = res
    K = control.ss(*Kd, dt, inputs=[f"e[{c}]" for c in range(l)], outputs=[f"u[{c}]" for c in range(m)],
                   name="discrete_mixsyn")
    return MixsynResult(controller=K, gamma=float(gamma), gamma_opt=float(gamma_opt), norm=nrm,
                        closed_loop=cl, epsilon=float(epsilon), bisection_steps=steps, bracket=br)
