"""Excitation and reference signals (time along axis 0; every random signal takes a seed).

* :func:`prbs` — maximum-length pseudo-random binary sequence, ±amplitude
  (unity power by default), repeated periodically (§5.4, Fig. 6.2).
* :func:`white_noise` — zero-mean white Gaussian noise.
* :func:`step_sequence` — piecewise-constant reference (series of steps, §6.3).
"""
from __future__ import annotations

import numpy as np
from scipy.signal import max_len_seq

from synthesis.validation import DataError, as_real_array, check_count

__all__ = ["prbs", "white_noise", "step_sequence", "step"]


def _check_length(n, name: str = "n") -> int:
    return check_count(n, f"{name} (a number of samples)", 1)


def prbs(n: int, nbits: int | None = None, *, amplitude: float = 1.0, seed=None) -> np.ndarray:
    """Maximum-length PRBS with values ``±amplitude`` (power ``amplitude²``).

    Parameters
    ----------
    n : int
        Number of samples returned.
    nbits : int, optional
        Shift-register length; the period is ``2**nbits − 1`` samples and the
        sequence is repeated (periodic cycles) when ``n`` exceeds it.  By default
        the smallest ``nbits`` (≥ 2) whose period covers ``n`` (one cycle).
    amplitude : float
        Level of the two values; 1 gives unity power (§5.4).
    seed : int or numpy Generator, optional
        Chooses the (nonzero) initial register state, i.e. the phase of the
        cycle; ``None`` starts from the all-ones state (deterministic).

    Returns
    -------
    ndarray, shape (n,)

    Examples
    --------
    >>> import numpy as np
    >>> prbs(7).tolist()                                           # one period of 2³ − 1 samples
    [1.0, 1.0, 1.0, -1.0, 1.0, -1.0, -1.0]
    >>> prbs(10, nbits=2).tolist()                                 # period 3, repeated
    [1.0, 1.0, -1.0, 1.0, 1.0, -1.0, 1.0, 1.0, -1.0, 1.0]
    >>> u = prbs(1023, amplitude=0.5, seed=0)
    >>> float(np.mean(u ** 2)), round(float(np.sum(u)), 6)         # power amplitude², one more + than −
    (0.25, 0.5)
    """
    n = _check_length(n)
    if nbits is None:
        nbits = max(2, int(np.ceil(np.log2(n + 1))))
    if isinstance(nbits, bool) or not isinstance(nbits, (int, np.integer)) or not 2 <= nbits <= 32:
        raise DataError(f"nbits must be an integer in [2, 32], got {nbits!r}")
    if not np.isfinite(amplitude) or amplitude <= 0:
        raise DataError(f"amplitude must be positive, got {amplitude!r}")
    state = None
    if seed is not None:
        rng = np.random.default_rng(seed)
        state = rng.integers(0, 2, size=nbits)
        if not state.any():
            state[rng.integers(nbits)] = 1
    period = 2**nbits - 1
    seq, _ = max_len_seq(nbits, state=state, length=period)
    cycle = amplitude * (2.0 * seq.astype(float) - 1.0)
    reps = -(-n // period)
    return np.tile(cycle, reps)[:n]


def white_noise(n: int, sigma: float = 1.0, channels: int | None = None, *, seed=None) -> np.ndarray:
    """Zero-mean white Gaussian noise with standard deviation ``sigma``.

    Returns shape ``(n,)`` when ``channels`` is None, else ``(n, channels)``.

    Examples
    --------
    >>> import numpy as np
    >>> w = white_noise(1000, 0.5, seed=0)
    >>> w.shape, round(float(np.std(w)), 1)
    ((1000,), 0.5)
    >>> white_noise(5, channels=2, seed=0).shape
    (5, 2)
    """
    n = _check_length(n)
    if not np.isfinite(sigma) or sigma < 0:
        raise DataError(f"sigma must be >= 0, got {sigma!r}")
    rng = np.random.default_rng(seed)
    shape = (n,) if channels is None else (n, _check_length(channels, "channels"))
    return sigma * rng.standard_normal(shape)


def step_sequence(n: int, levels, hold: int) -> np.ndarray:
    """Series of steps: ``levels[0]`` for ``hold`` samples, then ``levels[1]``, … (cycled).

    Parameters
    ----------
    n : int
        Number of samples.
    levels : array_like, shape (k,) or (k, channels)
        Successive reference values.
    hold : int
        Samples per level.

    Returns
    -------
    ndarray, shape (n,) or (n, channels)

    Examples
    --------
    >>> step_sequence(8, [0.0, 1.0, -1.0], 2).tolist()             # cycled after the last level
    [0.0, 0.0, 1.0, 1.0, -1.0, -1.0, 0.0, 0.0]
    >>> step_sequence(4, [[1.0, 0.0], [0.0, 1.0]], 2).tolist()     # two channels
    [[1.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.0, 1.0]]
    """
    n = _check_length(n)
    hold = _check_length(hold, "hold")
    lv = as_real_array(levels, "levels")  # text or complex levels had raised numpy's ValueError or TypeError
    if lv.ndim == 0 or lv.shape[0] == 0 or not np.all(np.isfinite(lv)):
        raise DataError("levels must be a non-empty finite array of step values")
    idx = (np.arange(n) // hold) % lv.shape[0]
    return lv[idx]


def step(n: int, at: int = 0, amplitude: float = 1.0) -> np.ndarray:
    """Unit (or scaled) step of length ``n`` switching on at sample ``at``.

    Examples
    --------
    >>> step(5, at=2).tolist()
    [0.0, 0.0, 1.0, 1.0, 1.0]
    >>> step(3, amplitude=2.0).tolist()
    [2.0, 2.0, 2.0]
    """
    n = _check_length(n)
    if not 0 <= at < n:
        raise DataError(f"step time at={at} must lie in [0, n)")
    r = np.zeros(n)
    r[at:] = amplitude
    return r
