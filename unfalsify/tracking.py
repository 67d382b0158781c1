"""Step tracking across the certified uncertainty: the steady state of the loop for the static plants of the
ball it is certified for, and at the low-frequency gain the data show.

The performance floor of :func:`unfalsify.certify_loop` is a step on P̂ alone; a certificate speaks of every plant
in its ball.  At steady state a loop stable across the ball keeps its error a Möbius function of the static gain,
so the worst static plant of a one-channel ball is at either end of it; with several channels the check tries the
rank-one direction the loop is most sensitive to and the identity's columns (a test at those offsets, not a proof
over the matrix ball).  The coprime-factor family is checked at static factors on the sphere of its radius.  What
is *not* claimed: the transient across the ball (a delay inside the ball can move the nominal transient into the
last quarter of the step), which the step on P̂ and on the reference model decides.
"""
from __future__ import annotations

import control
import numpy as np

from ._common import spectral_radius
from .certify import _controller_parts, _ill_posed, _near_singular, additive_channel, closed_loop_ry, tracking_floors


def _steady_state_reason(model, controller, radius: float, floor: float, data_gain=None) -> str:
    """Why the loop's steady-state tracking error exceeds ``floor`` across the certified ball (``''`` if it does not).

    The performance floor of :func:`certify_loop` is a step on P̂ alone; the certificate speaks of every
    plant within ``radius`` of P̂.  At steady state the worst such plant is a static offset at either end
    (the error ``|1 − T(1)|`` is a Möbius function of the DC gain, and the loop is stable across the
    ball, so no pole lies between).  The loop must also track at ``data_gain``, the low-frequency gain the
    data show (the plant's response at the record's lowest DFT frequency,
    :attr:`unfalsify.PremiseTest.plant_low_band`): measured, a model with DC gain
    −1694 where the record shows 1.3–1.7 passed every other test with a controller too weak to track the
    real plant.

    Several channels: the error of a static loop is ``max |I − T(1)|`` entrywise (each reference channel
    stepped alone must reach its own output and leave the others), and the ball's static offsets tried are
    ``±radius`` times the rank-one direction the loop is most sensitive to (the top singular pair of
    ``M̂(1)``) and times the identity's first ``min(l, m)`` columns -- a test at those offsets, not a proof
    over the whole matrix ball (for one channel the two ends are the whole ball).
    """
    if not radius > 0:
        return ""
    l = model.noutputs
    floors = tracking_floors(floor, l)
    tried = []
    for E in _static_offsets(model, controller, radius):
        try:
            loop = closed_loop_ry(model + control.ss([], [], [], E, model.dt), controller)
            if spectral_radius(np.asarray(loop.A, float)) >= 1.0:
                return (f"the loop is unstable with the static perturbation {_offset_text(E)} of P̂, inside the "
                        f"ball of radius {radius:.4g} the certificate claims")
            e = _tracked_errors(np.abs(np.eye(l) - np.atleast_2d(control.dcgain(loop))), floors)
        except (np.linalg.LinAlgError, ValueError):
            e = np.full(l, np.inf)
        tried.append((E, e))
    worst, where, errs = _worst_excess(tried, floors)
    if worst > 0:
        return _across_reason(errs, floors, f"the plant P̂ {_offset_text(where)} (a static offset inside the "
                              f"ball of radius {radius:.4g} the certificate claims)", "δ")
    return _data_gain_reason(model, controller, floors, data_gain)


def _across_reason(errs: np.ndarray, floors: np.ndarray, plant: str, size: str) -> str:
    """Why the loop fails its floor at ``plant``, a static plant of the certified ball (``size``: δ or ε)."""
    k = int(np.argmax(errs - floors))
    return (f"steady-state tracking error {errs[k]:.3g} > {floors[k]:g}{_output_text(k, floors.size)} for {plant}: "
            "the loop tracks on P̂ but not across the uncertainty it claims; use a weight W1 with more gain at low "
            f"frequency (integral action) or reduce {size} (a longer or richer record)")


