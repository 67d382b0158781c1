"""The problem every structured solver takes: the column form (C) of (7.4) and (7.5), and its dual bound.

Both programs are instances of

    min δ   s.t.   ‖T(h_k)‖₂ ≤ δ  (k = 0 … j−1),   ‖B − H̃ − X‖_F ≤ ρ  for some X ∈ 𝓛,        (C)

with ``H̃ = [T(u_0)h_0 … T(u_{j−1})h_{j−1}]`` (m × j; column k convolves the input column u_k with
the impulse h_k), a target ``B`` (m × j), a noise budget ρ and a linear subspace 𝓛 of m × j matrices
(the directions of the model parameters):

* ARX (7.4): j = 1, m = n, ``B = Y``, 𝓛 = range Φ (``X = Φθ``), ρ = σ√n;
* subspace (7.5): m = i, ``B = Y_f``, 𝓛 = ``{L A}`` (rows in the row space of ``A = [W_p; U_f]``;
  with L fixed ``B = Y_f − L A`` and 𝓛 = {0}), ρ = σ√(ij).

Weak duality (the lower bound).  For ANY ``V`` (m × j) and ANY ``W_k`` (m × m):

1. project ``V`` onto 𝓛^⊥ (then ``⟨V, X⟩ = 0`` for X ∈ 𝓛);
2. let ``g_k = T(u_k)ᵀ v_k`` and correct ``W_k`` so that ``T*(W_k) = g_k`` exactly, where
   ``T*(W)_d = Σ_i W[i+d, i]`` (sum of the d-th subdiagonal) is the adjoint of h ↦ T(h): add
   ``T(c_k)`` with ``c_{k,d} = (g_k − T*(W_k))_d / (m − d)``;
3. for every feasible (δ, h, X): ``⟨W_k, T(h_k)⟩ = h_kᵀ T*(W_k) = v_kᵀ T(u_k) h_k`` and
   ``|⟨W_k, T(h_k)⟩| ≤ ‖W_k‖_* ‖T(h_k)‖₂ ≤ δ ‖W_k‖_*`` (nuclear norm, the dual of the spectral norm);
   summing over k, ``⟨V, H̃⟩ = ⟨V, B − X − Ξ⟩ = ⟨V, B⟩ − ⟨V, Ξ⟩ ≥ ⟨V, B⟩ − ρ‖V‖_F`` (Cauchy–Schwarz);

so       ``δ ≥ (⟨V, B⟩ − ρ‖V‖_F) / Σ_k ‖W_k‖_*``   and, trivially, δ ≥ 0.

The bound is homogeneous of degree 0 in (V, W), needs no normalisation, and steps 1–2 make it valid
for an inexact dual point (the corrections only enlarge the denominator).  The (V, W) of the LMI
form: the multiplier ``G = [G11 G12; G21 G22] ⪰ 0`` of ``[δI T(h)ᵀ; T(h) δI] ⪰ 0`` gives
``W = −2 G21`` with ``‖W‖_* ≤ tr G`` (so this bound is never weaker than the trace form); on the
central path of the barrier method ``G = F(h, δ)⁻¹/t``.  At an optimum the bound is tight (strong
duality: Slater holds).  Everything is computed from the data and (V, W) alone, in floating point:
the only rounding not covered is that of the arithmetic itself (relative ~1e-13 here).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .toeplitz import (adjoint, adjoint_lowrank, block_adjoint, block_conv_cols, block_conv_cols_T,
                       block_toeplitz_matrix, conv_cols, conv_cols_T, nuclear_norm_lowrank, toeplitz_nuclear_upper)

__all__ = ["ColumnForm", "BlockColumnForm", "CirculantDual", "scale_dual"]


@dataclass(frozen=True, eq=False)
class CirculantDual:
    """A norm multiplier W (j = 1) stored in O(N): the leading m × m block of the N × N circulant with
    first column ``[column; 0]`` (``N = size ≥ len(column) ≥ m``; the entries ``column[m:]`` only fill
    the block's upper triangle and are free).

    ``T*(W)_d = (m − d) column_d`` (d < m) and ``‖W‖_* ≤ ‖fft([column; 0], N)‖₁`` (the circulant's singular
    values are the moduli of its DFT, and compressing a matrix does not increase its nuclear norm), so
    :meth:`ColumnForm.lower_bound` evaluates the bound in O(N log N) without forming W.  Used by the
    bracket route (:mod:`unfalsify.solvers.bracket`) at sizes where W cannot be stored.
    """

    column: np.ndarray
    size: int

    def scaled(self, a: float) -> "CirculantDual":
        """``a W``."""
        return CirculantDual(column=a * np.asarray(self.column, float), size=self.size)


def _corrected(Wk: np.ndarray, gk: np.ndarray) -> np.ndarray:
    """``W_k`` plus the lower-triangular Toeplitz term that makes ``T*(W_k) = g_k`` exact (step 2 of the bound in the
    module docstring: the d-th diagonal of an m × m lower-triangular Toeplitz matrix appears m − d times in T*)."""
    m = Wk.shape[0]
    idx = np.arange(m)
    c = (gk - adjoint(Wk)) / (m - idx)
    return Wk + np.tril(c[np.subtract.outer(idx, idx).clip(0)])


class ColumnForm:
    """Program (C) of the module docstring in given (original or scaled) units.

    Parameters
    ----------
    U, B : ndarray, shape (m, j)
        Input columns and targets.
    rho : float
        Noise budget ρ (a Frobenius / 2-norm bound, not an rms).
    basis_left : ndarray (m, p), optional
        j = 1 only: 𝓛 = range(basis_left) (orthonormal columns).
    basis_right : ndarray (j, r), optional
        𝓛 = ``{X Qᵀ}`` with ``Q = basis_right`` (orthonormal columns).
    """

    def __init__(self, U, B, rho, *, basis_left=None, basis_right=None):
        self.U = np.asarray(U, float)
        self.B = np.asarray(B, float)
        self.rho = float(rho)
        self.m, self.j = self.U.shape
        self.Ql = basis_left
        self.Qr = basis_right

    def leading_zeros(self) -> np.ndarray:
        """The number p_k of leading zero samples of each input column (j,), i.e. of leading zero rows of
        ``T(u_k)``; the column's length where it is all zero."""
        return _leading_zeros(self.U.reshape(self.U.shape[0], 1, self.j))

    def pinned(self) -> np.ndarray:
        """Mask (m, j) of the targets no impulse reaches: row a of column k when ``a < p_k``
        (:meth:`leading_zeros`), where ``T(u_k) h`` vanishes for every h, so Ξ and 𝓛 alone must take ``B``.

        The column form stays exact there (see :meth:`noise_floor`)."""
        return np.arange(self.m)[:, None] < self.leading_zeros()[None, :]

    def noise_floor(self) -> tuple[float, np.ndarray]:
        """The least noise norm of any feasible point, whatever δ: ``min_{X ∈ 𝓛} ‖(B − X)_Z‖_F`` over the
        :meth:`pinned` entries Z, and the point ``B0 = B − X`` of that minimum nearest to ``P B`` (B's part in
        𝓛^⊥; ``B0 = P B − Y`` with Y ∈ 𝓛 of least norm, so ``‖B0‖² = ‖PB‖² + ‖Y‖²`` is the least too);
        ``(0.0, P B)`` when nothing is pinned.

        Why it is the floor: where ``u_k`` starts with p_k zeros, ``{T(u_k)h}`` is exactly the set of columns
        vanishing in their first p_k rows (the first non-zero sample reaches every later row), so with δ free the
        other rows fit exactly.  (C) needs ``floor < ρ``.  It stays an exact reformulation of Theorem 7.1 on such a
        column: ``T(u_k)h_k`` uses only ``h_k``'s first ``m − p_k`` entries, and the rest can be chosen so that
        ``‖T(h_k)‖₂`` equals the norm of the shorter section (Parrott's theorem, one entry at a time: the
        top rows and the right columns of ``T_{n+1}(h)`` both have the norm of ``T_n(h)``), which is the
        Carathéodory–Fejér bound for the data after the zeros."""
        B0 = self.project(self.B)
        Z = self.pinned()
        if not Z.any():
            return 0.0, B0
        if self.Qr is not None and 0 < self.Qr.shape[1] < self.Qr.shape[0]:
            for a in np.flatnonzero(Z.any(axis=1)):  # row a of Y is y_aᵀQᵀ: least squares on its pinned columns
                cols = Z[a]
                B0[a] -= self.Qr @ _unit_basis_fit(self.Qr[cols], B0[a, cols])
        elif self.Ql is not None and 0 < self.Ql.shape[1] < self.Ql.shape[0]:
            for k in np.flatnonzero(Z.any(axis=0)):  # column k of Y is Q c_k: least squares on its pinned rows
                rows = Z[:, k]
                B0[:, k] -= self.Ql @ _unit_basis_fit(self.Ql[rows], B0[rows, k])
        R = B0[Z]
        return float(np.sqrt(R @ R)), B0

    def project(self, X: np.ndarray) -> np.ndarray:
        """Orthogonal projection onto 𝓛^⊥ (exactly zero when 𝓛 is the whole space: a square orthonormal basis, e.g.
        (7.5) with L optimised on no more columns than the rank of ``[W_p; U_f]``, where ``X − X Q Qᵀ`` would leave
        rounding of ``‖X‖`` that a noise budget at that level could not absorb)."""
        if (self.Ql is not None and self.Ql.shape[1] >= self.Ql.shape[0]) or \
                (self.Qr is not None and self.Qr.shape[1] >= self.Qr.shape[0]):
            return np.zeros_like(X)
        if self.Ql is not None and self.Ql.shape[1]:
            X = X - self.Ql @ (self.Ql.T @ X)
        if self.Qr is not None and self.Qr.shape[1]:
            X = X - (X @ self.Qr) @ self.Qr.T
        return X

    def apply(self, H: np.ndarray) -> np.ndarray:
        """``H̃``: column k is ``T(u_k) h_k``."""
        return conv_cols(self.U, H)

    def apply_T(self, X: np.ndarray) -> np.ndarray:
        """Adjoint of :meth:`apply`: column k is ``T(u_k)ᵀ x_k``."""
        return conv_cols_T(self.U, X)

    def lower_bound(self, V, W, rho: float | None = None) -> float:
        """The weak-duality bound of the module docstring for any ``V`` and ``W``.

        ``W`` is a stack ``(j, m, m)`` (or ``(m, m)`` for j = 1) of dense multipliers, or a pair of
        factor stacks ``(P, Q)`` of shapes ``(j, m, r)`` meaning ``W_k = P_k Q_kᵀ``.
        """
        rho = self.rho if rho is None else float(rho)
        V = np.asarray(V, float).reshape(self.m, self.j, order="F")
        if not np.all(np.isfinite(V)):
            return float("nan")
        V = self.project(V)
        num = float(np.sum(V * self.B)) - rho * float(np.linalg.norm(V))
        if not num > 0.0:
            return 0.0
        g = self.apply_T(V)  # (m, j)
        den = 0.0
        if isinstance(W, CirculantDual):
            return self._circulant_bound(num, g, W)
        if isinstance(W, tuple):
            P, Q = (np.asarray(a, float) for a in W)
            if P.ndim == 2:
                P, Q = P[None], Q[None]
            for k in range(self.j):
                d = g[:, k] - adjoint_lowrank(P[k], Q[k])
                c = d / (self.m - np.arange(self.m))
                den += nuclear_norm_lowrank(P[k], Q[k]) + toeplitz_nuclear_upper(c)
        else:
            Ws = np.asarray(W, float)
            if Ws.ndim == 2:
                Ws = Ws[None]
            if not np.all(np.isfinite(Ws)):
                return float("nan")
            for k in range(self.j):
                den += float(np.linalg.svd(_corrected(Ws[k], g[:, k]), compute_uv=False).sum())
        if not den > 0.0:
            return 0.0
        return max(0.0, num / den)

    def repaired_dual(self, V, W) -> tuple[np.ndarray, np.ndarray]:
        """The dual point that :meth:`lower_bound` evaluates, after its steps 1–2: ``(V, W)`` with V projected
        onto 𝓛^⊥ and each ``W_k`` dense and corrected so that ``T*(W_k) = T(u_k)ᵀ v_k`` holds exactly.

        With them the bound of the module docstring is a direct formula, to be checked by hand:
        ``(⟨V, B⟩ − ρ‖V‖_F) / Σ_k ‖W_k‖_*``.  It equals :meth:`lower_bound` for a dense W and is at least it for a
        factor pair or a :class:`CirculantDual` (whose nuclear norms :meth:`lower_bound` bounds from above).

        Returns
        -------
        V : ndarray, shape (m, j)
        W : ndarray, shape (j, m, m)
        """
        V = self.project(np.asarray(V, float).reshape(self.m, self.j, order="F"))
        if isinstance(W, CirculantDual):
            col = np.zeros(int(W.size))
            col[: np.size(W.column)] = np.ravel(W.column)
            idx = np.arange(self.m)
            Ws = col[np.subtract.outer(idx, idx) % int(W.size)][None]  # the circulant's leading m × m block
        elif isinstance(W, tuple):
            P, Q = (np.asarray(a, float) for a in W)
            Ws = P @ np.swapaxes(Q, -1, -2) if P.ndim == 3 else (P @ Q.T)[None]
        else:
            Ws = np.array(W, float)  # a copy: the certificate's arrays may be read-only
            Ws = Ws[None] if Ws.ndim == 2 else Ws
        g = self.apply_T(V)
        for k in range(self.j):
            Ws[k] = _corrected(Ws[k], g[:, k])
        return V, Ws

    def _circulant_bound(self, num: float, g: np.ndarray, W: CirculantDual) -> float:
        """The bound with a :class:`CirculantDual` W (j = 1), repaired inside the same circulant family:
        adding ``c_d = (g − T*(W))_d/(m − d)`` to the column makes ``T*(W) = g`` exact."""
        col = np.asarray(W.column, float).reshape(-1).copy()
        if self.j != 1 or not self.m <= col.size <= int(W.size) or not np.all(np.isfinite(col)):
            return float("nan")
        scale = self.m - np.arange(self.m)
        col[: self.m] += (g[:, 0] - scale * col[: self.m]) / scale
        den = float(np.abs(np.fft.fft(col, int(W.size))).sum())
        if not den > 0.0:
            return 0.0
        return max(0.0, num / den)


def _unit_basis_fit(Qs: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Least-squares coefficients c (least norm) of ``b ≈ Qs c`` for rows ``Qs`` of an orthonormal basis, whose
    singular values are at most 1: directions below rounding on that unit scale are dropped (``lstsq``'s cut is
    relative to the rows' own largest singular value, and fits b through rows that are zero up to rounding, such as
    the regressor rows of a record at rest, with coefficients of 1e17)."""
    U, s, Vt = np.linalg.svd(Qs, full_matrices=False)
    keep = s > max(Qs.shape) * np.finfo(float).eps
    return Vt[keep].T @ ((U[:, keep].T @ b) / s[keep])


def _leading_zeros(U: np.ndarray) -> np.ndarray:
    """Leading all-zero samples of each column of ``U`` (samples, channels, columns): (columns,) ints."""
    moving = np.any(U != 0.0, axis=1)  # (samples, columns)
    return np.where(moving.any(axis=0), np.argmax(moving, axis=0), U.shape[0])


def scale_dual(W, a: float):
    """``a W`` for any form of norm multiplier: dense (stack), factor pair ``(P, Q)`` (P scaled only,
    ``W = P Qᵀ``) or :class:`CirculantDual`; None stays None.  Solvers work in scaled units and
    hand back duals in data units with this (``T(u)ᵀv = s_u T(u/s_u)ᵀv``: ``a = s_u``)."""
    if W is None:
        return None
    if isinstance(W, CirculantDual):
        return W.scaled(a)
    if isinstance(W, tuple):
        return (W[0] * a, W[1])
    return W * a


class BlockColumnForm(ColumnForm):
    """Program (C) of (7.5) for l × m operators Δ_k (several inputs and outputs).

    Column k of the data holds i samples: ``u_k`` (i·m, the column of ``U_f``, samples stacked) and the
    target ``b_k`` (i·l).  Operator k has Markov parameters ``h_k`` (i, l, m) and acts on its column as
    ``T(h_k) u_k`` (``T(h_k)`` the il × im block lower-triangular Toeplitz matrix)::

        min δ   s.t.   ‖T(h_k)‖₂ ≤ δ  (k = 0 … j−1),   ‖B − H̃ − X‖_F ≤ ρ  for some X ∈ 𝓛,

    ``H̃ = [T(h_0)u_0 … T(h_{j−1})u_{j−1}]`` (il × j), ρ = σ√(ilj).  By the matrix Carathéodory–Fejér
    theorem ‖T(h_k)‖₂ is the least H∞ norm (largest singular value over frequency) of a causal LTI
    operator with those Markov parameters, so δ is the least common bound on ‖Δ_k‖∞ as in the SISO case.

    The lower bound (weak duality), derived as for one channel.  Write ``M_k h = T(h) u_k`` (linear in
    h) and ``M_k*`` for its adjoint, ``(M_k* v)_t = Σ_{s≥t} v_s u_{k,s−t}ᵀ`` (l × m, v_s the s-th block of
    v); write ``T*`` for the adjoint of h ↦ T(h), ``T*(W)_d = Σ_s W[block s+d, block s]`` (the d-th block
    subdiagonal summed; :func:`~unfalsify.solvers.toeplitz.block_adjoint`).  For ANY ``V`` (il × j) and ANY
    ``W_k`` (il × im):

    1. project V onto 𝓛^⊥, so ``⟨V, X⟩ = 0`` for every X ∈ 𝓛;
    2. with ``g_k = M_k* v_k`` replace ``W_k`` by ``W_k + T(c_k)``, ``c_{k,d} = (g_{k,d} − T*(W_k)_d)/(i − d)``
       (``T*(T(c))_d = (i − d) c_d``), so that ``T*(W_k) = g_k`` holds exactly;
    3. for every feasible (δ, h, X, Ξ = B − H̃ − X):
       ``⟨v_k, T(h_k)u_k⟩ = ⟨M_k* v_k, h_k⟩ = ⟨T*(W_k), h_k⟩ = ⟨W_k, T(h_k)⟩ ≤ ‖W_k‖_* ‖T(h_k)‖₂ ≤ δ‖W_k‖_*``
       (the nuclear norm is the dual of the spectral norm), and summing over k,
       ``Σ_k ⟨v_k, T(h_k)u_k⟩ = ⟨V, H̃⟩ = ⟨V, B⟩ − ⟨V, X⟩ − ⟨V, Ξ⟩ ≥ ⟨V, B⟩ − ρ‖V‖_F``;

    so ``δ ≥ (⟨V, B⟩ − ρ‖V‖_F) / Σ_k ‖W_k‖_*`` (and δ ≥ 0), for any (V, W), exact or not.  The multiplier
    ``Z ⪰ 0`` of the LMI ``[δI_im T(h)ᵀ; T(h) δI_il] ⪰ 0`` gives ``W = −2 Z21`` (the il × im block).  With
    l = m = 1 every quantity is that of :class:`ColumnForm` (tested).

    Parameters
    ----------
    U : ndarray, shape (i·m, j)
    B : ndarray, shape (i·l, j)
    rho : float
    n_inputs, n_outputs : int
        m and l.
    basis_right : ndarray (j, r), optional
        𝓛 = ``{X Qᵀ}`` (L optimised).
    """

    def __init__(self, U, B, rho, *, n_inputs: int, n_outputs: int, basis_right=None):
        super().__init__(U, B, rho, basis_right=basis_right)
        self.n_in, self.n_out = int(n_inputs), int(n_outputs)
        self.i = self.U.shape[0] // self.n_in
        if self.U.shape[0] != self.i * self.n_in or self.B.shape != (self.i * self.n_out, self.j):
            raise ValueError(f"U ({self.U.shape}) and B ({self.B.shape}) do not hold i samples of "
                             f"{self.n_in} input(s) and {self.n_out} output(s) per column")
        self.m = self.B.shape[0]  # the rows of V and B (ColumnForm's m)

    def leading_zeros(self) -> np.ndarray:
        """The number p_k of leading zero input samples (m-vectors) of each column (j,)."""
        return _leading_zeros(self.U.reshape(self.i, self.n_in, self.j))

    def pinned(self) -> np.ndarray:
        """Mask (il, j) of the targets no impulse reaches: every output of sample s in column k when ``s < p_k``."""
        return (np.arange(self.m)[:, None] // self.n_out) < self.leading_zeros()[None, :]

    def apply(self, H: np.ndarray) -> np.ndarray:
        """``H̃``: column k is ``T(h_k) u_k`` (H of shape (i, l, m, j))."""
        return block_conv_cols(self.U, H, self.n_in)

    def apply_T(self, X: np.ndarray) -> np.ndarray:
        """Adjoint of :meth:`apply`: ``M_k* x_k`` stacked as (i, l, m, j)."""
        return block_conv_cols_T(self.U, X, self.n_in)

    def repaired_dual(self, V, W) -> tuple[np.ndarray, np.ndarray]:
        """The dual point that :meth:`lower_bound` evaluates, after its steps 1–2: V (il, j) projected onto 𝓛^⊥ and
        W (j, il, im) with ``T*(W_k) = M_k* v_k`` exactly; ``(⟨V, B⟩ − ρ‖V‖_F) / Σ_k ‖W_k‖_*`` is then the bound."""
        V = self.project(np.asarray(V, float).reshape(self.m, self.j, order="F"))
        Ws = self._stack(W)
        g = self.apply_T(V)
        return V, np.stack([self._block_corrected(Ws[k], g[..., k]) for k in range(self.j)])

    def _stack(self, W) -> np.ndarray:
        """``W`` as a stack (j, il, im) of dense multipliers (one (il, im) matrix for j = 1), its shape checked."""
        Ws = np.asarray(W, float)
        Ws = Ws[None] if Ws.ndim == 2 else Ws
        i, l, m = self.i, self.n_out, self.n_in
        if Ws.shape != (self.j, i * l, i * m):
            raise ValueError(f"W must be a stack ({self.j}, {i * l}, {i * m}) of norm multipliers, got {Ws.shape}")
        return Ws

    def _block_corrected(self, Wk: np.ndarray, gk: np.ndarray) -> np.ndarray:
        """``W_k`` plus the block-Toeplitz term that makes ``T*(W_k) = g_k`` exact (step 2 of the bound): block d
        of the i × i lower-triangular block-Toeplitz matrix appears i − d times in the adjoint."""
        i, l, m = self.i, self.n_out, self.n_in
        return Wk + block_toeplitz_matrix((gk - block_adjoint(Wk, i, l, m)) / (i - np.arange(i))[:, None, None])

    def lower_bound(self, V, W, rho: float | None = None) -> float:
        """The weak-duality bound of the class docstring; ``W`` a dense stack (j, il, im) (or (il, im) for j = 1)."""
        rho = self.rho if rho is None else float(rho)
        if W is None:
            return float("nan")
        V = np.asarray(V, float).reshape(self.m, self.j, order="F")
        Ws = self._stack(W)
        if not (np.all(np.isfinite(V)) and np.all(np.isfinite(Ws))):
            return float("nan")
        V = self.project(V)
        num = float(np.sum(V * self.B)) - rho * float(np.linalg.norm(V))
        if not num > 0.0:
            return 0.0
        g = self.apply_T(V)  # (i, l, m, j)
        den = 0.0
        for k in range(self.j):
            den += float(np.linalg.svd(self._block_corrected(Ws[k], g[..., k]), compute_uv=False).sum())
        if not den > 0.0:
            return 0.0
        return max(0.0, num / den)
