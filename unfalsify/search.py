"""The design search of the §7.4 pipeline, and the judge of its loops.

:func:`unfalsify.robust_design_from_data` sizes the uncertainty and hands it here.  The requested design
(:class:`unfalsify.DesignOptions`: Theorem 3.7 at horizon i with ``W3 = cI``, ``c`` by default the fixed point
of :func:`additive_weight_fixed_point`) is built and judged first; when its loop does not certify, the family
:class:`unfalsify.DesignSearch` (other horizons, the other law, larger γ ratios and W3 factors) is tried by
increasing departure from it, and the first certified design is taken.  A loop must pass, on P̂ and on the
reference model P̂_ref (a longer horizon, :data:`REFERENCE_COLUMNS`, :data:`REFERENCE_HORIZON_CAP`):
:func:`unfalsify.certify_loop` (stable, the proven small gain, the performance floor), the excitation test
(:func:`unfalsify.check_excitation`), no narrow line of P̂'s output error where it is sensitive, and tracking
across the ball and at the data's low-frequency gain -- in coprime-factor form the same checks at ε.  A premise
the data refute (or, with ``untested="refuse"``, cannot test), or a required reference model that is missing, fails
every loop, and then nothing is searched.  When nothing certifies, :func:`_size_reason` says whether the size of δ
(ε) is what refuses, and what lowers it.
"""
from __future__ import annotations

import dataclasses
import functools
import itertools
import math
import warnings
from dataclasses import dataclass

import control
import numpy as np
from scipy.optimize import brentq

import synthesis
from synthesis import Additive, hinf_norm
from synthesis.results import result
from synthesis.validation import (DataError, check_count, check_flag, check_instance, check_level,
                                  check_nonnegative)

from ._common import channel_pair, spectral_radius
from .exceptions import UnfalsificationError
from .certify import LoopCertificate, certify_loop, tracking_floors
from .coprime import CoprimePremise, check_coprime_premise, coprime_factors, coprime_unfalsify
from .model import predictor_model
from .excitation import ExcitationCheck, check_excitation
from .frequency_response import _unit
from .options import CertificateOptions, DesignOptions, DesignSearch, _positive_real
from .premise import (HIDDEN_LINE_LIMIT, LINE_LOOP_GAIN, PremiseOptions, PremiseTest, _hidden_gain,
                      _hidden_line_statement, _line_gain, _line_spectra)
from .subspace import SubspaceResult
from .tracking import _coprime_data_gain, _coprime_tracking_reason, _steady_state_reason

__all__ = ["SearchRecord", "additive_weight_fixed_point", "REFERENCE_COLUMNS", "REFERENCE_HORIZON_CAP"]


@result
@dataclass(frozen=True)
class SearchRecord:
    """One design tried by the search: its options, level and certificate (or why it could not be built)."""

    horizon: int
    causal: bool
    gamma_ratio: float
    w3_gain: float
    gamma: float
    gamma_min: float
    certificate: LoopCertificate | None
    error: str = ""
    reference_certificate: LoopCertificate | None = None
    premise_reason: str = ""
    excitation: ExcitationCheck | None = None
    tracking_reason: str = ""

    @property
    def certified(self) -> bool:
        """Certified on P̂ (and on P̂_ref when there is one), with the premise unfalsified by the data."""
        return bool(self.certificate is not None and not self.reason)

    @property
    def reason(self) -> str:
        """Why not certified (``''`` when it is)."""
        if self.error or self.certificate is None:
            return self.error
        return _verdict_reason(self.certificate, self.reference_certificate, self.premise_reason, self.excitation,
                               self.tracking_reason)


def _verdict_reason(cert: LoopCertificate, ref: LoopCertificate | None, premise_reason: str = "",
                    excitation: ExcitationCheck | None = None, tracking_reason: str = "") -> str:
    """Every reason the loop is not certified, joined (``''`` when it is)."""
    reasons = [] if cert.certified else [cert.reason]
    if ref is not None and not ref.certified:
        reasons.append(ref.reason if ref.norm is None and math.isnan(ref.spectral_radius)
                       else f"on the reference model P̂_ref: {ref.reason}")
    if premise_reason:
        reasons.append(f"premise not supported by the data: {premise_reason}")
    if excitation is not None and not excitation.ok:
        reasons.append(excitation.reason)
    if tracking_reason:
        reasons.append(tracking_reason)
    return "; ".join(reasons)


def _untested_reason(assumed: tuple) -> str:
    """The refusal of ``CertificateOptions(untested="refuse")`` (``''`` when the data test every premise)."""
    if not assumed:
        return ""
    return ("these data cannot test the premise (CertificateOptions(untested='refuse')): " + "; ".join(assumed)
            + "; excite with several amplitudes, or certify with untested='warn' on that assumption")


