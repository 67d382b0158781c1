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
2. **A nonparametric frequency response** (:func:`frequency_response_estimate`): Welch cross-spectra
   of the input and the same output error, ``D̂ = S_ue/S_uu`` -- an estimate of ``P − P̂`` that needs no
   model -- with a simultaneous confidence disk of radius ``r(ω)`` at every frequency (Bendat &
   Piersol: ``r² = 2/(ν − 2) · F_{2, 2(ν−2)}(1 − α) · S_vv/S_uu``, ``S_vv = S_ee − |S_ue|²/S_uu``, ν the
   equivalent number of independent averages, α Bonferroni-split over the frequencies).  Estimating
   the *difference* keeps Welch's leakage bias small where P̂ is good (a lightly damped resonance of
   P itself would bias a direct estimate of P far beyond its confidence disk).  Where the input
   excites the plant (input spectrum above ``EXCITATION_FLOOR`` × its peak) and ``|D̂| − r > δ``, P̂
   is inconsistent with the record by more than the δ being certified: the certificate is refused
   and the reason names the frequencies.  Below the first Welch frequency -- where each detrended
   segment is blind, and where a slow pole or an integrator that P̂ misses lives -- the whole record's
   DFT is fitted by the local polynomial method (:func:`low_band_estimate`) with its own disks, and
   the same rule applies (measured: a 4th-order 50 Hz plant whose P̂ had 0.27 of the DC gain passed
   every Welch frequency and Theorem 7.1's noise ball, and its certified loop did not track).
3. **Excitation where the loop is sensitive** (:func:`check_excitation`, per design).  With
   ``M̂ = (I − C_y P̂)⁻¹ C_y`` (= ``−K(I + P̂K)⁻¹``), the loop is certified only when at every Welch
   frequency the whole confidence disk lies where the loop is stable frequency by frequency:
   ``(|D̂| + r) · max_bin |M̂| < 1``.  Where the input has no power, ``r`` is large and the test
   fails unless ``|M̂|`` is small there: the reason names the band and the input that would fix it.
   The lowest frequency of the grid stands for the band below half the resolution (each segment is
   detrended, so it estimates the band around zero, not the mean): it is tested like the others --
   measured, leaving it out let a model whose error sat below 0.05 rad/sample through.  Its disk is an
   average over the window's main lobe, not a bound on the band: where P̂ misses a slow mode the error
   grows towards DC inside that bin, and the disk does not hold there (measured on the adversarial
   catalogue: 0.016 ± 0.055 where the error at DC was 0.73, and 0.025 ± 0.115 against 1.24).  Below half
   the resolution the low band is the estimate to trust, and it refuses on evidence only (item 2); a
   "must fit" rule there cost 33 of 203 loops that held on the true plant, so it is not used.

Several inputs and outputs (u: (n, m), y: (n, l)).  Items 2 and 3 are stated in the spectral norm: the
Welch estimate is the H1 estimator ``D̂ = S_eu S_uu⁻¹`` (l × m per frequency) and its region a radius
``‖D − D̂‖₂ ≤ r`` -- per output row an F-based ellipsoid (Goodman; Bendat & Piersol), Bonferroni over the
rows and frequencies, turned into ``r = sqrt(Σ_r ρ_r²/λ_min(S_uu))``
(:func:`frequency_response_estimate`); the low band does the same with the local polynomial method;
inconsistency is ``‖D̂‖₂ − r > δ``; a frequency is excited when ``λ_min(S_uu)`` reaches the floor; and the
loop tests look at the perturbation's loop gain in the loop's own directions,
``σ̄(D̂M̂) ± r·σ̄(M̂)`` (:func:`check_excitation`).  With one input and one output every number is the SISO
one above.

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
import scipy.stats

from synthesis.results import result
from synthesis.validation import DataError, as_signal, check_count, check_sample_time

from ._common import channel_pair
from .arx import ArxResult, arx_unfalsify
from .certify import additive_channel, coprime_channel

__all__ = [
    "EXCITATION_FLOOR",
    "PremiseOptions",
    "FrequencyResponseEstimate",
    "frequency_response_estimate",
    "LowBandEstimate",
    "low_band_estimate",
    "OutputErrorResult",
    "output_error_residual",
    "output_error_unfalsify",
    "PremiseTest",
    "check_premise",
    "ExcitationCheck",
    "check_excitation",
    "untested_premises",
]

#: input power spectrum below this fraction of its peak: the frequency is not excited.
EXCITATION_FLOOR = 1e-3
#: correlation of adjacent Hann segments at 50 % overlap, for Welch's equivalent number of averages.
_HANN_OVERLAP_CORRELATION = 0.167
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


def _check_confidence(confidence) -> float:
    if isinstance(confidence, bool) or not isinstance(confidence, numbers.Real) or not 0.0 < confidence < 1.0:
        raise DataError(f"confidence must lie in (0, 1), got {confidence!r}")
    return float(confidence)




@result
@dataclass(frozen=True, eq=False)
class FrequencyResponseEstimate:
    """Welch estimate ``Ĝ = S_yu S_uu⁻¹`` of a frequency response, with a simultaneous confidence radius.

    SISO (one input and one output) fields are 1-D per frequency, as they always were; with several
    inputs ``m`` or outputs ``l`` (MIMO) the spectra are matrices per frequency (shapes below).  The
    confidence region is always a radius on the spectral norm, ``‖G − Ĝ‖₂ ≤ r`` (for SISO the disk
    ``|G − Ĝ| ≤ r``), so the tests that use it read the same for both.

    Attributes
    ----------
    frequency : ndarray, shape (F,)
        Frequencies in rad/s (``dt`` given) from 0 to Nyquist.
    response : ndarray, complex, shape (F,) or (F, l, m)
        ``Ĝ(e^{jω dt})``; NaN where the input spectrum is singular.
    radius : ndarray, shape (F,)
        Radius of the confidence region around ``Ĝ`` in the spectral norm (``inf`` where the input has no
        power in some direction).
    coherence : ndarray, shape (F,) or (F, l)
        Magnitude-squared coherence (MIMO: the multiple coherence of each output with all inputs).
    input_psd : ndarray, shape (F,) or (F, m, m)
        ``S_uu`` (MIMO: the Hermitian cross-spectral matrix ``E[U Uᴴ]``; its diagonal holds each input's
        auto-spectrum).
    noise_psd : ndarray, shape (F,) or (F, l, l)
        The incoherent output spectrum ``S_vv = S_yy − S_yu S_uu⁻¹ S_uy`` (SISO ``S_yy − |S_yu|²/S_uu``).
    averages : float
        Equivalent number of independent averages ν.
    confidence : float
        Simultaneous confidence of the regions over all frequencies (and outputs).
    nperseg : int
        Segment length (resolution ``2π/(nperseg·dt)``).
    dt : float
        Sample time.
    """

    frequency: np.ndarray
    response: np.ndarray
    radius: np.ndarray
    coherence: np.ndarray
    input_psd: np.ndarray
    noise_psd: np.ndarray
    averages: float
    confidence: float
    nperseg: int
    dt: float

    @property
    def inputs(self) -> int:
        """``m``, the number of input channels."""
        return 1 if self.response.ndim == 1 else int(self.response.shape[2])

    @property
    def outputs(self) -> int:
        """``l``, the number of output channels."""
        return 1 if self.response.ndim == 1 else int(self.response.shape[1])

    @property
    def gain(self) -> np.ndarray:
        """``‖Ĝ‖₂`` per frequency, shape (F,): ``|Ĝ|`` for SISO, the largest singular value for MIMO."""
        return _spectral_norm(self.response)

    @property
    def excited(self) -> np.ndarray:
        """Frequencies whose input power is at least :data:`EXCITATION_FLOOR` times the peak.

        MIMO: the *smallest* eigenvalue of ``S_uu`` against the peak of its largest one over all
        frequencies.  The radius grows like ``λ_min(S_uu)^(−1/2)``: an input direction without power (a silent
        channel, or two channels that move together) leaves ``Ĝ`` undetermined there however large the
        trace is, so the trace would call such a frequency excited.
        """
        if self.input_psd.ndim == 1:
            return self.input_psd >= EXCITATION_FLOOR * float(np.max(self.input_psd))
        lam = np.linalg.eigvalsh(self.input_psd)
        return lam[:, 0] >= EXCITATION_FLOOR * float(np.max(lam[:, -1]))

    @property
    def resolution(self) -> float:
        """Spacing of the frequencies, rad/s."""
        return float(2.0 * np.pi / (self.nperseg * self.dt))


def _spectral_norm(response: np.ndarray) -> np.ndarray:
    """``|Ĝ|`` of a (F,) response, the largest singular value per frequency of a (F, l, m) one (NaN stays NaN)."""
    if response.ndim == 1:
        return np.abs(response)
    if response.shape[1:] == (1, 1):  # |·| exactly, as SISO (the SVD differs in the last bit)
        return np.abs(response[:, 0, 0])
    finite = np.all(np.isfinite(response), axis=(1, 2))
    out = np.full(response.shape[0], np.nan)
    if np.any(finite):
        out[finite] = np.linalg.norm(response[finite], ord=2, axis=(1, 2))
    return out


def _record_pair(u, y, prefix: str = "", m: int | None = None, l: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(u, y)`` as (n, m) and (n, l) float arrays of one length (time along axis 0; DataError otherwise)."""
    try:
        u = as_signal(u, f"{prefix}u", width=m)
        y = as_signal(y, f"{prefix}y", n=u.shape[0], width=l)
    except DataError as exc:
        raise DataError(f"{exc} (u: (n, m) inputs, y: (n, l) outputs or output errors, time along axis 0"
                        + (", every segment with the channels of the first record)" if prefix else ")")) from None
    return u, y


def _segment_length(n: int) -> int:
    """A power of two giving at least eight Welch segments, within 16–256."""
    return int(min(256, max(16, 2 ** int(math.floor(math.log2(max(n // 8, 1)))))))


def frequency_response_estimate(u, y, dt: float = 1.0, *, nperseg: int | None = None, confidence: float = 0.99,
                                segments=()) -> FrequencyResponseEstimate:
    """Nonparametric frequency response by Welch cross-spectra (the H1 estimator), with a confidence radius.

    SISO: ``Ĝ = S_yu/S_uu`` with the disk of Bendat & Piersol (module docstring, item 2),
    ``r² = 2/(ν − 2) · F_{2, 2(ν−2)}(1 − α) · S_vv/S_uu``, α = (1 − confidence)/F.

    MIMO (u: (n, m), y: (n, l)): ``Ĝ = S_yu S_uu⁻¹`` (l × m per frequency) from the cross-spectral
    matrices ``S_uu = E[U Uᴴ]``, ``S_yu = E[Y Uᴴ]`` (same segments, window and weighting as SISO).
    Derivation of the radius.  At one frequency the ν segment DFTs satisfy, per output row ``r``,
    ``Y_{r,k} = g_r U_k + V_{r,k}``: a complex least-squares problem with ``m`` regressors.  With
    independent circular Gaussian ``V`` of variance σ_r², ``(ĝ_r − g_r) ν S_uu (ĝ_r − g_r)ᴴ/σ_r²`` is
    ``χ²_{2m}/2`` and the residual ``ν Ŝ_vv,r/σ_r²`` is ``χ²_{2(ν−m)}/2``, independent of it, so
    (Goodman 1965; Bendat & Piersol, multiple-input systems)
    ``(ĝ_r − g_r) Ŝ_uu (ĝ_r − g_r)ᴴ ≤ m/(ν − m) · F_{2m, 2(ν−m)}(1 − α) · Ŝ_vv,r``.  For m = 1 this
    is ``1/(ν − 1)·F_{2, 2(ν−1)}`` where the SISO disk above uses ``2/(ν − 2)·F_{2, 2(ν−2)}``: about twice
    as wide in ``r²``, a margin for the overlapping Hann segments, whose ν is only an equivalent count.
    To keep SISO results unchanged and state one rule, the region used for every ``m`` is
    ``ρ_r² = 2m/(ν − 2m) · F_{2m, 2(ν−2m)}(1 − α) · Ŝ_vv,r``, which contains Goodman's (larger factor,
    fewer degrees of freedom), with α = (1 − confidence)/(F·l) (Bonferroni over the frequencies and the
    outputs, so all ``l`` ellipsoids at all ``F`` frequencies hold together).  Each ellipsoid gives
    ``‖ĝ_r − g_r‖² ≤ ρ_r²/λ_min(Ŝ_uu)``, and ``‖G − Ĝ‖₂ ≤ ‖G − Ĝ‖_F``, so
    ``r = sqrt(Σ_r ρ_r² / λ_min(Ŝ_uu))`` -- the SISO disk for m = l = 1.  ``r = inf`` where ν ≤ 2m + ½
    or ``S_uu`` is singular (``λ_min ≤ 10⁻¹²·λ_max``; there ``Ĝ`` is NaN).

    Parameters
    ----------
    u : array_like, shape (n,) or (n, m)
        Input record (open loop; in closed loop the estimate is biased towards the inverse controller
        wherever the noise dominates).
    y : array_like, shape (n,) or (n, l)
        Output record (for the premise test, the output error ``y − P̂u``).
    dt : float
        Sample time (frequencies in rad/s).
    nperseg : int, optional
        Segment length (Hann window, 50 % overlap); default a power of two giving at least eight
        segments, 16–256.
    confidence : float
        Simultaneous confidence of the regions over all frequencies and outputs (Bonferroni).
    segments : sequence of (u, y), optional
        Further records of the same plant (e.g. a held-out segment), with the channels of the first;
        their spectra are averaged with the first one's, weighted by their number of Welch segments.

    Returns
    -------
    FrequencyResponseEstimate
        ``response`` (F,) for m = l = 1, (F, l, m) otherwise; ``radius`` (F,) always.

    Raises
    ------
    DataError
        NaN, mismatched lengths or channels, fewer samples than two segments, a confidence outside (0, 1).

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(4096)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:4096] + 0.1 * rng.standard_normal(4096)
    >>> est = frequency_response_estimate(u, y)
    >>> G = np.exp(-1j * est.frequency) + 0.5 * np.exp(-2j * est.frequency)
    >>> bool(np.all(np.abs(est.response - G) <= est.radius))
    True

    Two inputs, two outputs: ``y₁ = u₁(k−1)``, ``y₂ = 0.5 u₁ + u₂(k−1)``.

    >>> U = rng.standard_normal((4096, 2))
    >>> Y = np.column_stack([np.r_[0.0, U[:-1, 0]], 0.5 * U[:, 0] + np.r_[0.0, U[:-1, 1]]])
    >>> est = frequency_response_estimate(U, Y + 0.1 * rng.standard_normal((4096, 2)))
    >>> est.response.shape == (est.frequency.size, 2, 2), est.radius.shape == est.frequency.shape
    (True, True)
    >>> z = np.exp(-1j * est.frequency)
    >>> G = np.stack([np.stack([z, 0 * z], -1), np.stack([0.5 + 0 * z, z], -1)], -2)
    >>> bool(np.all(np.linalg.norm(est.response - G, ord=2, axis=(1, 2)) <= est.radius))
    True
    """
    _check_confidence(confidence)
    dt = check_sample_time(dt, "dt", allow_true=False)
    if nperseg is not None:
        nperseg = check_count(nperseg, "nperseg", 4)
    first = _record_pair(u, y)
    m, l = first[0].shape[1], first[1].shape[1]
    pairs = [first] + [_record_pair(us, ys, f"segments[{k}] ", m, l) for k, (us, ys) in enumerate(segments)]
    L = int(nperseg) if nperseg is not None else _segment_length(max(p[0].shape[0] for p in pairs))
    usable = [p for p in pairs if p[0].shape[0] >= 2 * L]
    if not usable:
        raise DataError(f"the record has {pairs[0][0].shape[0]} samples, fewer than two Welch segments of {L}: "
                        "collect a longer record or pass a smaller nperseg")
    if m == l == 1:  # the SISO estimator as it always was (its numbers are relied on)
        return _siso_welch([(us[:, 0], ys[:, 0]) for us, ys in usable], L, dt, confidence)
    return _mimo_welch(usable, L, dt, confidence)


def _siso_welch(usable, L: int, dt: float, confidence: float) -> FrequencyResponseEstimate:
    """The SISO Welch estimate and its Bendat–Piersol disks (1-D records, each at least two segments)."""
    Suu = Syy = Syu = 0.0
    count = 0
    for us, ys in usable:
        k = 1 + (us.size - L) // (L // 2)  # segments at 50 % overlap
        f, puu = scipy.signal.welch(us, nperseg=L)
        _, pyy = scipy.signal.welch(ys, nperseg=L)
        _, pyu = scipy.signal.csd(us, ys, nperseg=L)
        Suu, Syy, Syu, count = Suu + k * puu, Syy + k * pyy, Syu + k * pyu, count + k
    Suu, Syy, Syu = Suu / count, Syy / count, Syu / count
    nu = count / (1.0 + 2.0 * _HANN_OVERLAP_CORRELATION ** 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        G = np.where(Suu > 0, Syu / Suu, np.nan + 0j)
        Svv = np.maximum(Syy - np.abs(Syu) ** 2 / Suu, 0.0)
        coh = np.clip(np.abs(Syu) ** 2 / (Suu * Syy), 0.0, 1.0)
        alpha = (1.0 - confidence) / f.size
        if nu > 2.5:
            fq = scipy.stats.f.ppf(1.0 - alpha, 2, 2.0 * (nu - 2.0))
            radius = np.sqrt(2.0 / (nu - 2.0) * fq * Svv / Suu)
        else:
            radius = np.full(f.size, np.inf)
    radius = np.where(np.isfinite(radius) & (Suu > 0), radius, np.inf)
    return FrequencyResponseEstimate(frequency=2.0 * np.pi * f / dt, response=G, radius=radius, coherence=coh,
                                     input_psd=Suu, noise_psd=Svv, averages=float(nu), confidence=float(confidence),
                                     nperseg=L, dt=float(dt))


#: λ_min/λ_max of S_uu below which the input spectrum is taken as singular (Ĝ NaN, radius inf).
_SINGULAR_INPUT = 1e-12


def _cross_spectra(a: np.ndarray, b: np.ndarray, L: int) -> tuple[np.ndarray, np.ndarray]:
    """``(f, S)`` with ``S[:, i, j] = E[B_i A_jᴴ]`` (scipy's ``csd(a_j, b_i)``) for records a (n, p), b (n, q)."""
    f, s = scipy.signal.csd(a.T[None, :, :], b.T[:, None, :], nperseg=L, axis=-1)
    return f, np.moveaxis(s, -1, 0)


def _mimo_welch(usable, L: int, dt: float, confidence: float) -> FrequencyResponseEstimate:
    """The H1 estimate ``S_yu S_uu⁻¹`` and the spectral-norm radius of :func:`frequency_response_estimate`."""
    m, l = usable[0][0].shape[1], usable[0][1].shape[1]
    Suu = Syy = Syu = 0.0
    count = 0
    for us, ys in usable:
        k = 1 + (us.shape[0] - L) // (L // 2)  # segments at 50 % overlap
        f, puu = _cross_spectra(us, us, L)
        _, pyy = _cross_spectra(ys, ys, L)
        _, pyu = _cross_spectra(us, ys, L)
        Suu, Syy, Syu, count = Suu + k * puu, Syy + k * pyy, Syu + k * pyu, count + k
    Suu, Syy, Syu = Suu / count, Syy / count, Syu / count
    Suu = 0.5 * (Suu + np.conj(np.swapaxes(Suu, 1, 2)))  # Hermitian to rounding; eigvalsh reads one triangle
    nu = count / (1.0 + 2.0 * _HANN_OVERLAP_CORRELATION ** 2)
    lam = np.linalg.eigvalsh(Suu)
    regular = (lam[:, -1] > 0) & (lam[:, 0] > _SINGULAR_INPUT * lam[:, -1])
    Suy = np.conj(np.swapaxes(Syu, 1, 2))
    # Ĝᴴ = S_uu⁻¹ S_uy (S_uu Hermitian); singular frequencies get the identity so the batch solve runs
    X = np.linalg.solve(np.where(regular[:, None, None], Suu, np.eye(m)), Suy)
    G = np.where(regular[:, None, None], np.conj(np.swapaxes(X, 1, 2)), np.nan + 0j)
    explained = Syu @ X  # S_yu S_uu⁻¹ S_uy, the coherent part of S_yy
    Svv = Syy - explained
    Svv = 0.5 * (Svv + np.conj(np.swapaxes(Svv, 1, 2)))
    syy = np.real(np.diagonal(Syy, axis1=1, axis2=2))
    svv = np.maximum(np.real(np.diagonal(Svv, axis1=1, axis2=2)), 0.0)  # Ŝ_vv,r, each output's residual
    with np.errstate(divide="ignore", invalid="ignore"):
        coh = np.clip(np.real(np.diagonal(explained, axis1=1, axis2=2)) / syy, 0.0, 1.0)
        coh = np.where(regular[:, None] & (syy > 0), coh, 0.0)
        alpha = (1.0 - confidence) / (f.size * l)
        if nu - 2.0 * m > 0.5:
            fq = scipy.stats.f.ppf(1.0 - alpha, 2 * m, 2.0 * (nu - 2.0 * m))
            radius = np.sqrt(2.0 * m / (nu - 2.0 * m) * fq * np.sum(svv, axis=1) / lam[:, 0])
        else:
            radius = np.full(f.size, np.inf)
    radius = np.where(np.isfinite(radius) & regular, radius, np.inf)
    return FrequencyResponseEstimate(frequency=2.0 * np.pi * f / dt, response=G, radius=radius, coherence=coh,
                                     input_psd=Suu, noise_psd=Svv, averages=float(nu), confidence=float(confidence),
                                     nperseg=L, dt=float(dt))


@result
@dataclass(frozen=True, eq=False)
class LowBandEstimate:
    """Frequency response at the lowest DFT frequencies of a record by the local polynomial method.

    Attributes
    ----------
    frequency : ndarray, shape (K,)
        The DFT frequencies ``2πk/(N·dt)``, ``k = 1 … K`` (rad/s; rad/sample when ``dt = 1``).
    response : ndarray, complex, shape (K,) or (K, l, m)
        ``Ĝ`` at those frequencies ((K,) for one input and one output, as :class:`FrequencyResponseEstimate`).
    radius : ndarray, shape (K,)
        Radius of the confidence region around each ``Ĝ`` in the spectral norm (SISO: the disk; ``inf``
        where an input has no power in the window).
    confidence : float
        Simultaneous confidence over the ``K`` frequencies (and the ``l`` outputs; Bonferroni).
    window : int
        DFT bins in each local fit.
    degree : int
        Degree of the local polynomials (response and transient).
    samples : int
        ``N``, the record's length.
    dt : float
    """

    frequency: np.ndarray
    response: np.ndarray
    radius: np.ndarray
    confidence: float
    window: int
    degree: int
    samples: int
    dt: float

    @property
    def gain(self) -> np.ndarray:
        """``‖Ĝ‖₂`` per frequency, shape (K,): ``|Ĝ|`` for SISO, the largest singular value for MIMO."""
        return _spectral_norm(self.response)


#: bins of each local fit and degree of its polynomials (6 complex parameters, 10 complex residual dof).  Measured
#: on a *plant* pole 2.2 bins from 0 (99 % disks): 16 bins missed its response at the lowest bin in most records, 9
#: bins in 0–2 of 40, but with disks too wide to see a model error of 0.7 there.  The premise test applies it to
#: the model error P − P̂, which is smooth where P̂ is good; where it is not, a missed disk refuses, never certifies.
_LPM_WINDOW, _LPM_DEGREE = 16, 2


def _lpm_window(inputs: int) -> int:
    """Bins of a local fit with ``inputs`` input channels: 16, or twice its (m + 1)(degree + 1) parameters if more."""
    return max(_LPM_WINDOW, 2 * (inputs + 1) * (_LPM_DEGREE + 1))


def low_band_estimate(u, y, dt: float = 1.0, *, bins: int, confidence: float = 0.99,
                      window: int | None = None) -> LowBandEstimate:
    """Frequency response at the record's lowest DFT frequencies, with a confidence radius.

    Welch segments are short and each is detrended, so a response that changes below the first
    Welch frequency is invisible to :func:`frequency_response_estimate`.  Here the whole record's DFT
    is used (rectangular window; the mean, bin 0, is left out) with the local polynomial method of
    Pintelon and Schoukens: around each bin ``k`` the response and the transient (the term a record
    that does not start and end at rest adds to every bin) are fitted as polynomials of degree 2 in the
    bin offset, ``Y_r = G(r) U_r + T(r)``, over 16 bins (the first 16 at the lowest ones).  With
    independent complex residuals the error of ``Ĝ(k)`` is ``F(2, 2d)``-distributed after scaling by
    its variance, ``d`` the residual degrees of freedom, which gives the disk.  The disk assumes the
    response is quadratic across the window: where it bends within a few bins (a pole a few bins from 0)
    the estimate at the lowest bins is biased by up to about 10 % of the response (measured: 8 % for a
    first-order response 8 bins wide), which the disk does not include.

    MIMO (u: (n, m), y: (n, l)): the local fit has the ``m`` input columns, each times the polynomial,
    and the transient polynomial, ``p = (m + 1)(degree + 1)`` complex parameters per output, the same for
    every output row.  With ``C`` the m × m block of ``(XᴴX)⁻¹`` belonging to the response at the bin
    and ``s_r²`` the residual variance of output ``r`` (``d = window − p`` dof), the row ``ĝ_r`` obeys
    ``(ĝ_r − g_r) C⁻¹ (ĝ_r − g_r)ᴴ ≤ m·F_{2m, 2d}(1 − α)·s_r²`` (the χ²_{2m}/χ²_{2d} ratio of complex
    least squares; m = 1 is the SISO disk), so ``‖ĝ_r − g_r‖² ≤ λ_max(C)·m·F·s_r²`` and
    ``r = sqrt(λ_max(C)·m·F_{2m, 2d}(1 − α)·Σ_r s_r²)`` bounds ``‖G − Ĝ‖_F ≥ ‖G − Ĝ‖₂``, with
    α = (1 − confidence)/(K·l).  The window must leave as many residual dof as parameters,
    ``2p ≤ window``: 16 bins for one input, ``2(m + 1)·3`` for more (18 for two inputs).

    Parameters
    ----------
    u : array_like, shape (n,) or (n, m)
        Input.
    y : array_like, shape (n,) or (n, l)
        Output (for the premise test: the output error ``y − P̂u``).
    dt : float
        Sample time.
    bins : int
        ``K``: the response is estimated at bins ``1 … K``.
    confidence : float
        Simultaneous confidence over the ``K`` bins (and the outputs).
    window : int, optional
        Bins of each local fit; default 16 for one input, ``max(16, 2(m + 1)(degree + 1))`` for ``m``.

    Returns
    -------
    LowBandEstimate
        ``response`` (K,) for m = l = 1, (K, l, m) otherwise; ``radius`` (K,) always.

    Raises
    ------
    DataError
        NaN, mismatched lengths, ``bins < 1``, a window with fewer than ``2(m + 1)(degree + 1)`` bins, a
        record with fewer than ``2(K + window)`` samples, a confidence outside (0, 1).

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> u = rng.choice([-1.0, 1.0], 2000)
    >>> y = np.convolve(u, [2.0, 0.5])[:2000] + 0.1 * rng.standard_normal(2000)
    >>> est = low_band_estimate(u, y, bins=8)
    >>> G = 2.0 + 0.5 * np.exp(-1j * est.frequency)
    >>> bool(np.all(np.abs(est.response - G) <= est.radius))
    True

    Two inputs and one output, ``y = 2u₁ − u₂``:

    >>> U = rng.choice([-1.0, 1.0], (2000, 2))
    >>> est = low_band_estimate(U, U @ [2.0, -1.0] + 0.1 * rng.standard_normal(2000), bins=8)
    >>> est.response.shape, est.window
    ((8, 1, 2), 18)
    >>> bool(np.all(np.linalg.norm(est.response - [[2.0, -1.0]], ord=2, axis=(1, 2)) <= est.radius))
    True
    """
    _check_confidence(confidence)
    dt = check_sample_time(dt, "dt", allow_true=False)
    u, y = _record_pair(u, y)
    n, m, l = u.shape[0], u.shape[1], y.shape[1]
    K = check_count(bins, "bins", 1)
    need = 2 * (m + 1) * (_LPM_DEGREE + 1)
    W = _lpm_window(m) if window is None else check_count(window, "window", 1)
    if W < need:
        raise DataError(f"window={window!r} is too small for {m} input(s): a local fit has (m + 1)·(degree + 1) = "
                        f"{need // 2} complex parameters and needs as many residual degrees of freedom; pass "
                        f"window ≥ {need} or leave it to the default")
    if K < 1 or n < 2 * (K + W):
        raise DataError(f"low_band_estimate needs bins ≥ 1 and at least 2·(bins + {W}) samples; got bins={bins!r} "
                        f"and {n} samples: pass fewer bins or a longer record")
    U, Y = np.fft.rfft(u, axis=0), np.fft.rfft(y, axis=0)
    if m == l == 1:  # the SISO fit as it always was
        U, Y = U[:, 0], Y[:, 0]
        alpha = (1.0 - confidence) / K
        response, radius = np.empty(K, complex), np.empty(K)
        for k in range(1, K + 1):
            start = max(1, k - W // 2)
            response[k - 1], radius[k - 1] = _local_fit(U[start:start + W], Y[start:start + W], k - start, alpha)
    else:
        alpha = (1.0 - confidence) / (K * l)
        response, radius = np.empty((K, l, m), complex), np.empty(K)
        for k in range(1, K + 1):
            start = max(1, k - W // 2)
            response[k - 1], radius[k - 1] = _local_fit_mimo(U[start:start + W], Y[start:start + W], k - start, alpha)
    return LowBandEstimate(frequency=2.0 * np.pi * np.arange(1, K + 1) / (n * dt), response=response, radius=radius,
                           confidence=float(confidence), window=W, degree=_LPM_DEGREE, samples=int(n), dt=float(dt))


def _local_fit(U: np.ndarray, Y: np.ndarray, at: int, alpha: float) -> tuple[complex, float]:
    """``(Ĝ, radius)`` at offset ``at`` of one local polynomial fit ``Y_r = G(r) U_r + T(r)``."""
    r = np.arange(U.size) - at
    powers = r[:, None] ** np.arange(_LPM_DEGREE + 1)[None, :]
    X = np.hstack([powers * U[:, None], powers]).astype(complex)
    theta, _, rank, _ = np.linalg.lstsq(X, Y, rcond=None)
    dof = U.size - X.shape[1]
    if rank < X.shape[1] or not np.any(np.abs(U) > 0):
        return complex(np.nan), float("inf")
    s2 = float(np.sum(np.abs(Y - X @ theta) ** 2)) / dof
    # Ĝ(at) is theta[0]; its variance is s² times the (0, 0) entry of (XᴴX)⁻¹
    var = float(np.real(_inverse_gram(X, [0])[0, 0]))
    return complex(theta[0]), math.sqrt(scipy.stats.f.ppf(1.0 - alpha, 2, 2 * dof) * s2 * var)


def _inverse_gram(X: np.ndarray, rows) -> np.ndarray:
    """``(XᴴX)⁻¹`` restricted to ``rows`` × ``rows``, from the SVD of X: ``V_r Σ⁻² V_rᴴ`` is Hermitian positive
    semidefinite whatever the conditioning (``inv(XᴴX)`` squares cond X, and on a ramp input its rounding gave a
    negative variance)."""
    _, sv, Vh = np.linalg.svd(X, full_matrices=False)
    Vr = Vh.conj().T[rows, :] / sv
    return Vr @ Vr.conj().T


def _local_fit_mimo(U: np.ndarray, Y: np.ndarray, at: int, alpha: float) -> tuple[np.ndarray, float]:
    """``(Ĝ (l × m), radius)`` at offset ``at`` of one local fit ``Y_r = G(r) U_r + T(r)``, U (W, m), Y (W, l)."""
    W, m = U.shape
    l = Y.shape[1]
    d = _LPM_DEGREE + 1
    r = np.arange(W) - at
    powers = r[:, None] ** np.arange(d)[None, :]
    # columns: input j times 1, r, r², … (block j), then the transient's 1, r, r², …
    X = np.hstack([powers * U[:, j:j + 1] for j in range(m)] + [powers]).astype(complex)
    theta, _, rank, _ = np.linalg.lstsq(X, Y, rcond=None)
    if rank < X.shape[1]:  # an input silent in the window (or collinear with another): nothing known
        return np.full((l, m), np.nan + 0j), float("inf")
    dof = W - X.shape[1]
    s2 = np.sum(np.abs(Y - X @ theta) ** 2, axis=0) / dof  # per output
    at0 = np.arange(m) * d  # the response at the bin: each input's constant term
    C = _inverse_gram(X, at0)
    lam = float(np.linalg.eigvalsh(0.5 * (C + C.conj().T))[-1])
    fq = scipy.stats.f.ppf(1.0 - alpha, 2 * m, 2 * dof)
    return theta[at0, :].T.copy(), math.sqrt(lam * m * fq * float(np.sum(s2)))


def _siso_response(sys, omega: np.ndarray, dt: float) -> np.ndarray:
    """``sys(e^{jω dt})`` of a SISO discrete system."""
    return np.asarray(sys(np.exp(1j * omega * dt)), complex).reshape(-1)


def _bin_peak(sys, frequency: np.ndarray, spacing: float, dt: float, points: int = 9) -> np.ndarray:
    """``max |sys|`` over each frequency ± half the ``spacing``, so a peak between two frequencies of the
    grid is not missed."""
    offsets = np.linspace(-0.5, 0.5, points) * spacing
    omega = np.clip(frequency[:, None] + offsets[None, :], 0.0, np.pi / dt)
    return np.abs(_siso_response(sys, omega.reshape(-1), dt)).reshape(omega.shape).max(axis=1)


def _bin_response(sys, frequency: np.ndarray, spacing: float, dt: float, points: int) -> np.ndarray:
    """``sys`` (p × q) at ``points`` frequencies across each frequency ± half the ``spacing``: (F, points, p, q)."""
    offsets = np.linspace(-0.5, 0.5, points) * spacing
    omega = np.clip(frequency[:, None] + offsets[None, :], 0.0, np.pi / dt)
    z = np.asarray(sys(np.exp(1j * omega.reshape(-1) * dt), squeeze=False), complex)  # (p, q, F·points)
    return np.moveaxis(z, -1, 0).reshape(omega.shape + z.shape[:2])


def _bin_loop_gain(sys, response: np.ndarray, radius: np.ndarray, frequency: np.ndarray, spacing: float, dt: float,
                   sign: float, points: int = 9) -> tuple[np.ndarray, np.ndarray]:
    """MIMO ``max_bin (σ̄(D̂ M̂) + sign·r·σ̄(M̂))`` and ``max_bin σ̄(M̂)`` over each frequency ± half the ``spacing``.

    ``sys`` is ``M̂`` (m × l), ``response`` ``D̂`` (F, l, m), ``radius`` (F,).  By the triangle inequality every
    ``D`` with ``‖D − D̂‖₂ ≤ r`` has ``σ̄(D̂M̂) − r·σ̄(M̂) ≤ σ̄(D M̂) ≤ σ̄(D̂M̂) + r·σ̄(M̂)``: sign +1 bounds the
    loop gain of the perturbation from above, −1 from below.  NaN where ``D̂`` is NaN.
    """
    Mz = _bin_response(sys, frequency, spacing, dt, points)
    gain_M = np.linalg.norm(Mz, ord=2, axis=(2, 3))
    known = np.all(np.isfinite(response), axis=(1, 2))
    D = np.where(known[:, None, None], response, 0.0)  # NaN would stop the SVD; those rows are set NaN below
    gain_DM = np.linalg.norm(D[:, None] @ Mz, ord=2, axis=(2, 3))
    with np.errstate(invalid="ignore"):
        bound = np.max(gain_DM + sign * radius[:, None] * gain_M, axis=1)
    return np.where(known, bound, np.nan), gain_M.max(axis=1)


def _channels(response: np.ndarray, k: int) -> str:
    """MIMO: ``' (largest in u[:, j] → y[:, i])'``, the entry of ``D̂`` at frequency index ``k`` of largest modulus."""
    if response.ndim == 1 or not np.all(np.isfinite(response[k])):
        return ""
    i, j = np.unravel_index(int(np.argmax(np.abs(response[k]))), response[k].shape)
    return f" (largest from input u[:, {j}] to output y[:, {i}])"


def _bands(frequency: np.ndarray, mask: np.ndarray, unit: str) -> str:
    """The runs of True in ``mask`` as frequency intervals, e.g. ``'0.31–0.94 rad/s, 2.2 rad/s'``."""
    parts, k = [], 0
    idx = np.flatnonzero(mask)
    while k < idx.size:
        start = k
        while k + 1 < idx.size and idx[k + 1] == idx[k] + 1:
            k += 1
        lo, hi = frequency[idx[start]], frequency[idx[k]]
        parts.append(f"{lo:.3g} {unit}" if start == k else f"{lo:.3g}–{hi:.3g} {unit}")
        k += 1
    return ", ".join(parts[:6]) + (f" and {len(parts) - 6} more bands" if len(parts) > 6 else "")


def _unit(dt: float) -> str:
    return "rad/sample" if dt == 1.0 else "rad/s"


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
    A, B, C, D = (np.asarray(M, float) for M in control.ssdata(model))
    u, y = channel_pair(u, y)
    i = int(horizon)
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


def _fir_sigma(u: np.ndarray, e: np.ndarray, taps: int, burn: int) -> float:
    """Residual rms of the least-squares FIR fit of ``e`` on ``u`` (rows after ``burn``), per degree of freedom.

    Several channels: pooled over the outputs (:func:`_fir_rss`), the σ of the noise ball
    ``‖Ξ‖_F ≤ σ√(N·l)`` the solver uses -- one rms over every entry, as in (7.5)'s ``σ√(ilj)``.

    The memory is fixed: growing it while an F-test of nested fits found the longer one significant was
    measured to miss the slow model error it was meant to catch (a fourth-order plant whose error sat
    below the held-out record's noise) while it refused two integrating-plant loops that hold.
    """
    rss, dof = _fir_rss(u, e, taps, burn)
    return float(math.sqrt(rss / max(dof, 1)))


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
    opts = options or PremiseOptions()
    i = int(horizon)
    u, y = channel_pair(u, y)
    burn = i if opts.burn_in is None else int(opts.burn_in)
    N = u.shape[0]
    n = min(N - i, burn + int(opts.samples))
    if n < burn + 4 * i or n < 2 * burn:
        raise DataError(f"the output-error segment has {N} samples; it needs at least "
                        f"{i + max(burn + 4 * i, 2 * burn)} (horizon {i}, burn-in {burn}, 4i rows): pass a longer "
                        "validation record")
    A = np.asarray(control.ssdata(model)[0], float)
    rho = float(np.max(np.abs(np.linalg.eigvals(A)))) if A.size else 0.0
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
        sigma = _fir_sigma(seg_u, e, int(taps), burn)
        rule = (f"residual rms of a {taps}-tap least-squares FIR fit of the output error on the input, "
                f"per degree of freedom (rows {burn}…{n - 1})")
        if e.ndim == 2:
            rule += f", pooled over the {e.shape[1]} outputs (each fitted on all {m} inputs)"
        sigma = max(sigma, 1e-12 * max(float(np.sqrt(np.mean(e ** 2))), 1e-300))
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


def _frf_inconsistency(est: FrequencyResponseEstimate, delta: float) -> tuple[float, str]:
    """``max (‖D̂‖₂ − r)/δ`` over the excited band (``D̂`` the estimate of ``P − P̂``) and where it exceeds 1.

    ``‖D̂‖₂ − r > δ`` means every ``D`` in the region has ``‖D‖₂ ≥ ‖D̂‖₂ − r > δ`` (SISO ``|D̂| − r``): the
    plant is outside the δ-ball around P̂ at that frequency (with the region's confidence).
    """
    excited = est.excited & np.isfinite(est.radius)
    if not np.any(excited):
        return float("nan"), "the record excites no frequency"
    gap = est.gain - est.radius
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


def check_premise(model, u, y, horizon: int, delta_subspace: float, *, dt: float, validation=None,
                  options: PremiseOptions | None = None) -> PremiseTest:
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
    validation : tuple of array_like, optional
        ``(u_v, y_v)``: a record of the same plant not used to fit P̂ (held out).  Without it the
        output error is computed on the window, in sample (optimistic; the result says so).
    options : PremiseOptions, optional

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
    """
    opts = options or PremiseOptions()
    u, y = channel_pair(u, y)
    if validation is not None:
        try:
            uv, yv = validation
        except (TypeError, ValueError):
            raise DataError("validation must be a pair (u, y) of held-out data of the same plant") from None
        uv, yv = channel_pair(uv, yv, "validation ")
        oe_data, held_out = (uv, yv), True
    else:
        oe_data, held_out = (u, y), False
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
    return PremiseTest(delta_subspace=float(delta_subspace), output_error=oe, delta=float(delta), decided_by=decided,
                       frf=frf, inconsistency=float(worst), reason="; ".join(reasons), plant_frf=plant_frf,
                       low_band=low, plant_low_band=plant_low)


def untested_premises(u, validation=None) -> tuple[str, ...]:
    """What the certificate assumes that these data cannot test, read off the inputs themselves.

    The certificate speaks of an LTI plant.  Some departures from that the records show (the output-error and
    frequency-response tests of :func:`check_premise`), but an input channel whose samples take only two values,
    or only 0 and ±a, cannot show a static input nonlinearity at all: any function of the input is an affine
    function of it on two points, and an odd one (a saturation, a dead zone) a gain on {−a, 0, a}.  Such data
    are those of the gain ``f(a)/a`` times the linear plant, whatever the plant does at other amplitudes --
    which the loop's own input will have.  Measured on the adversarial catalogue (a third-order plant behind a
    saturation at 80 % of a ±1 PRBS): certified at every seed 0–9 with ``‖P − P̂‖∞/δ`` of 1.9–7.0 for the
    small-signal plant, and the true loop short of its δ margin at four of them; with a uniform multilevel input
    the same case certified with ratios 0.25–2.3 and every loop kept its margin (12 runs).

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
        if values.size > 2 and magnitudes.size > 1:
            continue
        shown = ", ".join(f"{v:.4g}" for v in values)
        out.append(f"input {ch} takes the values {{{shown}}} only: a static input nonlinearity (a saturation or a "
                   "dead zone, a gain that depends on the amplitude) acts on such data as a linear gain, so no test "
                   "on them can see it; the certificate assumes the plant linear at the amplitudes the loop will "
                   "use (data with several input amplitudes, e.g. a multilevel PRBS or Gaussian noise, would show "
                   "such a nonlinearity in the output error)")
    return tuple(out)


def _low_bins(n: int, nperseg: int, inputs: int = 1) -> int:
    """Bins below the first Welch frequency (``n/nperseg`` DFT bins), at least 1; 0 when the record is too short
    for :func:`low_band_estimate`'s default window with ``inputs`` input channels."""
    k = max(1, n // nperseg)
    return k if n >= 2 * (k + _lpm_window(inputs)) else 0


def _low_band_inconsistency(est: LowBandEstimate, delta: float) -> tuple[float, str]:
    """``max (‖D̂‖₂ − r)/δ`` over the low frequencies and, where it exceeds 1, why the premise fails."""
    gap = np.where(np.isfinite(est.radius), est.gain - est.radius, -np.inf)
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


@result
@dataclass(frozen=True, eq=False)
class ExcitationCheck:
    """Whether the data pin the plant down where the loop is sensitive (module docstring, item 3).

    Attributes
    ----------
    ok : bool
    worst : float
        ``max (|D̂| + r) · max_bin |M̂|`` over the Welch frequencies (< 1 needed); MIMO
        ``max max_bin (σ̄(D̂M̂) + r·σ̄(M̂))``.
    frequency : float
        Where the worst value is (rad/s; rad/sample when ``dt = 1``).
    reason : str
        ``''`` when ok; otherwise the band, the input's power there (MIMO: the input channel with the
        least power) and the fix.
    margin : float
        With ``delta`` given: the data's evidence against the δ margin on the plant,
        ``max δ·σ̄(Ẑ)/(1 + r·σ̄(Ẑ))``, ``Ẑ = (I − M̂D̂)⁻¹M̂``, over the Welch and low-band frequencies (≥ 1 refuses:
        every plant in the confidence disks has ``δ·σ̄(K(I+PK)⁻¹) ≥ 1`` there); in coprime-factor form the same for
        ε and the coprime channel (:func:`check_excitation`); NaN when not computed.
    """

    ok: bool
    worst: float
    frequency: float
    reason: str
    margin: float = float("nan")


def check_excitation(model, controller, frf: FrequencyResponseEstimate,
                     low_band: LowBandEstimate | None = None, *, factors=None,
                     delta: float | None = None) -> ExcitationCheck:
    """Check that the data determine the plant where the loop ``(P̂, K)`` is sensitive.

    At each Welch frequency the confidence disk ``|(P − P̂) − D̂| ≤ r`` must lie where the loop is
    stable frequency by frequency: ``(|D̂| + r) · max_bin |M̂| < 1`` with ``M̂ = (I − C_y P̂)⁻¹ C_y``.
    At the record's lowest DFT frequencies (``low_band`` given) the loop is refused where the data
    *show* a model error it does not tolerate, ``(|D̂| − r) · max_bin |M̂| ≥ 1``: a model error slower
    than the Welch segments is judged where it lives (measured: a model with a quarter of the plant's DC
    gain passed every Welch frequency, and its loop settled too slowly to track on the plant).

    MIMO (``D̂`` l × m, ``M̂`` m × l): for every ``D`` in the region ``‖D − D̂‖₂ ≤ r``,
    ``σ̄(D̂M̂) − r·σ̄(M̂) ≤ σ̄(DM̂) ≤ σ̄(D̂M̂) + r·σ̄(M̂)`` (triangle inequality, ``σ̄`` the largest singular
    value).  The Welch test is ``max_bin (σ̄(D̂M̂) + r·σ̄(M̂)) < 1``: then ``σ̄(D M̂) < 1`` for every such
    ``D``, the frequency-wise small-gain condition (``det(I − DM̂) ≠ 0`` along the homotopy ``τD``) -- no
    weaker than the ``(‖D̂‖₂ + r)·‖M̂‖₂ < 1`` it implies, and the same numbers for SISO.  The low-band
    evidence is ``max_bin (σ̄(D̂M̂) − r·σ̄(M̂)) ≥ 1``: every plant consistent with the data there has
    ``σ̄((P − P̂)M̂) ≥ 1``, so no small-gain argument covers the loop on it -- the SISO statement
    ``|D||M̂| ≥ 1`` exactly (neither proves instability; both refute the certificate's condition).
    ``(‖D̂‖₂ − r)·‖M̂‖₂ ≥ 1`` would not do: ``‖D‖₂ ≥ ‖D̂‖₂ − r`` says only that ``D`` is large in *some*
    direction, which ``M̂`` need not reach (``D M̂`` can be small), so it would refuse loops the data do
    not fault.  A test on the spectral radius ``ρ(DM̂)`` would be sharper still, but eigenvalues of
    non-normal matrices have no perturbation bound linear in ``r``.

    **The δ margin on the plant** (``delta`` given, additive form).  The certificate sizes the loop for δ around
    P̂; on the plant itself the map an additive perturbation sees is ``M_P = (I − M̂D)⁻¹M̂``, ``D = P − P̂``.  Where
    the data *show* that every plant in the disks has ``δ·σ̄(M_P) ≥ 1``, the loop is refused.  With
    ``Ẑ = (I − M̂D̂)⁻¹M̂``, the map on the plant at the disk's centre, and ``D = D̂ + E``, ``‖E‖₂ ≤ r``: ``M_P = Ẑ(I + EM_P)``,
    so ``σ̄(M_P) ≥ σ̄(Ẑ)/(1 + r·σ̄(Ẑ))``, and the evidence is ``δ·σ̄(Ẑ)/(1 + r·σ̄(Ẑ)) ≥ 1`` (SISO:
    ``δ|M̂|/(|1 − M̂D̂| + r|M̂|)``, the best case over the disk exactly), at the Welch and the low-band frequencies
    alike (evidence refuses, uncertainty does not).  Measured on the
    adversarial catalogue, ten seeds, both protocols (940 runs, 370 certified without this test, 10 of them false): it
    refuses one loop, a false certificate (a low-pass input at 0.15 of Nyquist, P̂'s DC gain 4.4 against the plant's
    1, δ = 2.9 from the output error, the true loop's δ·‖M_P‖∞ = 2.6; evidence 1.24 at the lowest frequencies), and
    none of the 360 loops the true-plant judge passed (the largest evidence among those, 0.70).  The disks' worst
    case instead of their best (refusing on uncertainty) would have refused 82 of those 360 at the Welch
    frequencies alone.

    **The ε margin in coprime-factor form** (``factors`` and ``delta`` = ε given).  The data estimate
    ``R = M̂P − N̂``, so ``(M̂, N̂ + R)`` is a factorisation of the plant, and a perturbation of those factors sees
    ``H_P = H(I − R H_u)⁻¹`` with ``H = [C_y; I](M̂ − N̂C_y)⁻¹`` the coprime channel and ``H_u`` its ``u`` rows.  With
    ``Ẑ = H(I − R̂H_u)⁻¹`` and ``R = R̂ + E``, ``H_P = Ẑ(I − EẐ_u)⁻¹``, so ``σ̄(H_P) ≥ σ̄(Ẑ)/(1 + r·σ̄(Ẑ_u))`` and the
    evidence is ``ε·σ̄(Ẑ)/(1 + r·σ̄(Ẑ_u))`` (the additive one is the case ``H = H_u = M̂``).  A coprime margin belongs
    to a factorisation; this one is the factorisation the data measure, with ``M̂`` kept.

    Parameters
    ----------
    model : control.StateSpace
        P̂ (``m`` inputs, ``l`` outputs).
    controller : control.StateSpace
        ``K`` with inputs ``[r; y]``.
    frf : FrequencyResponseEstimate
        The estimate ``D̂`` of the model error ``P − P̂``: :func:`frequency_response_estimate` of the
        input and the output error ``y − P̂u`` (:attr:`PremiseTest.frf`).
    low_band : LowBandEstimate, optional
        ``D̂`` below the Welch resolution (:attr:`PremiseTest.low_band`).
    factors : CoprimeFactors, optional
        The coprime-factor form (:mod:`unfalsify.coprime`): ``frf`` and ``low_band`` then estimate
        ``R = M̂P − N̂`` (:attr:`CoprimePremise.error_frf`) and the loop's map is ``C_y(M̂ − N̂C_y)⁻¹`` (the ``u``
        rows of :func:`unfalsify.coprime_channel`).  Since ``I − PC_y = M̂⁻¹(M̂ − N̂C_y)(I − (M̂ − N̂C_y)⁻¹RC_y)``,
        the same test is the frequency-wise condition of the loop, and it stays finite at an integrating P̂'s
        pole, where ``P − P̂`` and its estimate are unbounded.
    delta : float, optional
        The certified δ (or ε with ``factors``): also test that margin on the plants the data allow (above).

    Returns
    -------
    ExcitationCheck

    Raises
    ------
    DataError
        The estimates' channels differ from the model's; ``delta`` negative or not a number.

    Examples
    --------
    >>> import control
    >>> import numpy as np
    >>> import synthesis as sy
    >>> from unfalsify import predictor_model
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(300)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:300] + 0.01 * rng.standard_normal(300)    # FIR plant, output noise 0.01
    >>> model = predictor_model(sy.fit_predictor(u[:200], y[:200], 3), 1.0)
    >>> test = check_premise(model, u[:200], y[:200], 3, 0.05, dt=1.0)      # D̂ = P − P̂ and its disks
    >>> K = control.ss([], [], [], [[0.5, -0.5]], 1.0)                       # u = 0.5(r − y)
    >>> ex = check_excitation(model, K, test.frf, test.low_band)
    >>> ex.ok, bool(ex.worst < 1), ex.reason
    (True, True, '')

    Two inputs and two outputs, the second input silent: the data say nothing about its column of P.

    >>> P = control.ss([], [], [], np.eye(2), 1.0)                          # P̂ = I, a static 2 × 2 model
    >>> U = np.column_stack([rng.standard_normal(2048), np.zeros(2048)])
    >>> frf = frequency_response_estimate(U, 0.01 * rng.standard_normal((2048, 2)))   # e = y − P̂u
    >>> K2 = control.ss([], [], [], np.hstack([0.5 * np.eye(2), -0.5 * np.eye(2)]), 1.0)
    >>> ex = check_excitation(P, K2, frf)
    >>> ex.ok, "u[:, 1]" in ex.reason
    (False, True)
    """
    if delta is not None and (isinstance(delta, bool) or not isinstance(delta, numbers.Real) or not delta >= 0):
        what = "ε of the coprime-factor form" if factors is not None else "δ of the additive form"
        raise DataError(f"delta must be a number ≥ 0 ({what}), got {delta!r}")
    if factors is None:
        H = M = additive_channel(model, controller)
        norm = "K(I+P̂K)⁻¹"
    else:
        H = coprime_channel(factors, controller)
        M, norm = H[: model.ninputs, :], "K(M̂+N̂K)⁻¹"
    mimo = frf.response.ndim == 3 or (low_band is not None and low_band.response.ndim == 3)
    if not mimo:
        freq, dist, radius = frf.frequency, np.abs(frf.response), frf.radius
        peak = _bin_peak(M, frf.frequency, frf.resolution, frf.dt)
        with np.errstate(invalid="ignore"):
            bound = np.where(np.isfinite(radius), (dist + radius) * peak, np.where(peak > 0, np.inf, 0.0))
    else:
        for name, est in (("frf", frf), ("low_band", low_band)):
            if est is not None and _shape(est) != (M.ninputs, M.noutputs):
                raise DataError(f"{name} estimates a {_shape(est)[0]} × {_shape(est)[1]} model error (outputs × "
                                f"inputs) but the model P̂ has {M.ninputs} outputs and {M.noutputs} inputs: "
                                "estimate it from the same (u, y − P̂u) channels the model was fitted on")
        freq, dist, radius = frf.frequency, frf.gain, frf.radius
        bound, peak = _bin_loop_gain(M, frf.response, radius, frf.frequency, frf.resolution, frf.dt, +1.0)
        bound = np.where(np.isfinite(radius), bound, np.where(peak > 0, np.inf, 0.0))
    bound = np.nan_to_num(bound, nan=np.inf)
    welch = np.ones(freq.size, bool)
    if low_band is not None:
        # below the Welch resolution only evidence refuses: (|D̂| − r)·|M̂| ≥ 1.  The local fits' disks are
        # wide where the response bends fast (an integrator), so "the disk must fit" would refuse loops the
        # data do not fault; excitation itself is judged on the Welch frequencies above.
        spacing = 2.0 * np.pi / (low_band.samples * low_band.dt)
        if not mimo:
            low_peak = _bin_peak(M, low_band.frequency, spacing, low_band.dt)
            low_bound = np.nan_to_num(np.maximum(np.abs(low_band.response) - low_band.radius, 0.0) * low_peak, nan=0.0)
        else:
            low_bound, low_peak = _bin_loop_gain(M, low_band.response, low_band.radius, low_band.frequency, spacing,
                                                 low_band.dt, -1.0)
            low_bound = np.nan_to_num(np.maximum(low_bound, 0.0), nan=0.0, posinf=0.0)
        freq = np.concatenate([low_band.frequency, freq])
        dist = np.concatenate([low_band.gain, dist])
        radius = np.concatenate([low_band.radius, radius])
        peak = np.concatenate([low_peak, peak])
        bound = np.concatenate([low_bound, bound])
        welch = np.concatenate([np.zeros(low_band.frequency.size, bool), welch])
    k = int(np.argmax(bound))
    worst = float(bound[k])
    margin, margin_reason = ((float("nan"), "") if delta is None else
                             _margin_evidence(H, model.ninputs, frf, low_band, float(delta), factors is not None))
    if worst < 1.0:
        return ExcitationCheck(ok=not margin_reason, worst=worst, frequency=float(freq[k]), reason=margin_reason,
                               margin=margin)
    bad = bound >= 1.0
    unit = _unit(frf.dt)
    band = _bands(freq, bad, unit)
    lo, hi = float(freq[bad].min()), float(freq[bad].max())
    norm = f"‖{norm}‖₂" if mimo else f"|{norm}|"
    signal = ("independent white PRBS or multisines covering that band on the inputs" if mimo
              else "white PRBS or a multisine covering that band")
    if np.all(~np.isfinite(radius[bad]) | (radius[bad] >= dist[bad])):
        why = (f"the data do not determine the plant at {band}, where the loop is sensitive ({norm} up to "
               f"{float(np.max(peak[bad])):.3g}){_input_level(frf, bad[welch])} and the confidence radius reaches "
               f"{float(np.max(np.where(bad, radius, 0))):.3g}; excite {lo:.3g}–{hi:.3g} {unit}"
               f"{_input_fix(frf, bad[welch])} ({signal}) or record longer")
    else:
        test = "σ̄(D̂M̂) + r·σ̄(M̂)" if mimo else "(|P − P̂| estimate + r)·|K(I+P̂K)⁻¹|"
        why = (f"at {band} the data's frequency response differs from P̂ by more than the loop tolerates "
               f"({test} = {worst:.3g} ≥ 1 at {freq[k]:.3g} {unit}): refit P̂ on a "
               "richer or longer record, or raise the horizon")
    return ExcitationCheck(ok=False, worst=worst, frequency=float(freq[k]), reason=why, margin=margin)


def _margin_evidence(H, m: int, frf: FrequencyResponseEstimate, low_band: LowBandEstimate | None,
                     delta: float, coprime: bool = False) -> tuple[float, str]:
    """The largest evidence ``δ·σ̄(Ẑ)/(1 + r·σ̄(Ẑ_u))`` against the δ (or ε) margin (:func:`check_excitation`) over
    the Welch and low-band frequencies, and why it refuses (``''`` below 1).  ``H`` is the perturbation's channel
    (``M̂``, or the coprime ``[C_y; I](M̂ − N̂C_y)⁻¹``) and its first ``m`` rows the ``u`` rows."""
    parts = [(frf.frequency, _margin_ratio(H, m, frf.response, frf.radius, frf.frequency, frf.resolution, frf.dt,
                                           delta))]
    if low_band is not None:
        spacing = 2.0 * np.pi / (low_band.samples * low_band.dt)
        parts.append((low_band.frequency, _margin_ratio(H, m, low_band.response, low_band.radius, low_band.frequency,
                                                        spacing, low_band.dt, delta)))
    freq = np.concatenate([f for f, _ in parts])
    ratio = np.concatenate([r for _, r in parts])
    if not ratio.size:
        return float("nan"), ""
    k = int(np.argmax(ratio))
    worst = float(ratio[k])
    if worst < 1.0:
        return worst, ""
    unit = _unit(frf.dt)
    if coprime:
        what = (f"ε·σ̄([K; I](M̂ + (N̂ + R)K)⁻¹) ≥ {worst:.3g} in the factors (M̂, N̂ + R) of the plant, R = M̂P − N̂ "
                f"(ε = {delta:.4g}; bound ε·σ̄(Ẑ)/(1 + r·σ̄(Ẑ_u)), Ẑ = H(I − R̂H_u)⁻¹, H the coprime channel)")
    else:
        what = (f"δ·σ̄(K(I+PK)⁻¹) ≥ {worst:.3g} (δ = {delta:.4g}; bound δ·σ̄(Ẑ)/(1 + r·σ̄(Ẑ)), "
                "Ẑ = (I − M̂D̂)⁻¹M̂)")
    size = "ε" if coprime else "δ"
    return worst, (f"the data show that the plant lacks the {size} margin the loop is certified for: at {freq[k]:.3g} "
                   f"{unit} every plant within the confidence disks has {what}, so P̂ is wrong where the loop's margin "
                   f"is decided: refit P̂ where the data show it wrong (a longer horizon, a longer or richer record), "
                   f"which also lowers {size}")


def _margin_ratio(H, m: int, response: np.ndarray, radius: np.ndarray, frequency: np.ndarray, spacing: float,
                  dt: float, delta: float, points: int = 9) -> np.ndarray:
    """Per frequency, ``max_bin δ·σ̄(Ẑ)/(1 + r·σ̄(Ẑ_u))``, ``Ẑ = H(I − D̂H_u)⁻¹`` (``H_u``, ``Ẑ_u`` the first ``m`` rows),
    over its ± half ``spacing``; 0 where ``D̂`` or r is not finite (no evidence), ``δ/r`` where ``I − D̂H_u`` is
    singular (σ̄(Ẑ) infinite).  ``H`` is ``M̂`` (m × l: then ``Ẑ = Ẑ_u = (I − M̂D̂)⁻¹M̂``) or the coprime channel
    ((m + l) × l), ``response`` ``D̂`` (F,) or (F, l, m).

    Why: the plant closes ``v = D H_u v`` around the channel, so a perturbation of the plant sees
    ``H_P = H(I − D H_u)⁻¹``; with ``D = D̂ + E`` that is ``Ẑ(I − E Ẑ_u)⁻¹``, hence ``Ẑ = H_P(I − E Ẑ_u)`` and
    ``σ̄(H_P) ≥ σ̄(Ẑ)/(1 + r·σ̄(Ẑ_u))`` for every ``‖E‖₂ ≤ r``."""
    Hz = _bin_response(H, frequency, spacing, dt, points)  # (F, points, rows, l)
    l = Hz.shape[3]
    D = np.asarray(response, complex).reshape(frequency.size, l, m)
    known = np.all(np.isfinite(D), axis=(1, 2)) & np.isfinite(radius)
    D = np.where(known[:, None, None], D, 0.0)
    X = np.eye(l) - D[:, None] @ Hz[:, :, :m, :]  # (F, points, l, l)
    s = np.linalg.svd(X, compute_uv=False)
    singular = ~(s[..., -1] > s[..., 0] * 1e-14)
    X = np.where(singular[..., None, None], np.eye(l), X)  # solved below, then set to inf
    Z = np.swapaxes(np.linalg.solve(np.swapaxes(X, -1, -2), np.swapaxes(Hz, -1, -2)), -1, -2)  # H X⁻¹
    gain = np.where(singular, np.inf, np.linalg.norm(Z, ord=2, axis=(2, 3)))
    # the additive channel is all u rows (Ẑ_u = Ẑ): its norm is the one just taken
    gain_u = gain if Z.shape[2] == m else np.where(singular, np.inf, np.linalg.norm(Z[:, :, :m, :], ord=2, axis=(2, 3)))
    r = np.where(known, radius, 0.0)[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(np.isinf(gain), delta / r, delta * gain / (1.0 + r * gain_u))
    return np.where(known, ratio.max(axis=1), 0.0)


def _shape(est) -> tuple[int, int]:
    """``(l, m)`` of an estimate's response (``(1, 1)`` for SISO)."""
    return (1, 1) if est.response.ndim == 1 else tuple(int(x) for x in est.response.shape[1:])


def _input_power(frf: FrequencyResponseEstimate) -> np.ndarray:
    """Each input's auto-spectrum, shape (F, m)."""
    if frf.input_psd.ndim == 1:
        return frf.input_psd[:, None]
    return np.real(np.diagonal(frf.input_psd, axis1=1, axis2=2))


def _weakest_input(frf: FrequencyResponseEstimate, bad: np.ndarray) -> tuple[int, float]:
    """The input channel with the least power over the flagged Welch frequencies, and that power in dB below
    the peak of all inputs over all frequencies."""
    power = _input_power(frf)
    low = np.min(power[bad], axis=0)
    j = int(np.argmin(low))
    return j, 10.0 * np.log10(max(float(low[j]), 1e-300) / max(float(np.max(power)), 1e-300))


def _input_level(frf: FrequencyResponseEstimate, bad: np.ndarray) -> str:
    """``': the input's power there is down to … dB below its peak'`` over the flagged Welch frequencies (MIMO:
    the channel with the least power, and the weakest input direction when the channels move together)."""
    if not np.any(bad):
        return ""
    if frf.input_psd.ndim == 1:
        if not float(np.max(frf.input_psd)) > 0.0:  # a constant input: nothing left once each segment is detrended
            return ": the input has no power at any frequency (it is constant)"
        level = 10.0 * np.log10(max(float(np.min(frf.input_psd[bad])), 1e-300) / float(np.max(frf.input_psd)))
        return f": the input's power there is down to {level:.0f} dB below its peak"
    j, level = _weakest_input(frf, bad)
    lam = np.linalg.eigvalsh(frf.input_psd)
    direction = 10.0 * np.log10(max(float(np.min(lam[bad, 0])), 1e-300) / max(float(np.max(lam[:, -1])), 1e-300))
    if level < -200.0:  # exactly or numerically zero: a dB figure would be the rounding's
        text = f": input u[:, {j}] has no power there"
    else:
        text = f": input u[:, {j}] has the least power there, down to {level:.0f} dB below the inputs' peak"
    if direction < level - 20.0:  # every channel has power, but not independently
        text += (f", and the inputs' weakest direction is down to {direction:.0f} dB (the channels move together "
                 "there)")
    return text


def _input_fix(frf: FrequencyResponseEstimate, bad: np.ndarray) -> str:
    """MIMO: ``' on input u[:, j]'`` when one channel lacks power over the flagged band, else ``' in every input
    direction'`` (the channels have power but move together); SISO: ``''``."""
    if frf.input_psd.ndim == 1 or not np.any(bad):
        return ""
    j, level = _weakest_input(frf, bad)
    return f" on input u[:, {j}]" if level < 10.0 * np.log10(EXCITATION_FLOOR) else " in every input direction"
