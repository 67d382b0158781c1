"""Lower-triangular Toeplitz matrices ``T(x)`` of Theorem 7.1 and their numerics.

``T(x)`` is the n×n lower-triangular Toeplitz matrix with first column ``x``: it is
the matrix of the causal convolution ``y = x * u`` truncated to n samples.  Such
matrices commute, ``T(a) b = T(b) a``, and ``T(a) T(b) = T(a * b)``.

This module provides

* :func:`toeplitz_matrix` -- the dense matrix (small n);
* :func:`toeplitz_norm` -- ``‖T(h)‖₂`` (dense SVD for small n, Lanczos with FFT
  products for large n);
* :func:`deconvolve` -- ``T(u)⁻¹ y`` by forward substitution (float) or exactly
  in rational arithmetic (:mod:`fractions`), the extended-precision route used
  to certify answers;
* :func:`toeplitz_cond` -- ``cond₂ T(u) = ‖T(u)‖₂ ‖T(g)‖₂`` with ``g = T(u)⁻¹ e₁``
  (the inverse of a lower-triangular Toeplitz matrix is lower-triangular Toeplitz).

By Carathéodory–Fejér, ``‖T_n(h)‖₂`` is the smallest H∞ norm of any causal LTI
system whose first n Markov parameters are ``h``.
"""
from __future__ import annotations

from fractions import Fraction

import numpy as np
import scipy.linalg
import scipy.signal
from scipy.sparse.linalg import LinearOperator, svds

from synthesis._validation import DataError

from ._columns import _nfft

__all__ = [
    "toeplitz_matrix",
    "toeplitz_norm",
    "deconvolve",
    "toeplitz_cond",
    "DENSE_LIMIT",
]

#: Above this size :func:`toeplitz_norm` switches from a dense SVD to Lanczos.
DENSE_LIMIT = 400


def toeplitz_matrix(x) -> np.ndarray:
    """Dense lower-triangular Toeplitz matrix ``T(x)`` with first column ``x`` (Thm 7.1)."""
    x = np.asarray(x, dtype=float).reshape(-1)
    return scipy.linalg.toeplitz(x, np.zeros_like(x))


def _fft_operator(h: np.ndarray) -> LinearOperator:
    """``T(h)`` as a LinearOperator with O(n log n) FFT products.

    ``T(h) x`` is the first n samples of the full convolution; ``T(h)ᵀ = J T(h) J``
    with ``J`` the flip (lower-triangular Toeplitz matrices are persymmetric).
    """
    n = h.size
    nfft = int(2 ** np.ceil(np.log2(max(2 * n - 1, 2))))
    H = np.fft.rfft(h, nfft)

    def mv(x):
        x = np.asarray(x, dtype=float).reshape(-1)
        return np.fft.irfft(H * np.fft.rfft(x, nfft), nfft)[:n]

    def rmv(x):
        x = np.asarray(x, dtype=float).reshape(-1)
        return mv(x[::-1])[::-1]

    return LinearOperator((n, n), matvec=mv, rmatvec=rmv, dtype=float)


def _toeplitz_gram(h: np.ndarray) -> np.ndarray:
    """``T(h)ᵀT(h)`` in O(n²) (no matrix product): along the k-th diagonal,
    ``G[i, i+k] = r_k − Σ_{q<i} a_q a_{q+k}`` with ``r_k = Σ_j h_j h_{j+k}`` and ``a = h`` reversed
    (``G[i+1, j+1] = G[i, j] − h_{n−1−i} h_{n−1−j}``)."""
    n = h.size
    nf = _nfft(n)
    H = np.fft.rfft(h, nf)
    r = np.fft.irfft(H * np.conj(H), nf)[:n]  # r_k = Σ_j h_j h_{j+k}
    a = h[::-1]
    G = np.empty((n, n))
    flat = G.reshape(-1)
    for k in range(n):
        diag = np.empty(n - k)
        diag[0] = r[k]
        np.cumsum(a[: n - 1 - k] * a[k : n - 1], out=diag[1:])
        diag[1:] = r[k] - diag[1:]
        flat[k : (n - k) * (n + 1) : n + 1] = diag  # upper diagonal k
        flat[k * n : n * n : n + 1] = diag  # lower diagonal k
    return G