def _persistence_reason(pred, u, i: int, what: str, design: int | None = None) -> str:
    """Why the predictor's data are not persistently exciting (``''`` when they are).

    A predictor that records its ranks (:func:`synthesis.fit_predictor`) is judged by them; one that
    does not (the (L_w, L_u) found by (7.5)) by the numerical rank of the window's ``[U_p; U_f]``.
    ``design``: the design's horizon when ``pred`` is at another one (the reference predictor): a horizon
    the reason proposes is the design's.
    """
    ratio = i / design if design else 1.0
    if getattr(pred, "input_rank", None) is not None:
        if pred.persistently_exciting is False:
            full = 2 * i * int(getattr(pred, "m", 1))
            return (f"the {what} was fitted on an input that is not persistently exciting of order 2i = {2 * i} "
                    f"(rank {pred.input_rank} of {full}): "
                    + (_delayed_copy(u, i, ratio) or "excite more frequencies (white PRBS"
                       + (", independent per input channel" if full > 2 * i else "") + ") or lower the horizon"))
        if not pred.full_rank:
            return (f"the {what}'s regressor is rank deficient (rank {pred.rank} of {pred.n_regressors}; a "
                    "PersistenceWarning): use a longer or richer record")
        return ""
    u2 = np.asarray(u, float).reshape(np.shape(u)[0], -1)
    m = u2.shape[1]
    # block Hankel [U_p; U_f] of depth 2i, one row per column of the window: rank 2i·m needed.  Several inputs: each
    # channel at unit rms first, so the units do not decide the rank (10⁻⁶ and 10⁶ had dropped half of it)
    U = np.lib.stride_tricks.sliding_window_view(_unit_rms(u2) if m > 1 else u2, 2 * i, axis=0).reshape(-1, 2 * i * m)
    s = np.linalg.svd(U, compute_uv=False)
    rank = int(np.sum(s > max(U.shape) * np.finfo(float).eps * 1e3 * s[0])) if s.size and s[0] > 0 else 0
    if rank < 2 * i * m:
        return (f"the window's input is not persistently exciting of order 2i = {2 * i} (rank {rank} of {2 * i * m}): "
                + (_delayed_copy(u2, i, ratio)
                   or "excite more frequencies (white PRBS, independent per input channel) or lower the horizon"))
    return ""


def _unit_rms(u: np.ndarray) -> np.ndarray:
    """Each column of ``u`` divided by its rms (a silent column stays 0)."""
    rms = np.sqrt(np.mean(u ** 2, axis=0))
    return u / np.where(rms > 0.0, rms, 1.0)


def _delayed_copy(u, i: int, ratio: float = 1.0) -> str:
    """The fix when one input channel is another delayed by fewer than 2i samples (``''`` when none is); ``ratio``:
    this horizon over the design's (2 for the reference predictor), so that the horizon proposed is the design's.

    Two phases of one maximum-length PRBS are the same sequence shifted: measured, ``prbs(1500, seed=0)`` and
    ``prbs(1500, seed=17)`` are one sequence 13 samples apart, and a 2 × 2 record driven by them was refused as not
    persistently exciting with the fix "excite more frequencies (white PRBS)", which they already are.
    """
    u = np.asarray(u, float).reshape(np.shape(u)[0], -1)
    n, m = u.shape
    for a, b in itertools.permutations(range(m), 2):
        for lag in range(0 if a < b else 1, min(2 * i, n - 1)):
            x, z = u[lag:, a], u[:n - lag, b]  # input a at k against input b at k − lag
            scale = float(np.linalg.norm(x) * np.linalg.norm(z))
            if scale > 0 and abs(float(x @ z)) >= (1.0 - 1e-9) * scale:
                what = (f"input {a} is input {b}" if lag == 0 else
                        f"input {a} is input {b} delayed by {lag} sample{'s' if lag > 1 else ''} (two phases of "
                        "one PRBS are one sequence shifted)")
                return (f"{what} up to a factor: drive the inputs with independent sequences"
                        + (f", or lower the horizon to i ≤ {int(lag // (2 * ratio))}" if lag >= 2 * ratio else ""))
    return ""


def _gamma_of(pred, W1, W2, causal: bool, gamma_ratio: float, l: int, dt=None):
    def g(c: float) -> float:
        unc = Additive(float(c) * np.eye(pred.m), np.eye(l))
        return gamma_ratio * synthesis.gamma_min(pred, W1, W2, causal=causal, uncertainty=unc, dt=dt)

    return g


