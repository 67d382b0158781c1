"""Certificate of the loop that ships: stability, small gain and a performance floor on P̂.

The §7.4 pipeline returns an LTI controller ``K`` (inputs ``[r; y]``, output ``u``: (5.3)–(5.4)).
Theorem 3.7 bounds a *finite-horizon* game in which Δ acts from rest on the future inputs; in
the receding-horizon loop Δ also corrupts the past data ``w_p`` the controller trusts, so that
bound does not carry over to ``K`` by itself.  This module checks the implemented loop
directly, on the data-based model ``P̂`` (:func:`unfalsify.predictor_model`):

1. **Nominal stability**: the loop ``(P̂, K)`` is Schur stable.
2. **Small gain**: with ``M̂ = (I − C_y P̂)⁻¹ C_y`` (= ``−K(I + P̂K)⁻¹`` for ``K = −C_y``, the map
   an additive plant perturbation sees, :func:`unfalsify.additive_channel`),

       δ · ‖M̂‖∞ ≤ 1/(1 + margin),

   decided with the *proven* upper bound of :func:`synthesis.hinfnorm.hinf_norm` (the
   Hamiltonian-pencil test) **and**, independently, by a bounded-real matrix ``P ≻ 0`` with
   ``M(P) ≺ 0`` at the level ``1/((1 + margin)·δ)`` (:func:`synthesis.bounded_real_certificate`,
   stored on the result so that anyone can re-check it).  Then the loop is stable for every plant
   ``P̂ + Δ`` with ``Δ`` stable and ``‖Δ‖∞ ≤ (1 + margin)·δ``.
3. **Performance floor**: a controller that does almost nothing is trivially robust on a
   stable plant.  A unit step on every reference channel of ``(P̂, K)``, simulated noise free
   for ``step_samples`` samples, must track: the mean absolute error over the last quarter of
   the run is at most ``tracking_floor`` (default 0.1, i.e. 10 % of the step).

Which plants this covers, and the assumption that links it to δ: the certificate is a theorem
about the set ``{P̂ + Δ : Δ stable, ‖Δ‖∞ ≤ (1 + margin) δ}``.  The true plant belongs to it
only under the assumption of Chapter 7 that the smallest unfalsified additive uncertainty
(δ of (7.5), which bounds the first ``i`` Markov parameters of every column operator
``‖T(h_k)‖₂ ≤ δ`` — by Carathéodory–Fejér the least H∞ norm of a causal LTI system with those
Markov parameters) also bounds the plant's deviation from ``P̂`` at all frequencies, with the
model's own error absorbed by ``margin``.  Data cannot prove that assumption; they can only
fail to falsify it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import control
import numpy as np

from synthesis.validation import (DataError, as_discrete_system, InputTypeError, check_count, check_nonnegative,
                                  check_same_dt)
from synthesis import BoundedRealCertificate, NormBracket, bounded_real_certificate, hinf_norm
from synthesis.results import result

from ._common import spectral_radius

__all__ = ["LoopCertificate", "StepMetrics", "additive_channel", "certify_loop", "closed_loop_ry", "coprime_channel",
           "loop_parts", "step_metrics", "tracking_floors", "AdditiveRobustness", "additive_robustness"]

#: Default performance floor: mean |r − y| over the last quarter of a unit step.
TRACKING_FLOOR = 0.1
#: Default length of the step used for the performance floor (samples).
STEP_SAMPLES = 300
# a matrix counts as singular when its least singular value is below this fraction of the size of its terms
# (:func:`_near_singular`)
_SINGULAR_REL = 1e-12


#: the largest level :func:`synthesis.bounded_real_certificate` takes (2**200)
_KYP_LEVEL_MAX = 2.0 ** 200

@result
@dataclass(frozen=True)
class StepMetrics:
    """Unit-step metrics of a loop ``r → y``: each reference channel stepped alone; the worst channel.

    A step on reference ``c`` must bring output ``c`` to 1 and leave the other outputs at 0 (a loop
    whose steady state mixes the channels does not track, even if a step on all references at once
    would look right).  For one channel this is the plain unit step.

    Attributes
    ----------
    final_error : float
        The largest entry of ``channel_errors`` (``inf`` when the loop is unstable).
    overshoot : float
        ``max(y_c) − 1`` of the stepped channel, as a fraction of the step (0 when there is none).
    rise_samples : int
        First sample with ``y_c ≥ 0.9`` on the slowest stepped channel (−1 when one never gets there).
    samples : int
        Length of the run.
    channel_errors : ndarray or None
        ``(l, l)``: entry ``[r, c]`` is the mean ``|δ_rc − y_r|`` over the last quarter of the run after a
        unit step on reference ``c`` (None when the loop is unstable).
    """

    final_error: float
    overshoot: float
    rise_samples: int
    samples: int
    channel_errors: np.ndarray | None = None

    def output_errors(self, tracked=None) -> np.ndarray:
        """Per output channel, the worst steady error over the steps (``inf`` when unstable).

        ``tracked``: boolean mask of the reference channels whose steps count (default all); a reference
        nobody tracks (floor ``inf``, :func:`tracking_floors`) says nothing about the others.
        """
        if self.channel_errors is None:
            return np.array([float(self.final_error)])
        E = np.asarray(self.channel_errors)
        if tracked is not None:
            E = E[:, np.asarray(tracked, bool)]
        return np.max(E, axis=1) if E.shape[1] else np.zeros(E.shape[0])


@result
@dataclass(frozen=True)
class LoopCertificate:
    """Verdict of :func:`certify_loop` on the loop ``(P̂, K)``.

    Attributes
    ----------
    certified : bool
        Nominal loop stable, small gain proven and the performance floor met.
    reason : str
        ``''`` when certified; otherwise the first failed condition in words.
    delta, margin : float
        The uncertainty size and the relative margin of the small-gain test.
    spectral_radius : float
        Of the nominal closed loop ``(P̂, K)``.
    norm : NormBracket or None
        ``lower ≤ ‖M̂‖∞ ≤ upper`` (None when the nominal loop is unstable).
    small_gain : float
        ``δ · upper`` (``inf`` when the nominal loop is unstable); certified needs
        ``small_gain ≤ 1/(1 + margin)``.
    step : StepMetrics or None
        Unit step on ``(P̂, K)`` (None when the nominal loop is unstable).
    tracking_floor : float or tuple of float
        One floor for every output channel, or one per channel (:func:`tracking_floors`).
    bounded_real : BoundedRealCertificate or None
        The second proof of the small gain: ``‖M̂‖∞ < 1/((1 + margin)·δ)`` by a matrix ``P``
        (:meth:`BoundedRealCertificate.verify` re-checks it).  Computed when the pencil test
        passes and ``δ > 0``; certified needs it proven too.
    uncertainty : {"additive", "coprime"}
        The family certified: ``P̂ + Δ`` with ``‖Δ‖∞ ≤ (1 + margin)δ`` (``norm`` bounds
        ``‖K(I+P̂K)⁻¹‖∞``), or ``(M̂ + Δ_M)⁻¹(N̂ + Δ_N)`` with ``‖[Δ_N Δ_M]‖∞ ≤ (1 + margin)δ`` (``δ`` is
        then ε and ``norm`` bounds ``‖[K; I](M̂ + N̂K)⁻¹‖∞``, :func:`coprime_channel`).
    """

    certified: bool
    reason: str
    delta: float
    margin: float
    spectral_radius: float
    norm: NormBracket | None
    small_gain: float
    step: StepMetrics | None
    tracking_floor: float | tuple
    bounded_real: BoundedRealCertificate | None = None
    uncertainty: str = "additive"

    @property
    def stable(self) -> bool:
        """Nominal loop ``(P̂, K)`` stable."""
        return bool(self.spectral_radius < 1.0)

    @property
    def tracks(self) -> bool:
        """The performance floor is met."""
        if self.step is None:
            return False
        floors = np.atleast_1d(np.asarray(self.tracking_floor, float))
        return bool(np.all(self.step.output_errors(np.isfinite(floors) if floors.size > 1 else None) <= floors))

    @property
    def radius(self) -> float:
        """Proven small-gain radius ``1/upper``: every stable ``Δ`` with ``‖Δ‖∞`` below it keeps ``(P̂ + Δ, K)`` stable."""
        if self.norm is None or not math.isfinite(self.norm.upper):
            return 0.0
        return float(1.0 / self.norm.upper) if self.norm.upper > 0 else float("inf")


def loop_parts(plant, controller):
    """Checked ``(P, C, l)`` of a loop ``y = P u``, ``u = C [r; y]`` (discrete, one sample time, matching sizes).

    Raises
    ------
    DataError
        Continuous-time or non-finite systems, different sample times, a controller without
        inputs ``[r; y]`` (``2l``) and the plant's inputs as outputs.

    Examples
    --------
    >>> import control
    >>> P = control.ss([[1.0]], [[1.0]], [[0.1]], [[0.0]], 1.0)      # 0.1/(z − 1), an integrator
    >>> K = control.ss([], [], [], [[2.0, -2.0]], 1.0)              # u = 2(r − y), inputs [r; y]
    >>> P_, C, l = loop_parts(P, K)
    >>> l, C.ninputs, C.noutputs
    (1, 2, 1)
    >>> loop_parts(P, control.ss([], [], [], [[2.0]], 1.0))        # a controller of e alone  # doctest: +ELLIPSIS
    Traceback (most recent call last):
        ...
    synthesis.exceptions.DataError: controller must have inputs [r; y] (2) and 1 output(s), ...
    """
    P = as_discrete_system(plant, "plant")
    C = as_discrete_system(controller, "controller")
    check_same_dt(P, C, "plant", "controller")
    l = P.noutputs
    if C.ninputs != 2 * l or C.noutputs != P.ninputs:
        raise DataError(
            f"controller must have inputs [r; y] ({2 * l}) and {P.ninputs} output(s), got {C.ninputs} input(s) and "
            f"{C.noutputs} output(s); pass the controller of synthesis.hinf_design (inputs [r; y])")
    return P, C, l


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

    Examples
    --------
    >>> import numpy as np
    >>> import control
    >>> P = control.ss([[1.0]], [[1.0]], [[0.1]], [[0.0]], 1.0)      # 0.1/(z − 1), an integrator
    >>> K = control.ss([], [], [], [[2.0, -2.0]], 1.0)              # u = 2(r − y), inputs [r; y]
    >>> M = additive_channel(P, K)                                 # −2(z − 1)/(z − 0.8)
    >>> round(abs(complex(M(-1.0))), 6), round(abs(float(control.dcgain(M))), 6)
    (2.222222, 0.0)
    """
    P, C, l = loop_parts(plant, controller)
    return control.feedback(C[:, l:], P, sign=+1)  # u = Cy (P u + d)  =>  u = (I − Cy P)⁻¹ Cy d


