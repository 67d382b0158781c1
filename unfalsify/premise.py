"""The premise of the §7.4 certificate, tested on the data.

The loop certificate of :func:`unfalsify.robust_design_from_data` is a theorem about the set
``{P̂ + Δ : Δ stable, ‖Δ‖∞ ≤ (1 + margin)·δ}``.  It says something about the plant only under the
*premise* that the plant belongs to that set.  δ of (7.5) scores ``i``-step prediction given the
measured past outputs; smooth (band-limited) inputs make that easy while the least-squares model P̂
can be biased far beyond δ (equation-error bias, and no information at all where the input has no
power).  So the premise is tested three ways, each from the record itself:

1. **Output error, by Theorem 7.1** (:func:`output_error_unfalsify`).  P̂ is *simulated* on data not
   used to fit it wherever the record allows (``validation=``), its delay-line state started from the
   measured past; the residual ``e = y − P̂u`` must be explained as ``e = Δu + ξ`` with ``‖ξ‖₂ ≤
   σ_oe √N``.  The smallest ``‖Δ‖∞`` that does, δ_oe, is computed with the two-sided certificate of
   :func:`unfalsify.arx_unfalsify` (program (7.4) with no ARX parameters; the first ``burn_in`` rows
   are free because Δ is not at rest when the segment starts).  The admissible noise σ_oe is stated:
   by default the residual rms of a least-squares FIR fit of ``e`` on ``u``, corrected for the taps'
   degrees of freedom -- the part of the output error that no causal LTI operator of that memory
   explains.  A model error slower than that memory is partly taken for noise: the frequency-response
   tests below and the steady-state check of the pipeline look at it another way.  The loop is then designed and certified for
   ``max(δ, δ_oe)``.
2. **A nonparametric frequency response** (:mod:`unfalsify.frequency_response`): the Welch estimate
   ``D̂ = S_ue/S_uu`` of the same output error against the input -- an estimate of ``P − P̂`` that needs no
   model -- with a simultaneous confidence disk of radius ``r(ω)`` at every frequency.  Estimating the
   *difference* keeps Welch's leakage bias small where P̂ is good (a lightly damped resonance of P itself
   would bias a direct estimate of P far beyond its confidence disk).  Where the input excites the plant
   (input spectrum above ``EXCITATION_FLOOR`` × its peak) and ``|D̂| − r > δ``, P̂ is inconsistent with the
   record by more than the δ being certified: the certificate is refused and the reason names the
   frequencies.  A bin whose window gathers the input's power from one side only -- above a band-limited
   input's edge -- estimates the response *there*, not at its own frequency
   (:func:`unfalsify.leaked_bins`): its radius is infinite and it is not excited.  Below the first Welch
   frequency -- where each detrended segment is blind, and where a slow pole or an integrator that P̂ misses
   lives -- the local polynomial method (:func:`low_band_estimate`) gives its own disks, and the same rule
   applies (measured: a 4th-order 50 Hz plant whose P̂ had 0.27 of the DC gain passed every Welch frequency
   and Theorem 7.1's noise ball, and its certified loop did not track).
3. **Excitation where the loop is sensitive, and the δ margin** (:mod:`unfalsify.excitation`, per design):
   the whole confidence disk must lie where the loop is stable frequency by frequency, and where every
   plant in the disks lacks the δ margin the loop is certified for, the data refute it.

Several inputs and outputs (u: (n, m), y: (n, l)): every test is stated in the spectral norm; inconsistency is
``‖D̂x‖ − ‖Qx‖ > δ`` for some unit input direction ``x`` (``Q`` the region's factor, so each direction is taken
with its own confidence; at least ``‖D̂‖₂ − r``); with one input and one output every number is the SISO one above.

A ``PersistenceWarning`` of the predictors the pipeline uses (input not persistently exciting,
regressor rank deficient) also means *not certified* (checked in :mod:`unfalsify.robust`).

What no finite data can prove: behaviour between the Welch frequencies (a resonance narrower than
the resolution ``2π/(nperseg·dt)``), at frequencies where the loop is insensitive and the input is
silent, after the record (drift), or away from the operating point (nonlinearity); and each
confidence statement holds with its stated probability only.  The premise is *unfalsified*, never
proven.
"""
from __future__ import annotations

import math
import numbers
import warnings
from dataclasses import dataclass

import control
import numpy as np
import scipy.signal
import scipy.special
import scipy.stats

from synthesis.fingerprint import RecordFingerprint
from synthesis.results import result
from synthesis.validation import (DataError, as_signal, check_count, check_flag, check_horizon, check_instance,
                                  check_nonnegative, check_output_moves, check_sample_time)

from ._common import channel_pair, spectral_radius
from .arx import ArxResult, arx_unfalsify
from .certify import additive_channel, coprime_channel
from .excitation import ExcitationCheck  # noqa: F401 -- results pickled before the split name it here
from .excitation import _bin_response
from .factors import _model_factors
from .frequency_response import (FrequencyResponseEstimate, LowBandEstimate, _bands, _channels, _check_confidence,
                                 _lpm_window, _step, _unit, frequency_response_estimate, low_band_estimate)

__all__ = ["PremiseOptions", "OutputErrorResult", "output_error_residual", "output_error_unfalsify", "PremiseTest",
           "check_premise", "untested_premises", "LEVEL_SPREAD", "operating_point_note", "OFFSET_NOTE", "glitch_note",
           "GLITCH_LEVEL", "residual_line", "LINE_LOOP_GAIN", "hidden_line_gain", "HIDDEN_LINE_LIMIT",
           "unconfirmed_premise"]

#: growth of the model's free response over the segment above which its output error cannot be simulated.
_GROWTH_LIMIT = 10.0


@dataclass(frozen=True)
class PremiseOptions:
    """How :func:`unfalsify.robust_design_from_data` tests the premise of its certificate.

    Attributes
    ----------
    sigma : float or None
        Admissible rms noise of the output-error program (the output noise ``y − P u``, which for
        noise entering through the plant is larger than the one-step prediction error).  None:
        estimated (module docstring, item 1).
    confidence : float
        Simultaneous confidence of the frequency-response disks (default 0.99).
    nperseg : int or None
        Welch segment length (None: a power of two giving at least eight segments, 16–256).
    samples : int
        Largest number of samples of the output-error program (the first ones of the held-out data).
    burn_in : int or None
        Free rows at the start of the output-error segment (None: the horizon ``i``).
    taps : int or None
        Taps of the FIR fit that estimates σ (None: ``min(N/4, max(4i, 20))``).
    tol, time_limit : float
        Relative gap and wall-clock limit of the Theorem 7.1 solve (structured backend).  On the time
        limit the certified upper end of the bracket is used (never a smaller value).
    coprime_samples : int
        Largest number of rows of the coprime-factor program (:func:`unfalsify.coprime_unfalsify`), whose Δ acts
        on ``[u; y]``: twice the variables of the output-error program per row for one channel each, and a solve
        that grows like their cube (measured: 200 rows take about a third of the time of 300).

    Examples
    --------
    Made with keywords (the other fields keep their defaults) and passed to :func:`robust_design_from_data`; here
    on the setting of its example (a FIR plant, ``i = 3``, a 45-sample window, the predictors fitted on the
    whole record), with the output error's noise level given instead of estimated:

    >>> import warnings
    >>> import numpy as np
    >>> import synthesis as sy
    >>> from unfalsify import robust_design_from_data
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(300)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:300] + 0.01 * rng.standard_normal(300)
    >>> W1, W2 = sy.makeweight(10.0, (0.3, 1.0), 0.5, 1.0), sy.makeweight(0.1, (2.0, 0.3), 1.0, 1.0)
    >>> fits = {"predictor": sy.fit_predictor(u, y, 3), "predictor_for": lambda h: sy.fit_predictor(u, y, h)}
    >>> opts = PremiseOptions(sigma=0.01)
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore")  # NotCertifiedWarning or UntestedPremiseWarning
    ...     rd = robust_design_from_data(u[:45], y[:45], 3, W1, W2, "auto", dt=1.0, premise=opts, search=False,
    ...                                  **fits)
    >>> rd.premise.output_error.sigma, rd.premise.output_error.sigma_rule
    (0.01, 'given')
    >>> bool(rd.delta >= rd.premise.output_error.delta)  # the loop is designed for the larger δ
    True

    :func:`check_premise` takes them as ``options=``.  A bad value raises
    :class:`~synthesis.validation.DataError` naming the field:

    >>> PremiseOptions(sigma=-0.01)
    Traceback (most recent call last):
        ...
    synthesis.exceptions.DataError: sigma must be None (estimated) or a finite number > 0, got -0.01
    """

    sigma: float | None = None
    confidence: float = 0.99
    nperseg: int | None = None
    samples: int = 300
    burn_in: int | None = None
    taps: int | None = None
    tol: float = 1e-4
    time_limit: float = 60.0
    coprime_samples: int = 200

    def __post_init__(self):
        # checked where the options are made, not at the first solve that reads them
        if self.sigma is not None and (isinstance(self.sigma, bool) or not isinstance(self.sigma, numbers.Real)
                                       or not (np.isfinite(self.sigma) and self.sigma > 0)):
            raise DataError(f"sigma must be None (estimated) or a finite number > 0, got {self.sigma!r}")
        _check_confidence(self.confidence)
        for name, least, optional in (("nperseg", 4, True), ("samples", 1, False), ("burn_in", 0, True),
                                      ("taps", 1, True), ("coprime_samples", 1, False)):
            value = getattr(self, name)
            if not (optional and value is None):
                check_count(value, name, least)
        if isinstance(self.tol, bool) or not isinstance(self.tol, numbers.Real) or not 0.0 < self.tol < 1.0:
            raise DataError(f"tol must be a relative gap in (0, 1), got {self.tol!r}")
        if self.time_limit is not None and (isinstance(self.time_limit, bool) or
                                            not isinstance(self.time_limit, numbers.Real) or not self.time_limit > 0):
            raise DataError(f"time_limit must be None or a number of seconds > 0, got {self.time_limit!r}")


def _premise_options(options) -> PremiseOptions:
    """``options``, or the defaults for None; :class:`~synthesis.validation.InputTypeError` for another object
    (``options or PremiseOptions()`` had read an empty dict as the defaults and failed on a string deep inside)."""
    if options is None:
        return PremiseOptions()
    return check_instance(options, PremiseOptions, "options",
                          "a PremiseOptions (e.g. PremiseOptions(samples=400)) or None")


@result
@dataclass(frozen=True, eq=False)
class OutputErrorResult:
    """Theorem 7.1 on the output error ``e = y − P̂u``: the smallest additive LTI uncertainty on P̂ that
    explains the record's input–output behaviour.

    Attributes
    ----------
    delta : float
        The certified upper bound of that smallest ``‖Δ‖∞`` (``unfalsification.certificate.upper_bound``);
        NaN when the solve gave none.
    unfalsification : ArxResult
        The program (7.4) with no ARX parameters on ``(u, e)``, with its two-sided ``certificate``
        (``verify()`` re-checks both bounds from the data).
    residual : ndarray
        ``e = y − P̂u`` on the whole record after its first ``i`` samples (the program uses the first
        ``burn_in + samples`` of them, the first ``burn_in`` rows free); (n − i,), or (n − i, l) for l outputs.
    inputs : ndarray
        ``u`` aligned with ``residual``; (n − i,) or (n − i, m).
    sigma : float
        Admissible rms noise σ_oe (several outputs: one σ pooled over all output channels, the rms of every
        entry of the noise, whose ball is ``‖Ξ‖_F ≤ σ√(N·l)`` over the N non-free rows).
    sigma_rule : str
        How σ_oe was obtained.
    held_out : bool
        The segment was not used to fit P̂ (``validation=``); False: in-sample (optimistic).
    burn_in : int
    growth : float
        Largest growth of P̂'s free response over the segment, ``ρ(Â)^N`` (a model that grows more
        than 10× cannot be simulated and is refused).
    """

    delta: float
    unfalsification: ArxResult | None
    residual: np.ndarray
    inputs: np.ndarray
    sigma: float
    sigma_rule: str
    held_out: bool
    burn_in: int
    growth: float