def additive_weight_fixed_point(pred, W1, W2, delta: float, *, gamma_ratio: float = 1.1, margin: float = 0.1,
                                causal: bool = False, xtol: float = 1e-10, max_doublings: int = 80,
                                dt=None) -> float:
    """Smallest-found ``c`` with ``c = (1 + margin) δ γ(c)``, ``γ(c) = gamma_ratio · γ_min_a(W3 = cI, W4 = I)``.

    Returns 0 when ``delta == 0``.  See :mod:`unfalsify.robust` for why a root exists.

    Raises
    ------
    InputTypeError
        ``pred`` is not a :class:`synthesis.Predictor`.
    DataError
        ``delta`` or ``margin`` not a finite number ≥ 0, ``gamma_ratio`` not > 1, ``xtol`` not > 0,
        ``max_doublings`` not an integer ≥ 1, ``causal`` not a bool.

    Examples
    --------
    >>> import numpy as np
    >>> import synthesis as sy
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(300)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:300] + 0.01 * rng.standard_normal(300)
    >>> pred = sy.fit_predictor(u, y, 3)
    >>> W1 = sy.makeweight(10.0, (0.3, 1.0), 0.5, 1.0)
    >>> W2 = sy.makeweight(0.1, (2.0, 0.3), 1.0, 1.0)
    >>> c = additive_weight_fixed_point(pred, W1, W2, 0.05)
    >>> bool(c > 0), bool(additive_weight_fixed_point(pred, W1, W2, 0.1) > c)    # c grows with δ
    (True, True)
    >>> additive_weight_fixed_point(pred, W1, W2, 0.0)
    0.0
    """
    check_instance(pred, synthesis.Predictor, "pred", "a synthesis.Predictor (e.g. synthesis.fit_predictor(u, y, i))")
    delta, margin = check_nonnegative(delta, "delta"), check_nonnegative(margin, "margin")
    gamma_ratio = check_level(gamma_ratio, "gamma_ratio (the design needs γ > γ_min_a)", minimum=1.0)
    causal = check_flag(causal, "causal")
    # brentq refuses xtol = 0 with a bare "xtol too small"; a string had reached the product below
    xtol = check_level(xtol, "xtol (brentq's absolute tolerance on c, relative to max(c, 1))")
    max_doublings = check_count(max_doublings, "max_doublings", 1)
    if delta == 0:
        return 0.0
    g = _gamma_of(pred, W1, W2, causal, gamma_ratio, pred.l, dt)
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


def _design(pred, W1, W2, delta, *, c, gamma_ratio, causal, dt):
    unc = Additive(c * np.eye(int(pred.m)), np.eye(int(pred.l))) if c > 0 else None
    return synthesis.hinf_design(pred, W1, W2, gamma_ratio=gamma_ratio, causal=causal, uncertainty=unc, dt=dt)


def _candidates(search: DesignSearch, horizon: int, causal: bool, gamma_ratio: float):
    """Search options as (horizon, causal, gamma_ratio, w3_factor), requested first, by increasing departure."""
    causals = [causal] + [c for c in search.causal if c != causal]
    horizons = [horizon] + [h for h in search.horizons if h != horizon]
    ratios = [gamma_ratio] + [g for g in search.gamma_ratios if g > gamma_ratio]
    factors = [1.0] + [f for f in search.w3_factors if f > 1.0]
    opts = [horizons, causals, ratios, factors]
    idx = itertools.product(*(range(len(o)) for o in opts))
    ordered = sorted(idx, key=lambda t: (sum(t), t))
    return [tuple(o[k] for o, k in zip(opts, t)) for t in ordered]


def _channels(u, y) -> tuple[int, int]:
    """``(m, l)`` of signals with time along axis 0."""
    return (int(np.prod(np.shape(u)[1:], dtype=int)) if np.ndim(u) > 1 else 1,
            int(np.prod(np.shape(y)[1:], dtype=int)) if np.ndim(y) > 1 else 1)


class _DesignSpace:
    """The designs the pipeline can build: predictors per horizon, W3 fixed points, Theorem 3.7 designs.

    The search revisits horizons and (horizon, causal, γ ratio) triples with other W3 factors: each
    predictor is fitted and each fixed point solved once.
    """

    def __init__(self, u, y, pred, predictor, predictor_for, W1, W2, delta, options: DesignOptions, dt):
        self.u, self.y, self.W1, self.W2, self.delta, self.options, self.dt = u, y, W1, W2, delta, options, dt
        self.given, self.predictor_for = predictor, predictor_for
        self.predictors = {int(pred.horizon): pred}
        self.reference_horizon = None  # set by _reference_model
        self.fixed_point = functools.lru_cache(maxsize=None)(self._fixed_point)

    def record_length(self) -> int | None:
        """Samples of the record the predictors are fitted on: the given predictor's ``j + 2i − 1``, the window's
        without one (then fitted on it), None when only ``predictor_for`` is known."""
        if self.given is not None:
            j = getattr(self.given, "n_columns", None)
            return None if j is None else int(j) + 2 * int(self.given.horizon) - 1
        return None if self.predictor_for is not None else int(np.shape(self.u)[0])

    def predictor_at(self, h: int):
        if h not in self.predictors:
            self.predictors[h] = _predictor_at(h, self.u, self.y, self.given, self.predictor_for)
        return self.predictors[h]

    def _fixed_point(self, h, cz, ratio) -> float:
        if self.options.w3_rule == "thesis":
            return 1.0 / self.delta
        return additive_weight_fixed_point(self.predictor_at(h), self.W1, self.W2, self.delta, gamma_ratio=ratio,
                                           margin=self.options.margin, causal=cz, dt=self.dt)

    def build(self, h, cz, ratio, factor):
        c = factor * self.fixed_point(h, cz, ratio)
        # δ = 0: no uncertainty at all, the nominal design.  (W3 = 0 alone would not do: W4 = I keeps
        # the channel s → z_w1 of Fig. 3.5, so γ_min_a(c → 0) stays above the nominal γ_min.)
        return _design(self.predictor_at(h), self.W1, self.W2, self.delta, c=c, gamma_ratio=ratio, causal=cz,
                       dt=self.dt), c


