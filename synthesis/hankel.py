"""Gram matrix ``AAᵀ`` of the stacked block Hankel data ``A = [U_p; Y_p; U_f; Y_f]`` (§2.3).

The Hankel matrices (2.1)–(2.4) are never formed.  Interleave the signals as
``z_t = [u_t; y_t]`` (``c = m + l`` channels) and let ``Z`` be the block Hankel
matrix with ``2i`` block rows ``z_r … z_{r+j-1}``; ``A`` is a row permutation of
``Z`` (and of the thesis's ``B = [U; Y]``), so ``AAᵀ`` is a symmetric permutation
of ``ZZᵀ``.  ``ZZᵀ`` is computed as in (2.8)–(2.9):

1. the first block row ``[ZZᵀ]_{0,s} = Σ_t z_t z_{s+t}ᵀ`` (the lag products) by two
   matrix products of free reshapes of the raw signal (:func:`_lag_products`, ``O(ij)``
   time at level-3 BLAS speed, no copies of the signal);
2. every further block row from the one above it,
   ``[ZZᵀ]_{r,s} = [ZZᵀ]_{r-1,s-1} − z_{r-1} z_{s-1}ᵀ + z_{r+j-1} z_{s+j-1}ᵀ``, unrolled into
   cumulative sums over ``r`` of products of the first and last ``2i`` samples, all block
   rows at once (:func:`_upper_block_skew`, ``O(i²)`` work, no Python loop over ``i``);
3. the lower block triangle by symmetry, and the row order of ``A`` by one gather.

(The block-row loop that step 2 replaces, ``2i`` BLAS products of ``c × j`` slices for step 1
and one vectorised row of blocks per iteration, is kept as ``_interleaved_gram_loop``: the
reference in the tests and the "before" route of ``bench-predictor``.)

Because ``z`` interleaves ``u`` and ``y`` the single recursion covers ``UUᵀ``,
``YYᵀ`` and ``UYᵀ`` at once (the first block *column* needed by (2.9) is the
transpose of the first block row of the symmetric ``ZZᵀ``).  Time
``O(ij + i²)``, memory ``O(i² + j)`` (plus the ``n × (m+l)`` interleaved copy).
"""
from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import as_strided, sliding_window_view

from ._validation import as_signal, check_count, check_horizon

__all__ = ["hankel_gram", "hankel_order"]


def hankel_order(i: int, m: int, l: int) -> np.ndarray:
    """Row permutation from the interleaved Hankel ``Z`` to ``A = [U_p; Y_p; U_f; Y_f]`` (2.7).

    Returns ``perm`` with ``A = Z[perm]``, where row ``r*(m+l) + ch`` of ``Z`` holds channel
    ``ch`` of ``z_{r+t} = [u_{r+t}; y_{r+t}]``.

    Parameters
    ----------
    i : int
        The horizon (block rows of each of ``U_p, Y_p, U_f, Y_f``), ≥ 1.
    m, l : int
        Numbers of inputs and outputs, each ≥ 1.

    Raises
    ------
    DataError
        ``i``, ``m`` or ``l`` is not an integer ≥ 1 (a float such as ``3.0`` included).

    Examples
    --------
    ``i = 2``, one input and one output: ``Z`` has rows ``u_0, y_0, u_1, y_1, u_2, y_2, u_3, y_3``.

    >>> import numpy as np
    >>> from synthesis import block_hankel
    >>> perm = hankel_order(2, 1, 1)
    >>> perm
    array([0, 2, 1, 3, 4, 6, 5, 7])
    >>> u, y = np.arange(8.0), 10 + np.arange(8.0)
    >>> Z = block_hankel(np.column_stack([u, y]), 4, 5)
    >>> A = np.vstack([block_hankel(u, 2, 5), block_hankel(y, 2, 5),
    ...                block_hankel(u, 2, 5, 2), block_hankel(y, 2, 5, 2)])
    >>> np.array_equal(Z[perm], A)
    True
    """
    # i = 0 had returned an empty permutation and a negative i numpy's bare ValueError
    i = check_horizon(i)
    m, l = check_count(m, "m", 1), check_count(l, "l", 1)
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


