"""Recursive (growing or sliding-window) subspace predictor (thesis §2.3.1).

New data ``(u_n, y_n)`` append a column ``a_new`` to ``A = [W_p; U_f; Y_f]``; a sliding
window also removes the oldest column ``a_old``.  :class:`RecursivePredictor` keeps a
summary of size ``O(i²)`` that absorbs each pushed sample in ``O(i²)`` time, and
:meth:`RecursivePredictor.predictor` returns ``(Lw, Lu)`` in ``O(i³)`` time — both
independent of how much data came before.  Only the last ``2i − 1`` samples are kept
(growing window), or the window's own ``window + 2i − 1`` samples (sliding window, needed
to downdate).

Two summaries are available (``track=``):

``"gram"`` (default)
    The Gram matrix ``AAᵀ`` itself, updated by ``AAᵀ += a_new a_newᵀ`` and
    ``AAᵀ −= a_old a_oldᵀ`` (one in-place BLAS rank-k update ``dsyrk`` of the lower triangle per
    pushed chunk: half the arithmetic of a full product, no temporary); ``predictor()``
    factors it with the same rank-revealing Cholesky as :func:`fit_predictor`.  This is
    exact, cannot lose definiteness (there is no square root to take), copes with the
    singular Gram of a short or not persistently exciting window (§6.3 starts from
    ``n = 384`` samples at ``i = 64``) and is the fastest per sample, since
    ``predictor()`` costs ``O(i³)`` anyway for the SVD of §2.2.  It is the default for
    these reasons.
``"factor"``
    The Cholesky factor ``R`` of §2.3.1, updated by :func:`~synthesis.cholesky.cholupdate`
    and downdated by :func:`~synthesis.cholesky.choldowndate` (LINPACK, orthogonal
    rotations).  A downdate that would lose positive definiteness (always the case while
    the window has fewer columns than ``2i(m+l)``) is detected before anything changes;
    the factor is then recomputed from the window's samples and a :class:`RefactorWarning`
    is issued.  Like :func:`~synthesis.fit_predictor`, a (re)factorisation scales every channel to unit
    rms first (by a power of two, exact), so that which pivots of a singular Gram are rounding noise does
    not depend on the units.

In sliding mode both summaries are recomputed from the window's samples once every
``window`` pushed columns (``O(i·window)`` work, ``O(i)`` per sample amortised), so
rounding errors from adding and subtracting cannot accumulate, and at once when the energy of
a row of ``A`` in the window falls below ``1e-4`` of its peak since the last recomputation — the
error those additions and subtractions leave is relative to that peak, which matters when the
signal level drops by orders of magnitude (closed-loop operation after an excitation phase).
"""
from __future__ import annotations

import warnings

import numpy as np
from scipy.linalg import blas

from .exceptions import RefactorWarning

from ._validation import DataError, as_signal, check_count, check_horizon
from .cholesky import DowndateError, choldowndate, cholupdate
from .hankel import hankel_gram, hankel_order
from .predictor import (Predictor, _channel_scales, _predictor_from_factor, _predictor_from_gram, _psd_cholesky,
                        _resolve_rcond)

__all__ = ["RecursivePredictor", "RefactorWarning"]

#: A sliding window is recomputed from its samples as soon as a diagonal entry of ``AAᵀ`` (a row's energy in the
#: window) falls below this fraction of its largest value since the last recomputation: adding and subtracting
#: columns leaves an error of about ``eps`` times that largest value, so the relative error of the entry would
#: exceed ``eps / _DRIFT``.  Measured before: a 1e5 drop of the signal level (closed loop after an excitation
#: phase) left ``Lu`` off by 1.3e-5 (relative) for a whole window, where the batch fit is exact to 1e-13.
_DRIFT = 1e-4


def _syrk_lower(S: np.ndarray, cols: np.ndarray, alpha: float) -> None:
    """``S += alpha · colsᵀ cols`` on the lower triangle of the C-ordered ``S``, in place (BLAS ``dsyrk``).

    ``S.T`` is Fortran-ordered, so BLAS updates it without a copy; its upper triangle is ``S``'s
    lower one.  ``S``'s strict upper triangle is left stale: readers use the lower triangle
    (LAPACK ``dpotrf``/``eigh`` with ``lower``) or symmetrise (:attr:`RecursivePredictor.gram`).
    """
    out = blas.dsyrk(alpha, np.ascontiguousarray(cols).T, beta=1.0, c=S.T, trans=0, lower=0, overwrite_c=1)
    if not np.shares_memory(out, S):  # pragma: no cover - S is always C-contiguous here
        S[...] = out.T


