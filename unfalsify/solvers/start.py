"""The strictly feasible starting point of the barrier solvers: ridge impulses inside the noise ball.

Every barrier solver of the column form (C) (:mod:`~unfalsify.solvers.columns`) starts from the impulses
that fit the data column by column with a ridge penalty,

    h_k = argmin ‖b_k − M_k h‖² + λ‖h‖²,     Σ_k ‖b_k − M_k h_k‖² = target  (one λ for all columns),

where ``b_k`` is column k of ``B0 = P B`` (B with its component in 𝓛 removed) and ``M_k`` the linear map
``h ↦ T(h)u_k`` of column k (for the ARX program (7.4) first projected onto 𝓛^⊥, ``basis``).  With the
thin SVD ``M_k = U_k diag(s_k) V_kᵀ`` and the data coordinates ``β_k = U_kᵀ b_k`` the fit is
``h_k = V_k (s_k/(s_k² + λ) β_k)`` and its residual ``Σ (λ/(s² + λ))² β²`` grows with λ, so λ is found
by bisection (:func:`~unfalsify.solvers.toeplitz.ridge_lambda`).  A target below ρ² leaves the noise
slack ψ > 0 and every ``T(h_k)`` finite, so the point (h, δ) with δ above every ``‖T(h_k)‖₂`` is
strictly feasible; the solvers choose the target (``0.9 ρ`` for (7.4), ``0.7 ρ`` for (7.5)) and the
margin on δ, which stay theirs.

Where it lives.  This is solver arithmetic, not part of the problem: :mod:`~unfalsify.solvers.columns`
defines (C) and its dual bound for every solver (the cvxpy models, the bracket and the split use it,
none of them needs a starting point), so the start sits in its own small module beside the three
barrier solvers that use it (``arx_barrier``, ``column_barrier``, ``block_barrier``) and imports only
:mod:`~unfalsify.solvers.toeplitz`.  The operators are passed in as a stack because the solvers build
them differently (Toeplitz matrices of the input columns, per-channel block operators, the ARX channel
operator); the warm start of ``column_barrier`` reuses the same SVD and contractions for its ridge
corrections (:func:`coordinates`, :func:`impulses`).

The norm of 𝓛^⊥.  With L optimised the plain fit ignores the part of ``B0`` that 𝓛 would absorb, so a column
whose T(u_k) is singular in floating point gets impulses of about 1e15.  :func:`cold_impulses` then refits in the
norm of 𝓛^⊥, ``min λ‖H‖² + ‖P(B0 − H̃)‖²``, by the solver's own solve of those coupled normal equations, with λ
found by :func:`ridge_search`.

One operator or a stack.  The ARX program has one column and one operator (n × n, or nl × nlm with
several channels) and passes it as a matrix: its contractions are the matrix–vector products ``Uᵀb``,
``V c`` (BLAS).  The subspace programs pass stacks (j operators): their contractions are ``einsum``
over the stack.  The two forms round differently in the last bits (measured: starting points 1e-16
apart, δ after the solve up to 1e-13); each solver keeps the arithmetic it had before the three copies
were merged, so no result changed by a bit (``tests/test_solver_start.py``).

Examples
--------
>>> import numpy as np
>>> from unfalsify.solvers.start import operator_svd, ridge_fit
>>> M = np.stack([np.tril(np.ones((4, 4))), np.eye(4)])      # two columns' operators (2, 4, 4)
>>> B0 = np.array([[1.0, 0.5], [2.0, -1.0], [0.0, 0.3], [1.0, 0.2]])
>>> H = ridge_fit(operator_svd(M), B0, target=0.25)
>>> H.shape
(4, 2)
>>> r = B0 - np.stack([M[k] @ H[:, k] for k in range(2)], axis=1)
>>> bool(abs(float(np.sum(r * r)) - 0.25) < 1e-9)
True
"""
from __future__ import annotations

import numpy as np
import scipy.linalg

from .toeplitz import ridge_lambda

__all__ = ["operator_svd", "coordinates", "impulses", "ridge_fit", "ridge_fit_gram", "ridge_search", "cold_impulses",
           "start_target", "OUTLIER"]