def coprime_channel(factors, controller) -> control.StateSpace:
    """``H = [C_y; I](M̂ − N̂C_y)⁻¹``: the map ``v ↦ [u; y]`` a coprime-factor perturbation sees.

    With ``P = (M̂ + Δ_M)⁻¹(N̂ + Δ_N)`` the loop reads ``M̂y = N̂u + v``, ``v = [Δ_N  −Δ_M][u; y]``
    (:mod:`unfalsify.coprime`); it is stable for every stable ``[Δ_N Δ_M]`` with ``‖[Δ_N Δ_M]‖∞ ‖H‖∞ < 1``
    if it is nominally stable.  The realisation closes the loop around ``M̂⁻¹[N̂  I]`` in one state
    (:meth:`CoprimeFactors.equation`), so every pole of ``H`` is a pole of the nominal closed loop -- also
    for an integrating P̂, whose ``M̂⁻¹`` alone is unstable.

    Parameters
    ----------
    factors : CoprimeFactors
        ``(N̂, M̂)`` of P̂ (:func:`unfalsify.coprime_factors`).
    controller : control.StateSpace
        Inputs ``[r; y]``, outputs ``u``, the factors' sample time.

    Returns
    -------
    control.StateSpace
        Inputs ``v`` (l), outputs ``[u; y]`` (m + l).

    Raises
    ------
    InputTypeError
        ``factors`` is not a :class:`CoprimeFactors`.

    Examples
    --------
    >>> import numpy as np, control
    >>> from unfalsify import CoprimeFactors
    >>> F = CoprimeFactors(N=np.array([[[0.0]], [[0.1]]]), M=np.array([[[1.0]], [[-1.0]]]), dt=1.0)  # 0.1/(z − 1)
    >>> K = control.ss([], [], [], [[2.0, -2.0]], 1.0)              # u = 2(r − y)
    >>> H = coprime_channel(F, K)                          # [−2; 1] z/(z − 0.8), a pole at 0 from the delay line
    >>> sorted(H.poles().real.round(6).tolist()), np.round(np.abs(control.dcgain(H)).ravel(), 6).tolist()
    ([0.0, 0.8], [10.0, 5.0])
    """
    if not all(callable(getattr(factors, name, None)) for name in ("equation", "model")):
        # by what it offers: importing CoprimeFactors would close a circle (coprime → premise → excitation → here)
        raise InputTypeError("factors must be a CoprimeFactors (unfalsify.coprime_factors(pred, dt)), got "
                             f"{type(factors).__name__}")
    G = factors.equation()
    P, C, l = loop_parts(factors.model(), controller)
    m = P.ninputs
    A, B, Cp, D = (np.asarray(X, float) for X in control.ssdata(G))
    Bu, Bv, Du = B[:, :m], B[:, m:], D[:, :m]
    K = C[:, l:]
    Ac, Bc, Cc, Dc = (np.asarray(X, float) for X in control.ssdata(K))
    # y = Cp x + Du u + v, u = Cc xc + Dc y  =>  (I − Du Dc) y = Cp x + Du Cc xc + v
    E = np.linalg.inv(np.eye(l) - Du @ Dc)
    Yx, Yc, Yv = E @ Cp, E @ Du @ Cc, E
    Ux, Uc, Uv = Dc @ Yx, Cc + Dc @ Yc, Dc @ Yv
    n, nc = A.shape[0], Ac.shape[0]
    Acl = np.block([[A + Bu @ Ux, Bu @ Uc], [Bc @ Yx, Ac + Bc @ Yc]]) if nc else A + Bu @ Ux
    Bcl = np.vstack([Bv + Bu @ Uv, Bc @ Yv]) if nc else Bv + Bu @ Uv
    Ccl = np.block([[Ux, Uc], [Yx, Yc]]) if nc else np.vstack([Ux, Yx])
    Dcl = np.vstack([Uv, Yv])
    return control.ss(Acl, Bcl.reshape(n + nc, l), Ccl.reshape(m + l, n + nc), Dcl, P.dt)


