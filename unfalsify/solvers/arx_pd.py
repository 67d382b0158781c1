"""Solver ``"arx_pd"``: primal–dual interior-point method (NT scaling, Mehrotra) for the ARX program (7.4).

The column form (C) with j = 1 (:mod:`unfalsify.solvers.columns`) as a cone program in the form of
CVXOPT's ``coneqp`` (Vandenberghe, *The CVXOPT linear and quadratic cone program solvers*, 2010)::

    minimise cᵀx   s.t.   G x + s = q,   s ∈ K = S₊^{2n} × Q^{n+1},          x = (h, δ),  c = (0, 1),

    s_L = F(h, δ) = δI + Σ_a h_a E_a,   E_a = [0 Z_aᵀ; Z_a 0]   (Z_a the a-th shift, T(h) = Σ h_a Z_a),
    s_Q = (ρ, b − A h),                 b = P B,  A = P T(u)   (P the projector off 𝓛 = range Φ).

Its dual is ``maximise −qᵀz  s.t.  Gᵀz + c = 0, z ∈ K``, with ``z = (Z, (z₀, z₁))``: ``tr Z = 1``,
``2 T*(Z₂₁) = Aᵀz₁`` and objective ``−ρ z₀ − bᵀz₁``.  That is exactly the weak-duality pair of
:meth:`ColumnForm.lower_bound`: ``V = −z₁`` and ``W = −2 Z₂₁`` satisfy ``T*(W) = T(u)ᵀ P V`` and
``‖W‖_* ≤ tr Z = 1``, so every iterate's dual point is fed to the SAME certified bound as the barrier
method's linearised dual (the bound repairs what rounding leaves of the equality).  The upper side is
:func:`~unfalsify.solvers.toeplitz.certified_norm` of the iterate's impulses; the loop, stopping rule
(:func:`~unfalsify.solvers.barrier.gap_closed`), time limit, Ctrl-C and failures are those of
:func:`~unfalsify.solvers.barrier.run_barrier` (one predictor–corrector iteration per "centring").

Feasible start.  The ridge impulses of :func:`~unfalsify.solvers.arx_barrier.ridge_start` with
δ above ‖T(h)‖₂ make (h, δ) strictly primal feasible, and ``Z = I/(2n)``, ``z = (z₀, 0)`` strictly dual
feasible (``T*(Z₂₁) = 0 = Aᵀ0``, ``tr Z = 1``).  The primal slack is therefore kept as ``F(h, δ)`` itself
(its residual stays zero along Newton directions) and the dual residual ``Gᵀz + c`` stays at rounding level
(kept in the right-hand side so that it does not drift).

NT scaling.  For the LMI block the Nesterov–Todd point is the unique ``W ≻ 0`` with ``W Z W = S``.
With ``Z = L Lᵀ`` (Cholesky) and the eigendecomposition ``Lᵀ S L = Q Λ² Qᵀ``,
``R⁻¹ = Λ^{-1/2} Qᵀ Lᵀ`` gives ``R⁻¹ S R⁻ᵀ = Rᵀ Z R = Λ`` (the scaled point λ) and
``W⁻¹ = R⁻ᵀR⁻¹ = L Q Λ⁻¹ Qᵀ Lᵀ`` (check: ``W⁻¹ S W⁻¹ = Z``).  For the second-order cone the NT scaling is
``W_Q = β(2vvᵀ − J)`` (J = diag(1, −I), v built from the scaling point w̄, ``vᵀJv = 1``),
``W_Q⁻¹ = (2Jvvᵀ J − J)/β``.

Schur complement.  Eliminating ds and dz from the linearised system
``Gᵀdz = −r_x``, ``G dx + ds = 0``, ``W⁻ᵀds + W dz = t̃`` (t̃ the Mehrotra right-hand side in the
scaled space) leaves ``Gᵀ(WᵀW)⁻¹G dx = −r_x − Gᵀ(WᵀW)⁻¹Wᵀt̃`` with

* h–h block ``tr(W⁻¹E_a W⁻¹E_b)``: the Hessian of ``−log det F`` with ``F⁻¹`` replaced by ``W⁻¹``, so it is
  :func:`~unfalsify.solvers.toeplitz.corr_hessian` of the blocks of ``W⁻¹`` (the same O(n² log n) 2-D-FFT
  correlation as the barrier method; tested against the dense sum), plus the SOC term
  ``Aᵀ(W_Q⁻²)₁₁A = (AᵀA + 8v₀² (Aᵀv₁)(Aᵀv₁)ᵀ)/β²`` (``AᵀA`` formed once, a rank-one update per iteration);
* h–δ column ``tr(W⁻¹E_aW⁻¹) = 2 T*((W⁻²)₂₁)`` and δ–δ entry ``tr W⁻² = ‖W⁻¹‖²_F``.

One Cholesky factor of this (n + 1) × (n + 1) matrix ((nlm + 1)² for several channels) serves the predictor and the corrector.  Step lengths are
exact: the smallest eigenvalue of ``Λ^{-1/2} d̃ Λ^{-1/2}`` for the LMI, a quadratic for the SOC.

Cost.  Every iteration works on dense 2n × 2n matrices, because Z has no structure: one Cholesky of Z (the
feasibility check of the previous step), one symmetric eigendecomposition (the NT point), about eight 2n × 2n
products (half of them triangular or symmetric: trmm, syrk) and four Lanczos step lengths, against n × n Cholesky
factorisations and products for the barrier method.  Measured (``bench-unfalsify --series arx-pd``, tol 1e-4):
10–11 iterations at n = 200 … 1000 against 44–77 barrier Newton steps, but one iteration costs about 9–10 Newton
steps at n = 1000 (6.3 s; the eigendecomposition alone 1.5 s), so the method is slower than ``arx_barrier``
there (0.75× at n = 1000, 0.62× at n = 400, 0.93× at n = 200; ``experiments/bench/BENCHMARKS.md``).
Memory O(n²) (about ten 2n × 2n arrays).

Several channels (u (n, m), y (n, l); :class:`~unfalsify.solvers.arx_barrier.ArxBlockForm`).  The same method with
h the nlm Markov parameters (C order (t, α, β)), T(h) the nl × nm block lower-triangular Toeplitz matrix, the LMI
``[δI_nm T(h)ᵀ; T(h) δI_nl]`` of order n(l + m) (ν = n(l + m) + 1), the SOC of order nl + 1, ``A`` the projected
dense channel operator; the structure-dependent pieces (T(h), its Gram, the block adjoint, the block FFT Hessian
:func:`~unfalsify.solvers.toeplitz.block_corr_hessian` of the blocks of ``W⁻¹``, the certified block norm) are
those of :mod:`~unfalsify.solvers.arx_barrier` (its ``_Siso`` / ``_Channels``), and the dual point is
``W = −2Z₂₁`` (nl × nm) for :meth:`BlockColumnForm.lower_bound`.  One channel each runs the SISO routines.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg
from scipy.linalg import blas as _blas

from .arx_barrier import ridge_start
from .barrier import Deadline, PrimalDualSteps, Stop, cholesky_retry, run_barrier
from .base import SolverOutput, unscaled, zero_answer
from .arx_barrier import _Channels, _channel_operator, _Siso
from .columns import BlockColumnForm, ColumnForm
from .cones import (_sdp_step, _soc_div, _soc_prod, _soc_step, _soc_w, _soc_winv, nt_scaling,
                    soc_scaling)
from .toeplitz import toeplitz_matrix

__all__ = ["solve", "solve_arx_pd", "nt_scaling", "soc_scaling"]


# ---- the iterate and one predictor–corrector step ---------------------------------------------------
class _Point:
    """Primal (h, δ) with its slacks ``S = F(h, δ)`` and ``s_Q = (ρ, b − Ah)``; dual ``Z``, ``z``; ``Lz`` the
    Cholesky factor of Z once computed (the step's feasibility check computes it for the next scaling)."""

    __slots__ = ("h", "d", "Z", "z", "T", "sq", "Lz")

    def __init__(self, h, d, Z, z, form: ColumnForm, A: np.ndarray, b: np.ndarray, ops, Lz=None, T=None):
        self.h, self.d, self.Z, self.z, self.Lz = h, float(d), Z, z, Lz
        self.T = ops.toeplitz(h) if T is None else T
        self.sq = np.r_[form.rho, b - A @ h]

    def slack(self) -> np.ndarray:
        """``F(h, δ)`` (2n × 2n)."""
        return _lmi(self.T, self.d)


def _lmi(T, d):
    """``[dI Tᵀ; T dI]`` for T of shape (N₂, N₁) (N₁ + N₂ square)."""
    n2, n1 = T.shape
    N = n1 + n2
    F = np.empty((N, N))
    F[:n1, :n1] = 0.0
    F[n1:, n1:] = 0.0
    F[:n1, n1:] = T.T
    F[n1:, :n1] = T
    F[np.diag_indices(N)] = d
    return F


def _symmetric(U):
    """The full symmetric matrix of syrk's upper triangle ``U`` (its strict lower triangle is garbage)."""
    il = np.tril_indices(U.shape[0], -1)
    U[il] = U.T[il]
    return np.ascontiguousarray(U)


class _Scaling:
    """The NT scaling of one iterate with the products the iteration reuses: ``Rinv`` (R⁻¹), ``lam``,
    ``Winv`` (W⁻¹ = R⁻ᵀR⁻¹), ``M = R⁻¹R⁻ᵀ`` and the SOC's ``beta``, ``v``."""

    __slots__ = ("Rinv", "lam", "Winv", "M", "beta", "v")


class _ArxPrimalDual(PrimalDualSteps):
    """The method of the module docstring, plugged into :func:`run_barrier`: ``centre`` is one
    predictor–corrector iteration, ``t`` the complementarity μ, ``advance`` the stall check."""

    def __init__(self, form: ColumnForm, *, tol, time_limit, progress, max_iter=200, eta=0.99):
        if form.j != 1:
            raise ValueError("the primal–dual solver is for the ARX program (j = 1)")
        self.f = form
        self.tol, self.time_limit, self.progress = tol, time_limit, progress
        self.max_iter, self.eta = max_iter, eta
        if isinstance(form, BlockColumnForm):  # several channels: T(h) is nl × nm (module docstring)
            self.ops = _Channels(form)
            n, l, m = form.i, form.n_out, form.n_in
            self.desc = f"primal-dual ARX unfalsification ({l}×{m}, n={n})"
            self.A = form.project(_channel_operator(form))
        else:
            self.ops = _Siso(form)
            n, l, m = form.m, 1, 1
            self.desc = f"primal-dual ARX unfalsification (n={n})"
            self.A = form.project(toeplitz_matrix(form.U[:, 0]))
        self.N1, self.N2 = n * m, n * l  # the LMI's blocks: δI_nm (top left), δI_nl (bottom right)
        self.N = self.N1 + self.N2
        self.p = n * l * m  # unknowns h
        self.b = form.project(form.B)[:, 0]
        self.AtA = self.A.T @ self.A
        self.nu = self.N + 1  # the degree of K
        self.steps = 0
        self.factorisations = 0
        self.small_steps = 0
        self.last_gap = np.inf

    # -- the linear algebra of one iteration
    def _residual_x(self, p: _Point):
        """``r_x = Gᵀz + c``: ``(−2T*(Z₂₁) + Aᵀz₁, 1 − tr Z)``."""
        n1 = self.N1
        return -2.0 * self.ops.adjoint(p.Z[n1:, :n1]) + self.A.T @ p.z[1:], 1.0 - float(np.trace(p.Z))

    def _scaling(self, p: _Point) -> _Scaling:
        """:func:`nt_scaling` of ``(F(h, δ), Z)`` with ``S L`` formed from T(h) (two n × n × 2n products instead
        of one 2n-cubed), and the SOC scaling."""
        n1 = self.N1
        L = p.Lz
        if L is None:
            L = scipy.linalg.cholesky(p.Z, lower=True, check_finite=False)
            self.factorisations += 1
        SL = p.d * L
        SL[:n1] += p.T.T @ L[n1:]
        SL[n1:] += p.T @ L[:n1]
        # triangular and symmetric BLAS (trmm, syrk): half the flops of a general product each
        G = _blas.dtrmm(1.0, L, SL, lower=1, trans_a=1)  # Lᵀ S L
        G += G.T
        G *= 0.5
        lam2, Q = scipy.linalg.eigh(G, overwrite_a=True, check_finite=False, driver="evd")
        self.factorisations += 1
        if not lam2[0] > 0.0:
            raise np.linalg.LinAlgError("the NT scaling needs F(h, δ) ≻ 0 and Z ≻ 0")
        sc = _Scaling()
        sc.lam = np.sqrt(lam2)
        Q /= np.sqrt(sc.lam)
        B = _blas.dtrmm(1.0, L, Q, lower=1)  # R⁻ᵀ = L Q Λ^{-1/2}
        sc.Rinv = B.T
        sc.Winv = _symmetric(_blas.dsyrk(1.0, B))  # B Bᵀ
        sc.M = _symmetric(_blas.dsyrk(1.0, B, trans=1))  # Bᵀ B
        sc.beta, sc.v = soc_scaling(p.sq, p.z)
        return sc

    def _schur(self, Winv, beta, w):
        """The Schur complement ``Gᵀ(WᵀW)⁻¹G`` of the module docstring, (p + 1) × (p + 1) (p unknowns h)."""
        n1, p = self.N1, self.p
        W11, W21, W22 = Winv[:n1, :n1], Winv[n1:, :n1], Winv[n1:, n1:]
        H = np.empty((p + 1, p + 1))
        Aw = self.A.T @ w[1:]
        H[:p, :p] = self.ops.hessian(W11, W21, W22)  # corr_hessian (block_corr_hessian) of W⁻¹'s blocks
        H[:p, :p] += (self.AtA + 8.0 * w[0] ** 2 * np.outer(Aw, Aw)) / beta**2
        W2_21 = W21 @ W11 + W22 @ W21  # (W⁻²)₂₁
        H[:p, p] = H[p, :p] = 2.0 * self.ops.adjoint(W2_21)
        H[p, p] = float(np.sum(Winv * Winv))
        return H

    def _scaled_slack_step(self, sc: _Scaling, dh, dd):
        """``ds̃ = R⁻¹ F(dh, dδ) R⁻ᵀ = dδ M + X + Xᵀ`` with ``X = R⁻¹₂ T(dh) R⁻¹₁ᵀ`` (R⁻¹ = [R⁻¹₁ R⁻¹₂] by
        columns): F's off-diagonal blocks give ``R⁻¹₁T(dh)ᵀR⁻¹₂ᵀ + R⁻¹₂T(dh)R⁻¹₁ᵀ``."""
        n1 = self.N1
        C, D = sc.Rinv[:, :n1], sc.Rinv[:, n1:]
        X = D @ (self.ops.toeplitz(dh) @ C.T)
        out = X + X.T
        out += dd * sc.M
        return out

    def _direction(self, sc: _Scaling, cf, rx, tL, tq, *, affine=False):
        """Solve the scaled Newton system for the right-hand side ``t̃ = (tL, tq)``.

        ``affine``: ``tL = −Λ`` (diagonal, given as the vector −lam), whose terms are cheaper.
        Returns ``(dh, dδ, dsL, dzL, dsq, dzq)``: the step in x and the scaled slack/dual steps
        (``ds̃ + dz̃ = t̃``)."""
        n1, p = self.N1, self.p
        C, D = sc.Rinv[:, :n1], sc.Rinv[:, n1:]
        # (WᵀW)⁻¹Wᵀ t̃ = R⁻ᵀ t̃ R⁻¹ for the LMI block: its (2, 1) block and trace are all the right-hand side needs
        if affine:
            Y21 = (tL[:, None] * D).T @ C
            trY = float(tL @ np.diag(sc.M))
        else:
            Y21 = D.T @ (tL @ C)
            trY = float(np.sum(tL * sc.M))
        wq = _soc_winv(sc.beta, sc.v, tq)  # (WᵀW)⁻¹Wᵀ t̃ for the SOC
        rhs = np.empty(p + 1)
        rhs[:p] = -rx[0] + 2.0 * self.ops.adjoint(Y21) - self.A.T @ wq[1:]
        rhs[p] = -rx[1] + trY
        sol = scipy.linalg.cho_solve(cf, rhs, check_finite=False)
        dh, dd = sol[:p], float(sol[p])
        dsL = self._scaled_slack_step(sc, dh, dd)
        dzL = -dsL
        if affine:
            dzL[np.diag_indices(self.N)] += tL
        else:
            dzL += tL
        dsq = _soc_winv(sc.beta, sc.v, np.r_[0.0, -(self.A @ dh)])
        dzq = tq - dsq
        return dh, dd, dsL, dzL, dsq, dzq

    def _max_step(self, sc: _Scaling, lq, dsL, dzL, dsq, dzq):
        self.factorisations += 2
        return min(_sdp_step(sc.lam, dsL), _sdp_step(sc.lam, dzL), _soc_step(lq, dsq), _soc_step(lq, dzq))

    def _feasible(self, h, d, Z):
        """``(Lz, T)``: the Cholesky factor of Z and T(h) if ``F(h, δ) ≻ 0`` (``δ²I − T(h)ᵀT(h)`` factorises and,
        for a rectangular T, δ > 0), else None."""
        self.factorisations += 1
        try:
            Lz = scipy.linalg.cholesky(Z, lower=True, check_finite=False)
        except np.linalg.LinAlgError:
            return None
        if not d > 0.0:
            return None
        T = self.ops.toeplitz(h)
        K = self.ops.gram(h, T)
        K *= -1.0
        K[np.diag_indices_from(K)] += d * d
        self.factorisations += 1
        try:
            scipy.linalg.cholesky(K, lower=True, overwrite_a=True, check_finite=False)
        except np.linalg.LinAlgError:
            return None
        return Lz, T

    def centre(self, mu, p: _Point, deadline: Deadline):
        """One Mehrotra predictor–corrector iteration from ``p``; returns the new point and its step length."""
        deadline.check()
        if self.steps >= self.max_iter:
            raise Stop("max_iter")
        sc = self._scaling(p)
        lam = sc.lam
        lq = _soc_w(sc.beta, sc.v, p.z)  # = W_Q⁻¹ s_Q
        cf = cholesky_retry(self._schur(sc.Winv, sc.beta, sc.v))
        self.factorisations += 1
        rx = self._residual_x(p)
        gap = float(lam @ lam + lq @ lq)
        mu = gap / self.nu
        # predictor (affine scaling): ds̃ + dz̃ = −λ
        _, _, dsL, dzL, dsq, dzq = self._direction(sc, cf, rx, -lam, -lq, affine=True)
        a = min(1.0, self._max_step(sc, lq, dsL, dzL, dsq, dzq))
        diag = np.diag_indices(self.N)
        gap_a = (float(np.sum(dsL * dzL)) * a * a + a * float(lam @ (np.diag(dsL) + np.diag(dzL))) + float(lam @ lam)
                 + float((lq + a * dsq) @ (lq + a * dzq)))
        sigma = min(1.0, max(0.0, gap_a / gap)) ** 3
        # corrector: λ∘(ds̃ + dz̃) = σμe − λ∘λ − ds̃_a∘dz̃_a
        RL = dsL @ dzL
        RL += RL.T
        RL *= -0.5
        RL[diag] += sigma * mu - lam * lam
        RL /= lam[:, None] + lam[None, :]
        RL *= 2.0
        tL = RL
        Rq = -_soc_prod(lq, lq) - _soc_prod(dsq, dzq)
        Rq[0] += sigma * mu
        tq = _soc_div(lq, Rq)
        dh, dd, dsL, dzL, dsq, dzq = self._direction(sc, cf, rx, tL, tq)
        amax = self._max_step(sc, lq, dsL, dzL, dsq, dzq)
        a = min(1.0, self.eta * amax)
        dZ = sc.Rinv.T @ dzL @ sc.Rinv
        dz = _soc_winv(sc.beta, sc.v, dzq)
        for _ in range(30):  # the exact boundary is Lanczos's estimate: back off until both sides factorise
            Z = p.Z + a * dZ
            Z += Z.T
            Z *= 0.5
            ok = self._feasible(p.h + a * dh, p.d + a * dd, Z)
            if ok is not None:
                break
            a *= 0.5
        else:
            raise Stop("failed")
        new = _Point(p.h + a * dh, p.d + a * dd, Z, p.z + a * dz, self.f, self.A, self.b, self.ops, Lz=ok[0],
                     T=ok[1])
        self.steps += 1
        self.last_gap = gap
        if not (np.isfinite(a) and np.all(np.isfinite(new.h)) and np.isfinite(new.d)):
            raise Stop("failed")
        self.small_steps = self.small_steps + 1 if a < 1e-8 else 0
        return new, a

    # -- the rest of run_barrier's contract
    def upper(self, p: _Point) -> float:
        return self.ops.norm(p.h, p.d)

    def impulses(self, p: _Point) -> np.ndarray:
        return p.h[:, None].copy()

    def dual(self, mu, p: _Point, step):
        """``V = −z₁``, ``W = −2Z₂₁`` (module docstring) for :meth:`ColumnForm.lower_bound`."""
        n1 = self.N1
        return -p.z[1:, None].copy(), -2.0 * p.Z[None, n1:, :n1]

    def run(self, h0):
        deadline = Deadline(self.time_limit)
        up0 = self.ops.norm(h0)
        d0 = 1.2 * up0 + 1e-3 * (1.0 + up0)
        N = self.N
        Z0 = np.eye(N) / N
        p0 = _Point(h0, d0, Z0, np.zeros(self.b.size + 1), self.f, self.A, self.b, self.ops)
        p0.z[0] = d0 / (N * self.f.rho)  # ⟨s_Q, z_Q⟩ = the LMI block's μ per degree
        return run_barrier(self, self.f, p0, np.inf, deadline, up0)


def solve_arx_pd(form: ColumnForm, h0: np.ndarray, *, tol=1e-7, time_limit=None, progress=True) -> dict:
    """Run the primal–dual method on the ARX column form ``form`` (j = 1, one channel) from impulses ``h0``.

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

    Returns
    -------
    dict
        The bracket of :func:`unfalsify.solvers.barrier.run_barrier` (scaled units) plus ``factorisations``
        (dense Cholesky, eigendecompositions and smallest-eigenvalue computations); ``newton`` and ``outer``
        both count predictor–corrector iterations.
    """
    solver = _ArxPrimalDual(form, tol=tol, time_limit=time_limit, progress=progress)
    out = solver.run(np.asarray(h0, float).reshape(-1))
    out["factorisations"] = solver.factorisations
    return out


def solve(problem, *, tol: float = 1e-6, time_limit=None, progress: bool = True) -> SolverOutput:
    """Registered solver ``"arx_pd"``: (7.4) of an :class:`unfalsify.ArxProblem` (one channel or several),
    certified to the relative gap ``tol`` by the primal–dual method of the module docstring; the answer in data
    units."""
    f = problem.column_form(scaled=True)
    deadline = Deadline()
    shape = (problem.n,) if problem.siso else (problem.n, problem.n_outputs, problem.n_inputs)
    if zero_answer(f):
        return unscaled(problem, np.zeros(shape), 0.0, "optimal", deadline.elapsed())
    out = solve_arx_pd(f, ridge_start(f, f.project(f.B)), tol=float(tol), time_limit=time_limit, progress=progress)
    W = None if out["W"] is None else out["W"][0]
    V = None if out["V"] is None else out["V"][:, 0]
    return unscaled(problem, out["H"][:, 0].reshape(shape), out["upper"], out["status"], deadline.elapsed(), V=V,
                    W=W, stats=dict(newton=out["newton"], outer=out["outer"], factorisations=out["factorisations"]))
