"""What a Chapter 7 solve will cost, estimated before it starts, and the guard every front end applies.

A conic solver given a program too large for the machine does not fail: it swaps, or the operating system kills
the process, and a research script dies without a message.  Both front ends, :func:`~unfalsify.arx_unfalsify`
((7.4)) and :func:`~unfalsify.subspace_unfalsify` ((7.5)), therefore estimate the time and peak memory of the
solve from our measurements on this kind of machine (2 cores), refuse one whose memory exceeds half of what is
available (:class:`~synthesis.DataError`, naming a smaller size or the other backend), and warn about one
estimated above :data:`LONG_SOLVE_SECONDS` (:class:`~unfalsify.exceptions.LongSolveWarning`).

The estimates are fits, not promises: each docstring below states the measurements it reproduces.
"""
from __future__ import annotations

import warnings

from synthesis.validation import DataError, check_count, check_instance

from .exceptions import LongSolveWarning, UnknownSolverError

__all__ = ["solve_estimate", "arx_solve_estimate"]

#: estimated seconds of a solve above which :class:`~unfalsify.exceptions.LongSolveWarning` is issued
LONG_SOLVE_SECONDS = 60.0


def solve_estimate(horizon: int, columns: int, backend: str, channels: tuple[int, int] = (1, 1)
                   ) -> tuple[float, float]:
    """Rough wall time (s) and peak memory (bytes) of a (7.5) solve, from our measurements.

    One input and one output, structured backend, 2 cores: 1.0, 4.1, 21 and 193 s and 0.13, 0.19, 0.69
    and 2.5 GB at (i, j) = (10, 200), (20, 400), (50, 500), (100, 1000) -- fitted as ``1 + 1.9e-6·j·i^2.5`` s
    and ``0.15 GB + 48 stacks of j·i² doubles``.  cvxpy/Clarabel: 5.9 s at (10, 200), 97 s at (20, 400),
    killed above 23.6 GB at (64, 200) -- ``5.9·(j/200)·(i/10)^4`` s and ``2·j·(i(2i+1))²`` bytes (the dense PSD
    cones).  Several channels (``channels = (m, l)``), measured on 2 × 2 data: structured 11 s at (10, 200)
    and 341 s, 1.1 GB at (20, 400) -- ``11·(j/200)·(i/10)^4·(ml/4)²`` s and ``0.15 GB + 185 stacks of
    j·i²·ml doubles``; cvxpy 73 s at (10, 200) -- the SISO estimate times ``(ml)^1.8`` s and ``(ml)²`` bytes.
    Estimates, not promises: they decide a warning or a refusal before the solve.

    Raises
    ------
    DataError
        ``horizon`` or ``columns`` not an integer ≥ 1; ``channels`` not a pair of integers ≥ 1
        (:class:`~synthesis.validation.InputTypeError` when not a pair at all).
    UnknownSolverError
        ``backend`` neither ``"structured"`` nor ``"cvxpy"``.

    Examples
    --------
    >>> t, mem = solve_estimate(10, 200, "structured")             # i = 10, j = 200
    >>> round(t, 2), round(mem / 1e9, 2)                           # seconds, GB
    (1.12, 0.16)
    >>> t, mem = solve_estimate(10, 200, "cvxpy")
    >>> round(t, 2), round(mem / 1e9, 3)
    (5.9, 0.018)
    >>> t, mem = solve_estimate(20, 400, "structured", channels=(2, 2))    # the 2 × 2 measurement
    >>> round(t), round(mem / 1e9, 1)
    (352, 1.1)
    """
    # int() had read -5 and 2.7 silently, and an unknown backend got cvxpy's numbers
    i, j = check_count(horizon, "horizon", 1), check_count(columns, "columns", 1)
    if backend not in ("structured", "cvxpy"):
        raise UnknownSolverError(f"backend must be 'structured' or 'cvxpy' (the two measured), got {backend!r}")
    m, l = _channels(channels)
    ml = m * l
    if ml > 1:
        if backend == "structured":
            return 11.0 * (j / 200.0) * (i / 10.0) ** 4 * (ml / 4.0) ** 2, 1.5e8 + 185 * 8.0 * j * i * i * ml
        t, mem = solve_estimate(i, j, backend)
        return t * ml ** 1.8, mem * ml ** 2
    if backend == "structured":
        return 1.0 + 1.9e-6 * j * i ** 2.5, 1.5e8 + 48 * 8.0 * j * i * i
    return 5.9 * (j / 200.0) * (i / 10.0) ** 4, 2.0 * j * (i * (2 * i + 1)) ** 2


