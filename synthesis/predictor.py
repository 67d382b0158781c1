"""Least-squares subspace predictor (thesis §2.1–2.3).

The predictor ``(Lw, Lu)`` solves (2.5),

    min ‖Y_f − [Lw Lu] [W_p; U_f]‖_F,

so that future outputs are predicted by (2.6), ``ŷ = Lw w_p + Lu u_f`` with
``w_p = [u_{k-i}; …; u_{k-1}; y_{k-i}; …; y_{k-1}]`` (3.13).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy.linalg import lapack
from scipy.special import fdtrc

from .exceptions import PersistenceWarning

from ._lazy import _Deferred, _LazyField
from ._validation import (DataError, as_real_array, as_signal, check_count, check_horizon, check_inputs_move,
                          check_nonnegative, check_output_moves, check_sample_time)
from .fingerprint import RecordFingerprint, record_fingerprint
from .hankel import hankel_gram
from ._repr import result

__all__ = ["Predictor", "fit_predictor", "block_hankel", "PersistenceWarning", "default_rcond"]


@result
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
        Singular values of the regressor factor ``[R11 0; R21 R22]`` (§2.2), descending.  On the
        fast (well-conditioned) Cholesky path they are not needed for the predictor and are
        computed on first access (an SVD of the ``i(2m+l)``-square factor), then cached.
    rank : int
        Numerical rank ``q`` kept in the pseudo-inverse.  The Gram methods (``"cholesky"``, ``"recursive"``)
        decide it on the regressor with each ``u`` and ``y`` channel scaled to unit rms by a power of two
        (exact), so that it does not depend on the signals' units; the predictor is then the minimum-norm one
        of rank ``q`` for the data themselves.
    method : str
        How it was computed (``"cholesky"``, ``"qr"``, ``"lstsq"``, ``"recursive"``).
    input_rank : int or None
        Numerical rank of the input part ``[U_p; U_f]`` (full when it equals ``2mi``, i.e. the
        input is persistently exciting of order ``2mi``); ``None`` when not computed.
    rcond : float or None
        Relative tolerance that decided ``rank`` (singular values ``<= rcond * σ₁`` discarded; for the Gram
        methods those of the channel-scaled regressor, see ``rank``).
    solver : str or None
        How ``[Lw Lu]`` was obtained from the factor ``R``: ``"triangular"`` (``R3 R1⁻¹`` by
        triangular solves, taken when ``R1`` is well conditioned: a power-iteration estimate of
        ``κ₂(R1)`` below ``0.8/rcond``) or ``"spectral"`` (the rank-revealing pseudo-inverse of
        §2.2); ``None`` for ``"lstsq"``.
    dt : float or None
        Sample time of the data the predictor was fitted on, when it was given
        (``fit_predictor(..., dt=...)``).  The designs then check the weights' sample time
        against it (:func:`synthesis.hinf_design`); ``None``: unknown (the arrays carry none).
    fingerprint : RecordFingerprint or None
        The record it was fitted on, as hashes (:func:`synthesis.record_fingerprint`; :func:`fit_predictor` sets
        it): a test on "held-out" data can check that they are (:func:`unfalsify.check_premise`).  Not compared
        by ``==``.  ``None``: unknown.
    control_pvalue : float or None
        Whether the data show the future inputs acting on the predicted outputs at all: the p-value of the
        F-test of ``L_u = 0`` (the nested regressions of ``Y_f`` on ``W_p`` and on ``[W_p; U_f]``, each output row
        of the horizon, Bonferroni over the ``i·l`` rows; 1 when ``U_f`` explains less than ``rcond²`` of a row's
        energy, 0 when the larger regression is exact).  Near 1 when the horizon is not longer than the plant's
        delay (``i = 1`` on a strictly proper plant): ``L_u`` is then noise, and the designs warn
        (:class:`~synthesis.HorizonWarning`).  A rank-deficient regressor (and ``"lstsq"``, whose rank the SVD
        decides) is tested in the space it spans: ``W_p``'s rows and what ``U_f`` adds beyond them, directions
        below ``rcond·σ₁`` left out, the numerator's degrees of freedom the rank ``U_f`` adds and the residual's
        ``j`` minus the rank spanned.  Computed on first access; ``None`` where no test is meaningful: fewer
        columns ``j`` than twice the regressor's rank (the test could not tell "no effect" from "too few data"),
        ``U_f`` adding no direction beyond ``W_p`` (an input that is not persistently exciting, which a
        :class:`~synthesis.PersistenceWarning` names), or a predictor pickled before the field existed.

    Examples
    --------
    Made by :func:`fit_predictor` (or :meth:`RecursivePredictor.predictor <synthesis.RecursivePredictor.predictor>`).
    The FIR plant ``y_k = u_{k-1} + 0.5 u_{k-2}`` at horizon ``i = 4``, one input and one output:

    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(500)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:500] + 0.01 * rng.standard_normal(500)
    >>> pred = fit_predictor(u, y, 4, dt=0.1)
    >>> pred.horizon, pred.m, pred.l, pred.n_columns, pred.dt
    (4, 1, 1, 493, 0.1)
    >>> pred.Lw.shape, pred.Lu.shape, pred.rank, pred.full_rank, pred.persistently_exciting
    ((4, 8), (4, 4), 12, True, True)
    >>> bool(pred.control_pvalue < 0.01)  # the data show u acting on y over the horizon
    True

    ``Lu`` holds the plant's Markov parameters 0, 1, 0.5, block lower triangular (2.10)
    (``+ 0.0`` turns a rounded ``-0.`` into ``0.``):

    >>> np.round(pred.Lu, 1) + 0.0
    array([[0. , 0. , 0. , 0. ],
           [1. , 0. , 0. , 0. ],
           [0.5, 1. , 0. , 0. ],
           [0. , 0.5, 1. , 0. ]])

    :meth:`predict` maps the past ``i`` samples (stacked by :meth:`past_vector`) and ``i`` planned inputs to the
    next ``i`` outputs (2.6); on a fresh noise-free record of the same plant:

    >>> u_new = rng.standard_normal(20)
    >>> y_new = np.convolve(u_new, [0.0, 1.0, 0.5])[:20]
    >>> w_p = pred.past_vector(u_new[:10], y_new[:10])  # samples 6–9 of u, then of y
    >>> y_hat = pred.predict(w_p, u_new[10:14])          # outputs 10–13
    >>> w_p.shape, y_hat.shape, bool(np.abs(y_hat[:, 0] - y_new[10:14]).max() < 0.01)
    ((8,), (4, 1), True)
    """

    Lw: np.ndarray
    Lu: np.ndarray
    horizon: int
    m: int
    l: int
    n_columns: int
    singular_values: np.ndarray = _LazyField()
    rank: int
    method: str
    input_rank: int | None = None
    rcond: float | None = None
    solver: str | None = None
    dt: float | None = None
    fingerprint: RecordFingerprint | None = field(default=None, compare=False)
    control_pvalue: float | None = _LazyField(default=None)

    @property
    def n_regressors(self) -> int:
        """Number of regressor rows, ``i(2m + l)``."""
        return self.horizon * (2 * self.m + self.l)

    @property
    def persistently_exciting(self) -> bool | None:
        """True when ``[U_p; U_f]`` had full row rank ``2mi`` (``None`` if unknown)."""
        return None if self.input_rank is None else self.input_rank == 2 * self.m * self.horizon

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
        # as_real_array: a string had raised numpy's ValueError, a complex vector TypeError
        w_p = as_real_array(w_p, "w_p").reshape(-1)
        u_f = as_real_array(u_f, "u_f").reshape(-1)
        if w_p.size != self.Lw.shape[1]:
            raise DataError(f"w_p must have {self.Lw.shape[1]} entries, got {w_p.size}")
        if u_f.size != self.Lu.shape[1]:
            raise DataError(f"u_f must have {self.Lu.shape[1]} entries, got {u_f.size}")
        if not (np.all(np.isfinite(w_p)) and np.all(np.isfinite(u_f))):
            raise DataError("w_p and u_f must be finite (no NaN/inf)")
        return (self.Lw @ w_p + self.Lu @ u_f).reshape(self.horizon, self.l)

    def past_vector(self, u_past, y_past) -> np.ndarray:
        """Stack the last ``i`` samples of ``u`` and ``y`` into ``w_p`` (3.13).

        ``u_past`` and ``y_past`` must end at the same sample, so they must have the same length: the
        last ``i`` rows of records of different lengths would pair inputs and outputs of different times.
        """
        i = self.horizon
        u_past = as_signal(u_past, "u_past", width=self.m, record=False)
        y_past = as_signal(y_past, "y_past", width=self.l, record=False)
        if u_past.shape[0] != y_past.shape[0]:
            raise DataError(
                f"u_past has {u_past.shape[0]} samples but y_past has {y_past.shape[0]}; their last i={i} rows would "
                "come from different times: pass the same samples of both (e.g. u[:k] and y[:k])")
        if u_past.shape[0] < i or y_past.shape[0] < i:
            raise DataError(f"need at least i={i} past samples of u and y")
        return np.concatenate([u_past[-i:].reshape(-1), y_past[-i:].reshape(-1)])