def _check_model(model) -> None:
    """P̂ must be a StateSpace (:func:`unfalsify.predictor_model`): its state is the stacked past ``w_p`` the tests
    start from, which another realisation's would not be; a string or a number had raised python-control's bare
    TypeError or turned into a static gain."""
    check_instance(model, control.StateSpace, "model", "the StateSpace of unfalsify.predictor_model(pred, dt)")


def _model_dt(model, dt) -> float:
    """The data's sample time ``dt`` (checked), which must be the model's: a model built with ``dt=True`` leaves its
    sample time unspecified, and then nothing contradicts ``dt``."""
    dt = check_sample_time(dt, "dt", allow_true=False)
    model_dt = getattr(model, "dt", None)
    if isinstance(model_dt, numbers.Real) and not isinstance(model_dt, bool) and not np.isclose(
            float(model_dt), dt, rtol=1e-9, atol=0):
        raise DataError(f"dt = {dt!r} but the model P̂ has sample time {model_dt}: the frequency estimates would be "
                        f"read at the wrong frequencies; pass dt={model_dt} (the data's), or rebuild P̂ with "
                        f"unfalsify.predictor_model(pred, {dt})")
    return dt


def output_error_residual(model, u, y, horizon: int) -> np.ndarray:
    """``e = y − P̂u`` for ``k ≥ horizon``, P̂ simulated from the measured past.

    Parameters
    ----------
    model : control.StateSpace
        :func:`unfalsify.predictor_model` of horizon i, m inputs and l outputs (state
        ``w_p = [u_{k−i}; …; u_{k−1}; y_{k−i}; …; y_{k−1}]``, the samples stacked with their channels: order
        ``i(m + l)``).
    u, y : array_like, shape (n,) or (n, m) and (n, l)
        The record (time along axis 0); its first ``horizon`` samples start the state, the simulation uses
        only ``u`` afterwards (output error, not prediction error).
    horizon : int
        The model's ``i``.

    Returns
    -------
    ndarray, shape (n − horizon,), or (n − horizon, l) for several channels

    Raises
    ------
    DataError
        A model that is not the predictor model of horizon i for the data's m inputs and l outputs.

    Examples
    --------
    >>> import numpy as np
    >>> import synthesis as sy
    >>> from unfalsify import predictor_model
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(300)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:300] + 0.01 * rng.standard_normal(300)    # FIR plant, output noise 0.01
    >>> model = predictor_model(sy.fit_predictor(u[:200], y[:200], 3), 1.0)   # P̂ from the first 200 samples
    >>> e = output_error_residual(model, u[200:], y[200:], 3)                # on the held-out 100
    >>> e.shape, bool(np.sqrt(np.mean(e ** 2)) < 0.02)                       # about the noise level
    ((97,), True)
    >>> u2 = rng.standard_normal((300, 2))                                   # 2 × 2: y = [u₁ + u₂; u₂] delayed
    >>> y2 = np.column_stack([np.roll(u2[:, 0] + u2[:, 1], 1), np.roll(u2[:, 1], 1)])
    >>> y2 += 0.01 * rng.standard_normal((300, 2))
    >>> model2 = predictor_model(sy.fit_predictor(u2[:200], y2[:200], 2), 1.0)
    >>> e2 = output_error_residual(model2, u2[200:], y2[200:], 2)            # (n − i, l)
    >>> e2.shape, bool(np.sqrt(np.mean(e2 ** 2)) < 0.02)
    ((98, 2), True)
    """
    _check_model(model)
    A, B, C, D = (np.asarray(M, float) for M in control.ssdata(model))
    u, y = channel_pair(u, y)
    i = check_horizon(horizon)  # int() had passed 3.5 and '3'
    m, l = (1, 1) if u.ndim == 1 else (u.shape[1], y.shape[1])
    if A.shape[0] != i * (m + l) or B.shape[1] != m or C.shape[0] != l:
        raise DataError(f"model must be the predictor_model of horizon {i} for {m} input(s) and {l} output(s) (order "
                        f"{i * (m + l)}), got order {A.shape[0]} with {B.shape[1]} input(s) and {C.shape[0]} "
                        "output(s); build it with unfalsify.predictor_model(synthesis.fit_predictor(u, y, i), dt) "
                        "on data with the same channels")
    # the delay-line state w_p: the first i input samples (each m-vector), then the first i outputs
    x0 = np.concatenate([u[:i].reshape(-1), y[:i].reshape(-1)])
    _, yhat, _ = scipy.signal.dlsim((A, B, C, D, 1.0), u[i:], x0=x0)
    if u.ndim == 1:
        return y[i:] - np.asarray(yhat).reshape(-1)
    return y[i:] - np.asarray(yhat).reshape(-1, l)


def _fir_rss(u: np.ndarray, e: np.ndarray, taps: int, burn: int) -> tuple[float, int]:
    """Residual sum of squares of the least-squares FIR fit of ``e`` on ``u`` (rows after ``burn``) and its
    degrees of freedom.

    One channel: the rows after ``burn`` minus the taps.  Several (u (n, m), e (n, l)): each output is fitted
    on all inputs' ``taps`` delays (taps·m coefficients per output), the sum of squares is over every entry
    and the degrees of freedom are ``l·(rows − taps·m)``.
    """
    if e.ndim == 1:
        n = e.size
        X = np.zeros((n, taps))
        for t in range(taps):
            X[t:, t] = u[: n - t]
        X, target = X[burn:], e[burn:]
        coef = np.linalg.lstsq(X, target, rcond=None)[0]
        r = target - X @ coef
        return float(r @ r), target.size - taps
    n, m = u.shape
    X = np.zeros((n, taps, m))
    for t in range(taps):
        X[t:, t] = u[: n - t]
    X, target = X[burn:].reshape(n - burn, taps * m), e[burn:]
    coef = np.linalg.lstsq(X, target, rcond=None)[0]
    r = target - X @ coef
    return float(np.sum(r * r)), target.shape[1] * (target.shape[0] - taps * m)


#: the least estimated σ, relative to the rms of the error it is estimated from (:func:`_fir_sigma`)
_SIGMA_FLOOR = 1e-8


def _fir_sigma(u: np.ndarray, e: np.ndarray, taps: int, burn: int) -> tuple[float, bool]:
    """Residual rms of the least-squares FIR fit of ``e`` on ``u`` (rows after ``burn``), per degree of freedom, at
    least ``_SIGMA_FLOOR`` times the rms of ``e``; and whether the floor set it.

    Several channels: pooled over the outputs (:func:`_fir_rss`), the σ of the noise ball
    ``‖Ξ‖_F ≤ σ√(N·l)`` the solver uses -- one rms over every entry, as in (7.5)'s ``σ√(ilj)``.

    The memory is fixed: growing it while an F-test of nested fits found the longer one significant was
    measured to miss the slow model error it was meant to catch (a fourth-order plant whose error sat
    below the held-out record's noise) while it refused two integrating-plant loops that hold.

    The floor: on noise-free data the fit leaves rounding (σ about 1e-12 of the error's rms), a noise ball no
    interior-point method resolves.  Measured on a noise-free coprime-factor record (error rms 0.03, the truth
    0.0275): at σ = 1e-12 and 1e-10 × the rms both structured methods failed after 15–47 s (certified brackets
    [0.015, 0.038] and [0.022, 0.038]); from 1e-9 on they certified 0.0275434 in 4–12 s, and δ moved by 1.4e-5
    relative between 1e-8 and 1e-6, i.e. about 1e-7 at the floor, far inside the premise test's tolerance.
    """
    rss, dof = _fir_rss(u, e, taps, burn)
    sigma = math.sqrt(rss / max(dof, 1))
    floor = _SIGMA_FLOOR * max(float(np.sqrt(np.mean(np.square(e[burn:])))), 1e-300)
    return (float(sigma), False) if sigma >= floor else (float(floor), True)


def _floor_note(floored: bool) -> str:
    """What the σ rule adds when :func:`_fir_sigma`'s floor set σ."""
    return (f"; at its floor, {_SIGMA_FLOOR:g} × the error's rms (the fit left rounding only: noise-free data)"
            if floored else "")


