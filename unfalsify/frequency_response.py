"""The data's frequency response, with simultaneous confidence regions: the nonparametric estimates the
premise of the §7.4 certificate is tested against (:mod:`unfalsify.premise`, :mod:`unfalsify.excitation`).

Two estimators of one object, ``G(e^{jω dt})`` of the map from ``u`` to a signal (the premise test feeds
them the output error ``e = y − P̂u``, so they estimate ``P − P̂``):

* **Welch** (:func:`frequency_response_estimate`): the H1 estimate ``Ĝ = S_yu S_uu⁻¹`` from Hann-windowed,
  detrended segments at 50 % overlap, with a simultaneous confidence disk of radius ``r(ω)`` at every
  frequency (Bendat & Piersol: ``r² = 2/(ν − 2) · F_{2, 2(ν−2)}(1 − α) · S_vv/S_uu``, ``S_vv = S_yy −
  |S_yu|²/S_uu``, ν the equivalent number of independent averages, α Bonferroni-split over the
  frequencies).  A frequency is *excited* where the input spectrum reaches ``EXCITATION_FLOOR`` × its
  peak.  Several inputs and outputs (u: (n, m), y: (n, l)): ``Ĝ`` is l × m per frequency and its region a
  radius on the spectral norm, ``‖G − Ĝ‖₂ ≤ r`` -- per output row an F-based ellipsoid (Goodman; Bendat &
  Piersol), Bonferroni over the rows and frequencies, turned into ``r = sqrt(Σ_r ρ_r²/λ_min(S_uu))``; a
  frequency is excited when ``λ_min`` of the channel-normalised ``D⁻¹S_uuD⁻¹`` (``D²`` each input's mean
  auto-spectrum) reaches the floor, so the inputs' units do not decide it (the radius stays in the record's
  units).  The same ellipsoids, whitened by the input spectrum, also keep their directions: ``region``,
  ``Q = ρ·S_uu^(-1/2)`` with ``‖(G − Ĝ)X‖₂ ≤ σ̄(QX)`` for every ``X`` of m rows, which does not depend on the
  inputs' units (the excitation check bounds the loop gain by it).  With one input and one output every number
  is the SISO one.
* **The local polynomial method** (:func:`low_band_estimate`) below the first Welch frequency, where each
  detrended segment is blind and where a slow pole or an integrator lives: the whole record's DFT is
  fitted bin by bin with a response and a transient quadratic in the bin, and F-distribution disks (several
  inputs: per-row ellipsoids, with their ``region`` as for Welch).

Each confidence statement holds with its stated probability only, and says nothing between the
estimate's frequencies (the Welch resolution is ``2π/(nperseg·dt)``).
"""
from __future__ import annotations

import dataclasses
import math
import numbers
from dataclasses import dataclass

import numpy as np
import scipy.signal
import scipy.stats

from synthesis.results import result
from synthesis.validation import DataError, as_signal, check_count, check_instance, check_sample_time

__all__ = ["EXCITATION_FLOOR", "FrequencyResponseEstimate", "frequency_response_estimate", "leaked_bins",
           "LowBandEstimate", "low_band_estimate"]