def start_target(rho: float, floor: float, share: float) -> float:
    """The squared residual a cold start fits to: ``(share·ρ)²``, or, when the data pin a part ``floor`` of the
    noise (:meth:`~unfalsify.solvers.columns.ColumnForm.noise_floor`, entries no impulse reaches), the same share
    of the slack above it, ``floor² + share²(ρ² − floor²)``: a fixed fraction of ρ may lie below what any
    impulses can reach.

    Examples
    --------
    >>> start_target(1.0, 0.0, 0.7) == 0.7 ** 2
    True
    >>> round(start_target(1.0, 0.8, 0.7), 4)      # 0.64 + 0.49 × 0.36
    0.8164
    """
    if not floor > 0.0:
        return (share * rho) ** 2
    return floor**2 + share**2 * (rho**2 - floor**2)


def operator_svd(M: np.ndarray, *, basis: np.ndarray | None = None, split=None):
    """Thin SVD ``(U, s, Vt)`` of every operator of the stack ``M`` (j, r, p), or of one operator (r, p), each
    first projected onto the orthogonal complement of ``span basis`` (r × q, orthonormal columns) when given.

    ``split``: optional ``split(work)`` that applies ``work(sl)`` to slices of the stack (in parallel) and returns
    the list of its results in order, e.g. ``lambda work: chunks.map(work, j, M.size)``; the SVDs are
    LAPACK calls per operator, so the split does not change a bit.

    Examples
    --------
    >>> import numpy as np
    >>> M = np.stack([np.tril(np.ones((3, 3))), 2.0 * np.eye(3)])
    >>> U, s, Vt = operator_svd(M, basis=np.array([[1.0], [0.0], [0.0]]))   # rows 1 and 2 of each M_k kept
    >>> s.round(6).tolist()
    [[2.135779, 0.662153, 0.0], [2.0, 2.0, 0.0]]
    """
    if basis is not None:
        M = M - basis @ (basis.T @ M)
    if split is None:
        return tuple(np.linalg.svd(M, full_matrices=False))
    parts = split(lambda sl: np.linalg.svd(M[sl], full_matrices=False))
    return tuple(np.concatenate(x) for x in zip(*parts))


def coordinates(U: np.ndarray, B0: np.ndarray) -> np.ndarray:
    """The data coordinates ``β_k = U_kᵀ b_k`` (j, q) of the columns of ``B0`` (r, j); of one operator
    (U (r, q)) and one column (``B0`` (r,)): ``β = Uᵀ b`` (q,)."""
    if U.ndim == 2:
        return U.T @ B0
    return np.einsum("kaq,ak->kq", U, B0)


def impulses(s: np.ndarray, Vt: np.ndarray, beta: np.ndarray, lam) -> np.ndarray:
    """The ridge impulses ``h_k = V_k (s_k/(s_k² + λ_k) β_k)`` as columns (p, j), ``lam`` one λ or one per column;
    of one operator (s (q,), Vt (q, p), β (q,)): h (p,).

    Examples
    --------
    >>> import numpy as np
    >>> M, b = np.eye(2), np.array([1.0, 2.0])
    >>> U, s, Vt = operator_svd(M)
    >>> impulses(s, Vt, coordinates(U, b), 1.0).tolist()          # (MᵀM + λI)⁻¹Mᵀb with λ = 1
    [0.5, 1.0]
    """
    lam = np.asarray(lam, float)
    c = s / (s * s + (lam[:, None] if lam.ndim else lam)) * beta
    if Vt.ndim == 2:
        return Vt.T @ c
    return np.einsum("kqp,kq->pk", Vt, c)


def ridge_fit(svd, B0: np.ndarray, target: float) -> np.ndarray:
    """Ridge impulses (p, j) of the columns of ``B0`` (r, j) with one λ and the residual
    ``Σ_k ‖b_k − M_k h_k‖² = target`` (to the bisection's resolution, on the side below it);
    ``svd`` from :func:`operator_svd`.  Of one operator and one column ``B0`` (r,): h (p,)."""
    U, s, Vt = svd
    beta = coordinates(U, B0)
    return impulses(s, Vt, beta, ridge_lambda(s, beta, target))


