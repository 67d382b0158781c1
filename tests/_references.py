"""Independent references shared by the tests: written from the definitions, never from the package."""
import numpy as np

#: shapes (l outputs, m inputs) of the MIMO tests
SHAPES = [(2, 1), (1, 2), (2, 2)]


def block_toeplitz_by_loops(h):
    """Block lower-triangular Toeplitz matrix of h (n, l, m), by loops (independent of the package)."""
    n, l, m = h.shape
    T = np.zeros((n * l, n * m))
    for r in range(n):
        for c in range(r + 1):
            T[r * l:(r + 1) * l, c * m:(c + 1) * m] = h[r - c]
    return T