def toeplitz_norm(h, *, method: str = "auto", tol: float = 1e-12) -> float:
    """Spectral norm ``‖T(h)‖₂`` of the lower-triangular Toeplitz matrix with first column ``h``.

    Parameters
    ----------
    h : array_like, shape (n,)
        First column (Markov parameters).
    method : {"auto", "dense", "lanczos"}
        ``"dense"``: LAPACK SVD of the dense matrix, O(n³).  ``"lanczos"``: ARPACK
        (:func:`scipy.sparse.linalg.svds`) on a LinearOperator whose products are
        FFT convolutions, O(n log n) each.  ``"auto"``: dense for ``n <= DENSE_LIMIT``.
    tol : float
        Relative tolerance passed to ARPACK.
    """
    if method not in ("auto", "dense", "lanczos"):
        raise ValueError(f"unknown method {method!r}; use 'auto', 'dense' or 'lanczos'")
    h = np.asarray(h, dtype=float).reshape(-1)
    n = h.size
    if n == 0:
        return 0.0
    scale = float(np.max(np.abs(h)))
    if scale == 0.0:
        return 0.0
    if method == "auto":
        method = "dense" if n <= DENSE_LIMIT else "lanczos"
    if method == "dense" or n < 3:
        return float(np.linalg.norm(toeplitz_matrix(h), 2))
    op = _fft_operator(h / scale)
    v0 = np.ones(n) / np.sqrt(n)
    s = svds(op, k=1, which="LM", tol=tol, v0=v0, return_singular_vectors=False, solver="arpack")
    return float(s[0]) * scale


def deconvolve(u, y, *, exact: bool = False) -> np.ndarray:
    """Solve ``T(u) h = y`` (so that ``y = h * u`` on the window), requires ``u[0] != 0``.

    Parameters
    ----------
    u, y : array_like, shape (n,)
    exact : bool
        If True, forward substitution in exact rational arithmetic on the binary
        values of ``u`` and ``y`` (:class:`fractions.Fraction`), rounded to float only
        at the end: the result is the correctly rounded ``T(u)⁻¹ y`` regardless of
        cond ``T(u)`` (O(n²) big-number operations; fine for n up to a few hundred).
        If False, :func:`scipy.signal.lfilter` (IIR filter ``1/u(q)``), O(n²) flops,
        whose error grows like cond ``T(u)``.

    Raises
    ------
    DataError
        ``u[0] == 0`` (``T(u)`` singular) or ``u``, ``y`` of different lengths.
    """
    u = np.asarray(u, dtype=float).reshape(-1)
    y = np.asarray(y, dtype=float).reshape(-1)
    if u.size == 0 or u.size != y.size:
        raise DataError(f"u and y must be non-empty and of the same length, got {u.size} and {y.size} samples")
    if u[0] == 0.0:
        raise DataError(
            "T(u) is singular: u[0] == 0; start the record at the first non-zero input sample "
            "(the system is at rest before it)"
        )
    if not exact:
        return scipy.signal.lfilter([1.0], u, y)
    n = y.size
    uf = [Fraction(float(v)) for v in u]
    yf = [Fraction(float(v)) for v in y]
    h: list[Fraction] = []
    for t in range(n):
        acc = yf[t]
        for k in range(1, t + 1):
            if uf[k]:
                acc -= uf[k] * h[t - k]
        h.append(acc / uf[0])
    return np.array([_to_float(v) for v in h])


def _to_float(v: Fraction) -> float:
    try:
        return float(v)
    except OverflowError:
        return float("inf") if v > 0 else float("-inf")


def toeplitz_cond(u) -> float:
    """2-norm condition number of ``T(u)``: ``‖T(u)‖₂ · ‖T(u)⁻¹‖₂``.

    ``T(u)⁻¹ = T(g)`` with ``g = T(u)⁻¹ e₁`` (the impulse response of ``1/u(q)``), so
    both factors are Toeplitz norms; this avoids the dense inverse and stays
    meaningful up to ~1e300.  Returns ``inf`` when ``u[0] == 0``.
    """
    u = np.asarray(u, dtype=float).reshape(-1)
    if u[0] == 0.0:
        return float("inf")
    e1 = np.zeros_like(u)
    e1[0] = 1.0
    with np.errstate(over="ignore", invalid="ignore"):
        g = deconvolve(u, e1)
    if not np.all(np.isfinite(g)):
        return float("inf")
    return toeplitz_norm(u) * toeplitz_norm(g)
