"""The barrier Hessian of the Toeplitz LMI from displacement generators: O(m²) work, no 2-D transform.

``F = [δI T(h)ᵀ; T(h) δI]`` with ``T(h) = Σ_a h_a Zᵃ`` (Z the lower shift).  The Hessian of ``−log det F`` in h
is ``H_ab = tr(F⁻¹E_aF⁻¹E_b)`` (E_a the derivative of F in h_a), and with ``S = F⁻¹ = [S11 S12; S21 S22]``

    H = 2A + C + Cᵀ,    A_ab = tr(S12 Zᵃ S12 Zᵇ),    C_ab = tr(S22 Zᵃ S11 Zᵇᵀ).

:func:`unfalsify.solvers.toeplitz.corr_hessian` forms both as 2-D cross-correlations of the dense blocks (four
2m × 2m transforms, O(m² log m) with the FFT's constant).  The blocks of F⁻¹ have more structure than dense
matrices: with ``W = (δ²I − TᵀT)⁻¹`` and ``V = (δ²I − TTᵀ)⁻¹``, ``S11 = δW``, ``S22 = δV``, ``S21 = −TW``,
and each has displacement rank 2 —

* ``S11 − Z S11 Zᵀ`` and ``S22 − Zᵀ S22 Z`` (``δ²I − TᵀT`` minus ``Zᵀ(·)Z`` is ``δ²eₘ₋₁eₘ₋₁ᵀ − rrᵀ``, r the last
  row of T; the inverse's displacement w.r.t. the transposed shift has the same rank and inertia);
* ``Z S12 − S12 Z`` and ``S12 − Z S12 Zᵀ`` (T commutes with Z).

Shifting both lags moves the trace along a diagonal of the (a, b) plane, and the difference is the trace
with a displacement in place of a block:

* ``C_ab − C_{a+1,b+1} = tr((S22 − ZᵀS22Z) Zᵃ S11 Zᵇᵀ)``, and with ``S22 − ZᵀS22Z = Σ x_r y_rᵀ``, each term
  ``y_rᵀ Zᵃ S11 Zᵇᵀ x_r`` moves the same way with ``S11 − Z S11 Zᵀ = Σ u_s v_sᵀ`` in place of S11:
  ``C = dc(dc(Σ_{r,s} c(y_r, u_s) c(x_r, v_s)ᵀ))``, ``c(y, u)_a = Σ_i y_{i+a} u_i`` a correlation and
  ``dc(M)_ab = Σ_k M_{a+k,b+k}`` a cumulative sum along the diagonals (the chains end where a lag reaches m,
  where every term is zero);
* ``A_ab − A_{a+1,b−1} = tr((Z S12 − S12 Z) Zᵃ S12 Zᵇ⁻¹)`` for b ≥ 1, and again one level down, so A is two
  cumulative sums along the anti-diagonals (``ac(M)_ab = Σ_k M_{a+k,b−k}``) of rank-k outer products of
  correlations, plus boundary columns: ``y_rᵀ Zᵃ S12 x_r`` (one product with S12 per generator) and
  ``A_a0 = tr(Zᵃ S12²)``, the superdiagonal sums of S12², read off the generators of ``S12² − Z S12² Zᵀ``
  (:func:`_superdiagonal_sums`) without forming S12².

The h–δ column ``T*(S21 S11)`` (``cross=True``) comes the same way from the generators of
``S21 S11 − Z S21 S11 Zᵀ`` (:func:`_cross_column`).

The generators are read off the dense displacement matrices by a rank-4 range finder (:func:`_generators`;
every displacement above has rank 2, so the range is exact up to rounding), or come with the blocks:
:func:`inverse_blocks` builds the blocks themselves from K's Cholesky factor through those same generators
(two block solves, O(m²)) instead of forming ``K⁻¹`` densely (potri, ⅔m³) and multiplying it by T(h) (2m³), and
hands them on (:class:`Generators`); and K's factor itself comes from the generators of ``J K J − Z(J K J)Zᵀ``
by the generalised Schur algorithm (:func:`schur_cholesky`, O(m²)).  What a Hessian costs: eight
products of an m × m block with m × 4 generators, 4 × 4 batched FFT correlations of length 2m, two outer
products of rank 16 and four cumulative-sum passes — about 60 m² flops, against the transforms' ~40 m² log₂ m
of :func:`~unfalsify.solvers.toeplitz.corr_hessian` run at FFT speed.  It applies to the blocks of F⁻¹ only
(the structure above is what it uses); for other blocks (e.g. a primal–dual scaling matrix) the FFT route
stays.
"""
from __future__ import annotations