def _interleaved_gram_loop(z: np.ndarray, rows: int, j: int) -> np.ndarray:
    """``ZZᵀ`` by the block-row loop of (2.8)–(2.9) (the route before the vectorised one).

    Kept as the reference for :func:`_interleaved_gram` (tests) and as the baseline of
    ``python -m experiments bench-predictor``: ``rows`` BLAS products of ``c × j`` slices and
    ``rows − 1`` Python iterations of the recursion.
    """
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


def _lag_products(z: np.ndarray, j: int, rows: int) -> np.ndarray:
    """``S[a, b, s] = Σ_{t<j} z_{t,a} z_{t+s,b}`` for ``s < rows``: the first block row of ``ZZᵀ``.

    With block length ``P = rows`` and ``Q = ⌊(j−1)/P⌋`` whole blocks, the rows
    ``Z_b[q] = [z_{qP} … z_{qP+P−1}]`` and ``Z_n[q] = Z_b[q+1]`` are free reshapes of the signal,
    and the two matrix products ``C = Z_bᵀ[Z_b  Z_n]`` (``Pc × 2Pc``) hold every product
    ``z_{qP+p} z_{qP+p+s}ᵀ`` summed over ``q``: ``S[s] = Σ_p C[p, p+s]`` (a skewed sum).  The at
    most ``P`` columns ``t ≥ QP`` are added by one more product.  This does twice the
    multiplications of ``rows`` separate lag products, but as two level-3 BLAS calls instead of
    ``rows`` memory-bound ``c × j`` products (each streaming the whole signal).  (``z`` must be
    C-contiguous.)
    """
    z = np.ascontiguousarray(z)
    c = z.shape[1]
    P = rows
    Q = (j - 1) // P
    S = np.zeros((c, c, rows))
    if Q > 0:
        Zb = z[: Q * P].reshape(Q, P * c)
        Zn = z[P : (Q + 1) * P].reshape(Q, P * c)
        C = np.empty((P, c, 2 * P, c))  # C[p, a, p', b]
        C2 = C.reshape(P * c, 2 * P * c)
        # contiguous products, then copied into the halves (a product into a non-contiguous `out`
        # is slower than the copy: 0.36 → 0.27 ms at (i, j) = (64, 2048))
        C2[:, : P * c] = Zb.T @ Zb
        C2[:, P * c :] = Zb.T @ Zn
        st = C.strides  # skewed view V[p, a, b, s] = C[p, a, p + s, b]  (p + s < 2P)
        V = as_strided(C, shape=(P, c, c, rows), strides=(st[0] + st[2], st[1], st[3], st[2]), writeable=False)
        S += V.sum(axis=0)
    t0 = Q * P
    if t0 < j:
        win = sliding_window_view(z[t0 : j + rows - 1], rows, axis=0)  # win[t, b, s] = z_{t0+t+s, b}
        S += np.tensordot(z[t0:j], win, axes=(0, 0))
    return S