def _data_gain_reason(model, controller, floors: np.ndarray, data_gain) -> str:
    """Why the loop does not track at ``data_gain``, the low-frequency gain the data show (``''`` when it does)."""
    l = model.noutputs
    if data_gain is None or not np.all(np.isfinite(data_gain)):
        return ""
    G = np.asarray(data_gain, complex).reshape(l, model.ninputs)
    e = _dc_errors_at_gain(controller, G, floors)
    if np.all(e <= floors):
        return ""
    k = int(np.argmax(e - floors))
    dc = np.atleast_2d(control.dcgain(model)).real
    return (f"steady-state tracking error {e[k]:.3g} > {floors[k]:g}{_output_text(k, l)} at the low-frequency gain the "
            f"data show ({_gain_text(np.abs(G))}, the plant's response at the record's lowest DFT frequency) while "
            f"P̂'s DC gain is {_gain_text(dc)}: P̂ is wrong where tracking is decided; "
            "refit it (a longer horizon, a longer or richer record)")


def _worst_excess(tried, floors: np.ndarray):
    """``(excess, where, errors)`` of the ``(where, errors)`` pair whose errors exceed their floors most."""
    worst, where, errs = -np.inf, None, None
    for w, e in tried:
        excess = np.nan_to_num(e - floors, nan=np.inf)
        if not np.max(excess) <= worst:
            worst, where, errs = float(np.max(excess)), w, e
    return worst, where, errs


def _tracked_errors(E: np.ndarray, floors: np.ndarray) -> np.ndarray:
    """Per output, the largest steady error over the references that are tracked (finite floor)."""
    return np.max(E[:, np.isfinite(floors)], axis=1)


def _output_text(k: int, l: int) -> str:
    return f" on output {k}" if l > 1 else ""


def _static_offsets(model, controller, radius: float) -> list:
    """The static perturbations of norm ``radius`` the steady-state check tries (see :func:`_steady_state_reason`)."""
    l, m = model.noutputs, model.ninputs
    if l == m == 1:
        return [np.array([[-radius]]), np.array([[radius]])]
    directions = [np.eye(l, m)]
    try:
        Md = np.atleast_2d(control.dcgain(additive_channel(model, controller)))  # m × l
        if np.all(np.isfinite(Md)):
            U, _, Vh = np.linalg.svd(Md)
            directions.append(np.outer(Vh[0].conj(), U[:, 0].conj()).real)  # E = v₁u₁ᵀ: E·M̂(1) has gain σ₁
    except (np.linalg.LinAlgError, ValueError):
        pass
    return [sign * radius * D / max(np.linalg.norm(D, 2), 1e-300) for D in directions for sign in (-1.0, 1.0)]


def _offset_text(E) -> str:
    E = np.atleast_2d(E)
    return f"{float(E[0, 0]):+.4g}" if E.size == 1 else f"+ {np.array2string(E, precision=3)}"


def _gain_text(G) -> str:
    G = np.atleast_2d(G)
    return f"{float(G[0, 0]):.4g}" if G.size == 1 else np.array2string(G, precision=3)


def _dc_errors_at_gain(controller, p, floors: np.ndarray) -> np.ndarray:
    """Per output, ``max_c |I − T(1)|`` of ``u = C_r r + C_y y`` around a static plant of gain ``p`` (l × m),
    over the tracked references ``c`` (finite ``floors``); ``inf`` where the loop has a pole at 1.

    ``T(1)`` comes from the loop with the controller's one state (:func:`_static_loop_dc`).  It had been taken from
    the controller's DC gain, with ``T(1) = I`` whenever that was infinite ("integral action"): python-control
    reports every entry infinite for a pole at 1, so a controller integrating ``y`` alone (``T(1) = 0``, a steady
    error of 1) or ``r`` alone (no steady state) was read as tracking perfectly."""
    G = np.atleast_2d(np.asarray(p, complex))
    l = G.shape[0]
    T = _static_loop_dc(controller, G)
    if T is None:
        return np.full(l, np.inf)
    return _tracked_errors(np.abs(np.eye(l) - T), floors)


