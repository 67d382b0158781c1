"""Does a recorded output pile up at its extreme values?  A clipped sensor, seen in the record itself.

A sensor (or an ADC) that clips returns its limit for every sample beyond it: the record is that of a static output
nonlinearity, which no LTI certificate covers, and P̂ fitted through it is biased where the output is large.  Noise
makes an unclipped record's extreme values unique; a clipped one repeats its limit exactly, far more often than any
other value.  Measured (a script: the catalogue's third-order plant, white PRBS and uniform multilevel inputs, the
output clipped at 70 % and 50 % of its largest magnitude, seeds 0–2, both protocols; 24 runs): 24 certified, one of
them without its δ margin on the plant (true ``δ‖K(I+PK)⁻¹‖∞ = 1.34``, a uniform input, nothing in ``assumed``).

The rule: an output channel is clipped at an extreme when that value (to 1e-9 of the channel's range) occurs in at
least :data:`CLIP_FRACTION` of the samples, at least 5 times, and at least 4 times as often as the median count of
the channel's distinct values (a coarsely quantised sensor repeats every value; its extremes are not singled out).
"""
from __future__ import annotations

import numpy as np

from synthesis.validation import as_signal

__all__ = ["clipped_outputs", "CLIP_FRACTION"]

#: Fraction of the samples at an extreme value from which an output counts as clipped there.
CLIP_FRACTION = 0.01
#: Fewest samples at an extreme, and how many times the median count of a distinct value they must exceed.
_MIN_SAMPLES, _OVER_MEDIAN = 5, 4.0


def _moving_part(x: np.ndarray) -> np.ndarray:
    """``x`` without the runs of its first and last value at its ends: a record at rest before its input moves (or
    after it stops) repeats one value there, which need not be a sensor's limit (measured: a noise-free record at rest
    for its first 50 of 1000 samples, driven by a 0/1 PRBS, had been called clipped at its smallest value, 0)."""
    moved = np.flatnonzero(x != x[0])
    if not moved.size:
        return x[:0]
    x = x[moved[0]:]
    last = np.flatnonzero(x != x[-1])
    return x[: last[-1] + 2] if last.size else x[:1]


def _clipped_ends(x: np.ndarray) -> list[tuple[str, float, int]]:
    x = _moving_part(x)
    if not x.size:
        return []
    lo, hi = float(np.min(x)), float(np.max(x))
    span = hi - lo
    if not span > 0.0:
        return []
    _, counts = np.unique(np.round((x - lo) / (1e-9 * span)), return_counts=True)
    typical = float(np.median(counts))
    need = max(_MIN_SAMPLES, CLIP_FRACTION * x.size, _OVER_MEDIAN * typical)
    ends = []
    for name, value in (("smallest", lo), ("largest", hi)):
        k = int(np.sum(np.abs(x - value) <= 1e-9 * span))
        if k >= need:
            ends.append((name, value, k))
    return ends


def clipped_outputs(y) -> str:
    """Why the record's outputs look clipped (module docstring), or ``''``.

    Parameters
    ----------
    y : array_like, shape (n,) or (n, l)
        The recorded outputs, time along axis 0.

    Returns
    -------
    str
        A refusal naming each clipped channel, its limit and how often the record sits there, and the fix.

    Examples
    --------
    >>> import numpy as np
    >>> y = np.sin(0.05 * np.arange(1000)) + 0.01 * np.random.default_rng(0).standard_normal(1000)
    >>> clipped_outputs(y)
    ''
    >>> print(clipped_outputs(np.clip(y, -0.8, 0.8))[:63])
    output 0 sits at its smallest value -0.8 in 208 of 1000 samples
    """
    y = as_signal(y, "y")
    found = []
    for c in range(y.shape[1]):
        ends = _clipped_ends(y[:, c])
        if ends:
            found.append(f"output {c} sits at " + " and at ".join(
                f"its {name} value {value:.4g} in {k} of {y.shape[0]} samples" for name, value, k in ends))
    if not found:
        return ""
    return ("; ".join(found) + ": a clipped sensor (or a saturated output) repeats its limit, and such a record is "
            "that of a static output nonlinearity, which the LTI certificate does not cover. Record within the "
            "sensor's range (lower the excitation, or change the sensor's range), or use a part of the record without "
            "clipping")