#: columns per regressor of the reference predictor's fit when its horizon is chosen from the record: a
#: least-squares fit with ``j`` columns for ``r`` regressors absorbs the fraction ``r/j`` of the noise, here a tenth
REFERENCE_COLUMNS = 10


#: the longest reference horizon chosen from the record (its model's order, and the cost of its checks, grow with it)
REFERENCE_HORIZON_CAP = 60


def _reference_horizon(options: CertificateOptions, i: int, space: "_DesignSpace") -> int:
    """The horizon of the reference model P̂_ref: ``options.reference_horizon`` when given; otherwise the longest
    horizon the fitting record supports (:func:`_record_horizon`), at least 2i; 2i when the record's length is
    unknown (a ``predictor_for`` without a fitted predictor)."""
    if options.reference_horizon is not None:
        return int(options.reference_horizon)
    longest = _record_horizon(space)
    return 2 * i if longest is None else max(2 * i, longest)


def _record_horizon(space: "_DesignSpace") -> int | None:
    """The largest horizon ``h ≤`` :data:`REFERENCE_HORIZON_CAP` whose predictor, fitted on the record the design's
    predictor was fitted on, has at least :data:`REFERENCE_COLUMNS` columns per regressor: ``n − 2h + 1 ≥
    REFERENCE_COLUMNS·h(2m + l)``.  A slow mode (time constant of tens to hundreds of samples) that flips or shrinks
    the plant's DC gain is invisible over a short horizon, where the plant looks like its fast part; the longest
    well-determined horizon is the one that sees it.  None when the record's length is unknown."""
    n = space.record_length()
    if n is None:
        return None
    m, l = _channels(*channel_pair(space.u, space.y))
    h = (n + 1) // (2 + REFERENCE_COLUMNS * (2 * m + l))
    return min(h, REFERENCE_HORIZON_CAP) if h >= 1 else None


def _reference_model(space: _DesignSpace, options: CertificateOptions, i: int, dt: float):
    """``(P̂_ref, note, persistence reason)``: the model at the reference horizon, or why there is none.

    A horizon chosen from the record (no ``reference_horizon`` given) whose predictor is not persistently exciting
    (an input of few sines) or fails falls back to 2i: the longer reference adds evidence, it does not demand more
    excitation than the design itself."""
    ref_h = _reference_horizon(options, i, space)
    if options.reference_horizon is None and ref_h > 2 * i:
        found = _reference_at(space, ref_h, i, dt)
        if found[0] is not None and not found[2]:
            space.reference_horizon = ref_h
            return found
        ref_h = 2 * i
    space.reference_horizon = ref_h
    return _reference_at(space, ref_h, i, dt)


def _reference_at(space: _DesignSpace, ref_h: int, i: int, dt: float):
    """``(P̂_ref, note, persistence reason)`` at horizon ``ref_h``, or ``(None, why not, '')``."""
    try:
        ref_pred = space.predictor_at(ref_h)
        return (predictor_model(ref_pred, dt), "",
                _persistence_reason(ref_pred, space.u, ref_h, f"reference predictor (horizon {ref_h})", design=i))
    except (ValueError, Warning) as exc:  # no predictor at that horizon (DataError), too little data
        return None, (f"no reference model at horizon {ref_h} ({exc}); the model's own error cannot be checked: "
                      "pass predictor_for=lambda h: fit_predictor(u_long, y_long, h) (a longer record)"), ""


