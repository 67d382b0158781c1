"""Model-free subspace based finite-horizon H∞ laws (thesis Ch. 3), each written as a performance map.

Every law is the saddle point of ``min_u sup_d ‖z‖² − γ²‖d‖²`` with ``z = M_d d + M_u u + M_x x``
solved by the one engine :mod:`synthesis.minimax`.  Notation (per horizon ``i``):
``H_k`` = block Toeplitz of Markov parameters of ``W_k`` (3.10), ``Γ_k`` = extended
observability matrix (3.12), ``ŷ = L_w w_p + L_u u`` (3.20).

================  ==================  =====================================  ==========================================
law               d                   z                                      gain columns (x)
================  ==================  =====================================  ==========================================
Thm 3.1 (3.21)    r                   [H1(r − L_u u − L_w w_p) + Γ1 x_w1;     [w_p; x_w1; x_w2]
                                       H2 u + Γ2 x_w2]
Thm 3.2 (causal)  r_{k+1..k+i-1}      same, with r_k moved from d into x     [r_k; w_p; x_w1; x_w2]   (3.38)
Thm 3.4 (3.49)    [r; s]              z1 −= H1(H4 s + Γ4 x_w4);               [w_p; x_w1; x_w2; x_w3; x_w4]
                                       z3 = H3(L_u u + L_w w_p) + Γ3 x_w3
Thm 3.7           [r; s]              z1 as Thm 3.4; z3 = H3 u + Γ3 x_w3      [w_p; x_w1; x_w2; x_w3; x_w4]
================  ==================  =====================================  ==========================================

Multiplicative: ``W3`` (inputs ``l``) acts on the output, ``W4`` (outputs ``l``) feeds ``s``
into it.  Additive: ``W3`` (inputs ``m``) acts on ``u``, ``W4`` (outputs ``l``).  The
closed forms (3.6)–(3.8), (3.38)–(3.41), (3.45)–(3.46), (3.63)–(3.64) are checked against
this engine in the tests.
"""
from __future__ import annotations

import dataclasses
import numbers
import warnings
from dataclasses import dataclass

import control
import numpy as np

from ._lazy import _Deferred, _LazyField
from ._validation import DataError, check_flag, check_level, check_predictor_dt, check_sample_time
from .exceptions import HorizonWarning
from .controller import WeightState, lti_controller
from .minimax import _gains, _level, _saddle, _warn_near, minimax_gamma_min
from .weights import WeightError, _ss_parts, as_weight, common_dt, markov_toeplitz, observability
from ._repr import result

__all__ = [
    "Additive",
    "HinfDesign",
    "HorizonWarning",
    "Multiplicative",
    "PerformanceMap",
    "gamma_min",
    "hinf_design",
    "performance_map",
]


@dataclass(frozen=True)
class Multiplicative:
    """Output multiplicative uncertainty ``y = (I + W4 Δ W3)(L_w w_p + L_u u)`` (Fig. 3.4, Thm 3.4).

    ``W3``: ``l`` inputs (driven by the output); ``W4``: ``l`` outputs.  Either may be 0 (Thm 3.6).
    """

    W3: object
    W4: object


@dataclass(frozen=True)
class Additive:
    """Additive uncertainty ``y = L_w w_p + L_u u + W4 Δ W3 u`` (Fig. 3.5, Thm 3.7).

    ``W3``: ``m`` inputs (driven by the control); ``W4``: ``l`` outputs.  Either may be 0.
    """

    W3: object
    W4: object


@result
@dataclass(frozen=True, eq=False)
class PerformanceMap:
    """``z = M_d d + M_u u + M_x x`` for one law, with the block layout of ``d`` and ``x``."""

    Md: np.ndarray
    Mu: np.ndarray
    Mx: np.ndarray
    disturbances: tuple  # ((name, size), ...) for d
    columns: tuple  # ((name, size), ...) for x


