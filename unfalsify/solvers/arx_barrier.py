"""Solver ``"arx_barrier"``: Cholesky-based barrier method for the ARX program (7.4) in column form (C) (j = 1).

The barrier method of :mod:`unfalsify.solvers.barrier` (Boyd & Vandenberghe §11.3) on the n + 1
variables (h, δ) of (C) with ``𝓛 = range Φ`` projected out,

    f_t(h, δ) = t δ − log det F(h, δ) − w log(ρ² − ‖P(B − T(u)h)‖²),   F = [δI T(h)ᵀ; T(h) δI],

but every quantity is read off one Cholesky factorisation instead of an SVD of T(h):

* ``det F = det(δ²I − TᵀT)`` (Schur complement), so with ``K = δ²I − T(h)ᵀT(h) = L Lᵀ``,
  ``log det F = 2 Σ log L_ii`` and F ≻ 0 ⟺ (δ > 0 and the Cholesky factorisation succeeds);
* ``F⁻¹ = [S11 S12; S21 S22]`` with ``S11 = δK⁻¹``, ``S21 = −T K⁻¹``, ``S22 = (I + T K⁻¹ Tᵀ)/δ``;
* the gradient ``∂/∂h_a = 2 T*(T K⁻¹)_a``, ``∂/∂δ = t − 2δ tr K⁻¹``; the Hessian's h–h block and its h–δ
  column ``−4δ T*(T K⁻²)`` come from the displacement generators of F⁻¹'s blocks in O(n²)
  (:func:`unfalsify.solvers.displacement.displacement_hessian`; once the path's gap ν/t is below 1e-7·δ, from
  the 2-D-FFT correlation of :func:`unfalsify.solvers.toeplitz.corr_hessian`, which keeps three more digits),
  its δ–δ entry ``2(δ²‖K⁻¹‖²_F + ‖T K⁻¹‖²_F)``.

For one channel from n = 400 a Newton step's only n³ work is the Cholesky factor of the Newton system
(n³/3 flops).  K's factor (of ``J K J = δ²I − TTᵀ``, J the exchange matrix) comes from the generalised Schur
algorithm on the rank-2 displacement generators of that matrix in O(n²)
(:func:`~unfalsify.solvers.displacement.schur_cholesky`), and the blocks of F⁻¹ from the generators of their
own displacements, read off two block solves with that factor (:func:`~unfalsify.solvers.displacement.inverse_blocks`,
O(n²)).  Below n = 400 (where both are measured slower) and for several channels, K is factorised by LAPACK
and, as also once the path's gap is below 1e-7·δ, ``K⁻¹`` comes from the factor by potri (⅔n³) and the
products ``T K⁻¹`` and ``(T K⁻¹) Tᵀ`` with the triangular T(h) by trmm (n³ each).  The h–δ column
``−4δ T*(T K⁻²) = 4 T*(S21 S11)`` comes with the Hessian (which reuses the generators), ``T(h)ᵀT(h)`` costs O(n²)
(:func:`toeplitz_gram`), and a trial point of the line search never forms the dense T(h).  The certificate's two dense SVDs are evaluated only once
the path's gap ν/t is within 4·tol of δ (:data:`_BOUND_FACTOR`), then only where the last certified gap, shrunk like 1/t, would be
within tol (:meth:`_ArxBarrier.bound_due`), and at the centring that ends a solve, whatever ended it.  Up to
n = 1000 a solve holds BLAS to one thread (:func:`_blas_policy`), except in the bounds.  Measured on 2 cores, the same solves in
one process, alternating (the servo data of the benchmark, seed 0, tol 1e-4, same Newton steps and δ both
ways): the Hessian 12 ms against 39–48 ms by the FFT at n = 400 and 57 ms against 220–230 ms at n = 1000;
whole solves n = 400 1.6 s (displacement, one BLAS thread) against 2.9–3.4 s (FFT, one thread) and 3.7–3.8 s
(FFT, two threads, the route before), n = 1000 21–22 s against 36–37 s and 33–34 s.  The FFT Hessian had
been 58 % of a solve at n = 1000; the displacement one is about a quarter.

A trial point of the line search costs one factorisation of K (n³/3 flops, O(n²) from n = 400) instead of an
SVD (~20 n³), so
no step-to-the-boundary computation is needed: the line search starts from the full Newton step,
backtracks (Armijo) where f_t does not decrease or the Cholesky factorisation fails, and, when the
full step is accepted, tries 2, 4, … times it while f_t keeps decreasing.

Path steps.  From a centred point the next one, at μt, is predicted two ways
(:func:`~unfalsify.solvers.barrier.path_predictor`), each backtracked on feasibility, and the point with the
lower ``f_{μt}`` is taken (one or two trial factorisations): the tangent linearly in 1/t
(``x + (1 − 1/μ) t ẋ``: near the optimum ``x(t) − x* = O(1/t)``), and the Hermite cubic in 1/t through this
centred point and the one before, with both tangents.  The path curves: at n = 1000 the tangent's step was
feasible only when halved or quartered at 10 of 13 path steps, and the first Newton step after it had
λ² ≈ 50–450; the cubic's full step was taken at 10 of 13.  Measured, Newton steps (servo data of the benchmark,
seeds 0/1/2, with the noise weight 1 and μ = 2 above n = 800, the rules before the next paragraph's; tangent alone
→ both): n = 40 (tol 1e-6) 29/25/28 → 26/28/27, n = 80 (tol 1e-7)
29/32/31 → 29/34/31, n = 200 (tol 1e-4) 32/31/35 → 30/27/30, n = 400 44/44/45 → 38/34/39, n = 600 54/53/48 →
41/41/39, n = 1000 65/63/52 → 46/49/46, n = 3000 (seed 0) 142 → 68.  The cubic alone was worse at small n and
tight tolerances (n = 80: 46/44/42), hence the choice by ``f_{μt}``.

The noise barrier carries the weight ``w = √(order of the LMI)`` (2n for one channel; ν = 2n + w), as in
:mod:`~unfalsify.solvers.column_barrier`: with w = 1 the one noise constraint is swamped by the 2n LMI terms.
The steps then spend the noise slack ψ: logged at n = 3000 (μ = 3), ψ/ρ² fell from 2.7e-4 to 2.7e-8 in 13
Newton steps after t grew, far below its value at the next centre (about 1e-4), and the iterates crawled back
at λ² ≈ 2.9 for 75 steps; at n = 10⁴ the third centring crawled the same way (λ² ≈ 2 for 25+ steps, when the
run was stopped).  Capping each step to keep half of ψ did not help (ψ then halved at each of 12 consecutive
steps).  Measured, Newton steps with w = √(2n) against w = 1 (servo data, seeds 0/1/2, tol 1e-4 unless
stated): n = 40 (tol 1e-6) 24/25/25 against 26/28/27, n = 80 (tol 1e-7) 30/27/28 against 29/34/31, n = 200
25/25/26 against 30/27/30, n = 600 31/30/25 against 41/41/39, n = 1000 28/29/27 against 46/49/46 (μ = 3
against μ = 2), n = 3000 (seed 0) 33 (35 s) against 68.  t grows by μ = 3 per outer iteration at every n: with
w = 1, μ = 2 had been needed above n = 800 (n = 3000: 142 steps against 269 with μ = 3); with the weight μ = 3
is the better at n = 1000 (28/29/27 against 34/31/31) and n = 3000 (33 against 37).

The dual point read off each centred iterate (the Newton-linearised ``G = (S − S ΔF S)/t`` and noise
multiplier, :func:`unfalsify.solvers.barrier.linearised_dual`) is bounded by :meth:`ColumnForm.lower_bound`; the upper
bound ``‖T(h)‖₂`` is recomputed by :func:`unfalsify.solvers.toeplitz.certified_norm`.  The stopping rule uses
these certified bounds only (:func:`unfalsify.solvers.barrier.run_barrier`).  Memory O(n²).  Above n = 4000 the
upper bound takes the iterate's δ (just above ‖T(h)‖₂, as K ≻ 0) as the shift of a Lanczos estimate on
``(δ²I − TᵀT)⁻¹`` proven by a Cholesky factorisation (:func:`~unfalsify.solvers.toeplitz.norm_by_shift_invert`),
and on the structured route the dual's products with the step's ``T(dh)`` are FFTs
(:func:`~unfalsify.solvers.toeplitz.toeplitz_times`).  Measured at n = 10⁴ (seed 0, tol 1e-4, both cores): the
upper bound 11.8 s (Lanczos on TᵀT had taken 1182 s: near the optimum the top singular values cluster at δ), the
dual point 151 s with six dense products (126 s with four and the FFTs, timed alone), the lower bound's SVD of order 10⁴ about 200 s; certified (gap 4.7e-5)
at the first evaluation, 899 s into the solve, 18.7 minutes with the front end's certificate.

Several channels (u (n, m), y (n, l); :class:`ArxBlockForm`).  The same method on the p + 1 = nlm + 1
variables (h, δ), h the l × m Markov parameters in C order (t, α, β), with ``T(h)`` the nl × nm block
lower-triangular Toeplitz matrix and ``F = [δI_nm T(h)ᵀ; T(h) δI_nl]``.  Every formula above holds for a
rectangular T(h) with ``K = δ²I_nm − TᵀT`` (nm × nm), except that ``det F = δ^{nl−nm} det K``: the barrier
gains ``−(nl − nm) log δ``, the δ-gradient ``−(nl − nm)/δ`` and the δ–δ Hessian ``(nl − nm)/δ²`` (zero for
l = m).  The adjoint is the block adjoint (:func:`~unfalsify.solvers.toeplitz.block_adjoint`), the h–h
Hessian the block 2-D-FFT correlation :func:`~unfalsify.solvers.toeplitz.block_corr_hessian`
(O((lm)² n² log n)), the data operator ``M h = T(h)u`` a dense nl × nlm matrix (its projected Gram
``MᵀPM`` formed once), the upper bound :func:`~unfalsify.solvers.toeplitz.block_certified_norm`, and the
barrier parameter ν = n(l + m) + 1.  One channel each runs the SISO code above unchanged.
"""
from __future__ import annotations

