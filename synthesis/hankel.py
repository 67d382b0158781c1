"""Gram matrix ``AAᵀ`` of the stacked block Hankel data ``A = [U_p; Y_p; U_f; Y_f]`` (§2.3).

PLACEHOLDER: forms the Hankel matrices explicitly; to be replaced by the
O(ij + i²) recursions (2.8)–(2.9).
"""
from __future__ import annotations

import numpy as np

from .predictor import block_hankel

__all__ = ["hankel_gram"]


def hankel_gram(u: np.ndarray, y: np.ndarray, i: int) -> np.ndarray:
    """Return ``AAᵀ`` with ``A = [U_p; Y_p; U_f; Y_f]`` (row order of (2.7))."""
    j = u.shape[0] - 2 * i + 1
    A = np.vstack([block_hankel(u, i, j, 0), block_hankel(y, i, j, 0), block_hankel(u, i, j, i), block_hankel(y, i, j, i)])
    return A @ A.T