import functools
from typing import NamedTuple

import numpy as np
import scipy.fft
import scipy.linalg

from .toeplitz import conv_cols, conv_cols_T

__all__ = ["displacement_hessian", "inverse_blocks", "Generators", "schur_cholesky"]

#: Columns of the range finder (:func:`_generators`): the displacement ranks are 2, so two to spare.
_RANK = 4


def displacement_hessian(S11, S21, S22, *, cross: bool = False, generators: "Generators | None" = None):
    """``tr(F⁻¹E_aF⁻¹E_b)`` for all (a, b) from the displacement structure of F⁻¹'s blocks (module docstring).

    Parameters
    ----------
    S11, S21, S22 : ndarray, shape (..., m, m)
        The blocks of ``F⁻¹``, ``F = [δI T(h)ᵀ; T(h) δI]`` (a stack: one F per leading index).  They must be
        those blocks (up to rounding): the route uses their structure, and other matrices give wrong numbers.
    cross : bool
        Also return ``T*(S21 S11)`` (shape (..., m)): ``4 T*(S21 S11)`` is the h–δ column of the Hessian.
    generators : Generators, optional
        Generators of the blocks' displacements already at hand (:func:`inverse_blocks` returns them); without
        them they are read off the blocks by a range finder (two products of a block with m × 4 matrices each).

    Returns
    -------
    H : ndarray, shape (..., m, m)
        Equal to :func:`unfalsify.solvers.toeplitz.corr_hessian` to rounding.

    Examples
    --------
    >>> import numpy as np
    >>> from unfalsify.solvers.toeplitz import corr_hessian, toeplitz_matrix
    >>> m, d = 6, 2.0
    >>> T = toeplitz_matrix(np.array([0.9, -0.4, 0.3, 0.2, -0.1, 0.05]))
    >>> S = np.linalg.inv(np.block([[d * np.eye(m), T.T], [T, d * np.eye(m)]]))
    >>> blocks = S[:m, :m], S[m:, :m], S[m:, m:]
    >>> H, x = displacement_hessian(*blocks, cross=True)
    >>> H_fft, x_fft = corr_hessian(*(b[None] for b in blocks), m, cross=True)
    >>> bool(np.allclose(H, H_fft[0]) and np.allclose(x, x_fft[0]))
    True
    """
    S11, S21, S22 = (np.asarray(X, float) for X in (S11, S21, S22))
    m = S11.shape[-1]
    S12 = np.swapaxes(S21, -1, -2)
    if generators is None:
        generators = Generators(_generators(S11 - _shift_down(S11)), _generators(S22 - _shift_up(S22)),
                                _generators(S21 - _shift_down(S21)))
    u, v = generators.s11
    ga, ha = generators.s21
    H = _a_term(S12, (ha, ga), m)  # S12 − Z S12 Zᵀ = (S21 − Z S21 Zᵀ)ᵀ = ha gaᵀ
    H *= 2.0  # H = 2A + (C + Cᵀ), in place: A is this call's own array
    H += _c_term(generators.s22, u, v, m)
    if not cross:
        return H
    return H, _cross_column(S21, S11, (ga, ha), u, v, m)


class Generators(NamedTuple):
    """Generator pairs (X, G), ``X Gᵀ`` equal to a displacement of a block of F⁻¹ (m × k each, k ≥ 2):
    ``s11`` of ``S11 − Z S11 Zᵀ``, ``s22`` of ``S22 − Zᵀ S22 Z`` and ``s21`` of ``S21 − Z S21 Zᵀ``."""

    s11: tuple
    s22: tuple
    s21: tuple


