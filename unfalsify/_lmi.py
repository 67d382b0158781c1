"""cvxpy building blocks: affine Toeplitz expressions and the Toeplitz-norm LMI."""
from __future__ import annotations

from functools import lru_cache

import cvxpy as cp
import numpy as np
import scipy.sparse as sp

__all__ = ["toeplitz_expr", "toeplitz_norm_lmi"]


@lru_cache(maxsize=32)
def _selector(n: int) -> sp.csr_matrix:
    """Sparse ``S`` (n² × n) with ``vec_F(T(x)) = S x``: entry (r, c), r ≥ c, is ``x[r-c]``."""
    r, c = np.tril_indices(n)
    rows = r + c * n
    cols = r - c
    return sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(n * n, n))


def toeplitz_expr(x: cp.Expression, n: int) -> cp.Expression:
    """``T(x)`` (lower-triangular Toeplitz, first column ``x``) as an affine cvxpy expression."""
    return cp.reshape(_selector(n) @ x, (n, n), order="F")


def toeplitz_norm_lmi(h: cp.Expression, delta: cp.Expression, n: int) -> cp.Constraint:
    """``‖T(h)‖₂ ≤ δ`` as the 2n×2n LMI ``[δI T(h)ᵀ; T(h) δI] ⪰ 0``."""
    T = toeplitz_expr(h, n)
    eye = np.eye(n)
    return cp.bmat([[delta * eye, T.T], [T, delta * eye]]) >> 0