import contextlib

import numpy as np
import scipy.linalg
from scipy.linalg import blas as _blas
from scipy.linalg import lapack as _lapack

from .barrier import (Deadline, Stop, best_along, cholesky_retry, delta_step, linearised_dual, path_steps,
                      run_barrier)
from .base import SolverOutput, one_blas_thread, unscaled, zero_answer
from .columns import BlockColumnForm, ColumnForm
from .displacement import displacement_hessian, inverse_blocks, schur_cholesky
from .start import operator_svd, ridge_fit, ridge_fit_gram, start_target
from .toeplitz import (adjoint, block_adjoint, block_certified_norm, block_corr_hessian, block_toeplitz_matrix,
                       certified_norm, conv_cols_T, corr_hessian, toeplitz_gram, toeplitz_matrix,
                       toeplitz_times)

__all__ = ["solve", "solve_arx_barrier", "ridge_start", "ArxBlockForm"]

#: The dense algebra of a Newton step: ``"blas3"`` (K⁻¹ from the Cholesky factor by LAPACK's potri, the
#: products with the triangular T(h) by trmm, the h–δ column with the Hessian, the bounds only
#: near the tolerance) or ``"former"`` (K⁻¹ by two triangular solves against I, general products, the bounds
#: at every centring), the benchmark's same-run reference (:func:`unfalsify.solvers.baselines.former_routes`).
#: ``"hessian"``: the one-channel Hessian from displacement generators (``"displacement"``) or by the 2-D FFT
#: (``"fft"``, :func:`unfalsify.solvers.baselines.fft_barrier_hessian`); the former route always uses the FFT.
#: ``"blocks"``: for one channel with n ≥ :data:`_STRUCTURED_FROM`, the blocks of F⁻¹ from displacement
#: generators (``"generators"``, :func:`unfalsify.solvers.displacement.inverse_blocks`, O(n²)) or densely by
#: potri and trmm (``"dense"``, 2⅔n³; :func:`unfalsify.solvers.baselines.dense_inverse_blocks`).
_STEP_ROUTE = {"route": "blas3", "hessian": "displacement", "blocks": "generators"}