def inverse_blocks(L, h, d, *, generators: bool = False, flipped: bool = False):
    """``K⁻¹``, ``T(h)K⁻¹`` and ``S22 = (I + T(h)K⁻¹T(h)ᵀ)/δ`` from the Cholesky factor L of ``K = δ²I − TᵀT`` in O(m²).

    The dense route forms ``K⁻¹`` from L (LAPACK potri, ⅔m³ flops) and multiplies it by T(h) twice (m³ each).
    Here each block is rebuilt from the generators of its displacement instead:

    * ``K⁻¹ − Z K⁻¹ Zᵀ = Q₁ G₁ᵀ`` (rank 2, module docstring), read by a rank-4 range finder whose products with
      the displacement cost two solves with L each (``K⁻¹Ω`` and ``K⁻¹ZᵀΩ``);
    * ``T K⁻¹ − Z T K⁻¹ Zᵀ = T(K⁻¹ − Z K⁻¹ Zᵀ) = (T Q₁) G₁ᵀ`` because T commutes with Z: no further solve;
    * ``δS22 − Zᵀ δS22 Z = e eᵀ + T K⁻¹ Tᵀ − Zᵀ T K⁻¹ Tᵀ Z = Q₂ G₂ᵀ`` (e the last unit vector), the same way;

    and a block follows from its displacement by one cumulative sum along the diagonals
    (``M = Σ_k Zᵏ D Zᵏᵀ``).  The work is two solves with L, each against m × 16 right-hand sides, FFT products with
    T(h), three outer products of rank 4 and three cumulative-sum passes: O(m²), against 2⅔m³.  Accurate to
    about 1e-13 of the largest entry at m = 1000–3000 with K within 1e-7 of singular (the cumulative sums add
    the rounding of m terms), where potri keeps about 1e-15.

    Parameters
    ----------
    L : ndarray, shape (m, m)
        Lower Cholesky factor of ``δ²I − T(h)ᵀT(h)`` (upper triangle zero or ignored by LAPACK's potrs).
    h : ndarray, shape (m,)
        First column of the lower-triangular Toeplitz T(h).
    d : float
        δ.
    generators : bool
        Also return the :class:`Generators` of the blocks' displacements (for :func:`displacement_hessian`).
    flipped : bool
        L is instead the lower Cholesky factor of ``J K J = δ²I − T(h)T(h)ᵀ`` (J the exchange matrix), as
        :func:`schur_cholesky` returns it.

    Returns
    -------
    Kinv, A, S22 : ndarray, shape (m, m)
        ``K⁻¹``, ``T(h)K⁻¹`` and ``(I + T(h)K⁻¹T(h)ᵀ)/δ``: the blocks ``S11 = δK⁻¹``, ``S21 = −A`` and ``S22`` of
        ``F⁻¹``, ``F = [δI T(h)ᵀ; T(h) δI]``.
    gens : Generators
        Only with ``generators=True``.

    Examples
    --------
    >>> import numpy as np
    >>> from unfalsify.solvers.toeplitz import toeplitz_matrix
    >>> h, d = np.array([0.9, -0.4, 0.3, 0.2, -0.1, 0.05]), 2.0
    >>> T = toeplitz_matrix(h)
    >>> K = d * d * np.eye(6) - T.T @ T
    >>> Kinv, A, S22 = inverse_blocks(np.linalg.cholesky(K), h, d)
    >>> bool(np.allclose(Kinv, np.linalg.inv(K)) and np.allclose(A, T @ np.linalg.inv(K)))
    True
    >>> bool(np.allclose(S22, (np.eye(6) + T @ np.linalg.solve(K, T.T)) / d))
    True
    """
    h = np.asarray(h, float).reshape(-1, 1)
    m = h.shape[0]
    probe = _probe(m)

    def solve(*blocks):
        B = np.hstack(blocks)
        X = (scipy.linalg.cho_solve((L, True), B[::-1], check_finite=False)[::-1] if flipped  # K⁻¹ = J(JKJ)⁻¹J
             else scipy.linalg.cho_solve((L, True), B, check_finite=False))
        return np.split(X, len(blocks), axis=1)

    def images(X, Y):
        """``(K⁻¹ − Z K⁻¹ Zᵀ) X`` and ``δ(S22 − Zᵀ S22 Z) Y = (e eᵀ + T K⁻¹ Tᵀ − Zᵀ T K⁻¹ Tᵀ Z) Y``."""
        Kx, Kzx, Ky, Kzy = solve(X, _shift_rows_up(X), conv_cols_T(h, Y), conv_cols_T(h, _shift_rows(Y)))
        D2 = conv_cols(h, Ky) - _shift_rows_up(conv_cols(h, Kzy))
        D2[-1] += Y[-1]
        return Kx - _shift_rows(Kzx), D2

    Q1, Q2 = (np.linalg.qr(D)[0] for D in images(probe, probe))
    G1, G2 = images(Q1, Q2)  # both displacements are symmetric: D Q = Dᵀ Q
    TQ1 = conv_cols(h, Q1)
    Kinv = _forward_diag_cumsum(Q1 @ G1.T)
    A = _forward_diag_cumsum(TQ1 @ G1.T)
    S22 = _diag_cumsum(Q2 @ G2.T)
    S22 /= d
    if not generators:
        return Kinv, A, S22
    return Kinv, A, S22, Generators((d * Q1, G1), (Q2, G2 / d), (-TQ1, G1))