def block_hankel(x: np.ndarray, rows: int, cols: int, start: int = 0) -> np.ndarray:
    """Block Hankel matrix with ``rows`` block rows and ``cols`` columns, (2.1)–(2.4).

    ``x`` has shape ``(n, k)`` (or ``(n,)``); block row ``r`` holds ``x[start + r : start + r + cols].T``.
    Returns an array of shape ``(rows*k, cols)`` (a copy).

    Raises
    ------
    DataError
        NaN/inf or badly shaped ``x``, ``rows`` or ``cols`` not positive integers, ``start``
        negative, or too few samples.

    Examples
    --------
    One signal: each row is the one above it shifted by one sample.

    >>> import numpy as np
    >>> block_hankel(np.arange(6.0), 3, 4)
    array([[0., 1., 2., 3.],
           [1., 2., 3., 4.],
           [2., 3., 4., 5.]])

    Two channels: a block row holds both channels of one sample; ``start=1`` skips the first sample.

    >>> x = np.column_stack([np.arange(5.0), 10 + np.arange(5.0)])
    >>> block_hankel(x, 2, 3, start=1)
    array([[ 1.,  2.,  3.],
           [11., 12., 13.],
           [ 2.,  3.,  4.],
           [12., 13., 14.]])
    """
    x = as_signal(x, "x")
    rows, cols, start = check_count(rows, "rows", 1), check_count(cols, "cols", 1), check_count(start, "start", 0)
    k = x.shape[1]
    seg = x[start : start + rows + cols - 1]
    if seg.shape[0] < rows + cols - 1:
        raise DataError(f"x has {seg.shape[0]} sample(s) from start = {start} but a block Hankel matrix of {rows} "
                        f"rows and {cols} columns needs rows + cols − 1 = {rows + cols - 1}: pass a longer x, or "
                        "fewer rows or columns")
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


_EPS = np.finfo(float).eps
#: methods that factor the Gram matrix AAᵀ (and therefore square the singular values)
_GRAM_METHODS = ("cholesky", "recursive")
#: every method a predictor can be computed by (:attr:`Predictor.method`)
_METHODS = ("cholesky", "qr", "lstsq", "recursive")


def default_rcond(method: str, n_regressors: int, n_columns: int) -> float:
    """Default relative tolerance of the pseudo-inverse of §2.2 (singular values ``<= rcond·σ₁`` dropped).

    ``"qr"`` and ``"lstsq"`` work on the data itself and resolve singular values down to
    ``max(i(2m+l), j)·eps·σ₁``.  ``"cholesky"`` and ``"recursive"`` work on the Gram matrix
    ``AAᵀ``, whose rounding errors (``≈ eps·‖AAᵀ‖``) put a floor of ``≈ √eps·σ₁`` under the
    singular values of its factor; their default is ``10·√(max(i(2m+l), j)·eps)`` (≈ 1e-6 for
    the thesis's sizes), i.e. a regressor whose condition number exceeds ~10⁶ -- once each
    ``u`` and ``y`` channel is scaled to unit rms, so that the units do not matter -- is treated
    as rank deficient.  Data that are that ill-conditioned (noise-free outputs of a low-order
    plant) have a gap of many decades there, so the decision is robust.

    Parameters
    ----------
    method : {"cholesky", "recursive", "qr", "lstsq"}
        How the predictor is computed.
    n_regressors, n_columns : int
        ``i(2m+l)`` and ``j``, each ≥ 1.

    Raises
    ------
    DataError
        An unknown ``method`` or a count that is not an integer ≥ 1 (they had given a tolerance all the same:
        ``default_rcond("bogus", -1, 0)`` was 0).

    Examples
    --------
    ``i = 10``, one input and one output (``i(2m+l) = 30`` regressors), ``j = 1000`` columns:

    >>> import numpy as np
    >>> bool(default_rcond("qr", 30, 1000) == 1000 * np.finfo(float).eps)
    True
    >>> round(default_rcond("cholesky", 30, 1000), 8)
    4.71e-06
    """
    if method not in _METHODS:
        raise DataError(f"unknown method {method!r}; use one of {', '.join(map(repr, _METHODS))}")
    base = max(check_count(n_regressors, "n_regressors", 1), check_count(n_columns, "n_columns", 1)) * _EPS
    if method in _GRAM_METHODS:
        return 10.0 * float(np.sqrt(base))
    return float(base)