def output_error_unfalsify(model, u, y, horizon: int, *, held_out: bool, options: PremiseOptions | None = None
                           ) -> OutputErrorResult:
    """The smallest additive LTI uncertainty on P̂ that explains the record (module docstring, item 1).

    Parameters
    ----------
    model : control.StateSpace
        P̂, the :func:`unfalsify.predictor_model` of horizon ``horizon`` (m inputs, l outputs).
    u, y : array_like, shape (n,) or (n, m) and (n, l)
        A record of the plant, best one not used to fit P̂ (say which with ``held_out``).  Several
        channels: Δ is l × m (Markov parameters h_t l × m, ``‖Δ‖∞ ≥ ‖T(h)‖₂`` with the nl × nm block
        Toeplitz T(h)), σ_oe is pooled over the outputs and the noise ball is ``‖Ξ‖_F ≤ σ_oe √(N·l)``,
        N = samples (the non-free rows); see :func:`unfalsify.arx_unfalsify`.
    horizon : int
        P̂'s ``i``: the first ``i`` samples start its state.
    held_out : bool
        Whether ``(u, y)`` was left out of P̂'s fit (stored on the result).
    options : PremiseOptions, optional

    Returns
    -------
    OutputErrorResult
        ``delta`` NaN when P̂'s free response grows more than 10× over the segment or the solve
        certified nothing.

    Examples
    --------
    >>> import numpy as np, synthesis, unfalsify as uf
    >>> rng = np.random.default_rng(1)
    >>> u = np.sign(rng.standard_normal(600))
    >>> y = np.convolve(u, [0.0, 0.5, 0.25, 0.125])[:600] + 0.02 * rng.standard_normal(600)
    >>> P_hat = uf.predictor_model(synthesis.fit_predictor(u[:300], y[:300], 4), 1.0)
    >>> oe = uf.output_error_unfalsify(P_hat, u[300:], y[300:], 4, held_out=True)
    >>> oe.held_out, oe.delta < 0.05, oe.unfalsification.certificate.verify()
    (True, True, True)
    """
    opts = _premise_options(options)
    held_out = check_flag(held_out, "held_out")
    i = check_horizon(horizon)  # int() had passed 3.5 and '3'
    u, y = channel_pair(u, y)
    # the program below sees the output error y − P̂u, which moves with u even when y does not: a dead sensor's
    # constant output had given δ = 0 (its error, −P̂u, is a FIR response of u, which the σ fit took for noise)
    check_output_moves(y, "the output-error record")
    burn = i if opts.burn_in is None else int(opts.burn_in)
    N = u.shape[0]
    n = min(N - i, burn + int(opts.samples))
    if n < burn + 4 * i or n < 2 * burn:
        # the pipeline's record mode (and the design command) hands this test the record's held-out last third:
        # there "a longer validation record" is a longer record, the only form of the fix the command can apply
        raise DataError(f"the output-error segment has {N} samples; it needs at least "
                        f"{i + max(burn + 4 * i, 2 * burn)} (horizon {i}, burn-in {burn}, 4i rows): pass a longer "
                        "validation record (in record mode, where the record's last third is held out, a record three "
                        "times that long), or lower the horizon")
    rho = spectral_radius(control.ssdata(model)[0])
    with np.errstate(over="ignore"):  # an unstable model's growth is inf (a float power would raise OverflowError)
        growth = float(np.float64(rho) ** (N - i)) if rho > 0 else 0.0
    seg_u = u[i:i + n]
    m = 1 if u.ndim == 1 else u.shape[1]
    if not growth <= _GROWTH_LIMIT:
        return OutputErrorResult(delta=float("nan"), unfalsification=None, residual=np.zeros(0), inputs=np.zeros(0),
                                 sigma=float("nan"), sigma_rule="", held_out=bool(held_out), burn_in=burn,
                                 growth=float(growth))
    e_all = output_error_residual(model, u, y, i)
    e = e_all[:n]
    if opts.sigma is not None:
        sigma, rule = float(opts.sigma), "given"
    else:
        # several inputs: taps·m coefficients per output, so the memory shrinks to keep 4 rows per coefficient
        taps = opts.taps if opts.taps is not None else min((n - burn) // (4 * m), max(4 * i, 20))
        sigma, floored = _fir_sigma(seg_u, e, int(taps), burn)
        rule = (f"residual rms of a {taps}-tap least-squares FIR fit of the output error on the input, "
                f"per degree of freedom (rows {burn}…{n - 1})")
        if e.ndim == 2:
            rule += f", pooled over the {e.shape[1]} outputs (each fitted on all {m} inputs)"
        rule += _floor_note(floored)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a non-optimal status is read from the result below
        res = arx_unfalsify(seg_u, e, 0, 0, sigma, backend="structured", tol=opts.tol,
                            time_limit=opts.time_limit, progress=False, free_rows=burn)
    # δ is the certified upper end of the bracket (NaN after a failed solve, never a value below the bracket)
    delta = float(res.delta) if math.isfinite(res.delta) else float("nan")
    return OutputErrorResult(delta=delta, unfalsification=res, residual=e_all, inputs=u[i:], sigma=float(sigma),
                             sigma_rule=rule,
                             held_out=bool(held_out), burn_in=burn, growth=float(growth))


@result
@dataclass(frozen=True, eq=False)
class PremiseTest:
    """The premise of the certificate, tested on the data before any design (module docstring, items 1–2).

    Attributes
    ----------
    delta_subspace : float
        δ of (7.5).
    output_error : OutputErrorResult or None
        Theorem 7.1 on P̂'s output error (None when it could not be run: ``reason`` says why).
    delta : float
        ``max(delta_subspace, output_error.delta)``: what the loop is designed and certified for.
    decided_by : str
        ``"subspace (7.5)"`` or ``"output error (Theorem 7.1)"``: which δ is the larger.
    frf : FrequencyResponseEstimate or None
        The nonparametric estimate ``D̂`` of the model error ``P − P̂`` (from ``u`` to ``y − P̂u``) the
        model and the loops are judged by.
    inconsistency : float
        ``max (|D̂| − r)/δ`` over the excited frequencies (> 1: P̂ lies outside the confidence
        region by more than δ).
    reason : str
        ``''`` when the premise survived these tests; otherwise why not, and the fix.
    plant_frf : FrequencyResponseEstimate or None
        The direct Welch estimate of the plant ``Ĝ = S_yu/S_uu`` on the same data.
    low_band : LowBandEstimate or None
        ``P − P̂`` at the record's DFT frequencies below the Welch resolution (:func:`low_band_estimate`
        of the input and the output error): a model error slower than the Welch segments, which their
        detrending hides.  ``|D̂| − r > δ`` there refuses the premise; :func:`check_excitation` also
        judges the loop on these frequencies.
    plant_low_band : LowBandEstimate or None
        The same for the plant itself; its lowest frequency gives the low-frequency gain the pipeline's
        tracking check uses.
    validation_shared : float
        Fraction of the ``validation`` record found in the data P̂ was fitted on (``fitted_on``; a lower bound, see
        :meth:`synthesis.RecordFingerprint.shared_fraction`).  Above 0 the output error was tested partly in sample
        and ``output_error.held_out`` is False.  NaN: no ``validation``, or not known what P̂ was fitted on.
    upper : float
        The largest ``‖D̂‖₂ + r`` over the excited Welch frequencies and the low band: how far from P̂ the data's
        confidence regions reach.  The tests above refuse only where the whole region lies beyond δ; where ``upper``
        exceeds the ball a certificate names, the data neither refute nor confirm it (:func:`unconfirmed_premise`).
        NaN: nothing estimated (and on results made before it was measured).
    upper_frequency : float
        Where ``upper`` is reached (the data's frequency unit; NaN without).
    record_low_band : LowBandEstimate or None
        ``P − P̂`` below the Welch resolution from the output error over the longest contiguous record given
        (``record`` of :func:`check_premise`; None without one, or when it is too short).  In sample, so it can only
        refute: ``|D̂| − r > δ`` there refuses the premise; it never enters ``upper`` or the loop's tests.
    """

    delta_subspace: float
    output_error: OutputErrorResult | None
    delta: float
    decided_by: str
    frf: FrequencyResponseEstimate | None
    inconsistency: float
    reason: str
    plant_frf: FrequencyResponseEstimate | None = None
    low_band: LowBandEstimate | None = None
    plant_low_band: LowBandEstimate | None = None
    validation_shared: float = float("nan")
    upper: float = float("nan")
    upper_frequency: float = float("nan")
    record_low_band: LowBandEstimate | None = None

    @property
    def ok(self) -> bool:
        """The premise survived the output-error and frequency-response tests."""
        return not self.reason

    @property
    def delta_output_error(self) -> float:
        """δ of the output-error test (NaN when there is none)."""
        return float(self.output_error.delta) if self.output_error is not None else float("nan")


def _relative_gap(gap: float, delta: float) -> float:
    """``gap/δ``, the inconsistency of a model with the data's disks (δ = 0: ``inf`` for any positive gap)."""
    return gap / delta if delta > 0 else (float("inf") if gap > 0 else 0.0)


def _model_gap(est) -> np.ndarray:
    """Per frequency, a lower bound on ``‖P − P̂‖₂`` over the estimate's confidence region (NaN where it has none).

    One input (no ``region``): ``|D̂| − r``.  Several inputs: the region bounds ``‖(D − D̂)x‖ ≤ ‖Qx‖`` for every ``x``
    (``Q`` its factor, :attr:`FrequencyResponseEstimate.region`), so every ``D`` in it has
    ``‖D‖₂ ≥ ‖D̂x‖ − ‖Qx‖`` for each unit ``x``; the bound is the largest over a few directions
    (:func:`_gap_directions`), never below ``‖D̂‖₂ − σ̄(Q)`` (``x`` the top right singular vector of ``D̂``).
    ``‖D̂‖₂ − r`` with ``r = σ̄(Q)`` (the rule before) takes the least-excited input direction's confidence for every
    direction, so an error the record shows in one direction was not refuted when the region was wide in another:
    measured on the whole-record low band of a 2 × 2 plant (condition number 20) whose low-gain direction has a slow
    mode, ``‖D̂‖₂ − r`` = −0.10 against 0.050 in a direction at 0.0043 rad/sample, δ = 0.011 (true ``‖P − P̂‖₂``
    0.063 there); its loop had been certified and lacked its δ margin on the plant.
    """
    gap = est.gain - est.radius
    region = getattr(est, "region", None)
    if region is None:
        return gap
    out = gap.copy()
    for k in np.flatnonzero(np.isfinite(est.radius) & np.all(np.isfinite(region), axis=(1, 2))):
        D, Q = est.response[k], region[k]
        X = _gap_directions(D, Q)
        out[k] = max(float(gap[k]), float(np.max(np.linalg.norm(D @ X, axis=0) - np.linalg.norm(Q @ X, axis=0))))
    return out


def _gap_directions(D: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """Unit input directions (columns) where ``‖D̂x‖ − ‖Qx‖`` is tried: the right singular vectors of ``D̂`` and of
    ``Q`` and the direction of the largest ``‖D̂x‖/‖Qx‖`` (``Q⁻¹w``, ``w`` the top right singular vector of
    ``D̂Q⁻¹``, where ``Q`` is invertible).  Any unit ``x`` gives a valid bound; these are where it is likely largest."""
    cols = [np.linalg.svd(D)[2].conj().T, np.linalg.svd(Q)[2].conj().T]
    try:
        w = np.linalg.svd(D @ np.linalg.inv(Q))[2][0].conj()
        x = np.linalg.solve(Q, w)
        if np.all(np.isfinite(x)) and np.linalg.norm(x) > 0:
            cols.append((x / np.linalg.norm(x))[:, None])
    except np.linalg.LinAlgError:
        pass  # a singular factor: the singular vectors above
    return np.hstack(cols)


def _frf_inconsistency(est: FrequencyResponseEstimate, delta: float) -> tuple[float, str]:
    """``max gap/δ`` over the excited band (``D̂`` the estimate of ``P − P̂``, gap :func:`_model_gap`) and where it
    exceeds 1.

    ``gap > δ`` means every ``D`` in the region has ``‖D‖₂ ≥ gap > δ`` (SISO ``|D̂| − r``): the plant is outside
    the δ-ball around P̂ at that frequency (with the region's confidence).
    """
    excited = est.excited & np.isfinite(est.radius)
    if not np.any(excited):
        if np.any(est.excited):  # excited, but no finite radius: a 2 × 2 record of 47 samples (two Welch segments)
            return float("nan"), (f"the record ({est.averages:.3g} Welch averages of {est.nperseg} samples) is too "
                                  "short for a confidence region of the frequency response at any frequency it "
                                  "excites; record longer")
        return float("nan"), "the record excites no frequency"
    gap = _model_gap(est)
    excess = np.where(excited, gap, -np.inf)
    worst = _relative_gap(float(np.max(excess)), delta)
    bad = excess > delta
    if not np.any(bad):
        return worst, ""
    k = int(np.argmax(excess))
    return worst, (f"the model P̂ lies outside the {est.confidence:.0%} confidence region of the data's frequency "
                   f"response by more than δ = {delta:.4g} at {_bands(est.frequency, bad, _unit(est.dt))} (by "
                   f"{excess[k]:.3g} at {est.frequency[k]:.3g} {_unit(est.dt)}{_channels(est.response, k)}): P̂ is "
                   "biased there; fit it on a longer or richer record (white PRBS), or raise the horizon")


def check_premise(model, u, y, horizon: int, delta_subspace: float, *, dt: float, validation=None, fitted_on=None,
                  options: PremiseOptions | None = None, record=None) -> PremiseTest:
    """Test the certificate's premise on the data (module docstring, items 1–2).

    Parameters
    ----------
    model : control.StateSpace
        P̂ (SISO :func:`unfalsify.predictor_model` of horizon ``horizon``).
    u, y : array_like
        The (7.5) window.
    horizon : int
    delta_subspace : float
        δ of (7.5).
    dt : float
        The data's sample time; must be the model's (unless P̂ was built with ``dt=True``).
    validation : tuple of array_like, optional
        ``(u_v, y_v)``: a record of the same plant not used to fit P̂ (held out).  Without it the
        output error is computed on the window, in sample (optimistic; the result says so).
    fitted_on : synthesis.RecordFingerprint or sequence of them, optional
        The data P̂ was fitted on (:attr:`synthesis.Predictor.fingerprint`, or :func:`synthesis.record_fingerprint`
        of the (7.5) window when δ and the predictor were found together).  A ``validation`` record that shares
        samples with them is not held out: ``output_error.held_out`` is then False and ``validation_shared`` says
        how much.  None: not checked.
    options : PremiseOptions, optional
    record : tuple of array_like, optional
        ``(u_r, y_r)``: the longest contiguous record that holds the window (in the pipeline's record mode the whole
        record, window and held-out part).  Its output error's low band (:func:`low_band_estimate`, rows after the
        burn-in) reaches frequencies the held-out record is too short for; in sample it is biased towards P̂, so it
        only refutes: where the whole region lies beyond δ the premise is refused (``record_low_band``).
        None: not used.

    Returns
    -------
    PremiseTest

    Examples
    --------
    >>> import numpy as np
    >>> import synthesis as sy
    >>> from unfalsify import predictor_model
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(300)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:300] + 0.01 * rng.standard_normal(300)    # FIR plant, output noise 0.01
    >>> model = predictor_model(sy.fit_predictor(u[:200], y[:200], 3), 1.0)
    >>> test = check_premise(model, u[:45], y[:45], 3, 0.05, dt=1.0, validation=(u[200:], y[200:]))
    >>> bool(test.delta >= 0.05), test.decided_by in ("subspace (7.5)", "output error (Theorem 7.1)")
    (True, True)
    >>> test.output_error.held_out, test.frf is not None, isinstance(test.ok, bool)
    (True, True, True)

    The same test on a "validation" record that P̂ was fitted on is in sample:

    >>> fitted = sy.record_fingerprint(u[:200], y[:200])
    >>> test = check_premise(model, u[:45], y[:45], 3, 0.05, dt=1.0, validation=(u[:200], y[:200]), fitted_on=fitted)
    >>> test.output_error.held_out, test.validation_shared
    (False, 0.96)
    """
    opts = _premise_options(options)
    _check_model(model)
    check_horizon(horizon)  # here: the tests below turn their own DataErrors into reasons
    delta_subspace = check_nonnegative(delta_subspace,
                                       "delta_subspace (δ of (7.5), e.g. subspace_unfalsify(...).delta)")
    dt = _model_dt(model, dt)
    u, y = channel_pair(u, y)
    if validation is not None:
        try:
            uv, yv = validation
        except (TypeError, ValueError):
            raise DataError("validation must be a pair (u, y) of held-out data of the same plant") from None
        uv, yv = channel_pair(uv, yv, "validation ")
        shared = _shared_fraction(fitted_on, uv, yv)
        oe_data, held_out = (uv, yv), not shared > 0
    else:
        oe_data, held_out, shared = (u, y), False, float("nan")
    reasons = []
    try:
        oe = output_error_unfalsify(model, *oe_data, horizon, held_out=held_out, options=opts)
    except DataError as exc:
        oe = None
        reasons.append(f"the output-error test cannot run ({exc})")
    if oe is not None and not math.isfinite(oe.delta):
        if not oe.growth <= _GROWTH_LIMIT:
            reasons.append(f"the model P̂ is unstable (its free response grows {oe.growth:.3g}× over the segment), so "
                           "its output error cannot be simulated and the premise cannot be tested: identify the plant "
                           "open loop, or stabilise it with an inner loop and design for the stabilised plant")
        else:
            st = oe.unfalsification.status if oe.unfalsification is not None else "none"
            reasons.append(f"the output-error program certified no δ (status {st!r}): P̂'s simulated output is far "
                           "from the record; use richer excitation or a longer record")
    delta_oe = oe.delta if oe is not None and math.isfinite(oe.delta) else float("nan")
    delta = max(float(delta_subspace), delta_oe) if math.isfinite(delta_oe) else float(delta_subspace)
    decided = "output error (Theorem 7.1)" if math.isfinite(delta_oe) and delta_oe > delta_subspace else "subspace (7.5)"
    frf, worst = None, float("nan")
    if oe is not None and oe.residual.size:
        u_e, e = oe.inputs[oe.burn_in:], oe.residual[oe.burn_in:]  # the output error's rows after the burn-in
        try:
            frf = frequency_response_estimate(u_e, e, dt, nperseg=opts.nperseg, confidence=opts.confidence)
        except DataError as exc:
            reasons.append(f"no frequency-response estimate of the model error ({exc})")
    plant_frf = None
    if oe is not None:
        try:
            plant_frf = frequency_response_estimate(*oe_data, dt, nperseg=opts.nperseg, confidence=opts.confidence)
        except DataError:
            plant_frf = None  # too short: the missing output-error estimate already says so
    if frf is not None:
        worst, why = _frf_inconsistency(frf, delta)
        if why:
            reasons.append(why)
    low = plant_low = None
    bins = _low_bins(e.shape[0], frf.nperseg, 1 if u_e.ndim == 1 else u_e.shape[1]) if frf is not None else 0
    if bins:
        y_e = oe_data[1][-e.shape[0]:]  # the outputs of the same rows (e and the record end together)
        low = low_band_estimate(u_e, e, dt, bins=bins, confidence=opts.confidence)
        plant_low = low_band_estimate(u_e, y_e, dt, bins=bins, confidence=opts.confidence)
        low_worst, why = _low_band_inconsistency(low, delta)
        worst = float(np.fmax(worst, low_worst))  # the larger one, NaN only when both are
        if why:
            reasons.append(why)
    whole = None
    if record is not None and frf is not None and oe.burn_in is not None:
        whole, whole_worst, why = _record_low_band(model, record, horizon, delta, dt, frf.nperseg, oe.burn_in, opts)
        if why:  # refutation only: an in-sample estimate that finds P̂ inside the ball confirms nothing
            worst = float(np.fmax(worst, whole_worst))
            reasons.append(why)
    upper, upper_at = _region_reach(frf, low)
    return PremiseTest(delta_subspace=float(delta_subspace), output_error=oe, delta=float(delta), decided_by=decided,
                       frf=frf, inconsistency=float(worst), reason="; ".join(reasons), plant_frf=plant_frf,
                       low_band=low, plant_low_band=plant_low, validation_shared=shared, upper=upper,
                       upper_frequency=upper_at, record_low_band=whole)


def _record_low_band(model, record, horizon: int, delta: float, dt: float, nperseg: int, burn: int,
                     opts: PremiseOptions) -> tuple[LowBandEstimate | None, float, str]:
    """``(estimate, max gap/δ, reason)`` (:func:`_model_gap`) of the low band of P̂'s output error over ``record``.

    The held-out record's low band starts at ``2π/(n_v·dt)``; a slow mode whose error the loop's integral action
    amplifies below that (a DC gain of the other sign than P̂'s) is seen only on a longer record.  The window is
    part of this one, so the estimate is in sample: the reason is a refutation, never a confirmation.
    """
    try:
        ur, yr = channel_pair(*record, "record ")
        e = output_error_residual(model, ur, yr, horizon)[burn:]
    except (DataError, TypeError, ValueError):
        return None, float("nan"), ""  # a record the held-out tests already cover, or none usable: no evidence
    est = _residual_low_band(ur[horizon:][burn:], e, dt, nperseg, opts.confidence)
    if est is None:
        return None, float("nan"), ""
    worst, why = _low_band_inconsistency(est, delta)
    if not why:
        return est, worst, ""
    return est, worst, (f"over the whole {ur.shape[0]}-sample record (in sample, lowest frequency "
                        f"{est.frequency[0]:.3g} {_unit(est.dt)}: slower than the held-out part shows) {why}")


def _residual_low_band(u_e, e, dt: float, nperseg: int, confidence: float) -> LowBandEstimate | None:
    """The low band (:func:`low_band_estimate`) of a residual ``e`` over its inputs ``u_e`` below the Welch
    resolution of ``nperseg``, or None where the record has no such bin or the residual is not finite (the
    refutation-only tests over a whole record, here and in :mod:`unfalsify.coprime`)."""
    bins = _low_bins(e.shape[0], nperseg, 1 if u_e.ndim == 1 else u_e.shape[1])
    if not bins or not np.all(np.isfinite(e)):
        return None
    return low_band_estimate(u_e, e, dt, bins=bins, confidence=confidence)


def _region_reach(frf: FrequencyResponseEstimate | None, low: LowBandEstimate | None) -> tuple[float, float]:
    """``(max ‖D̂‖₂ + r, where)`` over the excited Welch frequencies of ``frf`` and the frequencies of ``low`` with a
    finite radius; ``(nan, nan)`` when neither has one.  The frequencies the premise test reads are the ones it
    bounds: the unexcited ones have no finite region (the excitation check names them)."""
    reach, where = [], []
    if frf is not None:
        ok = frf.excited & np.isfinite(frf.radius) & np.isfinite(frf.gain)
        reach.append((frf.gain + frf.radius)[ok])
        where.append(frf.frequency[ok])
    if low is not None:
        ok = np.isfinite(low.radius) & np.isfinite(low.gain)
        reach.append((low.gain + low.radius)[ok])
        where.append(low.frequency[ok])
    reach, where = (np.concatenate(x) if x else np.zeros(0) for x in (reach, where))
    if not reach.size:
        return float("nan"), float("nan")
    k = int(np.argmax(reach))
    return float(reach[k]), float(where[k])


def unconfirmed_premise(test: PremiseTest, bound: float) -> str:
    """Why the data do not confirm the premise ``‖P − P̂‖∞ ≤ bound`` of a certificate, ``''`` when they do.

    The tests of :func:`check_premise` are one-sided: they refuse where the data's confidence region of ``P − P̂``
    lies wholly beyond δ, and pass where it does not -- also where it reaches far beyond the ball, i.e. where the
    data cannot tell.  δ of (7.5) bounds ``P − P̂`` over the horizon's ``i`` steps only (a finite-horizon Toeplitz
    norm, at most ``‖P − P̂‖∞``), so a model error slower than ``i`` samples -- at low frequency, where the noise
    that passes through the plant also widens the regions most -- can exceed the ball with no test seeing it.
    Measured (2026-11-29, 30 records of known plants with 1–3 inputs and 1–3 outputs, 1500 samples, noise 0.05,
    horizons 5 and 8, seeds 0–2): the i-step Toeplitz norm of ``P − P̂`` was 0.006–0.037, below δ in every run,
    while ``‖P − P̂‖∞`` (mostly at 0 rad/s) was 1.7–45 times it; 9 of the 23 certified records had the plant
    outside the ball.  Every certified record gets this statement (``upper`` 3.1–35 times the ball, at the
    lowest frequency of the low band); the Welch frequencies alone would have confirmed the ball of two one-channel
    records (0.75 and 0.84 of it), one with the plant at 1.15 δ, just inside a ball of 1.25 δ.  The slow error is a
    bias of the short predictor: at i = 5 a four times longer record left ``‖P − P̂‖∞/δ`` at 1.5 (one input) and 4.0
    (three inputs), while i = 12 brought it to 0.8 and 1.1 on the same 1500 samples.

    Parameters
    ----------
    test : PremiseTest
    bound : float
        The radius of the ball the certificate is a theorem about, ``(1 + margin)·δ``.

    Returns
    -------
    str
        ``''`` when ``test.upper <= bound`` (or nothing was estimated: the premise test then refuses or says why);
        otherwise the statement, with the numbers and the fix.

    Examples
    --------
    >>> import numpy as np
    >>> t = PremiseTest(delta_subspace=0.1, output_error=None, delta=0.1, decided_by="subspace (7.5)", frf=None,
    ...                 inconsistency=-0.5, reason="", upper=0.3, upper_frequency=0.0)
    >>> unconfirmed_premise(t, 0.125)[:72]
    'the data do not confirm the premise ‖P − P̂‖∞ ≤ (1 + margin)·δ = 0.125: '
    >>> unconfirmed_premise(t, 0.5)
    ''
    """
    bound = check_nonnegative(bound, "bound ((1 + margin)·δ of the certificate)")
    upper = float(getattr(test, "upper", float("nan")))  # results made before it was measured have none
    if not upper > bound:
        return ""
    conf = f"{test.frf.confidence:.0%} " if test.frf is not None else ""
    unit = _unit(test.frf.dt) if test.frf is not None else "rad/sample"
    return (f"the data do not confirm the premise ‖P − P̂‖∞ ≤ (1 + margin)·δ = {bound:.4g}: their {conf}confidence "
            f"regions of P − P̂ reach {upper:.3g} ({_times(upper, bound)} that) at {test.upper_frequency:.3g} "
            f"{unit}, "
            "and δ of (7.5) bounds P − P̂ over the horizon's steps only, so a slower model error can exceed the ball "
            "unseen; the plant is assumed inside it there (the loop's own test against those regions, the "
            "excitation check, holds at the Welch frequencies; below them it refuses on evidence only, and a model "
            "error slower than the record shows is not seen: a loop with integral action fails on a plant whose DC "
            "gain the record leaves open); a longer record or a larger input amplitude narrows the regions, and a "
            "higher horizon lowers a slow error of P̂ itself")


def _times(upper: float, bound: float) -> str:
    """``upper/bound`` as "3.2 ×" for a reason's text; a zero bound (δ = 0) had raised ZeroDivisionError."""
    return f"{upper / bound:.3g} ×" if bound > 0 else "infinitely many times"


def _shared_fraction(fitted_on, u, y) -> float:
    """Fraction of the record ``(u, y)`` found in the fingerprints ``fitted_on`` (one, a sequence, or None: NaN)."""
    if fitted_on is None:
        return float("nan")
    prints = (fitted_on,) if isinstance(fitted_on, RecordFingerprint) else tuple(fitted_on)
    if not all(isinstance(fp, RecordFingerprint) for fp in prints):
        raise DataError(f"fitted_on must be a synthesis.RecordFingerprint or a sequence of them, got {fitted_on!r}")
    mask = np.zeros(np.shape(u)[0], bool)
    for fp in prints:
        mask |= fp.shared(u, y)
    return float(mask.mean()) if mask.size else 0.0


#: a channel counts as taking two levels (or three evenly spaced ones) when the rms distance of its samples to their
#: nearest level (the farthest 1 % left out) is below this fraction of the levels' spacing: noise on a recorded
#: two-level input (a measured PRBS) does not show the plant other amplitudes.  Measured on the adversarial catalogue (a
#: third-order plant behind a saturation at 80 % of a ±1 PRBS, input recorded with noise of 1 % and 5 % of its rms,
#: seeds 4, 5, 7, 9): every run had been taken as testable and certified under ``untested="refuse"``, and 7 of the 8
#: loops lacked their δ margin on the plant.  A ±1 PRBS recorded with noise of rms 0.2 sits at the threshold.
LEVEL_SPREAD = 0.1


def untested_premises(u, validation=None) -> tuple[str, ...]:
    """What the certificate assumes that these data cannot test, read off the inputs themselves.

    The certificate speaks of an LTI plant.  Some departures from that the records show (the output-error and
    frequency-response tests of :func:`check_premise`), but an input channel whose samples take only two values,
    or three evenly spaced ones (0 and ±a about the middle one), cannot show a static input nonlinearity at all:
    any function of the input is an affine function of it on two points, and an odd one (a saturation, a dead
    zone) a gain on {−a, 0, a}.  Such data are those of the gain ``f(a)/a`` times the linear plant, whatever the
    plant does at other amplitudes -- which the loop's own input will have.  Measured on the adversarial catalogue
    (a third-order plant behind a saturation at 80 % of a ±1 PRBS): certified at every seed 0–9 with
    ``‖P − P̂‖∞/δ`` of 1.9–7.0 for the small-signal plant, and the true loop short of its δ margin at four of them;
    with a uniform multilevel input the same case certified with ratios 0.25–2.3 and every loop kept its margin
    (12 runs).  A rate limit the input's steps exceed is as invisible on such data, and named too: measured
    (2026-11-28, seeds 0–2, both protocols of the adversarial catalogue) on the third-order and the resonant plant
    behind a rate limit of 0.2 and 0.1 per sample, a ±1 PRBS certified 8 of 12 runs with ``‖P − P̂‖∞/δ`` of 10–60
    for the small-signal plant, 7 of the loops without tracking on it; a Gaussian or uniform input certified 14 of
    18, every loop holding (and a PRBS held 10 samples, whose ramps end before the next step, 6 of 6, holding).

    The levels are found up to noise (:data:`LEVEL_SPREAD`): a two-level input recorded by a sensor is no longer
    two-valued, yet the plant received two levels (or amplitudes within the noise of them), so the record shows
    no more about a nonlinearity than the exact one.

    Parameters
    ----------
    u : array_like, shape (n,) or (n, m)
        The input of the window.
    validation : tuple of array_like, optional
        ``(u_v, y_v)``, the held-out record: its input counts too.

    Returns
    -------
    tuple of str
        One statement per input channel that cannot show such a nonlinearity (empty when every channel takes
        several amplitudes).

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> prbs = np.sign(rng.standard_normal(200))
    >>> len(untested_premises(prbs)), untested_premises(rng.standard_normal(200))
    (1, ())
    >>> print(untested_premises(prbs)[0][:60])
    input 0 takes the values {-1, 1} only: a static input nonlin
    >>> print(untested_premises(prbs + 0.02 * rng.standard_normal(200))[0][:62])   # the same PRBS, measured
    input 0 takes two levels {-1, 1} up to a spread of 0.94 % of t
    """
    u = as_signal(u, "u")  # real, finite, time along axis 0: NaN had made every channel look untestable-free
    if validation is not None:
        u = np.vstack([u, as_signal(validation[0], "validation u", width=u.shape[1])])
    out = []
    for ch in range(u.shape[1]):
        x = u[:, ch]
        scale = float(np.max(np.abs(x))) if x.size else 0.0
        if not scale > 0.0:
            continue  # a silent channel: the excitation tests refuse it
        values = np.unique(np.round(x / (scale * 1e-9)) * (scale * 1e-9))
        magnitudes = np.unique(np.abs(values[values != 0.0]))
        if values.size <= 2 or magnitudes.size <= 1:
            shown = ", ".join(f"{v:.4g}" for v in values)
            what = f"takes the values {{{shown}}} only"
        else:
            levels = _input_levels(x)
            if levels is None:
                continue
            centres, spread = levels
            shown = ", ".join(f"{v:.3g}" for v in centres)
            count, kind = ("two", "two levels") if centres.size == 2 else ("three", "three evenly spaced levels")
            what = (f"takes {kind} {{{shown}}} up to a spread of {100 * spread:.2g} % of their spacing (noise on a "
                    f"recorded {count}-level input, or amplitudes that vary that little)")
        out.append(f"input {ch} {what}: a static input nonlinearity (a saturation or a "
                   "dead zone, a gain that depends on the amplitude) acts on such data as a linear gain, so no test "
                   "on them can see it; nor can they show an actuator rate limit slower than the input's steps (the "
                   "plant receives ramps every time, and P̂ learns a slower plant than the small-signal one); the "
                   "certificate assumes the plant linear at the amplitudes and rates the loop will use (data with "
                   "several input amplitudes, e.g. a multilevel PRBS or Gaussian noise, would show such a "
                   "nonlinearity in the output error)")
    return tuple(out)


def _input_levels(x: np.ndarray) -> tuple[np.ndarray, float] | None:
    """``(levels, spread)`` when ``x`` takes two levels, or three evenly spaced ones, up to a spread below
    :data:`LEVEL_SPREAD`; None when it takes more.  The spread is the rms distance of the samples to their nearest
    level over the levels' spacing, the farthest 1 % left out (a single glitch of a recorded PRBS would otherwise
    hide its two levels); of the fits with two and three levels the tighter one is named."""
    best = None
    for k in (2, 3):
        for start in _kmeans_starts(x, k):
            centres = _kmeans_1d(x, start)
            if centres is None:
                continue
            steps = np.diff(centres)
            if k == 3 and not abs(steps[1] - steps[0]) <= 0.1 * float(np.mean(steps)):
                continue  # uneven levels: an odd nonlinearity about the middle one would show
            distance = np.abs(x - centres[np.searchsorted(0.5 * (centres[1:] + centres[:-1]), x)])
            kept = distance[distance <= np.quantile(distance, 0.99)]
            spread = float(np.sqrt(np.mean(kept ** 2))) / float(np.mean(steps))
            if best is None or spread < best[1]:
                best = (centres, spread)
    return best if best is not None and best[1] < LEVEL_SPREAD else None


def _kmeans_starts(x: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Two starts for :func:`_kmeans_1d`: at the samples' quantiles (robust to a glitch) and evenly over their range
    (a rare level still gets a centre)."""
    lo, hi = float(np.min(x)), float(np.max(x))
    fractions = (np.arange(k) + 0.5) / k
    return np.quantile(x, fractions), lo + (hi - lo) * fractions


def _kmeans_1d(x: np.ndarray, centres: np.ndarray, sweeps: int = 50) -> np.ndarray | None:
    """Sorted centres of the clusters of the samples ``x`` by Lloyd's iteration from ``centres`` (in one dimension
    the clusters are intervals split at the midpoints); None when a cluster empties or two centres coincide."""
    k = centres.size
    for _ in range(sweeps):
        label = np.searchsorted(0.5 * (centres[1:] + centres[:-1]), x)
        counts = np.bincount(label, minlength=k)
        if np.any(counts == 0):
            return None
        new = np.bincount(label, weights=x, minlength=k) / counts
        if np.array_equal(new, centres):
            break
        centres = new
    return centres if np.all(np.diff(centres) > 0) else None


#: a channel whose mean exceeds this fraction of its standard deviation is named by :func:`operating_point_note`
OFFSET_NOTE = 0.1


def operating_point_note(u, y) -> str:
    """Which channels of a record sit at an operating point (a mean above :data:`OFFSET_NOTE` of their standard
    deviation), and what that does to the models; ``''`` when none does.

    The predictor, P̂ and the controller have no constant term, so a record taken around an operating point is read
    as dynamics.  Measured on the adversarial catalogue's third-order and resonant plants (seeds 0–2): a sensor bias
    of 0.5 on outputs of about unit rms gave nearly integrating models and refused 7 of 9 runs, for reasons that do
    not name the bias (an input switching between 0 and 2 certified its 6 PRBS runs, each true on the plant).
    Subtracting the means (``python -m experiments design --detrend mean``) designs on the deviations.

    Parameters
    ----------
    u, y : array_like, shape (n,) or (n, k)
        The record: two or more samples, u and y of one length.  A constant channel away from zero is named as
        such (it has no standard deviation to compare its mean with); a channel that is zero throughout is not.

    Returns
    -------
    str

    Raises
    ------
    DataError
        Bad data, u and y of different lengths, or a single sample.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> u = np.sign(rng.standard_normal(400))
    >>> operating_point_note(u, 0.5 * u)
    ''
    >>> print(operating_point_note(u, 0.5 * u + 2.0)[:45])
    the mean of y (1.972) is 4 times its standard
    """
    u = as_signal(u, "u")
    y = as_signal(y, "y", n=u.shape[0])  # one record: a y of another length is another record's
    if u.shape[0] < 2:
        raise DataError("the record has one sample: it has no standard deviation to compare its mean with; pass the "
                        "whole record (two samples or more)")
    notes = []
    for what, x in (("u", u), ("y", y)):
        mean, spread = x.mean(axis=0), x.std(axis=0)
        for k in range(x.shape[1]):
            name = what if x.shape[1] == 1 else f"{what}[:, {k}]"
            if np.ptp(x[:, k]) == 0.0:  # exactly: the std of a constant is rounding (1e-17 of it), not 0
                # "inf times its standard deviation" said nothing; a channel that is zero throughout has no offset
                if x[0, k] != 0.0:
                    notes.append(f"{name} is constant at {float(x[0, k]):.4g} over the record")
                continue
            # in units of the channel's peak: std of values near 1e-200 underflowed to 0 (ZeroDivisionError)
            peak = float(np.max(np.abs(x[:, k])))
            ratio = abs(float(mean[k]) / peak) / float(np.std(x[:, k] / peak))
            if ratio > OFFSET_NOTE:
                notes.append(f"the mean of {name} ({float(mean[k]):.4g}) is {ratio:.2g} times its standard deviation")
    if not notes:
        return ""
    return ("; ".join(notes) + ": the models have no constant term, so an operating point is read as dynamics (a "
            "nearly integrating P̂); if the record was taken around an operating point, subtract its means "
            "(python -m experiments design --detrend mean)")


#: an output-error sample farther than this many robust standard deviations (1.4826 × the median absolute deviation)
#: from the median is named by :func:`glitch_note`
GLITCH_LEVEL = 8.0


def glitch_note(model, u, y, horizon: int) -> str:
    """Which samples of ``y`` look like a sensor's glitches against the model P̂; ``''`` when none does.

    The output error ``y − P̂u`` (:func:`output_error_residual`) of each output is standardised robustly (median,
    1.4826 × the median absolute deviation); samples beyond :data:`GLITCH_LEVEL` are named when there are a few of
    them (at most 3, or 0.5 % of the record): more is heavy-tailed noise or model error, not glitches.  Nothing is
    said for a P̂ that is not stable (its output error grows and says nothing about single samples).  A note, not a
    test: glitches enlarge δ and bias P̂, so the pipeline refuses such records for reasons that do not name them.
    Measured (a script; the adversarial catalogue's records of seeds 0–9 whose P̂, fitted on the first two thirds, is
    stable: 450): none named without glitches; with 5 spikes of 10 times the output's standard deviation added,
    some named in 59 % of the records and all 5 in 55 % (the rest: P̂ fitted through the spikes, or its error too
    large for single samples to stand out).

    Parameters
    ----------
    model : control.StateSpace
        :func:`unfalsify.predictor_model` of horizon ``horizon``.
    u, y : array_like
        The record.
    horizon : int
        The model's ``i``.

    Returns
    -------
    str

    Examples
    --------
    >>> import numpy as np
    >>> import synthesis as sy
    >>> from unfalsify import predictor_model
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(600)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:600] + 0.05 * rng.standard_normal(600)
    >>> model = predictor_model(sy.fit_predictor(u, y, 3), 1.0)
    >>> glitch_note(model, u, y, 3)
    ''
    >>> y[400] += 5.0                                                       # one glitch
    >>> print(glitch_note(model, u, y, 3)[:60])
    1 sample of y (y[400]) lies more than 8 robust standard devi
    """
    _check_model(model)
    if not spectral_radius(control.ssdata(model)[0]) < 1.0:
        return ""
    e = np.asarray(output_error_residual(model, u, y, horizon), float)
    e = e.reshape(e.shape[0], -1)
    i, n = check_horizon(horizon), e.shape[0]
    notes = []
    for ch in range(e.shape[1]):
        centred = e[:, ch] - np.median(e[:, ch])
        scale = 1.4826 * float(np.median(np.abs(centred)))
        if not (np.isfinite(scale) and scale > 0):
            continue
        big = np.flatnonzero(np.abs(centred) > GLITCH_LEVEL * scale) + i
        if 0 < big.size <= max(3, n // 200):
            name = "y" if e.shape[1] == 1 else f"y[:, {ch}]"
            where = ", ".join(f"{name}[{k}]" if e.shape[1] == 1 else f"row {k}" for k in big[:5])
            count = f"{big.size} sample{'s' if big.size > 1 else ''}"
            notes.append(f"{count} of {name} ({where}{', …' if big.size > 5 else ''}) "
                         f"{'lie' if big.size > 1 else 'lies'} more than {GLITCH_LEVEL:g} robust standard deviations "
                         "from P̂'s output")
    if not notes:
        return ""
    return "; ".join(notes) + ", as a sensor's glitches do: remove or interpolate them (they enlarge δ and bias P̂)"


def _low_bins(n: int, nperseg: int, inputs: int = 1) -> int:
    """Bins below the first Welch frequency (``n/nperseg`` DFT bins), at least 1; 0 when the record is too short
    for :func:`low_band_estimate`'s default window with ``inputs`` input channels."""
    k = max(1, n // nperseg)
    return k if n >= 2 * (k + _lpm_window(inputs)) else 0


def _low_band_inconsistency(est: LowBandEstimate, delta: float) -> tuple[float, str]:
    """``max gap/δ`` (:func:`_model_gap`) over the low frequencies and, where it exceeds 1, why the premise fails."""
    gap = np.where(np.isfinite(est.radius), _model_gap(est), -np.inf)
    if not np.any(np.isfinite(gap)):
        return float("nan"), ""
    k = int(np.argmax(gap))
    worst = _relative_gap(float(gap[k]), delta)
    if not gap[k] > delta:
        return worst, ""
    unit = _unit(est.dt)
    return worst, (f"at low frequency ({_bands(est.frequency, gap > delta, unit)}, below the Welch resolution) the "
                   f"model P̂ lies outside the {est.confidence:.0%} confidence region of the data's response by "
                   f"{gap[k]:.3g} at {est.frequency[k]:.3g} {unit}{_channels(est.response, k)}, more than "
                   f"δ = {delta:.4g}: P̂ misses slow dynamics (an integrator, a slow pole); raise the horizon, or fit "
                   "on a longer record")


#: the line test's level: the chance that one record of Gaussian noise flags a line anywhere (Bonferroni over bins)
LINE_LEVEL = 1e-3
#: bins on each side of a DFT bin whose medians give the local noise level of the output error's periodogram
LINE_HALF_WIDTH = 8
#: bins next to a DFT bin left out of its local level: a line leaks into them through the record's window
LINE_GAP = 2
#: the widest line :func:`residual_line` looks for, in DFT bins: a mode whose power spreads over two or three bins
#: stands out as a group although no single bin does (:func:`_wide_lines`)
LINE_BINS = 3
#: a significant line refuses where ``|Ê/Û|·|M̂| ≥ LINE_LOOP_GAIN`` (the raw DFT ratio underestimates a mode narrower
#: than the bin spacing, so the limit sits well below 1: measured, below)
LINE_LOOP_GAIN = 0.2


def residual_line(model, controller, u, y, horizon: int, dt: float, factors=None) -> tuple[float, float]:
    """The loop gain of the strongest narrow line in P̂'s output error over a whole record.

    The Welch estimate of the premise test sees ``P − P̂`` at the resolution ``2π/(nperseg·dt)`` of short segments of
    the held-out record (16 points over the band for 400 samples).  A lightly damped mode that P̂ misses is narrower
    than that: its output error is a line in the periodogram of the *whole* record, which is many times finer.  Where
    the periodogram ``I_k`` of ``e = y − P̂u`` (:func:`output_error_residual`) stands above
    ``ln(K/LINE_LEVEL)`` times its local level on *both* sides (the larger of the medians of the ``LINE_HALF_WIDTH``
    bins below and above it, ``LINE_GAP`` bins away, over ``ln 2``: an exponential variable's median; ``K`` bins),
    the data show such a line, and its size is measured where the loop sees it: ``|E_k/U_k|·|M̂(e^{jω_k dt})|``.

    Both sides, and only bins with a full window on each: noise that rises towards DC (a drift, AR(0.999)) stands
    above the bins to its right, and was taken for a line at the lowest bins when the level was the median around
    the bin (measured: 6 of 18 loops that held refused, on records with a trend, AR(0.995–0.999) noise, a pole at
    0.99 or 200 samples; none with both sides).

    A mode one to three bin spacings wide (half-power width ``ζω·dt``) splits its power over two or three bins, none
    of them above the one-bin threshold, and the Welch segments are far too short to resolve it: the sums over
    ``w = 2 … LINE_BINS`` adjacent bins are tested too, each against the tail of a sum of ``w`` exponential variables
    at the same level, a group read at its power-weighted centre (:func:`_wide_lines`).  Measured (2026-11-28): a
    FIR plant with a mode at 0.8 rad/sample of pole radius 0.975–0.99 (1200 samples, ±1 input, 4 seeds each): a line
    found in 1 of 16 records by one bin, in 9 with widths up to 3; 300 records without a mode (white or AR(0.9)
    noise, PRBS or Gaussian input): a line found in 9 and 26 of them (found, not refused: a line refuses from
    ``LINE_LOOP_GAIN``).  In the hunt of ``experiments/studies/RESULTS.md`` (2026-11-28, "Plants, actuators and noise
    levels") one false certificate is refused (a ζ = 0.01 mode at 8 rad/s in series with the third-order plant,
    certified in coprime-factor form), no certified loop that held is, and no verdict or δ of the adversarial
    catalogue changed.

    Several inputs and outputs: one bin does not identify the line's transfer ``G`` (``m`` unknowns per output, one
    equation ``E_k = G U_k``), but ``‖G(ω_k)‖₂ ≥ ‖E_k‖/‖U_k‖``, so ``‖E_k‖/‖U_k‖·σ̄(M̂(e^{jω_k dt}))`` (``M̂`` the
    loop's additive channel, :func:`unfalsify.additive_channel`) is a lower bound of the small-gain product ``‖G‖·‖M̂‖``
    at that frequency, the one number the certificate bounds (one input and output: the same ``|E_k/U_k|·|M̂|``).
    The line is searched in each output channel against its own local level (channels can have different noise
    levels, and a sum over them would dilute a line that is in one only), with the ``K`` of the threshold counting
    every bin of every output (Bonferroni).  The coprime-factor form: a line is a fact of ``P − P̂`` whichever form
    bounds it, so the same number counts; and the equation error's line ``M̂_f E_k`` is at most ``‖[Δ_N Δ_M]‖`` times
    ``‖[U_k; Y_k]‖`` (``M̂_f y − N̂_f u = [Δ_N −Δ_M][u; y]``), so ``‖M̂_f E_k‖/‖[U_k; Y_k]‖·σ̄(H)`` bounds the coprime
    small-gain product at that frequency from below; the larger of the two counts (measured: a loop that held on
    the plant, certified with ε = 0.030 for a plant 0.19 from P̂'s factors at its mode, where the additive number
    was 0.14 and the coprime one 0.55).  An unstable P̂ cannot be simulated, but its equation error
    ``ε = M̂_f y − N̂_f u`` (the predictor's one-step error on measured data, finite memory; ``P̂ = M̂_f⁻¹N̂_f``,
    :mod:`unfalsify.coprime`) can: ``M̂_f(e^{jω})⁻¹ Ε(ω)`` is the output error in the frequency domain, up to the
    record's edges (measured on a stable P̂: within 1.5 % of the simulated one's DFT).

    Measured (records of 1200 samples at 10 Hz, the third-order plant in parallel with a mode ``c·ω²/(s² + 2ζωs +
    ω²)``, ω 1.5–3 rad/s, ζ 0.001–0.01, c 0.01–0.03, seeds 0–2, white PRBS and uniform input; record mode): without
    this test 95 of 108 runs certified, 74 of them unstable or without the δ margin on the plant; with it 41 (24 of the
    74 certify a design that holds, 10 are refused, and one run's search moved to a design that fails), and one loop
    that held is refused.  On the adversarial catalogue (record protocol seeds 0–2, validation protocol seed 0; 208
    runs) no verdict changed.  With several channels, the coprime-factor form and an unstable P̂ covered (2026-11-28,
    old and new tree in one session): of the 41, 5 were certified in coprime form; 3 are now refused, the other 2
    show no significant line (38 remain); 2 × 2 coupled lags with a ζ = 0.003 mode at 0.2 rad/s (from u₁ to y₁, or
    from both inputs to both outputs; PRBS and uniform input, seeds 0–2, the protocol of
    :mod:`experiments.studies.mimo_pipeline`): 9 of 12 runs certified, 8 false, before; 1 certified, none false,
    after (one loop that held refused, its premise false on the plant: ``‖P − P̂‖∞/δ`` = 167); no verdict changed on
    the catalogue (record protocol seeds 0–1, validation protocol seed 0; 156 runs, 10 loops certified in coprime
    form among them).  A mode whose line stays below the noise -- sharper or weaker -- is not seen: no finite
    record excludes it; :func:`hidden_line_gain` measures the loop gain such a line could carry.

    Parameters
    ----------
    model : control.StateSpace
        P̂, :func:`unfalsify.predictor_model` of horizon ``horizon`` (m inputs, l outputs, stable or not).
    controller : control.StateSpace
        ``K`` with inputs ``[r; y]``.
    u, y : array_like, shape (n,) or (n, m) and (n, l)
        The record.
    horizon : int
    dt : float
    factors : CoprimeFactors, optional
        P̂'s coprime factors (:func:`unfalsify.coprime_factors`), for a loop certified in coprime-factor form: each
        line then counts with the larger of ``‖E_k‖/‖U_k‖·σ̄(M̂)`` and ``‖M̂_f E_k‖/‖[U_k; Y_k]‖·σ̄(H)``, ``H`` the
        coprime channel (:func:`unfalsify.coprime_channel`).

    Returns
    -------
    (float, float)
        The largest loop gain over the significant lines (0 without one) and its frequency (NaN without).

    Examples
    --------
    A FIR plant and the loop ``u = 0.2(r − y)``; then the same plant with a mode at 0.8 rad/sample (pole radius
    0.999) that the predictor of horizon 3 cannot follow:

    >>> import control
    >>> import numpy as np
    >>> import scipy.signal
    >>> import synthesis as sy
    >>> from unfalsify import predictor_model
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(600)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:600] + 0.01 * rng.standard_normal(600)
    >>> K = control.ss([], [], [], [[0.2, -0.2]], 1.0)                     # inputs [r; y]
    >>> residual_line(predictor_model(sy.fit_predictor(u, y, 3), 1.0), K, u, y, 3, 1.0)
    (0.0, nan)
    >>> y2 = y + scipy.signal.lfilter([0.0, 0.02], [1.0, -2 * 0.999 * np.cos(0.8), 0.999 ** 2], u)
    >>> pred = sy.fit_predictor(u, y2, 3)
    >>> gain, w = residual_line(predictor_model(pred, 1.0), K, u, y2, 3, 1.0)
    >>> bool(gain >= LINE_LOOP_GAIN), round(w, 2)
    (True, 0.8)
    >>> from unfalsify import coprime_factors                             # the loop in coprime-factor form
    >>> gain_c, _ = residual_line(predictor_model(pred, 1.0), K, u, y2, 3, 1.0, coprime_factors(pred, 1.0))
    >>> bool(gain_c >= gain)                                              # the larger of the two numbers
    True
    """
    return _line_gain(_residual_lines(model, u, y, horizon, dt), model, controller, dt, factors)


#: the hidden-line loop gain from which a certificate states that it assumes no mode below the noise: from 1 on, a
#: line the test cannot see could break the small-gain condition at its frequency (LINE_LOOP_GAIN = 0.2 would state
#: it for every certified loop of the catalogue: measured in :func:`hidden_line_gain`)
HIDDEN_LINE_LIMIT = 1.0


def hidden_line_gain(model, controller, u, y, horizon: int, dt: float, factors=None) -> tuple[float, float]:
    """The loop gain of the largest narrow line the record could hide below :func:`residual_line`'s threshold.

    :func:`residual_line` sees a lightly damped mode of ``P − P̂`` only where its line stands above
    ``ln(K/LINE_LEVEL)`` times the local level of the output error's periodogram; no finite record excludes a line
    below that.  At each bin the test applies to (a full local level on both sides), the largest hidden line has
    ``‖E_k‖ = sqrt(Σ_o ln(K/LINE_LEVEL)·level_ko)`` (at the threshold of every output ``o``), and it counts as
    :func:`residual_line` counts a line, ``‖E_k‖/‖U‖·σ̄(M̂(e^{jω_k dt}))``, and with ``factors`` the larger of that
    and ``σ̄(M̂_f)‖E_k‖/‖[U; Y]‖·σ̄(H)``, but with ``‖U‖`` (``‖[U; Y]‖``) the root of the mean of ``‖U_j‖²``
    (``‖[U_j; Y_j]‖²``) over the bins ``j`` within ``LINE_HALF_WIDTH + LINE_GAP`` of ``k``: a mode narrower than a
    bin is driven by the input at its own frequency, between bins, whose expected power is that local mean and not
    one bin's (with ``‖U_k‖`` alone, a PRBS's weak bins and the nulls of a held input put ``X`` ≥ 1.8 on every
    certified loop of the adversarial catalogue).  The maximum over the bins, ``X``, is the loop gain of a line that
    can stay below the noise.  It depends on the record and the loop, not on the plant: about
    ``sqrt(ln(K/LINE_LEVEL))`` times the ratio of the output error's to the input's local spectrum times ``σ̄(M̂)``,
    so more input power at that frequency (or a loop less sensitive there) lowers it; a longer record does not lower
    ``X`` (the line and the noise grow alike) but resolves narrower modes, whose line underestimates their peak less.

    From :data:`HIDDEN_LINE_LIMIT` = 1 on, a line the test cannot see could carry a loop gain the small-gain
    condition does not cover (``δ·σ̄(M̂) < 1/(1 + margin)``): even a mode as wide as the record's resolution, whose
    line measures its gain, could destabilise the loop unseen, and :func:`unfalsify.robust_design_from_data` states
    that in ``assumed``.  Below 1 only a mode narrower than the resolution could, as for any finite record.  Measured
    (2026-11-28; ``experiments/studies/RESULTS.md``, "A lightly damped mode that P̂ misses"): on the family of
    :func:`residual_line` (108 runs) the 38 false certificates have ``X`` 0.20–3.07 (median 1.71; 31 from 1 on, the
    other 7 all ζ = 0.001 modes, narrower than the resolution), the 42 loops that hold 0.18–3.57 (median 0.55; 9
    from 1 on); the 81 certified loops of the adversarial catalogue 0.23–13.2 (median 1.68; 65 from 1 on, every one
    from 0.2 on): ``X`` names what a record cannot see, it does not tell false certificates from true ones.

    Parameters
    ----------
    model, controller, u, y, horizon, dt, factors
        As for :func:`residual_line`.

    Returns
    -------
    (float, float)
        ``X`` and the frequency where it is reached; ``(inf, nan)`` where the record is too short for the line test
        (it then excludes no line).

    Examples
    --------
    The loop of :func:`residual_line`'s example: the same record hides less at a tenth of the noise.

    >>> import control
    >>> import numpy as np
    >>> import synthesis as sy
    >>> from unfalsify import predictor_model
    >>> rng = np.random.default_rng(0)
    >>> u, v = rng.standard_normal(600), rng.standard_normal(600)
    >>> K = control.ss([], [], [], [[0.2, -0.2]], 1.0)                     # inputs [r; y]
    >>> gains = []
    >>> for noise in (0.1, 0.01):
    ...     y = np.convolve(u, [0.0, 1.0, 0.5])[:600] + noise * v
    ...     model = predictor_model(sy.fit_predictor(u, y, 3), 1.0)
    ...     gains.append(hidden_line_gain(model, K, u, y, 3, 1.0)[0])
    >>> bool(gains[1] < gains[0] / 5)
    True
    >>> hidden_line_gain(model, K, u[:60], y[:60], 3, 1.0)                # too short for the line test
    (inf, nan)
    """
    return _hidden_gain(_line_spectra(model, u, y, horizon, dt)[1], model, controller, dt, factors)


def _hidden_gain(hidden, model, controller, dt: float, factors=None) -> tuple[float, float]:
    """:func:`hidden_line_gain` from the ``hidden`` arrays of :func:`_line_spectra` (``(inf, nan)`` without)."""
    if hidden is None or not hidden[0].size:
        return float("inf"), float("nan")
    return _line_gain(hidden, model, controller, dt, factors)


def _hidden_line_statement(gain: float, freq: float, dt: float) -> str:
    """The statement for ``assumed`` of a loop whose hidden-line gain reaches :data:`HIDDEN_LINE_LIMIT`."""
    where = (f"at {freq:.3g} {_unit(dt)}" if np.isfinite(freq) else "anywhere (the record is too short for the "
             "narrow-line test)")
    return (f"P − P̂ has no lightly damped mode whose line stays below the record's noise {where}: there a line the "
            f"narrow-line test cannot see could carry a loop gain of {gain:.3g} ≥ {HIDDEN_LINE_LIMIT:g} "
            "(hidden_line_gain), more than the small-gain condition covers; more input power at that frequency lowers "
            "it, and a longer record resolves narrower modes")


def _residual_lines(model, u, y, horizon: int, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The significant narrow lines of P̂'s output error over a record (:func:`residual_line`): their frequencies,
    ``‖E_k‖/‖U_k‖`` and ``‖M̂_f E_k‖/‖[U_k; Y_k]‖`` there (the additive and the coprime-factor perturbation the line
    shows at least), empty arrays without one.  They depend on P̂ and the record only, not on the controller: the
    design search computes them once and weighs them with each loop (:func:`_line_gain`)."""
    return _line_spectra(model, u, y, horizon, dt)[0]


def _line_spectra(model, u, y, horizon: int, dt: float) -> tuple[tuple, tuple | None]:
    """``(lines, hidden)``: the significant lines of :func:`_residual_lines`, and the same three arrays for the
    largest line each tested bin could hide (:func:`hidden_line_gain`): ``‖E_k‖`` at the detection threshold of every
    output, ``sqrt(Σ_o ln(K/LINE_LEVEL)·level_ko)``, over the local root-mean-square of ``‖U_j‖``, and ``σ̄(M̂_f)``
    times that over the local one of ``‖[U_j; Y_j]‖``.  ``hidden`` is None where the record is too short for the
    test (it then excludes no line).  Neither depends on the controller: computed once, weighed with each loop by
    :func:`_line_gain`."""
    none = np.zeros(0), np.zeros(0), np.zeros(0)
    # the public entries (residual_line, hidden_line_gain) had raised IndexError, TypeError or ZeroDivisionError on a
    # scalar record, a fractional horizon or dt = 0
    horizon = check_horizon(horizon)
    _check_model(model)
    dt = _model_dt(model, dt)  # a dt other than P̂'s had been taken: the line's frequency came out in wrong units
    u, y = channel_pair(u, y)
    x = u
    if x.shape[0] - horizon < 8 * (LINE_HALF_WIDTH + LINE_GAP):  # too few bins for a local level on each side
        return none, None
    E, U, Y, M = _output_error_dft(model, u, y, horizon)
    power = np.abs(E) ** 2                                               # (K, l): each output channel on its own
    sides = np.lib.stride_tricks.sliding_window_view(power, LINE_HALF_WIDTH, axis=0)  # power[k : k + LINE_HALF_WIDTH]
    level = np.full(power.shape, np.inf)
    reach = LINE_HALF_WIDTH + LINE_GAP                                   # bins k with a full window on each side
    level[reach:-reach] = _local_level(sides, np.arange(reach, power.shape[0] - reach), 1)
    size = np.linalg.norm(U, axis=1)
    threshold = np.log(power.size / LINE_LEVEL)  # Bonferroni over every bin of every output channel
    freq = 2.0 * np.pi * np.arange(1, power.shape[0] + 1) / ((x.shape[0] - horizon) * dt)
    joint = np.hypot(size, np.linalg.norm(Y, axis=1))
    lines = _merge_lines([_wide_lines(E, M, power, sides, size, joint, freq, w) for w in range(1, LINE_BINS + 1)])
    # a mode narrower than a bin is driven by the input at its own frequency, between bins, whose expected power is
    # the local mean of |U_k|², not one bin's (measured: |U_k| alone put X ≥ 1.8 on every certified catalogue loop,
    # at a PRBS's weak bins and the nulls of a held input)
    local_u, local_w = _local_mean(size ** 2, reach), _local_mean(joint ** 2, reach)
    tested = np.all(np.isfinite(level), axis=1) & (local_u > 0)
    edge = np.sqrt(threshold * level[tested].sum(axis=1))  # the largest ‖E_k‖ below the threshold of every output
    hidden = (freq[tested], edge / np.sqrt(local_u[tested]),
              edge * np.linalg.norm(M[tested], ord=2, axis=(1, 2)) / np.sqrt(local_w[tested]))
    return lines, hidden


def _wide_lines(E, M, power, sides, size, joint, freq, w: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The significant lines of :func:`_line_spectra` that span ``w`` adjacent bins: where the periodogram summed over
    bins ``k … k + w − 1`` stands above ``t_w`` times the local level (the larger median of the ``LINE_HALF_WIDTH``
    bins ``LINE_GAP`` away on either side of the group, over ``ln 2``), ``t_w`` the level ``LINE_LEVEL/K`` of a sum
    of ``w`` exponential variables (``w = 1``: ``ln(K/LINE_LEVEL)``, the one-bin test).  The line's size is that of
    the group, ``‖E‖/‖U‖`` and ``‖M̂_f E‖/‖[U; Y]‖`` over its bins (:func:`_group_input`), at the power-weighted
    centre of its bins (one bin: the bin itself).

    Why several bins: a mode of ``P − P̂`` whose half-power width ``ζω·dt`` is one to three bin spacings splits its
    power over two or three bins, each below the one-bin threshold, and raises the bins next to them, while the Welch
    test's segments are too short to resolve it (measured: the third-order plant in series with a ζ = 0.01 mode at
    8 rad/s, 1200 samples at 10 Hz, white PRBS, record mode: no bin above the one-bin threshold, a loop certified in
    coprime-factor form without its ε margin on the plant; groups of two and three bins at 7.97 rad/s with
    ``‖E‖/‖U‖`` = 0.37 and 0.39, and the search found no loop that tolerates them).
    """
    K, reach = power.shape[0], LINE_HALF_WIDTH + LINE_GAP
    starts = np.arange(reach, K - reach - w + 1)                # groups with a full local window on each side
    none = np.zeros(0), np.zeros(0), np.zeros(0)
    if starts.size == 0:
        return none
    group = np.sum([power[starts + j] for j in range(w)], axis=0)  # (groups, l)
    level = _local_level(sides, starts, w)
    threshold = float(scipy.special.gammainccinv(w, LINE_LEVEL / power.size))  # Bonferroni as the one-bin test
    u2 = _group_input(size ** 2, starts, w)
    with np.errstate(divide="ignore", invalid="ignore"):
        line = np.any(group > threshold * level, axis=1) & (u2 > 0)
    if not line.any():
        return none
    starts, group, u2 = starts[line], group[line], u2[line]
    bins = [starts + j for j in range(w)]
    weight = np.array([np.sum(power[b], axis=1) for b in bins])          # (w, groups): where in the group the power is
    centre = np.sum(weight * np.array([freq[b] for b in bins]), axis=0) / np.sum(weight, axis=0)
    coprime2 = np.sum([np.sum(np.abs((M[b] @ E[b][:, :, None])[:, :, 0]) ** 2, axis=1) for b in bins], axis=0)
    return centre, np.sqrt(np.sum(group, axis=1) / u2), np.sqrt(coprime2 / _group_input(joint ** 2, starts, w))


def _local_level(sides: np.ndarray, starts: np.ndarray, w: int) -> np.ndarray:
    """The periodogram's local level beside each group of ``w`` bins from ``starts``: the larger median of the
    ``LINE_HALF_WIDTH`` bins ``LINE_GAP`` away on either side (``sides[k]`` = the bins ``k … k + LINE_HALF_WIDTH − 1``),
    over ``ln 2`` (an exponential variable's median over its mean)."""
    reach = LINE_HALF_WIDTH + LINE_GAP
    return np.maximum(np.median(sides[starts - reach], axis=-1),
                      np.median(sides[starts + w + LINE_GAP], axis=-1)) / np.log(2.0)


def _group_input(x2: np.ndarray, starts: np.ndarray, w: int) -> np.ndarray:
    """The input's power over the group of ``w`` bins from each of ``starts``: one bin's own (``w = 1``, the one-bin
    test as it was); wider groups at least ``w`` times the mean over the group and its local windows.  A group
    in a null of the input (a held PRBS's at multiples of 1/hold cycles per sample) has almost no input power, and
    ``‖E‖/‖U‖`` there is no mode's gain: measured, an integrating plant under a PRBS held 10 samples showed a 3-bin
    group at 0.0983 cycles/sample with ``‖E‖/‖U‖`` = 1.74, and the loop that holds on the plant was refused."""
    own = np.sum([x2[starts + j] for j in range(w)], axis=0)
    if w == 1:
        return own
    reach = LINE_HALF_WIDTH + LINE_GAP
    local = np.array([np.mean(x2[k - reach: k + w + reach]) for k in starts])
    return np.maximum(own, w * local)


def _merge_lines(found: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The lines of every width of :func:`_wide_lines` together (a mode may show at several widths: each counts)."""
    return tuple(np.concatenate([f[k] for f in found]) for k in range(3))


def _local_mean(x: np.ndarray, reach: int) -> np.ndarray:
    """The mean of ``x`` over the bins ``k − reach … k + reach`` (NaN where that window is not full)."""
    out = np.full(x.shape, np.nan)
    if x.size > 2 * reach:
        out[reach:-reach] = np.convolve(x, np.ones(2 * reach + 1) / (2 * reach + 1), mode="valid")
    return out


def _output_error_dft(model, u, y, horizon: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(E, U, Y, M)``: the DFT of P̂'s output error, of the input and of the output over the record after the first
    ``horizon`` samples, bins 1 … n/2 − 1, shapes (K, l), (K, m), (K, l), and ``M̂_f`` at those bins (K, l, l).

    A stable P̂ is simulated (:func:`output_error_residual`).  An unstable one cannot be (its simulation diverges),
    but its equation error ``ε = M̂_f y − N̂_f u`` (the one-step error of the predictor on measured data: finite
    memory, no simulation; :meth:`~unfalsify.CoprimeFactors.residual` of P̂'s factors ``P̂ = M̂_f⁻¹N̂_f``) can, and
    ``M̂_f(e^{jω})⁻¹ Ε(ω)`` is the output error in the frequency domain, up to the record's edges.
    """
    u, y = channel_pair(u, y)
    output_error_residual(model, u[: horizon + 1], y[: horizon + 1], horizon)  # checks the model against the data
    factors = _model_factors(model, horizon)
    x, z = u.reshape(u.shape[0], -1)[horizon:], y.reshape(y.shape[0], -1)[horizon:]
    n = x.shape[0]
    M = factors.response(2.0 * np.pi * np.arange(1, n // 2) / (n * _step(model.dt)))[1]  # rfft's bins 1 … n/2 − 1
    if spectral_radius(control.ssdata(model)[0]) < 1.0:
        E = _centred_dft(output_error_residual(model, u, y, horizon).reshape(n, -1))
    else:
        E = _centred_dft(factors.residual(u, y).reshape(n, -1))
        E = (np.linalg.pinv(M) @ E[:, :, None])[:, :, 0]  # pinv: a pole of P̂ on the unit circle stays finite
    return E, _centred_dft(x), _centred_dft(z), M


def _centred_dft(x: np.ndarray) -> np.ndarray:
    """The DFT of ``x`` (time along axis 0) less its mean, bins 1 … n/2 − 1."""
    return np.fft.rfft(x - x.mean(axis=0), axis=0)[1:-1]


def _line_gain(lines: tuple[np.ndarray, np.ndarray, np.ndarray], model, controller, dt: float,
               factors=None) -> tuple[float, float]:
    """The largest ``‖E_k‖/‖U_k‖·σ̄(M̂)`` over the lines of :func:`_residual_lines` and its frequency ((0, NaN)
    without); with ``factors`` (P̂'s coprime factors) the larger of that and ``‖M̂_f E_k‖/‖[U_k; Y_k]‖·σ̄(H)``,
    ``H`` the coprime channel (:func:`unfalsify.coprime_channel`)."""
    freq, ratio, coprime = lines
    if not freq.size:
        return 0.0, float("nan")
    gain = ratio * _peak_gain(additive_channel(model, controller), freq, dt)
    if factors is not None:
        gain = np.maximum(gain, coprime * _peak_gain(coprime_channel(factors, controller), freq, dt))
    k = int(np.argmax(gain))
    return float(gain[k]), float(freq[k])


def _peak_gain(sys, freq: np.ndarray, dt: float) -> np.ndarray:
    """``σ̄(sys(e^{jω dt}))`` at each frequency."""
    return np.linalg.norm(_bin_response(sys, freq, 0.0, dt, points=1)[:, 0], ord=2, axis=(1, 2))
