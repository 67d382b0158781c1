"""Fingerprint of a record: which samples of another record it contains.

A held-out test means something only on data the model was not fitted on.  A :class:`Predictor` keeps the
:class:`RecordFingerprint` of the record it was fitted on, so that a later test can check that its "held-out"
record really is held out (:func:`unfalsify.check_premise`).

The fingerprint holds a 64-bit hash of every aligned block of ``block`` samples of ``[u y]`` (``block`` rows, every
channel, compared bit for bit after conversion to float64), not the data.  A record is then scanned at every
offset: any stretch of at least ``2·block − 1`` samples it shares with the fingerprinted record contains one of its
aligned blocks, so such an overlap is always found; shorter ones may not be.  Blocks whose samples are all equal
(an idle record) are left out: equal idle stretches of two experiments would otherwise look shared.  Two different
blocks share a hash with probability about ``2⁻⁶⁴``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._repr import result
from ._validation import as_signal, check_count

__all__ = ["RecordFingerprint", "record_fingerprint"]

#: samples of each hashed block: an overlap of 2·64 − 1 = 127 samples or more is always found, and 64 samples of a
#: quantised two-code idle output (2⁶⁴ patterns) do not repeat by chance
BLOCK = 64

_GOLDEN = 0x9E3779B97F4A7C15
_BASE = np.uint64(0x100000001B3)  # odd: the block hash is a polynomial in it over the integers mod 2⁶⁴


@result
@dataclass(frozen=True)
class RecordFingerprint:
    """Hashes of the aligned blocks of a record ``[u y]`` (:func:`record_fingerprint`).

    Attributes
    ----------
    block : int
        Samples per hashed block.
    inputs, outputs : int
        Channels of ``u`` and ``y``.
    samples : int
        Length of the record.
    digests : ndarray of uint64
        The sorted hashes of its blocks ``[k·block, (k + 1)·block)`` whose samples are not all equal.
    """

    block: int
    inputs: int
    outputs: int
    samples: int
    digests: np.ndarray

    def shared(self, u, y) -> np.ndarray:
        """Mask of the samples of ``(u, y)`` that lie in a block of ``block`` samples found in the fingerprinted
        record, shape (n,).

        Raises
        ------
        DataError
            ``u`` or ``y`` not a record, or with other channel counts than the fingerprinted record.
        """
        rows = _rows(u, y, self.inputs, self.outputs)
        n, k = rows.shape[0], self.block
        mask = np.zeros(n, bool)
        if n < k or self.digests.size == 0:
            return mask
        found = np.flatnonzero(np.isin(_block_hashes(rows, k), self.digests))
        if found.size:
            cover = np.zeros(n + 1, int)
            np.add.at(cover, found, 1)
            np.add.at(cover, found + k, -1)
            mask = np.cumsum(cover[:n]) > 0
        return mask

    def shared_fraction(self, u, y) -> float:
        """Fraction of the samples of ``(u, y)`` found in the fingerprinted record (:meth:`shared`).

        A lower bound on the fraction they share: of each shared stretch, up to ``block − 1`` samples at either end
        may lie outside the fingerprint's aligned blocks.

        Examples
        --------
        >>> import numpy as np
        >>> rng = np.random.default_rng(0)
        >>> u, y = rng.standard_normal(1000), rng.standard_normal(1000)
        >>> fp = record_fingerprint(u[:600], y[:600])
        >>> fp.shared_fraction(u[600:], y[600:]), fp.shared_fraction(u[:256], y[:256])
        (0.0, 1.0)
        >>> round(fp.shared_fraction(u[400:], y[400:]), 3)        # 200 shared; the 128 in whole aligned blocks
        0.213
        """
        mask = self.shared(u, y)
        return float(mask.mean()) if mask.size else 0.0


def record_fingerprint(u, y, *, block: int = BLOCK) -> RecordFingerprint:
    """The :class:`RecordFingerprint` of the record ``(u, y)``.

    Parameters
    ----------
    u : array_like, shape (n,) or (n, m)
    y : array_like, shape (n,) or (n, l)
        The record, time along axis 0 (the arrays a model was fitted on).
    block : int
        Samples per hashed block (default :data:`BLOCK` = 64): overlaps of ``2·block − 1`` samples or more are
        always found.

    Returns
    -------
    RecordFingerprint

    Raises
    ------
    DataError
        ``u`` or ``y`` not a record of equal length, or ``block`` not an integer ≥ 1.

    Examples
    --------
    A stretch of the record taken again is found, up to its ends outside whole aligned blocks; the same input with
    other noise on the output is not:

    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> u = rng.standard_normal(2000)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:2000]
    >>> fp = record_fingerprint(u, y + 0.01 * rng.standard_normal(2000))
    >>> fp.shared_fraction(u[1003:], y[1003:])                   # the same input, the output without noise
    0.0
    >>> fp2 = record_fingerprint(u, y)
    >>> round(fp2.shared_fraction(u[1003:1503], y[1003:1503]), 3), fp2.shared_fraction(u[1024:1536], y[1024:1536])
    (0.896, 1.0)
    """
    block = check_count(block, "block", 1)
    u = as_signal(u, "u")
    y = as_signal(y, "y", n=u.shape[0])
    n = u.shape[0]
    aligned = n - n % block
    words = _row_hashes((u[:aligned], y[:aligned])).reshape(-1, block)
    # equal samples have equal words: a block of one repeated word is idle (a collision only hides a block)
    varied = words.min(axis=1) != words.max(axis=1)
    with np.errstate(over="ignore"):
        words *= _powers(block)
        hashes = _mix(np.sum(words, axis=1, dtype=np.uint64))
    return RecordFingerprint(block=block, inputs=u.shape[1], outputs=y.shape[1], samples=n,
                             digests=np.unique(hashes[varied]))


def _rows(u, y, m: int, l: int) -> np.ndarray:
    u = as_signal(u, "u", width=m)
    y = as_signal(y, "y", n=u.shape[0], width=l)
    return np.hstack([u, y])


def _mix(z: np.ndarray, t: np.ndarray | None = None) -> np.ndarray:
    """The splitmix64 finaliser, in place on ``z`` (returned): a bijection of 64-bit words that spreads every input
    bit over the output.  ``t``: a scratch array like ``z`` (fresh large arrays cost their page faults)."""
    t = np.empty_like(z) if t is None else t
    with np.errstate(over="ignore"):
        for shift, factor in ((30, 0xBF58476D1CE4E5B9), (27, 0x94D049BB133111EB)):
            np.right_shift(z, np.uint64(shift), out=t)
            z ^= t
            z *= np.uint64(factor)
        np.right_shift(z, np.uint64(31), out=t)
        z ^= t
    return z


def _row_hashes(signals) -> np.ndarray:
    """One mixed 64-bit word per sample from the bits of every channel of ``signals`` (arrays (n, k) of one length,
    read in order; −0.0 read as 0.0).  Two scratch arrays are reused: fresh large arrays cost their page faults."""
    n = signals[0].shape[0]
    h = np.zeros(n, np.uint64)
    word, scratch = np.empty(n, np.uint64), np.empty(n, np.uint64)
    channels = [x[:, k] for x in signals for k in range(x.shape[1])]
    with np.errstate(over="ignore"):
        for c, x in enumerate(channels):
            np.add(x, 0.0, out=word.view(np.float64))  # −0.0 + 0.0 = 0.0: the two zeros are one number
            word += np.uint64(_GOLDEN * (c + 1) % 2**64)
            h ^= word
            _mix(h, scratch)
    return h


def _powers(block: int) -> np.ndarray:
    """``_BASE^(block − 1 − s)`` mod 2⁶⁴ for s = 0 … block − 1: the weights of a block's polynomial hash."""
    p = np.ones(block, np.uint64)
    with np.errstate(over="ignore"):
        for s in range(block - 2, -1, -1):
            p[s] = p[s + 1] * _BASE
    return p


def _block_hashes(rows: np.ndarray, block: int) -> np.ndarray:
    """The hash of the ``block`` samples starting at every offset, shape (n − block + 1,): the same polynomial of
    the samples' mixed words as :func:`record_fingerprint`'s, by Horner's rule along the record."""
    h = _row_hashes((rows,))
    n = h.size - block + 1
    out = np.zeros(n, np.uint64)
    with np.errstate(over="ignore"):
        for s in range(block):
            out *= _BASE
            out += h[s:s + n]
    return _mix(out)