def _resolve_rcond(rcond, method: str, n_reg: int, j: int) -> float:
    if rcond is None:
        return default_rcond(method, n_reg, j)
    r = check_nonnegative(rcond, "rcond")  # numbers only: float() had parsed the string "0.5"
    if not r < 1.0:
        raise DataError(f"rcond must lie in [0, 1), got {rcond!r}")
    return r


def _rank(s: np.ndarray, rcond: float) -> int:
    if s.size == 0 or not s[0] > 0:
        return 0
    return int(np.count_nonzero(s > rcond * s[0]))


def _square_factor(R: np.ndarray) -> np.ndarray:
    """Pad a wide QR factor (fewer columns j than rows) with zero columns to a square one."""
    N = R.shape[0]
    if R.shape[1] < N:
        R = np.hstack([R, np.zeros((N, N - R.shape[1]))])
    return R


def _solve_from_r(R: np.ndarray, n_reg: int, rcond: float, *, squared: bool = False, scale=None):
    """Given lower-triangular ``L`` with ``A = L Qᵀ`` (2.7), return ``[Lw Lu]``, singular values, rank.

    ``[Lw Lu] = [R31 R32] V_q Σ_q⁻¹ U_qᵀ`` with the SVD ``R1 = [R11 0; R21 R22] = U Σ Vᵀ`` (§2.2).

    With ``squared=True`` (the Gram-based methods) ``U`` and ``Σ²`` are taken from the symmetric
    eigendecomposition of ``R1 R1ᵀ`` and ``R3 V_q Σ_q⁻¹ = (R3 R1ᵀ) U_q Σ_q⁻²`` — an exact identity,
    about 3× cheaper than the SVD, and no less accurate here: a factor of the rounded ``AAᵀ``
    only carries singular values down to ``≈ √eps·σ₁`` either way (see :func:`default_rcond`).

    ``scale``: ``R`` is the factor of the data divided row-wise by ``scale`` (:func:`_channel_scales`); the rank
    ``q`` is decided on it (the tolerance is then independent of the units) and ``[Lw Lu]`` is returned for the
    data themselves, still the minimum-norm one: with ``D = diag(scale)`` the rank-``q`` regressor is
    ``D_r U_q Σ_q V_qᵀ Qᵀ``, whose pseudo-inverse gives ``D_f R3 V_q Σ_q⁻¹ (D_r U_q)⁺`` (``= D_f L' D_r⁻¹`` when
    ``q`` is full).
    """
    R1 = R[:n_reg, :n_reg]
    R3 = R[n_reg:, :n_reg]
    if squared:
        lam, U = np.linalg.eigh(R1 @ R1.T)
        lam, U = np.maximum(lam[::-1], 0.0), U[:, ::-1]
        s = np.sqrt(lam)
        q = _rank(s, rcond)
        K = (R3 @ R1.T) @ U[:, :q] / lam[:q]
    else:
        U, s, Vt = np.linalg.svd(R1)
        q = _rank(s, rcond)
        K = (R3 @ Vt[:q].T) / s[:q]
    if scale is None:
        return K @ U[:, :q].T, s, q
    Qm, Rm = np.linalg.qr(scale[:n_reg, None] * U[:, :q])  # (D_r U_q)⁺ = Rm⁻¹ Qmᵀ: full column rank q
    K = _trsolve(np.asfortranarray(Rm.T), np.asfortranarray(K.T), trans=0).T if q else K  # K Rm⁻¹
    return scale[n_reg:, None] * (K @ Qm.T), s, q


def _input_rows(i: int, m: int, l: int) -> np.ndarray:
    """Rows of ``A = [U_p; Y_p; U_f; Y_f]`` holding the input part ``[U_p; U_f]``."""
    return np.r_[0 : i * m, i * (m + l) : i * (2 * m + l)]


def _input_rank_from_factor(R: np.ndarray, i: int, m: int, l: int, rcond: float, *, squared: bool = False) -> int:
    """Rank of ``[U_p; U_f]``: its rows of ``A = R Qᵀ`` are the selected rows of ``R``.

    Those rows vanish beyond column ``i(2m+l)`` (``R`` is lower triangular).  ``squared=True``
    uses the eigenvalues of their Gram block (cheaper; same √eps floor as the Gram methods).
    """
    Rin = R[_input_rows(i, m, l), : i * (2 * m + l)]
    if squared:
        s = np.sqrt(np.maximum(np.linalg.eigvalsh(Rin @ Rin.T)[::-1], 0.0))
    else:
        s = np.linalg.svd(Rin, compute_uv=False)
    return _rank(s, rcond)


def _factor_singular_values(R1: np.ndarray) -> np.ndarray:
    """Singular values of the regressor factor ``R1`` (deferred on the triangular path)."""
    return np.linalg.svd(R1, compute_uv=False)


#: Margin of the triangular path: it is taken when ``κ̂₂(R1) · rcond < 1/_CERT_MARGIN``, ``κ̂₂`` being
#: the power-iteration estimate (a lower bound of ``κ₂``: worst estimate/true 0.92 over the 300
#: warm-started updates of the §6.3 benchmark, 0.95 cold); it covers a shortfall of up to 20 %.
#: (With 2 instead, the first §6.3 windows, κ₂·rcond ≈ 0.4–0.5, fell back to the 4× slower route.)
_CERT_MARGIN = 1.25
#: Products with ``S = R1 R1ᵀ`` and with ``S⁻¹`` in :func:`_eig_max_estimate` (block power iteration):
#: from 4 pseudo-random start vectors, and when warm started from the previous dominant vectors
#: (recursive predictor, §2.3.1: the window changes little between updates).  ``k`` products give
#: the Rayleigh quotient of ``S^(2k−1)`` (ratio ``(λ₂/λ₁)^(2k−2)`` from a random start), as the
#: ``k − 1`` steps on ``R1ᵀR1`` plus one half step of the route before (``(3, 5)`` / ``(1, 3)`` steps).
_POWER_PRODUCTS = {"cold": (4, 6), "warm": (2, 4)}
_START_VECTORS: dict = {}


