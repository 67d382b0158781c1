"""Least-squares subspace predictor (thesis §2.1–2.3).

The predictor ``(Lw, Lu)`` solves (2.5),

    min ‖Y_f − [Lw Lu] [W_p; U_f]‖_F,

so that future outputs are predicted by (2.6), ``ŷ = Lw w_p + Lu u_f`` with
``w_p = [u_{k-i}; …; u_{k-1}; y_{k-i}; …; y_{k-1}]`` (3.13).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from ._validation import DataError, as_signal, check_horizon

__all__ = ["Predictor", "fit_predictor", "block_hankel", "PersistenceWarning"]


class PersistenceWarning(UserWarning):
    """The input is not persistently exciting of order 2mi (§5.1, comment 1)."""


@dataclass(frozen=True)
class Predictor:
    """Subspace predictor ``ŷ = Lw w_p + Lu u_f`` (2.6).

    Attributes
    ----------
    Lw : ndarray, shape (i*l, i*(m+l))
        Past-data matrix; columns ordered as ``w_p = [u_{k-i} … u_{k-1}; y_{k-i} … y_{k-1}]`` (3.13).
    Lu : ndarray, shape (i*l, i*m)
        Future-input matrix; block lower triangular in the noise-free LTI limit (2.10).
    horizon : int
        The thesis's ``i``.
    m, l : int
        Number of inputs and outputs.
    n_columns : int
        The thesis's ``j = n - 2i + 1`` (number of prediction problems).
    singular_values : ndarray
        Singular values of the regressor factor ``[R11 0; R21 R22]`` (§2.2), descending.
    rank : int
        Numerical rank ``q`` kept in the pseudo-inverse.
    method : str
        How it was computed (``"cholesky"``, ``"qr"``, ``"lstsq"``, ``"recursive"``).
    """

    Lw: np.ndarray
    Lu: np.ndarray
    horizon: int
    m: int
    l: int
    n_columns: int
    singular_values: np.ndarray
    rank: int
    method: str

    @property
    def n_regressors(self) -> int:
        """Number of regressor rows, ``i(2m + l)``."""
        return self.horizon * (2 * self.m + self.l)

    @property
    def full_rank(self) -> bool:
        """True when the regressor ``[W_p; U_f]`` had full row rank."""
        return self.rank == self.n_regressors

    def predict(self, w_p, u_f) -> np.ndarray:
        """Predicted future outputs (2.6), shape ``(i, l)`` (time along axis 0).

        Parameters
        ----------
        w_p : array_like, shape (i*(m+l),)
            Past data stacked as in (3.13); see :meth:`past_vector`.
        u_f : array_like, shape (i, m) or (i*m,)
            Future inputs.
        """
        w_p = np.asarray(w_p, dtype=float).reshape(-1)
        u_f = np.asarray(u_f, dtype=float).reshape(-1)
        if w_p.size != self.Lw.shape[1]:
            raise DataError(f"w_p must have {self.Lw.shape[1]} entries, got {w_p.size}")
        if u_f.size != self.Lu.shape[1]:
            raise DataError(f"u_f must have {self.Lu.shape[1]} entries, got {u_f.size}")
        return (self.Lw @ w_p + self.Lu @ u_f).reshape(self.horizon, self.l)

    def past_vector(self, u_past, y_past) -> np.ndarray:
        """Stack the last ``i`` samples of ``u`` and ``y`` into ``w_p`` (3.13)."""
        i = self.horizon
        u_past = as_signal(u_past, "u_past", width=self.m)
        y_past = as_signal(y_past, "y_past", width=self.l)
        if u_past.shape[0] < i or y_past.shape[0] < i:
            raise DataError(f"need at least i={i} past samples of u and y")
        return np.concatenate([u_past[-i:].reshape(-1), y_past[-i:].reshape(-1)])


def block_hankel(x: np.ndarray, rows: int, cols: int, start: int = 0) -> np.ndarray:
    """Block Hankel matrix with ``rows`` block rows and ``cols`` columns, (2.1)–(2.4).

    ``x`` has shape ``(n, k)``; block row ``r`` holds ``x[start + r : start + r + cols].T``.
    Returns an array of shape ``(rows*k, cols)`` (a copy).
    """
    x = np.asarray(x, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    k = x.shape[1]
    seg = x[start : start + rows + cols - 1]
    if seg.shape[0] < rows + cols - 1:
        raise DataError("not enough samples for the requested block Hankel matrix")
    # windows[c, ch, r] = seg[c + r, ch]
    windows = sliding_window_view(seg, rows, axis=0)  # (cols, k, rows)
    return np.ascontiguousarray(windows.transpose(2, 1, 0).reshape(rows * k, cols))


def _data_matrices(u: np.ndarray, y: np.ndarray, i: int):
    j = u.shape[0] - 2 * i + 1
    Up = block_hankel(u, i, j, 0)
    Uf = block_hankel(u, i, j, i)
    Yp = block_hankel(y, i, j, 0)
    Yf = block_hankel(y, i, j, i)
    return Up, Uf, Yp, Yf, j


def _default_rcond(n_reg: int, j: int) -> float:
    return max(n_reg, j) * np.finfo(float).eps


def _solve_from_r(R: np.ndarray, n_reg: int, rcond: float | None, j: int):
    """Given lower-triangular ``L`` with ``A = L Qᵀ`` (2.7), return ``[Lw Lu]``, singular values, rank."""
    R11 = R[:n_reg, :n_reg]
    R31 = R[n_reg:, :n_reg]
    U, s, Vt = np.linalg.svd(R11)
    tol = (rcond if rcond is not None else _default_rcond(n_reg, j)) * (s[0] if s.size and s[0] > 0 else 1.0)
    q = int(np.count_nonzero(s > tol))
    L = (R31 @ Vt[:q].T) / s[:q] @ U[:, :q].T
    return L, s, q


def _split(L: np.ndarray, i: int, m: int, l: int):
    return L[:, : i * (m + l)].copy(), L[:, i * (m + l) :].copy()


def fit_predictor(u, y, horizon: int, *, method: str = "cholesky", rcond: float | None = None) -> Predictor:
    """Fit the least-squares subspace predictor (2.5) from input/output data.

    Parameters
    ----------
    u : array_like, shape (n,) or (n, m)
        Input samples, time along axis 0.
    y : array_like, shape (n,) or (n, l)
        Output samples, time along axis 0.
    horizon : int
        Prediction horizon ``i``; the number of prediction problems is ``j = n - 2i + 1``.
    method : {"cholesky", "qr", "lstsq"}
        ``"qr"``: QR of ``[W_p; U_f; Y_f]`` (2.7) and the SVD pseudo-inverse of §2.2.
        ``"cholesky"``: Cholesky factor of ``AAᵀ`` built by the Hankel recursions (2.8)–(2.9),
        never forming the Hankel matrices (§2.3).  ``"lstsq"``: ``numpy.linalg.lstsq`` on the
        explicit Hankel matrices (a plain reference).
    rcond : float, optional
        Relative tolerance for the pseudo-inverse: singular values below ``rcond * σ₁`` are
        discarded (§2.2).  Default ``max(i(2m+l), j) * eps``.

    Returns
    -------
    Predictor

    Raises
    ------
    DataError
        On NaN/inf, length mismatch, too few samples for the horizon, or a bad horizon.

    Warns
    -----
    PersistenceWarning
        When the regressor is rank deficient (input not persistently exciting of order 2mi).
    """
    u = as_signal(u, "u")
    y = as_signal(y, "y", n=u.shape[0])
    n, m = u.shape
    l = y.shape[1]
    i = check_horizon(horizon, n)
    n_reg = i * (2 * m + l)
    j = n - 2 * i + 1
    if method == "cholesky":
        from .hankel import hankel_gram  # local import keeps the module graph simple

        G = hankel_gram(u, y, i)
        R = _psd_cholesky(G)
        L, s, q = _solve_from_r(R, n_reg, rcond, j)
    elif method == "qr":
        Up, Uf, Yp, Yf, j = _data_matrices(u, y, i)
        A = np.vstack([Up, Yp, Uf, Yf])
        R = np.linalg.qr(A.T, mode="r").T
        L, s, q = _solve_from_r(R, n_reg, rcond, j)
    elif method == "lstsq":
        Up, Uf, Yp, Yf, j = _data_matrices(u, y, i)
        Phi = np.vstack([Up, Yp, Uf])
        sol, _, q, s = np.linalg.lstsq(Phi.T, Yf.T, rcond=rcond if rcond is not None else _default_rcond(n_reg, j))
        L = sol.T
        s = np.asarray(s)
    else:
        raise ValueError(f"unknown method {method!r}; use 'cholesky', 'qr' or 'lstsq'")
    _warn_rank(q, n_reg, i, m)
    Lw, Lu = _split(L, i, m, l)
    return Predictor(Lw, Lu, i, m, l, j, np.asarray(s), int(q), method)


def _warn_rank(q: int, n_reg: int, i: int, m: int) -> None:
    if q < n_reg:
        warnings.warn(
            f"regressor [W_p; U_f] has numerical rank {q} < {n_reg}: the data are not persistently "
            f"exciting of order 2mi = {2 * m * i} (or the outputs are noise free); the minimum-norm "
            "predictor is returned",
            PersistenceWarning,
            stacklevel=3,
        )


def _psd_cholesky(G: np.ndarray) -> np.ndarray:
    """Lower-triangular ``L`` with ``L Lᵀ = G`` for symmetric positive *semi*-definite ``G``.

    Tries LAPACK Cholesky first; if ``G`` is only semidefinite (rank-deficient data),
    falls back to a symmetric eigendecomposition, clipping eigenvalues below
    ``n * eps * λ_max`` to zero, followed by a QR to restore triangular form.
    """
    try:
        return np.linalg.cholesky(G)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(G)
        tol = G.shape[0] * np.finfo(float).eps * max(w.max(), 0.0)
        w = np.where(w > tol, w, 0.0)
        F = V * np.sqrt(w)  # G ≈ F Fᵀ
        return np.linalg.qr(F.T, mode="r").T