def schur_cholesky(h, d):
    """The lower Cholesky factor of ``J K J = δ²I − T(h)T(h)ᵀ`` by the generalised Schur algorithm, O(m²) flops.

    ``K = δ²I − T(h)ᵀT(h)`` (J the exchange matrix; ``J T(h)ᵀ J = T(h)`` for a lower-triangular Toeplitz T(h)).
    ``R = δ²I − TTᵀ`` has the displacement ``R − Z R Zᵀ = g₀g₀ᵀ − g₁g₁ᵀ`` with ``g₀ = δe₀`` and ``g₁ = h``, and the
    algorithm (Kailath–Sayed) peels one column of the factor per step: a hyperbolic rotation zeroes the negative
    generator's leading entry, the positive generator is then the factor's column, and shifting it down gives
    the generators of the Schur complement.  The rotations are applied in the mixed form (Bojanczyk, Brent,
    de Hoog and Sweet, 1995), which keeps the factorisation backward stable for a positive definite R: measured
    ``‖LLᵀ − R‖ ≈ 3e-15‖R‖`` at m = 1000 with R within 1e-7 of singular, as LAPACK's potrf.  R is positive
    definite exactly when every rotation exists (``|g₁ₖ| < g₀ₖ``).  Measured on one core, with the O(m²) Gram
    that potrf needs counted: m = 400 2.7 ms against 3.4 ms, m = 1000 14 against 22 ms; m = 3000 64 ms against
    0.6 s (potrf on both cores); m = 200 1.3 against 0.9 ms.

    Parameters
    ----------
    h : ndarray, shape (m,)
        First column of T(h).
    d : float
        δ.

    Returns
    -------
    ndarray, shape (m, m), or None
        L lower triangular with ``L Lᵀ = δ²I − T(h)T(h)ᵀ`` (a Fortran-ordered view), or None where that matrix is
        not positive definite (in floating point).

    Examples
    --------
    >>> import numpy as np
    >>> from unfalsify.solvers.toeplitz import toeplitz_matrix
    >>> h, d = np.array([0.9, -0.4, 0.3, 0.2]), 2.0
    >>> T = toeplitz_matrix(h)
    >>> L = schur_cholesky(h, d)
    >>> bool(np.allclose(L, np.linalg.cholesky(d * d * np.eye(4) - T @ T.T)))
    True
    >>> print(schur_cholesky(h, 0.5))  # δ below ‖T(h)‖₂
    None
    """
    g1 = np.array(h, dtype=float).reshape(-1)
    m = g1.size
    g0 = np.zeros(m)
    g0[0] = d
    Lt = np.zeros((m, m))  # Lᵀ by rows: each step writes a contiguous row
    for k in range(m):
        a, b = g0[k], g1[k]
        if not abs(b) < a:  # also NaN
            return None
        rho = b / a
        c = np.sqrt((1.0 - rho) * (1.0 + rho))
        x0, x1 = g0[k:], g1[k:]
        x0 -= rho * x1
        x0 /= c
        x1 *= c
        x1 -= rho * x0  # mixed form: the rotated positive generator enters the negative one
        Lt[k, k:] = x0
        g0[k + 1:] = x0[:-1]  # Z g₀ (numpy buffers the overlapping copy)
        g1[k] = 0.0
    return Lt.T


# ---- the two terms ------------------------------------------------------------------------------------------
def _c_term(s22, u, v, m):
    """``C + Cᵀ`` with ``C_ab = tr(S22 Zᵃ S11 Zᵇᵀ)``; ``S11 − Z S11 Zᵀ = u vᵀ``, ``S22 − ZᵀS22Z = x yᵀ``
    (``s22 = (x, y)``).  C is a double diagonal cumulative sum of ``leftᵀ right``, which commutes with the
    transpose, so ``C + Cᵀ`` is that of ``leftᵀ right + rightᵀ left``: one product with twice the inner
    dimension, no transposed n × n addition."""
    x, y = s22
    left = _pair_corr(y, u, m)  # (..., k·k, m): c(y_r, u_s)
    right = _pair_corr(x, v, m)  # c(x_r, v_s)
    both = np.concatenate([left, right], axis=-2)
    swapped = np.concatenate([right, left], axis=-2)
    return _diag_cumsum(_diag_cumsum(np.swapaxes(both, -1, -2) @ swapped))