def closed_loop_ry(plant, controller) -> control.StateSpace:
    """Noise-free closed loop ``r → y`` of ``y = P u``, ``u = C_r r + C_y y`` (controller inputs ``[r; y]``).

    Examples
    --------
    >>> import numpy as np
    >>> import control
    >>> P = control.ss([[1.0]], [[1.0]], [[0.1]], [[0.0]], 1.0)      # 0.1/(z − 1), an integrator
    >>> K = control.ss([], [], [], [[2.0, -2.0]], 1.0)              # u = 2(r − y), inputs [r; y]
    >>> T = closed_loop_ry(P, K)                                   # 0.2/(z − 0.8)
    >>> T.poles().real.round(6).tolist(), round(float(control.dcgain(T)), 6)
    ([0.8], 1.0)
    """
    return _closed_loop_ry(*loop_parts(plant, controller))


def _controller_parts(C, l: int) -> tuple[np.ndarray, ...]:
    """``(A_c, B_r, B_y, C_c, D_r, D_y)`` of a controller ``u = C [r; y]`` with ``l`` references and outputs."""
    Ac, Bc, Cc, Dc = (np.asarray(X, float) for X in control.ssdata(C))
    n, m = Ac.shape[0], Dc.shape[0]
    Bc, Cc = Bc.reshape(n, 2 * l), Cc.reshape(m, n)
    return Ac, Bc[:, :l], Bc[:, l:], Cc, Dc[:, :l], Dc[:, l:]