def _start_block(n: int) -> np.ndarray:
    V = _START_VECTORS.get(n)
    if V is None:
        V = _START_VECTORS.setdefault(n, np.random.default_rng(12).standard_normal((n, 4)))
    return V


def _eig_max_estimate(apply, products: int, V: np.ndarray):
    """``λ_max(S)`` of a symmetric positive (semi)definite ``S`` from below, by block power iteration.

    ``apply(V) = S V``.  ``products`` (≥ 1) products with ``S``; the estimate is the largest
    Rayleigh quotient ``vᵀSv / vᵀv`` of the columns before the last product, which never exceeds
    ``λ_max``, and is within a few per cent of it after a handful of products from a random start
    unless the start is (improbably) deficient in the dominant direction.  Columns are normalised
    after every product (no overflow for any finite ``S``).  Returns the estimate and the column
    with the largest quotient (a warm start for the next call); ``nan, None`` if an iterate is not
    finite.  Deterministic: the random part of the start is seeded and cached per size.
    """
    with np.errstate(all="ignore"):  # a zero or non-finite iterate only makes the estimate NaN
        V = V / np.sqrt(np.einsum("ij,ij->j", V, V))
        for _ in range(products - 1):
            W = apply(V)
            V = W / np.sqrt(np.einsum("ij,ij->j", W, W))
        q = np.einsum("ij,ij->j", V, apply(V))
    if not np.all(np.isfinite(q)):
        return float("nan"), None
    k = int(np.argmax(q))
    return float(q[k]), V[:, k].copy()


def _trsolve(R1, B, trans: int = 0):
    """``R1⁻¹ B`` (``trans=1``: ``R1⁻ᵀ B``) for lower-triangular ``R1`` (LAPACK ``dtrtrs``); NaN if singular."""
    X, info = lapack.dtrtrs(R1, B, lower=1, trans=trans)
    return X if info == 0 else np.full(np.shape(B), np.nan)


def _gram_inverse_apply(F: np.ndarray, lower: bool):
    """``V ↦ S⁻¹ V``, ``S = F Fᵀ`` (``lower``) or ``FᵀF``, by two triangular solves (LAPACK ``dpotrs``); NaN if singular."""
    def apply(V):
        X, info = lapack.dpotrs(F, V, lower=int(lower))
        return X if info == 0 else np.full(np.shape(V), np.nan)
    return apply


def _well_conditioned(R1: np.ndarray, rcond: float, warm: dict | None = None, *, lower: bool = True) -> bool:
    """True if the lower-triangular ``R1`` is well conditioned relative to ``rcond``.

    ``R1 = [R11 0; R21 R22]`` is lower triangular (a Cholesky or QR factor, (2.7)); with
    ``lower=False`` the argument is ``R1ᵀ`` (upper triangular, e.g. LAPACK's upper Cholesky factor
    of ``G11``).  Its condition
    number ``κ₂(R1) = σ₁/σ_min = √(λ_max(S) λ_max(S⁻¹))``, ``S = R1 R1ᵀ``, is estimated by block
    power iteration on ``S`` and on ``S⁻¹`` (:func:`_eig_max_estimate`; ``S`` applied as ``R1 (R1ᵀ V)``,
    ``S⁻¹`` by two triangular solves in one LAPACK call, ``O(n²)`` per vector, never formed; a lower bound within a
    few per cent on the §6.3 data; ``warm``, a dict the caller keeps between calls, carries the
    dominant vectors over so that fewer products are needed).
    When ``κ₂ · rcond`` is below ``1/1.25`` no singular value falls below ``rcond·σ₁``: the
    rank-revealing pseudo-inverse of §2.2 keeps all of them (``q = i(2m+l)``) and equals
    ``R3 R1⁻¹``; its input part ``[U_p; U_f]`` (a subset of rows, whose singular values
    interlace) has full rank ``2mi`` by the same bound; and two triangular solves replace the
    eigendecomposition.  An underestimate can only matter within a factor 1.25 of the tolerance,
    where keeping or dropping the smallest singular value are both defensible (both are computed
    accurately there: ``κ₂² eps ≪ 1``).
    """
    n_reg = R1.shape[0]
    d = np.abs(np.diagonal(R1))
    if not (d.size and d.min() > 0 and np.all(np.isfinite(d))):
        return False
    limit = 1.0 / (rcond * _CERT_MARGIN) if rcond > 0 else np.inf
    V0 = _start_block(n_reg)
    prev = warm.get(n_reg) if warm is not None else None
    products = _POWER_PRODUCTS["cold" if prev is None else "warm"]
    V1 = V0 if prev is None else np.column_stack([prev[0], V0[:, 1:]])
    V2 = V0 if prev is None else np.column_stack([prev[1], V0[:, 1:]])
    apply_s = (lambda V: R1 @ (R1.T @ V)) if lower else (lambda V: R1.T @ (R1 @ V))
    l1, v1 = _eig_max_estimate(apply_s, products[0], V1)
    li, vi = _eig_max_estimate(_gram_inverse_apply(R1, lower), products[1], V2)
    if warm is not None and v1 is not None and vi is not None:
        warm[n_reg] = (v1, vi)
    with np.errstate(all="ignore"):
        kappa = np.sqrt(l1 * li)
    return bool(np.isfinite(kappa) and kappa < limit)


def _channel_scales(diag: np.ndarray, i: int, m: int, l: int, j: int) -> np.ndarray | None:
    """Power-of-two scale of every row of ``A = [U_p; Y_p; U_f; Y_f]`` from the diagonal of ``AAᵀ``, or None.

    Each channel's rows get ``2^round(log2(rms))``, ``rms`` the channel's root mean square over its rows of
    ``A`` (its ``2i`` lags, ``j`` columns), an all-zero channel 1; ``None`` when every scale is 1 (channels within a
    factor √2 of unit rms).  The Gram methods decide the rank against a tolerance relative to the
    largest singular value (:func:`default_rcond`, ``≈ √eps``), which is not invariant under a change of units
    of one channel: measured, a ±1 input with its output in units ``1e-4`` (or ``1e5``) times the natural ones
    gave regressor rank 13 of 18 and an ``Lu`` off by 100 % (``γ_min`` of the §5.4 example off by 61 % at
    ``1e5``), where the least-squares predictor itself only changes units.  Powers of two scale exactly.
    """
    c = m + l
    ch = np.concatenate([np.tile(np.arange(m), i), m + np.tile(np.arange(l), i)] * 2)
    ms = np.bincount(ch, weights=diag, minlength=c) / (np.bincount(ch, minlength=c) * j)
    if not np.all(np.isfinite(ms)):  # pragma: no cover - the Gram route refuses data whose squares overflow
        return None
    units = _power_of_two_rms(ms)
    return units[ch] if np.any(units != 1.0) else None


