"""Solver ``"column_barrier"``: barrier method for the subspace program (7.5) in the column form (C).

Barrier method (Boyd & Vandenberghe §11.3) on the ij + 1 variables (H, δ) of (C), the predictor
eliminated by projection (:mod:`unfalsify.solvers.columns`):

    f_t(H, δ) = t δ − Σ_k log det F_k(h_k, δ) − w log ψ,   ψ = ρ² − ‖P(B − H̃)‖²_F,
    F_k = [δI T(h_k)ᵀ; T(h_k) δI]      (the LMI of (7.5) per column, conditioned form),

P the projection onto 𝓛^⊥ (𝓛 = {0} with L fixed, ``{X Qᵀ}`` with L optimised).  The noise barrier
carries the weight ``w = √(2ij)`` (a weighted barrier, parameter ν = 2ij + w, duality gap ν/t on the
central path): with w = 1 the single noise constraint is swamped by the 2ij LMI terms and the iterates
crowd its boundary (measured at (i, j) = (5, 60): ψ collapsing after every increase of t, tens of short
steps to recover, and status "failed" after 364 Newton steps with w = 1; certified in 29 steps with
w = 60).  Structure used:

* **Cholesky instead of SVD.**  ``K_k = δ²I − T_kᵀT_k`` (T_k = T(h_k)) is the Schur complement of
  F_k: ``log det F_k = log det K_k``, F_k ≻ 0 ⟺ the Cholesky of K_k exists (the line search's
  feasibility test), and ``F_k⁻¹ = [δK⁻¹, −K⁻¹Tᵀ; −TK⁻¹, (I + TK⁻¹Tᵀ)/δ]``.  Batched over the j columns.
  K⁻¹ is formed only at points whose slope or Newton step is needed (a trial point of a path step needs
  log det K alone), and the Gram stack ``T_kᵀT_k`` comes from an O(i²) recursion from i = 32 on.
* **Hessian from displacement generators.**  ``tr(F⁻¹E_aF⁻¹E_b)`` for every column at once by
  :func:`~unfalsify.solvers.displacement.displacement_hessian` (O(i²) a column), not the 2-D FFT
  cross-correlations of :func:`~unfalsify.solvers.toeplitz.corr_hessian` (O(i² log i) at the FFT's rate):
  measured on one thread for the stacks of the benchmark, 16 against 20 ms at (20, 400), 81 against 243 ms
  at (50, 500), 136 against 526 ms for 250 columns of i = 100.  Its cumulative sums keep about 1e-13 of the
  largest entry, so below a path gap of 1e-7·δ, and from the first step whose decrement it leaves
  non-positive, the FFT Hessian takes over (as in :mod:`~unfalsify.solvers.arx_barrier`).
* **Newton system without O(n⁴) storage.**  The Hessian in H is block diagonal (j blocks i × i: the barrier plus
  ``c T(u_k)ᵀT(u_k)``, c = 2w/ψ) plus the rank-one noise term ``(4w/ψ²) g gᵀ`` and, with L optimised, minus ``c U Uᵀ``,
  ``U = Mᵀ(Q ⊗ I)`` (M: H ↦ H̃), of rank r·i = 3i².  L fixed: one LU solve per block + Sherman–Morrison + the Schur
  complement of the δ row (exact, O(j i³)).  L optimised: Woodbury with the capacitance ``C = Σ_k q_k q_kᵀ ⊗ E_k``
  (``q_k`` row k of Q, ``E_k = (cI + c² T(u_k) G_k⁻¹ T(u_k)ᵀ)⁻¹``, G_k the barrier block) solved by preconditioned
  conjugate gradients; C is never formed (products cost O(i r j)), memory O(j i²).  Up to an order i·r of
  :data:`_DENSE_CAPACITANCE`, C is formed and factored densely
  (:func:`~unfalsify.solvers.capacitance._dense_capacitance_factor`) once a CG solve has cost more than that
  (:meth:`_ColumnSystem._dense_cheaper`) or stopped short of its tolerance after i·r iterations (the bound of exact
  arithmetic), and for the rest of the solve: a noise ball far inside the residual makes C ill-conditioned and CG long
  (measured at (20, 400), σ = 0.01 × the least-squares rms: 88 000 CG iterations and 53 s with CG alone, 4.2 s with
  the switch; at σ = ½ the rms CG stays, 13 iterations a solve).
* **Steps.**  After each centring t grows by ``mu`` (5), and the centring at μt starts from the best (lowest
  ``f_{μt}``) of the centred point and the two predictions of
  :func:`~unfalsify.solvers.barrier.path_predictor` (the tangent linear in 1/t, and the Hermite cubic through the
  last two centred points), each backtracked to strict feasibility — the rule of
  :mod:`~unfalsify.solvers.arx_barrier`.  Measured (servo data of the benchmark, seed 0, tol 1e-4), Newton steps
  before → after, L fixed / L optimised: (10, 200) 33 → 23 / 33 → 24, (20, 400) 36 → 28 / 37 → 29, (50, 500)
  47 → 31 / 42 → 34, (100, 1000) 48 → 41 / 52 → 48.  Longer steps cost more Newton steps in all:
  measured at (i, j) = (50, 500), 42 steps with μ = 5 against 60 with μ = 20 and 63 with μ = 60, and at
  (100, 1000) with L fixed, certified in 60 steps with μ = 5 while with μ = 20 one column pinned at
  ‖T(h_k)‖ = δ crawled for 30 full Newton steps of 7e-5 each in the second centring.  Steps use a safeguarded secant line search
  on the slope of f_t (function values lose their digits at large t), not the short damped step.

* **Warm starts** (``warm=``, :meth:`_ColumnBarrier.warm`).  Every centred point is recorded (impulses, δ,
  relative gap ``ν/(tδ)``, slacks); a related problem (window advanced by k samples: old columns k… are the
  new columns 0…; or another σ) resumes from the last recorded point at gap ≥ 0.3 (chosen by the front end),
  made strictly feasible, at that gap's t.  Later points hug the boundaries and stalled after the data moved
  (measured at (20, 400): 60 Newton steps at λ² ≈ 3 after a one-sample advance); a resumed path that still
  stalls, or whose centrings stop converging twice (:data:`_WARM_MAX_STAGNATIONS`), is re-solved cold.  (The
  stagnating warm paths measured with L optimised had one new column pressed against δ: its K's smallest
  eigenvalue 2e-5·δ² against a median of 0.016·δ² over the columns.)  The tail of the path (about 4 steps per
  centring, set by ``_NOISE_KEEP``) is what a warm start cannot skip: 23–33 Newton steps against 36–38 cold there.
* **Lower bounds when they can close the gap.**  The bound costs j SVDs; it is evaluated once ``ν/t`` is
  within :data:`_BOUND_FACTOR` × tol of δ (:meth:`_ColumnBarrier.bound_due`), and at the last centring whatever
  ends the solve.

* **Threads over columns.**  The stacks (products, Cholesky factors, FFT Hessians) are split into
  contiguous column chunks run on a thread pool (:mod:`unfalsify.solvers.stacks`, ``workers=``), BLAS held to one
  thread per worker.

Every centred iterate gives a dual point (``W_k = −2 (F_k⁻¹ − F_k⁻¹ΔF_kF_k⁻¹)_{21}/t`` and the noise
multiplier, linearised with the last Newton step), bounded by :meth:`ColumnForm.lower_bound`: the
stopping rule and the returned bracket use that **certified** gap whatever the accuracy of the Newton
solves.

Conditioning of the L-optimised solves (measured at (i, j) = (100, 1000)): once t ≳ 5·10⁵ the noise
slack ψ is small, so the noise curvature c = 2w/ψ is large and ``E_k → T(u_k)⁻ᵀ G_k T(u_k)⁻¹`` inherits
cond T(u_k) (up to 1e30 for ±1 input windows) and varies from column to column; the Kronecker
preconditioner alone then needed 1000+ CG iterations per solve (Ritz values of the preconditioned
capacitance from 7.5e-4 to 22).  The smallest eigenvalues belong to the m common-impulse directions
(``dh_k = l`` for every k: ``T(u_k) l = T(l) u_k`` lies in 𝓛, so the noise term does not see them),
which the CG deflates exactly (:mod:`unfalsify.solvers.capacitance`): 308 iterations
for the same solve.  The line search keeps at least half of ψ per step (:meth:`_ColumnBarrier._noise_step`):
letting ψ fall 99 % of the way to the boundary had sent it from 106 to 0.026 in six steps after t grew,
far below its value at the next centre (8.6), and 40+ Newton steps crawled back.
"""
from __future__ import annotations

