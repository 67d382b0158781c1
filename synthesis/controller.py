"""Implementations of a finite-horizon law as a controller (thesis §5.1–5.2).

A design (``HinfDesign`` or ``LqgDesign``) carries the full horizon gain ``G``, with
``u_opt = G @ v`` and ``v`` the column blocks listed in ``design.columns``
(``"r_k"`` for the causal law, ``"w_p"``, ``"x_w1"``, ``"x_w2"``, ``"x_w3"``, ``"x_w4"``),
and the weight states the controller must run (``design.weight_states``).

Two implementations of steps 5–11 of §5.1, which must produce identical controls:

* :func:`lti_controller` — the LTI system (5.3)–(5.4), state
  ``ξ = [u_p; y_p; x_w1; x_w2; (x_w3)]``, inputs ``[r; y]``, output ``u``;
* :class:`RecedingHorizonController` — the literal receding-horizon loop: form ``w_p``,
  compute ``u_opt = G v``, apply its first ``m`` entries, shift the data window and
  update the weight states.

``x_w4`` (robust laws) is driven by the fictitious ``s``, which is 0 in operation, so
with zero initial state it stays 0: it is not part of the controller state and its gain
columns are multiplied by 0.
"""
from __future__ import annotations

from dataclasses import dataclass

import control
import numpy as np

from ._validation import DataError, as_real_array, as_signal
from ._repr import result

__all__ = ["WeightState", "RecedingHorizonController", "lti_controller"]

_DRIVES = ("e", "u", "y")


@result
@dataclass(frozen=True)
class WeightState:
    """A weight filter state run inside the controller.

    Attributes
    ----------
    name : str
        Gain column block it feeds (``"x_w1"``, ``"x_w2"``, ``"x_w3"``).
    A, B : ndarray
        State update ``x ← A x + B v``.
    drive : {"e", "u", "y"}
        What ``v`` is: the tracking error ``r_k − y_k``, the control ``u_k`` or the output ``y_k``.
    """

    name: str
    A: np.ndarray
    B: np.ndarray
    drive: str

    @property
    def n(self) -> int:
        return self.A.shape[0]


def _column_slices(design) -> dict[str, slice]:
    out, start = {}, 0
    for name, size in design.columns:
        out[name] = slice(start, start + size)
        start += size
    if start != design.gain.shape[1]:
        raise DataError(f"design.columns add up to {start} but the gain has {design.gain.shape[1]} columns")
    return out


def _check_design(design, *, extra: tuple = ()) -> None:
    """Refuse anything that is not a design (HinfDesign / LqgDesign or an object with their fields)."""
    for attr in ("gain", "columns", "weight_states", "horizon", "m", "l", "causal") + extra:
        if not hasattr(design, attr):
            raise DataError(f"design has no attribute {attr!r}; pass an HinfDesign or LqgDesign")
    _column_slices(design)


def _first_step_gains(design):
    """First ``m`` rows of ``G`` split into ``(k_r, K)``: ``u_k = k_r r_k + K ξ`` (5.4)."""
    m, l, i = design.m, design.l, design.horizon
    G1 = np.asarray(design.gain, float)[:m]
    cols = _column_slices(design)
    k_r = G1[:, cols["r_k"]] if "r_k" in cols else np.zeros((m, l))
    blocks = [G1[:, cols["w_p"]]]
    for ws in design.weight_states:
        blocks.append(G1[:, cols[ws.name]])
    K = np.hstack(blocks)
    assert K.shape[1] == i * (m + l) + sum(ws.n for ws in design.weight_states)
    return k_r, K


def _state_names(design) -> list[str]:
    i, m, l = design.horizon, design.m, design.l
    names = [f"u_p[{t}][{c}]" for t in range(i) for c in range(m)]
    names += [f"y_p[{t}][{c}]" for t in range(i) for c in range(l)]
    for ws in design.weight_states:
        names += [f"{ws.name}[{c}]" for c in range(ws.n)]
    return names


