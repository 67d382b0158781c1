"""Is a record that of one time-invariant plant?  A Chow test on ARX fits of its consecutive segments.

Every certificate of Chapter 7 assumes the data come from one LTI plant (plus noise): δ is unfalsified for the plant
that produced the window, and the certificate speaks about the plant the loop will meet.  A plant that changes
during the record (a gain that drifts, a load that moves) violates that premise, and the model-error tests of
:mod:`unfalsify.premise` need not see it: they compare P̂ with data, and a large enough δ covers the change on the
record while the plant moves on.  This module tests the premise directly.

The test (Chow's test of a structural change, applied to an ARX regression): every output is regressed on the
past ``p`` samples of all outputs and inputs, once on the whole record and once on each of ``K`` consecutive
segments.  If one ARX model generated the record (white equation errors), the drop of the residual sum of squares
from the pooled fit to the segment fits is chance, and

    F = ((RSS_pooled − Σ RSS_s)/d₁) / (Σ RSS_s/d₂),   d₁ = Σ rank_s − rank_pooled,  d₂ = N − Σ rank_s,

follows the F(d₁, d₂) distribution; a small p-value says the segments need different models.  Several outputs:
one test per output, the smallest p-value times l (Bonferroni).

The ARX order matters: an output-error plant's equation error is coloured, and a short ARX model leaves it
coloured, which the F-test reads as a change.  Measured on the adversarial catalogue's records (1500 samples,
seeds 0–9, two halves; 450 records of LTI plants, 20 with the input gain drifting 0.6 → 1.4 over the record):
with p = 8, LTI records with multisine inputs gave p-values down to 1e-11; with p = 16 the smallest p-value of an
LTI plant with stationary noise was 3.1e-3, the two below 1e-3 both being records whose noise drifts, and all 20
drifting plants gave 1e-3 or less (18 of them below 1e-6).  The default order is therefore the largest up to 16
that leaves ten rows per parameter in each segment, and at least 8 (a shorter record is refused, unless ``order``
is given).  On the last 600 samples alone (order 14) no LTI record fell below 1e-3 and 4 of the 20 drifting ones
did: a test of time invariance needs the whole record.

False rejections at 1e-3 on LTI records built to be hard (1500 samples, 50 records each, white, ±1 PRBS and
low-pass inputs): none for a pole at 0.995, a resonance at 0.05 rad/sample with radius 0.99, AR(0.99) process
noise, random stable plants of order 4 and 8, or a signal-to-noise ratio of 1; the p-values there lay above
0.009.  2 × 2 records: 1 of 50 (5e-4).  A first-order output-error plant at 200 records per input (white, ±1 PRBS,
low-pass): 1 of 200 below 1e-3 for every input, alike with Gaussian and with heavy-tailed (Student t, 3 degrees of
freedom) sensor noise, the smallest p-values 7e-6 and 8e-5.  So the false-rejection rate is about five times the
level, and heavy tails are not its cause (an earlier count of 1 in 50 with t noise had suggested so): in the worst
Gaussian record the halves' noise variances differ by 1.24 by chance and the ARX(16) fit leaves the output-error
equation error slightly coloured.  Trimming the rows whose residual exceeds 3.5 robust standard deviations made
it worse (2–3 of 200).  A false rejection refuses a certificate; it never issues a wrong one.

Noise-free records (simulations) leave residuals at the rounding level, where F is no statistic: ranks decided at
rounding and rounding errors that do not scale like noise had rejected noise-free LTI records (p = 6e-38 at 3000
samples; 6e-21 with noise 1e-12 at 1000).  All fits of one test therefore share the pooled regressor's singular
directions above 1e-8 of the largest (noisy records keep them all: of the adversarial catalogue's 470 records, seeds
0–9, only the 40 low-band multisine ones changed, p 0.016–0.95 before and 0.056–0.99 after, none near the level),
and residuals below ``1e3·eps·‖y‖`` count as exact fits: one model for the whole record (p = 1), or exact but
different models for the segments (p = 0).

Two records (``against=``): a fitting record and a validation record from another experiment are each tested
alone by the halves, which cannot see a plant that changed *between* them.  ``against=`` compares them: the rows of
each record regressed on its own past only, one ARX model for both against one for each.  Measured (scripts,
2026-11-28; the first 720 samples of a 1200-sample record against its last 480, ARX(16)): of the adversarial
catalogue's 500 LTI records (seeds 0–9) one fell below 1e-3 (5.4e-4, a quantised low-band multisine); of 80 records
with Student-t(3) or 20σ-outlier noise none (smallest 0.013); of 60 records whose gain stepped ×1.5 or poles moved
×0.6 at the start of the validation record or 80 samples into it, 57 (all 40 at the start); of 80 slow drifts
(poles ×0.85 or ×1.2, gain ×0.8 or ×1.2 over the record) 6.  The two records' inputs must be alike: an output-error
plant's ARX fit depends on the input's spectrum, and 18 of 270 LTI pairs with inputs of different bands (a low-pass
noise against a multisine, seeds 0–9) fell below 1e-3.  A window of 49 samples against the 480 (Chow's predictive
test, ARX(8), (11) or (16), seeds 0–5) saw at most 1 of the 36 abrupt changes below 1e-3, and 7–15 of 348 honest
records fell below it (20σ outliers in the window: p down to 1e-14): too short a record is refused (``DataError``)
rather than tested.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.stats

from synthesis.results import result
from synthesis.validation import DataError, as_signal, check_count, check_level

from .arx import arx_regressor

__all__ = ["InvarianceTest", "check_time_invariance", "min_record_length", "TIME_INVARIANCE_LEVEL"]

#: Default level of :func:`check_time_invariance`: a p-value below it rejects time invariance.
TIME_INVARIANCE_LEVEL = 1e-3
#: Largest default ARX order (module docstring: 8 left coloured equation errors that the test reads as change).
_MAX_ORDER = 16
#: Rows per parameter that the default order leaves in every segment.
_ROWS_PER_PARAMETER = 10
#: Smallest default order: a shorter ARX model leaves an output-error plant's equation error coloured.
_MIN_ORDER = 8
#: Singular values of the (column-scaled) regressor below this fraction of the largest are dropped from every fit of
#: one test (:func:`_pooled_coordinates`): directions that only near noise-free data leave this weak carry rounding.
#: Noisy records keep every direction (their regressors' condition numbers stay far below 1e8).
_RANK_RTOL = 1e-8
#: Residuals below ``_EXACT·eps·‖target‖`` are rounding, not noise (:func:`_chow`): a noise-free record's ARX fits
#: left 0.5–0.8 of ``eps·cond·‖target‖`` (measured, orders 9 and 16, 400–10 000 samples).
_EXACT = 1e3


@result
@dataclass(frozen=True)
class InvarianceTest:
    """Result of :func:`check_time_invariance`.

    Attributes
    ----------
    p_value : float
        Probability, under one ARX model of order ``order`` with white equation errors, of an F at least as large
        (several outputs: the smallest per-output p-value times the number of outputs, at most 1).
    statistic : float
        F of the output with the smallest p-value.
    dof : tuple of int
        ``(d₁, d₂)`` of that output's F distribution.
    order : int
        ARX order p (past samples of every output and input).
    segments : int
        Number K of consecutive segments compared.
    samples : int
        Length of the record.
    level : float
        The level the p-value is compared with.
    reason : str
        ``''`` when time invariance is not rejected; otherwise what the data show and the fix.
    split : int
        The sample where the second of two unequal parts begins (``split=``), 0 for ``segments`` equal ones.
    """

    p_value: float
    statistic: float
    dof: tuple
    order: int
    segments: int
    samples: int
    level: float
    reason: str
    split: int = 0

    @property
    def rejected(self) -> bool:
        """The record's segments need different ARX models at the test's level."""
        return bool(self.p_value < self.level)


def _default_order(n: int, channels: int, segments: int) -> int:
    """The largest order up to 16 leaving :data:`_ROWS_PER_PARAMETER` rows per parameter in each segment."""
    rows = n // segments
    return int(min(_MAX_ORDER, rows // (_ROWS_PER_PARAMETER * channels + 1)))


def min_record_length(outputs: int, inputs: int, segments: int = 2) -> int:
    """Shortest record :func:`check_time_invariance` tests at its default order (8, ten rows per parameter in each of
    ``segments`` segments).

    Examples
    --------
    >>> min_record_length(1, 1), min_record_length(2, 2)
    (336, 656)
    >>> min_record_length(1, 1, segments=1)
    Traceback (most recent call last):
    ...
    synthesis.exceptions.DataError: segments must be an integer ≥ 2, got 1
    """
    outputs, inputs = check_count(outputs, "outputs", 1), check_count(inputs, "inputs", 1)
    segments = check_count(segments, "segments", 2)
    return int(segments * _MIN_ORDER * (_ROWS_PER_PARAMETER * (outputs + inputs) + 1))


def _pooled_coordinates(Phi: np.ndarray) -> np.ndarray:
    """``Φ`` (columns scaled to unit norm) in the coordinates of its right singular vectors whose singular values
    exceed :data:`_RANK_RTOL` of the largest: the regressor every fit of :func:`_chow` uses."""
    scale = np.linalg.norm(Phi, axis=0)
    X = Phi / np.where(scale > 0, scale, 1.0)
    _, sv, Vt = np.linalg.svd(X, full_matrices=False)
    keep = sv > _RANK_RTOL * (sv[0] if sv.size else 0.0)
    return X @ Vt[keep].T


def _rss_rank(Phi: np.ndarray, target: np.ndarray) -> tuple[float, int]:
    theta, _, rank, _ = np.linalg.lstsq(Phi, target, rcond=None)
    r = target - Phi @ theta
    return float(r @ r), int(rank)


def _chow(Phi: np.ndarray, target: np.ndarray, parts: list) -> tuple[float, float, tuple[int, int]]:
    """F, its p-value and (d₁, d₂) for one output, the segments given as lists of rows (``parts``).

    Every fit works in the coordinates of the pooled regressor's singular directions above :data:`_RANK_RTOL` (columns
    scaled to unit norm first), so that the pooled and the segment fits share one rank: near noise-free records make
    the regressor singular to within rounding, and ranks decided separately at the rounding level had made d₁ and the
    F of an LTI record meaningless (p = 6e-21 with noise 1e-12).  Residuals at the rounding level of the target
    (:data:`_EXACT`) carry no noise to scale F by: then one model fits the record exactly (p = 1), or the segments need
    different exact models (F = ∞, p = 0)."""
    Z = _pooled_coordinates(Phi)
    pooled, rank = _rss_rank(Z, target)
    parts = [_rss_rank(Z[ix], target[ix]) for ix in parts]
    within = sum(r for r, _ in parts)
    d1 = sum(k for _, k in parts) - rank
    d2 = Z.shape[0] - sum(k for _, k in parts)
    rounding = (_EXACT * np.finfo(float).eps * float(np.linalg.norm(target))) ** 2
    if within <= rounding and d1 > 0:
        return (0.0, 1.0, (d1, d2)) if pooled <= rounding else (float("inf"), 0.0, (d1, d2))
    if d1 <= 0 or d2 <= 0 or not within > 0:
        return float("nan"), 1.0, (d1, d2)
    F = max(pooled - within, 0.0) / d1 / (within / d2)
    return float(F), float(scipy.stats.f.sf(F, d1, d2)), (int(d1), int(d2))


def check_time_invariance(u, y, *, order: int | None = None, segments: int = 2,
                          level: float = TIME_INVARIANCE_LEVEL, split: int | None = None,
                          against=None) -> InvarianceTest:
    """Test whether ``(u, y)`` is the record of one time-invariant plant (module docstring: Chow's test on ARX fits
    of ``segments`` consecutive parts).

    Parameters
    ----------
    u, y : array_like, shape (n,) or (n, m) and (n, l)
        The whole record, time along axis 0: the longer, the smaller the change it detects (a gain drifting
        0.6 → 1.4 over 1500 samples was detected, its last 600 samples alone were not).
    order : int, optional
        ARX order p.  Default: the largest up to 16 that leaves ten rows per parameter in each segment; a record
        whose default would be below 8 is refused (``DataError``).
    segments : int
        Number of consecutive segments (2: the two halves).
    level : float
        p-values below it reject time invariance.
    split : int, optional
        Compare the two parts ``[0, split)`` and ``[split, n)`` instead of ``segments`` equal ones, e.g. where a
        held-out part begins: a change there is what makes a model fitted before it and tested after it disagree,
        and halves dilute a change that lies off their middle (a gain stepping 1 → 1.5 at 720 of 1200 samples
        gave p = 0.004 on the halves and 1e-4 at 800; measured, a script).  The default order then leaves ten rows
        per parameter in the shorter part.
    against : tuple of array_like, optional
        ``(u2, y2)``, a second record (another experiment, e.g. a validation record): compare ``(u, y)`` with it
        instead of with itself -- one ARX model for both records, each row regressed on its own record's past only.
        A plant that changed between the two experiments is what this sees, and neither record alone can (a
        plant whose poles moved ×0.6 between a fitting record and a validation record; :func:`_across`).  The
        default order then leaves ten rows per parameter in the shorter record.

    Returns
    -------
    InvarianceTest

    Raises
    ------
    DataError
        A record too short for the default order 8 (the message gives the length needed), an order that leaves
        fewer rows than parameters, an order or number of segments below 1 or 2, a level outside (0, 1).

    Examples
    --------
    >>> import numpy as np
    >>> import scipy.signal
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(1000)
    >>> y = scipy.signal.lfilter([0.0, 0.5], [1.0, -0.8], u) + 0.05 * rng.standard_normal(1000)
    >>> check_time_invariance(u, y).rejected
    False
    >>> gain = np.linspace(0.6, 1.4, 1000)                          # the input gain drifts
    >>> y2 = scipy.signal.lfilter([0.0, 0.5], [1.0, -0.8], gain * u) + 0.05 * rng.standard_normal(1000)
    >>> test = check_time_invariance(u, y2)
    >>> test.rejected, test.p_value < 1e-6
    (True, True)
    >>> step = np.where(np.arange(1000) < 700, 1.0, 1.3)             # the gain steps at sample 700
    >>> y3 = scipy.signal.lfilter([0.0, 0.5], [1.0, -0.8], step * u) + 0.05 * rng.standard_normal(1000)
    >>> check_time_invariance(u, y3, split=700).rejected
    True
    >>> y4 = scipy.signal.lfilter([0.0, 0.75], [1.0, -0.8], u) + 0.05 * rng.standard_normal(1000)  # a second plant
    >>> check_time_invariance(u[:500], y[:500], against=(u[500:], y[500:])).rejected     # two records of one plant
    False
    >>> check_time_invariance(u[:500], y[:500], against=(u[500:], y4[500:])).rejected    # the gain 1.5 times larger
    True
    """
    u = as_signal(u, "u")
    y = as_signal(y, "y", n=u.shape[0])
    n, m = u.shape
    l = y.shape[1]
    segments = check_count(segments, "segments", 2)
    level = check_level(level, "level", maximum=1.0)  # float(level) had passed '0.1' and raised TypeError on None
    if against is not None:
        if split is not None:
            raise DataError("pass split= (a change inside one record) or against= (a second record), not both")
        return _across(u, y, against, order, float(level))
    if split is not None:
        split = check_count(split, "split", 1)
        if split >= n:
            raise DataError(f"split must lie inside the record (1 ≤ split < {n}), got {split}")
        segments = 2
    shortest = n // segments if split is None else min(split, n - split)
    p = _default_order(shortest * segments, l + m, segments) if order is None else order
    if order is None and p < _MIN_ORDER and split is not None:
        raise DataError(f"the part {'before' if split < n - split else 'from'} sample {split} is too short to test "
                        f"time invariance at that split: ten rows per parameter of an ARX({_MIN_ORDER}) model need "
                        f"{min_record_length(l, m) // 2} samples in each part; pass order= to test with a shorter "
                        "model anyway")
    if order is None and p < _MIN_ORDER:
        need = min_record_length(l, m, segments)
        raise DataError(f"a record of {n} samples is too short to test time invariance with {l} output(s) and {m} "
                        f"input(s): {segments} segments of ten rows per parameter of an ARX({_MIN_ORDER}) model need "
                        f"{need} samples (a shorter model leaves coloured equation errors, which the test reads as "
                        "change); pass a longer record, or order= to test with a shorter model anyway")
    p = check_count(p, "order", 1)
    if segments * (p * (l + m) + 1) > n - p or (split is not None and min(split - p, n - split) < p * (l + m) + 1):
        raise DataError(f"order {p} leaves fewer rows than parameters in {segments} segments of {n} samples: use a "
                        "smaller order (or the default)")
    Phi = arx_regressor(u, y, p, p)[0][p:]  # rows whose whole past lies in the record
    # row r of Φ predicts sample r + p: the part after the split starts at row split − p
    parts = (np.array_split(np.arange(n - p), segments) if split is None else
             [np.arange(max(split - p, 0)), np.arange(max(split - p, 0), n - p)])
    F, pv, dof, worst = _worst_output(Phi, y[p:], parts)
    reason = ""
    if pv < level:
        where, how = _evidence(F, pv, dof, worst, l, level, "segment")
        what = (f"its {segments} consecutive segments" if split is None else
                f"its parts before and from sample {split}")
        reason = (f"the record is not that of one time-invariant plant: ARX({p}) fits on {what} differ{where} ({how}); "
                  "the plant, or the noise, changed during the record. Use a record over which neither changes (or "
                  "its part that does not), or model the change")
    return InvarianceTest(p_value=float(pv), statistic=float(F), dof=tuple(dof), order=p, segments=segments,
                          samples=int(n), level=float(level), reason=reason, split=0 if split is None else int(split))


def _across(u: np.ndarray, y: np.ndarray, against, order: int | None, level: float) -> InvarianceTest:
    """:func:`check_time_invariance` of two records (``against=``): Chow's test of one ARX model for both, the rows of
    each record regressed on that record's own past (no row straddles the two experiments)."""
    if not (isinstance(against, (tuple, list)) and len(against) == 2):
        raise DataError(f"against must be a pair (u2, y2), got {type(against).__name__}")
    u2 = as_signal(against[0], "against u")
    y2 = as_signal(against[1], "against y", n=u2.shape[0])
    (n1, m), l = u.shape, y.shape[1]
    if u2.shape[1] != m or y2.shape[1] != l:
        raise DataError(f"against has {u2.shape[1]} input(s) and {y2.shape[1]} output(s), the record {m} and {l}: "
                        "pass a record of the same channels")
    shortest = min(n1, u2.shape[0])
    p = _default_order(2 * shortest, l + m, 2) if order is None else check_count(order, "order", 1)
    if order is None and p < _MIN_ORDER:
        raise DataError(f"the shorter of the two records has {shortest} samples, too few to compare them: ten rows per "
                        f"parameter of an ARX({_MIN_ORDER}) model need {min_record_length(l, m) // 2} samples in "
                        "each; pass longer records, or order= to test with a shorter model anyway")
    if shortest - p < p * (l + m) + 1:
        raise DataError(f"order {p} leaves fewer rows than parameters in a record of {shortest} samples: use a "
                        "smaller order (or the default)")
    Phi = np.vstack([arx_regressor(u, y, p, p)[0][p:], arx_regressor(u2, y2, p, p)[0][p:]])
    Y = np.vstack([y[p:], y2[p:]])
    parts = [np.arange(n1 - p), np.arange(n1 - p, Phi.shape[0])]
    F, pv, dof, worst = _worst_output(Phi, Y, parts)
    reason = ""
    if pv < level:
        where, how = _evidence(F, pv, dof, worst, l, level, "record")
        reason = (f"the two records are not those of one time-invariant plant: ARX({p}) fits on the record and on the "
                  f"second record differ{where} ({how}); the plant, or the noise, changed between the experiments. "
                  "Use records of the plant as it is now (both taken after the change), or model the change")
    return InvarianceTest(p_value=float(pv), statistic=float(F), dof=tuple(dof), order=p, segments=2,
                          samples=int(n1 + u2.shape[0]), level=level, reason=reason, split=int(n1))


def _worst_output(Phi: np.ndarray, Y: np.ndarray, parts) -> tuple[float, float, tuple, int]:
    """Chow's test of every output column of ``Y`` on ``Phi`` over ``parts``: ``(F, p, dof, output)`` of the smallest
    p-value, the p-value multiplied by the number of outputs (Bonferroni, at most 1)."""
    l = Y.shape[1]
    tests = [_chow(Phi, Y[:, c], parts) for c in range(l)]
    worst = min(range(l), key=lambda c: tests[c][1])
    F, pv, dof = tests[worst]
    return F, min(1.0, pv * l), dof, worst


def _evidence(F: float, pv: float, dof, worst: int, outputs: int, level: float, part: str) -> tuple[str, str]:
    """The rejection's output (``''`` for one output) and its statistic, for a reason naming each ``part``."""
    where = f" (output {worst})" if outputs > 1 else ""
    how = (f"Chow's F = {F:.3g} on {dof} degrees of freedom, p = {pv:.2g} < {level:g}" if np.isfinite(F) else
           f"each {part} is fitted exactly, to rounding, but not by one model")
    return where, how