import os

import numpy as np

from synthesis.validation import DataError

from .barrier import (Deadline, PathAdvance, Stop, best_along, delta_step, linearised_dual, path_steps, pcg,
                      run_barrier)
from .base import SolverOutput, one_blas_thread, unscaled, zero_answer
from .capacitance import _Capacitance, _common_impulse_basis, _Deflation
from .columns import ColumnForm
from .displacement import displacement_hessian
from .stacks import (_SERIAL, _block_solve, _blocks_of, _BlockSum, _bmv, _chol_logdet, _Chunks, _inner, _max_norm,
                     _shifted, _spd_inverse, _stack_of, _StackPool, _sym_inverse_into)
from .start import cold_impulses, coordinates, impulses, operator_svd, ridge_fit, start_target
from .toeplitz import _tr, adjoint, corr_hessian, toeplitz_gram_stack, toeplitz_stack
from .wider_ball import tighten_lower

__all__ = ["solve", "solve_columns_barrier", "check_workers"]


def _new_pool() -> _StackPool:
    """A stack pool for one solve (bypassed on the former route)."""
    return _StackPool(bypass=_STEP_ROUTE["route"] == "former")


def _chunked_hessian(S11, S21, S22, chunks: _Chunks = _SERIAL, precise: bool = False, out: np.ndarray | None = None):
    """The barrier Hessian of every column over the stack in chunks (bounded workspace), on ``chunks``' threads;
    with it ``T*(S21_k S11_k)`` per column (``cross=True``), shape (m, j), as :func:`adjoint`.

    By :func:`~unfalsify.solvers.displacement.displacement_hessian` (O(m²) per column), or by the 2-D FFT of
    :func:`~unfalsify.solvers.toeplitz.corr_hessian` when ``precise``, below m = :data:`_DISPLACEMENT_FROM` (and on the
    former route): the displacement route's cumulative sums keep about 1e-13 of the largest entry against the
    FFT's 1e-16.  The Hessian stack goes into ``out`` if given."""
    j, m = S11.shape[0], S11.shape[1]
    if out is None:
        out = np.empty((j, m, m))
    cross = np.empty((j, m))
    fft = precise or _STEP_ROUTE["route"] == "former" or m < _DISPLACEMENT_FROM

    def work(s):
        for sl in _blocks_of(s, m * m):
            if fft:
                out[sl], cross[sl] = corr_hessian(S11[sl], S21[sl], S22[sl], m, cross=True)
            else:
                out[sl], cross[sl] = displacement_hessian(S11[sl], S21[sl], S22[sl], cross=True)

    chunks.map(work, j, S11.size)
    return out, cross.T


class _Point:
    """The barrier's blocks at (H, δ): ``T_k``, ``T_kᵀT_k``, log det of the Cholesky-checked ``K_k``, its inverse
    (formed when first needed: a trial point of a path step needs only f, i.e. log det K), the residual.

    The stacks derived from K⁻¹ are formed in two passes over the columns, each block of :data:`_BLOCK_BYTES` on the
    chunks' threads carried through every product and elementwise step and its sums while it is in cache:
    (K⁻¹, S21, and the slope's ``Σ tr K⁻¹``, ``⟨K⁻¹, TᵀT⟩``, ``T*(S21)``), then (S11, S22, and ``‖F⁻¹‖²_F``).  (Whole-
    stack steps had left these sums, the adjoint and the elementwise steps to the main thread: 10 of 56 s at
    (100, 1000) with L fixed.)"""

    def __init__(self, H, d, T, TtT, logdet, r, psi, chunks: _Chunks = _SERIAL, pool: _StackPool | None = None):
        self.H, self.d, self.T, self.TtT = H, d, T, TtT
        self.logdet, self.r, self.psi = logdet, r, psi
        self.chunks = chunks
        self.pool = pool if pool is not None else _new_pool()
        self._blocks = None
        self._first = None  # (K⁻¹, S21, Σ tr K⁻¹, ⟨K⁻¹, TᵀT⟩, T*(S21))
        self._upper = None
        self._norm2 = None  # ‖F⁻¹‖²_F summed over the columns

    def _first_pass(self):
        """K⁻¹, ``S21 = −T K⁻¹`` and the slope's sums, block by block."""
        if self._first is None:
            T, TtT, shift = self.T, self.TtT, self.d * self.d
            j, m = T.shape[0], T.shape[1]
            Kinv, S21 = self.pool.take(T.shape), self.pool.take(T.shape)
            adj = np.empty((m, j))

            def work(s):
                trK = inner = 0.0
                for b in _blocks_of(s, m * m):
                    _sym_inverse_into(_shifted(TtT[b], shift), Kinv[b])
                    np.matmul(T[b], Kinv[b], out=S21[b])
                    np.negative(S21[b], out=S21[b])
                    trK += float(np.trace(Kinv[b], axis1=1, axis2=2).sum())
                    inner += _inner(Kinv[b], TtT[b])
                    adj[:, b] = adjoint(S21[b])
                return trK, inner

            parts = self.chunks.map(work, j, T.size)
            self._first = (Kinv, S21, sum(p[0] for p in parts), sum(p[1] for p in parts), adj)
        return self._first

    @property
    def Kinv(self) -> np.ndarray:
        """``K_k⁻¹ = (δ²I − T_kᵀT_k)⁻¹`` (computed once)."""
        return self._first_pass()[0]

    @property
    def S21(self) -> np.ndarray:
        """``−T K⁻¹`` (computed once): the slope of the line search reads it, the Newton step's blocks reuse it."""
        return self._first_pass()[1]

    def adjoint_S21(self) -> np.ndarray:
        """``T*(S21_k)`` per column, shape (m, j) (:func:`~unfalsify.solvers.toeplitz.adjoint`)."""
        return self._first_pass()[4]

    def blocks(self):
        """``(S11, S21, S22)`` of ``F⁻¹``: ``δK⁻¹``, ``−TK⁻¹``, ``(I + TK⁻¹Tᵀ)/δ`` (computed once)."""
        if self._blocks is None:
            Kinv, S21 = self.Kinv, self.S21
            T, d = self.T, self.d
            j, m = T.shape[0], T.shape[1]
            S11, S22 = self.pool.take(T.shape), self.pool.take(T.shape)
            diag = np.arange(m)

            def work(s):
                total = 0.0
                for b in _blocks_of(s, m * m):
                    P = np.matmul(S21[b], _tr(T[b]))  # −T K⁻¹ Tᵀ
                    np.negative(P, out=P)
                    P[:, diag, diag] += 1.0
                    np.add(P, _tr(P), out=S22[b])
                    S22[b] *= 0.5 / d
                    np.multiply(Kinv[b], d, out=S11[b])
                    total += _inner(S11[b], S11[b]) + _inner(S22[b], S22[b]) + 2.0 * _inner(S21[b], S21[b])
                return total

            self._norm2 = float(sum(self.chunks.map(work, j, T.size)))
            self._blocks = (S11, S21, S22)
        return self._blocks

    def norm2(self) -> float:
        """``Σ_k ‖F_k⁻¹‖²_F = Σ_k (‖S11‖² + ‖S22‖² + 2‖S21‖²)`` (the δ–δ entry of the Hessian)."""
        self.blocks()
        return self._norm2

    def trace_S(self) -> float:
        """``Σ_k tr F_k⁻¹ = Σ_k (δ tr K⁻¹ + (m + ⟨K⁻¹, TᵀT⟩)/δ)`` (no block products)."""
        m, j = self.H.shape
        _, _, trK, inner, _ = self._first_pass()
        return self.d * trK + (m * j + inner) / self.d

    def upper(self) -> float:
        """``max_k ‖T(h_k)‖₂`` as ``√λ_max(T_kᵀT_k)`` (LAPACK ``syevd`` values of the Gram stack, a third
        of the SVDs' cost; the certificate recomputes the norms from the impulses on its own); computed once."""
        if self._upper is None:
            self._upper = _max_norm(self.TtT, self.chunks)
        return self._upper