@result
@dataclass(frozen=True, eq=False)
class HinfDesign:
    """A finite-horizon subspace H∞ design (Ch. 3) and its LTI controller (5.3)–(5.4).

    Attributes
    ----------
    gamma, gamma_min : float
        Level used and the exact threshold (3.8)/(3.41)/(3.46)/(3.64): of the finite-horizon game on the predictor,
        not a bound on the H∞ norm of the LTI loop (5.3)–(5.4) with a plant (measured on a third-order plant:
        γ = 0.970, the weighted loop on the true plant 0.981).  That norm is :func:`~synthesis.hinf_norm` of the
        closed loop (``control.feedback``, or ``experiments.closed_loop_system``, with the weights).
    gain : ndarray, shape (i·m, n_x)
        ``u_opt = gain @ v`` over the horizon (3.9), with ``v`` stacked as in :attr:`columns`:
        ``[w_p; x_w1; x_w2]`` (Thm 3.1), ``[r_k; w_p; x_w1; x_w2]`` (causal, (3.38)),
        ``[w_p; x_w1; x_w2; x_w3; x_w4]`` (robust), ``[r_k; w_p; …]`` for causal robust.
    disturbance_gain : ndarray, shape (n_d, n_x)
        Worst-case disturbance ``d_wc = disturbance_gain @ v``, ``d`` laid out as in :attr:`disturbances`.
    controller : control.StateSpace
        The LTI controller (5.3)–(5.4): inputs ``[r; y]``, output ``u``, state
        ``[u_p; y_p; x_w1; x_w2; (x_w3)]``, sample time :attr:`dt`.  Built on first access
        (python-control object construction costs about as much as the gains at i = 64, and
        the receding-horizon and adaptive controllers of §5.1/§5.3 need only :attr:`gain`).
    columns, disturbances : tuple of (name, size)
    weight_states : tuple of WeightState
        The weight states the controller runs (``x_w4`` is not one: it is driven by the
        fictitious ``s`` = 0 in operation).
    predictor, W1, W2, uncertainty, horizon, m, l, causal, dt
        The inputs of the design (weights as discrete ``StateSpace``).
    """

    predictor: object
    W1: control.StateSpace
    W2: control.StateSpace
    uncertainty: object
    horizon: int
    m: int
    l: int
    causal: bool
    dt: float
    gamma: float
    gamma_min: float
    gain: np.ndarray
    disturbance_gain: np.ndarray
    columns: tuple
    disturbances: tuple
    weight_states: tuple
    controller: control.StateSpace | None = _LazyField(default=None)

    @property
    def first_gain(self) -> np.ndarray:
        """First ``m`` rows of :attr:`gain` (the applied control, ``k1 … k4`` of §5.2)."""
        return self.gain[: self.m]

    def block(self, name: str) -> np.ndarray:
        """Columns of :attr:`gain` for one block of ``v`` (e.g. ``"w_p"``, ``"x_w1"``)."""
        start = 0
        for n, size in self.columns:
            if n == name:
                return self.gain[:, start:start + size]
            start += size
        raise KeyError(f"no column block {name!r}; blocks are {[c for c, _ in self.columns]}")


# ---------------------------------------------------------------------------------------------
def _predictor_parts(pred):
    try:
        Lw = np.asarray(pred.Lw, dtype=float)
        Lu = np.asarray(pred.Lu, dtype=float)
        i, m, l = int(pred.horizon), int(pred.m), int(pred.l)
    except AttributeError as exc:
        # a RecursivePredictor is the most likely thing to be passed here: it holds a Predictor, it is not one
        recursive = callable(getattr(pred, "predictor", None))
        hint = ": a RecursivePredictor is not one, pass its rp.predictor()" if recursive else "; use fit_predictor"
        raise DataError(f"pred must be a Predictor (attributes Lw, Lu, horizon, m, l){hint}") from exc
    if i < 1 or m < 1 or l < 1:
        raise DataError(f"predictor has horizon={i}, m={m}, l={l}; all must be >= 1")
    if Lw.shape != (i * l, i * (m + l)) or Lu.shape != (i * l, i * m):
        raise DataError(
            f"predictor matrices have shapes Lw {Lw.shape}, Lu {Lu.shape}; expected {(i * l, i * (m + l))} and "
            f"{(i * l, i * m)} for i={i}, m={m}, l={l}")
    if not (np.all(np.isfinite(Lw)) and np.all(np.isfinite(Lu))):
        raise DataError("predictor contains NaN or infinite values; refit it from clean data")
    return Lw, Lu, i, m, l