#: From this n (one channel) K's factor comes from the generalised Schur algorithm and the blocks of F⁻¹ from
#: displacement generators.  Measured on one core at n = 400: the factor 2.7 ms against 3.4 ms (Gram and potrf),
#: the blocks 4 ms against 8–15 ms (potri and trmm); at n = 200 both are slower (1.3 against 0.9 ms, 2.0 against
#: 1.3 ms).
_STRUCTURED_FROM = 400

#: Below this relative gap of the path (ν/t < _PRECISE_GAP·δ) the one-channel Hessian is the FFT's: the
#: displacement route loses digits to cancellation (about 1e-13 of the largest entry at n = 1000 against
#: 1e-16), which stalled a solve to tol 1e-9 near its end (status "failed").
_PRECISE_GAP = 1e-7

#: The factor μ of t per outer iteration (module docstring: path steps).
_MU = 3.0

#: Up to this n (one channel) a solve holds BLAS to one thread (:func:`_blas_policy`).
_ONE_BLAS_THREAD_UP_TO = 1000
#: :meth:`_ArxBarrier._check_stall`: this many accepted Newton steps in a row of length at most ``_STALL_STEP`` are a
#: stall
_STALL_STEP = 2.0**-20
_STALL_STEPS = 8
#: :meth:`_ArxBarrier._check_stall`: a centring of this many Newton steps is a stall
_CENTRING_STEPS = 200

#: The bounds (two dense SVDs at n ≤ 4000) are evaluated once the path's gap ν/t is within this factor of
#: tol·δ, where the certified gap can close (:meth:`_ArxBarrier.bound_due`), and at the centring that ends a solve.
#: Measured at the centred points (servo data, seeds 0/1/2, n = 40 … 600, tol 1e-4 … 1e-8): the certified gap is
#: ν/(tδ) divided by 2.9–4.0, the same at every centring of a solve; so from 4·tol on it can close.
_BOUND_FACTOR = 4.0


class _Siso:
    """The Toeplitz structure of one channel: T(h) n × n, its Gram in O(n²), adjoint, FFT Hessian."""

    excess = 0  # nl − nm: det F = δ^{nl−nm} det K
    generators = True  # the blocks of F⁻¹ may come from displacement generators (inverse_blocks)
    gram_needs_T = False  # the Gram TᵀT in O(n²) from h alone

    def __init__(self, form: ColumnForm):
        self.form = form

    def residual(self, h):
        f = self.form
        return f.project(f.B[:, 0] - f.apply(h[:, None])[:, 0])

    def image(self, h):
        """``P T(u)h``: the projected data operator (the residual's change along h is its negative)."""
        f = self.form
        return f.project(f.apply(h[:, None])[:, 0])

    def apply_T(self, r):
        return self.form.apply_T(r[:, None])[:, 0]

    def toeplitz(self, h):
        return toeplitz_matrix(h)

    def gram(self, h, T=None):
        return toeplitz_gram(h)

    def times_T(self, T, X):
        """``T X``: T lower triangular (trmm on Tᵀ's Fortran view of T's rows: no copy of T)."""
        return _blas.dtrmm(1.0, T.T, X, trans_a=1)

    def times_Tt(self, A, T):
        """``A Tᵀ`` (trmm from the right)."""
        return _blas.dtrmm(1.0, T.T, A, side=1)

    def adjoint(self, X):
        return adjoint(X)

    def hessian(self, S11, S21, S22):
        return corr_hessian(S11[None], S21[None], S22[None], S11.shape[0])[0]

    def hessian_and_column(self, S11, S21, S22, precise=False, generators=None):
        """The h–h Hessian block of F⁻¹ = [S11, S21ᵀ; S21, S22] (S11 = δK⁻¹, S21 = −T K⁻¹) and its h–δ column
        ``4 T*(S21 S11)``: from the displacement generators of F⁻¹'s blocks
        (:func:`~unfalsify.solvers.displacement.displacement_hessian`, O(n²); ``generators`` those
        :func:`~unfalsify.solvers.displacement.inverse_blocks` returned, if it formed the blocks), or with
        ``_STEP_ROUTE["hessian"] == "fft"`` (and in the former route) off the FFT Hessian's spectra
        (``corr_hessian``'s former route forms the product instead)."""
        if _STEP_ROUTE["route"] == "blas3" and _STEP_ROUTE["hessian"] == "displacement" and not precise:
            H, x = displacement_hessian(S11, S21, S22, cross=True, generators=generators)
            return H, 4.0 * x
        H, x = corr_hessian(S11[None], S21[None], S22[None], S11.shape[0], cross=True)
        return H[0], 4.0 * x[0]

    def norm(self, h, near=None):
        """The certificate's own route (dense SVD up to n = 4000); ``near`` (the iterate's δ, just above
        ‖T(h)‖₂) is the shift of its proven Lanczos route above that."""
        return certified_norm(h, near)


class _Channels(_Siso):
    """The block-Toeplitz structure of l × m Markov parameters (module docstring, several channels)."""

    generators = False
    gram_needs_T = True

    def __init__(self, form: "ArxBlockForm"):
        self.form = form
        self.n, self.l, self.m = form.i, form.n_out, form.n_in
        self.excess = self.n * (self.l - self.m)

    def residual(self, h):
        f = self.form
        return f.project(f.B[:, 0] - f.apply(h.reshape(self.n, self.l, self.m, 1))[:, 0])

    def image(self, h):
        f = self.form
        return f.project(f.apply(h.reshape(self.n, self.l, self.m, 1))[:, 0])

    def apply_T(self, r):
        return self.form.apply_T(r[:, None]).reshape(-1)

    def toeplitz(self, h):
        return block_toeplitz_matrix(h.reshape(self.n, self.l, self.m))

    def gram(self, h, T):
        return T.T @ T

    def times_T(self, T, X):
        return T @ X  # block lower triangular, not triangular: a general product

    def times_Tt(self, A, T):
        return A @ T.T

    def adjoint(self, X):
        return block_adjoint(X, self.n, self.l, self.m).reshape(-1)

    def hessian(self, S11, S21, S22):
        return block_corr_hessian(S11, S21, S22, self.n, self.l, self.m)

    def hessian_and_column(self, S11, S21, S22, precise=False, generators=None):
        return self.hessian(S11, S21, S22), 4.0 * self.adjoint(S21 @ S11)

    def norm(self, h, near=None):
        return block_certified_norm(h.reshape(self.n, self.l, self.m))