def _power_of_two_rms(mean_square: np.ndarray) -> np.ndarray:
    """``2^round(log2(rms))`` for each mean square (1 where it is 0): a unit that scales a channel to about unit rms
    exactly (:func:`_channel_scales`, and ``subspace_id``'s channels)."""
    ms = np.asarray(mean_square, float)
    return np.ldexp(1.0, np.round(0.5 * np.log2(np.where(ms > 0, ms, 1.0))).astype(int))


def _unscaled(L: np.ndarray, d) -> np.ndarray:
    """``[Lw Lu]`` of the data from that of the data divided row-wise by ``d`` (:func:`_channel_scales`).

    ``y_f / d_f = L' (r / d_r)`` gives ``L = diag(d_f) L' diag(d_r)⁻¹`` (exact: powers of two).
    """
    if d is None:
        return L
    n_reg = L.shape[1]
    return d[n_reg:, None] * L / d[None, :n_reg]


def _triangular_predictor(L, R1, i, m, l, j, rcond, method, control=None) -> Predictor:
    """``L = [Lw Lu]`` (the fields are copied by the constructor); ``R1`` or its transpose, for the singular values;
    ``control``: the recipe of :attr:`Predictor.control_pvalue` (:func:`_control_test`)."""
    n_reg = i * (2 * m + l)
    Lw, Lu = L[:, : i * (m + l)], L[:, i * (m + l):]
    sv = _Deferred(_factor_singular_values, R1)
    return Predictor(Lw, Lu, i, m, l, j, sv, n_reg, method, 2 * m * i, float(rcond), "triangular",
                     control_pvalue=control)


def _control_test(Z: np.ndarray, energy, R33, i, m, l, j, rcond):
    """Recipe of :attr:`Predictor.control_pvalue`, or ``None`` with fewer residual degrees of freedom than regressors.

    ``Z = R1⁻ᵀ G13`` (``= R3ᵀ``: one column per output row of the horizon); either ``energy``, the rows' energies
    (the diagonal of ``G33``; the residuals are then ``energy − ‖Z‖²``), or ``R33``, the factor's last block (the
    residuals are its rows' energies).  Nothing is computed until the field is read (a design reads it, and so does
    every update of the adaptive loop of §5.3).
    """
    dof = j - i * (2 * m + l)
    if dof < i * (2 * m + l):
        # fewer than twice as many columns as regressors: the test could not tell "no effect" from "too few data"
        # (a fit on 61 columns for 60 regressors gave p = 0.45 at i = 20, where L_u is well away from 0)
        return None
    energy = None if energy is None else np.array(energy, float)
    return _Deferred(_control_pvalue, Z, energy, R33, i * (m + l), i * m, dof, rcond)


def _control_pvalue(Z: np.ndarray, energy, R33, n_past: int, n_inputs: int, dof: int, rcond: float) -> float:
    """The Bonferroni p-value of the F-tests of ``L_u = 0``, one per output row (:attr:`Predictor.control_pvalue`).

    ``R1`` is triangular with the ``W_p`` rows first, so the rows of ``Z`` past ``n_past`` hold what ``U_f`` explains
    beyond ``W_p`` (the nested regressions' difference).
    """
    gain = np.einsum("ij,ij->j", Z[n_past:], Z[n_past:])
    explained = np.einsum("ij,ij->j", Z[:n_past], Z[:n_past]) + gain
    if R33 is None:
        rss = energy - explained
    else:
        rss = np.einsum("ij,ij->i", R33, R33)
        energy = rss + explained
    return _bonferroni_f(gain, rss, energy, n_inputs, dof, rcond)


def _bonferroni_f(gain, rss, energy, n_num: int, dof: int, rcond: float) -> float:
    """Bonferroni p-value of one F-test per output row: ``gain`` (the nested regressions' difference, ``n_num``
    degrees of freedom) against ``rss`` (the larger regression's residual, ``dof``).

    Energies below ``rcond²`` of the row's are rounding (the Gram methods' floor, :func:`default_rcond`): no gain
    gives 1, no residual 0 (noise-free data: ``U_f`` explains what ``W_p`` leaves, to rounding).  Every row has the
    same degrees of freedom, so the least p-value is the F distribution's tail at the largest statistic: one
    evaluation, not one a row (8 µs less a read at ``i = 64``, which every adaptive update makes).
    """
    tiny = rcond ** 2 * energy
    moves = gain > tiny
    exact = moves & (rss <= tiny)
    if np.any(exact):
        return 0.0
    if not np.any(moves):
        return 1.0
    stat = np.max((gain[moves] / n_num) / (rss[moves] / dof))
    return float(min(1.0, fdtrc(n_num, dof, stat) * gain.size))  # the F distribution's tail, Bonferroni


def _control_test_ranked(R: np.ndarray, i: int, m: int, l: int, j: int, rcond: float, s1: float):
    """Recipe of :attr:`Predictor.control_pvalue` for a regressor of any rank, from the lower-triangular factor ``R``
    of ``A = [W_p; U_f; Y_f]`` (``A = R Qᵀ``; for the Gram methods the channel-scaled one the rank was decided on).

    ``s1``: the regressor's largest singular value; directions below ``rcond·s1`` are not spanned (the tolerance of
    the pseudo-inverse, §2.2).  Keeps a copy of the regressor's columns only, not ``R``.
    """
    n_past, n_reg = i * (m + l), i * (2 * m + l)
    if not s1 > 0:  # an all-zero regressor: nothing to test
        return None
    return _Deferred(_control_pvalue_ranked, np.array(R[:, :n_reg]), np.einsum("ij,ij->i", R[n_reg:, n_reg:],
                     R[n_reg:, n_reg:]), n_past, n_reg, j, rcond * s1, rcond)