#: Order m·r of the capacitance up to which it is factored densely where CG costs more, or fails
#: (:func:`_dense_capacitance_factor`: forming and factoring C at order 1200 takes about 0.1 s on one core, an
#: eigendecomposition 0.3 s; at order 7500, (50, 500), the Cholesky factor alone would take about 5 s).  Measured on a
#: fuzzed record (i, j) = (4, 38), L optimised, σ = 1e-10 against a least-squares rms of 7.6e-3: CG took a median of
#: 449 iterations on a capacitance of order 48 (42 of 525 solves stopped at 2000), the solve 34.6 s and 521 Newton
#: steps; with the dense route 4 s, and a tighter bracket (both end ``failed``: the noise ball is at the data's
#: rounding).
_DENSE_CAPACITANCE = 1200
#: The route of the Newton steps: ``"current"``, or ``"former"`` (the FFT Hessian, the Gram by products, K⁻¹ at every
#: trial point, the block inverse in the L-fixed Newton system, the path steps from the centred point itself: the
#: route before issue 27's changes to this solver, :func:`unfalsify.solvers.baselines.former_routes`).
_STEP_ROUTE = {"route": "current"}
#: Block size m from which the Hessian comes from displacement generators (:func:`_chunked_hessian`); below it the
#: FFT is faster (one thread, stacks of 200–400: m = 5 0.6 against 2.7 ms, m = 10 2.3 against 3.9 ms, m = 16 11.9
#: against 15.5 ms, m = 20 equal at 18.6 ms).
_DISPLACEMENT_FROM = 24
#: Block size m from which the Gram stack is formed by the O(m²) recursion (:meth:`_ColumnBarrier._gram`).
_GRAM_RECURSION_FROM = 32
#: Below this relative gap of the path (ν/t < _PRECISE_GAP·δ) the Hessian is the FFT's (:func:`_chunked_hessian`),
#: as in :mod:`~unfalsify.solvers.arx_barrier`, whose tol 1e-9 solves stalled on the displacement route's rounding.
_PRECISE_GAP = 1e-7
#: The lower bound is evaluated once the path's gap ν/t is within this factor of the tolerance (``bound_due``).
_BOUND_FACTOR = 100.0
#: Warm start (:meth:`_ColumnBarrier.warm`): the noise slack kept, as a fraction of the old centre's.
_WARM_PSI = 0.5
#: Warm start: a centring ends when λ² ≤ _FAR_DECREMENT has not halved over this many Newton steps.
_WARM_STAGNATION = 4
#: Warm start: the centrings ended by the stagnation rule after which the warm path is given up for a cold solve.
#: Measured at (20, 400), L optimised, servo data, windows advanced by 1–50 samples (seeds 0–2): the 4 warm paths that
#: failed had stagnated in 8–9 centrings each (66–125 Newton steps before the cold re-solve, 3–4.7× a cold solve);
#: of the 8 that certified, 7 never stagnated and one once.
_WARM_MAX_STAGNATIONS = 2
#: New columns of a warm start keep ``‖T(h_k)‖₂`` at most this fraction of the old δ (:meth:`_capped_ridge`).
_WARM_CAP = 0.9
#: The longest line-search step, in Newton steps.
_MAX_STEP = 1.0
#: Fraction of the noise slack ψ a line-search step must keep (``_noise_step``).
_NOISE_KEEP = 0.5
#: Newton decrement λ² above which a step counts as far from the centre (inexact CG, see ``_centre``).
_FAR_DECREMENT = 10.0
#: Relative CG residual of the Newton solves far from the centre (L optimised).
_CG_TOL_FAR = 1e-3