class ArxBlockForm(BlockColumnForm):
    """Program (7.4) for several channels as the column form (C): j = 1, i = n samples stacked.

    ``U`` (nm, 1) and ``B = Y`` (nl, 1) hold the samples stacked (``u_0; u_1; …``), the operator is
    ``h ↦ T(h)u`` of :class:`BlockColumnForm` (h (n, l, m)), ρ = σ√((n − free_rows)·l) and the model
    directions are ``𝓛 = {vec(ΦΘ)} = range(Q ⊗ I_l)`` (Q an orthonormal basis of range Φ, the free rows'
    unit columns included): the ARX parameters act on every output through its own column of Θ.  The
    lower bound is :meth:`BlockColumnForm.lower_bound` with this 𝓛 (its step 1 projects V off
    ``range(Q ⊗ I_l)``).
    """

    def __init__(self, U, B, rho, *, n_inputs: int, n_outputs: int, basis=None):
        super().__init__(U, B, rho, n_inputs=n_inputs, n_outputs=n_outputs)
        # 𝓛 as a left basis of the stacked (nl,) vectors: (Q ⊗ I_l) c is vec_C(Q C)
        self.Ql = None if basis is None else np.kron(basis, np.eye(self.n_out))


class _State:
    """Everything the method needs at one strictly feasible point (h, δ): T(h), the Cholesky factor
    of ``K = δ²I − TᵀT``, the projected residual and the barrier value (``phi`` = inf if infeasible).

    One channel from n = :data:`_STRUCTURED_FROM` on, ``L`` is the factor of ``J K J = δ²I − TTᵀ`` by the
    generalised Schur algorithm (:func:`~unfalsify.solvers.displacement.schur_cholesky`, O(n²), no Gram), and
    ``flipped`` is True; ``det(J K J) = det K``."""

    __slots__ = ("h", "d", "_T", "_ops", "L", "flipped", "logdet", "r", "psi", "ok", "w")

    def __init__(self, h, d, form: ColumnForm, ops: _Siso | None = None, w: float = 1.0):
        ops = _Siso(form) if ops is None else ops
        self.h, self.d, self.w = h, float(d), float(w)
        self.r = ops.residual(h)
        self.psi = form.rho**2 - float(self.r @ self.r)
        self._T, self._ops = None, ops
        self.ok = False
        self.L = None
        self.logdet = -np.inf
        self.flipped = ops.generators and h.size >= _STRUCTURED_FROM and _STEP_ROUTE["route"] != "former"
        if not (self.d > 0.0 and self.psi > 0.0):
            return
        self.L = schur_cholesky(h, self.d) if self.flipped else self._cholesky(ops, h)
        if self.L is None:
            return
        diag = np.diag(self.L)
        if not np.all(diag > 0):
            return
        self.logdet = 2.0 * float(np.sum(np.log(diag)))
        if ops.excess:  # det F = δ^{nl−nm} det K for a rectangular T(h)
            self.logdet += ops.excess * np.log(self.d)
        self.ok = True

    def _cholesky(self, ops, h):
        """LAPACK's Cholesky factor of K (None if it fails)."""
        K = ops.gram(h, self.T if ops.gram_needs_T else None)
        K *= -1.0
        K[np.diag_indices_from(K)] += self.d * self.d
        try:
            return scipy.linalg.cholesky(K, lower=True, overwrite_a=True, check_finite=False)
        except np.linalg.LinAlgError:
            return None

    @property
    def T(self):
        """The dense T(h), formed on first use: a trial point of the line search needs only K's factor, which
        one channel forms from h alone (the Schur algorithm, or LAPACK on the O(n²) Gram)."""
        if self._T is None:
            self._T = self._ops.toeplitz(self.h)
        return self._T

    def phi(self, t: float) -> float:
        """``f_t`` at this point (inf outside the domain); ``w`` is the noise barrier's weight."""
        if not self.ok:
            return np.inf
        return t * self.d - self.logdet - self.w * np.log(self.psi)