class _LoopJudge:
    """Every check a design's loop must pass: certificates on P̂ and P̂_ref, the premise, excitation, tracking."""

    def __init__(self, model, ref_model, ref_note, prem, premise_reason, delta, options: CertificateOptions,
                 ball: "_CoprimeBall | None" = None, line_record=None):
        self.model, self.ref_model, self.prem, self.ball = model, ref_model, prem, ball
        self.line_record = line_record  # (u, y, i): the record whose output error is searched for narrow lines
        self.premise_reason, self.delta = premise_reason, delta
        self.refuse_hidden = options.untested == "refuse"  # a hidden line the loop could not tolerate refuses it too
        self.margin = _positive_real(options.margin, "certificate_margin", allow_equal=True)
        self.floor = options.tracking_floor  # one number, or one per output channel (certify.tracking_floors)
        self.cert_opts = dict(margin=self.margin, tracking_floor=options.tracking_floor,
                              step_samples=options.step_samples)
        self.missing = None
        if ref_model is None and options.require_reference:
            # measured without a reference: certificates on P̂ alone that failed on the true plant (an
            # integrating plant with a resonance, i = 10), so a missing reference is a reason not to certify
            self.missing = LoopCertificate(certified=False, reason=ref_note, delta=delta, margin=self.margin,
                                           spectral_radius=float("nan"), norm=None, small_gain=float("nan"),
                                           step=None, tracking_floor=self.floor)

    def record(self, h, cz, ratio, c, d):
        if self.ball is not None:
            return self._coprime_record(h, cz, ratio, c, d)
        prem = self.prem
        ref = (certify_loop(self.ref_model, d.controller, self.delta, model_name="P̂_ref", **self.cert_opts)
               if self.ref_model is not None else self.missing)
        cert = certify_loop(self.model, d.controller, self.delta, **self.cert_opts)
        exc = (check_excitation(self.model, d.controller, prem.frf, prem.low_band, delta=self.delta)
               if prem.frf is not None and cert.stable else None)
        if exc is not None and exc.ok:
            exc = self._line_check(exc, d.controller)
        track = self.tracking(d.controller, self.delta) if cert.stable else ""
        return _record(h, cz, ratio, c, d, cert, ref, self.premise_reason, exc, track)

    def tracking(self, controller, size: float) -> str:
        """Why the loop does not track across the ball of ``size`` (δ, or ε in coprime-factor form) and at the data's
        low-frequency gain (``''`` when it does; a ball of size 0 is not checked)."""
        radius = (1.0 + self.margin) * size
        if self.ball is not None:
            b = self.ball
            return _coprime_tracking_reason(b.factors, b.data_gain, controller, radius, self.floor)
        prem = self.prem
        gain = prem.plant_low_band.response[0] if prem.plant_low_band is not None else None
        return _steady_state_reason(self.model, controller, radius, self.floor, gain)

    @functools.cached_property
    def _spectra(self):
        """The narrow lines of P̂'s output error over the longest record (:func:`unfalsify.residual_line`) and the
        lines it could hide (:func:`unfalsify.hidden_line_gain`), found once for the whole search (they do not depend
        on the loop, nor on the form of the uncertainty); ``(None, None)`` without a record."""
        if self.line_record is None:
            return None, None
        u, y, i = self.line_record
        return _line_spectra(self.model, u, y, i, float(self.model.dt))

    @property
    def _lines(self):
        return self._spectra[0]

    def hidden_gain(self, controller) -> tuple[float, float]:
        """:func:`unfalsify.hidden_line_gain` of the loop on the longest record (NaN, NaN without a record)."""
        if self.line_record is None:
            return float("nan"), float("nan")
        factors = self.ball.factors if self.ball is not None else None
        return _hidden_gain(self._spectra[1], self.model, controller, float(self.model.dt), factors)

    def _line_check(self, exc: ExcitationCheck, controller) -> ExcitationCheck:
        """``exc`` failed when P̂'s output error over the longest record shows a narrow line the loop does not
        tolerate (:func:`unfalsify.residual_line`).  A line is a fact of ``P − P̂`` (the plant's additive error), so
        it is weighed with the loop's additive channel also in coprime-factor form, where its coprime-factor size
        weighed with the coprime channel counts too (the larger)."""
        if self._lines is None:
            return exc
        factors = self.ball.factors if self.ball is not None else None
        gain, freq = _line_gain(self._lines, self.model, controller, float(self.model.dt), factors)
        if gain < LINE_LOOP_GAIN:
            return self._hidden_check(exc, controller) if self.refuse_hidden else exc
        unit = _unit(float(self.model.dt))
        measure = "‖Ê‖/‖Û‖·σ̄(M̂)" if factors is None else "max(‖Ê‖/‖Û‖·σ̄(M̂), ‖M̂Ê‖/‖[Û; Ŷ]‖·σ̄([K; I](M̂+N̂K)⁻¹))"
        why = (f"P̂'s output error over the record has a narrow line at {freq:.3g} {unit} where the loop is sensitive "
               f"({measure} = {gain:.3g} ≥ {LINE_LOOP_GAIN:g}): a lightly damped mode P̂ misses, narrower than the "
               "Welch resolution of the premise test; raise the horizon, or record longer")
        return dataclasses.replace(exc, ok=False, worst=max(exc.worst, gain), frequency=freq, reason=why)

    def _hidden_check(self, exc: ExcitationCheck, controller) -> ExcitationCheck:
        """``exc`` failed, under ``CertificateOptions(untested="refuse")``, when a line below the record's noise could
        carry a loop gain of :data:`unfalsify.HIDDEN_LINE_LIMIT` or more (:func:`unfalsify.hidden_line_gain`): the
        statement ``assumed`` would hold, so the search looks for a loop that needs no such assumption."""
        gain, freq = self.hidden_gain(controller)
        if not gain >= HIDDEN_LINE_LIMIT:
            return exc
        why = _untested_reason((_hidden_line_statement(gain, freq, float(self.model.dt)),))
        return dataclasses.replace(exc, ok=False, worst=max(exc.worst, gain), frequency=freq, reason=why)

    def _coprime_record(self, h, cz, ratio, c, d):
        """The same checks in coprime-factor form: small gain ``ε‖[K; I](M̂+N̂K)⁻¹‖∞`` on P̂ and P̂_ref.

        P̂_ref's own ε (Theorem 7.1 on its equation error, at least P̂'s) costs a solve, so it is measured only for
        a design that passes every check on P̂ and on P̂_ref at P̂'s ε; a check failed at the smaller ε fails at
        the larger one too, so the verdict is the same.
        """
        b = self.ball
        cert = certify_loop(self.model, d.controller, b.eps, factors=b.factors, **self.cert_opts)
        exc = (check_excitation(self.model, d.controller, b.frf, b.low_band, factors=b.factors, delta=b.eps)
               if b.frf is not None and cert.stable else None)
        if exc is not None and exc.ok:
            exc = self._line_check(exc, d.controller)
        track = self.tracking(d.controller, b.eps) if cert.stable else ""
        ref = self.missing
        if self.ref_model is not None and b.ref_factors is not None:
            ref = certify_loop(self.ref_model, d.controller, b.eps, factors=b.ref_factors, model_name="P̂_ref",
                               **self.cert_opts)
            if ref.certified and cert.certified and (exc is None or exc.ok) and not track:
                eps_ref, why = b.ref_epsilon()
                ref = (certify_loop(self.ref_model, d.controller, eps_ref, factors=b.ref_factors,
                                    model_name="P̂_ref", **self.cert_opts)
                       if not why else dataclasses.replace(ref, certified=False, reason=why))
        return _record(h, cz, ratio, c, d, cert, ref, self.premise_reason, exc, track)