def lti_controller(design) -> control.StateSpace:
    """The LTI controller (5.3)–(5.4) that performs steps 5–11 of §5.1.

    State ``ξ = [u_p; y_p; x_w1; x_w2; (x_w3)]`` with ``u_p = [u_{k-i}; …; u_{k-1}]`` and
    ``y_p`` likewise; inputs ``[r_k; y_k]``; output ``u_k = k_r r_k + K ξ`` where
    ``K = [k1 k2 k3 k4 (k5)]`` are the first ``m`` rows of the gain (``k_r = 0`` unless the
    law is causal, Thm 3.2).  Order ``i(m+l) + Σ n_w``; sample time that of the weights.

    Built as ``ξ⁺ = A₀ ξ + E_u u + E_r r + E_y y`` with ``u`` substituted:
    ``A = A₀ + E_u K``, ``B = [E_r + E_u k_r, E_y]``, ``C = K``, ``D = [k_r, 0]``.

    Examples
    --------
    A design at ``i = 4`` with a first-order W1: order ``i(m+l) + 1 = 9``.

    >>> import control, numpy as np
    >>> from synthesis import fit_predictor, hinf_design, makeweight, RecedingHorizonController
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(200)
    >>> y = np.convolve(u, [0.0, 0.5, 0.2])[:200] + 0.01 * rng.standard_normal(200)
    >>> W1 = makeweight(10.0, (0.5, 1.0), 0.5, 0.1)
    >>> design = hinf_design(fit_predictor(u, y, 4), W1, 0.1, dt=0.1)
    >>> K = lti_controller(design)
    >>> K.nstates, K.dt, K.input_labels, K.output_labels
    (9, 0.1, ['r[0]', 'y[0]'], ['u[0]'])

    It produces the controls of the receding-horizon loop of §5.1:

    >>> r, y_meas = np.ones(20), 0.1 * rng.standard_normal(20)
    >>> loop = RecedingHorizonController(design)
    >>> u_loop = []
    >>> for k in range(20):
    ...     u_k = loop.control()
    ...     loop.observe(u_k, y_meas[k], r[k])
    ...     u_loop.append(u_k[0])
    >>> np.allclose(control.forced_response(K, U=np.vstack([r, y_meas])).outputs, u_loop)
    True
    """
    _check_design(design, extra=("dt",))
    i, m, l = design.horizon, design.m, design.l
    k_r, K = _first_step_gains(design)
    nu, ny = i * m, i * l
    n = nu + ny + sum(ws.n for ws in design.weight_states)
    A0 = np.zeros((n, n))
    Eu, Er, Ey = np.zeros((n, m)), np.zeros((n, l)), np.zeros((n, l))
    # shift registers S_m, S_l (5.3)
    A0[: nu - m, m:nu] = np.eye(nu - m)
    Eu[nu - m: nu] = np.eye(m)
    A0[nu: nu + ny - l, nu + l: nu + ny] = np.eye(ny - l)
    Ey[nu + ny - l: nu + ny] = np.eye(l)
    start = nu + ny
    for ws in design.weight_states:
        sl = slice(start, start + ws.n)
        A0[sl, sl] = ws.A
        if ws.drive == "e":
            Er[sl] += ws.B
            Ey[sl] -= ws.B
        elif ws.drive == "u":
            Eu[sl] += ws.B
        elif ws.drive == "y":
            Ey[sl] += ws.B
        else:  # pragma: no cover - guarded by construction
            raise DataError(f"unknown drive {ws.drive!r}")
        start += ws.n
    A = A0 + Eu @ K
    B = np.hstack([Er + Eu @ k_r, Ey])
    D = np.hstack([k_r, np.zeros((m, l))])
    return control.ss(
        A, B, K, D, design.dt,
        inputs=[f"r[{c}]" for c in range(l)] + [f"y[{c}]" for c in range(l)],
        outputs=[f"u[{c}]" for c in range(m)],
        states=_state_names(design),
        name="subspace_controller",
    )