class _ColumnSystem:
    """What the column methods share: the data's Toeplitz stacks, the threads and stack pool, and the solve of
    their Newton (barrier) or Schur-complement (primal–dual) system

        (D − c U Uᵀ + α g gᵀ) X = R,   D = blockdiag(G_k + c T(u_k)ᵀT(u_k)),

    G_k the LMI blocks' curvature (the barrier Hessian, or the same form with the NT scaling in place of F⁻¹),
    c the curvature of the noise cone along 𝓛^⊥ and ``α g gᵀ`` its rank-one part (module docstring, "Newton
    system without O(n⁴) storage")."""

    def __init__(self, form: ColumnForm, *, cg_tol=1e-8, cg_maxiter=2000, chunks: _Chunks = _SERIAL):
        self.f = form
        self.chunks = chunks
        self.pool = _new_pool()  # the stacks of the points and Newton steps, reused (page faults at (100, 1000))
        self.m, self.j = form.m, form.j
        self.cg_tol, self.cg_maxiter = cg_tol, cg_maxiter
        self.far = False  # the next Newton solve is far from the centre (inexact CG, see pcg_tol)
        self.Tu = toeplitz_stack(form.U)
        self.TuTu = _tr(self.Tu) @ self.Tu
        self.Q = form.Qr if (form.Qr is not None and form.Qr.shape[1]) else None
        self.W = _common_impulse_basis(form.U, self.Q) if self.Q is not None else None
        self.cg_iters = 0
        self.dense_solves = 0  # capacitance solves by its dense factor (_lowrank_correction)
        self.dense_capacitance = False  # from the first CG solve that cost more than the dense one: dense only

    def _resid(self, H):
        return self.f.project(self.f.B - self.f.apply(H))

    def _gram(self, H):
        """``(T_k, T_kᵀT_k)`` stacks of the impulses H (the Gram by the O(m²) recursion from m = 32 on; measured
        at (100, 1000), one thread: 49 ms against 168 ms for the products, 6 against 16 ms at (50, 500), 1.2
        against 0.6 ms at (20, 400))."""
        shape = (self.j, self.m, self.m)
        T = _stack_of(H, self.chunks, self.pool.take(shape))
        if self.m < _GRAM_RECURSION_FROM or _STEP_ROUTE["route"] == "former":
            return T, self.chunks.matmul(_tr(T), T, out=self.pool.take(shape))
        G = self.pool.take(shape)

        def work(s):
            toeplitz_gram_stack(H[:, s], out=G[s])

        self.chunks.map(work, self.j, T.size)
        return T, G

    def _solve_h(self, G, cc, alpha, g, R, woodbury=None):
        """Solve ``(D − c U Uᵀ + α g gᵀ) X = R`` (class docstring; U Uᵀ only with L optimised); returns X and the
        Woodbury parts of L optimised (``woodbury``: those of an earlier solve with the same G and c, reused)."""
        D = _BlockSum(G, self.TuTu, cc)  # D = G + c T(u)ᵀT(u), formed block by block where it is used
        rhs = np.concatenate([R, g[..., None]], axis=-1)
        if self.Q is None and _STEP_ROUTE["route"] != "former":
            # p + 1 right-hand sides: one LU solve per block (⅔m³) instead of the inverse (2⅔m³)
            Y = _block_solve(D, rhs, self.chunks)
        else:  # the Woodbury correction applies D⁻¹ once more
            if _STEP_ROUTE["route"] == "former":  # by the inverse stack
                Dinv = _spd_inverse(D, self.chunks, out=self.pool.take(G.shape))

                def solve(X):
                    return _bmv(Dinv, X)
            else:  # by two LU solves per block (1⅓m³) instead of the inverse (2⅔m³)
                def solve(X):
                    return _block_solve(D, X, self.chunks)
            Y = solve(rhs)
            if self.Q is not None:
                if woodbury is None:
                    woodbury = self._woodbury(G, cc)
                Y = Y + self._lowrank_correction(woodbury, solve, rhs, Y)
        Xr, xg = Y[..., :-1], Y[..., -1]
        # Sherman–Morrison for the rank-one term
        coef = alpha / (1.0 + alpha * float(np.sum(g * xg)))
        return Xr - xg[..., None] * (coef * np.einsum("ik,ikp->p", g, Xr))[None, None, :], woodbury

    def _woodbury(self, G, cc):
        """The capacitance ``C = c⁻¹I − UᵀD⁻¹U = Σ_k q_k q_kᵀ ⊗ E_k`` of :meth:`_lowrank_correction` as its product,
        Kronecker preconditioner and deflation: ``(Cmul, (A⁻¹, B⁻¹), deflation)``.

        ``E_k = (cI + c² T(u_k) G_k⁻¹ T(u_k)ᵀ)⁻¹`` equals ``c⁻¹I − T(u_k) D_k⁻¹ T(u_k)ᵀ`` without its
        cancellation."""
        m, Tu = self.m, self.Tu
        take, mm = self.pool.take, self.chunks.matmul
        X = mm(Tu, _spd_inverse(G, self.chunks, out=take(G.shape)), out=take(G.shape))
        X = mm(X, _tr(Tu), out=take(G.shape))  # T(u_k) G_k⁻¹ T(u_k)ᵀ
        X *= cc * cc
        X[:, np.arange(m), np.arange(m)] += cc
        E = _spd_inverse(X, self.chunks, out=take(G.shape))
        del X
        return _Capacitance(self, E)

    def _dense_cheaper(self, iterations: int, rhs: int) -> bool:
        """Whether ``iterations`` CG iterations on ``rhs`` right-hand sides cost more than forming and factoring the
        capacitance densely.  Flop counts weighted by their measured rates (one core): a CG iteration's products,
        ``4 m r j + 2 m² j`` per right-hand side, and its preconditioner and deflation about as much again, run at
        about twice the rate of the dense route's ``j m² r²`` (forming C) and ``(mr)³/3`` (Cholesky).  Measured break-even
        (iterations, 3 right-hand sides): 2 at (i, j) = (4, 60), 24–28 at (10, 200), 160–230 at (20, 400); this rule
        gives 4, 32 and 172."""
        m, j, r = self.m, self.j, self.Q.shape[1]
        dense = j * m * m * r * r + (m * r) ** 3 / 3.0
        return iterations * rhs * (4.0 * m * r * j + 2.0 * m * m * j) > dense

    def _lowrank_correction(self, woodbury, solve, rhs, Y, tol: float | None = None):
        """Woodbury: ``D⁻¹U C⁻¹ Uᵀ D⁻¹ rhs`` with C of :meth:`_woodbury` by PCG (relative residual ``tol``, default
        :meth:`pcg_tol`); ``solve(X)`` is ``D_k⁻¹ X[:, k, :]`` per column and ``Y = solve(rhs)``.

        Preconditioner: the nearest Kronecker product ``A ⊗ B`` to C (:func:`_kronecker_preconditioner`), with the
        m common-impulse directions (:func:`_common_impulse_basis`) deflated (:class:`_Deflation`).  Vectors are
        stacks (p, m, r) (p right-hand sides); a product costs O(p m r j + p m² j) and C is never formed.
        """
        Q, Tu = self.Q, self.Tu
        YT = np.moveaxis(Y, 2, 0)  # (p, m, j)
        TuY = np.moveaxis(np.moveaxis(YT, 2, 0) @ _tr(Tu), 0, 2)  # column k: T(u_k) y_k
        Ut_b = TuY @ Q  # Uᵀ D⁻¹ rhs, (p, m, r)
        order = self.m * Q.shape[1]
        small = order <= _DENSE_CAPACITANCE
        if small and self.dense_capacitance:
            Z = woodbury.solve_dense(Ut_b)
            self.dense_solves += 1
        else:
            Cmul, (Ainv, Binv), deflation = woodbury.cg()
            # CG converges within the capacitance's order in exact arithmetic; beyond it, small systems go dense
            maxiter = min(self.cg_maxiter, order) if small else self.cg_maxiter
            Z, iterations = self._pcg(Cmul, lambda X: Binv @ X @ Ainv, Ut_b, deflation, tol, maxiter=maxiter)
            if small and (iterations >= maxiter or self._dense_cheaper(iterations, Ut_b.shape[0])):
                self.dense_capacitance = True  # the solves of this path only get harder (the noise slack shrinks)
                if iterations >= maxiter:
                    Z = woodbury.solve_dense(Ut_b)
                    self.dense_solves += 1
        UZ = np.moveaxis(Z @ Q.T, 2, 0) @ Tu  # (j, p, m): row form of T(u_k)ᵀ (Z Qᵀ)_k
        return solve(UZ.transpose(2, 0, 1))  # D_k⁻¹ (…) in the layout (m, j, p)

    def _capacitance(self, E):
        """The product ``Y ↦ Σ_k E_k Y q_k q_kᵀ`` on stacks (p, m, r), on the chunks' threads."""
        Et = self.pool.take(E.shape)
        np.copyto(Et, _tr(E))
        Q, QT, chunks = self.Q, np.ascontiguousarray(self.Q.T), self.chunks
        m, r, j = self.m, Q.shape[1], self.j

        def Cmul(Y3):
            p = Y3.shape[0]
            Z = chunks.dot(Y3.reshape(p * m, r), QT).reshape(p, m, j)  # column k of Y Qᵀ: Z[:, :, k]
            out = np.empty_like(Z)

            def work(s):
                out[:, :, s] = np.matmul(np.ascontiguousarray(Z[:, :, s].transpose(2, 0, 1)), Et[s]).transpose(1, 2, 0)

            chunks.map(work, j, Z.size + E.size)
            return chunks.dot(out.reshape(p * m, j), Q).reshape(p, m, r)

        return Cmul

    def pcg_tol(self) -> float:
        """Relative residual of the CG solves: ``cg_tol``, relaxed to :data:`_CG_TOL_FAR` when :attr:`far`."""
        return max(_CG_TOL_FAR, self.cg_tol) if self.far else self.cg_tol

    def _pcg(self, A, Minv, B, deflation: _Deflation | None = None, tol: float | None = None,
             maxiter: int | None = None):
        """Preconditioned CG on every right-hand side ``B[p]`` at once (relative residual ``tol``, default
        :meth:`pcg_tol`), deflated by ``deflation`` if given; returns X and the iterations taken (``maxiter``, default
        ``cg_maxiter``, when CG did not converge)."""
        maxiter = self.cg_maxiter if maxiter is None else maxiter
        def dot(X, Y):
            return np.einsum("pmr,pmr->p", X, Y)[:, None, None]

        start = None if deflation is None else deflation.start(B)
        project = None if deflation is None else deflation.project
        X, iterations = pcg(A, Minv, B, tol=self.pcg_tol() if tol is None else tol, maxiter=maxiter,
                            start=start, project=project, dot=dot)
        self.cg_iters += iterations
        return X, iterations

    # ---- cold start ----------------------------------------------------------------------------
    def _cold_impulses(self, svd, B0) -> np.ndarray:
        """:func:`~unfalsify.solvers.start.cold_impulses` (``‖B0 − H̃‖_F = 0.7 ρ``, or 0.7 of the way to ρ from B0's
        part that no impulse reaches, which the plain fit leaves whole: the
        :meth:`~unfalsify.solvers.columns.ColumnForm.noise_floor` for its point) with this system's projected fit."""
        fit = None if self.Q is None else (lambda lam: self._projected_fit(svd, B0, lam))
        pinned = B0[self.f.pinned()]
        target = start_target(self.f.rho, float(np.sqrt(pinned @ pinned)), 0.7)
        return cold_impulses(svd, B0, target, projected_fit=fit,
                             top=lambda H: _max_norm(self._gram(H)[1], self.chunks))

    def _projected_fit(self, svd, B0, lam: float):
        """``H = argmin λ‖H‖²_F + ‖P(B0 − H̃)‖²_F`` and its residual ``‖P(B0 − H̃)‖²_F``, or None where the solve lost
        its digits.

        The normal equations ``(D − U Uᵀ) h = Mᵀ P B0`` are the Newton system of the class docstring with ``G_k = λI``,
        c = 1 and no rank-one term, solved by the same Woodbury route; the SVD ``T(u_k) = U_k S_k V_kᵀ`` gives
        ``D_k⁻¹ = V_k (S_k² + λ)⁻¹ V_kᵀ`` and ``E_k = U_k λ(S_k² + λ)⁻¹ U_kᵀ`` without an inverse.  The CG goes to a
        relative residual of 1 % of ``ρ/‖B0‖`` within [1e-12, 1e-4] (the fit must resolve the noise ball, not the data;
        the caller checks the residual it returns).
        """
        Uk, s, Vt = svd
        # T(u_k)'s null directions (a column starting with p_k zero inputs has rank m − p_k): h is 0 there at the
        # optimum and D_k⁻¹ = 1/λ would only amplify rounding, so they are left out
        zeros = self.f.leading_zeros()
        reach = np.arange(s.shape[1])[None, :] < (s.shape[1] - zeros)[:, None]
        w = np.divide(1.0, s * s + lam, out=np.zeros_like(s), where=reach)

        def solve(X):  # D_k⁻¹ x_k for every column, X (m, j, p)
            return np.einsum("kqa,kqp->akp", Vt, np.einsum("kqa,akp->kqp", Vt, X) * w[..., None])

        E = np.matmul(Uk * (lam / (s * s + lam))[:, None, :], _tr(Uk))
        rhs = self.f.apply_T(self.f.project(B0))[..., None]  # B0 need not lie in 𝓛^⊥ (noise_floor's point)
        tol = min(max(1e-2 * self.f.rho / max(float(np.linalg.norm(B0)), np.finfo(float).tiny), 1e-12), 1e-4)
        try:
            woodbury = _Capacitance(self, E)
            Y = solve(rhs)
            H = (Y + self._lowrank_correction(woodbury, solve, rhs, Y, tol))[..., 0]
        except np.linalg.LinAlgError:
            return None
        if not np.all(np.isfinite(H)):
            return None
        r = self._resid(H)
        return H, float(np.sum(r * r))