class _ArxBarrier:
    """The barrier method of the module docstring, plugged into :func:`run_barrier`."""

    def __init__(self, form: ColumnForm, *, tol, time_limit, progress, mu=None, center_tol=0.1, max_newton=3000):
        if form.j != 1:
            raise ValueError("the Cholesky barrier solver is for the ARX program (j = 1)")
        self.f = form
        self.tol, self.time_limit, self.progress = tol, time_limit, progress
        self.center_tol, self.max_newton = center_tol, max_newton
        self.steps = 0
        self.trials = 0  # Cholesky factorisations of K tried (line searches and path steps included)
        if isinstance(form, BlockColumnForm):
            self.ops = _Channels(form)
            n, l, m = form.i, form.n_out, form.n_in
            self.n, self.nK = n, n * m  # K = δ²I − TᵀT is nm × nm
            self.desc = f"structured ARX unfalsification ({l}×{m}, n={n})"
            PM = form.project(_channel_operator(form))
            lmi = n * (l + m)
        else:
            self.ops = _Siso(form)
            self.n = self.nK = form.m
            self.desc = f"structured ARX unfalsification (n={self.n})"
            PM = form.project(toeplitz_matrix(form.U[:, 0]))
            lmi = 2 * self.n
        # the noise barrier's weight w (module docstring) and the barrier parameter ν = (order of the LMI) + w
        self.w = 1.0 if _STEP_ROUTE["route"] == "former" else float(np.sqrt(lmi))
        self.nbar = lmi + self.w
        self.MtPM = PM.T @ PM
        self.mu = _default_mu(form) if mu is None else float(mu)
        self._centred = None  # (t, (h, δ), its tangent) of the last centred point the path stepped from
        self._delta = None  # δ of the last centred point (bound_due's scale)
        self._precise = False  # the precise routes for every Newton step from here on (newton)
        self._seen = None  # (t, certified relative gap) where both bounds were last evaluated (bound_due)
        self.bound_threads = contextlib.nullcontext  # the context of the bounds' BLAS calls (solve_arx_barrier)
        self._stalled = 0  # accepted steps in a row cut to at most _STALL_STEP (_check_stall)
        self.reason = None  # why the solve stopped, where the status alone does not say

    def _state(self, h, d) -> _State:
        s = _State(h, d, self.f, self.ops, self.w)
        self.trials += bool(s.d > 0.0 and s.psi > 0.0)  # only then is K factorised
        return s

    # ---- one Newton step ---------------------------------------------------------------------
    def _inverse_blocks(self, s: _State, precise: bool):
        """``K⁻¹``, ``A = T K⁻¹``, ``S22 = (I + A Tᵀ)/δ`` (so ``S11 = δK⁻¹`` and ``S21 = −A``) and the generators
        of their displacements where they came from them (else None).

        One channel from n = :data:`_STRUCTURED_FROM` on (unless ``precise``): from displacement
        generators in O(n²) (:func:`~unfalsify.solvers.displacement.inverse_blocks`).  Otherwise potri forms
        K⁻¹ from the Cholesky factor in ⅔n³ flops (two solves against I: 2n³), and the products with the
        triangular T(h) are trmm's n³ each (general products: 2n³)."""
        if _STEP_ROUTE["route"] == "former":
            Kinv = scipy.linalg.cho_solve((s.L, True), np.eye(self.nK), check_finite=False)
            A = s.T @ Kinv
            return Kinv, A, self._finish_s22(A @ s.T.T, s.d), None
        if s.flipped and _STEP_ROUTE["blocks"] == "generators" and not precise:  # the structured route (_State)
            return inverse_blocks(s.L, s.h, s.d, generators=True, flipped=True)
        Kinv, info = _lapack.dpotri(s.L, lower=1)
        if info != 0:
            raise np.linalg.LinAlgError(f"potri failed (info = {info}): K is not positive definite")
        Kinv = np.tril(Kinv)
        Kinv += np.tril(Kinv, -1).T
        if s.flipped:  # (J K J)⁻¹ = J K⁻¹ J
            Kinv = np.ascontiguousarray(Kinv[::-1, ::-1])
        A = self.ops.times_T(s.T, Kinv)
        return Kinv, A, self._finish_s22(self.ops.times_Tt(A, s.T), s.d), None

    @staticmethod
    def _finish_s22(ATt, d):
        """``(I + A Tᵀ)/δ``, in place on ``A Tᵀ``."""
        ATt[np.diag_indices_from(ATt)] += 1.0
        ATt /= d
        return ATt

    def newton(self, t: float, s: _State):
        """Newton direction ``(dh, dδ)``, decrement λ², the central-path tangent and the blocks of F⁻¹.

        By the precise routes (dense blocks, FFT Hessian) once the path's gap is below :data:`_PRECISE_GAP`·δ,
        and from the first step whose Newton system the structured routes' rounding left indefinite (measured:
        n = 200, tol 1e-8, at a path gap of 1.7e-7·δ, where the solve had stopped with status "failed") or whose
        δ Schur complement it left non-positive (:func:`~unfalsify.solvers.barrier.delta_step`)."""
        if not self._precise and self.nbar / t < _PRECISE_GAP * s.d:
            self._precise = True
        if self._precise:
            return self._newton(t, s, precise=True)
        try:
            return self._newton(t, s, precise=False)
        except np.linalg.LinAlgError:
            self._precise = True
            return self._newton(t, s, precise=True)

    def _newton(self, t: float, s: _State, precise: bool):
        d, ops = s.d, self.ops
        Kinv, A, S22, gens = self._inverse_blocks(s, precise)
        g_noise = ops.apply_T(s.r)
        psi, w = s.psi, self.w
        grad_h = 2.0 * ops.adjoint(A) - 2.0 * w * g_noise / psi
        grad_d = t - 2.0 * d * float(np.trace(Kinv))
        dd = 2.0 * (d * d * _sum_squares(Kinv) + _sum_squares(A))
        if ops.excess:  # the δ^{nl−nm} factor of det F (rectangular T(h))
            grad_d -= ops.excess / d
            dd += ops.excess / (d * d)
        # at n = 10⁴ every n × n array is 800 MB (and a fresh one costs up to a second in page faults): the
        # blocks are scaled in place, K⁻¹ and A are not used again
        S11, S21 = np.multiply(Kinv, d, out=Kinv), np.negative(A, out=A)
        del Kinv, A
        # c: the h–δ column 4 T*(S21 S11); the FFT Hessian once the path's gap is below _PRECISE_GAP·δ
        Hm, c = ops.hessian_and_column(S11, S21, S22, precise=precise, generators=gens)
        Hm = np.ascontiguousarray(Hm)  # (a no-op for the routes' own arrays) the in-place updates need it
        # Hm += (2w/ψ) MᵀPM + (4w/ψ²) g gᵀ in place (symmetric: its Fortran view is the same matrix)
        _blas.daxpy(self.MtPM.reshape(-1), Hm.reshape(-1), a=2.0 * w / psi)
        _blas.dger(4.0 * w / psi**2, g_noise, g_noise, a=Hm.T, overwrite_a=1)
        cf = cholesky_retry(Hm, overwrite=True)
        sol = scipy.linalg.cho_solve(cf, np.column_stack([grad_h, c]), check_finite=False)
        xg, xc = sol[:, 0], sol[:, 1]
        elim = delta_step(dd, grad_d, c @ xg, c @ xc)
        if elim is None:  # the solves lost their digits
            if not precise:  # the structured routes' rounding: newton() moves to the precise routes
                raise np.linalg.LinAlgError("the δ Schur complement of the Newton system is not positive")
            return np.zeros_like(xg), 0.0, float("nan"), (np.zeros_like(xc), 0.0), (S11, S21, S22)  # centre() stops
        dlt, dd_eff = elim
        dh = -xg - xc * dlt
        lam2 = -(grad_h @ dh + grad_d * dlt)
        tangent = (xc / dd_eff, -1.0 / dd_eff)  # d(h, δ)/dt on the central path
        return dh, dlt, lam2, tangent, (S11, S21, S22)

    # ---- the plug-in of run_barrier ----------------------------------------------------------
    def centre(self, t, s, deadline: Deadline):
        """Damped Newton on ``f_t`` from ``s`` until λ² ≤ center_tol; returns the state and last step."""
        if not s.ok:
            raise Stop("failed")
        taken = 0
        while True:
            deadline.check()
            dh, dlt, lam2, tangent, blocks = self.newton(t, s)
            self.steps += 1
            taken += 1
            if not np.isfinite(lam2):
                raise Stop("failed")
            if self.steps > self.max_newton:
                raise Stop("max_iter")
            if lam2 <= self.center_tol:
                self._delta = s.d
                return s, (dh, dlt, tangent, blocks)
            phi0 = s.phi(t)
            a = 1.0  # Armijo backtracking; a trial outside the domain fails its Cholesky factorisation
            for _ls in range(40):
                sn = self._state(s.h + a * dh, s.d + a * dlt)
                if sn.phi(t) <= phi0 - 0.25 * a * lam2 + 1e-13 * abs(phi0):
                    break
                a *= 0.5
            else:  # no decrease along the Newton direction: the precise routes once, then the reason
                self._escalate("the barrier method's line search found no decrease in 40 halvings of a Newton step")
                continue
            if a == 1.0:  # the full step was accepted: try longer ones while f_t decreases
                phin = sn.phi(t)
                for _ex in range(6):
                    a *= 2.0
                    sx = self._state(s.h + a * dh, s.d + a * dlt)
                    if not sx.phi(t) < phin:
                        break
                    sn, phin = sx, sx.phi(t)
            self._check_stall(a, taken)
            s = sn

    def _check_stall(self, a: float, taken: int) -> None:
        """A stall: :data:`_STALL_STEPS` accepted steps in a row of length at most :data:`_STALL_STEP` (Armijo halved the
        Newton step 20 times and more: the direction does not decrease f_t), or a centring longer than
        :data:`_CENTRING_STEPS` Newton steps.  The first stall moves to the precise routes, the next stops the solve
        ``failed`` with the reason.

        Measured on fuzzed records (δ 2e6–6e6 times the data's scale, cond T(u) 1e7–3e7, where the Newton system's
        barrier part is 1e-21 of its noise part, or a path gap of 5e-8 at tol 1e-8): Armijo's rounding slack accepts
        steps of 2⁻¹⁵–2⁻⁴⁰ and the solves ran 2500–3000 Newton steps in one centring until ``max_iter`` (17–19 s at
        n = 16–60), where the primal–dual method certified δ in 4 iterations.  Healthy centrings take under 20 steps."""
        self._stalled = self._stalled + 1 if a <= _STALL_STEP else 0
        short = self._stalled >= _STALL_STEPS
        long = taken % _CENTRING_STEPS == 0
        if not (short or long):
            return
        self._stalled = 0
        why = (f"{_STALL_STEPS} Newton steps in a row were cut below 1e-6 of their length" if short else
               f"a centring took {taken} Newton steps")
        self._escalate(f"the barrier method stalled: {why}")

    def _escalate(self, what: str) -> None:
        """The answer to a stall: the precise routes from here on if the solve is not on them yet, else stop it
        ``failed`` with the reason ``what`` (kept on :attr:`reason`)."""
        if not self._precise:
            self._precise = True
            return
        self.reason = f"{what} (its Newton systems lost their digits); method='primal_dual' is the second route"
        raise Stop("failed")

    def upper(self, s: _State) -> float:
        return self.ops.norm(s.h, s.d)

    def bound_due(self, t, upper) -> bool:
        """Whether the bounds (a dense SVD each) are worth evaluating at t (the former route: always).

        Not before the path's own gap ``ν/t`` is within :data:`_BOUND_FACTOR` × ``tol`` of δ (the smaller of
        ``upper`` and the centred point's δ, which bounds ‖T(h)‖₂ and is current where the best upper bound may
        be stale); after the bounds were evaluated once, only where the certified gap then, shrunk like 1/t,
        would be within ``tol``: measured, the certified gap at the centred points is a constant fraction of
        ``ν/(tδ)`` (1/3.4 at n = 400), so the bounds of the centrings in between could not close it."""
        if _STEP_ROUTE["route"] == "former":
            return True
        scale = upper if self._delta is None else min(upper, self._delta)
        if self.nbar / t > _BOUND_FACTOR * self.tol * scale:
            return False
        return self._seen is None or self._seen[1] * self._seen[0] / t <= self.tol

    def upper_due(self, t, s: _State) -> bool:
        """:meth:`bound_due` for the upper bound."""
        return self.bound_due(t, s.d)

    def evaluated(self, t, upper, lower) -> None:
        """Keep the certified relative gap at t (both bounds were evaluated there) for :meth:`bound_due`."""
        self._seen = (t, (upper - lower) / upper)

    def impulses(self, s: _State) -> np.ndarray:
        return s.h[:, None].copy()

    def dual(self, t, s: _State, step):
        dh, dlt, _, blocks = step
        dr = -self.ops.image(dh)
        if s.flipped:  # one channel, large n: the step's T(dh) by FFT products (two n × n products fewer)
            def dT(X, transpose):
                return toeplitz_times(dh, X, transpose=transpose)
        else:
            dT = self.ops.toeplitz(dh)
        v, W = linearised_dual(t, blocks, dT, dlt, s.r, dr, s.psi, weight=self.w)
        return v[:, None], W[None]

    def advance(self, t, s: _State, step, bounds, deadline):
        """Step towards the centre at ``μt``: of the predictions of
        :func:`~unfalsify.solvers.barrier.path_predictor` (linear in 1/t from this centred point, and the Hermite
        cubic in 1/t through it and the one before), the point with the lower ``f_{μt}``, each backtracked on
        feasibility (the former route: linear in t)."""
        t_new = t * self.mu
        centre = (t, np.append(s.h, s.d), np.append(*step[2]))
        if _STEP_ROUTE["route"] == "former":
            steps = [(t_new - t) * centre[2]]
        else:
            steps = path_steps(t_new, centre, self._centred)
        self._centred = centre
        return t_new, best_along(s, steps, lambda p: self._feasible_along(s, p, t_new), lambda q: q.phi(t_new))

    def _feasible_along(self, s: _State, p, t):
        """The first strictly feasible point of ``s + a p``, ``a = 1, ½, …, 2⁻⁷`` (else ``s``)."""
        a = 1.0
        for _ in range(8):
            sn = self._state(s.h + a * p[:-1], s.d + a * p[-1])
            if np.isfinite(sn.phi(t)):
                return sn
            a *= 0.5
        return s

    def run(self, h0):
        deadline = Deadline(self.time_limit)
        with self.bound_threads():
            up0 = self.ops.norm(h0)
        d0 = 1.2 * up0 + 1e-3 * (1.0 + up0)
        return run_barrier(self, self.f, self._state(h0, d0), self.nbar / d0, deadline, up0)