def _near_singular(M: np.ndarray, scale: float) -> bool:
    """Whether ``M`` is singular to within ``_SINGULAR_REL`` of ``scale``, the size of the terms that formed it
    (``1 + ‖X‖₂`` for ``I − X``).

    One test for the loop's realisation and the tracking check's ``T(1)``, which had used condition numbers of 1/eps
    and 1e12: a condition number cannot see a scalar ``1 − x`` that cancels to 1e-14 (its condition number is 1), and
    such a loop had been realised with a gain of 1e14."""
    return not np.linalg.svd(M, compute_uv=False)[-1] > _SINGULAR_REL * scale


def _ill_posed(X: np.ndarray) -> bool:
    """Whether the loop equation ``(I − X) z = b`` is ill-posed (:func:`_near_singular`)."""
    return _near_singular(np.eye(X.shape[0]) - X, 1.0 + np.linalg.norm(X, 2))


def _closed_loop_ry(P, C, l: int) -> control.StateSpace:
    """``r → y`` with the controller's one state, shared by its ``r`` and ``y`` inputs.

    ``feedback(P, C_y) * C_r`` had realised ``C_r`` as a second copy of that state, outside the loop: its poles (an
    open-loop unstable or integrating controller's) made the realisation of a stable loop unstable, and
    :func:`step_metrics` then refused the loop as not tracking.  With ``u = C_c x_c + D_r r + D_y y`` and
    ``y = C_p x_p + D_p u``: ``y = E (C_p x_p + D_p C_c x_c + D_p D_r r)``, ``E = (I − D_p D_y)⁻¹``.
    """
    Ap, Bp, Cp, Dp = (np.asarray(X, float) for X in control.ssdata(P))
    n_p, m = Ap.shape[0], Dp.shape[1]
    Bp, Cp = Bp.reshape(n_p, m), Cp.reshape(l, n_p)
    Ac, Br, By, Cc, Dr, Dy = _controller_parts(C, l)
    n_c = Ac.shape[0]
    DD = Dp @ Dy
    if _ill_posed(DD):
        raise DataError("the loop is ill-posed: I − D_P D_y is singular (the plant's and the controller's direct "
                        "feedthrough close an algebraic loop); the controller must not cancel the plant's D")
    E = np.linalg.inv(np.eye(l) - DD)
    Yp, Yc, Yr = E @ Cp, E @ Dp @ Cc, E @ Dp @ Dr  # y = Yp x_p + Yc x_c + Yr r
    Up, Uc, Ur = Dy @ Yp, Cc + Dy @ Yc, Dr + Dy @ Yr  # u likewise
    A = np.block([[Ap + Bp @ Up, Bp @ Uc], [By @ Yp, Ac + By @ Yc]])
    B = np.vstack([Bp @ Ur, Br + By @ Yr])
    return control.ss(A, B.reshape(n_p + n_c, l), np.hstack([Yp, Yc]).reshape(l, n_p + n_c), Yr, P.dt)