class RecedingHorizonController:
    """Step-by-step receding-horizon implementation of §5.1 (steps 5–11).

    At each step :meth:`control` forms ``v = [(r_k); w_p; x_w1; x_w2; (x_w3; x_w4 = 0)]``,
    computes the whole plan ``u_opt = G v`` (kept in :attr:`plan`) and returns its first
    ``m`` entries; :meth:`observe` then shifts the past-data window and updates the weight
    states (step 10).  The controller state is past data plus weight states, so
    :meth:`set_design` can swap in a new gain without any state transformation (adaptive
    control, §5.3).

    Parameters
    ----------
    design : HinfDesign or LqgDesign

    Examples
    --------
    A design at ``i = 4`` on a record of the plant ``y_k = 0.5 u_{k-1} + 0.2 u_{k-2}``, its past-data window
    started from the record's last samples:

    >>> import numpy as np
    >>> from synthesis import fit_predictor, hinf_design, makeweight
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(200)
    >>> y = np.convolve(u, [0.0, 0.5, 0.2])[:200] + 0.01 * rng.standard_normal(200)
    >>> W1 = makeweight(10.0, (0.5, 1.0), 0.5, 0.1)
    >>> design = hinf_design(fit_predictor(u, y, 4), W1, 0.1, dt=0.1)
    >>> K = RecedingHorizonController(design)
    >>> K.reset(u_past=u, y_past=y)
    >>> K.state.shape  # [u_p; y_p; x_w1]: 4 + 4 past samples and W1's state
    (9,)

    Each step: :meth:`control` gives ``u_k``, the plant answers, :meth:`observe` records ``u_k``, ``y_k`` and the
    reference ``r_k`` (here a unit step; W1 has a state, so ``r_k`` is needed):

    >>> u_hist, y_out = list(u[-2:]), []
    >>> for k in range(60):
    ...     u_k = K.control()
    ...     y_k = 0.5 * u_hist[-1] + 0.2 * u_hist[-2]
    ...     K.observe(u_k, y_k, r_k=1.0)
    ...     u_hist.append(u_k[0])
    ...     y_out.append(y_k)
    >>> u_k.shape, K.plan.shape  # the applied control and the whole plan over the horizon
    ((1,), (4, 1))
    >>> bool(abs(y_out[-1] - 1.0) < 0.1)  # settles near r (W1 has no integrator, so not on it)
    True

    :meth:`set_design` swaps in new gains (same ``i``, ``m``, ``l`` and weight states) and keeps the state:

    >>> calmer = hinf_design(design.predictor, W1, 0.1, gamma_ratio=2.0, dt=0.1)
    >>> before = K.state
    >>> K.set_design(calmer)
    >>> bool(np.array_equal(K.state, before)), round(K.design.gamma / K.design.gamma_min, 6)
    (True, 2.0)
    """

    def __init__(self, design):
        self._check(design)
        self._design = design
        self.plan = None
        self.reset()

    # -- set-up -----------------------------------------------------------------------
    @staticmethod
    def _check(design):
        _check_design(design)

    @property
    def design(self):
        return self._design

    def __repr__(self) -> str:
        d = self._design
        pred = d.predictor
        return (f"RecedingHorizonController(horizon={pred.horizon}, m={pred.m}, l={pred.l}, "
                f"gamma={float(d.gamma):.6g}, gamma_min={float(d.gamma_min):.6g})")

    def reset(self, u_past=None, y_past=None) -> None:
        """Initialise the past-data window (zeros unless given) and zero the weight states (§5.1 comments 5–6).

        ``u_past`` / ``y_past``: at least ``i`` past samples (time along axis 0); the last ``i`` are used.
        """
        d = self._design
        i, m, l = d.horizon, d.m, d.l
        self.u_p = np.zeros((i, m))
        self.y_p = np.zeros((i, l))
        if u_past is not None:
            u_past = as_signal(u_past, "u_past", width=m, record=False)
            if u_past.shape[0] < i:
                raise DataError(f"u_past needs at least i = {i} samples, got {u_past.shape[0]}")
            self.u_p = u_past[-i:].copy()
        if y_past is not None:
            y_past = as_signal(y_past, "y_past", width=l, record=False)
            if y_past.shape[0] < i:
                raise DataError(f"y_past needs at least i = {i} samples, got {y_past.shape[0]}")
            self.y_p = y_past[-i:].copy()
        self.x_w = {ws.name: np.zeros(ws.n) for ws in d.weight_states}
        self.plan = None

    def set_design(self, design) -> None:
        """Swap the gains; the state (past data and weight states) is kept as is."""
        self._check(design)
        old = self._design
        if (design.horizon, design.m, design.l) != (old.horizon, old.m, old.l):
            raise DataError(
                f"new design has (i, m, l) = {(design.horizon, design.m, design.l)} but the controller state "
                f"was built for {(old.horizon, old.m, old.l)}")
        new_ws = [(ws.name, ws.n, ws.drive) for ws in design.weight_states]
        old_ws = [(ws.name, ws.n, ws.drive) for ws in old.weight_states]
        if new_ws != old_ws:
            raise DataError(f"new design's weight states {new_ws} differ from the running ones {old_ws}")
        self._design = design

    # -- operation --------------------------------------------------------------------
    @property
    def state(self) -> np.ndarray:
        """``ξ = [u_p; y_p; x_w1; x_w2; (x_w3)]``, same order as :func:`lti_controller`'s state."""
        parts = [self.u_p.reshape(-1), self.y_p.reshape(-1)]
        parts += [self.x_w[ws.name] for ws in self._design.weight_states]
        return np.concatenate(parts)

    def _vector(self, r_k):
        d = self._design
        parts = []
        for name, size in d.columns:
            if name == "r_k":
                parts.append(r_k)
            elif name == "w_p":
                parts.append(np.concatenate([self.u_p.reshape(-1), self.y_p.reshape(-1)]))  # (3.13)
            elif name in self.x_w:
                parts.append(self.x_w[name])
            else:  # x_w4: driven by the fictitious s = 0
                parts.append(np.zeros(size))
        return np.concatenate(parts)

    def _ref(self, r_k, required: bool, why: str = ""):
        l = self._design.l
        if r_k is None:
            if required:
                raise DataError(why)
            return np.zeros(l)
        r = as_real_array(r_k, "r_k").reshape(-1)  # text or complex had raised numpy's ValueError/TypeError
        if r.size != l or not np.all(np.isfinite(r)):
            raise DataError(f"r_k must be {l} finite value(s), got {r_k!r}")
        return r

    def control(self, r_k=None) -> np.ndarray:
        """Steps 6–8: the control ``u_k`` (shape ``(m,)``); ``r_k`` is needed only for the causal law."""
        d = self._design
        r = self._ref(r_k, required=d.causal,
                      why="this is a causal design (Thm 3.2): pass the present reference r_k to control()")
        self.plan = (np.asarray(d.gain) @ self._vector(r)).reshape(d.horizon, d.m)
        return self.plan[0].copy()

    def observe(self, u_k, y_k, r_k=None) -> None:
        """Steps 9–10: record the applied ``u_k``, measured ``y_k`` and reference ``r_k``.

        ``r_k`` drives the W1 state through ``r_k − y_k`` (step 10), so it is required whenever
        W1 has states; it may be omitted (taken as 0) only when it cannot matter (static W1).
        """
        d = self._design
        u = as_real_array(u_k, "u_k").reshape(-1)  # text or complex had raised numpy's ValueError/TypeError
        y = as_real_array(y_k, "y_k").reshape(-1)
        if u.size != d.m or y.size != d.l or not (np.all(np.isfinite(u)) and np.all(np.isfinite(y))):
            raise DataError(f"u_k must be {d.m} and y_k {d.l} finite value(s)")
        tracks = any(ws.drive == "e" and np.size(ws.A) for ws in d.weight_states)
        r = self._ref(r_k, required=tracks,
                      why="W1 has states driven by r_k − y_k (step 10 of §5.1): pass the reference r_k to "
                          "observe() (r_k = 0 for regulation)")
        self.u_p = np.vstack([self.u_p[1:], u[None, :]])
        self.y_p = np.vstack([self.y_p[1:], y[None, :]])
        drive = {"e": r - y, "u": u, "y": y}
        for ws in d.weight_states:
            self.x_w[ws.name] = ws.A @ self.x_w[ws.name] + ws.B @ drive[ws.drive]