#: :class:`HorizonWarning` when :attr:`~synthesis.Predictor.control_pvalue` exceeds this: the data give no evidence
#: that the future inputs move the predicted outputs
CONTROL_PVALUE_LIMIT = 0.01


def _warn_no_control(pred, stacklevel: int) -> None:
    """:class:`HorizonWarning` when the predictor's data show no effect of ``U_f`` on ``Y_f`` (``L_u`` is noise).

    A horizon not longer than the plant's delay (``i = 1`` on a strictly proper plant) gives a law whose control
    reaches no predicted output: measured, ``L_u`` of 0.5 z⁻¹ + 0.2 z⁻² at ``i = 1`` was 1.3e-3 (noise) and the
    H∞ law's gain 0.37 acted on it, with no warning.  Read lazily (a predictor without the field is not tested).
    """
    p = getattr(pred, "control_pvalue", None)
    if p is not None and p > CONTROL_PVALUE_LIMIT:
        i = int(pred.horizon)
        warnings.warn(
            f"the data show no effect of the control on the predicted output over the horizon i={i} (F-test of "
            f"L_u = 0: p = {p:.2g}): the plant's delay is at least {i} sample(s) (i = 1 on a strictly proper plant), "
            f"or L_u is lost in what so short a horizon leaves unpredicted, and the law acts on noise in L_u; use a "
            f"horizon longer than the plant's delay (i >= 2 for a strictly proper plant) and the plant's order (on "
            f"closed-loop data, where the input is mostly the loop's response, the test can fail at any horizon: "
            f"excite the loop through its reference, or fit on an open-loop record)",
            HorizonWarning, stacklevel=stacklevel + 1)


def _weights(pred_m, pred_l, W1, W2, uncertainty, data_dt=None):
    W1 = as_weight(W1, "W1", inputs=pred_l)
    W2 = as_weight(W2, "W2", inputs=pred_m)
    unc = None
    if uncertainty is not None:
        if not isinstance(uncertainty, (Multiplicative, Additive)):
            raise WeightError("uncertainty must be Multiplicative(W3, W4), Additive(W3, W4) or None")
        w3_in = pred_l if isinstance(uncertainty, Multiplicative) else pred_m
        W3 = as_weight(uncertainty.W3, "W3", inputs=w3_in, allow_zero=True)
        W4 = as_weight(uncertainty.W4, "W4", outputs=pred_l, allow_zero=True, square_rank=True)
        unc = (W3, W4)
    dt = common_dt(W1, W2, *(unc or ()))
    if data_dt is not None:
        data_dt = check_sample_time(data_dt)
        if dt is True:
            dt = data_dt
        elif data_dt is not True and not np.isclose(dt, data_dt, rtol=1e-9, atol=0):
            raise WeightError(
                f"the weights have sample time {dt} but the data's is {data_dt}; discretise the weights at the "
                f"data's sample time (e.g. synthesis.tustin(W, {data_dt}) or synthesis.makeweight(..., {data_dt}))")
    # give static weights the common sample time so every system returned is discrete with one dt
    fix = lambda W: W if W.nstates else control.ss(W.A, W.B, W.C, W.D, dt)  # noqa: E731
    W1, W2 = fix(W1), fix(W2)
    if unc is not None:
        unc = (fix(unc[0]), fix(unc[1]))
    return W1, W2, unc, dt


