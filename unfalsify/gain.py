"""Theorem 7.1: the smallest H∞ gain of a causal LTI operator that explains input/output data.

Data ``(u, y)`` of length n are explained by some LTI ``Δ`` with ``‖Δ‖∞ ≤ γ`` (system at
rest before t = 0) iff (7.1) ``T(y)ᵀT(y) ⪯ γ² T(u)ᵀT(u)``.  When ``u₀ ≠ 0``, ``T(u)`` is
invertible and, because lower-triangular Toeplitz matrices commute,
``T(y) = T(h) T(u)`` with ``h = T(u)⁻¹ y`` (the first n Markov parameters of the only
causal operator that maps u to y on the window).  (7.1) is then ``T(h)ᵀT(h) ⪯ γ² I``:

    γ_min = ‖T(h)‖₂,   h = T(u)⁻¹ y,

which by Carathéodory–Fejér is also the smallest H∞ norm of any causal LTI system with
Markov parameters h.  This never forms ``T(u)ᵀT(u)`` (whose condition number is
``cond(T(u))²``).

Several channels (u: (n, m), y: (n, l), time along axis 0).  The data relation
``y_s = Σ_{t≤s} h_t u_{s−t}`` is linear in the l × m Markov parameters h, and the least H∞ norm of a
causal LTI Δ with first n Markov parameters h is ``‖T(h)‖₂`` (T(h) the nl × nm block lower-triangular
Toeplitz matrix; matrix Carathéodory–Fejér), so Theorem 7.1 becomes ``γ_min = min ‖T(h)‖₂`` subject to
the data relation.  In block-Toeplitz form the relation is ``T(y) = T(h) T(u)`` with the signal
matrices ``T(u)`` (nm × n) and ``T(y)`` (nl × n) of :func:`~unfalsify.solvers.toeplitz.signal_toeplitz`,
and (7.1) keeps its form, ``T(y)ᵀT(y) ⪯ γ² T(u)ᵀT(u)`` (Poolla et al. 1994, time-domain model
validation, which holds for several channels).  With ``T(u) = QR`` (thin QR, R n × n invertible when
``u₀ ≠ 0``) that is

    γ_min = ‖T(y) R⁻¹‖₂,

computed without forming the Gram matrix.  For one input (m = 1) T(u) is square, h is unique
(``h = T(u)⁻¹ y``, one deconvolution per output) and γ_min = ‖T(h)‖₂ as for SISO; for m > 1 many h
explain the data and only γ_min is returned (``impulse`` is None).  Necessity is one line: any
feasible h gives ``T(y)ᵀT(y) = T(u)ᵀT(h)ᵀT(h)T(u) ⪯ ‖T(h)‖₂² T(u)ᵀT(u)``; sufficiency is the
commutant-lifting step of Poolla et al., checked in ``tests/test_unfalsify_mimo.py`` against the
semidefinite program ``min ‖T(h)‖₂`` written out in cvxpy.

A record that starts at rest (the input vector zero for the first p samples) makes T(u) singular; its answer
is that of the samples after the zeros when y is zero there too, and ∞ when it is not (no causal Δ makes an
output before the input): see :func:`unfalsified_gain_result`.
"""
from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from synthesis.results import result

from synthesis.validation import as_signal, check_flag, check_nonnegative

from ._common import COND_WARN, samples_at_rest
from .exceptions import IllConditionedWarning
from .solvers.extension import minimal_extension
from .solvers.toeplitz import block_toeplitz_norm, deconvolve, signal_toeplitz, toeplitz_cond, toeplitz_norm

__all__ = ["GainResult", "unfalsified_gain", "unfalsified_gain_result", "is_unfalsified"]