class _ColumnBarrier(_ColumnSystem, PathAdvance):
    """The barrier method of the module docstring on a :class:`ColumnForm` with j ≥ 1 columns."""

    def __init__(self, form: ColumnForm, *, tol, time_limit, progress, mu=5.0, max_newton=3000,
                 cg_tol=1e-8, cg_maxiter=2000, noise_weight=None, chunks: _Chunks = _SERIAL):
        super().__init__(form, cg_tol=cg_tol, cg_maxiter=cg_maxiter, chunks=chunks)
        self.tol, self.time_limit, self.progress = tol, time_limit, progress
        self.mu, self.max_newton = mu, max_newton
        self.precise = False  # the FFT Hessian from here on (_newton)
        self.wn = float(noise_weight) if noise_weight is not None else float(np.sqrt(2 * self.m * self.j))
        self.nu = 2 * self.m * self.j + self.wn
        self.center_tol = 1.0
        self.stalled = 0
        self.steps = 0
        self.trials = 0  # Cholesky stacks tried (_point): the line search's feasibility tests and the starts
        self.desc = f"structured unfalsification ({self.m}×{self.j})"
        self._prev = None
        self._centred = None  # (t, (H, δ), tangent) of the last centred point the path stepped from (advance)
        self.warm_blend = None  # set by warm(): how far the warm point was moved towards the ridge start
        self.path = []  # the centred points (record())
        self.warm_started = False  # set by warm()
        self.stagnated = 0  # centrings of a warm path ended by the stagnation rule (centre())

    # ---- evaluation --------------------------------------------------------------------------
    def _point(self, H, d, gram=None) -> _Point | None:
        """The blocks at (H, δ), or None outside the domain (a Cholesky fails or the noise ball is left);
        ``gram``: :meth:`_gram` of H if already computed."""
        r = self._resid(H)
        psi = self.f.rho**2 - float(np.sum(r * r))
        if not (psi > 0 and d > 0):
            return None
        T, TtT = self._gram(H) if gram is None else gram
        self.trials += 1
        logdet = _chol_logdet(TtT, self.chunks, shift=d * d)  # K = δ²I − TᵀT, block by block
        if logdet is None:
            return None
        p = _Point(H, d, T, TtT, logdet, r, psi, self.chunks, self.pool)
        if _STEP_ROUTE["route"] == "former":  # K⁻¹ at every trial point, as before
            _ = p.Kinv  # formed now
        return p

    def _slope(self, t, p: _Point, dh, dlt, q) -> float:
        """Directional derivative of f_t at p along (dh, dlt); ``q = P H̃(dh)``.

        ``tr(F⁻¹ΔF) = dδ tr F⁻¹ + 2⟨S21, ΔT⟩`` and ``⟨S21, ΔT⟩ = ⟨T*(S21), dh⟩``: S21 is the block the next
        Newton step needs if this point is accepted (most are), so the slope costs no product of its own.
        """
        tr_fdf = dlt * p.trace_S() + 2.0 * float(np.sum(p.adjoint_S21() * dh))
        return t * dlt - tr_fdf - 2.0 * self.wn * float(np.sum(p.r * q)) / p.psi

    # ---- Newton system -----------------------------------------------------------------------
    def _newton(self, t, p: _Point):
        """Newton step ``(dH, dδ)``, squared decrement and the central-path tangent ``d(H, δ)/dt``.

        By the FFT Hessian once the path's gap is below :data:`_PRECISE_GAP`·δ, and from the first step whose
        decrement the displacement Hessian's rounding left non-positive."""
        if not self.precise and self.nu / t < _PRECISE_GAP * p.d:
            self.precise = True
        out = self._newton_at(t, p, self.precise)
        if not self.precise and not out[2] > 0.0:
            self.precise = True
            out = self._newton_at(t, p, True)
        return out

    def _newton_at(self, t, p: _Point, precise: bool):
        """:meth:`_newton` with the Hessian's route given."""
        S11, S21, S22 = p.blocks()
        psi = p.psi
        g_noise = self.f.apply_T(p.r)  # Mᵀ r
        grad_h = -2.0 * p.adjoint_S21() - 2.0 * self.wn * g_noise / psi
        grad_d = t - p.trace_S()
        dd = p.norm2()
        # c: (F⁻²)21 = S21 S11 + S22 S21 = 2 S21 S11 (TᵀT = δ²I − K), its adjoint off the Hessian's spectra
        G, x = _chunked_hessian(S11, S21, S22, self.chunks, precise, out=self.pool.take(S11.shape))
        c = 4.0 * x
        X, _ = self._solve_h(G, 2.0 * self.wn / psi, 4.0 * self.wn / psi**2, g_noise,
                             np.stack([grad_h, c], axis=-1))
        xg, xc = X[..., 0], X[..., 1]
        elim = delta_step(dd, grad_d, float(np.sum(c * xg)), float(np.sum(c * xc)))
        if elim is None:  # the solves lost their digits: a non-finite decrement (centre() stops, _newton retries)
            return np.zeros_like(xg), 0.0, float("nan"), (np.zeros_like(xc), 0.0)
        dlt, dd_eff = elim
        dh = -xg - xc * dlt
        lam2 = -(float(np.sum(grad_h * dh)) + grad_d * dlt)
        return dh, dlt, lam2, (xc / dd_eff, -1.0 / dd_eff)

    # ---- dual point --------------------------------------------------------------------------
    def _dual(self, t, p: _Point, dh, dlt):
        """Dual point of the Newton-linearised centrality conditions (:func:`linearised_dual`)."""
        dr = -self.f.project(self.f.apply(dh))
        S11, S21, S22 = p.blocks()
        dT = _stack_of(dh, self.chunks, self.pool.take(S11.shape))
        W = self.pool.take(S11.shape)  # the six block products on the chunks' threads, a block at a time
        parts = self.chunks.map(lambda s: [linearised_dual(t, (S11[b], S21[b], S22[b]), dT[b], dlt, p.r, dr, p.psi,
                                                           weight=self.wn, out=W[b])[0]
                                           for b in _blocks_of(s, self.m * self.m)], self.j, W.size)
        return parts[0][0], np.array(W)  # v does not depend on the block; W escapes the pool (a copy)

    # ---- steps -------------------------------------------------------------------------------
    def _noise_step(self, r, q) -> float:
        """Largest a ≤ 1 keeping the noise slack ``ψ(a) = ρ² − ‖r − a q‖²`` at least :data:`_NOISE_KEEP` ψ(0).

        Without this cap (99 % of the way to the boundary) the first steps after t grows drove ψ far
        below its value at the next centre, and the iterates crawled back along the boundary: measured
        at (i, j) = (100, 1000), L optimised, t = 4.9·10⁵, ψ from 106 to 0.026 in six steps, then 40+
        Newton steps gaining about 10 % of ψ each, against 12 steps to the centre (ψ = 8.6) when ψ may
        at most halve per step.
        """
        qq, rq, rr = float(np.sum(q * q)), float(np.sum(r * q)), float(np.sum(r * r))
        if qq <= 0:
            return _MAX_STEP
        disc = rq * rq + qq * (1.0 - _NOISE_KEEP) * (self.f.rho**2 - rr)
        return min(_MAX_STEP, (rq + np.sqrt(max(disc, 0.0))) / qq)

    def _line_search(self, t, p: _Point, dh, dlt, slope0, a_init=1.0):
        """A step along (dh, dlt) near the minimiser of f_t on the line (convex there), by safeguarded
        secant steps on the slope (function values lose their digits at large t).  Only points with a
        non-positive slope are accepted (they lie before the minimiser, so f_t decreases).  The first
        trial is ``min(a_init, a₀)``, a₀ the Newton step cut to keep half the noise slack; a trial
        short of a₀ that is inside and still descending is expanded 4× while no upper end is known."""
        q = self.f.project(self.f.apply(dh))
        a0 = self._noise_step(p.r, q)
        lo, s_lo, p_lo = 0.0, slope0, None
        hi, s_hi = None, None
        a = min(a0, a_init)
        for _ in range(40):
            pn = self._point(p.H + a * dh, p.d + a * dlt)
            if pn is None:
                hi, s_hi = a, None
            else:
                s = self._slope(t, pn, dh, dlt, q)
                if s <= 0.0:
                    lo, s_lo, p_lo = a, s, pn
                    if a >= a0 or s >= 0.1 * slope0:
                        return pn, a
                else:
                    hi, s_hi = a, s
            if p_lo is not None and hi is not None and hi - lo <= 0.05 * hi:
                return p_lo, lo
            if hi is None:  # inside and descending short of a₀: expand
                a = min(a0, 4.0 * a)
            elif s_hi is None:  # infeasible above: shrink towards lo
                a = lo + 0.5 * (hi - lo)
            else:  # secant on the slope, kept inside the bracket
                a = lo - s_lo * (hi - lo) / (s_hi - s_lo)
                a = min(max(a, lo + 0.1 * (hi - lo)), hi - 0.1 * (hi - lo))
        return p_lo, lo  # p_lo None: no progress along this direction (rounding, at the end of the path)

    # ---- starting point ----------------------------------------------------------------------
    def start(self, B0) -> _Point:
        """Ridge impulses with ``‖B0 − H̃‖_F = 0.7 ρ`` (B0 = B minus a point of 𝓛), δ 20 % above their norm."""
        self._svd = operator_svd(self.Tu, split=lambda work: self.chunks.map(work, self.j, self.Tu.size))
        H = self._cold_impulses(self._svd, B0)
        gram = self._gram(H)
        up = _max_norm(gram[1], self.chunks)
        p = self._point(H, 1.2 * up + 1e-3 * (1.0 + up), gram)
        self.start_H = H  # returned if it is not strictly feasible: the front end names the noise it leaves
        if p is None:  # inside by construction, unless the noise budget is at the rounding level of the data
            raise Stop("failed")
        return p

    def warm(self, B0, warm: dict):
        """A strictly feasible point near a centred point of a related solve, and the t to resume at.

        ``warm``: ``H`` (m × j, scaled units; NaN columns are new), ``d`` (that point's δ), ``gap``
        (``ν/(t δ)`` of its centring), ``psi`` (its noise slack over ρ²) and ``slack`` (its ``δ/max_k‖T(h_k)‖₂ − 1``).
        New columns get ridge impulses capped at :data:`_WARM_CAP` × the old δ (:meth:`_capped_ridge`).  If the
        residual then leaves the noise ball (new data, a new predictor space, a smaller σ), the smallest
        ridge correction of all columns brings it back to the old slack (the projection onto 𝓛^⊥ can only
        shorten the corrected residual); as a safety net the point then moves along the segment to the cold
        ridge start (strictly feasible, so the segment stays in the convex domain) until the noise slack is
        :data:`_WARM_PSI` of the old one.  δ is then
        raised above every column's ``‖T(h_k)‖₂`` by the old relative slack, and t is the old centring's in
        this problem's terms (the same ``ν/(tδ)``; measured at (20, 400): resuming at the trace rule
        ``t = Σ tr F_k⁻¹`` or one μ-step below the old t cost as many Newton steps or more).
        Returns ``(point, t)``, or None when the point is unusable (then the caller starts cold).
        """
        ridge = self.start(B0)
        H = np.asarray(warm["H"], float)
        if H.shape != (self.m, self.j):
            return None
        new = ~np.all(np.isfinite(H), axis=0)
        d_old = float(warm.get("d", np.nan))
        if np.any(new):
            H = H.copy()
            H[:, new] = self._capped_ridge(B0[:, new], self.Tu[new], _WARM_CAP * d_old) if np.isfinite(d_old) \
                else ridge.H[:, new]
        rho2 = self.f.rho**2
        psi_min = min(_WARM_PSI * max(float(warm["psi"]), 0.0) * rho2, ridge.psi)
        rw = self._resid(H)
        if float(np.sum(rw * rw)) > rho2 - psi_min:
            # outside the noise ball (new data, a new predictor space, a smaller σ): the smallest ridge
            # correction of every column that brings the residual back inside (λ as large as possible)
            H = H + ridge_fit(self._svd, rw, rho2 - 2.0 * psi_min)
            rw = self._resid(H)
        # smallest a with ‖r_w + a (r_r − r_w)‖² ≤ ρ² − ψ_min (the residual is affine in a): the segment to the
        # strictly feasible ridge start, should the correction above fall short by rounding
        dr = ridge.r - rw
        qa, qb, qc = float(np.sum(dr * dr)), 2.0 * float(np.sum(rw * dr)), float(np.sum(rw * rw)) - (rho2 - psi_min)
        if qc <= 0.0:
            a = 0.0
        elif qa <= 0.0:
            a = 1.0
        else:
            a = min(1.0, (-qb - np.sqrt(max(qb * qb - 4.0 * qa * qc, 0.0))) / (2.0 * qa))
        H = H + a * (ridge.H - H)
        gram = self._gram(H)
        up = _max_norm(gram[1], self.chunks)
        gap = float(warm["gap"])
        if not (np.isfinite(gap) and gap > 0.0 and np.all(np.isfinite(H))):
            return None
        slack = min(max(float(warm.get("slack", 0.0)), 1e-9), 0.2)
        p = self._point(H, up * (1.0 + slack) + 1e-12, gram)
        if p is None:
            return None
        self.warm_blend, self.warm_started = float(a), True
        # the old centring's t, in this problem's terms: the same relative gap ν/(tδ) (measured at (20, 400):
        # resuming at the trace rule t = Σ tr F_k⁻¹ or one μ-step below the old t cost as many or more steps)
        return p, self.nu / (gap * p.d)

    def _capped_ridge(self, B0, Tu, cap: float) -> np.ndarray:
        """Ridge impulses of the columns ``B0`` (m × c, inputs ``Tu`` (c, m, m)), each with the smallest λ
        that keeps ``‖T(h_k)‖₂ ≤ cap``.

        The new columns of an advanced window: the cold start's ridge impulses fit the data with the whole
        noise budget to spare and have norms far above the old δ (measured at (20, 400): 6.6 against 1.7),
        which would throw the resumed point far off the path; capped at the old δ they sit where the old
        columns are.  Bisection on log₁₀ λ for all columns at once (the norm falls as λ grows)."""
        Us, s, Vt = operator_svd(Tu)
        beta = coordinates(Us, B0)

        def norms(H):
            T = toeplitz_stack(H)
            return np.sqrt(np.maximum(np.linalg.eigvalsh(_tr(T) @ T)[:, -1], 0.0))

        lo, hi = np.full(B0.shape[1], -30.0), np.full(B0.shape[1], 10.0)
        for _ in range(45):
            mid = 0.5 * (lo + hi)
            over = norms(impulses(s, Vt, beta, 10.0**mid)) > cap
            lo, hi = np.where(over, mid, lo), np.where(over, hi, mid)
        return impulses(s, Vt, beta, 10.0**hi)

    # ---- main loop ---------------------------------------------------------------------------
    def centre(self, t, p, deadline: Deadline):
        """Newton steps on f_t until λ² ≤ ``center_tol`` (or 60 steps); returns the point and the last step.

        Inexact Newton far from the centre: while the last decrement exceeds :data:`_FAR_DECREMENT`
        (and on the first step after t grew) the CG solves of L optimised stop at the relative residual
        :data:`_CG_TOL_FAR` instead of ``cg_tol``.  Measured at (100, 1000), t = 4.9·10⁵: 237 CG
        iterations instead of 1005 for a direction 4 % off, whose line-search step and new point agreed
        to 2e-6 relative; the steps near the centre, whose directions also make the dual point, keep
        ``cg_tol``.
        """
        lam2_prev, recent = np.inf, []
        for _ in range(60):
            deadline.check()
            self.far = lam2_prev > _FAR_DECREMENT
            dh, dlt, lam2, tangent = self._newton(t, p)
            lam2_prev = lam2
            self.steps += 1
            if not np.isfinite(lam2) or self.steps > self.max_newton:
                raise Stop("failed" if not np.isfinite(lam2) else "max_iter")
            if not lam2 > 0.0:  # not a descent direction: the Newton solve lost its digits, not centred
                self.stalled += 1
                break
            if lam2 <= self.center_tol:
                break
            recent = (recent + [lam2])[-_WARM_STAGNATION:]
            if self.warm_started and lam2 <= _FAR_DECREMENT and len(recent) == _WARM_STAGNATION \
                    and min(recent[1:]) > 0.5 * recent[0]:
                # warm start: full Newton steps that no longer reduce λ² (measured at (20, 400), window advanced by
                # one sample: λ² between 2 and 4 for 50 steps).  Near enough to the centre for the dual point,
                # whose bound is certified wherever it is taken; the path goes on from here.
                self.stagnated += 1
                if self.stagnated >= _WARM_MAX_STAGNATIONS:
                    raise Stop("failed")  # not converging to the centres: _solve re-solves cold
                break
            pn, _ = self._line_search(t, p, dh, dlt, -lam2)
            if pn is None:  # rounding-level stall: take the bounds here; run() stops if they do not improve
                self.stalled += 1
                break
            p = pn
        return p, (dh, dlt, tangent)

    # ---- the plug-in of run_barrier ----------------------------------------------------------
    def upper(self, p: _Point) -> float:
        return p.upper()

    def impulses(self, p: _Point) -> np.ndarray:
        return p.H.copy()

    def dual(self, t, p: _Point, step):
        dh, dlt, _ = step
        return self._dual(t, p, dh, dlt)

    def advance(self, t, p: _Point, step, bounds, deadline: Deadline):
        """``μt`` and a point near its centre: of the centred point itself and the predictions of
        :func:`~unfalsify.solvers.barrier.path_predictor` (linear in 1/t, and the Hermite cubic through this
        centred point and the one before), each backtracked on feasibility, the one with the lowest ``f_{μt}``
        (the former route: the centred point)."""
        t_new, p = super().advance(t, p, step, bounds, deadline)
        if _STEP_ROUTE["route"] == "former":
            return t_new, p
        dH, dd = step[2]
        centre = (t, np.append(p.H.ravel(), p.d), np.append(dH.ravel(), dd))
        steps = path_steps(t_new, centre, self._centred)
        self._centred = centre
        return t_new, best_along(p, steps, lambda x: self._feasible_along(p, x), lambda q: self._f(t_new, q))

    def _f(self, t, p: _Point) -> float:
        """``f_t`` at p (comparisons between nearby points only: at large t its value loses digits)."""
        return t * p.d - p.logdet - self.wn * float(np.log(p.psi))

    def _feasible_along(self, p: _Point, x):
        """The first strictly feasible point of ``p + a x``, ``a = 1, ½, …, 2⁻⁵`` (else None)."""
        dH, dd = x[:-1].reshape(p.H.shape), float(x[-1])
        a = 1.0
        for _ in range(6):
            q = self._point(p.H + a * dH, p.d + a * dd)
            if q is not None:
                return q
            a *= 0.5
        return None

    def run(self, p: _Point, t: float | None = None) -> dict:
        """:func:`run_barrier` from ``p`` at path parameter ``t`` (default the cold ``ν/δ``); adds the CG count
        and the state a warm start of a related problem needs (``state``: :meth:`warm`'s ``d``, ``gap``, ``psi``)."""
        deadline = Deadline(self.time_limit)
        up = p.upper()
        self._prev = (up, 0.0)
        out = run_barrier(self, self.f, p, self.nu / p.d if t is None else t, deadline, up)
        out.update(cg=self.cg_iters, cg_dense=self.dense_solves, trials=self.trials, stagnated=self.stagnated)
        out.pop("last")
        if self.path:
            out["state"] = dict(path=self.path)
        return out

    def bound_due(self, t, upper) -> bool:
        """Whether the lower bound (j SVDs, 10–20 % of a solve at (20, 400)) is worth evaluating at t: once the
        path's own gap ``ν/t`` is within :data:`_BOUND_FACTOR` × ``tol`` of ``upper`` the certified gap can close;
        and after a stall, whose verdict (:class:`PathAdvance`) asks whether either bound improved."""
        return bool(self.stalled) or self.nu / t <= _BOUND_FACTOR * self.tol * upper

    def record(self, t, p: _Point) -> None:
        """Keep the centred point at t (impulses, δ, relative gap ``ν/(tδ)``, noise slack ψ/ρ², δ slack)."""
        self.path.append(dict(H=p.H, d=float(p.d), gap=float(self.nu / (t * p.d)), psi=float(p.psi / self.f.rho**2),
                              slack=float(p.d / p.upper() - 1.0)))