def _static_loop_dc(controller, G: np.ndarray) -> np.ndarray | None:
    """``T(1)`` of ``y = G u``, ``u = C [r; y]`` (G static, l × m, complex allowed), None where the loop is ill-posed or
    has a pole at 1.  With ``E = (I − G D_y)⁻¹``: ``y = E G (C_c x + D_r r)``, ``x⁺ = A_c x + B_r r + B_y y``."""
    l = G.shape[0]
    Ac, Br, By, Cc, Dr, Dy = _controller_parts(controller, l)
    n = Ac.shape[0]
    GD = G @ Dy
    if _ill_posed(GD):
        return None
    EG = np.linalg.solve(np.eye(l) - GD, G)
    D = EG @ Dr
    if not n:
        return D
    A, B, C = Ac + By @ EG @ Cc, Br + By @ EG @ Dr, EG @ Cc
    if _ill_posed(A):
        return None
    return C @ np.linalg.solve(np.eye(n) - A, B) + D


def _coprime_data_gain(factors, low_band):
    """The plant's gain the data show at the lowest low-band frequency, ``M̂⁻¹(N̂ + R̂)`` (None without one)."""
    if low_band is None or low_band.frequency.size == 0:
        return None
    Nw, Mw = factors.response(low_band.frequency[:1])
    R = np.asarray(low_band.response[:1], complex).reshape(1, factors.outputs, factors.inputs)
    try:
        return np.linalg.solve(Mw[0], Nw[0] + R[0])
    except np.linalg.LinAlgError:
        return None


def _coprime_static_gains(factors, radius: float, angles: int = 64) -> list:
    """Static plants ``(M̂(1) + E_M)⁻¹(N̂(1) + E_N)`` with ``‖[E_N E_M]‖₂ = radius`` the tracking check tries.

    One channel: the whole circle ``(E_N, E_M) = radius (cos θ, sin θ)`` at ``angles`` points (the DC gain
    is a Möbius function of each, so the sampled extremes approach the ball's).  Several: the same circle
    along ``[I_{l×m}  I_l]``, a test at those offsets, not a proof over the matrix ball.
    """
    N1, M1 = (X[0].real for X in factors.response(np.zeros(1)))
    l, m = N1.shape
    DN = np.eye(l, m) / max(np.linalg.norm(np.eye(l, m), 2), 1e-300)
    gains = []
    for t in np.linspace(0.0, 2.0 * np.pi, angles, endpoint=False):
        Mp = M1 + radius * np.sin(t) * np.eye(l)
        if _near_singular(Mp, np.linalg.norm(M1, 2) + radius):
            continue  # the family holds a plant with a pole at 1 here: its neighbours on the circle stand for it
        gains.append(np.linalg.solve(Mp, N1 + radius * np.cos(t) * DN))
    return gains


def _coprime_tracking_reason(factors, data_gain, controller, radius: float, floor) -> str:
    """:func:`_steady_state_reason` for the coprime family around ``factors``: the loop must track at every static
    plant of the ball and at the data's gain ``data_gain`` (None: not known)."""
    l = factors.outputs
    floors = tracking_floors(floor, l)
    worst, where, errs = _worst_excess(((G, _dc_errors_at_gain(controller, G, floors))
                                        for G in _coprime_static_gains(factors, radius)), floors)
    if worst > 0:
        return _across_reason(errs, floors, f"the static plant of gain {_gain_text(where)} inside the "
                              f"coprime-factor ball of radius {radius:.4g} the certificate claims", "ε")
    if data_gain is None:
        return ""
    return _data_gain_reason(factors.model(), controller, floors, data_gain)