def ridge_fit_gram(gram: np.ndarray, c: np.ndarray, residual, target: float, *, rel: float = 0.05,
                   max_iter: int = 60) -> np.ndarray:
    """Ridge impulses ``h = (G + λI)⁻¹c`` of one operator M from its Gram ``G = MᵀM`` (p × p) and ``c = Mᵀb``,
    with the residual ``residual(h) = ‖b − M h‖²`` within ``rel`` of ``target`` (no SVD).

    One Cholesky factorisation of ``G + λI`` per λ (p³/3 flops, against about 20p³ for the thin SVD of
    :func:`operator_svd`): Newton steps on ``log r`` against ``log λ`` (``dr/dλ = 2λ hᵀ(G + λI)⁻¹h``), kept inside
    the bracket of ``log λ`` known so far by bisection.  ``h = 0`` if ``‖b‖² ≤ target`` already; if even the
    smallest λ tried leaves the residual above ``target``, that λ's impulses (a start outside the noise ball,
    which the solver then reports).

    Examples
    --------
    >>> import numpy as np
    >>> M, b = np.tril(np.ones((4, 4))), np.array([1.0, 2.0, 0.0, 1.0])
    >>> h = ridge_fit_gram(M.T @ M, M.T @ b, lambda h: float(np.sum((b - M @ h) ** 2)), target=0.25)
    >>> bool(abs(float(np.sum((b - M @ h) ** 2)) / 0.25 - 1.0) <= 0.05)
    True
    >>> h_svd = ridge_fit(operator_svd(M), b, 0.25)      # the same fit (to the residual's tolerance)
    >>> bool(np.allclose(h, h_svd, rtol=0.1, atol=0.05))
    True
    """
    c = np.asarray(c, float)
    if residual(np.zeros_like(c)) <= target:
        return np.zeros_like(c)
    p = gram.shape[0]
    scale = max(float(np.trace(gram)) / p, np.finfo(float).tiny)
    lo, hi = -np.inf, np.inf  # bracket of log λ: residual below target at lo, above at hi
    x, h = np.log(scale), None
    G = np.empty_like(gram)  # G + λI, one p × p buffer for every λ (p = 10⁴: 800 MB)
    for _ in range(max_iter):
        lam = float(np.exp(x))
        np.copyto(G, gram)
        G.flat[:: p + 1] += lam
        try:  # on the transpose (symmetric, LAPACK's order): factorised in place, no copy
            factor = scipy.linalg.cho_factor(G.T, overwrite_a=True, check_finite=False)
        except np.linalg.LinAlgError:  # rounding at a tiny λ: G is positive semidefinite
            lo, x = x, x + np.log(10.0)
            continue
        h = scipy.linalg.cho_solve(factor, c, check_finite=False)
        r = residual(h)
        if abs(r / target - 1.0) <= rel:
            return h
        if r > target:
            hi = x
        else:
            lo = x
        slope = 2.0 * lam * lam * float(h @ scipy.linalg.cho_solve(factor, h, check_finite=False)) / r
        step = (np.log(target) - np.log(r)) / slope if slope > 0 else -np.inf
        x_new = x + step
        if not lo < x_new < hi:  # Newton left the bracket: bisect it, or step a decade out of a one-sided one
            if np.isfinite(lo) and np.isfinite(hi):
                x_new = 0.5 * (lo + hi)
            else:
                x_new = x + (np.log(10.0) if r < target else -np.log(10.0)) * 3.0
        if hi - lo < 1e-12 * max(1.0, abs(x)):
            break
        x = x_new
    return h


#: :func:`cold_impulses` tries the fit in the norm of 𝓛^⊥ when the largest column impulse ``‖h_k‖₂`` exceeds this
#: multiple of the median (measured: 3–5 on the benchmark's ±1 records, up to 7 on 80 fuzzed one-channel records
#: that solve well from the plain fit, 100 to 1e13 on those that were slow or failed from it).
OUTLIER = 20.0


