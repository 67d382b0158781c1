"""Rank-1 update and downdate of a Cholesky factor (thesis §2.3.1, after [17] / LINPACK).

``cholupdate(L, x)`` returns the factor of ``L Lᵀ + x xᵀ`` and ``choldowndate(L, x)``
the factor of ``L Lᵀ − x xᵀ``, both in ``O(N²)`` time.  Factors are lower triangular
with ``G = L Lᵀ`` (the convention of :func:`numpy.linalg.cholesky`); ``lower=False``
works on upper-triangular ``R`` with ``G = Rᵀ R`` (the thesis's ``R = chol(AAᵀ)``).

Both routines loop over the ``N`` columns and do vector work across the remaining
rows, so the Python-level cost is ``N`` iterations of a few numpy operations.

* The update applies ``N`` Givens (orthogonal) rotations to ``[L x]`` (LINPACK ``dchud``).
* The downdate is the LINPACK ``dchdd`` algorithm (Stewart 1979): solve ``L p = x``;
  ``L Lᵀ − x xᵀ`` is positive definite iff ``‖p‖ < 1``; then ``N`` *orthogonal* rotations
  that map ``[p; √(1−‖p‖²)]`` to ``e_{N+1}`` turn ``[Lᵀ; 0]`` into ``[L̃ᵀ; xᵀ]``.  Using
  orthogonal instead of hyperbolic rotations makes it the numerically preferred
  variant; the test ``‖p‖ < 1`` detects loss of positive definiteness *before* anything
  is modified, and :class:`DowndateError` is raised.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.linalg import solve_triangular

from ._validation import DataError, as_real_array, check_flag, check_nonnegative
from .exceptions import DowndateError

__all__ = ["cholupdate", "choldowndate", "DowndateError"]


def _prepare(L, x, lower: bool, overwrite: bool):
    lower, overwrite = check_flag(lower, "lower"), check_flag(overwrite, "overwrite")
    # as_real_array: a complex factor had lost its imaginary part (ComplexWarning), a complex x raised TypeError
    L = as_real_array(L, "the Cholesky factor L")
    x = as_real_array(x, "x").reshape(-1)
    if L.ndim != 2 or L.shape[0] != L.shape[1]:
        raise DataError(f"the Cholesky factor must be a square matrix, got shape {L.shape}")
    if x.size != L.shape[0]:
        raise DataError(f"x must have {L.shape[0]} entries to match the factor, got {x.size}")
    if not (np.all(np.isfinite(L)) and np.all(np.isfinite(x))):
        raise DataError("the factor and x must be finite (no NaN/inf)")
    # the update reads one triangle only: a full matrix (a Gram matrix passed for its factor) had returned a result
    # that kept the other triangle, silently neither a factor nor the update of one
    if np.any(np.triu(L, 1) if lower else np.tril(L, -1)):
        side, other = ("lower", "upper") if lower else ("upper", "lower")
        raise DataError(f"the Cholesky factor must be {side} triangular (lower={lower}), but its strictly {other} "
                        f"triangle is not zero: pass the factor, not the matrix it factors (e.g. np.linalg.cholesky(G) "
                        f"for G), or lower={not lower} for {'an' if lower else 'a'} {other} triangular factor")
    # Work on Rt, an upper-triangular view whose rows are the columns of the lower factor.
    if overwrite and L.flags.writeable:
        W = L
    else:
        W = L.copy()
    Rt = W.T if lower else W
    return W, Rt, x.copy()


def cholupdate(L, x, *, lower: bool = True, overwrite: bool = False) -> np.ndarray:
    """Cholesky factor of ``L Lᵀ + x xᵀ`` (rank-1 update, §2.3.1).

    Parameters
    ----------
    L : array_like, shape (N, N)
        Triangular factor: lower with ``G = L Lᵀ`` (default), or upper ``R`` with ``G = Rᵀ R``
        when ``lower=False``.  May be singular (zero diagonal entries are allowed).
    x : array_like, shape (N,)
        The column to add (``a_new`` in §2.3.1).
    lower : bool
        Triangle of the factor.
    overwrite : bool
        Update ``L`` in place (if it is a writeable float array).

    Returns
    -------
    ndarray, shape (N, N)
        The updated factor, with non-negative diagonal.

    Notes
    -----
    ``N`` Givens rotations, ``O(N²)`` flops (LINPACK ``dchud``).

    Examples
    --------
    The result is the factor :func:`numpy.linalg.cholesky` gives for the updated matrix:

    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> M = rng.standard_normal((4, 4))
    >>> G = M @ M.T + np.eye(4)
    >>> x = rng.standard_normal(4)
    >>> L1 = cholupdate(np.linalg.cholesky(G), x)
    >>> np.allclose(L1, np.linalg.cholesky(G + np.outer(x, x)))
    True
    >>> np.allclose(L1, np.tril(L1))
    True
    """
    W, R, x = _prepare(L, x, lower, overwrite)
    N = R.shape[0]
    for k in range(N):
        rkk, xk = float(R[k, k]), float(x[k])
        r = math.hypot(rkk, xk)
        if r == 0.0:
            continue  # nothing to rotate in this row
        c, s = rkk / r, xk / r
        R[k, k] = r
        if k + 1 < N:
            row = R[k, k + 1 :]
            tail = x[k + 1 :]
            new_row = c * row + s * tail
            tail *= c
            tail -= s * row
            row[...] = new_row
    return W


def choldowndate(L, x, *, lower: bool = True, overwrite: bool = False, rtol: float | None = None) -> np.ndarray:
    """Cholesky factor of ``L Lᵀ − x xᵀ`` (rank-1 downdate, §2.3.1), LINPACK ``dchdd``.

    Parameters
    ----------
    L : array_like, shape (N, N)
        Nonsingular triangular factor (lower by default, see :func:`cholupdate`).
    x : array_like, shape (N,)
        The column to remove (``a_old`` in §2.3.1).
    lower : bool
        Triangle of the factor.
    overwrite : bool
        Downdate ``L`` in place (only after the positive-definiteness check has passed).
    rtol : float, optional
        The downdate is refused when ``1 − ‖L⁻¹x‖² ≤ rtol`` (the downdated matrix would be
        singular to working precision); in ``[0, 1)``.  Default ``N · eps``.

    Returns
    -------
    ndarray, shape (N, N)

    Raises
    ------
    DowndateError
        If ``L`` is singular or ``L Lᵀ − x xᵀ`` is not numerically positive definite
        (nothing is modified in that case).
    DataError
        ``L`` or ``x`` not real finite arrays of matching sizes; ``rtol`` not a number in ``[0, 1)``.

    Examples
    --------
    A downdate undoes an update (:func:`cholupdate`):

    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> M = rng.standard_normal((4, 4))
    >>> L = np.linalg.cholesky(M @ M.T + np.eye(4))
    >>> x = rng.standard_normal(4)
    >>> np.allclose(choldowndate(cholupdate(L, x), x), L)
    True

    Removing more than the matrix holds is refused (``I − [1 1]ᵀ[1 1]`` is indefinite):

    >>> choldowndate(np.eye(2), [1.0, 1.0])
    Traceback (most recent call last):
    ...
    synthesis.exceptions.DowndateError: downdate would lose positive definiteness (1 - ||L^-1 x||^2 = -1); refactor the Gram matrix instead
    """
    if rtol is not None:
        # float() had read "1" as 1.0 and refused every downdate as a loss of definiteness; -1 had been accepted
        rtol = check_nonnegative(rtol, "rtol")
        if not rtol < 1.0:
            raise DataError(f"rtol must lie in [0, 1) (1 - ||L^-1 x||^2 is at most 1, so rtol >= 1 refuses every "
                            f"downdate), got {rtol!r}; leave it None for N * eps")
    W, R, x = _prepare(L, x, lower, overwrite)  # nothing is modified before the checks pass
    N = R.shape[0]
    tol = N * np.finfo(float).eps if rtol is None else rtol
    if N == 0:
        return W
    d = np.abs(np.diag(R))
    if not np.all(d > np.finfo(float).tiny) or d.min() <= N * np.finfo(float).eps * d.max():
        raise DowndateError("cannot downdate a singular Cholesky factor; refactor the Gram matrix instead")
    # Solve Rᵀ p = x (R upper, i.e. L p = x for the lower factor).
    p = solve_triangular(R, x, trans="T", lower=False, check_finite=False)
    alpha2 = 1.0 - p @ p
    if not alpha2 > tol:
        raise DowndateError(
            f"downdate would lose positive definiteness (1 - ||L^-1 x||^2 = {alpha2:.3g}); "
            "refactor the Gram matrix instead"
        )
    alpha = np.sqrt(alpha2)
    # Rotations k = N-1 … 0 zero p_k against alpha.
    cs = [0.0] * N
    sn = [0.0] * N
    alpha = float(alpha)
    for k, pk in zip(range(N - 1, -1, -1), p[::-1].tolist()):
        scale = math.hypot(alpha, pk)
        cs[k] = alpha / scale
        sn[k] = pk / scale
        alpha = scale
    # Apply them to the rows of R and a zero row, vectorised across columns.
    xx = np.zeros(N)
    for k in range(N - 1, -1, -1):
        row = R[k, k:]
        xk = xx[k:]
        c, s = cs[k], sn[k]
        t = c * xk + s * row
        row *= c
        row -= s * xk
        xk[...] = t
    # Normalise to a non-negative diagonal.
    neg = np.diag(R) < 0
    if np.any(neg):
        R[neg, :] *= -1.0
    return W