@dataclass(frozen=True, eq=False)
class _MapPlan:
    """The parts of a law that do not depend on the predictor, computed once per weights and horizon.

    The performance map is affine in ``(L_w, L_u)`` through one fixed block ``B`` (the predictor
    enters only as ``ŷ = L_w w_p + L_u u``, (3.20)): ``M_u = M_u⁰ + B L_u`` and the ``w_p`` columns
    of ``M_x`` are ``B L_w``, with ``B = [−H1; 0]`` ((3.21), Thm 3.2, Thm 3.7) or ``[−H1; 0; H3]``
    (multiplicative, (3.49)).  ``template`` is the map at ``L_w = 0``, ``L_u = 0`` (Markov Toeplitz
    and observability blocks of the weights, (3.10)–(3.12)).  :meth:`fill` adds the predictor
    terms — two matrix products per update in the adaptive loop of §5.3 instead of rebuilding the
    Toeplitz matrices — and :func:`_design_from_plan` solves the game for the columns
    ``reduced_Mx = [M_x without w_p | B]`` only (the saddle-point gains are linear in ``M_x``, so
    the ``w_p`` gain is the ``B`` gain times ``L_w``: ``i·l`` columns solved instead of ``i(m+l)``).
    """

    i: int
    m: int
    l: int
    causal: bool
    kind: object
    W1: control.StateSpace
    W2: control.StateSpace
    unc: tuple | None
    dt: object
    template: PerformanceMap
    H1: np.ndarray
    H3: np.ndarray | None  # multiplicative law only
    wp_col: int  # first column of w_p in M_x
    weight_states: tuple
    reduced_Mx: np.ndarray  # [M_x columns other than w_p | B], read-only
    b_is_reference: bool  # B = −(the r columns of [M_x | M_d]): Q_fullᵀB is read off Q_fullᵀ[M_x M_d]

    @property
    def wp(self) -> slice:
        """Columns of ``w_p`` in ``M_x`` (and in the gains)."""
        return slice(self.wp_col, self.wp_col + self.i * (self.m + self.l))

    def control_map(self, Lu: np.ndarray) -> np.ndarray:
        """``M_u = M_u⁰ + B L_u`` (a new array)."""
        Mu = self.template.Mu.copy()
        p1 = self.H1.shape[0]
        Mu[:p1] += -self.H1 @ Lu
        if self.H3 is not None:
            Mu[-self.H3.shape[0]:] += self.H3 @ Lu
        return Mu

    def saddle(self, Lu: np.ndarray):
        """:func:`synthesis.minimax._saddle` of ``(M_d, M_u, reduced_Mx)`` for the predictor's ``L_u``.

        Without uncertainty and for :class:`Additive`, ``B = [−H1; 0]`` is minus the reference
        columns of the map (``r`` is the first disturbance block, (3.21); its first ``l`` columns
        are ``r_k`` in ``M_x`` for the causal law, Thm 3.2), so ``Q_fullᵀ B`` is minus columns of
        ``Q_fullᵀ M_d`` and ``Q_fullᵀ M_x`` already computed: the reflectors are applied to ``M_d``
        and the other ``M_x`` columns only (the result is bit-identical: Householder products are
        odd in their argument).
        """
        Md, Mu = self.template.Md, self.control_map(Lu)
        if not self.b_is_reference:
            return _saddle(Md, Mu, self.reduced_Mx)
        nb = self.i * self.l
        sd = _saddle(Md, Mu, self.reduced_Mx[:, :-nb])
        k = self.wp_col  # r_k columns (causal law) lead M_x
        top = -np.hstack([sd.QtMx[:, :k], sd.QtMd])[:, :nb]
        bottom = -np.hstack([sd.QcMx[:, :k], sd.X])[:, :nb]
        return dataclasses.replace(sd, QtMx=np.hstack([sd.QtMx, top]), QcMx=np.hstack([sd.QcMx, bottom]))

    def fill(self, Lw: np.ndarray, Lu: np.ndarray) -> PerformanceMap:
        """The performance map for the predictor ``(L_w, L_u)`` (equal to :func:`_build_map`'s)."""
        t = self.template
        p1 = self.H1.shape[0]
        Mx = t.Mx.copy()
        wp = self.wp
        Mx[:p1, wp] += -self.H1 @ Lw
        if self.H3 is not None:
            Mx[-self.H3.shape[0]:, wp] += self.H3 @ Lw
        return PerformanceMap(t.Md, self.control_map(Lu), Mx, t.disturbances, t.columns)

    def expand(self, G: np.ndarray, Lw: np.ndarray) -> np.ndarray:
        """Gain on the columns of ``M_x`` from the gain ``G`` on :attr:`reduced_Mx`: ``w_p`` block ``G_B L_w``."""
        wp, nb = self.wp, self.i * self.l
        n_other = G.shape[1] - nb
        out = np.empty((G.shape[0], self.template.Mx.shape[1]))
        out[:, : wp.start] = G[:, : wp.start]
        out[:, wp.stop:] = G[:, wp.start: n_other]
        np.matmul(G[:, n_other:], Lw, out=out[:, wp])
        return out