def arx_solve_estimate(n: int, channels: tuple[int, int] = (1, 1)) -> tuple[float, float]:
    """Rough wall time (s) and peak memory (bytes) of a (7.4) solve by the cvxpy backend (Clarabel).

    The program has one LMI of order ``d = n(m + l)`` (``channels = (m, l)``), whose PSD cone of dimension
    ``s = d(d + 1)/2`` Clarabel scales densely.  Measured (2 cores, one solve per process, σ half the noise):
    one channel, 1.4, 11 and 43 s and 0.26, 0.65 and 1.84 GB at n = 40, 60, 80; two inputs and one output,
    7.9 s and 0.44 GB at n = 40; 2 × 2 data, 8.4 s and 0.58 GB at n = 30 -- fitted as ``11·(s/7260)^2.6`` s
    and ``0.17 GB + 10·s²`` bytes (the multichannel points lie below the fit).  The structured backend's memory
    grows like n², not n⁴, and it certifies n = 10⁴ on one channel.

    Raises
    ------
    DataError
        ``n`` not an integer ≥ 1; ``channels`` not a pair of integers ≥ 1.

    Examples
    --------
    >>> t, mem = arx_solve_estimate(80)                      # one channel, n = 80
    >>> round(t), round(mem / 1e9, 2)                        # seconds, GB
    (49, 1.83)
    >>> t, mem = arx_solve_estimate(80, channels=(1, 2))     # one input, two outputs: an LMI of order 240
    >>> round(t), round(mem / 1e9, 1)
    (400, 8.5)
    """
    m, l = _channels(channels)
    d = check_count(n, "n", 1) * (m + l)
    s = d * (d + 1) / 2.0
    return 11.0 * (s / 7260.0) ** 2.6, 1.7e8 + 10.0 * s * s


def _channels(channels) -> tuple[int, int]:
    """``channels`` as a pair ``(m, l)`` of integers ≥ 1 (raises InputTypeError or DataError otherwise)."""
    check_instance(channels, (tuple, list), "channels", "a pair (m, l): the numbers of inputs and outputs")
    if len(channels) != 2:
        raise DataError(f"channels must be a pair (m, l), the numbers of inputs and outputs; got {len(channels)} "
                        f"entries {tuple(channels)!r}")
    return check_count(channels[0], "channels[0] (inputs m)", 1), check_count(channels[1], "channels[1] (outputs l)", 1)


def _memory_available() -> float:
    """Bytes of memory available now (``MemAvailable``), or 24 GiB when it cannot be read."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    return 24.0 * 2 ** 30


def _guard(estimate: tuple[float, float], what: str, smaller: str, other: str | None = None,
           other_estimate: tuple[float, float] | None = None, stacklevel: int = 3) -> None:
    """Refuse a solve that cannot fit in memory (naming ``smaller`` and the ``other`` backend if it needs less);
    warn about one estimated above :data:`LONG_SOLVE_SECONDS`.  ``stacklevel`` as for ``warnings.warn`` called
    by this function's caller (the ``_guard_*`` wrappers take it as seen from the front end: 2 is the user)."""
    seconds, memory = estimate
    alt_s, alt_m = other_estimate if other_estimate is not None else (float("inf"), float("inf"))
    available = _memory_available()
    if memory > 0.5 * available:
        raise DataError(
            f"{what} needs about {memory / 2 ** 30:.1f} GB, more than half the {available / 2 ** 30:.1f} GB "
            f"available: {smaller}" + (f", or backend={other!r} (about {alt_m / 2 ** 30:.1f} GB)"
                                       if other and alt_m < memory else ""))
    if seconds > LONG_SOLVE_SECONDS:
        warnings.warn(
            f"{what} is estimated at {seconds:.0f} s and {memory / 2 ** 30:.1f} GB"
            + (f" (backend={other!r}: about {alt_s:.0f} s)" if other and alt_s < seconds else "")
            + f"; {smaller} is faster", LongSolveWarning, stacklevel=stacklevel + 1)


def _guard_subspace(i: int, j: int, backend: str, channels: tuple[int, int] = (1, 1), stacklevel: int = 2) -> None:
    """:func:`_guard` for (7.5) at (i, j)."""
    other = "cvxpy" if backend == "structured" else "structured"
    _guard(solve_estimate(i, j, backend, channels), f"the (7.5) solve at (i, j) = ({i}, {j}) with backend={backend!r}",
           "a shorter window (fewer columns j) or a smaller horizon", other, solve_estimate(i, j, other, channels),
           stacklevel=stacklevel + 1)


def _guard_arx(n: int, channels: tuple[int, int] = (1, 1), stacklevel: int = 2) -> None:
    """:func:`_guard` for (7.4) by the cvxpy backend (the structured backend's memory is O(n²))."""
    _guard(arx_solve_estimate(n, channels), f"the (7.4) solve at n = {n} with backend='cvxpy'",
           "fewer samples or backend='structured' (memory O(n²))", stacklevel=stacklevel + 1)
