"""Stacks of small matrices, one per column of the column form of (7.5): the batched linear algebra of
:mod:`unfalsify.solvers.column_barrier` and :mod:`unfalsify.solvers.column_pd`.

* :class:`_Chunks` runs a stack's products, factorisations and inverses on a thread pool, split into contiguous
  column chunks (numpy's batched products and LAPACK release the GIL; BLAS is held to one thread per worker by
  the solver);
* :class:`_StackPool` reuses the large stacks of one solve, and the blocked passes (:func:`_blocks_of`,
  :data:`_BLOCK_BYTES`) keep whole-stack temporaries out of fresh memory mappings;
* Cholesky log-determinants (the barrier's feasibility test), symmetric inverses and block solves of the stacks.
"""
from __future__ import annotations

import sys

import numpy as np

from .toeplitz import _tr, toeplitz_stack


class _Chunks:
    """Work on the column stack split into contiguous chunks, run on a thread pool.

    numpy's batched matrix products, LAPACK and the FFTs release the GIL, so with ``workers``
    threads (and a single-threaded BLAS, set by :func:`solve_columns_barrier`) the stacks of the
    barrier are processed ``workers`` chunks at a time.  Every chunk runs the same deterministic
    code as the whole stack would, so the result does not depend on ``workers`` beyond the order of
    a few floating-point sums.  Stacks below ``min_size`` elements are processed serially.
    """

    def __init__(self, pool=None, workers: int = 1, min_size: int = 400_000):
        self.pool, self.workers, self.min_size = pool, max(1, int(workers)), min_size

    def slices(self, j: int, size: int) -> list[slice]:
        parts = self.workers if (self.pool is not None and size >= self.min_size and j >= 2 * self.workers) else 1
        b = np.linspace(0, j, parts + 1).astype(int)
        return [slice(int(b[k]), int(b[k + 1])) for k in range(parts)]

    def map(self, fn, j: int, size: int) -> list:
        """``[fn(s) for s in slices]`` (on the pool when there is more than one slice)."""
        sl = self.slices(j, size)
        if len(sl) == 1:
            return [fn(sl[0])]
        return list(self.pool.map(fn, sl))

    def matmul(self, A: np.ndarray, B: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """``A @ B`` for stacks ``(j, p, q) @ (j, q, r)`` (into ``out`` if given)."""
        if out is None:
            out = np.empty(A.shape[:-1] + B.shape[-1:], np.result_type(A, B))
        self.map(lambda s: np.matmul(A[s], B[s], out=out[s]), A.shape[0], out.size + A.size)
        return out

    def dot(self, A: np.ndarray, B: np.ndarray) -> np.ndarray:
        """``A @ B`` for matrices, the rows of A in chunks (BLAS is single-threaded inside the solve); threaded by
        the count of multiply-adds, not of elements (the CG's (3i, 3i) × (3i, j) products at (100, 1000) had run on
        the main thread alone: 8 of its 50 serial seconds with L optimised)."""
        out = np.empty((A.shape[0], B.shape[1]), np.result_type(A, B))
        self.map(lambda s: np.matmul(A[s], B, out=out[s]), A.shape[0], A.shape[0] * A.shape[1] * B.shape[1])
        return out


#: the serial default (tests and small problems)
_SERIAL = _Chunks()

#: Bytes from which a stack comes from a :class:`_StackPool` (below, numpy's allocations come from the heap and are
#: reused anyway).
_POOL_FROM = 4 << 20


class _StackPool:
    """Float stacks reused within one solve, handed out again once nothing but the pool refers to them.

    A stack of 80 MB (a (1000, 100, 100) stack at (i, j) = (100, 1000)) is above glibc's largest mmap threshold, so
    every fresh one is a new mapping whose pages fault on first touch: measured at (100, 1000) with L fixed, 26 s of
    system time in a 55 s solve, and 43 s when the process allocator kept freed memory instead
    (``MALLOC_MMAP_MAX_=0``).  The pool keeps the stacks it made and gives one out again when its reference count
    shows that no point, view or temporary still uses it (a numpy view refers to its base), so a buffer is never
    shared between two live arrays.  The pool lives as long as the solver; it is bypassed (``bypass=True``: the
    solver's former route, :func:`unfalsify.solvers.baselines.former_routes`) and for stacks below
    :data:`_POOL_FROM` bytes.
    """

    def __init__(self, bypass: bool = False):
        self.bypass = bool(bypass)
        self._stacks: dict[tuple, list[np.ndarray]] = {}
        self.made = 0  # stacks allocated (for tests and measurements)
        # the count of a stack nothing else holds, read the way take() reads it: interpreters differ in the
        # references a call adds (Python 3.14 skips some), so it is measured, not assumed
        probe = [np.empty(0)]
        self._free_refs = sys.getrefcount(probe[0])

    def take(self, shape) -> np.ndarray:
        """An uninitialised C-ordered float stack of ``shape``: a free one of the pool, or a new one."""
        shape = tuple(int(n) for n in shape)
        if self.bypass or 8 * int(np.prod(shape)) < _POOL_FROM:
            return np.empty(shape)
        stacks = self._stacks.setdefault(shape, [])
        for k in range(len(stacks)):
            if sys.getrefcount(stacks[k]) <= self._free_refs:  # any other holder (a point, a view) makes it busy
                return stacks[k]
        stack = np.empty(shape)
        stacks.append(stack)
        self.made += 1
        return stack


def _spd_inverse(X: np.ndarray, chunks: _Chunks = _SERIAL, shift: float | None = None,
                 out: np.ndarray | None = None) -> np.ndarray:
    """Inverse of a stack of symmetric (positive definite) matrices, symmetrised, on ``chunks``' threads;
    with ``shift`` the inverse of ``shift·I − X`` (formed block by block, never as a whole stack).  X may be a
    :class:`_BlockSum`.  The result is C-ordered whatever X's layout (a strided stack makes every later batched
    product strided), into ``out`` if given."""
    if out is None:
        out = np.empty(X.shape)

    def work(s):
        for b in _blocks_of(s, X.shape[1] * X.shape[2]):
            _sym_inverse_into(X[b] if shift is None else _shifted(X[b], shift), out[b])

    chunks.map(work, X.shape[0], X.size)
    return out


class _BlockSum:
    """The stack ``A + c B`` read block by block (``X[b]``), never formed whole."""

    def __init__(self, A: np.ndarray, B: np.ndarray, c: float):
        self.A, self.B, self.c = A, B, c
        self.shape, self.size = A.shape, A.size

    def __getitem__(self, b):
        out = np.multiply(self.B[b], self.c)
        out += self.A[b]
        return out


#: Bytes of one block of a stack's temporaries (:func:`_blocks_of`, the Hessian's pieces, the two passes of
#: :class:`_Point`): small enough to come from the heap and be reused while in cache.  A fresh mapping costs its page
#: faults on first touch: at (100, 1000) the stacks are 80 MB, and whole-stack temporaries were a quarter of the CPU
#: time in system calls.  Measured there with L fixed (whole solve, separate processes): 8 MB blocks 46 s and 16 s of
#: system time, 2 MB 42 s / 13 s, 1 MB 41 s / 7 s, 256 KB 63 s (the per-call overhead of small batches).
_BLOCK_BYTES = 1 << 20


def _blocks_of(s: slice, item: int):
    """Consecutive sub-slices of the column slice ``s`` whose stacks of ``item`` floats each fit in
    :data:`_BLOCK_BYTES`."""
    step = max(1, _BLOCK_BYTES // (8 * max(1, item)))
    for k in range(s.start, s.stop, step):
        yield slice(k, min(k + step, s.stop))


def _shifted(X: np.ndarray, shift: float) -> np.ndarray:
    """``shift·I − X`` for a stack (a new array)."""
    K = np.negative(X)
    K[..., np.arange(X.shape[-1]), np.arange(X.shape[-1])] += shift
    return K


def _sym_inverse_into(X: np.ndarray, out: np.ndarray) -> None:
    """``out = (X⁻¹ + X⁻ᵀ)/2`` for a stack (numpy's batched LU, which releases the GIL)."""
    Y = np.linalg.inv(X)
    np.add(Y, _tr(Y), out=out)
    out *= 0.5


def _block_solve(A, X: np.ndarray, chunks: _Chunks = _SERIAL) -> np.ndarray:
    """Columns ``A_k⁻¹ X[:, k, :]`` for a stack A (j, m, m) (or a :class:`_BlockSum`) and X (m, j, p), on ``chunks``'
    threads, A read in blocks of :data:`_BLOCK_BYTES`."""
    Xs = np.ascontiguousarray(np.moveaxis(X, 1, 0))  # (j, m, p)
    out = np.empty_like(Xs)

    def work(s):
        for b in _blocks_of(s, A.shape[1] * A.shape[2]):
            out[b] = np.linalg.solve(A[b], Xs[b])

    chunks.map(work, A.shape[0], A.size)
    return np.moveaxis(out, 0, 1)


def _stack_of(H: np.ndarray, chunks: _Chunks, out: np.ndarray) -> np.ndarray:
    """:func:`~unfalsify.solvers.toeplitz.toeplitz_stack` of H into ``out``, the columns in chunks on the threads."""
    chunks.map(lambda s: toeplitz_stack(H[:, s], out=out[s]), H.shape[1], out.size)
    return out


def _bmv(A: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Columns ``A_k X[:, k]`` for a stack A (j, m, m) and X (m, j) (or (m, j, p))."""
    if X.ndim == 2:
        return (A @ X.T[:, :, None])[:, :, 0].T
    return np.moveaxis(A @ np.moveaxis(X, 1, 0), 0, 1)


def _inner(A: np.ndarray, B: np.ndarray) -> float:
    """``⟨A, B⟩`` of two stacks without a product stack (``np.vdot`` reads both once)."""
    return float(np.vdot(A, B))


def _max_norm(TtT: np.ndarray, chunks: _Chunks = _SERIAL) -> float:
    """``max_k √λ_max(TtT_k)`` over a stack of Gram matrices."""
    tops = chunks.map(lambda s: float(np.linalg.eigvalsh(TtT[s])[:, -1].max()), TtT.shape[0], TtT.size)
    return float(np.sqrt(max(max(tops), 0.0)))


def _chol_logdet(K: np.ndarray, chunks: _Chunks = _SERIAL, shift: float | None = None) -> float | None:
    """``log det K`` of a stack, or None if some K_k is not positive definite (numpy's batched Cholesky, which
    releases the GIL, so chunks run in parallel; scipy's LAPACK wrappers hold it); with ``shift`` that of
    ``shift·I − K``, formed block by block."""
    def work(s):
        total = 0.0
        for b in _blocks_of(s, K[0].size):
            part = _chol_logdet_of(K[b] if shift is None else _shifted(K[b], shift))
            if part is None:
                return None
            total += part
        return total

    parts = chunks.map(work, K.shape[0], K.size)
    if any(v is None for v in parts):
        return None
    return float(sum(parts))


def _chol_logdet_of(K: np.ndarray) -> float | None:
    """:func:`_chol_logdet` of one block."""
    try:
        L = np.linalg.cholesky(K)
    except np.linalg.LinAlgError:
        return None
    logdet = 2.0 * float(np.sum(np.log(np.diagonal(L, axis1=-2, axis2=-1))))
    return logdet if np.isfinite(logdet) else None