def solve_arx_barrier(form: ColumnForm, h0: np.ndarray, *, tol=1e-7, time_limit=None, progress=True, mu=None) -> dict:
    """Run the Cholesky barrier method on the ARX column form ``form`` (j = 1) from impulses ``h0``
    (an :class:`ArxBlockForm` for several channels: h0 of size nlm, in C order (t, α, β)).

    Parameters
    ----------
    form : ColumnForm
        Program (C) with j = 1 (see :mod:`unfalsify.solvers.columns`).
    h0 : ndarray, shape (n,)
        Strictly feasible start: ``‖P(B − T(u)h0)‖ < ρ``.
    tol : float
        Stop when the certified relative gap ``(upper − lower)/upper ≤ tol``.
    time_limit : float, optional
        Wall-clock limit in seconds (status ``"time_limit"``).
    progress : bool
        tqdm bar for solves longer than ~2 s.
    mu : float, optional
        Factor of t per outer iteration; default 3 (measured in the module docstring; the former route of
        :func:`unfalsify.solvers.baselines.former_routes`: 8 for n ≤ 200, 3 above).

    Returns
    -------
    dict
        The bracket of :func:`unfalsify.solvers.barrier.run_barrier` (scaled units): ``status``
        (``optimal``, ``time_limit``, ``interrupted``, ``max_iter``, ``failed``), the best certified
        ``upper`` and its impulses ``H`` (n × 1), the best ``lower`` and its dual point ``V`` (n × 1),
        ``W`` (1 × n × n), ``newton``, ``outer``, ``time``, and ``trials`` (Cholesky factorisations of K tried).
    """
    solver = _ArxBarrier(form, tol=tol, time_limit=time_limit, progress=progress, mu=mu)
    solver.bound_threads = _configured_blas()
    with _blas_policy(form):
        out = solver.run(np.asarray(h0, float).reshape(-1))
    out["trials"] = solver.trials
    if solver.reason is not None:
        out["reason"] = solver.reason
    return out


