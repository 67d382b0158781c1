"""From data to a robust controller: thesis §7.4 steps 1–5 (subspace δ → Theorem 3.7 design).

Step 3 of §7.4 says: compute δ by (7.5), then design with Theorem 3.7 (additive uncertainty,
Fig. 3.5) using ``W3 = (1/δ) I``, ``W4 = I``.  That weight choice is inverted.  The
small-gain argument for Fig. 3.5:

* the level-γ design bounds the (finite-horizon) gain from ``[r; s]`` to
  ``z = [z_w1; z_w2; z_w3]`` by γ, in particular from ``s`` to ``z_w3 = W3 u``;
* closing ``s = Δ z_w3`` is therefore stable for ``‖Δ‖∞ < 1/γ`` (normalised channel);
* the plant perturbation is ``P_Δ = W4 Δ W3``; with ``W4 = I``, ``W3 = c I`` this is
  ``P_Δ = c Δ``, so the design covers every additive perturbation with
  ``‖P_Δ‖∞ < c/γ``.

To cover the unfalsified ``‖P_Δ‖∞ ≤ δ`` one needs ``c ≥ γ δ``.  The thesis's ``c = 1/δ``
covers ``‖P_Δ‖∞ < 1/(γδ)`` instead -- the wrong direction: the larger the unfalsified
uncertainty, the *smaller* the perturbation it protects against.  When ``γδ² > 1`` it does
not cover δ; when ``γδ² < 1`` (small δ) it over-covers by the factor ``1/(γδ²)`` (≈ 250 for
δ = 0.05, γ = 1.4), pushing the controller towards doing nothing.

Here ``W4 = I``, ``W3 = c I`` with ``c`` the solution of the scalar fixed point

    c = (1 + margin) · δ · γ(c),     γ(c) = gamma_ratio · γ_min_a(c)    (3.64),

found by bracketing and Brent's method.  A solution exists: ``f(c) = c − (1+margin)δγ(c)``
is continuous, ``f(0) < 0`` for δ > 0, and ``γ_min_a(c)`` stays bounded as ``c → ∞``
(``X → Q_1`` in (3.64)), so ``f(c) → +∞``.  At the solution the design covers additive
perturbations up to ``c/γ = (1 + margin) δ``.

Which δ: the subspace δ of (7.5) bounds column operators acting on ``U_f`` *additively on
the predictor output*, exactly where Fig. 3.5 puts ``W4 Δ W3 u``.  The ARX δ of (7.4) bounds
Δ in the *equation error*, ``A(q)y − B(q)u = ξ + Δu``, i.e. a plant perturbation ``Δ/A(q)``,
which is unbounded for the integrating servo (``A(1) = 0``): it must not be fed to
Theorem 3.7.

The guarantee is the finite-horizon one of Chapter 3 for the predictor; it does not
transfer automatically to the receding-horizon LTI controller (5.3)–(5.4) on the true plant.
Check that with :func:`additive_robustness` (nominal closed-loop poles and a proven upper
bound of ``‖K(I + PK)⁻¹‖∞``; small gain: ``δ·‖K(I + PK)⁻¹‖∞ < 1``).  Measured on
the servo (i = 20, W11/W21): at the fixed-point ``c`` for δ ≈ 0.05 the certificate holds
(``δ·‖·‖∞ ≈ 0.6``), but for larger weights, e.g. ``c = 0.5``, the LTI loop's peak was 10
against the finite-horizon promise ``γ/c = 3.4``.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import control
import numpy as np
from scipy.optimize import brentq

import synthesis
from synthesis import Additive, HinfDesign, NormBracket, hinf_norm
from synthesis._validation import DataError

from ._common import SolverWarning, UnfalsificationError
from .subspace import SubspaceResult, subspace_unfalsify

__all__ = [
    "RobustDesignResult",
    "robust_design_from_data",
    "additive_weight_fixed_point",
    "AdditiveRobustness",
    "additive_channel",
    "additive_robustness",
]


@dataclass(frozen=True, eq=False)
class RobustDesignResult:
    """§7.4 pipeline result.

    Attributes
    ----------
    unfalsification : SubspaceResult
        The (7.5) solution that produced δ.
    design : synthesis.HinfDesign
        Theorem 3.7 design with ``uncertainty = Additive(W3 = cI, W4 = I)`` (the nominal
        Theorem 3.1 design, ``uncertainty=None``, when δ = 0).
    delta : float
        Unfalsified δ used by the design: the solver's δ, or the larger certified δ
        (``unfalsification.certificate.delta_certified``) when the certificate fails.
    w3_gain : float
        ``c`` (``W3 = c I``).
    w3_rule : str
        ``"small-gain"`` (``c = (1+margin) δ γ(c)``) or ``"thesis"`` (``c = 1/δ``).
    margin : float
    gamma, gamma_min_a : float
        Level used and (3.64) at ``W3 = c``.
    gamma_min_nominal : float
        (3.8) for the same predictor and ``W1, W2`` without uncertainty.
    covered_delta : float
        ``c/γ``: the additive ``‖P_Δ‖∞`` the small-gain argument covers (≥ δ for the
        small-gain rule; for the thesis rule it is ``1/(γδ)``).
    """

    unfalsification: SubspaceResult
    design: HinfDesign
    delta: float
    w3_gain: float
    w3_rule: str
    margin: float
    gamma: float
    gamma_min_a: float
    gamma_min_nominal: float
    covered_delta: float

    @property
    def controller(self) -> control.StateSpace:
        """The LTI controller (inputs ``[r; y]``, output ``u``)."""
        return self.design.controller

    @property
    def covers_delta(self) -> bool:
        """True when ``covered_delta >= delta``."""
        return bool(self.covered_delta >= self.delta)


def _gamma_of(pred, W1, W2, causal: bool, gamma_ratio: float, l: int):
    def g(c: float) -> float:
        unc = Additive(float(c) * np.eye(pred.m), np.eye(l))
        return gamma_ratio * synthesis.gamma_min(pred, W1, W2, causal=causal, uncertainty=unc)

    return g


def additive_weight_fixed_point(pred, W1, W2, delta: float, *, gamma_ratio: float = 1.1, margin: float = 0.1,
                                causal: bool = False, xtol: float = 1e-10, max_doublings: int = 80) -> float:
    """Smallest-found ``c`` with ``c = (1 + margin) δ γ(c)``, ``γ(c) = gamma_ratio · γ_min_a(W3 = cI, W4 = I)``.

    Returns 0 when ``delta == 0``.  See the module docstring for why a root exists.
    """
    if not (np.isfinite(delta) and delta >= 0):
        raise DataError(f"delta must be finite and >= 0, got {delta!r}")
    if not (np.isfinite(margin) and margin >= 0):
        raise DataError(f"margin must be finite and >= 0, got {margin!r}")
    if not (np.isfinite(gamma_ratio) and gamma_ratio > 1.0):
        raise DataError(f"gamma_ratio must be > 1 (the design needs γ > γ_min_a), got {gamma_ratio!r}")
    if delta == 0:
        return 0.0
    g = _gamma_of(pred, W1, W2, causal, gamma_ratio, pred.l)
    k = (1.0 + margin) * delta

    def f(c):
        return c - k * g(c)

    lo = 0.0
    hi = max(k * g(0.0), np.finfo(float).tiny)
    for _ in range(max_doublings):
        if f(hi) >= 0:
            break
        lo, hi = hi, 2.0 * hi
    else:  # pragma: no cover - excluded by the boundedness of γ_min_a
        raise UnfalsificationError("could not bracket the W3 fixed point c = (1+margin) δ γ(c)")
    if f(hi) == 0:
        return float(hi)
    return float(brentq(f, lo, hi, xtol=xtol * max(hi, 1.0), rtol=4 * np.finfo(float).eps))


def robust_design_from_data(
    u,
    y,
    horizon: int,
    W1,
    W2,
    sigma: float,
    *,
    gamma_ratio: float = 1.1,
    margin: float = 0.1,
    w3_rule: str = "small-gain",
    predictor=None,
    causal: bool = False,
    unfalsification: SubspaceResult | None = None,
    form: str = "conditioned",
    solver: str = "CLARABEL",
    solver_options: dict | None = None,
) -> RobustDesignResult:
    """§7.4 steps 1–5: δ by subspace unfalsification (7.5), then a robust Theorem 3.7 design.

    Parameters
    ----------
    u, y : array_like
        SISO experiment data (step 1).
    horizon : int
        i, for both (7.5) and the design.
    W1, W2 : weights
        Performance weights, as for :func:`synthesis.hinf_design` (step 2).
    sigma : float
        Admissible rms noise level of (7.5) (step 2).
    gamma_ratio : float
        ``γ = gamma_ratio · γ_min_a`` (step 4).
    margin : float
        Relative margin of the small-gain rule: the design covers ``(1 + margin) δ``.
    w3_rule : {"small-gain", "thesis"}
        ``"small-gain"`` (default): ``W3 = c I`` with ``c = (1 + margin) δ γ(c)`` (see the module
        docstring).  ``"thesis"``: the literal §7.4 ``W3 = (1/δ) I``, for comparison only
        (warns when it does not cover δ).
    predictor : synthesis.Predictor, optional
        A fixed predictor of horizon i (e.g. least squares on a longer record): δ is then
        computed for *this* model (L fixed in (7.5)) and the design uses it.  Default: the
        ``(L_w, L_u)`` found by (7.5) jointly with δ.  Either way δ bounds the uncertainty
        of the model the design uses.
    causal : bool
        Causal law (Thm 3.2 variant).
    unfalsification : SubspaceResult, optional
        Reuse a (7.5) solution instead of solving again (it must come from the same data).
    form, solver, solver_options
        Passed to :func:`subspace_unfalsify`.

    Returns
    -------
    RobustDesignResult

    Raises
    ------
    UnfalsificationError
        If (7.5) did not produce a finite δ.
    DataError, synthesis.WeightError
        Bad data / weights / predictor.

    Warns
    -----
    SolverWarning
        The (7.5) answer is not certified (:meth:`Certificate.ok` false): δ is then raised to the
        certified value.
    UserWarning
        ``w3_rule="thesis"`` does not cover δ.
    """
    if w3_rule not in ("small-gain", "thesis"):
        raise ValueError(f"unknown w3_rule {w3_rule!r}; use 'small-gain' or 'thesis'")
    if not (np.isfinite(gamma_ratio) and gamma_ratio > 1.0):
        raise DataError(f"gamma_ratio must be > 1 (γ > γ_min_a), got {gamma_ratio!r}")
    unf = unfalsification
    if unf is None:
        unf = subspace_unfalsify(u, y, horizon, sigma, form=form, predictor=predictor, solver=solver,
                                 solver_options=solver_options)
    elif unf.horizon != horizon:
        raise DataError(f"the given unfalsification has horizon {unf.horizon}, not {horizon}")
    delta = float(unf.delta)
    if not np.isfinite(delta):
        raise UnfalsificationError(f"(7.5) returned no δ (status {unf.status!r}); cannot size the uncertainty")
    delta = max(delta, 0.0)
    cert = unf.certificate
    if not cert.ok():
        # the solver's δ is not certified by its own variables (e.g. 'optimal_inaccurate'): size the
        # uncertainty by the δ that the returned impulses do certify, never by a smaller one
        warnings.warn(
            f"(7.5) answer not certified (status {unf.status!r}, δ = {delta:.6g}, certified δ = "
            f"{cert.delta_certified:.6g}, noise rms {cert.noise_rms:.6g} vs σ = {cert.sigma:.6g}); the design uses "
            "max(δ, certified δ): solve (7.5) with form='conditioned' or smaller data for a certified δ",
            SolverWarning,
            stacklevel=2,
        )
        if not np.isfinite(cert.delta_certified):
            raise UnfalsificationError("(7.5) returned impulses that certify no finite δ; cannot size the uncertainty")
        delta = max(delta, float(cert.delta_certified))
    pred = unf.predictor
    if predictor is not None:
        pred = predictor
        if not np.allclose(np.hstack([unf.Lw, unf.Lu]), np.hstack([predictor.Lw, predictor.Lu])):
            raise DataError("the given unfalsification was not computed for the given predictor")
    if int(pred.horizon) != int(horizon):
        raise DataError(f"predictor has horizon {pred.horizon}, expected {horizon}")
    l = int(pred.l)
    if w3_rule == "small-gain":
        c = additive_weight_fixed_point(pred, W1, W2, delta, gamma_ratio=gamma_ratio, margin=margin, causal=causal)
    else:
        if delta == 0:
            raise DataError("w3_rule='thesis' needs δ > 0 (W3 = 1/δ)")
        c = 1.0 / delta
    # δ = 0: no uncertainty at all, the nominal design.  (W3 = 0 alone would not do: W4 = I keeps
    # the channel s → z_w1 of Fig. 3.5, so γ_min_a(c → 0) stays above the nominal γ_min.)
    unc = Additive(c * np.eye(int(pred.m)), np.eye(l)) if c > 0 else None
    design = synthesis.hinf_design(pred, W1, W2, gamma_ratio=gamma_ratio, causal=causal, uncertainty=unc)
    g_nom = synthesis.gamma_min(pred, W1, W2, causal=causal)
    covered = c / design.gamma if design.gamma > 0 else np.inf
    if covered < delta:
        warnings.warn(
            f"the design covers additive perturbations up to c/γ = {covered:.3g} < δ = {delta:.3g} "
            f"(w3_rule={w3_rule!r}); the small-gain rule W3 = cI with c ≥ γδ is needed",
            UserWarning,
            stacklevel=2,
        )
    return RobustDesignResult(
        unfalsification=unf,
        design=design,
        delta=delta,
        w3_gain=float(c),
        w3_rule=w3_rule,
        margin=float(margin),
        gamma=float(design.gamma),
        gamma_min_a=float(design.gamma_min),
        gamma_min_nominal=float(g_nom),
        covered_delta=float(covered),
    )


@dataclass(frozen=True)
class AdditiveRobustness:
    """Additive-uncertainty robustness of a loop ``u = C_r r + C_y y``, ``y = P u``.

    Attributes
    ----------
    spectral_radius : float
        Of the nominal closed loop (stable when < 1).
    peak : float
        *Proven upper bound* of ``‖M‖∞``, ``M = (I − C_y P)⁻¹ C_y`` (= ``−K(I + PK)⁻¹`` with
        ``K = −C_y``): the transfer an additive output perturbation sees (``bracket.upper``;
        ∞ when the nominal loop is not stable).
    bracket : NormBracket
        ``lower ≤ ‖M‖∞ ≤ upper`` from :func:`synthesis.hinf_norm` (``lower`` attained at
        ``bracket.frequency``).
    """

    spectral_radius: float
    peak: float
    bracket: NormBracket | None = None

    @property
    def stable(self) -> bool:
        """Nominal closed loop stable (``spectral_radius < 1``)."""
        return bool(self.spectral_radius < 1.0)

    @property
    def max_additive(self) -> float:
        """Small-gain radius ``1/peak`` (proven side): every stable ``P_Δ`` with ``‖P_Δ‖∞ < 1/peak`` keeps the loop stable."""
        return float(1.0 / self.peak) if self.peak > 0 else float("inf")

    def certifies(self, delta: float) -> bool:
        """``stable and δ·peak < 1`` with the proven upper bound (small-gain certificate for ``‖P_Δ‖∞ ≤ δ``)."""
        return bool(self.stable and delta * self.peak < 1.0)


def additive_channel(plant, controller) -> control.StateSpace:
    """``M = (I − C_y P)⁻¹ C_y``: the transfer an additive plant perturbation sees (Fig. 3.5).

    With ``u = C_r r + C_y y`` and ``y = (P + P_Δ) u``, the perturbation's output ``d = P_Δ u``
    returns as ``u = M d`` (``M = −K(I + PK)⁻¹`` for ``K = −C_y``); the loop is stable for
    every stable ``P_Δ`` with ``‖P_Δ‖∞ ‖M‖∞ < 1`` (small gain) if it is nominally stable.

    Parameters
    ----------
    plant : control.StateSpace or TransferFunction
        Discrete plant P (``m`` inputs, ``l`` outputs).
    controller : control.StateSpace
        Discrete controller, inputs ``[r; y]`` (``2l``), outputs ``u`` (``m``), same sample time.

    Raises
    ------
    DataError
        The controller does not have inputs ``[r; y]`` and the plant's inputs as outputs.
    """
    P = control.ss(plant)
    C = control.ss(controller)
    l = P.noutputs
    if C.ninputs != 2 * l or C.noutputs != P.ninputs:
        raise DataError(
            f"controller must have inputs [r; y] ({2 * l}) and {P.ninputs} output(s), got {C.ninputs} input(s) and "
            f"{C.noutputs} output(s); pass the controller of synthesis.hinf_design (inputs [r; y])"
        )
    return control.feedback(C[:, l:], P, sign=+1)  # u = Cy (P u + d)  =>  u = (I − Cy P)⁻¹ Cy d


def additive_robustness(plant, controller, *, tol: float = 1e-8, n_grid: int = 64) -> AdditiveRobustness:
    """Nominal stability and a certified ``‖M‖∞``, ``M = (I − C_y P)⁻¹ C_y``, for a controller with inputs ``[r; y]``.

    Parameters
    ----------
    plant, controller
        As for :func:`additive_channel`.
    tol : float
        Relative gap of the norm bracket (:func:`synthesis.hinf_norm`).
    n_grid : int
        Starting grid of :func:`synthesis.hinf_norm` (pole angles added); the proof does not
        depend on it.

    Returns
    -------
    AdditiveRobustness
        ``peak`` is the proven upper bound of ``‖M‖∞`` (∞ when the nominal loop is not stable),
        ``bracket`` both sides.
    """
    M = additive_channel(plant, controller)
    br = hinf_norm(M, tol=tol, n_grid=n_grid)
    return AdditiveRobustness(spectral_radius=float(br.spectral_radius), peak=float(br.upper), bracket=br)