#: input power spectrum below this fraction of its peak: the frequency is not excited.
EXCITATION_FLOOR = 1e-3
#: correlation of adjacent Hann segments at 50 % overlap, for Welch's equivalent number of averages.
_HANN_OVERLAP_CORRELATION = 0.167


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
    leaked : ndarray of bool, shape (F,), or None
        Frequencies whose estimate is the response somewhere else (:func:`leaked_bins`): the input's power that the
        Hann window gathers there lies on one side, and no frequency within two bins beyond that side stands for
        itself.  Their radius is ``inf`` and they are not :attr:`excited`.  None: not computed (an estimate made
        by hand).
    region : ndarray, complex, shape (F, m, m), or None
        Several inputs: the confidence region with its directions, a factor ``Q = ρ·S_uu^(-1/2)`` (any factor with
        ``QᴴQ = ρ² S_uu⁻¹``) such that ``‖(G − Ĝ)X‖₂ ≤ σ̄(QX)`` for every ``X`` of ``m`` rows, in the same event as
        the radius (:func:`frequency_response_estimate`, derivation); ``σ̄(Q)`` is the radius.  Unlike ``r·σ̄(X)``
        it does not depend on the inputs' units: in units ``u → Du``, ``Q → QD⁻¹`` and ``X → DX``.  NaN where the
        radius is ``inf``.  None: one input (there ``σ̄(QX) = r·σ̄(X)``), or an estimate made by hand or pickled
        before the field existed (then ``r·σ̄(X)`` is the bound).
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
    leaked: np.ndarray | None = None
    region: np.ndarray | None = None  # a default: pickles made before the field load with None

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

        MIMO: the *smallest* eigenvalue of the channel-normalised ``D⁻¹S_uuD⁻¹`` against the peak of its largest
        one over all frequencies, ``D²`` each input's mean auto-spectrum (:func:`_normalised_input_psd`).  The
        smallest eigenvalue, because the radius grows like ``λ_min(S_uu)^(−1/2)``: an input direction without
        power (a silent channel, or two channels that move together) leaves ``Ĝ`` undetermined there however large
        the trace is, so the trace would call such a frequency excited.  Normalised, because persistency of
        excitation does not depend on the inputs' units: on ``S_uu`` itself a 2 × 2 record of independent ±1
        inputs recorded in units 10⁻³ and 10³ had ``λ_min/λ_max ≈ 10⁻¹²`` and excited no frequency.  A channel
        without power at any frequency stays without it (nothing is excited).  One input: ``S_uu`` against its
        peak, where the units cancel.
        """
        own = np.ones(self.frequency.size, bool) if self.leaked is None else ~np.asarray(self.leaked, bool)
        if self.input_psd.ndim == 1:
            return own & (self.input_psd >= EXCITATION_FLOOR * float(np.max(self.input_psd)))
        if self.input_psd.shape[1] == 1:  # one input: the units cancel (the numbers of one input as they were)
            lam = np.linalg.eigvalsh(self.input_psd)
            return own & (lam[:, 0] >= EXCITATION_FLOOR * float(np.max(lam[:, -1])))
        lam = np.linalg.eigvalsh(_normalised_input_psd(self.input_psd))
        return own & (lam[:, 0] > 0.0) & (lam[:, 0] >= EXCITATION_FLOOR * float(np.max(lam[:, -1])))

    @property
    def resolution(self) -> float:
        """Spacing of the frequencies, rad/s."""
        return float(2.0 * np.pi / (self.nperseg * self.dt))


def _channel_scale(input_psd: np.ndarray) -> np.ndarray:
    """``1/D``, ``D²`` each input's mean auto-spectrum over the frequencies, shape (m,); 0 for a channel without power
    (its row and column of the normalised spectrum are then 0: that channel excites nothing)."""
    power = np.mean(np.real(np.diagonal(input_psd, axis1=1, axis2=2)), axis=0)
    with np.errstate(divide="ignore"):
        return np.where(power > 0.0, 1.0 / np.sqrt(np.where(power > 0.0, power, 1.0)), 0.0)


def _normalised_input_psd(input_psd: np.ndarray) -> np.ndarray:
    """``D⁻¹ S_uu(ω) D⁻¹`` of (F, m, m) input cross-spectra, ``D²`` each input's mean auto-spectrum over the
    frequencies: the spectrum every excitation decision on several inputs is taken on.

    An invertible diagonal rescaling of the inputs (other units) leaves it unchanged, and with it whether an input
    direction has power, while the eigenvalues of ``S_uu`` itself spread with the units (``λ_min/λ_max ≈ 10⁻¹²`` for
    two independent white inputs in units 10⁻³ and 10³).  The confidence radii stay in the record's units, from
    ``S_uu``.  A channel without power keeps a zero row and column.

    >>> import numpy as np
    >>> u = np.sign(np.random.default_rng(0).standard_normal((1500, 2)))
    >>> a = frequency_response_estimate(u, np.zeros((1500, 2))).input_psd
    >>> b = frequency_response_estimate(u * [1e-3, 1e3], np.zeros((1500, 2))).input_psd
    >>> bool(np.allclose(_normalised_input_psd(a), _normalised_input_psd(b)))
    True
    """
    d = _channel_scale(input_psd)
    return input_psd * d[None, :, None] * d[None, None, :]


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


def _segment_pairs(segments) -> tuple:
    """``segments`` of :func:`frequency_response_estimate` as a tuple of ``(u, y)`` pairs; InputTypeError otherwise (a
    number had failed as "not iterable", a string or a bare array in Python's unpacking)."""
    what = "a list or tuple of (u, y) record pairs, e.g. [(u2, y2)] ([] or () for none)"
    check_instance(segments, (list, tuple), "segments", what)
    for k, pair in enumerate(segments):
        check_instance(pair, (list, tuple), f"segments[{k}]", "a pair (u, y) of one further record's input and output")
        if len(pair) != 2:
            raise DataError(f"segments[{k}] has {len(pair)} entries; each segment is a pair (u, y) of one further "
                            "record's input and output")
    return tuple(segments)


def _segment_length(n: int) -> int:
    """A power of two giving at least eight Welch segments, within 16–256."""
    return int(min(256, max(16, 2 ** int(math.floor(math.log2(max(n // 8, 1)))))))


def frequency_response_estimate(u, y, dt: float = 1.0, *, nperseg: int | None = None, confidence: float = 0.99,
                                segments=()) -> FrequencyResponseEstimate:
    """Nonparametric frequency response by Welch cross-spectra (the H1 estimator), with a confidence radius.

    SISO: ``Ĝ = S_yu/S_uu`` with the disk of Bendat & Piersol (module docstring),
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

    The directions of the region (``region``, several inputs).  Row ``r`` of ``E = G − Ĝ`` obeys
    ``e_r Ŝ_uu e_rᴴ = ‖e_r Ŝ_uu^(1/2)‖² ≤ ρ_r²``, so in the same event (all rows, all frequencies)
    ``‖E Ŝ_uu^(1/2)‖₂ ≤ ‖E Ŝ_uu^(1/2)‖_F ≤ ρ``, ``ρ² = Σ_r ρ_r²`` (= ``r²·λ_min(Ŝ_uu)``), and for any ``X`` of ``m``
    rows ``‖EX‖₂ = ‖E Ŝ_uu^(1/2) · Ŝ_uu^(-1/2) X‖₂ ≤ ρ·σ̄(Ŝ_uu^(-1/2) X) = σ̄(QX)``, ``Q = ρ·Ŝ_uu^(-1/2)``.  Since
    ``σ̄(Ŝ_uu^(-1/2) X) ≤ λ_min^(-1/2)·σ̄(X)`` it is never looser than ``r·σ̄(X)``, and it is the same in any input
    units: ``u → Du`` gives ``Ŝ_uu → DŜ_uuD``, ``ρ`` unchanged (``Ŝ_vv`` is), and ``(DŜ_uuD)^(-1/2)D`` is
    ``Ŝ_uu^(-1/2)`` times a unitary factor.  ``r·σ̄(X)`` instead takes the radius from the direction of least
    power, which the units choose.  ``Q`` is computed as ``ρ·N^(-1/2)D⁻¹`` on the channel-normalised
    ``N = D⁻¹Ŝ_uuD⁻¹`` (the same ``QᴴQ``, without the units' spread in the eigenvalues).

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
    InputTypeError
        ``segments`` not a list or tuple of ``(u, y)`` pairs.
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
    segments = _segment_pairs(segments)
    first = _record_pair(u, y)
    m, l = first[0].shape[1], first[1].shape[1]
    pairs = [first] + [_record_pair(us, ys, f"segments[{k}] ", m, l) for k, (us, ys) in enumerate(segments)]
    L = int(nperseg) if nperseg is not None else _segment_length(max(p[0].shape[0] for p in pairs))
    usable = [p for p in pairs if p[0].shape[0] >= 2 * L]
    if not usable:
        raise DataError(f"the record has {pairs[0][0].shape[0]} samples, fewer than two Welch segments of {L}: "
                        "collect a longer record or pass a smaller nperseg")
    if m == l == 1:  # the SISO estimator as it always was (its numbers are relied on)
        est = _siso_welch([(us[:, 0], ys[:, 0]) for us, ys in usable], L, dt, confidence)
    else:
        est = _mimo_welch(usable, L, dt, confidence)
    leaked = _leaked([us for us, _ in usable], L)
    region = None if est.region is None else np.where(leaked[:, None, None], np.nan, est.region)
    return dataclasses.replace(est, radius=np.where(leaked, np.inf, est.radius), leaked=leaked, region=region)


#: a Welch bin stands for its own frequency when the centroid of the input power its Hann window gathers lies within
#: this many bins of it
_CENTROID_LIMIT = 0.5
#: bins on each side within which a bin standing for itself makes a leaked bin's estimate an interpolation
_BRACKET = 2
#: the fine spectrum behind :func:`leaked_bins` resolves this many frequencies per Welch bin
_FINE = 4
#: a bin stands for itself only when its own band (±½ bin) holds at least this share of the power its window gathers,
#: relative to that share under a flat spectrum (the dc bin of a band-pass input gathers only its neighbours' power)
_OWN_SHARE = 0.1


def leaked_bins(inputs, nperseg: int) -> np.ndarray:
    """Welch bins whose estimate is the response at other frequencies: leakage from one side.

    A Welch estimate at ``ω_k`` averages the response over the input power its Hann window gathers (the main lobe,
    ±2 bins).  When that power lies on one side of ``ω_k`` -- above a band-limited input's edge, or below a
    multisine's lowest line -- the estimate and its confidence disk are the response *there*, however small the
    disk: measured, under a quantised low-band multisine the estimate of the coprime model error ``M̂P − N̂`` read
    0.14 ± 0.16 at 1.4 bins above the top line, where the error was 0.66, and the loop certified on it lacked its
    margin on the plant.  From a spectrum :data:`_FINE` times finer, a bin *stands for itself* when the centroid of
    its gathered power lies within :data:`_CENTROID_LIMIT` bins of it and its own band (±½ bin) holds at least
    :data:`_OWN_SHARE` of the power the window gathers (relative to that share under a flat spectrum), for every
    input channel.  A bin that does not is *leaked* unless bins standing for themselves lie within :data:`_BRACKET`
    bins on both sides (an interpolation across a spectral null, whose error is of second order, as between a held
    PRBS's lobes).
    Measured: white PRBS and Gaussian noise leave no bin leaked (300 records each of 200, 480 and 2000 samples); a
    PRBS held 3 samples leaves one beside its null, where the null is wider than the bracket, in 1–3.5 % of records.

    Parameters
    ----------
    inputs : sequence of array_like, shape (n,) or (n, m)
        The input records of the estimate (their fine spectra are averaged, weighted by length).
    nperseg : int
        The Welch segment length (at least 4).

    Returns
    -------
    ndarray of bool, shape (nperseg // 2 + 1,)
        True where the bin's estimate is leaked.

    Examples
    --------
    A multisine below a tenth of Nyquist leaves the bins above its band leaked; white noise leaves none:

    >>> import numpy as np
    >>> t = np.arange(2048)
    >>> u = sum(np.sin(2 * np.pi * f * t + f) for f in (0.01, 0.02, 0.03, 0.04)).reshape(-1, 1)
    >>> np.flatnonzero(leaked_bins([u], 32))[:4]
    array([2, 3, 4, 5])
    >>> bool(leaked_bins([np.random.default_rng(0).standard_normal((2048, 1))], 32).any())
    False
    """
    L = check_count(nperseg, "nperseg", 4)
    if isinstance(inputs, np.ndarray) or not isinstance(inputs, (list, tuple)):  # a bare record had been iterated
        raise DataError("inputs must be a list of input records (e.g. [u] for one record), got "
                        f"{type(inputs).__name__}")
    records = [as_signal(x, f"inputs[{k}]") for k, x in enumerate(inputs)]
    if not records or len({x.shape[1] for x in records}) > 1:
        raise DataError("inputs must be one or more input records with the same channels (time along axis 0)")
    return _leaked(records, L)


def _leaked(records, L: int) -> np.ndarray:
    """:func:`leaked_bins` of checked (n, m) records."""
    offset, own = _gathered_power(records, L)
    stands = np.all((np.abs(offset) <= _CENTROID_LIMIT) & (own >= _OWN_SHARE), axis=1)
    F = stands.size
    # the spectrum is even and periodic: bins below 0 mirror bins above it, and likewise about Nyquist
    mirrored = np.concatenate([stands[_BRACKET:0:-1], stands, stands[-2:-2 - _BRACKET:-1]])
    below = np.array([mirrored[k:k + _BRACKET].any() for k in range(F)])
    above = np.array([mirrored[k + _BRACKET + 1:k + 2 * _BRACKET + 1].any() for k in range(F)])
    return ~stands & ~(below & above)


def _gathered_power(inputs, L: int) -> tuple[np.ndarray, np.ndarray]:
    """Per Welch bin and input channel: the signed offset, in bins, of the centroid of the input power the Hann
    window gathers, and the share of that power in the bin's own band (±½ bin) relative to the share under a flat
    spectrum; shapes (L // 2 + 1, m).

    The fine two-sided spectrum (``_FINE·L`` points, periodic) is convolved circularly with the window's power
    response ``|W|²`` and with ``|W|²·d`` (d the offset in bins) for the centroid, and with a ±½-bin box for the
    own band.
    """
    n_fine = _FINE * L
    power, weight = 0.0, 0
    for x in inputs:
        seg = min(n_fine, x.shape[0])
        _, p = scipy.signal.welch(x, nperseg=seg, nfft=n_fine, return_onesided=False, axis=0)
        power, weight = power + x.shape[0] * p, weight + x.shape[0]
    power = power / weight  # (n_fine, m), fft order
    window = scipy.signal.get_window("hann", L)
    kernel = np.abs(np.fft.fft(window, n_fine)) ** 2
    d = np.fft.fftfreq(n_fine) * L  # offset in Welch bins
    box = np.where(np.abs(d) < 0.5, 1.0, np.where(np.abs(d) == 0.5, 0.5, 0.0))
    spectrum = np.fft.fft(power, axis=0)

    def circular(kern):  # Σ_j power[j] kern[m − j]
        return np.real(np.fft.ifft(spectrum * np.fft.fft(kern)[:, None], axis=0))

    bins = _FINE * np.arange(L // 2 + 1)
    total = circular(kernel)[bins]
    # Σ_j power[j] (|W|²d)(j − m) = −Σ_j power[j] (|W|²d)(m − j): |W|² is even and d odd
    with np.errstate(divide="ignore", invalid="ignore"):
        offset = np.where(total > 0, -circular(kernel * d)[bins] / total, 0.0)
        flat = np.sum(box) / np.sum(kernel)  # the own band's share of a flat spectrum's gathered power
        share = np.where(total > 0, np.maximum(circular(box)[bins], 0.0) / total / flat, 0.0)
    return offset, share


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


def _normalised_solve(Suu: np.ndarray, Suy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(regular, S_uu⁻¹S_uy)`` per frequency for several inputs, decided and solved on ``N = D⁻¹S_uuD⁻¹``
    (:func:`_normalised_input_psd`): ``S_uu⁻¹ = D⁻¹N⁻¹D⁻¹``.  Singular where ``λ_min(N) ≤`` :data:`_SINGULAR_INPUT`
    ``· λ_max(N)`` (the solution there is the identity's, set NaN by the caller): on ``S_uu`` itself, inputs in
    units 10⁻³ and 10³ made half the frequencies of a white record singular."""
    m = Suu.shape[1]
    d = _channel_scale(Suu)
    N = Suu * d[None, :, None] * d[None, None, :]
    lam = np.linalg.eigvalsh(N)
    regular = (lam[:, -1] > 0) & (lam[:, 0] > _SINGULAR_INPUT * lam[:, -1])
    X = np.linalg.solve(np.where(regular[:, None, None], N, np.eye(m)), d[None, :, None] * Suy)
    return regular, d[None, :, None] * X


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
    lam = np.linalg.eigvalsh(Suu)  # the radius's λ_min, in the record's units
    Suy = np.conj(np.swapaxes(Syu, 1, 2))
    if m == 1:  # one input: the units cancel (its numbers as they were)
        regular = (lam[:, -1] > 0) & (lam[:, 0] > _SINGULAR_INPUT * lam[:, -1])
        # Ĝᴴ = S_uu⁻¹ S_uy (S_uu Hermitian); singular frequencies get the identity so the batch solve runs
        X = np.linalg.solve(np.where(regular[:, None, None], Suu, np.eye(m)), Suy)
    else:  # singular or not on the channel-normalised spectrum, whatever the inputs' units
        regular, X = _normalised_solve(Suu, Suy)
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
            rho = np.sqrt(2.0 * m / (nu - 2.0 * m) * fq * np.sum(svv, axis=1))  # ρ of the whitened region
        else:
            radius = rho = np.full(f.size, np.inf)
    radius = np.where(np.isfinite(radius) & regular, radius, np.inf)
    # one input: σ̄(QX) is r·σ̄(X) exactly, and its numbers stay those of r
    region = _welch_region(Suu, rho, np.isfinite(radius)) if m > 1 else None
    return FrequencyResponseEstimate(frequency=2.0 * np.pi * f / dt, response=G, radius=radius, coherence=coh,
                                     input_psd=Suu, noise_psd=Svv, averages=float(nu), confidence=float(confidence),
                                     nperseg=L, dt=float(dt), region=region)


def _inverse_root(N: np.ndarray, usable: np.ndarray) -> np.ndarray:
    """``N^(-1/2)`` of (F, m, m) Hermitian matrices, positive definite where ``usable`` (NaN elsewhere)."""
    m = N.shape[1]
    w, V = np.linalg.eigh(np.where(usable[:, None, None], N, np.eye(m)))
    with np.errstate(divide="ignore", invalid="ignore"):
        root = (V / np.sqrt(w)[:, None, :]) @ np.conj(np.swapaxes(V, 1, 2))
    return np.where(usable[:, None, None] & (w[:, :1, None] > 0.0), root, np.nan)


def _welch_region(Suu: np.ndarray, rho: np.ndarray, finite: np.ndarray) -> np.ndarray:
    """``Q = ρ·N^(-1/2)D⁻¹`` per frequency, ``N = D⁻¹S_uuD⁻¹`` (:func:`_normalised_input_psd`), so that
    ``QᴴQ = ρ²S_uu⁻¹`` (:func:`frequency_response_estimate`: ``‖(G − Ĝ)X‖₂ ≤ σ̄(QX)``); NaN where not ``finite``.
    Taken on ``N``: in units 10⁻³ and 10³ the eigenvalues of ``S_uu`` itself spread over 12 decades."""
    d = _channel_scale(Suu)
    root = _inverse_root(Suu * d[None, :, None] * d[None, None, :], finite)
    return rho[:, None, None] * root * d[None, None, :]


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
    region : ndarray, complex, shape (K, m, m), or None
        Several inputs: the confidence region with its directions, a factor ``Q = ρ·C^(1/2)`` (``QᴴQ = ρ²C``, ``C``
        the fit's m × m covariance block, :func:`low_band_estimate`) such that ``‖(G − Ĝ)X‖₂ ≤ σ̄(QX)`` for every
        ``X`` of ``m`` rows, in the same event as the radius; ``σ̄(Q)`` is the radius, and in units ``u → Du``,
        ``Q → QD⁻¹``, so ``σ̄(QX)`` does not depend on them.  NaN where the radius is ``inf``.  None: one input, or
        an estimate made by hand or pickled before the field existed (``r·σ̄(X)`` is then the bound).
    """

    frequency: np.ndarray
    response: np.ndarray
    radius: np.ndarray
    confidence: float
    window: int
    degree: int
    samples: int
    dt: float
    region: np.ndarray | None = None  # a default: pickles made before the field load with None

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
    ``2p ≤ window``: 16 bins for one input, ``2(m + 1)·3`` for more (18 for two inputs).  The same rows give
    the region's directions (``region``): ``‖(ĝ_r − g_r) C^(-1/2)‖² ≤ m·F·s_r²``, so with
    ``ρ² = m·F_{2m, 2d}(1 − α)·Σ_r s_r²`` and ``E = G − Ĝ``, ``‖E C^(-1/2)‖₂ ≤ ‖E C^(-1/2)‖_F ≤ ρ`` and
    ``‖EX‖₂ ≤ ρ·σ̄(C^(1/2)X) = σ̄(QX)`` for any ``X`` of ``m`` rows, in the same event; ``r = ρ·λ_max(C)^(1/2)`` is
    the case ``X = I``.  Input units ``u → Du`` give ``C → D⁻¹CD⁻¹``: ``σ̄(C^(1/2)DX)`` is ``σ̄(C^(1/2)X)``.

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
        response, radius, region = np.empty(K, complex), np.empty(K), None
        for k in range(1, K + 1):
            start = max(1, k - W // 2)
            response[k - 1], radius[k - 1] = _local_fit(U[start:start + W], Y[start:start + W], k - start, alpha)
    else:
        alpha = (1.0 - confidence) / (K * l)
        response, radius, region = np.empty((K, l, m), complex), np.empty(K), np.empty((K, m, m), complex)
        for k in range(1, K + 1):
            start = max(1, k - W // 2)
            response[k - 1], radius[k - 1], region[k - 1] = _local_fit_mimo(U[start:start + W], Y[start:start + W],
                                                                             k - start, alpha)
        region = region if m > 1 else None  # one input: σ̄(QX) = r·σ̄(X), and the numbers stay those of r
    return LowBandEstimate(frequency=2.0 * np.pi * np.arange(1, K + 1) / (n * dt), response=response, radius=radius,
                           confidence=float(confidence), window=W, degree=_LPM_DEGREE, samples=int(n), dt=float(dt),
                           region=region)


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


def _local_fit_mimo(U: np.ndarray, Y: np.ndarray, at: int, alpha: float) -> tuple[np.ndarray, float, np.ndarray]:
    """``(Ĝ (l × m), radius, Q (m × m))`` at offset ``at`` of one local fit ``Y_r = G(r) U_r + T(r)``, U (W, m),
    Y (W, l); ``Q = ρ·C^(1/2)``, the region's factor (:func:`low_band_estimate`), NaN with an infinite radius."""
    W, m = U.shape
    l = Y.shape[1]
    d = _LPM_DEGREE + 1
    r = np.arange(W) - at
    powers = r[:, None] ** np.arange(d)[None, :]
    # columns: input j times 1, r, r², … (block j), then the transient's 1, r, r², …
    X = np.hstack([powers * U[:, j:j + 1] for j in range(m)] + [powers]).astype(complex)
    # several inputs: fit (and decide the rank) on unit-norm columns, so the inputs' units do not decide it (one
    # input: as it was); a silent input keeps its zero columns and the fit stays rank deficient
    norms = np.linalg.norm(X, axis=0) if m > 1 else np.ones(X.shape[1])
    scale = np.where(norms > 0.0, 1.0 / np.where(norms > 0.0, norms, 1.0), 1.0)
    theta, _, rank, _ = np.linalg.lstsq(X * scale, Y, rcond=None)
    if rank < X.shape[1]:  # an input silent in the window (or collinear with another): nothing known
        return np.full((l, m), np.nan + 0j), float("inf"), np.full((m, m), np.nan + 0j)
    theta = scale[:, None] * theta
    dof = W - X.shape[1]
    s2 = np.sum(np.abs(Y - X @ theta) ** 2, axis=0) / dof  # per output
    at0 = np.arange(m) * d  # the response at the bin: each input's constant term
    gram = _inverse_gram(X * scale, at0)  # (SXᴴXS)⁻¹ on the unit-norm columns
    C = scale[at0, None] * gram * scale[None, at0]  # (XᴴX)⁻¹ = S (SXᴴXS)⁻¹ S
    lam = float(np.linalg.eigvalsh(0.5 * (C + C.conj().T))[-1])
    fq = scipy.stats.f.ppf(1.0 - alpha, 2 * m, 2 * dof)
    rho = math.sqrt(m * fq * float(np.sum(s2)))
    # Q = ρ·gram^(1/2)·S: QᴴQ = ρ²·S·gram·S = ρ²C, taken on the unit-norm columns (the units' spread stays out)
    w, V = np.linalg.eigh(0.5 * (gram + gram.conj().T))
    root = (V * np.sqrt(np.maximum(w, 0.0))[None, :]) @ V.conj().T
    return theta[at0, :].T.copy(), math.sqrt(lam * m * fq * float(np.sum(s2))), rho * root * scale[None, at0]


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


def _step(dt) -> float:
    """The sample time as a number: 1 (frequencies in rad/sample) for an unspecified one (``dt=True`` or None)."""
    return 1.0 if dt is True or dt is None else float(dt)


def _check_estimate_dt(est, dt, name: str, owner: str) -> None:
    """Refuse an estimate whose sample time differs from the system it is compared with.

    Its frequencies are in rad/s of its own ``dt``: read with another sample time they would name other points
    of the unit circle.  ``dt=True`` (unspecified) is read as 1 (rad/sample), as the estimates do.
    """
    step = _step(dt)
    if est is not None and not math.isclose(float(est.dt), step, rel_tol=1e-9):
        raise DataError(f"{name} was estimated with dt = {est.dt:g} but the sample time of {owner} is {step:g}: "
                        f"its frequencies would be read at other points of the unit circle; estimate it with "
                        f"dt={step:g}")
