"""The Woodbury capacitance of the L-optimised Newton system of (7.5) (:mod:`unfalsify.solvers.column_barrier`).

With L optimised the Hessian in the impulses is block diagonal minus ``c U Uᵀ`` of rank ``r·i``; the Newton
system is solved through the capacitance ``C = Σ_k q_k q_kᵀ ⊗ E_k``, never formed for CG (products cost
O(i r j)): preconditioned by the nearest Kronecker product (Van Loan–Pitsianis, :func:`_kronecker_preconditioner`),
with the m common-impulse directions, which carry its smallest eigenvalues, deflated exactly
(:func:`_common_impulse_basis`, :class:`_Deflation`); or formed and factored densely where that costs less
(:func:`_dense_capacitance_factor`).
"""
from __future__ import annotations

import numpy as np
import scipy.linalg

from .stacks import _SERIAL, _Chunks


def _kronecker_preconditioner(Q: np.ndarray, E: np.ndarray, sweeps: int = 4):
    """``(A⁻¹, B⁻¹)`` of the nearest Kronecker product ``A ⊗ B`` to ``C = Σ_k q_k q_kᵀ ⊗ E_k`` (Van Loan–Pitsianis).

    In matrix form C maps Y (m × r) to ``Σ_k E_k Y q_k q_kᵀ``; if every ``E_k = w_k B`` it is exactly
    ``B Y A`` with ``A = Σ_k w_k q_k q_kᵀ``.  Alternating least squares on the rank-one approximation of
    the rearranged C: ``A ∝ Σ_k ⟨E_k, B⟩ q_k q_kᵀ``, ``B ∝ Σ_k (q_kᵀ A q_k) E_k``, starting from ``B = mean E_k``.
    """
    j, m = E.shape[0], E.shape[1]
    E2 = E.reshape(j, m * m)
    B = E.mean(axis=0)
    for _ in range(sweeps):
        wa = E2 @ B.ravel()
        A = (Q.T * wa) @ Q
        # q_kᵀ A q_k by a product (a three-operand einsum loops over (k, r, s) in C: 10 of the 50 serial seconds of
        # the L-optimised solve at (100, 1000))
        wb = np.einsum("kr,kr->k", Q @ A, Q)
        B = (wb @ E2).reshape(m, m) / max(float(np.sum(A * A)), 1e-300)
    return np.linalg.inv(0.5 * (A + A.T)), np.linalg.inv(0.5 * (B + B.T))