def _row_space(B: np.ndarray, tol: float) -> np.ndarray:
    """Orthonormal basis (as columns) of the row space of ``B`` spanned by its singular values above ``tol``."""
    if B.size == 0:
        return np.zeros((B.shape[1], 0))
    _, s, Vt = np.linalg.svd(B, full_matrices=False)
    return Vt[: int(np.count_nonzero(s > tol))].T


def _control_pvalue_ranked(R: np.ndarray, tail, n_past: int, n_reg: int, j: int, tol: float, rcond: float):
    """:attr:`Predictor.control_pvalue` in the column space the regressor actually spans (rank-deficient regressor).

    ``R``: the factor's first ``n_reg`` columns (the regressor's coordinates; the ``W_p`` rows live in the first
    ``n_past``, ``R`` being lower triangular); ``tail``: the energy of each ``Y_f`` row beyond them (orthogonal to
    every regressor).  The nested regressions: ``V0`` spans ``W_p``'s rows (singular values above ``tol``), ``V1``
    what the ``U_f`` rows add beyond it (their part orthogonal to ``V0``, same tolerance), so that the rank gained
    ``r1`` is the numerator's degrees of freedom and ``j − r0 − r1`` the residual's.  ``None`` when ``U_f`` adds no
    direction (no test has power: the input is not persistently exciting, a :class:`PersistenceWarning` says so) or
    fewer than twice as many columns as the spanned rank (as :func:`_control_test`).
    """
    V0 = _row_space(R[:n_past, :n_past], tol)
    Ru = R[n_past:n_reg].copy()
    Ru[:, :n_past] -= (Ru[:, :n_past] @ V0) @ V0.T
    V1 = _row_space(Ru, tol)
    V1 -= np.vstack([V0, np.zeros((n_reg - n_past, V0.shape[1]))]) @ (V0.T @ V1[:n_past])  # re-orthogonalise
    rank = V0.shape[1] + V1.shape[1]
    dof = j - rank
    if V1.shape[1] == 0 or dof < rank:
        return None
    Y = R[n_reg:]
    past = Y[:, :n_past] @ V0
    ahead = Y @ V1
    residual = Y.copy()
    residual[:, :n_past] -= past @ V0.T
    residual -= ahead @ V1.T
    rss = np.einsum("ij,ij->i", residual, residual) + tail
    gain = np.einsum("ij,ij->i", ahead, ahead)
    energy = np.einsum("ij,ij->i", Y, Y) + tail
    return _bonferroni_f(gain, rss, energy, V1.shape[1], dof, rcond)


def _predictor_from_factor(R, i, m, l, j, rcond, method, *, stacklevel=3, route="auto", warm=None,
                           scale=False) -> Predictor:
    """Predictor from a lower-triangular factor ``R`` of ``A`` (``A = R Qᵀ``, (2.7)).

    ``route="auto"``: for the Gram methods (``"cholesky"``, ``"recursive"``) try
    :func:`_well_conditioned` first and fall back to the rank-revealing spectral
    pseudo-inverse (:func:`_solve_from_r`) when ``R1`` is not found well conditioned;
    ``"spectral"`` always takes the rank-revealing route (``"qr"`` always does).  The Gram methods first
    scale the channels to unit rms (:func:`_channel_scales`, exact) unless ``scale`` gives the row scales
    ``R`` was already divided by (``None``: unscaled).
    """
    n_reg = i * (2 * m + l)
    squared = method in _GRAM_METHODS
    if scale is False:  # the Gram methods work on channels of unit rms (:func:`_channel_scales`)
        scale = _channel_scales(np.einsum("ij,ij->i", R, R), i, m, l, j) if squared else None
        if scale is not None:
            R = R / scale[:, None]  # the factor of the scaled data: A/d = (R/d) Qᵀ, still lower triangular
    unscaled = R[:n_reg, :n_reg] if scale is None else R[:n_reg, :n_reg] * scale[:n_reg, None]
    if squared and route == "auto":
        R1 = np.asfortranarray(R[:n_reg, :n_reg])
        if _well_conditioned(R1, rcond, warm):
            L = _trsolve(R1, R[n_reg:, :n_reg].T, trans=1).T  # R3 R1⁻¹
            control = _control_test(R[n_reg:, :n_reg].T, None, R[n_reg:, n_reg:], i, m, l, j, rcond)
            return _triangular_predictor(_unscaled(L, scale), unscaled, i, m, l, j, rcond, method, control)
    L, s, q = _solve_from_r(R, n_reg, rcond, squared=squared, scale=scale)
    s1 = float(s[0])  # σ₁ of the regressor q was decided on (channel-scaled for the Gram methods)
    r_in = _input_rank_from_factor(R, i, m, l, rcond, squared=squared)
    _warn_rank(q, r_in, i, m, l, j, rcond, stacklevel=stacklevel + 1)
    Lw, Lu = _split(L, i, m, l)
    if scale is not None:  # the singular values of the regressor itself, not of the scaled one q was decided on
        s = _Deferred(_factor_singular_values, unscaled)
    if q == n_reg:
        control = _control_test(R[n_reg:, :n_reg].T, None, R[n_reg:, n_reg:], i, m, l, j, rcond)
    else:  # R1's pivots of rounding size would decide the triangular test: test in the space the regressor spans
        control = _control_test_ranked(R, i, m, l, j, rcond, s1)
    return Predictor(Lw, Lu, i, m, l, j, s, int(q), method, int(r_in), float(rcond), "spectral",
                     control_pvalue=control)