def step_metrics(loop: control.StateSpace, samples: int = STEP_SAMPLES) -> StepMetrics:
    """Unit step on every input of a discrete loop ``r → y``; the worst output channel's metrics.

    Parameters
    ----------
    loop : control.StateSpace or control.TransferFunction
        A discrete-time loop (e.g. :func:`closed_loop_ry`).
    samples : int
        Length of the step run, ≥ 1 (the last quarter is the tracking window).

    Raises
    ------
    DataError
        ``loop`` continuous-time or with NaN entries, ``samples`` not an integer ≥ 1.
    InputTypeError
        ``loop`` not a python-control system.

    Examples
    --------
    >>> import control
    >>> P = control.ss([[1.0]], [[1.0]], [[0.1]], [[0.0]], 1.0)      # 0.1/(z − 1), an integrator
    >>> K = control.ss([], [], [], [[2.0, -2.0]], 1.0)              # u = 2(r − y), inputs [r; y]
    >>> m = step_metrics(closed_loop_ry(P, K))                     # y_k = 1 − 0.8^k
    >>> m.rise_samples, m.samples, bool(m.final_error < 1e-12), m.overshoot == 0.0
    (11, 300, True, True)
    """
    loop = as_discrete_system(loop, "loop", hint="the step run counts samples")
    samples = check_count(samples, "samples", 1)
    A, B, C, D = (np.asarray(M, float) for M in control.ssdata(loop))
    if spectral_radius(A) >= 1.0:
        return StepMetrics(final_error=float("inf"), overshoot=float("inf"), rise_samples=-1, samples=int(samples))
    p, l = B.shape[1], C.shape[0]
    # all references at once, one column of the state per stepped channel: y[k] is (l, p)
    x = np.zeros((A.shape[0], p))
    y = np.empty((samples, l, p))
    for k in range(samples):
        y[k] = C @ x + D
        x = A @ x + B
    target = np.eye(l, p)
    errors = np.mean(np.abs(target - y[-max(samples // 4, 1):]), axis=0)
    own = y[:, np.arange(min(l, p)), np.arange(min(l, p))]          # y_c after the step on r_c
    over = float(max(np.max(own) - 1.0, 0.0))
    rises = [np.nonzero(own[:, c] >= 0.9)[0] for c in range(own.shape[1])]
    rise = max(int(r[0]) for r in rises) if all(r.size for r in rises) else -1
    return StepMetrics(final_error=float(np.max(errors)), overshoot=over, rise_samples=rise, samples=int(samples),
                       channel_errors=errors)


_TALL_HINT = ("; the plant has fewer inputs ({m}) than outputs ({l}), so no controller tracks independent steps on "
              "every output: give tracking_floor per output channel, inf for the outputs not tracked "
              "(CertificateOptions(tracking_floor=...), or --tracking-floor 0.1,inf of python -m experiments design)")


def _check_step_samples(step_samples) -> int:
    """The length of the step run: an integer ≥ 8 (its last quarter is the tracking window)."""
    return check_count(step_samples, "step_samples", 8)


def tracking_floors(tracking_floor, channels: int | None) -> np.ndarray:
    """The performance floor per output channel: one number for all, or one per channel.

    A plant with fewer inputs than outputs cannot track independent steps on every output: give
    ``inf`` for the outputs that are not tracked (their references are then not stepped in the
    check); at least one output must be tracked, or the floor would not exclude a controller that
    does nothing.

    Parameters
    ----------
    tracking_floor : float or sequence of float
        Mean absolute step error allowed over the last quarter of the run, ≥ 0 (``inf``: not tracked).
    channels : int or None
        The plant's outputs ``l``; None: not known yet (an option object checks its floors before any plant is
        seen), every check but the count.

    Returns
    -------
    ndarray, shape (channels,) (None: one entry per floor given)

    Raises
    ------
    DataError
        A negative or NaN floor, a sequence whose length is not ``channels``, no tracked output, or ``channels``
        not None nor an integer ≥ 1.

    Examples
    --------
    >>> tracking_floors(0.1, 2).tolist(), tracking_floors([0.1, 0.2], 2).tolist()
    ([0.1, 0.1], [0.1, 0.2])
    >>> tracking_floors([0.1, float("inf")], 2).tolist()          # output 1 not tracked
    [0.1, inf]
    >>> tracking_floors([0.1, 0.2, 0.3], None).tolist()            # count not known yet: the floors checked alone
    [0.1, 0.2, 0.3]
    """
    if channels is not None:
        channels = check_count(channels, "channels (the plant's outputs l)", 1)  # 2.0 had been accepted
    if not isinstance(tracking_floor, (list, tuple, np.ndarray)) or np.ndim(tracking_floor) == 0:
        if isinstance(tracking_floor, np.ndarray):
            tracking_floor = tracking_floor.item()
        check_nonnegative(tracking_floor, "tracking_floor")
        return np.full(1 if channels is None else channels, float(tracking_floor))
    floors = list(tracking_floor)
    if not floors:
        raise DataError("tracking_floor is empty: give one number for all output channels or one per channel")
    if channels is not None and len(floors) != channels:
        raise DataError(f"tracking_floor has {len(floors)} entries but the plant has {channels} outputs: give one "
                        "number for all channels or one per output channel")
    for k, f in enumerate(floors):
        check_nonnegative(f, f"tracking_floor[{k}]", allow_inf=True)
    floors = np.asarray(floors, float)
    if not np.any(np.isfinite(floors)):
        raise DataError("tracking_floor is inf on every output: at least one output must be tracked (a finite floor), "
                        "or the floor would not exclude a controller that does nothing")
    return floors


def certify_loop(model, controller, delta: float, *, margin: float = 0.1, tracking_floor: float = TRACKING_FLOOR,
                 step_samples: int = STEP_SAMPLES, tol: float = 1e-8, factors=None,
                 model_name: str = "P̂") -> LoopCertificate:
    """Certify the implemented loop ``(P̂, K)`` for additive uncertainty of size δ (see the module docstring),
    or, with ``factors``, for coprime-factor uncertainty of size ε = δ.

    Parameters
    ----------
    model : control.StateSpace
        The nominal model ``P̂`` (e.g. :func:`unfalsify.predictor_model`), discrete.
    controller : control.StateSpace
        The controller with inputs ``[r; y]`` (as from :func:`synthesis.hinf_design`).
    delta : float
        Additive uncertainty size (≥ 0).
    margin : float
        Relative margin: certified needs ``δ · ‖M̂‖∞ ≤ 1/(1 + margin)``.
    tracking_floor : float or sequence of float
        Performance floor (mean absolute step error over the last quarter of the run), for every output
        channel or one per channel; each reference channel is stepped alone (:func:`step_metrics`).
    step_samples : int
        Length of the step run.
    tol : float
        Relative gap of the H∞ bracket.
    factors : CoprimeFactors, optional
        ``P̂ = M̂⁻¹N̂`` (:func:`unfalsify.coprime_factors`; ``model`` must be this P̂): the small gain is then
        ``δ·‖[K; I](M̂ + N̂K)⁻¹‖∞`` (:func:`coprime_channel`), which stays finite for an integrating P̂.
    model_name : str
        What the reasons call ``model`` (``"P̂_ref"`` for the reference model).

    Returns
    -------
    LoopCertificate

    Raises
    ------
    DataError
        Bad δ / margin / floor, or a controller that does not fit the model.

    Examples
    --------
    >>> import control
    >>> P = control.ss([[1.0]], [[1.0]], [[0.1]], [[0.0]], 1.0)      # 0.1/(z − 1), an integrator
    >>> K = control.ss([], [], [], [[2.0, -2.0]], 1.0)              # u = 2(r − y), inputs [r; y]
    >>> cert = certify_loop(P, K, 0.2)                            # ‖M̂‖∞ = 20/9: 0.2 · 20/9 < 1/1.1
    >>> cert.certified, cert.reason, round(cert.small_gain, 4)
    (True, '', 0.4444)
    >>> cert = certify_loop(P, K, 1.0)
    >>> cert.certified, cert.reason.startswith("small gain")
    (False, True)
    """
    for name, v in (("delta", delta), ("margin", margin)):
        check_nonnegative(v, name)
    _check_step_samples(step_samples)
    P, C, l = loop_parts(model, controller)
    floors = tracking_floors(tracking_floor, l)
    tracking_floor = float(floors[0]) if np.ndim(tracking_floor) == 0 else tuple(float(f) for f in floors)
    if factors is None:
        M, kind, name = control.feedback(C[:, l:], P, sign=+1), "additive", f"‖K(I+{model_name}K)⁻¹‖∞"
    else:
        _check_factors(P, factors)
        M, kind, name = coprime_channel(factors, C), "coprime", "‖[K; I](M̂+N̂K)⁻¹‖∞"
    rho = spectral_radius(np.asarray(M.A, float))
    common = dict(delta=float(delta), margin=float(margin), spectral_radius=rho, tracking_floor=tracking_floor,
                  uncertainty=kind)
    if not rho < 1.0:
        return LoopCertificate(certified=False,
                               reason=f"nominal loop unstable on the model {model_name} (spectral radius {rho:.6g})",
                               norm=None, small_gain=float("inf"), step=None, **common)
    bracket = hinf_norm(M, tol=tol)
    kyp = None
    small_gain = float(delta) * bracket.upper if delta > 0 else 0.0
    step = step_metrics(_closed_loop_ry(P, C, l), int(step_samples))
    reason = ""
    if not math.isfinite(bracket.upper):
        reason = f"{name} not proven finite ({bracket.reason})"
    elif small_gain > 1.0 / (1.0 + margin):
        size = "δ" if factors is None else "ε"
        reason = (f"small gain: {size}·{name} = {delta:.4g} × {bracket.upper:.4g} = {small_gain:.4g} > "
                  f"1/(1 + margin) = {1.0 / (1.0 + margin):.4g}")
    elif not np.all((errs := step.output_errors(np.isfinite(floors))) <= floors):
        worst = int(np.argmax(errs - floors))
        channel = f" on output {worst}" if l > 1 else ""
        reason = (f"performance floor: the step on {model_name} leaves a mean error {errs[worst]:.3g} > "
                  f"{floors[worst]:.3g}{channel} over its last quarter (the controller does not track)"
                  + (_TALL_HINT.format(m=P.ninputs, l=l) if P.ninputs < l and np.all(np.isfinite(floors)) else ""))
    elif delta > 0:  # the second, independent proof of the small gain (only for a loop that passed the rest)
        # a level beyond what a bounded-real matrix can hold (δ below about 1e-60) is implied by the largest one it can
        kyp = bounded_real_certificate(M, min(1.0 / ((1.0 + margin) * float(delta)), _KYP_LEVEL_MAX),
                                       lower=bracket.lower)
        if not kyp:
            reason = (f"small gain: proven by the pencil test ({small_gain:.4g} ≤ {1.0 / (1.0 + margin):.4g}) but "
                      f"not by a bounded-real matrix P ({kyp.reason})")
    return LoopCertificate(certified=not reason, reason=reason, norm=bracket, small_gain=small_gain, step=step,
                           bounded_real=kyp, **common)


def _check_factors(P, factors) -> None:
    """``P`` must be ``M̂⁻¹N̂`` of ``factors`` (compared at three frequencies)."""
    try:
        same_shape = (factors.inputs, factors.outputs) == (P.ninputs, P.noutputs)
        w = np.array([0.3, 1.1, 2.7]) / float(P.dt)
        Nw, Mw = factors.response(w)
        ours = np.moveaxis(np.asarray(P.horner(np.exp(1j * w * P.dt)), complex).reshape(P.noutputs, P.ninputs, 3),
                           -1, 0)
        same = same_shape and np.allclose(Mw @ ours, Nw, rtol=1e-6, atol=1e-9 * (1.0 + np.max(np.abs(Nw))))
    except (AttributeError, ValueError, np.linalg.LinAlgError) as exc:
        raise DataError(f"factors must be the CoprimeFactors of the model ({exc})") from None
    if not same:
        raise DataError("the factors are not those of the model (M̂ P̂ ≠ N̂): pass model=factors.model(), or the "
                        "factors of unfalsify.coprime_factors(pred, dt) for the predictor of the model")


@result
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

    Examples
    --------
    >>> import control
    >>> P = control.ss([[1.0]], [[1.0]], [[0.1]], [[0.0]], 1.0)      # 0.1/(z − 1), an integrator
    >>> K = control.ss([], [], [], [[2.0, -2.0]], 1.0)              # u = 2(r − y), inputs [r; y]
    >>> rob = additive_robustness(P, K)                            # M = −2(z − 1)/(z − 0.8), peak 20/9 at z = −1
    >>> rob.stable, round(rob.peak, 4), round(rob.spectral_radius, 6)
    (True, 2.2222, 0.8)
    >>> bool(rob.bracket.lower <= 20 / 9 <= rob.peak)
    True
    """
    M = additive_channel(plant, controller)
    br = hinf_norm(M, tol=tol, n_grid=n_grid)
    return AdditiveRobustness(spectral_radius=float(br.spectral_radius), peak=float(br.upper), bracket=br)