class RecursivePredictor:
    """Subspace predictor maintained under data updates and downdates (§2.3.1).

    Build it with :meth:`from_data`; add samples with :meth:`push`; get the current
    :class:`~synthesis.Predictor` with :meth:`predictor`, which equals
    ``fit_predictor(u_window, y_window, horizon, method="cholesky")`` on the same data
    window (to rounding).

    Attributes
    ----------
    horizon, m, l : int
        Horizon ``i``, number of inputs and outputs.
    window : int or None
        Sliding-window length in columns (``None``: growing window).
    track : str
        ``"gram"`` or ``"factor"`` (see the module docstring).

    Examples
    --------
    A growing window: start from 200 samples at ``i = 4``, push 100 more; the predictor equals the batch fit on
    all 300 samples, and only the last ``2i − 1 = 7`` samples are kept:

    >>> import numpy as np
    >>> from synthesis import fit_predictor
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(400)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:400] + 0.01 * rng.standard_normal(400)
    >>> rp = RecursivePredictor.from_data(u[:200], y[:200], 4)
    >>> rp.n_columns
    193
    >>> rp = rp.push(u[200:300], y[200:300])
    >>> rp.n_columns, rp.n_samples_kept
    (293, 7)
    >>> p, q = rp.predictor(), fit_predictor(u[:300], y[:300], 4)
    >>> err = max(np.abs(p.Lw - q.Lw).max(), np.abs(p.Lu - q.Lu).max())
    >>> p.method, bool(err < 1e-10)
    ('recursive', True)

    A sliding window of 150 columns: the record's last 150 columns are used, then each sample pushed adds a
    column and downdates the oldest.  After 60 more samples the window covers samples 103–259
    (``150 + 2i − 1 = 157`` samples), and the predictor is the batch fit on them:

    >>> sw = RecursivePredictor.from_data(u[:200], y[:200], 4, window=150)
    >>> for k in range(200, 260):
    ...     sw = sw.push(u[k], y[k])
    >>> sw.n_columns, sw.n_samples_kept
    (150, 157)
    >>> p, q = sw.predictor(), fit_predictor(u[103:260], y[103:260], 4)
    >>> err = max(np.abs(p.Lw - q.Lw).max(), np.abs(p.Lu - q.Lu).max())
    >>> q.n_columns, bool(err < 1e-10)
    (150, True)
    """

    def __init__(self, horizon: int, m: int, l: int, *, window=None, track: str = "gram", rcond=None):
        if not (isinstance(track, str) and track in ("gram", "factor")):  # an array had raised numpy's ValueError
            raise DataError(f"unknown track {track!r}; use 'gram' or 'factor'")
        self.horizon = check_horizon(horizon)
        self.m, self.l = check_count(m, "m", 1), check_count(l, "l", 1)
        if window is not None:
            if isinstance(window, bool) or not isinstance(window, (int, np.integer)) or window < 1:
                raise DataError(f"window must be None (growing) or a positive number of columns, got {window!r}")
            window = int(window)
        self.window = window
        self.track = track
        if rcond is not None:
            rcond = _resolve_rcond(rcond, "recursive", 1, 1)  # validate now, not at the first predictor()
        self._rcond = rcond
        i, c = self.horizon, self.m + self.l
        self._N = 2 * i * c
        self._perm = hankel_order(i, self.m, self.l)
        self._j = 0
        self._since_refresh = 0
        self._peak = None  # largest diagonal of AAᵀ since the last recomputation (sliding window only)
        self._buf = np.empty((max(64, 4 * (2 * i + (window or 0))), c))
        self._start = 0
        self._end = 0
        self._S = np.zeros((self._N, self._N))  # Gram AAᵀ, or its upper Cholesky factor R (AAᵀ = RᵀR)
        self._col_index: dict = {}  # gather index of _columns per number of columns
        self._warm: dict = {}  # dominant vectors of R1 and R1⁻¹ from the last predictor() (conditioning check)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_data(cls, u, y, horizon: int, window: int | None = None, *, track: str = "gram", rcond=None):
        """Initialise from a data record (at least ``2i`` samples, i.e. ``j >= 1``).

        Parameters
        ----------
        u : array_like, shape (n,) or (n, m)
        y : array_like, shape (n,) or (n, l)
        horizon : int
            Prediction horizon ``i``.
        window : int, optional
            Sliding-window length in columns ``j``; ``None`` lets the window grow.  If the
            record has more than ``window`` columns only the last ``window`` are used; if it
            has fewer, the window grows until it holds ``window`` columns, then slides.
        track : {"gram", "factor"}
            Summary to maintain (module docstring).
        rcond : float, optional
            Pseudo-inverse tolerance, as in :func:`~synthesis.fit_predictor` (default
            :func:`~synthesis.predictor.default_rcond` for ``"recursive"``).
        """
        u = as_signal(u, "u")
        y = as_signal(y, "y", n=u.shape[0])
        n = u.shape[0]
        i = check_horizon(horizon, n)
        obj = cls(i, u.shape[1], y.shape[1], window=window, track=track, rcond=rcond)
        j = n - 2 * i + 1
        if obj.window is not None and j > obj.window:
            u, y = u[j - obj.window :], y[j - obj.window :]
            j = obj.window
        obj._append(np.hstack([u, y]))
        obj._j = j
        obj._recompute()
        obj._trim()
        return obj

    # ------------------------------------------------------------------ properties
    @property
    def n_columns(self) -> int:
        """Current number of columns ``j`` of ``A`` (prediction problems in the window)."""
        return self._j

    @property
    def n_samples_kept(self) -> int:
        """Number of raw samples stored (``2i − 1`` growing, ``j + 2i − 1`` sliding)."""
        return self._end - self._start

    @property
    def gram(self) -> np.ndarray:
        """Current ``AAᵀ`` in the row order of (2.7) (a copy)."""
        if self.track == "gram":
            return np.tril(self._S) + np.tril(self._S, -1).T  # only the lower triangle is kept current
        return self._S.T @ self._S

    # ------------------------------------------------------------------ operations
    def push(self, u_new, y_new) -> "RecursivePredictor":
        """Add one or more samples (``u_new``: (k,) or (k, m); ``y_new``: (k,) or (k, l)).

        A single sample of a MIMO signal may be given as a 1-D array of length ``m`` /
        ``l``.  Each sample appends one column to ``A`` (``O(i²)`` work); in sliding mode the
        oldest columns beyond ``window`` are downdated.  Returns ``self``.
        """
        u_new = self._as_chunk(u_new, "u_new", self.m)
        y_new = self._as_chunk(y_new, "y_new", self.l)
        if u_new.shape[0] != y_new.shape[0]:
            raise DataError(
                f"u_new has {u_new.shape[0]} samples but y_new has {y_new.shape[0]}; push the same number of each"
            )
        return self._push_samples(np.hstack([u_new, y_new]))

    def _push_samples(self, z: np.ndarray) -> "RecursivePredictor":
        """:meth:`push` of already validated samples ``z = [u y]`` (finite floats, shape (k, m + l))."""
        i = self.horizon
        seg = np.concatenate([self._data()[-(2 * i - 1) :], z])
        # the first 2i − 1 samples after construction complete no column of A
        k = max(0, seg.shape[0] - 2 * i + 1)
        self._append(z)
        self._j += k
        drop = 0 if self.window is None else max(0, self._j - self.window)
        refresh = self.window is not None and (k + drop > self.window or self._since_refresh + k >= self.window)
        if refresh:
            self._j -= drop
            self._trim()
            self._recompute()
            return self
        new_cols = self._columns(seg)
        old_cols = self._columns(self._data()[: drop + 2 * i - 1]) if drop else None
        self._j -= drop
        self._since_refresh += k
        if self.track == "gram":
            _syrk_lower(self._S, new_cols, 1.0)
            if drop:
                _syrk_lower(self._S, old_cols, -1.0)
        else:
            for a in new_cols:
                cholupdate(self._S, a, lower=False, overwrite=True)
            if drop:
                try:
                    for a in old_cols:
                        choldowndate(self._S, a, lower=False, overwrite=True)
                except DowndateError as exc:
                    warnings.warn(
                        f"Cholesky downdate failed ({exc}); refactoring from the {self._j}-column window",
                        RefactorWarning,
                        stacklevel=3,  # the caller of push()
                    )
                    self._trim()
                    self._recompute()
                    return self
        self._trim()
        if self.window is not None and self._drifted(bool(drop)):
            self._recompute()
        return self

    def _drifted(self, downdated: bool) -> bool:
        """Whether a row's energy fell so far below its peak since the last recomputation (:data:`_DRIFT`) that
        the rounding of the updates and downdates would show; keeps the peak up to date."""
        diag = self._S.diagonal() if self.track == "gram" else np.einsum("ij,ij->j", self._S, self._S)  # a view
        if self._peak is None:
            self._peak = diag.copy()
            return False
        np.maximum(self._peak, diag, out=self._peak)
        return downdated and bool((diag < _DRIFT * self._peak).any())

    def predictor(self) -> Predictor:
        """Current predictor ``(Lw, Lu)`` (``O(i³)``), method ``"recursive"``.

        Equal (to rounding) to ``fit_predictor(..., method="cholesky")`` on the current data
        window; a rank-deficient window gives the minimum-norm predictor with its numerical
        rank, and a :class:`~synthesis.PersistenceWarning`.

        Raises
        ------
        DataError
            Fewer than ``2i`` samples pushed since construction (no column of ``A``, ``j = 0``).
        """
        i, m, l, j = self.horizon, self.m, self.l, self._j
        if j < 1:
            short = 2 * i - self.n_samples_kept
            raise DataError(
                f"the recursive predictor holds {self.n_samples_kept} sample(s), no complete column of the data "
                f"matrix (horizon i={i} needs 2i = {2 * i}): push at least {short} more sample(s) of u and y first")
        tol = _resolve_rcond(self._rcond, "recursive", i * (2 * m + l), j)
        if self.track == "gram":
            return _predictor_from_gram(self._S, i, m, l, j, tol, "recursive", stacklevel=3, warm=self._warm)
        # a snapshot: the predictor's lazy fields (singular values, control_pvalue) keep blocks of the factor, which
        # later pushes update in place (cholupdate); measured 12 µs at i = 64 (256²), against ~1 ms for the predictor
        R = np.array(self._S.T)
        return _predictor_from_factor(R, i, m, l, j, tol, "recursive", stacklevel=3, warm=self._warm)

    # ------------------------------------------------------------------ internals
    def _as_chunk(self, x, name: str, width: int) -> np.ndarray:
        arr = np.asarray(x) if not isinstance(x, np.ndarray) else x  # as_signal checks the type (a str is no sample)
        if np.ndim(arr) == 0:
            arr = np.reshape(arr, (1,))
        if np.ndim(arr) == 1 and width > 1 and np.size(arr) == width:
            arr = np.reshape(arr, (1, width))  # one MIMO sample
        return as_signal(arr, name, width=width, record=False)

    def _data(self) -> np.ndarray:
        return self._buf[self._start : self._end]

    def _append(self, z: np.ndarray) -> None:
        k = z.shape[0]
        if self._end + k > self._buf.shape[0]:
            kept = self._data()
            cap = max(self._buf.shape[0], 2 * (kept.shape[0] + k))
            buf = np.empty((cap, self._buf.shape[1])) if cap > self._buf.shape[0] else self._buf
            buf[: kept.shape[0]] = kept.copy()
            self._buf, self._start, self._end = buf, 0, kept.shape[0]
        self._buf[self._end : self._end + k] = z
        self._end += k

    def _trim(self) -> None:
        keep = 2 * self.horizon - 1 + (self._j if self.window is not None else 0)
        self._start = max(self._start, self._end - keep)

    def _columns(self, seg: np.ndarray) -> np.ndarray:
        """Columns of ``A`` (as rows, shape (k, N)) for every 2i-sample window of ``seg``.

        Window ``t`` of the C-ordered ``seg`` is its flat slice ``[t·c, t·c + N)`` in the
        interleaved order of :func:`~synthesis.hankel.hankel_order`, so the columns are one gather
        ``seg.flat[t·c + perm]`` (index cached per ``k``).
        """
        c = self.m + self.l
        k = seg.shape[0] - 2 * self.horizon + 1
        idx = self._col_index.get(k)
        if idx is None:
            if len(self._col_index) > 8:
                self._col_index.clear()
            idx = self._col_index[k] = (np.arange(k) * c)[:, None] + self._perm[None, :]
        return np.ascontiguousarray(seg).reshape(-1)[idx]

    def _recompute(self) -> None:
        """Recompute the summary from the stored window (sliding mode or initialisation)."""
        data = self._data()
        m = self.m
        G = hankel_gram(data[:, :m], data[:, m:], self.horizon)
        # factor track: store the upper factor R = Lᵀ (G = Rᵀ R) so that the rotations of
        # cholupdate/choldowndate sweep contiguous rows
        self._S = G if self.track == "gram" else self._factor(G)
        self._since_refresh = 0
        self._peak = np.diagonal(G).copy() if self.window is not None else None

    def _factor(self, G: np.ndarray) -> np.ndarray:
        """Upper ``R`` with ``Rᵀ R = G``, factored with every channel scaled to unit rms (:func:`_channel_scales`).

        The factorisation of a semidefinite ``G`` (noise-free data) decides which pivots are rounding noise
        relative to the largest entry, which depends on the units: factored unscaled, a window with channels in
        units ``1e±3`` gave an ``Lu`` off by up to 35 % against :func:`~synthesis.fit_predictor` on the same window
        (which scales).  ``G = D G_s D`` with ``G_s = L_s L_sᵀ`` gives the factor ``D L_s`` (powers of two: exact);
        measured cost 35–320 µs more per recomputation (``i`` = 8–64), against 160–1500 µs for ``hankel_gram``.
        """
        d = _channel_scales(np.diagonal(G), self.horizon, self.m, self.l, max(self._j, 1))
        if d is None:
            return np.ascontiguousarray(_psd_cholesky(G).T)
        L = _psd_cholesky(G / np.outer(d, d))
        return np.ascontiguousarray((d[:, None] * L).T)

    def __repr__(self) -> str:
        win = "growing" if self.window is None else f"window={self.window}"
        return (
            f"RecursivePredictor(horizon={self.horizon}, m={self.m}, l={self.l}, {win}, "
            f"track={self.track!r}, n_columns={self._j})"
        )