@result
@dataclass(frozen=True)
class GainResult:
    """Result of Theorem 7.1.

    Attributes
    ----------
    gamma : float
        Smallest γ satisfying (7.1), ``‖T(h)‖₂``.
    impulse : ndarray or None
        ``h = T(u)⁻¹ y``: Markov parameters of the causal operator mapping u to y; shape (n,) for SISO,
        (n, l, 1) for one input and l outputs, None for several inputs (h is not unique then) and when no
        causal operator explains the data.  After ``leading_zeros`` = p zero inputs only the first n − p are
        determined; the last p are the least-norm extension, so that ``‖T(h)‖₂ = γ`` still.
    cond_Tu : float
        2-norm condition number of ``T(u)`` (nm × n for m inputs) of the samples after the leading zeros;
        above :data:`COND_WARN` the answer is flagged.
    exact : bool
        Whether ``h`` was computed in exact rational arithmetic.
    method : str
        How ``‖T(h)‖₂`` was computed (``"dense"`` or ``"lanczos"``; ``"qr"``: ``‖T(y)R⁻¹‖₂`` for m > 1);
        ``"acausal"``: y moves while u is still zero, no causal Δ explains the data and γ = ∞; ``"zero input"``:
        u and y are zero throughout, γ = 0.
    leading_zeros : int
        How many samples the input is exactly zero (every channel) before it first moves; the answer is
        that of the data after them, the system being at rest before t = 0.
    """

    gamma: float
    impulse: np.ndarray | None
    cond_Tu: float
    exact: bool
    method: str
    leading_zeros: int = 0

    @property
    def well_conditioned(self) -> bool:
        """True when ``cond_Tu <= COND_WARN``."""
        return bool(self.cond_Tu <= COND_WARN)


def _checked_pair(u, y) -> tuple[np.ndarray, np.ndarray]:
    """``(u, y)`` as (n, m) and (n, l) float arrays (time along axis 0)."""
    u = as_signal(u, "u")
    y = as_signal(y, "y", n=u.shape[0])
    return u, y


def _at_rest_result(u: np.ndarray, y: np.ndarray, p: int) -> GainResult | None:
    """The answer when the input is zero for its first p samples and that alone decides it, else None.

    y moving before u does: no causal Δ explains the data (γ = ∞, no h).  An input that never moves and an
    output that stays at zero: Δ = 0 (γ = 0, every Markov parameter free, the least-norm choice zero).
    """
    n, m = u.shape
    if np.any(y[:p] != 0.0):
        return GainResult(gamma=float("inf"), impulse=None, cond_Tu=float("inf"), exact=False, method="acausal",
                          leading_zeros=p)
    if p < n:
        return None
    impulse = None if m > 1 else (np.zeros(n) if y.shape[1] == 1 else np.zeros((n, y.shape[1], 1)))
    return GainResult(gamma=0.0, impulse=impulse, cond_Tu=float("inf"), exact=True, method="zero input",
                      leading_zeros=p)


def _extended(short: GainResult, n: int, p: int) -> GainResult:
    """The answer of the samples after p zero inputs as that of the whole record (h at full length).

    With ``u_0 … u_{p−1} = 0`` and ``y_0 … y_{p−1} = 0``, ``T(u) = [0 0; T(u') 0]`` and likewise T(y), so (7.1)
    is (7.1) of ``(u', y') = (u[p:], y[p:])``.  The last p Markov parameters never meet the data; the least-norm
    extension (:func:`~unfalsify.solvers.extension.minimal_extension`) keeps ``‖T(h)‖₂ = γ``.
    """
    h = short.impulse
    if h is not None and np.all(np.isfinite(h)):
        h = minimal_extension(h, n)
    elif h is not None:
        h = np.concatenate([h, np.full((p,) + h.shape[1:], np.nan)])
    return dataclasses.replace(short, impulse=h, leading_zeros=p)