def _predictor_from_gram(G, i, m, l, j, rcond, method, *, stacklevel=3, route="auto", warm=None) -> Predictor:
    """Predictor from the Gram matrix ``AAᵀ`` (A-row order): ``R = chol(AAᵀ)`` then §2.2.

    Triangular route (``route="auto"``): only the regressor block is factored,
    ``G11 = R1 R1ᵀ`` (``n = i(2m+l)``, not the whole ``2i(m+l)``), and
    ``[Lw Lu]ᵀ = G11⁻¹ G13 = R1⁻ᵀ R1⁻¹ G13`` by two triangular solves (LAPACK ``dpotrs``) — i.e.
    ``R3 R1⁻¹`` with the ``R3 = G31 R1⁻ᵀ`` a full Cholesky factor would hold, without factoring
    the ``Y_f`` block nobody uses.  The Gram methods work on the data with every channel scaled to unit rms
    by a power of two (:func:`_channel_scales`: exact, so the rank decisions do not depend on the units) and
    scale the predictor back.  Reads only the lower triangle of ``G``: LAPACK factors
    ``G11ᵀ`` (Fortran order, a plain copy of the C-ordered block) as ``R1ᵀ R1`` through its upper
    triangle — the same numbers, without the transposing copy of ``G11``.
    """
    n_reg = i * (2 * m + l)
    scale = _channel_scales(np.diagonal(G), i, m, l, j) if method in _GRAM_METHODS else None
    if scale is not None:
        G = G / np.outer(scale, scale)  # the Gram matrix of the data divided row-wise by the (power-of-two) scales
    if method in _GRAM_METHODS and route == "auto":
        R1t, info = lapack.dpotrf(G[:n_reg, :n_reg].T, lower=0, clean=1)  # upper factor: R1ᵀ
        if info == 0 and _well_conditioned(R1t, rcond, warm, lower=False):
            # G11⁻¹ G13 as LAPACK dpotrs does it, in its two triangular solves: the first, Z = R1⁻ᵀ G13, also gives
            # what U_f explains beyond W_p (Predictor.control_pvalue)
            Z, info = lapack.dtrtrs(R1t, G[n_reg:, :n_reg].T, lower=0, trans=1)
            if info == 0:
                X, info = lapack.dtrtrs(R1t, Z, lower=0, trans=0)
            if info == 0:
                unscaled = R1t if scale is None else R1t * scale[None, :n_reg]
                control = _control_test(Z, np.diagonal(G)[n_reg:], None, i, m, l, j, rcond)
                return _triangular_predictor(_unscaled(X.T, scale), unscaled, i, m, l, j, rcond, method, control)
        route = "spectral"  # R1 is not (well) conditioned: the full factor's triangular route would refuse too
    R = _psd_cholesky(G)
    return _predictor_from_factor(R, i, m, l, j, rcond, method, stacklevel=stacklevel + 1, route=route, warm=warm,
                                  scale=scale)


def _split(L: np.ndarray, i: int, m: int, l: int):
    return L[:, : i * (m + l)].copy(), L[:, i * (m + l) :].copy()


#: Peaks of a channel the Gram route (``method="cholesky"``) takes: it squares the data, and beyond this range the
#: squares leave floating point (measured: a record scaled by 1e-170 gave rank 0 and an all-zero predictor, by 1e-160
#: an Lu off by 1.5e-4 without a warning, by 1e154 LAPACK's "did not converge").
GRAM_RANGE = (1e-100, 1e100)


def _check_gram_range(u: np.ndarray, y: np.ndarray) -> None:
    for name, x in (("u", u), ("y", y)):
        peak = np.max(np.abs(x), axis=0)
        bad = np.flatnonzero((peak > 0) & ((peak < GRAM_RANGE[0]) | (peak > GRAM_RANGE[1])))
        if bad.size:
            k = int(bad[0])
            raise DataError(
                f"{name}[:, {k}] peaks at {peak[k]:.3g}: method='cholesky' forms the Gram matrix AAᵀ, whose entries "
                f"(about 1e{2 * np.log10(peak[k]):.0f} times the record length) leave floating-point range; rescale "
                "the signal (e.g. to volts, or divide it by its rms) or pass method='qr'")