def _a_term(S12, s12, m):
    """``A_ab = tr(S12 Zᵃ S12 Zᵇ)``."""
    gx, gy = _commutator_generators(S12)  # Z S12 − S12 Z = gx gyᵀ
    level = np.empty(S12.shape)  # level 2, then in place level 1 and the result: one n × n array in all
    # column 0: Σ_r y_rᵀ Zᵃ S12 x_r; columns c ≥ 1: −Σ_{r,s} c(y_r, x_s)_a c(y_s, x_r)_{c−1}
    level[..., :, 0] = np.sum(_corr(np.swapaxes(gy, -1, -2), np.swapaxes(S12 @ gx, -1, -2), m), axis=-2)
    k = gx.shape[-1]
    left = _pair_corr(gy, gx, m)  # row (r, s): c(y_r, x_s)
    right = np.swapaxes(left.reshape(left.shape[:-2] + (k, k, m)), -2, -3).reshape(left.shape)  # c(y_s, x_r)
    np.matmul(np.swapaxes(left, -1, -2), -right[..., :, :-1], out=level[..., :, 1:])
    _antidiag_cumsum(level)
    _shift_columns_right(level)  # level 1: columns c ≥ 1 are those of level 2's cumulative sum, c − 1
    level[..., :, 0] = _superdiagonal_sums(S12, s12, m)  # A_a0 = tr(Zᵃ S12²)
    return _antidiag_cumsum(level)


def _shift_columns_right(M):
    """``M[..., :, 1:] = M[..., :, :-1]`` in place, row by row (a whole-array overlapping copy would buffer an
    n × n temporary), each row for the whole stack at once."""
    for a in range(M.shape[-2]):
        M[..., a, 1:] = M[..., a, :-1].copy()
    return M


def _superdiagonal_sums(P, gk, m):
    """``Σ_i (P²)_{i, i+a}`` for a = 0 … m−1, from ``P² − Z P² Zᵀ = P G + G P − G² − (ZPe)(ZPᵀe)ᵀ``
    (``G = P − Z P Zᵀ = g kᵀ``, ``gk = (g, k)``, e the last unit vector), never forming P²."""
    g, k = gk
    kg = np.swapaxes(k, -1, -2) @ g  # kᵀg
    last_col = _shift_vec(P[..., :, -1])  # Z P e
    last_row = _shift_vec(P[..., -1, :])  # Z Pᵀ e
    alpha = np.concatenate([P @ g, g, -(g @ kg), -last_col[..., None]], axis=-1)
    beta = np.concatenate([k, np.swapaxes(P, -1, -2) @ k, k, last_row[..., None]], axis=-1)
    return _weighted_diag_sums(beta, alpha, m)


def _cross_column(S21, S11, s21, u, v, m):
    """``T*(S21 S11)_a = Σ_i (S21 S11)_{i+a, i}`` from ``AB − Z AB Zᵀ = A G_B + G_A B − G_A G_B − (ZAe)(ZBᵀe)ᵀ``
    (A = S21, B = S11, ``G_B = u vᵀ``, ``G_A = A − Z A Zᵀ = ga haᵀ``, ``s21 = (ga, ha)``)."""
    ga, ha = s21
    hu = np.swapaxes(ha, -1, -2) @ u
    alpha = np.concatenate([S21 @ u, ga, -(ga @ hu), -_shift_vec(S21[..., :, -1])[..., None]], axis=-1)
    beta = np.concatenate([v, np.swapaxes(S11, -1, -2) @ ha, v, _shift_vec(S11[..., -1, :])[..., None]], axis=-1)
    return _weighted_diag_sums(alpha, beta, m)


# ---- kernels ------------------------------------------------------------------------------------------------
def _generators(Y):
    """``Y ≈ X Gᵀ`` with X, G of :data:`_RANK` columns: ``X = Q`` an orthonormal basis of ``Y Ω`` (Ω fixed,
    Gaussian) and ``G = Yᵀ Q`` — exact up to rounding for Y of rank ≤ :data:`_RANK`."""
    Q = np.linalg.qr(Y @ _probe(Y.shape[-1]))[0]
    return Q, np.swapaxes(Y, -1, -2) @ Q