def unfalsified_gain_result(u, y, *, exact: bool | None = None, method: str = "auto", warn: bool = True) -> GainResult:
    """Theorem 7.1 with diagnostics: smallest γ for (7.1), ``h`` and cond ``T(u)``.

    Parameters
    ----------
    u : array_like, shape (n,) or (n, m)
    y : array_like, shape (n,) or (n, l)
        Input/output data, time along axis 0, system at rest before t = 0.  One channel each is the
        SISO Theorem 7.1; several channels see the module docstring (γ = ‖T(y)R⁻¹‖₂ for m > 1).
    exact : bool, optional
        One input: compute ``h = T(u)⁻¹ y`` in exact rational arithmetic (default: when n ≤ 400).
        Forward substitution in floating point is usually accurate too (triangular
        systems are), but the exact route needs no such argument.  Ignored for m > 1.
    method : {"auto", "dense", "lanczos"}
        How ``‖T(h)‖₂`` is computed (one input), see :func:`unfalsify.toeplitz_norm`.
    warn : bool
        Emit :class:`IllConditionedWarning` when ``cond T(u) > COND_WARN`` (1e8).

    Raises
    ------
    DataError
        On NaN/inf, length mismatch or time along axis 1 (the message names ``u.T``).

    Notes
    -----
    An input that is zero for its first p samples (a record that starts at rest) makes T(u) singular.  If
    y is zero there too, ``T(u) = [0 0; T(u') 0]`` and ``T(y) = [0 0; T(y') 0]`` with ``u' = u[p:]``,
    ``y' = y[p:]``, so (7.1) is that of the data after the zeros: γ and h are theirs, h extended at the same
    norm (``leading_zeros``).  If y moves first, no causal Δ explains the data: γ = ∞ (``method="acausal"``).

    Examples
    --------
    Two inputs, two outputs: y = D u for a constant D is explained by the static Δ = D, whose H∞ norm
    is the largest singular value of D:

    >>> import numpy as np
    >>> import unfalsify as uf
    >>> u = np.random.default_rng(0).standard_normal((40, 2))
    >>> D = np.array([[1.0, 2.0], [0.0, 1.0]])
    >>> r = uf.unfalsified_gain_result(u, u @ D.T)
    >>> bool(np.isclose(r.gamma, np.linalg.norm(D, 2))), r.impulse is None, r.method
    (True, True, 'qr')
    """
    u, y = _checked_pair(u, y)
    exact = None if exact is None else check_flag(exact, "exact")
    warn = check_flag(warn, "warn")
    n, p = u.shape[0], samples_at_rest(u)
    answer = _at_rest_result(u, y, p) if p else None
    if answer is not None:
        return answer
    u, y = u[p:], y[p:]
    if u.shape[1] == 1 and y.shape[1] == 1:
        short = _siso_result(u[:, 0].copy(), y[:, 0].copy(), exact, method, warn)
    else:
        short = _mimo_result(u, y, exact, method, warn)
    return _extended(short, n, p) if p else short


def _warn_cond(cond: float) -> None:
    if not cond <= COND_WARN:
        warnings.warn(
            f"cond T(u) = {cond:.3g} > {COND_WARN:.0e}: T(u)ᵀT(u) is numerically singular and the "
            "unfalsified gain is dominated by the unstable inverse of u(q); it may change completely under "
            "data perturbations far below sensor resolution (use shorter records or a minimum-phase input)",
            IllConditionedWarning,
            stacklevel=4,
        )


def _mimo_result(u: np.ndarray, y: np.ndarray, exact, method: str, warn: bool) -> GainResult:
    """Several channels: h per output by deconvolution (m = 1), or ``‖T(y)R⁻¹‖₂`` (m > 1)."""
    n, m = u.shape
    if m == 1:
        if exact is None:
            exact = n <= 400
        with np.errstate(over="ignore", invalid="ignore"):
            h = np.stack([deconvolve(u[:, 0], y[:, a], exact=exact, overflow="return") for a in range(y.shape[1])],
                         axis=1)[:, :, None]
        cond = toeplitz_cond(u[:, 0])
        if warn:
            _warn_cond(cond)
        if not np.all(np.isfinite(h)):
            return GainResult(gamma=float("inf"), impulse=h, cond_Tu=cond, exact=bool(exact), method="overflow")
        used = method if method != "auto" else ("dense" if n * y.shape[1] <= 400 else "lanczos")
        return GainResult(gamma=block_toeplitz_norm(h, method=used), impulse=h, cond_Tu=cond, exact=bool(exact),
                          method=used)
    Tu = signal_toeplitz(u)
    s = np.linalg.svd(Tu, compute_uv=False)
    cond = float(s[0] / s[-1]) if s[-1] > 0 else float("inf")
    if warn:
        _warn_cond(cond)
    R = np.linalg.qr(Tu, mode="r")
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        X = scipy.linalg.solve_triangular(R, signal_toeplitz(y).T, trans="T", lower=False).T  # T(y) R⁻¹
    gamma = float(np.linalg.norm(X, 2)) if np.all(np.isfinite(X)) else float("inf")
    return GainResult(gamma=gamma, impulse=None, cond_Tu=cond, exact=False, method="qr")