def solve_columns_barrier(form: ColumnForm, B0: np.ndarray, *, tol=1e-6, time_limit=None, progress=True,
                          mu=5.0, noise_weight=None, workers: int | None = 1, warm: dict | None = None) -> dict:
    """Run the column barrier method on ``form`` (program (C) of (7.5)).

    Parameters
    ----------
    form : ColumnForm
        The column form, scaled units; ``basis_right`` set when L is optimised.
    B0 : ndarray, shape (m, j)
        ``P B`` (B minus a point of 𝓛): seeds the ridge starting point.
    tol : float
        Relative certified gap ``(upper − lower)/upper`` at which to stop.
    time_limit : float, optional
        Wall-clock seconds; then the best certified bracket is returned with status ``time_limit``.
    progress : bool
        tqdm bar (iteration, bounds) for solves longer than about 2 s.
    mu, noise_weight : float
        Growth of t per centring; weight w of the noise barrier (default √(2ij)).
    workers : int or None
        Threads over the column stack (:class:`_Chunks`); ``None``: ``os.cpu_count()``.  BLAS is held
        to one thread per worker during the solve (threadpoolctl), ``workers=1`` included: the solve
        then uses exactly ``workers`` cores.
    warm : dict, optional
        Resume from a related solve's last centred point (:meth:`_ColumnBarrier.warm`; scaled units):
        ``H`` (m × j, NaN columns are new), ``d``, ``gap``, ``psi`` as in the ``state`` this function returns.
        The stop is the same certified gap.  If the point is unusable the solve starts cold and ``warm`` in
        the answer says why.

    Returns
    -------
    dict
        status (``optimal``, ``time_limit``, ``interrupted``, ``max_iter``, ``failed``), the best upper
        bound and its impulses ``H`` (m × j), the best lower bound and its dual point ``V`` (m × j),
        ``W`` (j × m × m), Newton, outer and CG iteration counts, wall time, ``t`` and ``state`` of the last
        centring (what ``warm`` takes), and ``warm``: ``"used"``, or why the warm point was not (only when
        ``warm`` was given).  Ctrl-C during the solve returns the bracket so far with status ``interrupted``.
    """
    return _on_threads(workers, lambda chunks: _solve(form, B0, tol, time_limit, progress, mu, noise_weight, chunks,
                                                     warm))


