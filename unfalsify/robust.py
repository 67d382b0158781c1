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

Theorem 3.7's guarantee is the finite-horizon one of Chapter 3 for the predictor; it does not
transfer by itself to the receding-horizon LTI controller (5.3)–(5.4) (measured on the servo,
i = 20, W11/W21: at ``c = 0.5`` the LTI loop's ``‖K(I+PK)⁻¹‖∞`` was 10 against the
finite-horizon promise ``γ/c = 3.4``).  So :func:`robust_design_from_data` certifies the loop it
ships on the data-based model P̂ (:mod:`unfalsify.certify`: stability, a *proven* small-gain
bound, a performance floor), searches the design family when the first design fails (the search and
its judge: :mod:`unfalsify.search`), and says so (:class:`NotCertifiedWarning`) when nothing
certifies.  With a plant model in hand, :func:`additive_robustness` checks a loop the same way
(proven upper bound of ``‖K(I + PK)⁻¹‖∞``).
"""
from __future__ import annotations

import functools
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import control
import numpy as np

import synthesis
from synthesis import HinfDesign, record_fingerprint
from synthesis.fingerprint import BLOCK as FINGERPRINT_BLOCK
from synthesis.validation import (DataError, as_signal, check_horizon, check_instance, check_output_moves,
                                  check_predictor_dt, check_sample_time)

from ._common import NOISE_RESOLUTION, channel_pair, check_predictor, check_sigma, samples_at_rest
from .exceptions import (FewDataWarning, NotCertifiedError, NotCertifiedWarning, SolverWarning, UnfalsificationError,
                         UntestedPremiseWarning)
from .certify import AdditiveRobustness  # noqa: F401 -- results pickled before it moved to certify name it here
from .certify import LoopCertificate
from .coprime import CoprimePremise, unconfirmed_coprime_premise
from .clipping import clipped_outputs
from .feedback import FEEDTHROUGH_STATEMENT, FeedbackTest, check_feedback
from .arx import arx_regressor
from .invariance import InvarianceTest, check_time_invariance, min_record_length
from .model import predictor_model
from .excitation import ExcitationCheck
from .options import CertificateOptions, DesignOptions, DesignSearch, EstimationOptions, _gather_options
from .premise import (HIDDEN_LINE_LIMIT, PremiseOptions, PremiseTest, _hidden_line_statement, check_premise,
                      glitch_note, operating_point_note, unconfirmed_premise, untested_premises)
# the names of this module before the design search moved to search.py (code and tests import them from here)
from .search import REFERENCE_COLUMNS, REFERENCE_HORIZON_CAP, additive_weight_fixed_point  # noqa: F401
# SearchRecord: results pickled before the split name it here
from .search import SearchRecord, _verdict_reason  # noqa: F401
from .search import (_DesignSpace, _LoopJudge, _channels, _coprime_form, _persistence_reason, _reference_model,
                     _search_designs, _size_reason, _size_source, _untested_reason)
from .solvers.base import one_blas_thread
from .subspace import SubspaceResult, _fixed_predictor, subspace_data, subspace_unfalsify
from synthesis.results import result

__all__ = ["estimate_delta", "RobustDesignResult", "robust_design_from_data"]


@result
@dataclass(frozen=True, eq=False)
class RobustDesignResult:
    """§7.4 pipeline result, with the certificate of the loop it ships.

    Attributes
    ----------
    unfalsification : SubspaceResult
        The (7.5) solution that produced δ.
    design : synthesis.HinfDesign
        The design returned: the first certified one of the search, or the requested design
        when none certifies (then ``certified`` is False and ``reason`` says why).
    delta : float
        Unfalsified δ: the solver's δ, or the larger certified δ
        (``unfalsification.certificate.delta_certified``) when its certificate fails.
    w3_gain : float
        ``c`` (``W3 = c I``) of the returned design.
    w3_rule : str
        ``"small-gain"`` (``c = (1+margin) δ γ(c)``, times the search's factor) or ``"thesis"`` (``c = 1/δ``).
    margin : float
        Relative margin of the W3 rule (the certificate's is ``certificate.margin``).
    gamma, gamma_min_a : float
        Level used and (3.64) at ``W3 = c``.
    gamma_min_nominal : float
        (3.8) for the same predictor and ``W1, W2`` without uncertainty.
    covered_delta : float
        ``c/γ``: what Theorem 3.7's *finite-horizon* argument covers.  Not a statement about
        the LTI loop; :attr:`certified` is.
    model : control.StateSpace
        The data-based nominal model P̂ (:func:`unfalsify.predictor_model` of the predictor δ
        was computed for) the loop is certified on.
    certificate : LoopCertificate
        Verdict on the returned loop ``(P̂, K)``.
    search : tuple of SearchRecord
        Every design tried, in order (the first is the requested design).
    premise : PremiseTest or None
        The premise of the certificate tested on the data (:mod:`unfalsify.premise`): δ of P̂'s output
        error by Theorem 7.1 beside δ of (7.5) (``delta`` is the larger, ``premise.decided_by`` says
        which), and P̂ against the nonparametric frequency response.  None only for results built by hand.
    premise_reason : str
        Why the data falsify (or cannot test) the premise, the predictors' persistence of excitation, time
        invariance, feedback (``feedback``) and outputs clipped in the record (:func:`unfalsify.clipped_outputs`)
        included (``''`` when they do not).
    excitation : ExcitationCheck or None
        Whether the data determine the plant where the returned loop is sensitive.
    tracking_reason : str
        Why the returned loop does not keep its steady-state tracking floor for every static perturbation
        of P̂ in the certified ball (``''`` when it does).
    reference_model : control.StateSpace or None
        A second data-based model ``P̂_ref`` (the predictor model at ``reference_horizon``): the same
        certificate must hold on it too.  A short horizon gives a coarse ARX model whose own error can
        exceed δ near the peak of ``|K(I+P̂K)⁻¹|``, and over a short horizon a slow mode that flips or
        shrinks the plant's DC gain is invisible; a longer one exposes both.  None when no reference
        predictor could be had (see ``reference_note``).
    reference_horizon : int or None
        The horizon of ``P̂_ref``: ``CertificateOptions.reference_horizon`` when given, else the longest
        horizon the fitting record supports with :data:`unfalsify.REFERENCE_COLUMNS` columns per
        regressor (at most :data:`unfalsify.REFERENCE_HORIZON_CAP`, at least 2i; 2i when the record's
        length is unknown or the longer predictor is not persistently exciting).  None on results made
        before it was recorded.
    reference_certificate : LoopCertificate or None
        The verdict on ``(P̂_ref, K)``.
    reference_note : str
        Why there is no reference model (``''`` when there is one).
    uncertainty : {"additive", "coprime"}
        The family the certificate speaks of (``CertificateOptions.uncertainty``): ``P̂ + Δ`` with
        ``‖Δ‖∞ ≤ (1 + certificate.margin)·delta``, or ``(M̂ + Δ_M)⁻¹(N̂ + Δ_N)`` with
        ``‖[Δ_N Δ_M]‖∞ ≤ (1 + certificate.margin)·epsilon`` (the certificate's margin, not the W3 rule's ``margin``).
        The design is sized by ``delta`` either way.
    coprime : CoprimePremise or None
        The coprime-factor premise (ε by Theorem 7.1 on the equation error, in sample and held out, each with
        its certificate; the gap to the data's estimates), when it was tested.
    additive_reason : str
        Why ``uncertainty="auto"`` left the additive form (the data refute its premise); ``''`` otherwise.
        :attr:`reason` repeats it when the coprime form does not certify either.
    assumed : tuple of str
        What the certificate assumes that these data cannot test (:func:`unfalsify.untested_premises`: an input channel
        with two values, or 0 and ±a, up to noise, cannot show a saturation or a dead zone; one time-invariant plant
        when ``invariance`` is None: no record given is long enough to test it; and one plant for the fitting data and
        a ``validation`` record when the two could not be compared or Chow's test of the two rejects one model).  A
        loop certified with a non-empty ``assumed`` holds for the plant only as far as these statements do; with
        ``CertificateOptions(untested="refuse")`` a non-empty ``assumed`` refuses the certificate instead.
    invariance : InvarianceTest or None
        Chow's test of time invariance (:func:`unfalsify.check_time_invariance`) on the longest record the
        pipeline has: the whole record with ``window=``, else the validation record, else the window.  A rejection
        refuses the certificate (``premise_reason``).  None where that record is too short
        (``invariance_note`` says so).  When the pipeline holds out the record's last third itself, the record is
        also tested at that boundary (``split=``: P̂ fitted before it and tested after it speaks of two plants if
        the plant changed there); this field is then the test that rejected, or the halves' test.
    invariance_note : str
        Why time invariance was not tested (``''`` when it was).
    feedback : FeedbackTest or None
        :func:`unfalsify.check_feedback` on the same record: whether its input depends on the output's noise (a
        closed-loop record).  Detected, it is stated in ``assumed``; when the input is largely the loop's response
        to that noise the certificate is refused (``premise_reason``).  None where the record is too short.
    window : tuple of int or None
        Record mode (``window=``): the samples ``[start, stop)`` of the record that form the (7.5) window;
        None when ``u, y`` were the window itself.
    hidden_line_gain : float
        ``X``: the loop gain of the largest narrow line the longest record could hide below the narrow-line test's
        threshold (:func:`unfalsify.hidden_line_gain`, for the returned loop; inf where the record is too short for
        the test).  From :data:`unfalsify.HIDDEN_LINE_LIMIT` on (a loop stable on P̂) ``assumed`` states that
        ``P − P̂`` has no such mode; NaN on results made before it was measured.
    hidden_line_frequency : float
        The frequency where ``X`` is reached (NaN without).
    size_reason : str
        When no design certifies and the size of the uncertainty is what refuses: δ (ε) with where it came from
        (the (7.5) window, P̂'s output error) and what lowers it, and why it is too large -- designs of the search
        that are stable and track on P̂ (and P̂_ref) but fail only the checks that grow with δ, with the largest δ
        one of them tolerates, or an additive ball holding a plant of singular DC gain, which no controller makes
        track.  :attr:`reason` starts with it.  ``''`` otherwise (and on results made before it was added).
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
    model: control.StateSpace
    certificate: LoopCertificate
    search: tuple
    reference_model: control.StateSpace | None = None
    reference_certificate: LoopCertificate | None = None
    reference_note: str = ""
    premise: PremiseTest | None = None
    premise_reason: str = ""
    excitation: ExcitationCheck | None = None
    tracking_reason: str = ""
    uncertainty: str = "additive"
    coprime: CoprimePremise | None = None
    additive_reason: str = ""
    assumed: tuple = ()
    invariance: InvarianceTest | None = None
    invariance_note: str = ""
    window: tuple | None = None
    feedback: FeedbackTest | None = None
    hidden_line_gain: float = float("nan")
    hidden_line_frequency: float = float("nan")
    reference_horizon: int | None = None
    size_reason: str = ""

    @property
    def controller(self) -> control.StateSpace:
        """The LTI controller (inputs ``[r; y]``, output ``u``)."""
        return self.design.controller

    @property
    def certified(self) -> bool:
        """The returned loop is certified on P̂ and on P̂_ref (stable, proven small gain, performance floor)
        and the data do not falsify the premise (output error, frequency response, excitation where the
        loop is sensitive, persistence of excitation, time invariance over the record)."""
        return not self.reason

    @property
    def reason(self) -> str:
        """Why the loop is not certified (``''`` when it is): :attr:`size_reason` first when there is one, then why the
        returned (requested) design is refused."""
        why = _with_form(_verdict_reason(self.certificate, self.reference_certificate, self.premise_reason,
                                         self.excitation, self.tracking_reason), self.additive_reason)
        return f"{self.size_reason}; the requested design: {why}" if why and self.size_reason else why

    @property
    def premise_note(self) -> str:
        """Whether the data confirm the ball this result's certificate is a theorem about: ``''`` when they do,
        otherwise the statement that the plant is assumed inside it, not shown to be.  Additive form: ``(1 + margin)·δ``
        around P̂ with the certificate's margin and the data's confidence regions of ``P − P̂``
        (:func:`unfalsify.unconfirmed_premise`); coprime-factor form: ``(1 + margin)·ε`` around P̂'s factors and the
        regions of ``M̂P − N̂`` (:func:`unfalsify.unconfirmed_coprime_premise`).  The premise tests refuse only on
        evidence against the ball, so a certified result can carry this note: its loop passed the test against the
        regions themselves, but its δ (ε) names a ball the plant may lie outside (measured, 2026-11-29:
        ``‖P − P̂‖∞/δ`` up to 4.3 on certified records of known plants; in coprime form, a loop unstable on a plant
        3.8–9.1 ε from the family)."""
        # the certificate's own margin (``certificate.margin``), not the W3 rule's (``margin``)
        if self.uncertainty == "coprime":
            # the coprime form's ball is as unconfirmed as the additive one (a coprime result had said nothing:
            # measured, a loop certified in that form was unstable on a plant 3.8–9.1 ε from the family)
            if self.coprime is None:
                return ""
            return unconfirmed_coprime_premise(self.coprime, (1.0 + self.certificate.margin) * self.coprime.epsilon)
        if self.premise is None:
            return ""
        return unconfirmed_premise(self.premise, (1.0 + self.certificate.margin) * self.delta)

    @property
    def epsilon(self) -> float:
        """ε of the coprime-factor family (NaN when that form was not tested)."""
        return float(self.coprime.epsilon) if self.coprime is not None else float("nan")

    @property
    def delta_subspace(self) -> float:
        """δ of (7.5) (``delta`` is the larger of it and :attr:`delta_output_error`)."""
        return float(self.premise.delta_subspace) if self.premise is not None else float(self.delta)

    @property
    def delta_output_error(self) -> float:
        """δ of P̂'s output error by Theorem 7.1 (NaN when it could not be computed)."""
        return self.premise.delta_output_error if self.premise is not None else float("nan")

    @property
    def small_gain(self) -> float:
        """``δ · ‖K(I + P̂K)⁻¹‖∞`` with the proven upper bound of the norm (the larger of P̂ and P̂_ref)."""
        ref = self.reference_certificate
        return max(self.certificate.small_gain, ref.small_gain if ref is not None else 0.0)

    @property
    def covers_delta(self) -> bool:
        """Same as :attr:`certified`: δ is covered only when the implemented loop is certified."""
        return self.certified


def _with_form(reason: str, additive_reason: str) -> str:
    """A coprime-form refusal, with why the additive form was left before it."""
    if not reason or not additive_reason:
        return reason
    return (f"in coprime-factor form: {reason}; the additive form was not used: premise not supported by the data: "
            f"{additive_reason}")


def _window_residual_rms(u, y, i: int, predictor) -> tuple[float, int, int, float]:
    """rms of ``R = Y_f − L [W_p; U_f]`` on the window (L: the given predictor, or least squares on the window), the
    regressors and columns of ``[W_p; U_f]``, and ``‖R‖_F/‖Y_f‖_F``."""
    A, _, Yf = subspace_data(u, y, i)
    if predictor is not None:  # the problem's own check (a predictor of other channels had raised numpy's matmul error)
        L = _fixed_predictor(predictor, i, *_channels(*channel_pair(u, y)))
    else:
        L = np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T
    R = Yf - L @ A
    norm = float(np.linalg.norm(R))
    return norm / np.sqrt(R.size), A.shape[0], A.shape[1], norm / max(float(np.linalg.norm(Yf)), np.finfo(float).tiny)


def _check_window(u, y, i: int, sigma: float, predictor) -> None:
    """Refuse or flag windows that make δ meaningless (before any LMI is solved)."""
    rms, rows, j, relative = _window_residual_rms(u, y, i, predictor)
    if predictor is None:
        if j <= rows:
            raise DataError(
                f"the window has j = {j} columns but the predictor estimated on it has {rows} regressors "
                f"(i(2m+l) = {rows}): it interpolates the data exactly and δ = 0 says nothing. Use a longer window "
                f"(j ≥ {3 * rows}) or pass predictor=fit_predictor(u_long, y_long, {i}) fitted on a longer record")
        if j < 3 * rows:
            warnings.warn(
                f"the window has j = {j} < 3 × {rows} columns for the {rows} regressors of the predictor estimated "
                "on it: the fit absorbs much of the noise and δ is optimistic. Use a longer window or pass a "
                "predictor fitted on a longer record (predictor=...)", FewDataWarning, stacklevel=3)
    if not relative > NOISE_RESOLUTION:
        _refuse_pure_feedback(u, y, i)
        # σ must lie below the residual rms and its budget above rounding: both cannot hold, so say why once
        raise DataError(
            f"the model fits this window to rounding (residual {relative:.2g} of the data, rms {rms:.3g}): noise-free "
            "data leave neither a model error to unfalsify nor a noise level to set σ by, and δ = 0 for every σ. "
            "Use a record with noise (in a simulation, add sensor noise, e.g. 1e-3 of the output's rms) or the "
            "record of a real experiment")
    if not sigma < rms:
        raise DataError(
            f"sigma = {sigma:.4g} is not below the residual rms {rms:.4g} of the model on this window: every "
            "residual is explained as noise and δ = 0 says nothing about the uncertainty. σ is the noise level "
            f"you assume; it must be below the residual rms (e.g. sigma = {0.5 * rms:.3g}, half of it)")


def _refuse_pure_feedback(u, y, i: int) -> None:
    """Refuse a window whose input is, to rounding, a causal linear function of the output (of its current and past i
    samples and the input's past i): a feedback record without a reference, which the predictor also fits to rounding.
    Such data say nothing of the plant (every plant fits them with the controller's inverse), and calling them
    noise-free would name the wrong cause (measured: the third-order plant under u = −y, r = 0, with noise).  When the
    fit needs the current output, noise-free open-loop data of a plant with a direct feedthrough fit the same way (u_k
    recovered from y_k): the message then names both causes."""
    u, y = as_signal(u, "u"), as_signal(y, "y")
    n = u.shape[0]
    if n <= 3 * i + 1:
        return
    past = arx_regressor(y, u, i, i)[0][i:]  # rows [u_{t−1}ᵀ … u_{t−i}ᵀ, −y_{t−1}ᵀ … −y_{t−i}ᵀ] for t ≥ i
    if not _fits_to_rounding(np.hstack([y[i:], past]), u[i:]):
        return
    within_sample = not _fits_to_rounding(past, u[i:])
    raise DataError(
        "the input is, to rounding, a causal linear function of the output on this window: the record is that of a "
        "feedback loop without a reference (u = −K·y), which every plant explains together with the controller's "
        "inverse, so these data say nothing of the plant"
        + (", or noise-free data of a plant with a direct feedthrough (u_k recovered from y_k), which leave no noise "
           "level to set σ by" if within_sample else "")
        + ". Use a reference excitation that moves the input (u = K(r − y), r a PRBS or multisine), or record in open "
        "loop" + (" with noise" if within_sample else ""))


def _fits_to_rounding(X: np.ndarray, target: np.ndarray) -> bool:
    """Does a least-squares fit on the columns of ``X`` leave ``target`` at rounding?"""
    residual = target - X @ np.linalg.lstsq(X, target, rcond=None)[0]
    size = max(float(np.linalg.norm(target)), np.finfo(float).tiny)
    return float(np.linalg.norm(residual)) <= NOISE_RESOLUTION * size


def robust_design_from_data(
    u,
    y,
    horizon: int,
    W1,
    W2,
    sigma,
    *,
    design: DesignOptions | None = None,
    certificate: CertificateOptions | None = None,
    estimation: EstimationOptions | None = None,
    premise: PremiseOptions | None = None,
    search: DesignSearch | bool | None = True,
    predictor=None,
    predictor_for=None,
    unfalsification: SubspaceResult | None = None,
    validation=None,
    window=None,
    dt=None,
    require_certified: bool = False,
    **legacy,
) -> RobustDesignResult:
    """§7.4 steps 1–5 -- δ by subspace unfalsification (7.5), a robust Theorem 3.7 design -- and a
    certificate of the LTI loop that ships.

    Theorem 3.7's guarantee is finite-horizon; it does not carry over by itself to the
    receding-horizon LTI controller (5.3)–(5.4).  So every design is checked on the implemented
    loop with the data-based model ``P̂`` (:func:`unfalsify.predictor_model`) -- and with a
    reference model ``P̂_ref`` at a longer horizon when one can be had -- by
    :func:`unfalsify.certify_loop`: the loop stable, ``δ·‖K(I+P̂K)⁻¹‖∞ ≤ 1/(1 + certificate_margin)``
    proven, and a step that tracks (the performance floor).  When the first design does not
    certify, the design family :class:`DesignSearch` is searched; the first certified design is
    returned, and every design tried is reported in ``result.search``.

    What is certified: every plant ``P̂ + Δ`` with ``Δ`` stable and ``‖Δ‖∞ ≤ (1 + certificate_margin)δ``
    is stabilised (and likewise around ``P̂_ref``).  The true plant is among them under the *premise* that
    its deviation from ``P̂`` is at most that large.  No finite record proves the premise; the pipeline
    tests it on the data before it certifies (:mod:`unfalsify.premise`) and refuses, with the reason and
    the fix, when the data falsify it or cannot test it:

    * δ is the larger of δ of (7.5) and δ of P̂'s *output error* ``y − P̂u`` by Theorem 7.1 (two-sided
      certificate, stated noise level), on ``validation`` data not used to fit P̂ when given;
    * P̂ must lie within δ of the confidence region of a nonparametric (Welch) frequency response
      over the band the input excites;
    * the data must determine the plant where the loop is sensitive: at every Welch frequency
      ``(|P̂ − Ĝ| + r)·|K(I+P̂K)⁻¹| < 1`` (``r`` the confidence radius, large where the input is silent);
    * P̂'s output error over the longest record (the whole record in record mode) must show no narrow line where
      the loop is sensitive, ``‖Ê‖/‖Û‖·σ̄(M̂) < 0.2`` (:func:`unfalsify.residual_line`; any number of channels, P̂
      stable or not, in both forms of the uncertainty): a lightly damped mode that P̂ misses is far narrower than
      the Welch resolution, and is seen only there;
    * the predictors' data must be persistently exciting (a ``PersistenceWarning`` means not certified).

    What the data cannot test is stated in ``result.assumed`` (:func:`unfalsify.untested_premises`) and, for a certified
    loop, warned (:class:`UntestedPremiseWarning`): an input with two values, or 0 and ±a (up to noise), shows no static
    input nonlinearity (a saturation acts on it as a gain), so the certificate then assumes the plant linear at the
    amplitudes the loop will use; records all shorter than :func:`unfalsify.min_record_length` (336 samples for one
    input and one output) cannot show a plant that changes during the experiment, so the certificate then assumes one
    time-invariant plant; and P̂'s output error tested in sample -- without ``validation``, or on a ``validation``
    record that shares samples with the data P̂ was fitted on (found by :attr:`synthesis.Predictor.fingerprint`,
    ``result.premise.validation_shared``) -- can miss a bias of P̂ that held-out data would show.  A ``validation``
    record is compared with the fitting data (the whole record with ``window=``, else the window) by
    ``check_time_invariance(against=)``: a rejection, or a record too short for the comparison (a window of fewer than
    168 samples for one input and one output), is stated -- the certificate then assumes that the plant did not
    change between the two experiments, which neither record alone shows.  No record excludes a
    lightly damped mode whose line stays below its noise: ``result.hidden_line_gain`` is the loop gain such a line
    could carry (:func:`unfalsify.hidden_line_gain`), and from :data:`unfalsify.HIDDEN_LINE_LIMIT` = 1 on (beyond
    what the small-gain condition covers) ``assumed`` states that the plant has no such mode there.

    **Coprime-factor form** (``CertificateOptions.uncertainty``, default ``"auto"``).  For an integrating plant
    ``‖P − P̂‖∞`` is infinite, so the additive premise is false and the data refute it.  ``"auto"`` then
    certifies in the family ``(M̂ + Δ_M)⁻¹(N̂ + Δ_N)``, ``‖[Δ_N Δ_M]‖∞ ≤ (1 + margin)ε``, around the FIR factors
    ``P̂ = M̂⁻¹N̂`` of the predictor's first row (:mod:`unfalsify.coprime`), with the premise tested in its own
    terms: ε is the larger of Theorem 7.1 on the equation error ``M̂y − N̂u`` (input ``[u; y]``) on the window
    at the σ of (7.5) and on the held-out record with the noise estimated, each with its two-sided
    certificate; the data's estimate of ``M̂P − N̂`` must lie within ε of the family at every excited
    frequency; the loop needs ``ε‖[K; I](M̂ + N̂K)⁻¹‖∞ ≤ 1/(1 + margin)`` proven (pencil test and bounded-real
    matrix) on P̂ and P̂_ref, the same frequency-wise excitation test, and tracking at every static plant of
    the ball.  ``result.uncertainty`` says which family is certified, ``result.epsilon`` its size and
    ``result.additive_reason`` why the additive form was left.  The design is sized by δ either way.

    Parameters
    ----------
    u, y : array_like, shape (n,) or (n, m) and (n, l)
        Experiment data (step 1), time along axis 0, any numbers of inputs m and outputs l: the (7.5)
        window, ``n = 2i + j − 1`` samples -- or, with ``window=``, the whole record.  With several
        channels every norm is the largest singular value: δ bounds ``‖Δ‖∞`` of an l × m additive Δ,
        the small gain is ``δ·σ̄``-based (``‖K(I+P̂K)⁻¹‖∞``), the weights are l × l (W1) and m × m (W2)
        (:func:`synthesis.diagonal_weight`), each reference channel is stepped alone and the tracking
        floor may be given per output channel (``CertificateOptions.tracking_floor``).
    horizon : int
        i, for both (7.5) and the design.  Choose i above the plant's order and long enough to see its
        slowest relevant dynamics and any right-half-plane zero: the law is a finite-horizon game over i
        samples, and a short horizon can destabilise a non-minimum-phase plant (measured: on a
        non-minimum-phase plant at 10 Hz the i = 10 design is unstable on the true plant in every seed, its
        controller with an unstable pole at 1.20 -- not on the zero at 1.11 --,
        while the search's i = 20 certifies; a 4th-order plant at 50 Hz with i = 15 -- 0.3 s -- missed a
        slow mode).  The (7.5) window needs ``j`` well above the ``i(2m + l)`` regressors when the
        predictor is estimated on it (``window="auto"`` takes ``j = 3 i(2m + l)``), and its cost grows like
        ``j·i^2.5`` (:func:`solve_estimate`).
    W1, W2 : weights
        Performance weights, as for :func:`synthesis.hinf_design` (step 2).
    sigma : float or "auto"
        Admissible rms noise level of (7.5) (step 2); a positive number below the residual rms
        of the model on the window.  ``"auto"``: half that residual rms (the rule of our
        experiments: half of what the model leaves unexplained is called noise, the rest must be
        explained by Δ).
    design : DesignOptions, optional
        The first design: level ``gamma_ratio``, W3 rule and its ``margin``, causal law (step 4).
    certificate : CertificateOptions, optional
        The loop certificate: its margin (default 0.25), performance floor, reference model.
    estimation : EstimationOptions, optional
        How (7.5) is solved: ``form``, ``backend`` (default ``"structured"`` for the conditioned form:
        faster, O(i²j) memory), cvxpy ``solver`` and its options.
    search : DesignSearch, bool or None
        The design family searched when the first design does not certify (True: the default
        :class:`DesignSearch`; False/None: no search).
    predictor : synthesis.Predictor, optional
        A fixed predictor of horizon i (e.g. least squares on a longer record): δ is computed for
        this model (L fixed in (7.5)), the design and P̂ use it.  Default: the ``(L_w, L_u)`` found
        by (7.5) jointly with δ.
    predictor_for : callable, optional
        ``horizon -> Predictor`` for the search's other horizons (e.g.
        ``lambda h: fit_predictor(u_long, y_long, h)``).  Without it the search fits them by least
        squares on ``(u, y)`` when ``predictor`` is None, and skips them otherwise.
    unfalsification : SubspaceResult, optional
        Reuse a (7.5) solution (:func:`estimate_delta`) instead of solving again (same data).
    dt : float, optional
        The data's sample time; the weights' must equal it (``WeightError`` otherwise).  Default:
        the weights' common sample time.
    require_certified : bool
        Raise :class:`NotCertifiedError` instead of warning when nothing certifies.
    validation : tuple of array_like, optional
        ``(u_v, y_v)``: a record of the same plant *not used to fit the predictors* (e.g. the end of
        the experiment), on which P̂'s output error is unfalsified.  Without it the window itself is
        used (in sample: optimistic; ``result.premise.output_error.held_out`` is False).  With ``window=``
        the whole record is compared with it (Chow's test of the two records); without, the window is,
        which is usually too short for that test (``result.assumed`` then says so).
    premise : PremiseOptions, optional
        How the premise is tested (noise level of the output-error program, confidence of the
        frequency response, sizes, time limit).
    window : slice, (start, length) or "auto", optional
        Record mode: ``u, y`` are the whole record and ``window`` picks the (7.5) window in it.  The
        last third of the record is held out for the premise test (unless ``validation`` is given);
        the window must lie in the first two thirds, on which the predictor of P̂ (when ``predictor``
        is None) and those of the other horizons (when ``predictor_for`` is None) are fitted by
        least squares -- no lambda needed.  ``"auto"``: ``2i + j − 1`` samples with ``j = 3·i(2m + l)``
        columns (three per regressor of the predictor), or as many as the fitting part holds, from the
        start of the record, or from i samples before the input first moves if it starts at rest.  None
        (default): ``u, y`` are the window itself.  When δ of a window is what refuses every design,
        ``result.size_reason`` says so and proposes a window twice as long.
    **legacy
        The keywords of earlier releases (``gamma_ratio``, ``margin``, ``w3_rule``, ``causal``,
        ``certificate_margin``, ``tracking_floor``, ``step_samples``, ``reference_horizon``,
        ``require_reference``, ``form``, ``solver``, ``solver_options``, ``backend``) still work: each
        sets the field of its option object.

    BLAS runs on one thread during the call (threadpoolctl; the configured count is restored after): its many
    small dense operations ran 2.2 times slower with OpenBLAS's two threads (measured on 2 cores: a record-mode
    design of a 1500-sample record at i = 8, 14 s against 6.5 s).

    The steps can be run one by one: :func:`estimate_delta` (data checks and δ of (7.5)),
    :func:`unfalsify.predictor_model` (P̂), :func:`unfalsify.check_premise` (δ of the output error, the
    frequency-response tests), :func:`unfalsify.check_time_invariance` (one plant over the record),
    :func:`unfalsify.certify_loop` and :func:`unfalsify.check_excitation` (the loop).
    Returns
    -------
    RobustDesignResult

    Raises
    ------
    DataError
        Bad data, weights, σ (not a positive number, or not below the window's residual rms),
        a window with no more columns than the predictor estimated on it has regressors.
    UnfalsificationError
        (7.5) did not produce a finite δ.
    NotCertifiedError
        ``require_certified=True`` and no design certifies.

    Warns
    -----
    NotCertifiedWarning
        No design of the search certifies; ``result.certified`` is False and ``result.reason``
        says why (nominal loop unstable on P̂, small gain, performance floor).  When the size of δ is what
        refuses, ``result.size_reason`` leads it: δ, where it came from (the (7.5) window or P̂'s output
        error) and what lowers it (measured: the docstring's FIR record of 300 samples at seed 0 gives
        δ = 0.60 on ``window="auto"``'s 32 samples, 0.014–0.028 from 45 samples on).
    FewDataWarning
        j < 3 × the regressors of a predictor estimated on the window.
    SolverWarning
        The (7.5) answer is not certified: δ is raised to the certified value.

    Examples
    --------
    A FIR plant at horizon i = 3 on a 45-sample window (j = 39), the predictor fitted on the whole record:

    >>> import warnings
    >>> import numpy as np
    >>> import synthesis as sy
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(300)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:300] + 0.01 * rng.standard_normal(300)
    >>> pred = sy.fit_predictor(u, y, 3)
    >>> W1 = sy.makeweight(10.0, (0.3, 1.0), 0.5, 1.0)
    >>> W2 = sy.makeweight(0.1, (2.0, 0.3), 1.0, 1.0)
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore")                    # NotCertifiedWarning if no design certifies
    ...     rd = robust_design_from_data(u[:45], y[:45], 3, W1, W2, "auto", predictor=pred,
    ...                                  predictor_for=lambda h: sy.fit_predictor(u, y, h), dt=1.0)
    >>> bool(rd.delta > 0), isinstance(rd.certified, bool), len(rd.search) >= 1
    (True, True, True)
    >>> bool(rd.delta >= rd.unfalsification.delta * (1 - 1e-9))       # δ of (7.5), or the larger premise δ
    True
    """
    design, certificate, estimation = _gather_options(design, certificate, estimation, legacy)
    search = _search_family(search)
    if premise is not None:
        check_instance(premise, PremiseOptions, "premise",
                       "a PremiseOptions (e.g. PremiseOptions(samples=400)) or None")
    predictor = check_predictor(predictor)
    if predictor_for is not None:
        check_instance(predictor_for, Callable, "predictor_for",
                       "a callable horizon -> Predictor (e.g. lambda h: synthesis.fit_predictor(u_long, y_long, h)) "
                       "or None")
    # many small BLAS calls: OpenBLAS's other threads cost more than they bring (measured on 2 cores: a
    # record-mode design of a 1500-sample record at i = 8 took 14 s with two threads, 6.5 s with one)
    with one_blas_thread():
        whole = (u, y) if window is not None else None
        held_out_here = window is not None and validation is None  # record mode holds out the record's last third
        span = None
        if window is not None:
            u, y, validation, predictor, predictor_for, span = _record_mode(u, y, horizon, window, validation,
                                                                            predictor, predictor_for)
        i = check_horizon(horizon, np.asarray(u).shape[0] if np.ndim(u) else 0)
        if predictor is not None and int(predictor.horizon) != i:
            raise DataError(f"predictor has horizon {predictor.horizon}, but the design's horizon is {i}: fit it at "
                            f"the design's horizon (synthesis.fit_predictor(u, y, {i})) or pass horizon="
                            f"{predictor.horizon}")
        _warn_few_columns(predictor)
        unf = unfalsification
        if unf is None:
            unf = estimate_delta(u, y, i, sigma, predictor=predictor, estimation=estimation)
        elif unf.horizon != i:
            raise DataError(f"the given unfalsification has horizon {unf.horizon}, not {i}")
        pred = _model_predictor(unf, predictor)
        # a predictor fitted with dt= knows the data's sample time: prefer it to the weights' (hinf_design does too)
        model = predictor_model(pred, _data_dt(check_predictor_dt(pred, dt), W1, W2))
        # the longest contiguous record holding the window: its low band reaches below the held-out record's
        # (refutes only)
        contiguous = whole or ((u, y) if validation is not None else None)
        prem = check_premise(model, u, y, i, _delta_of(unf), dt=float(model.dt), validation=validation,
                             fitted_on=_fitted_on(predictor, u, y, validation), options=premise or PremiseOptions(),
                             record=contiguous)
        delta = prem.delta
        if design.w3_rule == "thesis" and delta == 0:
            raise DataError("w3_rule='thesis' needs δ > 0 (W3 = 1/δ)")
        space = _DesignSpace(u, y, pred, predictor, predictor_for, W1, W2, delta, design, dt)
        ref_model, ref_note, ref_reason = _reference_model(space, certificate, i, float(model.dt))
        persistence = _persistence_reason(pred, u, i, "predictor of P̂")
        cop, ball, form_reason = _coprime_form(certificate, prem, pred, model, u, y, unf, validation, premise, space,
                                               ref_model, persistence, contiguous)
        additive_reason = prem.reason if ball is not None and certificate.uncertainty == "auto" else ""
        record = whole or _longest(u, y, validation)
        split = _held_out_start(np.shape(record[0])[0]) if held_out_here else None
        invariance, invariance_note = _time_invariance(record, split)
        across = _across_records(whole or (u, y), None if held_out_here else validation, whole is not None)
        feedback = check_feedback(*record, feedthrough=certificate.feedthrough)
        assumed = (untested_premises(u, validation) + _in_sample(prem)
                   + (_untested_invariance(*record, whole is not None) if invariance is None else ()) + across
                   + ((feedback.statement,) if feedback is not None and feedback.detected else ())
                   + ((FEEDTHROUGH_STATEMENT,) if certificate.feedthrough else ()))
        untested_reason = _untested_reason(assumed) if certificate.untested == "refuse" else ""
        premise_reason = "; ".join(r for r in (form_reason, persistence, ref_reason, untested_reason,
                                               invariance.reason if invariance is not None else "",
                                               feedback.reason if feedback is not None else "",
                                               clipped_outputs(record[1]))
                                   if r)
        judge = _LoopJudge(model, ref_model, ref_note, prem, premise_reason, delta, certificate, ball,
                           line_record=(*record, i))
        if premise_reason or judge.missing is not None:
            search = None  # the data falsify (or cannot test) the premise, or no reference: no design can fix that
        chosen, c, rec, records, designs = _search_designs(space, judge, search, i)
        size_reason = ""
        if not rec.certified:
            tried = len(records)
            size = f"δ = {delta:.4g}" if ball is None else f"coprime-factor ε = {ball.eps:.4g}"
            fit_samples = None
            if whole is not None:
                n_whole = int(np.shape(whole[0])[0])
                fit_samples = _held_out_start(n_whole) if held_out_here else n_whole
            source = _size_source(prem, unf, model, i, span, fit_samples, cop if ball is not None else None)
            size_reason = _size_reason(judge, records, designs, delta if ball is None else ball.eps,
                                       "δ" if ball is None else "ε", *source)
            notes = [n for n in (operating_point_note(*record), glitch_note(model, *record, i)) if n]
            msg = (f"the §7.4 loop is NOT certified for {size}: "
                   + (f"{size_reason}; the requested design: " if size_reason else "")
                   + _with_form(rec.reason, additive_reason)
                   + (f"; none of the {tried} designs searched certifies" if tried > 1 else "; no search was made")
                   + "".join(f"; note: {n}" for n in notes))
            if require_certified:
                raise NotCertifiedError(msg)
            warnings.warn(msg, NotCertifiedWarning, stacklevel=2)
        hidden, hidden_freq = judge.hidden_gain(chosen.controller)
        if hidden >= HIDDEN_LINE_LIMIT and rec.certificate.stable:  # an unstable loop's channel bounds nothing
            assumed = assumed + (_hidden_line_statement(hidden, hidden_freq, float(model.dt)),)
        if rec.certified and assumed:
            warnings.warn("the §7.4 loop is certified on a premise these data cannot test: " + "; ".join(assumed),
                          UntestedPremiseWarning, stacklevel=2)
        g_nom = synthesis.gamma_min(chosen.predictor, W1, W2, causal=chosen.causal, dt=dt)
        return RobustDesignResult(
            unfalsification=unf, design=chosen, delta=delta, w3_gain=float(c), w3_rule=design.w3_rule,
            margin=float(design.margin), gamma=float(chosen.gamma), gamma_min_a=float(chosen.gamma_min),
            gamma_min_nominal=float(g_nom), covered_delta=float(c / chosen.gamma if chosen.gamma > 0 else np.inf),
            model=model, certificate=rec.certificate, search=tuple(records), reference_model=ref_model,
            reference_certificate=rec.reference_certificate, reference_note=ref_note, premise=prem,
            premise_reason=premise_reason, excitation=rec.excitation, tracking_reason=rec.tracking_reason,
            uncertainty="additive" if ball is None else "coprime", coprime=cop, additive_reason=additive_reason,
            assumed=assumed, invariance=invariance, invariance_note=invariance_note, window=span, feedback=feedback,
            hidden_line_gain=float(hidden), hidden_line_frequency=float(hidden_freq),
            reference_horizon=space.reference_horizon, size_reason=size_reason)


def _fitted_on(predictor, u, y, validation):
    """What P̂ was fitted on: the given predictor's record (None when it carries no fingerprint), else the window,
    on which (7.5) finds the predictor together with δ; None without ``validation`` (nothing to check it against).
    A window is often shorter than two of the fingerprint's blocks, so its blocks are a quarter of it (at least 16
    samples): sixteen samples of every channel do not repeat by chance in a record with noise."""
    if validation is None:
        return None
    if predictor is not None:
        return getattr(predictor, "fingerprint", None)
    n = np.shape(u)[0]
    return record_fingerprint(u, y, block=min(FINGERPRINT_BLOCK, max(n // 4, 16)))


def _in_sample(prem: PremiseTest) -> tuple[str, ...]:
    """The premise stated when P̂'s output error was not tested on held-out data (nothing when it was, or when the
    test did not run: the premise is then refused)."""
    oe = prem.output_error
    if oe is None or oe.held_out:
        return ()
    fix = ("pass validation=(u_v, y_v), a record not used for fitting, or the whole record with window= (the "
           "pipeline then holds out its last third)")
    if prem.validation_shared > 0:
        return (f"the validation record is not held out: at least {100 * prem.validation_shared:.3g} % of its samples "
                "are in the data P̂ was fitted on, so P̂'s output error was tested in sample, where a bias of P̂ that "
                f"held-out data would show can hide; {fix}",)
    return ("P̂'s output error was tested on the (7.5) window, not on held-out data, where a bias of P̂ that "
            f"held-out data would show can hide; {fix}",)


def _longest(u, y, validation) -> tuple:
    """The longer of the window and the validation record."""
    if validation is not None and np.shape(validation[0])[0] > np.shape(u)[0]:
        return tuple(validation)
    return u, y


def _time_invariance(record, split: int | None = None) -> tuple[InvarianceTest | None, str]:
    """:func:`check_time_invariance` of ``(u, y)``, or None and why it could not run (a record too short).

    With ``split`` (where record mode's held-out part begins) the record is tested there too, each test at the
    level: the halves dilute a change that lies near the held-out boundary, which is the change that matters to
    a P̂ fitted before it and tested after it (a gain stepping 1 → 1.5 at 720 of 1200 samples: p = 0.004 on the
    halves, 1e-4 at 800, and a loop certified that lacked its δ margin on the plant after the step; measured,
    a script).  On the adversarial catalogue's 480 LTI records (seeds 0–9) no p-value at the boundary fell below
    0.009, so the two tests' false-rejection rate stays that of the halves' (module :mod:`unfalsify.invariance`)
    plus at most the level.  A part too short for the test at the boundary leaves the halves' test alone."""
    try:
        halves = check_time_invariance(*record)
    except DataError as exc:
        return None, f"time invariance not tested: {exc}"
    if split is None or halves.rejected:
        return halves, ""
    try:
        boundary = check_time_invariance(*record, split=split)
    except DataError:
        return halves, ""
    return (boundary if boundary.rejected else halves), ""


def _across_records(fitting, validation, whole: bool) -> tuple[str, ...]:
    """The statement for ``assumed`` when a validation record given by the caller is not shown to come from the plant
    of the fitting data (``fitting``: the whole record with ``window=``, else the window): Chow's test of the two
    records (:func:`check_time_invariance` with ``against=``) rejects one model for both, or a record is too short.

    Neither record alone shows a plant that changed between the two experiments, and P̂'s output error on the
    validation record shows it only where the validation input excites the change.  With a window of 49 samples
    and a validation record of 480 (the adversarial catalogue's validation protocol), a plant whose poles moved
    ×0.6 at the start of the validation record, and one whose gain stepped 1 → 1.5 80 samples into it, were
    certified without their δ margin on the new plant (seed 0); given the whole record with ``window=`` the
    pipeline refused both (its held-out boundary test), and the test of the 720-sample fitting record against
    the validation record rejects 57 of 60 such abrupt changes (seeds 0–9; measured, a script).  Stated rather than
    refused: a rejection also comes from two inputs of different bands (an output-error plant's ARX(16) fit depends
    on the input's spectrum: 18 of 270 LTI record pairs with different inputs fell below the level, 1 of 500 with
    alike ones)."""
    if validation is None:
        return ()
    fu, fy = as_signal(fitting[0], "u"), as_signal(fitting[1], "y")
    vu = as_signal(validation[0], "validation u")
    need = min_record_length(fy.shape[1], fu.shape[1]) // 2
    if min(fu.shape[0], vu.shape[0]) < need:
        fix = ("record a longer fitting or validation record" if whole else
               "pass the fitting record with window= beside validation=, and the pipeline compares the two; or, if "
               "they are one experiment, the whole record with window= alone, whose held-out boundary is then tested")
        return (f"one plant made the fitting data and the validation record: they were not compared, as Chow's test of "
                f"two records needs {need} samples in each and the {'record' if whole else 'window'} has "
                f"{fu.shape[0]}, the validation record {vu.shape[0]}; a plant that changed between the experiments "
                f"shows only where P̂'s output error on the validation record sees it ({fix})",)
    test = check_time_invariance(fu, fy, against=tuple(validation))
    if not test.rejected:
        return ()
    return ("one plant made the fitting data and the validation record, although Chow's test rejects one "
            f"ARX({test.order}) model for both (p = {test.p_value:.2g} < {test.level:g}): the plant changed between "
            "the experiments, or their inputs differ in band (an ARX fit of a plant with output noise depends on the "
            "input's spectrum); with alike inputs, refit on records of the plant as it is now",)


def _held_out_start(n: int) -> int:
    """The sample where record mode's held-out part of an ``n``-sample record begins (:func:`_record_mode`)."""
    return n - int(n * HELD_OUT_FRACTION)


def _untested_invariance(u, y, whole: bool) -> tuple[str]:
    """The statement for ``assumed`` when the longest record is too short for :func:`check_time_invariance`
    (``whole``: it is the whole record of record mode, so only a longer experiment helps)."""
    u, y = as_signal(u, "u"), as_signal(y, "y")
    n, m, l = u.shape[0], u.shape[1], y.shape[1]
    need = min_record_length(l, m)
    fix = (f"record at least {need} samples" if whole else
           f"pass validation=(u_v, y_v) of {need} samples or more, or the whole record with window=")
    return (f"one time-invariant plant made the data: the longest record given ({n} samples) is too short for the "
            f"test of time invariance, which needs {need} with {l} output(s) and {m} input(s), so a plant or noise "
            f"that changed during the experiment would go unseen ({fix})",)


def estimate_delta(u, y, horizon: int, sigma, *, predictor=None,
                   estimation: EstimationOptions | None = None) -> SubspaceResult:
    """Step 1 of the §7.4 pipeline: check the window and solve (7.5) for δ.

    Parameters
    ----------
    u, y : array_like, shape (n,) or (n, m) and (n, l)
        The window, ``2i + j − 1`` samples, time along axis 0.
    horizon : int
    sigma : float or "auto"
        Admissible rms noise of (7.5) (``"auto"``: half the residual rms of the model on the window).
    predictor : synthesis.Predictor, optional
        Fixed ``(L_w, L_u)``; default: estimated by (7.5) jointly with δ.
    estimation : EstimationOptions, optional

    Returns
    -------
    SubspaceResult

    Raises
    ------
    DataError
        σ not a positive number below the window's residual rms; a window with no more columns than
        the predictor estimated on it has regressors; a solve too large for this machine's memory.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(80)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:80] + 0.05 * rng.standard_normal(80)
    >>> unf = estimate_delta(u, y, 3, "auto")
    >>> bool(unf.certificate.verify())
    True
    """
    # `estimation or ...` had read an empty dict as the defaults and failed on any other object deep inside
    opts = EstimationOptions() if estimation is None else check_instance(
        estimation, EstimationOptions, "estimation", "an EstimationOptions (e.g. EstimationOptions(backend='cvxpy')) "
        "or None")
    predictor = check_predictor(predictor)
    i = check_horizon(horizon, np.asarray(u).shape[0] if np.ndim(u) else 0)
    check_output_moves(channel_pair(u, y)[1], "the window")  # before σ = "auto", which a zero output makes 0
    if isinstance(sigma, str) and sigma == "auto":
        sigma = 0.5 * _window_residual_rms(u, y, i, predictor)[0]
    sigma = check_sigma(sigma)
    backend = opts.backend or ("structured" if opts.form == "conditioned" else "cvxpy")
    _check_window(u, y, i, sigma, predictor)
    return subspace_unfalsify(u, y, i, sigma, form=opts.form, predictor=predictor, solver=opts.solver,
                              solver_options=opts.solver_options, backend=backend)


def _model_predictor(unf: SubspaceResult, predictor):
    """The predictor of P̂: the given one (which (7.5) must have used), else (7.5)'s own."""
    if predictor is None:
        return unf.predictor
    if not np.allclose(np.hstack([unf.Lw, unf.Lu]), np.hstack([predictor.Lw, predictor.Lu])):
        raise DataError("the given unfalsification was not computed for the given predictor")
    return predictor


def _search_family(search) -> DesignSearch | None:
    if search is True:
        return DesignSearch()
    if search is False or search is None:
        return None
    if not isinstance(search, DesignSearch):
        raise DataError(f"search must be a DesignSearch, True or False/None, got {search!r}")
    return search


#: fraction of a record held out for the premise test in record mode (``window=``)
HELD_OUT_FRACTION = 1.0 / 3.0


def _record_mode(u, y, horizon, window, validation, predictor, predictor_for):
    """Split a whole record into the (7.5) window, a fitting part and a held-out part (``window=``).

    Returns ``(u_window, y_window, validation, predictor, predictor_for, (start, stop))``.
    """
    u_all, y_all = channel_pair(u, y)
    n = u_all.shape[0]
    m, l = _channels(u_all, y_all)
    i = check_horizon(horizon, n)
    fit_end = n if validation is not None else _held_out_start(n)
    if window == "auto":
        start = _auto_window_start(u_all, i)
        j = min(3 * i * (2 * m + l), fit_end - start - 2 * i + 1)  # three columns per regressor of the predictor
        if j < 1 and start > 0:
            raise DataError(f"the input is zero up to sample {start + i}, which leaves no (7.5) window of horizon {i} "
                            f"in the fitting part [0, {fit_end}); pass a longer record or validation=(u_v, y_v)")
        stop = start + 2 * i + j - 1
    elif isinstance(window, slice):
        start, stop, step = window.indices(n)
        if step != 1:
            raise DataError(f"window must be a contiguous slice, got step {step}")
    elif isinstance(window, tuple) and len(window) == 2:
        start, stop = int(window[0]), int(window[0]) + int(window[1])
    else:
        raise DataError(f"window must be a slice, a pair (start, length) or 'auto', got {window!r}")
    if not (0 <= start < stop <= fit_end):
        raise DataError(
            f"the window [{start}, {stop}) must lie in the fitting part [0, {fit_end}) of the {n}-sample record "
            f"(the last {n - fit_end} samples are held out for the premise test): choose an earlier or shorter "
            "window, or pass validation=(u_v, y_v) from another experiment to use the whole record for fitting")
    _check_fitting_part(fit_end - 2 * i + 1, i, m, l, n, validation is None)
    u_fit, y_fit = u_all[:fit_end], y_all[:fit_end]
    if validation is None:
        validation = (u_all[fit_end:], y_all[fit_end:])
    if predictor is None:
        predictor = _fitted(u_fit, y_fit, i)
    if predictor_for is None:
        predictor_for = functools.partial(_fitted, u_fit, y_fit)
    return u_all[start:stop], y_all[start:stop], validation, predictor, predictor_for, (start, stop)


def _check_fitting_part(j: int, i: int, m: int, l: int, n: int, held_out: bool) -> None:
    """Refuse a record whose fitting part gives the predictor no more columns than regressors: it would fit those
    samples exactly, and every later test would blame noise-free data or the window instead of the length."""
    rows = i * (2 * m + l)
    if j > rows:
        return
    need = 3 * rows + 2 * i - 1  # three columns per regressor, as window="auto" takes
    if held_out:
        need = int(np.ceil(need / (1.0 - HELD_OUT_FRACTION)))
    raise DataError(
        f"the record is too short for horizon i = {i}: its fitting part gives the predictor j = {max(j, 0)} columns "
        f"for its i(2m + l) = {rows} regressors, so it would fit those samples exactly; record at least {need} samples"
        f"{' (the last third is held out)' if held_out else ''}, or lower the horizon")


def _auto_window_start(u: np.ndarray, i: int) -> int:
    """Where ``window="auto"`` starts: i samples before the input first moves, so that the first column's future
    begins with it.  A record that starts at rest would otherwise give (7.5) columns whose outputs are all noise
    (their input is zero since the column's start), which a noise budget of half the residual cannot hold."""
    rest = samples_at_rest(u)
    return max(0, rest - i) if rest < u.shape[0] else 0


def _warn_few_columns(predictor) -> None:
    """FewDataWarning for a given predictor fitted on fewer than three columns per regressor."""
    j, rows = getattr(predictor, "n_columns", None), getattr(predictor, "n_regressors", None)
    if j is not None and rows is not None and int(j) < 3 * int(rows):
        warnings.warn(
            f"the predictor was fitted on j = {j} columns for its {rows} regressors (fewer than 3 per regressor): "
            "it absorbs much of the noise, so P̂ and δ are optimistic; fit it on a longer record "
            f"(j ≥ {3 * int(rows)}, i.e. at least {3 * int(rows) + 2 * int(predictor.horizon) - 1} samples)",
            FewDataWarning, stacklevel=3)


def _fitted(u, y, h):
    """Least-squares predictor of horizon ``h``; its rank warnings are judged by the premise test."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", synthesis.PersistenceWarning)
        return synthesis.fit_predictor(u, y, h)


def _data_dt(dt, W1, W2) -> float:
    """The data's sample time: ``dt``, else the weights' common one (1.0 when every weight is static)."""
    if dt is not None:
        # checked here: a string or an array had raised ValueError or TypeError from float()
        dt = check_sample_time(dt, "dt")
        return 1.0 if dt is True else dt  # True (unspecified) reads as 1, as float(True) did
    common = synthesis.common_dt(W1, W2)
    return 1.0 if common is True else float(common)


def _delta_of(unf: SubspaceResult) -> float:
    """δ to design for: the solver's, raised to the certified value when its certificate fails."""
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
            stacklevel=3,
        )
        if not np.isfinite(cert.delta_certified):
            raise UnfalsificationError("(7.5) returned impulses that certify no finite δ; cannot size the uncertainty")
        delta = max(delta, float(cert.delta_certified))
    return delta