def _map_plan(i, m, l, W1, W2, *, causal=False, uncertainty=None, dt=None) -> _MapPlan:
    """Validate the weights and build the predictor-independent :class:`_MapPlan` of a law."""
    W1s, W2s, unc, dt = _weights(m, l, W1, W2, uncertainty, dt)
    kind = type(uncertainty) if unc else None
    zero_w, zero_u = np.zeros((i * l, i * (m + l))), np.zeros((i * l, i * m))
    causal = check_flag(causal, "causal")
    template = _build_map(zero_w, zero_u, i, m, l, W1s, W2s, kind, unc, bool(causal))
    H1 = markov_toeplitz(W1s, i)
    H3 = markov_toeplitz(unc[0], i) if kind is Multiplicative else None
    # B: the predictor-term block (module docstring of _MapPlan); the w_p columns of the template are 0
    B = np.zeros((template.Mu.shape[0], i * l))
    B[: H1.shape[0]] = -H1
    if H3 is not None:
        B[-H3.shape[0]:] = H3
    wp_col = l if causal else 0
    wp = slice(wp_col, wp_col + i * (m + l))
    if np.any(template.Mx[:, wp]):  # pragma: no cover - a structural fact of _build_map
        raise AssertionError("the w_p columns of the performance map must vanish at L_w = 0")
    reduced = np.hstack([template.Mx[:, : wp.start], template.Mx[:, wp.stop:], B])
    b_is_reference = bool(np.array_equal(B, -np.hstack([template.Mx[:, : wp.start], template.Md])[:, : i * l]))
    for a in (template.Md, reduced):
        a.flags.writeable = False  # shared by every map filled from this plan
    ws = [_weight_state("x_w1", W1s, "e"), _weight_state("x_w2", W2s, "u")]
    if unc is not None:
        ws.append(_weight_state("x_w3", unc[0], "y" if kind is Multiplicative else "u"))
    return _MapPlan(i=i, m=m, l=l, causal=bool(causal), kind=kind, W1=W1s, W2=W2s, unc=unc, dt=dt,
                    template=template, H1=H1, H3=H3, wp_col=wp_col, weight_states=tuple(ws),
                    reduced_Mx=reduced, b_is_reference=b_is_reference)