def _on_threads(workers, run):
    """``run(chunks)`` with ``chunks`` a :class:`_Chunks` over ``workers`` threads (``None``: every core) and BLAS
    held to one thread per worker, ``workers = 1`` included: the column methods' products are many and small, and a
    second BLAS thread competing with other jobs was measured 5.5× slower (183 s against 33 s at (50, 500) under
    load)."""
    n = check_workers(workers)
    with one_blas_thread():
        if n == 1:
            return run(_SERIAL)
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=n) as pool:
            return run(_Chunks(pool, n))


def check_workers(workers) -> int:
    """``workers`` checked (a positive integer, or None for ``os.cpu_count()``)."""
    if workers is None:
        return max(1, os.cpu_count() or 1)
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise DataError(f"workers must be a positive integer or None (all cores); got {workers!r}")
    return int(workers)


def _solve(form, B0, tol, time_limit, progress, mu, noise_weight, chunks: _Chunks, warm=None, wider=True) -> dict:
    solver = _ColumnBarrier(form, tol=tol, time_limit=time_limit, progress=progress, mu=mu, noise_weight=noise_weight,
                            chunks=chunks)
    clock = Deadline(time_limit)
    t, note = None, None
    try:
        if warm is not None:
            resumed = solver.warm(B0, warm)
            if resumed is None:
                note = "the warm point could not be made strictly feasible; started cold"
            else:
                note = "used"
        if warm is None or resumed is None:
            p = solver.start(B0)
        else:
            p, t = resumed
    except (KeyboardInterrupt, Stop) as exc:  # before the first point: no bracket but δ ≥ 0
        return dict(status="interrupted" if isinstance(exc, KeyboardInterrupt) else str(exc), lower=0.0,
                    upper=float("nan"), H=getattr(solver, "start_H", np.zeros((form.m, form.j))), V=None, W=None,
                    outer=0, newton=0, cg=0,
                    time=clock.elapsed())
    out = solver.run(p, t)
    if note == "used" and out["status"] in ("failed", "max_iter"):
        # the resumed path stalled: never an answer worse than cold, so solve again from the cold start
        why = (f"stagnated in {solver.stagnated} centrings" if solver.stagnated >= _WARM_MAX_STAGNATIONS
               else f"stopped with status {out['status']!r}")
        note = f"the resumed path {why} after {out['newton']} Newton steps; re-solved cold"
        wasted = out["newton"]
        out = _solve(form, B0, tol, time_limit, progress, mu, noise_weight, chunks)
        out["warm_newton"] = wasted
    elif wider:
        # a noise ball the barrier cannot resolve: the lower bound from larger balls (unfalsify.solvers.wider_ball)
        out = tighten_lower(form, out, lambda f, tol_, left: _solve(f, B0, tol_, left, False, mu, noise_weight, chunks,
                                                                    wider=False), tol=tol, clock=clock)
    if note is not None:
        out.update(warm=note, warm_blend=solver.warm_blend)
    return out