class _CoprimeBall:
    """What the coprime-factor judge needs: the factors and ε of P̂, P̂_ref's factors and (on demand) its ε,
    the estimates of ``R = M̂P − N̂`` and the data's gain."""

    def __init__(self, factors, eps, ref_factors, ref_data, held_out, options, frf, low_band, data_gain):
        self.factors, self.eps, self.ref_factors = factors, float(eps), ref_factors
        self.ref_data, self.held_out, self.options = ref_data, held_out, options
        self.frf, self.low_band, self.data_gain = frf, low_band, data_gain
        self._ref = None

    def ref_epsilon(self) -> tuple[float, str]:
        """``(ε_ref, reason)``: the larger of P̂'s ε and Theorem 7.1 on P̂_ref's equation error (solved once)."""
        if self._ref is None:
            try:
                cu = coprime_unfalsify(self.ref_factors, *self.ref_data, held_out=self.held_out, options=self.options)
                self._ref = (float(np.fmax(self.eps, cu.epsilon)), "")
            except DataError as exc:
                self._ref = (float("nan"), f"no coprime-factor ε for the reference model P̂_ref ({exc})")
        return self._ref


def _coprime_form(options: CertificateOptions, prem: PremiseTest, pred, model, u, y, unf, validation, premise,
                  space: "_DesignSpace", ref_model, persistence: str = "", record=None):
    """``(coprime premise or None, ball or None, premise reason)``: which form the loop is certified in.

    ``"auto"`` moves to the coprime form only when the data refute the additive premise and do not refute the
    coprime one; otherwise the additive verdict stands, with the coprime form's reason beside it.  A predictor whose
    data are not persistently exciting (``persistence``, a reason) certifies in neither form, so ``"auto"`` does not
    spend the coprime premise's solves on it (measured: 33 of 49 s for a constant input).
    """
    if options.uncertainty == "additive" or (options.uncertainty == "auto" and (not prem.reason or persistence)):
        return None, None, prem.reason
    opts = premise or PremiseOptions()
    factors = coprime_factors(pred, float(model.dt))
    cop = check_coprime_premise(factors, u, y, float(unf.sigma), validation=validation, options=opts, record=record)
    if options.uncertainty == "auto" and not cop.ok:
        return cop, None, f"{prem.reason}; in coprime-factor form too: {cop.reason}"
    if not math.isfinite(cop.epsilon):
        return cop, None, cop.reason or "no coprime-factor ε could be certified"
    ref_factors = None
    if ref_model is not None:
        ref_factors = coprime_factors(space.predictor_at(space.reference_horizon), float(model.dt))
    ball = _CoprimeBall(factors, cop.epsilon, ref_factors, validation if validation is not None else (u, y),
                        validation is not None, opts, cop.error_frf, cop.error_low_band,
                        _coprime_data_gain(factors, cop.error_low_band))
    return cop, ball, cop.reason


def _search_designs(space: _DesignSpace, judge: _LoopJudge, search: DesignSearch | None, i: int):
    """``(design, c, record, records, designs)``: the requested design, then the search's first certified one;
    ``designs`` lists the design of each record (None where it could not be built)."""
    o = space.options
    first, c0 = space.build(i, bool(o.causal), o.gamma_ratio, 1.0)
    records, designs = [judge.record(i, bool(o.causal), o.gamma_ratio, c0, first)], [first]
    if records[0].certified or search is None:
        return first, c0, records[0], records, designs
    for h, cz, ratio, factor in _candidates(search, i, bool(o.causal), o.gamma_ratio)[1:]:
        try:
            d, c = space.build(h, cz, ratio, factor)
            rec = judge.record(h, cz, ratio, c, d)
        except (ValueError, np.linalg.LinAlgError) as exc:  # DataError / InfeasibleGammaError / no predictor
            records.append(SearchRecord(h, cz, ratio, float("nan"), float("nan"), float("nan"), None,
                                        error=f"{type(exc).__name__}: {exc}"))
            designs.append(None)
            continue
        records.append(rec)
        designs.append(d)
        if rec.certified:
            return d, c, rec, records, designs
    return first, c0, records[0], records, designs