def _siso_result(u: np.ndarray, y: np.ndarray, exact, method: str, warn: bool) -> GainResult:
    """The SISO Theorem 7.1 (unchanged)."""
    n = u.size
    if exact is None:
        exact = n <= 400
    with np.errstate(over="ignore", invalid="ignore"):
        h = deconvolve(u, y, exact=exact, overflow="return")
    cond = toeplitz_cond(u)
    if warn:
        _warn_cond(cond)
    if not np.all(np.isfinite(h)):
        gamma = float("inf")
        used = "overflow"
    else:
        used = method if method != "auto" else ("dense" if n <= 400 else "lanczos")
        gamma = toeplitz_norm(h, method=used)
    return GainResult(gamma=gamma, impulse=h, cond_Tu=cond, exact=bool(exact), method=used)


def unfalsified_gain(u, y, **kwargs) -> float:
    """Smallest γ such that an LTI ``Δ`` with ``‖Δ‖∞ ≤ γ`` maps u to y on the window (Thm 7.1).

    Computed as ``‖T(h)‖₂`` with ``h = T(u)⁻¹ y``; see :func:`unfalsified_gain_result`
    for the keyword arguments and the diagnostics (cond ``T(u)``, h).

    Examples
    --------
    >>> import numpy as np
    >>> u = np.random.default_rng(0).standard_normal(10)
    >>> y = 0.5 * u + 0.3 * np.concatenate([[0.0], u[:-1]])          # Δ = 0.5 + 0.3q⁻¹, ‖Δ‖∞ = 0.8
    >>> g = unfalsified_gain(u, y)
    >>> round(g, 4)                                                  # below 0.8: 10 samples do not see all of Δ
    0.7918
    >>> bool(np.isclose(g, toeplitz_norm(deconvolve(u, y))))        # ‖T(h)‖₂, h = T(u)⁻¹y
    True
    """
    return unfalsified_gain_result(u, y, **kwargs).gamma


def is_unfalsified(u, y, gamma: float, *, rtol: float = 1e-9, **kwargs) -> bool:
    """True if the data do not falsify "y = Δu with ‖Δ‖∞ ≤ gamma" (Thm 7.1), up to ``rtol``.

    Raises
    ------
    DataError
        ``gamma`` or ``rtol`` not a finite number ≥ 0 (a string is refused, not parsed); bad data
        (:func:`unfalsified_gain`).

    Examples
    --------
    >>> import numpy as np
    >>> u = np.random.default_rng(0).standard_normal(10)
    >>> y = 0.5 * u + 0.3 * np.concatenate([[0.0], u[:-1]])          # Δ = 0.5 + 0.3q⁻¹, ‖Δ‖∞ = 0.8
    >>> is_unfalsified(u, y, 0.8), is_unfalsified(u, y, 0.7)
    (True, False)
    """
    # float("1e9") had parsed a string silently, and a string rtol reached the sum below
    g = check_nonnegative(gamma, "gamma (the gain bound)")
    rtol = check_nonnegative(rtol, "rtol (the relative tolerance of the comparison)")
    return bool(unfalsified_gain(u, y, **kwargs) <= g * (1.0 + rtol))