def solve(problem, *, tol: float = 1e-6, time_limit=None, progress: bool = True,
          workers: int | None = 1, warm_start: dict | None = None) -> SolverOutput:
    """Registered solver ``"column_barrier"``: (7.5) of an :class:`unfalsify.SubspaceProblem` (L optimised
    or fixed), certified to the relative gap ``tol``; the answer in data units.

    ``warm_start``: the ``state`` of a related solve (``stats["state"]`` of an earlier answer, data units),
    its impulses already mapped onto this problem's columns (NaN columns are new); see
    :func:`solve_columns_barrier`.  The answer's ``stats`` carry ``state`` (data units) for the next one.
    """
    f = problem.column_form(scaled=True)
    clock = Deadline()
    if zero_answer(f):
        return unscaled(problem, np.zeros(f.U.shape), 0.0, "optimal", clock.elapsed(),
                        stats={} if warm_start is None else dict(warm="not needed: δ = 0 without a solve"))
    su, sy = problem.scale
    warm = None
    if warm_start is not None:  # data units -> this problem's scaled units (impulses and δ scale by s_u/s_y)
        warm = dict(warm_start, H=np.asarray(warm_start["H"], float) * (su / sy), d=float(warm_start["d"]) * su / sy)
    out = solve_columns_barrier(f, f.noise_floor()[1], tol=float(tol), time_limit=time_limit, progress=progress,
                                workers=workers, warm=warm)
    stats = {k: out[k] for k in ("newton", "outer", "cg", "cg_dense", "trials", "warm", "warm_blend", "warm_newton",
                                 "wider") if k in out}
    if "state" in out:
        stats["state"] = dict(path=[dict(c, H=c["H"] * (sy / su), d=c["d"] * sy / su) for c in out["state"]["path"]])
    return unscaled(problem, out["H"], out["upper"], out["status"], clock.elapsed(), V=out["V"], W=out["W"],
                    stats=stats)