def _size_limit(judge: _LoopJudge, rec, controller, size: float) -> tuple[float, bool]:
    """``(limit, tracking fails there)`` for the loop of ``rec``: ``limit = min(size, small-gain bound)``, the
    largest δ (ε in coprime-factor form) its proven small gain on P̂ and P̂_ref allows, at most ``size``; and whether
    its tracking across the ball fails at that δ (then a smaller δ decides it: :func:`_tracking_limit`).

    ``(NaN, False)`` when the loop fails a check the size does not decide (unstable, a step that does not track on
    P̂ or P̂_ref, no reference model, the excitation test, the premise, tracking at the data's low-frequency gain),
    or passes the size's checks at ``size`` itself (it was refused for something else, e.g. the bounded-real proof).
    """
    cert, ref = rec.certificate, rec.reference_certificate
    nothing = float("nan"), False
    if controller is None or cert is None or rec.premise_reason or (
            rec.excitation is not None and not rec.excitation.ok):
        return nothing
    checked = [c for c in (cert, ref) if c is not None]  # a missing reference is unstable (spectral radius NaN)
    if not all(c.stable and c.tracks and c.norm is not None for c in checked):
        return nothing
    upper = max(float(c.norm.upper) for c in checked)
    if not math.isfinite(upper):
        return nothing
    if judge.tracking(controller, size * 1e-9):  # refused at P̂ itself or at the data's gain: no smaller δ helps
        return nothing
    limit = min(size, 1.0 / ((1.0 + judge.margin) * upper) if upper > 0 else float("inf"))
    fails = bool(rec.tracking_reason) if limit == size else bool(judge.tracking(controller, limit))
    return (limit, fails) if (limit < size or fails) else nothing


def _tracking_limit(judge: _LoopJudge, controller, hi: float) -> float:
    """The largest δ (ε) below ``hi``, where tracking across the ball fails, at which it passes; by bisection (the
    static plants tried at a radius lie on the rays of those tried at a larger one), to 6e-5 of ``hi``."""
    lo = hi * 1e-9
    for _ in range(14):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if judge.tracking(controller, mid) else (mid, hi)
    return lo


def _size_reason(judge: _LoopJudge, records, designs, size: float, name: str, where: str, fix: str) -> str:
    """Why no design certifies, when the size of the uncertainty (``name`` = ``size``: δ, or ε in coprime-factor
    form) is what refuses: ``''`` otherwise.

    Two findings, each general: loops of the search that are stable and track on P̂ (and P̂_ref) but fail only the
    checks that grow with the size (the proven small gain, tracking across the ball), with the largest size one of
    them tolerates; and, for any controller, an additive ball that holds a plant of singular DC gain, which no loop
    makes track (the step's steady error is 1 there; checked when every output is tracked with a floor below 1).
    ``where`` says where the size came from, ``fix`` what lowers it.
    """
    limits = [(*_size_limit(judge, r, d.controller if d is not None else None, size), d)
              for r, d in zip(records, designs)]
    limits = [x for x in limits if x[0] <= size]  # NaN compares False
    best, check = 0.0, ""
    # the loops whose tracking fails below their small-gain limit are bisected from the largest limit down, and only
    # while they can beat the best so far (the bisection costs fourteen tracking checks)
    for limit, fails, d in sorted(limits, key=lambda x: -x[0]):
        if limit <= best:
            break
        tolerated = _tracking_limit(judge, d.controller, limit) if fails else limit
        if tolerated > best:
            best, check = tolerated, "tracking across the ball" if fails else "the small gain"
    found = []
    dc = _singular_dc_gain(judge, size)
    if dc:
        found.append(dc)
    if limits:
        k, ref = len(limits), " and P̂_ref" if judge.ref_model is not None else ""
        found.append(f"{k} of the {len(records)} designs tried {'is' if k == 1 else 'are'} stable and "
                     f"track{'s' if k == 1 else ''} on P̂{ref} but fail{'s' if k == 1 else ''} only checks that grow "
                     f"with {name}; the best holds up to {name} = {best:.3g} ({check})")
    if not found:
        return ""
    return f"{name} = {size:.4g} is too large: " + "; ".join(found) + f"; {where}: {fix}"


def _singular_dc_gain(judge: _LoopJudge, delta: float) -> str:
    """The statement that the additive ball of ``δ`` holds a plant of singular DC gain, which no loop makes track
    (``''`` when it does not, in coprime-factor form, for a P̂ without a finite DC gain, or when an output is not
    tracked or its floor is 1 or more)."""
    if judge.ball is not None:
        return ""
    floors = np.asarray(tracking_floors(judge.floor, judge.model.noutputs), float)
    if not np.all(floors < 1.0):  # an untracked output (inf), or a floor that a zero output meets
        return ""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # python-control warns for a pole at 1
        try:
            G = np.atleast_2d(np.asarray(control.dcgain(judge.model), float))
        except (ValueError, np.linalg.LinAlgError):
            return ""
    if not np.all(np.isfinite(G)):
        return ""
    low = float(np.linalg.svd(G, compute_uv=False).min())
    radius = (1.0 + judge.margin) * delta
    if radius < low:
        return ""
    what = "zero DC gain" if G.size == 1 else "a singular DC gain"
    return (f"the ball of radius (1 + margin)·δ = {radius:.4g} around P̂ holds a plant with {what} (P̂'s smallest DC "
            f"singular value is {low:.4g}), which no controller makes track")