def fit_predictor(u, y, horizon: int, *, method: str = "cholesky", rcond: float | None = None,
                  dt: float | None = None) -> Predictor:
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
        ``"cholesky"`` (default): ``R = chol(AAᵀ)`` with ``AAᵀ`` built by the Hankel recursions
        (2.8)–(2.9) in ``O(ij + i²)`` time and ``O(i² + j)`` memory, never forming the Hankel
        matrices (§2.3).  When the regressor factor ``R1`` is well conditioned (a power-iteration
        estimate of ``κ₂(R1)`` below ``0.8/rcond``, so the pseudo-inverse of §2.2 would keep every
        singular value), ``[Lw Lu] = R3 R1⁻¹`` by a Cholesky factor of the regressor block
        ``G11`` and two triangular solves (``solver="triangular"``).  Otherwise — ill-conditioned or rank-deficient data — the
        rank-revealing pseudo-inverse of §2.2 is used (``solver="spectral"``; its ``U``, ``Σ``
        from the eigendecomposition of ``R1 R1ᵀ``, equivalent to the SVD of ``R1`` at the
        precision a Gram matrix carries) and a :class:`PersistenceWarning` names the rank.  A
        semidefinite ``AAᵀ`` is factored through its clipped eigendecomposition when LAPACK's
        Cholesky breaks down.
        ``"qr"``: QR of ``A = [W_p; U_f; Y_f]`` (2.7) and the SVD pseudo-inverse of §2.2
        (``O(i²j)`` time, ``O(ij)`` memory).
        ``"lstsq"``: ``numpy.linalg.lstsq`` on the explicit Hankel matrices (a plain reference; a QR of the data
        gives its :attr:`Predictor.control_pvalue`, about 1.7× the time of the fit alone).
    rcond : float, optional
        Relative tolerance for the pseudo-inverse: singular values ``<= rcond * σ₁`` are
        discarded (§2.2).  Default :func:`default_rcond` (``max(i(2m+l), j)·eps`` for
        ``"qr"``/``"lstsq"``, ``10·√(max(i(2m+l), j)·eps)`` for ``"cholesky"``).
    dt : float, optional
        The data's sample time, stored as :attr:`Predictor.dt`: the designs built on the
        predictor then refuse weights discretised at another sample time (the arrays alone
        carry no sample time).  From a file: ``fit_predictor(rec.u, rec.y, i, dt=rec.dt)`` with
        ``rec = experiments.load_record(...)``.

    Returns
    -------
    Predictor
        With ``singular_values`` of ``[R11 0; R21 R22]``, the numerical ``rank`` kept and the
        numerical ``input_rank`` of ``[U_p; U_f]``.

    Raises
    ------
    DataError
        On NaN/inf, length mismatch, wrong dimensions, too few samples for the horizon, a bad
        horizon or a bad ``rcond``; an input channel zero on every sample or a constant output channel (no
        response in the record); with ``"cholesky"``, a channel whose peak lies outside
        ``[1e-100, 1e100]`` (its Gram matrix would leave floating-point range: rescale, or ``"qr"``).
    ValueError
        On an unknown ``method``.

    Warns
    -----
    PersistenceWarning
        When ``[U_p; U_f]`` has rank ``< 2mi`` (input not persistently exciting of order
        ``2mi``), or the whole regressor ``[W_p; U_f]`` is rank deficient (noise-free outputs,
        or ``j < i(2m+l)``).  The minimum-norm predictor is returned in both cases.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(500)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:500] + 0.01 * rng.standard_normal(500)
    >>> pred = fit_predictor(u, y, 4)
    >>> pred.Lw.shape, pred.Lu.shape, pred.rank
    ((4, 8), (4, 4), 12)
    """
    if method not in ("cholesky", "qr", "lstsq"):
        raise DataError(f"unknown method {method!r}; use 'cholesky', 'qr' or 'lstsq'")
    if dt is not None:
        dt = check_sample_time(dt, "dt", allow_true=False)
    u = as_signal(u, "u")
    y = as_signal(y, "y", n=u.shape[0])
    n, m = u.shape
    l = y.shape[1]
    i = check_horizon(horizon, n)
    check_inputs_move(u, "the record")
    check_output_moves(y, "the record")
    n_reg = i * (2 * m + l)
    j = n - 2 * i + 1
    tol = _resolve_rcond(rcond, method, n_reg, j)
    if method == "cholesky":
        _check_gram_range(u, y)
        return _stamped(_predictor_from_gram(hankel_gram(u, y, i), i, m, l, j, tol, method), dt, u, y)
    Up, Uf, Yp, Yf, j = _data_matrices(u, y, i)
    if method == "qr":
        A = np.vstack([Up, Yp, Uf, Yf])
        R = _square_factor(np.linalg.qr(A.T, mode="r").T)
        return _stamped(_predictor_from_factor(R, i, m, l, j, tol, method), dt, u, y)
    # method == "lstsq"
    Phi = np.vstack([Up, Yp, Uf])
    sol, _, q, s = np.linalg.lstsq(Phi.T, Yf.T, rcond=tol)
    s = np.concatenate([np.asarray(s), np.zeros(n_reg - len(s))])
    r_in = _rank(np.linalg.svd(np.vstack([Up, Uf]), compute_uv=False), tol)
    _warn_rank(int(q), r_in, i, m, l, j, tol, stacklevel=3)
    Lw, Lu = _split(sol.T, i, m, l)
    control = _lstsq_control_test(Phi, Yf, i, m, l, j, tol, float(s[0]))
    return _stamped(Predictor(Lw, Lu, i, m, l, j, s, int(q), method, int(r_in), float(tol), control_pvalue=control),
                    dt, u, y)


def _lstsq_control_test(Phi: np.ndarray, Yf: np.ndarray, i: int, m: int, l: int, j: int, rcond: float, s1: float):
    """Recipe of :attr:`Predictor.control_pvalue` for ``method="lstsq"``: the factor ``R`` of ``A = [Φ; Y_f]`` (a QR
    of the data, as ``"qr"``) and the test in the space ``Φ`` spans at ``lstsq``'s own tolerance ``rcond·σ₁(Φ)``
    (:func:`_control_test_ranked`, whatever the rank: ``lstsq`` reveals it by the SVD, not by ``R1``'s pivots)."""
    R = _square_factor(np.linalg.qr(np.vstack([Phi, Yf]).T, mode="r").T)
    return _control_test_ranked(R, i, m, l, j, rcond, s1)


def _stamped(pred: Predictor, dt, u, y) -> Predictor:
    """``pred`` with the data's sample time (when given) and the fingerprint of the record it was fitted on."""
    # a new object of our own, not yet seen by anyone
    if dt is not None:
        object.__setattr__(pred, "dt", dt)
    object.__setattr__(pred, "fingerprint", record_fingerprint(u, y))
    return pred


def _warn_rank(q: int, r_in: int, i: int, m: int, l: int, j: int, rcond: float, *, stacklevel: int = 3) -> None:
    n_reg = i * (2 * m + l)
    if r_in < 2 * m * i:
        warnings.warn(
            f"the input part [U_p; U_f] has numerical rank {r_in} < 2mi = {2 * m * i}: the input is not "
            f"persistently exciting of order 2mi (regressor rank {q} of {n_reg}); the minimum-norm "
            "predictor is returned and Lu is not determined by the data — use a richer input "
            "(white noise, PRBS) or more samples",
            PersistenceWarning,
            stacklevel=stacklevel,
        )
    elif q < n_reg:
        why = (
            f"only j = {j} columns for {n_reg} regressors: collect at least {n_reg + 2 * i - 1} samples"
            if j < n_reg
            else "the outputs are (nearly) noise free, i.e. an exact function of the past data "
            f"(plant order < i·l), or rcond = {rcond:.3g} is too large (singular values below rcond times the "
            "largest are dropped; method='cholesky' decides on the channels scaled to unit rms, method='qr' has "
            "an eps-relative default)"
        )
        warnings.warn(
            f"regressor [W_p; U_f] has numerical rank {q} < {n_reg} although the input is persistently "
            f"exciting ({why}); the minimum-norm predictor is returned",
            PersistenceWarning,
            stacklevel=stacklevel,
        )


def _psd_cholesky(G: np.ndarray) -> np.ndarray:
    """Lower-triangular ``L`` with ``L Lᵀ = G`` for symmetric positive *semi*-definite ``G``.

    Tries LAPACK Cholesky first (when it succeeds it is backward stable, and the
    rounding-level pivots of a singular ``G`` stay below the default tolerance of
    :func:`default_rcond`).  If ``G`` is only semidefinite and LAPACK breaks down, it falls
    back to a symmetric eigendecomposition, clipping eigenvalues ``<= N·eps·λ_max`` (and
    negative rounding noise) to zero, followed by a QR of ``F = V √Λ`` to restore triangular
    form (``G ≈ F Fᵀ = L Lᵀ``).  An all-zero ``G`` gives ``L = 0``.
    """
    L, info = lapack.dpotrf(G, lower=1, clean=1)
    if info == 0:
        return L
    if info < 0:  # pragma: no cover - an argument error, not a property of the data
        raise ValueError(f"LAPACK dpotrf: illegal argument {-info}")
    else:
        w, V = np.linalg.eigh(G)
        tol = G.shape[0] * _EPS * max(w.max(initial=0.0), 0.0)
        w = np.where(w > tol, w, 0.0)
        F = V * np.sqrt(w)  # G ≈ F Fᵀ
        return np.linalg.qr(F.T, mode="r").T