def _sum_squares(X: np.ndarray) -> float:
    """``Σ X_ij²`` without an n × n temporary."""
    return float(np.vdot(X, X)) if X.flags.c_contiguous else float(np.sum(X * X))


def _default_mu(form: ColumnForm) -> float:
    """:data:`_MU` (the former route of :func:`~unfalsify.solvers.baselines.former_routes`: 8 up to n = 200, else 3)."""
    if _STEP_ROUTE["route"] == "former":
        return 8.0 if form.m <= 200 else 3.0
    return _MU


def _blas_policy(form):
    """One BLAS thread for one channel up to n = :data:`_ONE_BLAS_THREAD_UP_TO`, else BLAS as configured.

    A step's BLAS calls at these sizes are short, and between them the solve runs FFTs and numpy code on the
    main thread; OpenBLAS's second thread spins between calls and takes the core that work needs.  Measured
    on 2 cores, same process, alternating (module docstring): n = 400 1.6 s against 3.9 s with two threads,
    n = 1000 21–22 s against 25–27 s.  Larger n and several channels (dense n³ work dominates) are not measured
    and keep the configured threads.  The bounds (dense SVDs and products) get the configured threads back
    (:func:`_configured_blas`).
    """
    if isinstance(form, BlockColumnForm) or form.m > _ONE_BLAS_THREAD_UP_TO:
        return contextlib.nullcontext()
    return one_blas_thread()