def _size_source(prem: PremiseTest, unf: SubspaceResult, model, i: int, span, fit_samples: int | None,
                 cop: CoprimePremise | None = None) -> tuple[str, str]:
    """``(where, fix)`` for :func:`_size_reason`: where δ came from -- (7.5) on the window or P̂'s output error --
    with its share of ‖P̂‖∞, or ε (``cop``, the coprime-factor form) -- the equation error on the window or on the
    held-out record -- and what lowers it: a longer window where the window decides, a better P̂ where held-out data
    do (no window lowers those)."""
    window = (f"the window [{span[0]}, {span[1]}) ({span[1] - span[0]} samples, j = {span[1] - span[0] - 2 * i + 1} "
              "columns)" if span is not None else "the window given")
    if span is not None and fit_samples is not None and span[1] < fit_samples:
        # twice the window, within the fitting part: (7.5)'s cost grows with its columns
        length = min(2 * (span[1] - span[0]), fit_samples - span[0])
        longer = (f"a longer window, e.g. window=({span[0]}, {length}) (the fitting part holds {fit_samples} "
                  "samples), or a longer record")
    elif span is not None:
        longer = "a longer record (the window spans the fitting part)"
    else:
        longer = "a longer window (more samples of u, y), or the whole record with window="
    name = "δ" if cop is None else "ε"
    # "may": measured, on the FIR example's 32-sample window one noise sample of 3.8 standard deviations made δ 0.60
    # (0.008 without it), while otherwise (four plants, seeds 0-4, records of 300 and 1000 samples) lengthening the
    # window from "auto" to the whole fitting part moved δ by a factor of at most 1.8, either way
    longer = (f"what may lower it: {longer}; a larger σ, if the noise is larger than σ = {float(unf.sigma):.3g} "
              f"(what σ leaves of the residual is charged to the uncertainty: a smaller σ raises {name})")
    refit = "what may lower it: P̂ refitted at another horizon, or on a longer or richer record"
    if cop is not None:
        if cop.decided_by == "in sample" and cop.in_sample is not None:
            other = (f", above the held-out record's ε = {cop.held_out.epsilon:.3g}"
                     if cop.held_out is not None and cop.held_out.held_out else "")
            return f"ε comes from P̂'s equation error on {window}{other}", longer
        return f"ε comes from P̂'s equation error ({cop.decided_by})", refit
    relative = ""
    try:
        norm = hinf_norm(model).upper if spectral_radius(np.asarray(model.A, float)) < 1.0 else float("inf")
    except (ValueError, np.linalg.LinAlgError):
        norm = float("inf")
    if math.isfinite(norm) and norm > 0:
        relative = f", {100.0 * prem.delta / norm:.3g} % of ‖P̂‖∞ = {norm:.4g}"
    oe = prem.output_error
    if prem.decided_by.startswith("subspace"):
        other = ""
        if oe is not None and math.isfinite(prem.delta_output_error):
            other = (f", while P̂'s output error ({'held out' if oe.held_out else 'in sample'}) gives "
                     f"δ = {prem.delta_output_error:.3g}")
        return f"δ comes from (7.5) on {window}{relative}{other}", longer
    return (f"δ comes from P̂'s output error (Theorem 7.1{', held out' if oe is not None and oe.held_out else ''})"
            f"{relative}, above (7.5)'s δ = {prem.delta_subspace:.3g} on {window}", refit)


def _record(h, cz, ratio, c, design, cert, ref_cert, premise_reason="", excitation=None,
            tracking="") -> SearchRecord:
    return SearchRecord(horizon=int(h), causal=bool(cz), gamma_ratio=float(ratio), w3_gain=float(c),
                        gamma=float(design.gamma), gamma_min=float(design.gamma_min), certificate=cert,
                        reference_certificate=ref_cert, premise_reason=premise_reason, excitation=excitation,
                        tracking_reason=tracking)


def _predictor_at(h: int, u, y, predictor, predictor_for):
    if predictor_for is not None:
        p = predictor_for(h)
    elif predictor is None:
        with warnings.catch_warnings():
            warnings.simplefilter("error", synthesis.PersistenceWarning)
            p = synthesis.fit_predictor(u, y, h)
    else:
        raise DataError(f"horizon {h} needs a predictor: pass predictor_for=lambda h: fit_predictor(u_long, y_long, h)")
    if int(p.horizon) != int(h):
        raise DataError(f"predictor_for({h}) returned a predictor of horizon {p.horizon}")
    return p