def _commutator_generators(P):
    """:func:`_generators` of ``Z P − P Z`` from products of P with m × 2k matrices, never forming the difference
    (``(ZP − PZ)Ω = Z(PΩ) − P(ZΩ)`` and ``(ZP − PZ)ᵀQ = Pᵀ(ZᵀQ) − Zᵀ(PᵀQ)``)."""
    probe = _probe(P.shape[-1])
    k = probe.shape[-1]
    Y = P @ np.concatenate([probe, _shift_rows(probe)], axis=-1)
    Q = np.linalg.qr(_shift_rows(Y[..., :k]) - Y[..., k:])[0]
    G = np.swapaxes(P, -1, -2) @ np.concatenate([_shift_rows_up(Q), Q], axis=-1)
    k = Q.shape[-1]  # min(m, k): QR of an m × k matrix with m < k
    return Q, G[..., :k] - _shift_rows_up(G[..., k:])


@functools.lru_cache(maxsize=8)
def _probe(m: int) -> np.ndarray:
    """The range finder's fixed Gaussian m × :data:`_RANK` matrix (the same numbers in every run)."""
    return np.random.default_rng(20261125).standard_normal((m, _RANK))


def _corr(Y, U, m):
    """``Σ_i Y_{i+a} U_i`` for a = 0 … m−1 along the last axis (broadcast over the others), by FFT."""
    N = scipy.fft.next_fast_len(2 * m, real=True)
    return scipy.fft.irfft(scipy.fft.rfft(Y, N) * np.conj(scipy.fft.rfft(U, N)), N)[..., :m]


def _pair_corr(X, Y, m):
    """``c(X_r, Y_s)`` for every pair of columns (r, s), shape (..., k·k, m)."""
    k = X.shape[-1]
    c = _corr(np.swapaxes(X, -1, -2)[..., :, None, :], np.swapaxes(Y, -1, -2)[..., None, :, :], m)
    return c.reshape(c.shape[:-3] + (k * k, m))


def _weighted_diag_sums(alpha, beta, m):
    """``Σ_i Σ_j α_j[i + a] β_j[i] (m − a − i)`` for a = 0 … m−1: the subdiagonal sums of the matrix M with
    ``M − Z M Zᵀ = Σ_j α_j β_jᵀ`` (``M = Σ_k Zᵏ(Σ_j α_j β_jᵀ)Zᵏᵀ``, and entry (i + a, i) of the displacement
    enters m − a − i of the sums).  The weight is ``m − (i + a)``, a function of α's index alone, so it is one
    correlation of ``α·(m − index)`` with β (no difference of two large sums)."""
    weight = m - np.arange(m, dtype=float)
    return np.sum(_corr(np.swapaxes(alpha, -1, -2) * weight, np.swapaxes(beta, -1, -2), m), axis=-2)


def _diag_cumsum(M):
    """``out_ab = Σ_k M_{a+k, b+k}`` (in place on M, returned)."""
    for a in range(M.shape[-2] - 2, -1, -1):
        M[..., a, :-1] += M[..., a + 1, 1:]
    return M


def _forward_diag_cumsum(M):
    """``out_ab = Σ_k M_{a−k, b−k}`` over k ≤ min(a, b) (in place on M, returned): ``out − Z out Zᵀ = M``."""
    for a in range(1, M.shape[-2]):
        M[..., a, 1:] += M[..., a - 1, :-1]
    return M


def _antidiag_cumsum(M):
    """``out_ab = Σ_k M_{a+k, b−k}`` over b − k ≥ 0 (in place on M, returned)."""
    for a in range(M.shape[-2] - 2, -1, -1):
        M[..., a, 1:] += M[..., a + 1, :-1]
    return M


def _shift_down(M):
    """``Z M Zᵀ``: entry (i, j) is ``M[i−1, j−1]``."""
    out = np.zeros_like(M)
    out[..., 1:, 1:] = M[..., :-1, :-1]
    return out


def _shift_up(M):
    """``Zᵀ M Z``: entry (i, j) is ``M[i+1, j+1]``."""
    out = np.zeros_like(M)
    out[..., :-1, :-1] = M[..., 1:, 1:]
    return out


def _shift_rows(M):
    """``Z M``: row i is row i − 1 of M."""
    out = np.zeros_like(M)
    out[..., 1:, :] = M[..., :-1, :]
    return out


def _shift_rows_up(M):
    """``Zᵀ M``: row i is row i + 1 of M."""
    out = np.zeros_like(M)
    out[..., :-1, :] = M[..., 1:, :]
    return out




def _shift_vec(x):
    """``Z x``."""
    out = np.zeros_like(x)
    out[..., 1:] = x[..., :-1]
    return out