def _common_impulse_basis(U: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """Orthonormal basis ``(m, m, r)`` of the capacitance directions ``Y_a = Z_a U Q`` (Z_a: shift by a).

    ``Y Qᵀ = T(l) U`` for ``Y = Σ_a l_a Y_a`` (U's rows lie in 𝓛's row space), and
    ``T(u_k) l = T(l) u_k``: the move of the L variable that the common impulse change ``dh_k = l``
    cancels in every column.  The noise term does not see these m directions, only the LMI blocks do,
    so they carry the smallest eigenvalues of the capacitance (measured at (i, j) = (100, 1000),
    t = 4.9·10⁵: the Kronecker-preconditioned spectrum's smallest Ritz values, 7.5e-4 to 3e-3, lie
    in this subspace).
    """
    m = U.shape[0]
    UQ = U @ Q
    Y = np.zeros((m, m, Q.shape[1]))
    for a in range(m):
        Y[a, a:] = UQ[: m - a]
    basis, _ = np.linalg.qr(Y.reshape(m, -1).T)
    return basis.T.reshape(Y.shape)


class _Deflation:
    """Deflation of ``span W`` in CG on ``C`` (Saad, Yeung, Erhel & Guyomarc'h 2000).

    With ``E = Wᵀ C W``, CG starts at ``x₀ = W E⁻¹ Wᵀ b`` (the residual is then orthogonal to W) and
    keeps its search directions C-orthogonal to W (:meth:`project`): the iteration runs on the
    C-orthogonal complement of span W, whose smallest eigenvalues are those that slowed it.  The
    solution is that of C x = b; one read of W and of CW per iteration, split over ``chunks``' threads (W and CW are
    24 MB each at (100, 1000), so these reads are memory-bound: 11 of the 50 serial seconds of that solve with L
    optimised when they ran on the main thread).
    """

    def __init__(self, Cmul, W: np.ndarray, chunks: _Chunks = _SERIAL):
        k = W.shape[0]
        self.chunks = chunks
        self.W2 = W.reshape(k, -1)
        self.CW = Cmul(W).reshape(k, -1)
        E = self._gram(self.W2, self.CW)
        self.L = np.linalg.cholesky(0.5 * (E + E.T))  # LinAlgError: E not numerically positive definite

    def _gram(self, V2, X2) -> np.ndarray:
        """``V2 X2ᵀ``, summed over column chunks of the long axis on the threads."""
        return sum(self.chunks.map(lambda s: V2[:, s] @ X2[:, s].T, V2.shape[1], V2.size))

    def _combine(self, c, V2) -> np.ndarray:
        """``c V2`` (p, N), its columns in chunks on the threads."""
        out = np.empty((c.shape[0], V2.shape[1]))
        self.chunks.map(lambda s: np.matmul(c, V2[:, s], out=out[:, s]), V2.shape[1], V2.size)
        return out

    def _solve(self, V2, X2):
        """``E⁻¹ V2 X2ᵀ`` transposed: (p, k)."""
        return scipy.linalg.cho_solve((self.L, True), self._gram(V2, X2)).T

    def start(self, B: np.ndarray):
        """``(x₀, b − C x₀)`` for the stack B (p, …)."""
        B2 = B.reshape(B.shape[0], -1)
        c = self._solve(self.W2, B2)
        return self._combine(c, self.W2).reshape(B.shape), (B2 - self._combine(c, self.CW)).reshape(B.shape)

    def project(self, Z: np.ndarray) -> np.ndarray:
        """``Z − W E⁻¹ (CW)ᵀ Z``: C-orthogonal to span W."""
        Z2 = Z.reshape(Z.shape[0], -1)
        return (Z2 - self._combine(self._solve(self.CW, Z2), self.W2)).reshape(Z.shape)


def _dense_capacitance_factor(E: np.ndarray, Q: np.ndarray):
    """A factor of the capacitance ``C = Σ_k q_k q_kᵀ ⊗ E_k`` formed as an (mr × mr) matrix (row-major (m, r) order).

    Cholesky where C is numerically positive definite (its smallest pivot² above ``mr·eps`` of the largest diagonal
    entry); else the symmetric eigendecomposition with the directions below ``mr·eps`` of the largest eigenvalue
    dropped: in the ill-conditioned limit (a noise ball far inside the residual, E_k inheriting cond T(u_k)) those
    are the directions the rounding of C already leaves undetermined."""
    j, m, r = E.shape[0], E.shape[1], Q.shape[1]
    QQ = (Q[:, :, None] * Q[:, None, :]).reshape(j, r * r)
    # symmetric to rounding (each E_k is); LAPACK's potrf and syevd read one triangle, so no symmetrising pass (a
    # strided transpose: 43 ms of 100 at order 1200)
    C = (E.reshape(j, m * m).T @ QQ).reshape(m, m, r, r).transpose(0, 2, 1, 3).reshape(m * r, m * r)
    floor = m * r * np.finfo(float).eps * max(float(np.max(np.diag(C))), 0.0)
    try:
        L = np.linalg.cholesky(C)
        if float(np.min(np.diag(L))) ** 2 > floor:
            return ("cholesky", L)
    except np.linalg.LinAlgError:
        pass
    w, V = np.linalg.eigh(C)
    keep = w > max(float(w[-1]), 0.0) * m * r * np.finfo(float).eps
    return ("eigen", w[keep], V[:, keep])


def _dense_capacitance_apply(factor, B: np.ndarray) -> np.ndarray:
    """``C⁺ B`` for a stack B (p, m, r) by :func:`_dense_capacitance_factor`'s factor."""
    rhs = B.reshape(B.shape[0], -1).T
    if factor[0] == "cholesky":
        X = scipy.linalg.cho_solve((factor[1], True), rhs)
    else:
        _, w, V = factor
        X = V @ ((V.T @ rhs) / w[:, None])
    return X.T.reshape(B.shape)


class _Capacitance:
    """The capacitance ``C = Σ_k q_k q_kᵀ ⊗ E_k`` of one Newton system, for as many solves as use it (the primal–dual
    method's predictor and corrector): for CG its product, Kronecker preconditioner and deflation, or its dense
    factor, each built on first use."""

    def __init__(self, system, E: np.ndarray):
        self.system, self.E = system, E
        self._cg = self._factor = None

    def cg(self):
        """``(Cmul, (A⁻¹, B⁻¹), deflation)`` (:meth:`_ColumnSystem._capacitance`, :func:`_kronecker_preconditioner`,
        :func:`_deflation`)."""
        if self._cg is None:
            sys_ = self.system
            Cmul = sys_._capacitance(self.E)
            self._cg = (Cmul, _kronecker_preconditioner(sys_.Q, self.E), _deflation(Cmul, sys_.W, sys_.chunks))
        return self._cg

    def solve_dense(self, B: np.ndarray) -> np.ndarray:
        """``C⁺ B`` by the dense factor (:func:`_dense_capacitance_factor`)."""
        if self._factor is None:
            self._factor = _dense_capacitance_factor(self.E, self.system.Q)
        return _dense_capacitance_apply(self._factor, B)


def _deflation(Cmul, W, chunks: _Chunks = _SERIAL):
    """:class:`_Deflation` of ``span W``, or None if ``Wᵀ C W`` is not numerically positive definite."""
    try:
        return _Deflation(Cmul, W, chunks)
    except np.linalg.LinAlgError:
        return None