def _upper_block_skew(z: np.ndarray, rows: int, j: int) -> np.ndarray:
    """Array ``F[a, r, b, s]`` (shape ``(c, rows, c, 2·rows)``) holding ``[ZZᵀ]`` for ``s ≥ r`` (``s < rows``).

    The recursion (2.8)–(2.9) unrolled: for ``s ≥ r`` the ``(a, b)`` entry of block ``(r, s)`` is
    ``S[a, b, s−r] + Σ_{k<r} (z_{j+k,a} z_{j+k+s−r,b} − z_{k,a} z_{k+s−r,b})``, i.e. the lag
    products :func:`_lag_products` followed by a cumulative sum over ``k`` of products of the first
    and the last ``2·rows`` samples — the additions of the block-row loop, in the same order, with
    no Python loop over the horizon.  The sum is written through a skewed view straight into
    ``F[a, r, b, r + d]``; entries ``s ≥ rows`` are scratch.  Diagonal blocks are halved (the
    caller adds the transpose).  Entries ``s < r`` are zero.
    """
    c = z.shape[1]
    S = _lag_products(z, j, rows)
    # head z_0 … and tail z_j … (zero padded: products past the data only reach scratch entries)
    h = np.zeros((2 * rows - 1, c))
    t = np.zeros((2 * rows - 1, c))
    h[: min(2 * rows - 1, z.shape[0])] = z[: 2 * rows - 1]
    tail = z[j : j + 2 * rows - 1]
    t[: tail.shape[0]] = tail
    X = np.empty((c, c, rows, rows))  # X[a, b, 0, d] = S[a, b, d]; X[a, b, k+1, d] = t_{k,a} t_{k+d,b} − h_{k,a} h_{k+d,b}
    X[:, :, 0, :] = S
    if rows > 1:
        ht = sliding_window_view(h, rows, axis=0)[: rows - 1].transpose(1, 0, 2)  # [b, k, d] = h_{k+d, b}
        tt = sliding_window_view(t, rows, axis=0)[: rows - 1].transpose(1, 0, 2)
        np.multiply(t[: rows - 1].T[:, None, :, None], tt[None], out=X[:, :, 1:, :])
        X[:, :, 1:, :] -= h[: rows - 1].T[:, None, :, None] * ht[None]
    F = np.zeros((c, rows, c, 2 * rows))
    st = F.strides  # skewed view W[a, b, r, d] = F[a, r, b, r + d]
    W = as_strided(F, shape=(c, c, rows, rows), strides=(st[0], st[2], st[1] + st[3], st[3]))
    np.cumsum(X, axis=2, out=W)
    W[:, :, :, 0] *= 0.5  # diagonal blocks are added to their transpose by the caller
    return F


def _gram_from_skew(F: np.ndarray, rows: int, order: np.ndarray) -> np.ndarray:
    """Symmetric ``ZZᵀ`` from :func:`_upper_block_skew`, rows and columns in ``order`` (channel-major indices)."""
    c = F.shape[0]
    M = np.ascontiguousarray(F[:, :, :, :rows]).reshape(c * rows, c * rows)  # channel-major, upper blocks
    U = M.take(order, axis=0).take(order, axis=1)  # row gather, then column gather (no 2-D index arrays)
    return U + U.T


def _interleaved_gram(z: np.ndarray, rows: int, j: int, order=None) -> np.ndarray:
    """``ZZᵀ`` for the block Hankel ``Z`` of ``z`` with ``rows`` block rows and ``j`` columns.

    Interleaved order (index ``r·c + ch``: channel ``ch`` of block row ``r``), or the rows and
    columns ``order`` of it (e.g. :func:`hankel_order`), gathered once from the channel-major
    array of :func:`_upper_block_skew`.
    """
    c = z.shape[1]
    idx = np.arange(rows * c) if order is None else np.asarray(order)
    return _gram_from_skew(_upper_block_skew(z, rows, j), rows, (idx % c) * rows + idx // c)


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

    Examples
    --------
    Two inputs, one output, ``i = 3`` (``j = 45``): the same matrix as ``AAᵀ`` of the formed data.

    >>> import numpy as np
    >>> from synthesis import block_hankel
    >>> rng = np.random.default_rng(0)
    >>> u, y = rng.standard_normal((50, 2)), rng.standard_normal(50)
    >>> G = hankel_gram(u, y, 3)
    >>> G.shape
    (18, 18)
    >>> A = np.vstack([block_hankel(u, 3, 45), block_hankel(y, 3, 45),
    ...                block_hankel(u, 3, 45, 3), block_hankel(y, 3, 45, 3)])
    >>> np.allclose(G, A @ A.T)
    True
    """
    u = as_signal(u, "u")
    y = as_signal(y, "y", n=u.shape[0])
    n, m = u.shape
    l = y.shape[1]
    i = check_horizon(i, n)
    j = n - 2 * i + 1
    z = np.ascontiguousarray(np.hstack([u, y]))
    return _interleaved_gram(z, 2 * i, j, hankel_order(i, m, l))