def _build_map(Lw, Lu, i, m, l, W1, W2, unc_kind, unc, causal):
    H1, G1 = markov_toeplitz(W1, i), observability(W1, i)
    H2, G2 = markov_toeplitz(W2, i), observability(W2, i)
    p1, p2 = H1.shape[0], H2.shape[0]
    n1, n2 = G1.shape[1], G2.shape[1]
    z = lambda r, c: np.zeros((r, c))  # noqa: E731
    # (3.21): rows z1, z2; d = r
    Md_r = np.vstack([H1, z(p2, i * l)])
    Mu = np.vstack([-H1 @ Lu, H2])
    Mx_blocks = {
        "w_p": np.vstack([-H1 @ Lw, z(p2, Lw.shape[1])]),
        "x_w1": np.vstack([G1, z(p2, n1)]),
        "x_w2": np.vstack([z(p1, n2), G2]),
    }
    disturbances = [("r", i * l)]
    Md_blocks = [Md_r]
    names = ["w_p", "x_w1", "x_w2"]
    if unc is not None:
        W3, W4 = unc
        H3, G3 = markov_toeplitz(W3, i), observability(W3, i)
        H4, G4 = markov_toeplitz(W4, i), observability(W4, i)
        p3, n3, n4, ms = H3.shape[0], G3.shape[1], G4.shape[1], H4.shape[1]
        # z1 gets −H1(H4 s + Γ4 x_w4) (3.49); add the z3 row block
        Md_r = np.vstack([Md_r, z(p3, i * l)])
        Md_s = np.vstack([-H1 @ H4, z(p2, ms), z(p3, ms)])
        Md_blocks = [Md_r, Md_s]
        disturbances.append(("s", ms))
        if unc_kind is Multiplicative:
            z3_u, z3_wp = H3 @ Lu, H3 @ Lw
        else:
            z3_u, z3_wp = H3, z(p3, Lw.shape[1])
        Mu = np.vstack([Mu, z3_u])
        Mx_blocks = {
            "w_p": np.vstack([Mx_blocks["w_p"], z3_wp]),
            "x_w1": np.vstack([Mx_blocks["x_w1"], z(p3, n1)]),
            "x_w2": np.vstack([Mx_blocks["x_w2"], z(p3, n2)]),
            "x_w3": np.vstack([z(p1 + p2, n3), G3]),
            "x_w4": np.vstack([-H1 @ G4, z(p2 + p3, n4)]),
        }
        names += ["x_w3", "x_w4"]
    Md = np.hstack(Md_blocks)
    columns = [(n, Mx_blocks[n].shape[1]) for n in names]
    Mx = np.hstack([Mx_blocks[n] for n in names])
    if causal:
        # Thm 3.2: r_k is known, so its l columns move from d into x (first), (3.37)–(3.38)
        Mx = np.hstack([Md[:, :l], Mx])
        Md = Md[:, l:]
        disturbances[0] = ("r", (i - 1) * l)
        columns = [("r_k", l)] + columns
    return PerformanceMap(Md, Mu, Mx, tuple(disturbances), tuple(columns))


def performance_map(pred, W1, W2, *, causal: bool = False, uncertainty=None, dt=None) -> PerformanceMap:
    """Performance map ``z = M_d d + M_u u + M_x x`` of a law ((3.21), Thm 3.2, (3.49), Thm 3.7).

    Parameters are those of :func:`hinf_design`.

    Examples
    --------
    Horizon ``i = 4``, one input and one output, static weights ``W1 = 1``, ``W2 = 0.1``: ``z`` stacks
    the weighted errors and controls (8 rows), ``d`` is the reference over the horizon and ``x`` the
    past data ``w_p`` (the static weights have no states):

    >>> import numpy as np
    >>> from synthesis import fit_predictor
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(200)
    >>> y = np.convolve(u, [0.0, 0.5, 0.2])[:200] + 0.01 * rng.standard_normal(200)
    >>> pred = fit_predictor(u, y, 4)
    >>> pm = performance_map(pred, 1.0, 0.1)
    >>> pm.Md.shape, pm.Mu.shape, pm.Mx.shape
    ((8, 4), (8, 4), (8, 8))
    >>> pm.disturbances, pm.columns
    ((('r', 4),), (('w_p', 8), ('x_w1', 0), ('x_w2', 0)))
    """
    Lw, Lu, i, m, l = _predictor_parts(pred)
    dt = check_predictor_dt(pred, dt, error=WeightError)
    W1, W2, unc, _ = _weights(m, l, W1, W2, uncertainty, dt)
    return _build_map(Lw, Lu, i, m, l, W1, W2, type(uncertainty) if unc else None, unc,
                      check_flag(causal, "causal"))