def cold_impulses(svd, B0: np.ndarray, target: float, *, projected_fit=None, top=None) -> np.ndarray:
    """The impulses (p, j) of a cold start: the ridge fit :func:`ridge_fit`, or, where one column's impulse stands
    :data:`OUTLIER` times above the median, the ridge fit in the norm of 𝓛^⊥ if its largest ``‖T(h_k)‖₂`` is smaller.

    ``projected_fit(λ)``: ``(H, ‖P(B0 − H̃)‖²_F)`` of ``H = argmin λ‖H‖²_F + ‖P(B0 − H̃)‖²_F``, or None where its solve
    fails (the solver's own, :func:`ridge_search` finds λ); None with L fixed (𝓛 = {0}: the plain fit is that fit).
    ``top(H)``: ``max_k ‖T(h_k)‖₂``, the δ the start would take.

    Why: the plain fit ignores that 𝓛 absorbs part of the data, so a column whose T(u_k) is singular in floating
    point (a window of band-limited input, or one starting with a small sample; cond up to 1e25) gets impulses of
    1e15 and the first Newton system is singular (measured: every one-channel fuzzed record with L optimised that
    ended ``failed`` after 0–3 Newton steps while cvxpy certified δ).  The projected fit lets 𝓛 take those directions:
    on such a record δ₀ = 9.6 against 1.7e15 (scaled units) and the certified δ = 1.36511 of cvxpy; on records whose
    start was only far (δ₀ 1e4–1e7 times the projected one) 2–13 times fewer seconds.  The benchmark's records stay
    below the trigger and keep the plain fit, where the projected one (measured at (50, 500)) cost 4 s and saved
    no Newton step.
    """
    H = ridge_fit(svd, B0, target)
    if projected_fit is None:
        return H
    size = np.linalg.norm(H, axis=0)
    if not size.max() > OUTLIER * np.median(size):
        return H
    # from the scale of T(u)ᵀT(u) down: a small λ makes the projected solve ill-conditioned (slow, inexact)
    found = ridge_search(projected_fit, target, float(np.mean(svd[1] ** 2)))
    if found is None:
        return H
    return found[0] if top(found[0]) < top(H) else H


def ridge_search(fit, target: float, lam0: float, *, low: float = 0.5, high: float = 1.3, max_fits: int = 12):
    """Ridge impulses ``fit(λ)`` whose residual lies in ``[low, high] × target``, found from ``λ0`` by secant steps on
    ``log r`` against ``log λ`` (the residual grows with λ) kept inside the bracket known so far.

    ``fit(λ)`` returns ``(h, r)``, the impulses and their residual (squared), or None where λ is too small for its
    solve (a singular system in floating point): that λ counts as one whose residual is below the band.  For an
    operator whose ridge fit has no closed form, e.g. the fit in the norm of the projection onto 𝓛^⊥ of the column
    form, whose normal equations couple the columns and are solved iteratively; there every λ costs a solve, so the
    band is wide (any point well inside the noise ball is a start).  The first step assumes the small-λ law
    ``r ∝ λ²``.  Returns ``(h, r)`` of the fit in the band, else of the one with the largest residual below
    ``high × target``, else None.

    Examples
    --------
    >>> import numpy as np
    >>> M, b = np.tril(np.ones((4, 4))), np.array([1.0, 2.0, 0.0, 1.0])
    >>> def fit(lam):
    ...     h = np.linalg.solve(M.T @ M + lam * np.eye(4), M.T @ b)
    ...     return h, float(np.sum((b - M @ h) ** 2))
    >>> h, r = ridge_search(fit, target=0.25, lam0=1e-3)
    >>> bool(0.5 * 0.25 <= r <= 1.3 * 0.25)
    True
    """
    x, lo, hi = float(np.log(lam0)), -np.inf, np.inf   # log λ; the residual is below the band at lo, above at hi
    best, prev = None, None
    for _ in range(max_fits):
        out = fit(float(np.exp(x)))
        if out is None or not np.isfinite(out[1]):
            lo, prev = x, None
            x = x + 2.0 * np.log(10.0) if not np.isfinite(hi) else 0.5 * (x + hi)
            continue
        h, r = out
        if low * target <= r <= high * target:
            return h, r
        if r < high * target and (best is None or r > best[1]):
            best = (h, r)
        if r < target:
            lo = x
        else:
            hi = x
        slope = 2.0
        if prev is not None and prev[0] != x and r > 0 and prev[1] > 0:
            slope = (np.log(r) - np.log(prev[1])) / (x - prev[0])
            slope = min(max(slope, 0.05), 2.0)
        prev = (x, r)
        x_new = x + (np.log(target) - np.log(max(r, np.finfo(float).tiny))) / slope
        if not lo < x_new < hi:
            x_new = 0.5 * (lo + hi) if np.isfinite(lo) and np.isfinite(hi) else \
                x + (3.0 if r < target else -3.0) * np.log(10.0)
        x = x_new
    return best
