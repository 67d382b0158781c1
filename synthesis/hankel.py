"""Gram matrix ``AAᵀ`` of the stacked block Hankel data ``A = [U_p; Y_p; U_f; Y_f]`` (§2.3).

The Hankel matrices (2.1)–(2.4) are never formed.  Interleave the signals as
``z_t = [u_t; y_t]`` (``c = m + l`` channels) and let ``Z`` be the block Hankel
matrix with ``2i`` block rows ``z_r … z_{r+j-1}``; ``A`` is a row permutation of
``Z`` (and of the thesis's ``B = [U; Y]``), so ``AAᵀ`` is a symmetric permutation
of ``ZZᵀ``.  ``ZZᵀ`` is computed as in (2.8)–(2.9):

1. the first block row ``[ZZᵀ]_{0,s} = Σ_t z_t z_{s+t}ᵀ`` by ``2i`` BLAS products of
   shifted slices of the raw signal, each of length ``j`` (``O(ij)`` time, no copies);
2. every further block row from the one above it,
   ``[ZZᵀ]_{r,s} = [ZZᵀ]_{r-1,s-1} − z_{r-1} z_{s-1}ᵀ + z_{r+j-1} z_{s+j-1}ᵀ``,
   one vectorised row of blocks at a time (``2i`` numpy operations, ``O(i²)`` work);
3. the lower block triangle by symmetry.

Because ``z`` interleaves ``u`` and ``y`` the single recursion covers ``UUᵀ``,
``YYᵀ`` and ``UYᵀ`` at once (the first block *column* needed by (2.9) is the
transpose of the first block row of the symmetric ``ZZᵀ``).  Time
``O(ij + i²)``, memory ``O(i² + j)`` (plus the ``n × (m+l)`` interleaved copy).
"""
from __future__ import annotations

import numpy as np

from ._validation import as_signal, check_horizon

__all__ = ["hankel_gram", "hankel_order"]


def hankel_order(i: int, m: int, l: int) -> np.ndarray:
    """Row permutation from the interleaved Hankel ``Z`` to ``A = [U_p; Y_p; U_f; Y_f]`` (2.7).

    Returns ``perm`` with ``A = Z[perm]``, where row ``r*(m+l) + ch`` of ``Z`` holds channel
    ``ch`` of ``z_{r+t} = [u_{r+t}; y_{r+t}]``.
    """
    c = m + l
    perm = np.empty(2 * i * c, dtype=np.intp)
    pos = 0
    for first in (0, i):  # past block rows, then future block rows
        for chans in (range(m), range(m, c)):  # inputs, then outputs
            for r in range(first, first + i):
                for ch in chans:
                    perm[pos] = r * c + ch
                    pos += 1
    return perm


def _interleaved_gram(z: np.ndarray, rows: int, j: int) -> np.ndarray:
    """``ZZᵀ`` for the block Hankel ``Z`` of ``z`` with ``rows`` block rows and ``j`` columns."""
    c = z.shape[1]
    N = rows * c
    G = np.empty((N, N))
    head = z[:j]
    # 1. first block row: correlations of the raw signal at lags 0 … rows-1.
    for s in range(rows):
        G[:c, s * c : (s + 1) * c] = head.T @ z[s : s + j]
    if rows > 1:
        # 2. recursion (2.8)-(2.9), one block row at a time (vectorised along the row).
        h = z[: rows - 1].reshape(-1)  # z_0 … z_{rows-2}: samples leaving at the left
        t = z[j : j + rows - 1].reshape(-1)  # z_j … z_{j+rows-2}: samples entering at the right
        for r in range(1, rows):
            a, b = r * c, (r - 1) * c
            G[a : a + c, a:] = G[b:a, b : N - c] + np.outer(t[b:a], t[b:]) - np.outer(h[b:a], h[b:])
        # 3. lower block triangle by symmetry.
        blk = np.arange(N) // c
        lower = blk[:, None] > blk[None, :]
        G[lower] = G.T[lower]
    # diagonal blocks are symmetric in exact arithmetic; make them so in floating point.
    return 0.5 * (G + G.T)


def hankel_gram(u, y, i: int) -> np.ndarray:
    """Return ``AAᵀ`` with ``A = [U_p; Y_p; U_f; Y_f]`` (row order of (2.7)) in ``O(ij + i²)`` time.

    Parameters
    ----------
    u : array_like, shape (n,) or (n, m)
        Inputs, time along axis 0.
    y : array_like, shape (n,) or (n, l)
        Outputs, time along axis 0.
    i : int
        Prediction horizon; ``j = n - 2i + 1`` columns.

    Returns
    -------
    ndarray, shape (2i(m+l), 2i(m+l))
        The symmetric positive semidefinite Gram matrix, computed by the Hankel recursions
        (2.8)–(2.9) without forming the ``i × j`` block Hankel matrices.
    """
    u = as_signal(u, "u")
    y = as_signal(y, "y", n=u.shape[0])
    n, m = u.shape
    l = y.shape[1]
    i = check_horizon(i, n)
    j = n - 2 * i + 1
    z = np.ascontiguousarray(np.hstack([u, y]))
    G = _interleaved_gram(z, 2 * i, j)
    perm = hankel_order(i, m, l)
    return G[np.ix_(perm, perm)]
