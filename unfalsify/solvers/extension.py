"""The least-norm extension of Markov parameters (Carathéodory–Fejér).

Given the first k Markov parameters h of a causal LTI system, the least H∞ norm of any causal LTI system with
those parameters is ``γ = ‖T_k(h)‖₂`` (Carathéodory–Fejér).  A record whose input starts with p zeros
determines only ``h_0 … h_{n−p−1}`` (``T(u)h`` never reaches the last p entries), and Theorem 7.1's answer
is γ of that shorter section; the full-length h of the answer takes, for its last p entries, the next
Markov parameters of the system that attains γ, so that ``‖T_n(h)‖₂ = γ`` too.

That system, with ``T_k(h) v = γ w`` a top singular pair, is ``f(z) = γ w(z) / v(z)`` (``v(z) = Σ v_t z^t``,
one polynomial ``w_a(z)`` per output): ``f·v = γ w`` agrees with ``h·v`` to order k, and ``|f| = γ`` on the
unit circle.  Its Taylor coefficients are the impulse response of an IIR filter with denominator v.  When γ
is a multiple singular value, v is the projection of the first unit vector onto the top right singular
subspace (``h = [1, 0, …]``: ``T = I``, ``v = e_0``, ``f = 1``).  One output and several inputs is the
transposed problem (``‖T(hᵀ)‖₂ = ‖T(h)‖₂``).  The extension is checked, never assumed: where ``‖T_n(f)‖₂``
exceeds γ by more than rounding, the free entries are NaN and :class:`~unfalsify.IllConditionedWarning` says so.
"""
from __future__ import annotations

import warnings

import numpy as np
import scipy.signal
from scipy.sparse.linalg import svds

from synthesis import DataError
from synthesis.validation import as_real_array

from ..exceptions import IllConditionedWarning
from .toeplitz import DENSE_LIMIT, block_certified_norm, block_toeplitz_matrix, norm_below_by_cholesky

__all__ = ["minimal_extension"]

#: Relative excess of ``‖T_n(f)‖₂`` over γ that is still rounding.
EXTENSION_RTOL = 1e-8
#: Singular values within this fraction of the largest count as equal to it.
_CLUSTER_RTOL = 1e-10


def minimal_extension(h, n: int) -> np.ndarray:
    """The first n Markov parameters of a least-H∞-norm causal LTI system whose first ``len(h)`` are h.

    Parameters
    ----------
    h : array_like, shape (k,) or (k, l, m) with l = 1 or m = 1
        The given Markov parameters (SISO, or one input or one output).
    n : int
        How many to return, ``n ≥ k``.

    Returns
    -------
    ndarray, shape (n,) or (n, l, m)
        ``h`` followed by ``n − k`` parameters chosen so that ``‖T_n‖₂ = ‖T_k(h)‖₂`` (checked; NaN with
        :class:`~unfalsify.IllConditionedWarning` where the check fails).

    Raises
    ------
    DataError
        ``n < len(h)``, NaN or infinite h, or several inputs and several outputs.

    Examples
    --------
    Two Markov parameters ``[1, 1]`` have least norm ``‖T_2‖₂ = (1 + √5)/2``; the parameters that follow keep
    it, and their section of any length has the same norm:

    >>> import numpy as np
    >>> from unfalsify import toeplitz_norm
    >>> f = minimal_extension([1.0, 1.0], 6)
    >>> round(toeplitz_norm([1.0, 1.0]), 6), round(toeplitz_norm(f), 6)
    (1.618034, 1.618034)
    >>> f[:2].tolist()
    [1.0, 1.0]
    """
    siso = np.ndim(h) == 1
    h = as_real_array(h, "the Markov parameters h")  # a string or complex h had raised numpy's bare errors
    h3 = h[:, None, None] if siso else h
    if h3.ndim != 3:
        raise DataError(f"Markov parameters must have shape (k,) or (k, l, m), got {h.shape}: pass one channel's as a "
                        "1-D array (e.g. h.ravel() for a column), several channels' as (k, l, m) (l outputs, m inputs)")
    k, l, m = h3.shape
    if not (isinstance(n, (int, np.integer)) and n >= k):
        raise DataError(f"n must be an integer ≥ len(h) = {k}, got {n!r}")
    if not np.all(np.isfinite(h3)):
        raise DataError("h contains NaN or infinite values: clean the Markov parameters first")
    if l > 1 and m > 1:
        raise DataError(f"the extension is built for one input or one output, got {l} × {m} Markov parameters")
    out = np.zeros((n, l, m))
    out[:k] = h3
    if n > k and k > 0 and np.any(h3):
        tall = h3 if m == 1 else h3.transpose(0, 2, 1)  # one output: extend the transposed system
        tail, gamma = _extended_tail(tall, n)
        out[k:] = tail if m == 1 else tail.transpose(0, 2, 1)
        if not _norm_proven_below(out, gamma * (1.0 + EXTENSION_RTOL)):
            out[k:] = np.nan
            warnings.warn(
                f"the least-norm extension of {k} Markov parameters to {n} could not be verified (its Toeplitz "
                f"norm exceeds ‖T_{k}(h)‖₂ = {gamma:.6g} beyond rounding): the free entries are NaN",
                IllConditionedWarning,
                stacklevel=2,
            )
    return out[:, 0, 0] if siso else out


def _extended_tail(h: np.ndarray, n: int) -> tuple[np.ndarray, float]:
    """Entries k … n−1 of ``γ w(z)/v(z)`` for h (k, l, 1), (v, w) from the top singular subspace of T_k(h), and
    ``γ = ‖T_k(h)‖₂`` (its largest singular value, which the check of the extension compares with)."""
    k, l, _ = h.shape
    T = block_toeplitz_matrix(h)  # (kl, k)
    _, s, Vt = np.linalg.svd(T, full_matrices=False) if k * l <= 4 * DENSE_LIMIT else _top_pairs(T)
    top = s >= s[0] * (1.0 - _CLUSTER_RTOL)
    v = Vt[top].T @ Vt[top][:, 0]  # e_0 projected on the top right singular subspace
    if not abs(v[0]) > 0.0:
        return np.full((n - k, l, 1), np.nan), float(s[0])
    w = (T @ v).reshape(k, l)  # γ w of the pair (v, w); the factor γ is already in
    impulse = np.zeros(n)
    impulse[0] = 1.0
    with np.errstate(over="ignore", invalid="ignore"):
        f = np.stack([scipy.signal.lfilter(w[:, a], v, impulse) for a in range(l)], axis=1)
    return f[k:, :, None], float(s[0])


def _norm_proven_below(h: np.ndarray, c: float) -> bool:
    """``‖T(h)‖₂ ≤ c`` proven for h (n, l, m): the extension puts most singular values of T(h) at γ, where Lanczos
    does not converge (ARPACK gave up at n = 1900), so one input and one output take the Cholesky proof, several
    channels the certified bound (never an underestimate; above its dense limit a symbol bound that may refuse)."""
    if h.shape[1:] == (1, 1):
        return norm_below_by_cholesky(h[:, 0, 0], c)
    return block_certified_norm(h) <= c


def _top_pairs(T: np.ndarray):
    """A few leading singular triplets of a large T (ARPACK), largest first."""
    U, s, Vt = svds(T, k=min(4, min(T.shape) - 1), which="LM", solver="arpack")
    order = np.argsort(s)[::-1]
    return U[:, order], s[order], Vt[order]