def gamma_min(pred, W1, W2, *, causal: bool = False, uncertainty=None, dt=None) -> float:
    """Best achievable level ``γ_min`` (3.8), causal (3.41), multiplicative (3.46), additive (3.64).

    Computed exactly as ``‖(I − P_u) M_d‖₂`` by :func:`synthesis.minimax.minimax_gamma_min`.

    Parameters
    ----------
    pred, W1, W2, causal, uncertainty, dt
        As for :func:`hinf_design`.

    Returns
    -------
    float

    Raises
    ------
    WeightError, DataError
        As for :func:`hinf_design`.

    Warns
    -----
    HorizonWarning
        As for :func:`hinf_design`.

    Examples
    --------
    The plant ``0.5 z⁻¹ + 0.2 z⁻²`` has a delay, so no control reaches the first tracking error of
    the horizon and ``γ_min ≈ ‖W1‖ = 1``; the causal law, which knows ``r_k``, does better:

    >>> import numpy as np
    >>> from synthesis import fit_predictor
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(200)
    >>> y = np.convolve(u, [0.0, 0.5, 0.2])[:200] + 0.01 * rng.standard_normal(200)
    >>> pred = fit_predictor(u, y, 4)
    >>> g = gamma_min(pred, 1.0, 0.1)
    >>> round(g, 3), round(gamma_min(pred, 1.0, 0.1, causal=True), 3)
    (1.0, 0.261)

    The same number as the minimax engine on the performance map:

    >>> from synthesis import minimax_gamma_min
    >>> pm = performance_map(pred, 1.0, 0.1)
    >>> g == minimax_gamma_min(pm.Md, pm.Mu)
    True
    """
    pm = performance_map(pred, W1, W2, causal=causal, uncertainty=uncertainty, dt=dt)
    _warn_no_control(pred, stacklevel=2)
    return minimax_gamma_min(pm.Md, pm.Mu)


def hinf_design(pred, W1, W2, *, gamma: float | None = None, gamma_ratio: float = 1.1,
                causal: bool = False, uncertainty=None, dt=None) -> HinfDesign:
    """Finite-horizon model-free subspace based central H∞ design (Thms 3.1, 3.2, 3.4, 3.7).

    Parameters
    ----------
    pred : Predictor
        Subspace predictor ``(L_w, L_u)`` from :func:`synthesis.fit_predictor` (any object with
        ``Lw, Lu, horizon, m, l`` works).
    W1, W2 : control.StateSpace, control.TransferFunction, scalar or matrix
        Discrete weights on the tracking error ``r − y`` (``l`` inputs) and on ``u`` (``m``
        inputs), relative degree 0, one common sample time (the data's).
    gamma : float or callable, optional
        Level; must exceed ``γ_min``.  Default ``gamma_ratio * γ_min`` (∞ if ``γ_min = 0``,
        i.e. no disturbance channel, e.g. the causal law with ``i = 1``).  A callable is a
        γ policy: it receives ``γ_min`` and returns γ (e.g. :class:`synthesis.GammaPolicy`,
        ``γ = γ_min + α`` of §5.3), so γ_min is computed only once.
    gamma_ratio : float
        Used when ``gamma`` is None; 1.1 is the thesis's rule of thumb (§5.1 comment 4).
    causal : bool
        ``r_k`` is known when ``u_k`` is computed (Thm 3.2); the controller then has a
        feedthrough from ``r``.
    uncertainty : Multiplicative or Additive, optional
        Robust design (Thm 3.4 / Thm 3.7).
    dt : float, optional
        The data's sample time.  When known -- given here, or stored on the predictor by
        ``fit_predictor(u, y, i, dt=...)`` (:attr:`Predictor.dt`) -- the weights' sample time
        must equal it (else :class:`WeightError`), and it is the controller's sample time even
        when every weight is static.  Default: the predictor's ``dt``, else the weights' common
        sample time (``True``, unspecified, if all are static): a predictor fitted on bare
        arrays without ``dt`` cannot tell a mismatch.

    Returns
    -------
    HinfDesign

    Raises
    ------
    InfeasibleGammaError
        If ``gamma <= γ_min``.
    WeightError, DataError
        Improper / continuous / NaN weights, mismatched sample times or dimensions.

    Warns
    -----
    NearGammaMinWarning
        If ``gamma < 1.03 γ_min``.
    HorizonWarning
        If the data show no effect of the control on the predicted output over the horizon
        (:attr:`~synthesis.Predictor.control_pvalue` above 0.01: ``i = 1`` on a strictly proper plant).

    Examples
    --------
    Static weights at horizon ``i = 4``: the default level is ``1.1 γ_min`` and the controller
    (inputs ``[r; y]``, output ``u``) has the ``i(m+l) = 8`` states of the past data:

    >>> import numpy as np
    >>> from synthesis import fit_predictor
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(200)
    >>> y = np.convolve(u, [0.0, 0.5, 0.2])[:200] + 0.01 * rng.standard_normal(200)
    >>> pred = fit_predictor(u, y, 4)
    >>> design = hinf_design(pred, 1.0, 0.1)
    >>> round(design.gamma / design.gamma_min, 6), design.gain.shape
    (1.1, (4, 8))
    >>> K = design.controller
    >>> K.nstates, K.ninputs, K.noutputs
    (8, 2, 1)

    The gain is the saddle point of the minimax game on the performance map:

    >>> from synthesis import solve_minimax
    >>> pm = performance_map(pred, 1.0, 0.1)
    >>> np.allclose(solve_minimax(pm.Md, pm.Mu, pm.Mx, design.gamma).u_gain, design.gain)
    True
    """
    Lw, Lu, i, m, l = _predictor_parts(pred)
    plan = _map_plan(i, m, l, W1, W2, causal=causal, uncertainty=uncertainty,
                     dt=check_predictor_dt(pred, dt, error=WeightError))
    if gamma is None:
        ratio = check_level(gamma_ratio, "gamma_ratio")
        gamma = lambda g0: ratio * g0 if g0 > 0 else np.inf  # noqa: E731 - a γ policy
    elif not callable(gamma):
        gamma = _real(gamma, "gamma")
    _warn_no_control(pred, stacklevel=2)
    return _design_from_plan(pred, Lw, Lu, plan, gamma)