def _configured_blas():
    """A context that restores BLAS's threads as they are now (inside :func:`_blas_policy`: as configured).

    For the bounds, whose dense SVDs and products are long BLAS calls: at n = 1000 an SVD (values only) takes
    0.13 s on two threads against 0.20 s on one, a product 0.023 s against 0.049 s; a context costs under 1 ms.
    A user's or ``workers=1``'s limit of one thread is what is restored, so it stays one.
    """
    from threadpoolctl import threadpool_info, threadpool_limits

    threads = max((lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"), default=None)
    return lambda: threadpool_limits(limits=threads, user_api="blas")


def ridge_start(form: ColumnForm, B0: np.ndarray, frac: float = 0.9) -> np.ndarray:
    """Ridge impulses ``h = argmin ‖B0 − P T(u)h‖² + λ‖h‖²`` with ``‖B0 − P T(u)h‖ = frac·ρ`` (λ by bisection; for a
    record that starts with zero input, ``frac`` of the way from the noise floor to ρ: :func:`start_target`).

    ``B0 = P B`` (B with its component in 𝓛 removed, P the projector onto 𝓛^⊥); the result is strictly
    feasible for (C).  Fitting through P matters when 𝓛 holds whole rows (free equation errors): an
    unprojected fit would force ``(T(u)h)`` to vanish on them and start from an enormous ‖T(h)‖ (measured:
    ‖T(h0)‖ ≈ 1e13 and a failed solve where the optimum is 0.4).

    Where ``‖h‖₂`` (a lower bound of ‖T(h)‖₂) exceeds :data:`_FAR_RIDGE` × ‖B0‖/‖u‖, the fit at
    :data:`_NEAR_FRAC`·ρ is taken instead if its ``‖h‖₂`` is smaller: the data's part that T(u) reaches only
    through singular directions may need most of the noise ball.  Measured on a fuzzed record (n = 41, input with
    ``u₀ = 1e-8``, σ = 0.1 × the least-squares rms, cond T(u) = 6e24): that part is 0.95–0.97 ρ, so the fit at 0.9ρ
    had ‖T(h)‖₂ = 5.5e9 and both ARX solvers ended ``failed``, while at 0.97–0.999ρ it is 180–202 and the barrier
    certifies δ = 159.69 in scaled units (Clarabel: the same δ, 6.5022 in data units).
    """
    h = _ridge_start(form, B0, frac)
    scale = float(np.linalg.norm(B0)) / max(float(np.linalg.norm(form.U)), np.finfo(float).tiny)
    if frac < _NEAR_FRAC and np.linalg.norm(h) > _FAR_RIDGE * scale:
        near = _ridge_start(form, B0, _NEAR_FRAC)
        if np.linalg.norm(near) < np.linalg.norm(h):
            return near
    return h


#: :func:`ridge_start`: a fit with ``‖h‖₂`` above this multiple of ‖B0‖/‖u‖ is far from any δ the data need, unless
#: singular directions of T(u) carry a part of the data close to ρ (then the fit at :data:`_NEAR_FRAC`·ρ is tried).
_FAR_RIDGE = 1e3
#: :func:`ridge_start`: the residual, as a fraction of ρ, of the fallback fit (noise slack ψ = 2 % of ρ²).
_NEAR_FRAC = 0.99


def _ridge_start(form: ColumnForm, B0: np.ndarray, frac: float) -> np.ndarray:
    """The fit of :func:`ridge_start` at ``frac``·ρ."""
    channels = isinstance(form, BlockColumnForm)
    target = start_target(form.rho, form.noise_floor()[0], frac)  # a record that starts at rest pins noise
    if not channels and form.m >= _STRUCTURED_FROM and form.Qr is None:
        return _ridge_from_gram(form, B0[:, 0], target)
    Tu = _channel_operator(form) if channels else toeplitz_matrix(form.U[:, 0])
    # several channels: M is nl × nlm (wide); the thin factors span every direction the fit can use
    return ridge_fit(operator_svd(Tu, basis=form.Ql), B0[:, 0], target)


def _ridge_from_gram(form: ColumnForm, b: np.ndarray, target: float) -> np.ndarray:
    """:func:`ridge_start`'s fit for one channel without an SVD (:func:`~unfalsify.solvers.start.ridge_fit_gram`):
    the Gram of ``M = P T(u)`` is ``T(u)ᵀT(u) − (T(u)ᵀQ)(T(u)ᵀQ)ᵀ`` (P = I − QQᵀ, Q = ``form.Ql``), O(n²) plus a
    rank-q product, and ``Mᵀb = T(u)ᵀb`` (b = Pb).  The thin SVD with vectors had taken 0.45 s at n = 1000 and
    more than ten minutes at n = 10⁴; a factorisation per λ costs n³/3."""
    U = form.U
    gram = toeplitz_gram(U[:, 0])
    if form.Ql is not None and form.Ql.shape[1]:
        TQ = conv_cols_T(U, form.Ql)
        gram -= TQ @ TQ.T

    def residual(h):
        r = b - form.project(form.apply(h[:, None]))[:, 0]
        return float(r @ r)

    return ridge_fit_gram(gram, form.apply_T(b[:, None])[:, 0], residual, target)


def solve(problem, *, tol: float = 1e-6, time_limit=None, progress: bool = True) -> SolverOutput:
    """Registered solver ``"arx_barrier"``: (7.4) of an :class:`unfalsify.ArxProblem`, certified to the
    relative gap ``tol`` (see the module docstring); the answer in data units."""
    f = problem.column_form(scaled=True)
    deadline = Deadline()
    shape = (problem.n,) if problem.siso else (problem.n, problem.n_outputs, problem.n_inputs)
    if zero_answer(f):  # the least-squares model already explains the data: δ = 0
        return unscaled(problem, np.zeros(shape), 0.0, "optimal", deadline.elapsed())
    out = solve_arx_barrier(f, ridge_start(f, f.project(f.B)), tol=float(tol), time_limit=time_limit,
                            progress=progress)
    W = None if out["W"] is None else out["W"][0]
    V = None if out["V"] is None else out["V"][:, 0]
    return unscaled(problem, out["H"][:, 0].reshape(shape), out["upper"], out["status"], deadline.elapsed(), V=V,
                    W=W, stats=dict(newton=out["newton"], outer=out["outer"], trials=out["trials"],
                                    **({"reason": out["reason"]} if "reason" in out else {})))


def _channel_operator(form: BlockColumnForm) -> np.ndarray:
    """Dense ``M`` (nl × nlm) with ``M h = T(h)u`` (j = 1): row (s, α), column (t, α, β) holds ``u_{s−t, β}``."""
    n, l, m = form.i, form.n_out, form.n_in
    Tu = block_toeplitz_matrix(form.U[:, 0].reshape(n, 1, m)).reshape(n, n, m)  # [s, t, β] = u_{s−t, β}
    M = np.zeros((n, l, n, l, m))
    for a in range(l):
        M[:, a, :, a, :] = Tu
    return M.reshape(n * l, n * l * m)