def _design_from_plan(pred, Lw, Lu, plan: _MapPlan, gamma) -> HinfDesign:
    """The design for ``pred`` (already checked: ``Lw``, ``Lu``) from a :class:`_MapPlan`.

    One saddle factorisation (:meth:`_MapPlan.saddle`: QR of ``M_u = M_u⁰ + B L_u``,
    ``γ_min``) for ``γ_min``, the policy and the gains; the gains are solved for
    :attr:`_MapPlan.reduced_Mx` and expanded (:meth:`_MapPlan.expand`), so they equal
    ``solve_minimax`` on the full map (:meth:`_MapPlan.fill`) to rounding and ``γ_min`` equals
    :func:`gamma_min`'s to the last bit.  The ``control.StateSpace`` is deferred.
    """
    if (Lw.shape, Lu.shape) != ((plan.i * plan.l, plan.i * (plan.m + plan.l)), (plan.i * plan.l, plan.i * plan.m)):
        raise DataError(f"predictor shapes Lw {Lw.shape}, Lu {Lu.shape} do not match the plan's "
                        f"(i, m, l) = {(plan.i, plan.m, plan.l)}")
    sd = plan.saddle(Lu)
    level = _level(gamma, sd)
    _warn_near(level, sd.gamma_min, stacklevel=3)
    u_gain, d_gain, _ = _gains(sd, level)
    unc = plan.unc
    design = HinfDesign(
        predictor=pred, W1=plan.W1, W2=plan.W2,
        uncertainty=None if unc is None else plan.kind(unc[0], unc[1]),
        horizon=plan.i, m=plan.m, l=plan.l, causal=plan.causal, dt=plan.dt,
        gamma=level, gamma_min=sd.gamma_min, gain=plan.expand(u_gain, Lw),
        disturbance_gain=plan.expand(d_gain, Lw), columns=plan.template.columns,
        disturbances=plan.template.disturbances, weight_states=plan.weight_states,
        controller=_Deferred(lti_controller, with_owner=True),
    )
    return design


def _real(value, name: str) -> float:
    """A real level (NaN and values <= γ_min are left to :func:`solve_minimax`, which states γ_min)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise DataError(f"{name} must be a real number above gamma_min (or None, or a callable), got {value!r}")
    return float(value)


def _weight_state(name: str, W, drive: str) -> WeightState:
    A, B, _, _ = _ss_parts(W)
    return WeightState(name, A, B, drive)
