"""Solver ``"column_pd"``: primal–dual interior-point method (NT scaling, Mehrotra) for the subspace program (7.5).

The column form (C) of :mod:`unfalsify.solvers.columns` (m = i rows, j columns, L optimised or fixed) as a cone
program in the form of CVXOPT's ``coneqp`` (Vandenberghe, *The CVXOPT linear and quadratic cone program solvers*,
2010), the method of :mod:`~unfalsify.solvers.arx_pd` with one semidefinite block per column::

    minimise δ   s.t.   G x + s = q,   s ∈ (S₊^{2m})ʲ × Q^{mj+1},          x = (H, δ),

    s_k = F(h_k, δ) = [δI T(h_k)ᵀ; T(h_k) δI]    (k = 0 … j−1),
    s_Q = (ρ, P(B − H̃))                          (H̃ column k = T(u_k) h_k, P the projector onto 𝓛^⊥).

Its dual: maximise ``−ρ z₀ − ⟨PB, z₁⟩`` s.t. ``Σ_k tr Z_k = 1``, ``2 T*(Z_k,₂₁) = T(u_k)ᵀ(P z₁)_k``, ``Z_k ⪰ 0``,
``(z₀, z₁)`` in the cone.  ``V = −z₁`` and ``W_k = −2 Z_k,₂₁`` satisfy ``T*(W_k) = T(u_k)ᵀ(PV)_k`` and
``Σ_k ‖W_k‖_* ≤ Σ_k tr Z_k = 1``: every iterate's dual point goes to the SAME certified bound as the barrier
method's (:meth:`ColumnForm.lower_bound`, which repairs what rounding leaves of the equalities), and the upper
side is ``max_k ‖T(h_k)‖₂`` of the (strictly feasible) iterate; the stop, time limit, Ctrl-C and failures are
those of :func:`~unfalsify.solvers.barrier.run_barrier`, one predictor–corrector iteration per "centring".

One iteration (the ``arx_pd`` iteration, batched over the j blocks on the threads of
:class:`~unfalsify.solvers.stacks._Chunks`):

* the NT scaling of every block (``Z_k = L_kL_kᵀ``, ``L_kᵀ S_k L_k = Q_kΛ_k²Q_kᵀ``, ``S_k L_k`` from T(h_k) by two
  m × m × 2m products) and of the noise cone (:mod:`~unfalsify.solvers.cones`);
* the Schur complement in (H, δ) has the structure of the barrier method's Newton system: per column the FFT
  Hessian ``tr(W_k⁻¹E_aW_k⁻¹E_b)`` of the blocks of ``W_k⁻¹`` (:func:`~unfalsify.solvers.toeplitz.corr_hessian`;
  the displacement route needs F⁻¹'s structure, which ``W⁻¹`` lacks), the noise cone's curvature
  ``(MᵀPM + 8v₀² g gᵀ)/β²`` with ``g = MᵀPv₁`` (M: H ↦ H̃), and the δ row ``2T*((W_k⁻²)₂₁)``, ``Σ_k ‖W_k⁻¹‖²_F``.
  It is solved by the barrier method's code (:class:`~unfalsify.solvers.column_barrier._ColumnSystem`: block
  LU solves, Sherman–Morrison, with L optimised the Woodbury capacitance by deflated conjugate gradients),
  twice per iteration (predictor, corrector), the Woodbury parts built once;
* exact step lengths (batched eigenvalues of ``Λ^{-1/2} d Λ^{-1/2}``; a quadratic for the noise cone), a fraction
  0.99 of the way, backtracked until every ``Z_k`` and ``K_k = δ²I − T_kᵀT_k`` factorise and the residual stays in
  the noise ball.

Feasible start: the barrier method's ridge impulses (``‖P(B − H̃)‖_F = 0.7ρ``) with δ 20 % above their norm, and
``Z_k = I/(2mj)``, ``z = (z₀, 0)`` (dual feasible: ``T*(Z_k,₂₁) = 0``, ``Σ tr Z_k = 1``).  The primal slacks are kept
as functions of (H, δ) (zero primal residual); the dual residual ``Gᵀz + c`` stays at rounding level and is kept
in the right-hand side.

Cost.  Every iteration works on the j dense 2m × 2m blocks ``Z_k`` (no structure): a Cholesky factor, a symmetric
eigendecomposition, about eight products and two batched eigenvalue computations for the step lengths, where a
barrier Newton step works on m × m blocks.  The method takes few iterations (measured in
``experiments/bench/BENCHMARKS.md``), but each costs several Newton steps of :mod:`~unfalsify.solvers.column_barrier`.
Memory: about a dozen (j, 2m, 2m) stacks (320 MB each at (i, j) = (100, 1000)).
"""
from __future__ import annotations

import numpy as np

from .barrier import Deadline, PrimalDualSteps, Stop, delta_step, run_barrier
from .base import SolverOutput, unscaled, zero_answer
from .column_barrier import _ColumnSystem, _on_threads
from .stacks import _SERIAL, _chol_logdet, _Chunks, _max_norm
from .columns import ColumnForm
from .cones import _soc_div, _soc_prod, _soc_step, _soc_w, _soc_winv, sdp_step_stack, soc_scaling
from .start import operator_svd
from .toeplitz import _tr, adjoint, corr_hessian, toeplitz_stack

__all__ = ["solve", "solve_columns_pd"]


class _Point:
    """Primal (H, δ) with ``T_k = T(h_k)`` and its Gram stack, the projected residual ``r = P(B − H̃)``; dual ``Z``
    (j, 2m, 2m), ``z0``, ``z1`` (m × j); ``Lz`` the Cholesky factors of Z (from the step's feasibility check)."""

    __slots__ = ("H", "Lz", "T", "TtT", "Z", "d", "r", "z0", "z1")

    def __init__(self, H, d, T, TtT, r, Z, z0, z1, Lz=None):
        self.H, self.d, self.T, self.TtT, self.r = H, float(d), T, TtT, r
        self.Z, self.z0, self.z1, self.Lz = Z, float(z0), z1, Lz


class _Scaling:
    """The NT scaling of one iterate: ``Rinv`` (j, 2m, 2m), ``lam`` (j, 2m), ``Winv = R⁻ᵀR⁻¹``, ``M = R⁻¹R⁻ᵀ``, and
    the noise cone's ``beta``, ``v`` and scaled point ``lq = W_Q⁻¹ s_Q``."""

    __slots__ = ("M", "Rinv", "Winv", "beta", "lam", "lq", "v")


class _ColumnPrimalDual(_ColumnSystem, PrimalDualSteps):
    """The method of the module docstring, plugged into :func:`run_barrier`: ``centre`` is one predictor–corrector
    iteration, ``t`` unused, ``advance`` the stall check."""

    def __init__(self, form: ColumnForm, *, tol, time_limit, progress, max_iter=200, eta=0.99,
                 chunks: _Chunks = _SERIAL):
        super().__init__(form, chunks=chunks)
        self.tol, self.time_limit, self.progress = tol, time_limit, progress
        self.max_iter, self.eta = max_iter, eta
        self.N = 2 * self.m * self.j  # the order of the block-diagonal LMI
        self.nu = self.N + 1  # the degree of the cone
        self.steps = 0
        self.factorisations = 0
        self.small_steps = 0
        self.last_gap = np.inf
        self.desc = f"primal-dual structured unfalsification ({self.m}×{self.j})"

    # ---- the iterate ---------------------------------------------------------------------------------
    def _vec(self, x0, X):
        """A point of the noise cone ``(x₀, vec X)`` (X m × j)."""
        return np.r_[x0, X.ravel()]

    def _mat(self, x):
        """The m × j part of a noise-cone vector."""
        return x[1:].reshape(self.m, self.j)

    def _feasible(self, H, d, Z):
        """``(Lz, T, TtT, r)`` if every ``Z_k ≻ 0``, every ``K_k = δ²I − T_kᵀT_k ≻ 0`` and ``‖P(B − H̃)‖ < ρ``; else
        None."""
        if not d > 0.0:
            return None
        r = self._resid(H)
        if not float(np.sum(r * r)) < self.f.rho**2:
            return None
        self.factorisations += 2
        Lz = np.empty_like(Z)
        try:
            self.chunks.map(lambda s: np.copyto(Lz[s], np.linalg.cholesky(Z[s])), self.j, Z.size)
        except np.linalg.LinAlgError:
            return None
        T, TtT = self._gram(H)
        if _chol_logdet(TtT, self.chunks, shift=d * d) is None:
            return None
        return Lz, T, TtT, r

    def _residual_x(self, p: _Point):
        """``Gᵀz + c``: ``(−2T*(Z_k,₂₁) + T(u_k)ᵀ(P z₁)_k, 1 − Σ_k tr Z_k)``."""
        m = self.m
        rh = -2.0 * adjoint(p.Z[:, m:, :m]) + self.f.apply_T(self.f.project(p.z1))
        return rh, 1.0 - float(np.trace(p.Z, axis1=1, axis2=2).sum())

    # ---- scaling and Schur complement ----------------------------------------------------------------
    def _scaling(self, p: _Point) -> _Scaling:
        """The NT scaling of every block (``S_k L_k`` from T(h_k)) and of the noise cone."""
        m, j = self.m, self.j
        L = p.Lz if p.Lz is not None else np.linalg.cholesky(p.Z)
        sc = _Scaling()
        sc.Rinv, sc.Winv, sc.M = np.empty_like(p.Z), np.empty_like(p.Z), np.empty_like(p.Z)
        sc.lam = np.empty((j, 2 * m))
        ok = []

        def work(s):
            Ls = L[s]
            SL = p.d * Ls
            SL[:, :m] += _tr(p.T[s]) @ Ls[:, m:]
            SL[:, m:] += p.T[s] @ Ls[:, :m]
            G = _tr(Ls) @ SL
            G += _tr(G)
            G *= 0.5
            lam2, Q = np.linalg.eigh(G)
            ok.append(bool(np.all(lam2[:, 0] > 0.0)))
            lam = np.sqrt(np.maximum(lam2, 0.0))
            sc.lam[s] = lam
            Q /= np.sqrt(np.where(lam > 0.0, lam, 1.0))[:, None, :]
            B = Ls @ Q  # R⁻ᵀ = L Q Λ^{-1/2}
            np.copyto(sc.Rinv[s], _tr(B))
            W = B @ _tr(B)
            np.add(W, _tr(W), out=sc.Winv[s])
            sc.Winv[s] *= 0.5
            M = _tr(B) @ B
            np.add(M, _tr(M), out=sc.M[s])
            sc.M[s] *= 0.5

        self.chunks.map(work, j, p.Z.size)
        self.factorisations += 1
        if not all(ok):
            raise np.linalg.LinAlgError("the NT scaling needs F(h_k, δ) ≻ 0 and Z_k ≻ 0")
        sq, zq = self._vec(self.f.rho, p.r), self._vec(p.z0, p.z1)
        sc.beta, sc.v = soc_scaling(sq, zq)
        sc.lq = _soc_w(sc.beta, sc.v, zq)
        return sc

    def _schur(self, sc: _Scaling):
        """The Schur complement's parts: the h–h blocks (j, m, m), the h–δ column (m, j), the δ–δ entry, and the
        noise cone's ``(c, α, g)`` of :meth:`_solve_h`."""
        m = self.m
        W11, W21, W22 = (np.ascontiguousarray(sc.Winv[:, a:a + m, b:b + m]) for a, b in ((0, 0), (m, 0), (m, m)))
        G = np.empty_like(W11)
        col = np.empty((m, self.j))

        def work(s):
            G[s] = corr_hessian(W11[s], W21[s], W22[s], m)
            col[:, s] = 2.0 * adjoint(W21[s] @ W11[s] + W22[s] @ W21[s])  # 2 T*((W⁻²)₂₁)

        self.chunks.map(work, self.j, W11.size)
        dd = float(np.vdot(sc.Winv, sc.Winv))
        v0, v1 = float(sc.v[0]), self._mat(sc.v)
        g = self.f.apply_T(self.f.project(v1))
        return G, col, dd, 1.0 / sc.beta**2, 8.0 * v0 * v0 / sc.beta**2, g

    # ---- one direction -------------------------------------------------------------------------------
    def _direction(self, sc: _Scaling, schur, parts, rx, tL, tq, *, affine=False):
        """Solve the scaled Newton system for ``t̃ = (tL, tq)`` (``affine``: ``tL = −Λ`` given as the vectors −lam).

        Returns ``(dH, dδ, dsL, dzL, dsq, dzq, parts)``: the step in x, the scaled slack and dual steps
        (``ds̃ + dz̃ = t̃``), and what the next solve with this Schur complement reuses: its Woodbury parts and the
        h–h block's solve against the h–δ column (for the elimination of dδ; the corrector's right-hand side
        alone is then solved)."""
        m, j = self.m, self.j
        G, col, dd, cc, alpha, g = schur
        C, D = sc.Rinv[:, :, :m], sc.Rinv[:, :, m:]
        # (WᵀW)⁻¹Wᵀt̃ = R⁻ᵀt̃R⁻¹ on each block: its (2, 1) block and trace are all the right-hand side needs
        Y21 = np.empty((j, m, m))
        if affine:
            def work(s):
                Y21[s] = _tr(tL[s][:, :, None] * D[s]) @ C[s]
            trY = float(np.sum(tL * np.diagonal(sc.M, axis1=1, axis2=2)))
        else:
            def work(s):
                Y21[s] = _tr(D[s]) @ (tL[s] @ C[s])
            trY = float(np.vdot(tL, sc.M))
        self.chunks.map(work, j, sc.Rinv.size)
        wq = _soc_winv(sc.beta, sc.v, tq)
        rh = -rx[0] + 2.0 * adjoint(Y21) - self.f.apply_T(self.f.project(self._mat(wq)))
        rd = -rx[1] + trY
        if parts is None:
            X, woodbury = self._solve_h(G, cc, alpha, g, np.stack([rh, col], axis=-1))
            xr, xc = X[..., 0], X[..., 1]
        else:
            woodbury, xc = parts
            X, _ = self._solve_h(G, cc, alpha, g, rh[..., None], woodbury)
            xr = X[..., 0]
        parts = (woodbury, xc)
        # the system reads S Δ = r: the gradient of delta_step is −r
        elim = delta_step(dd, -rd, -float(np.sum(col * xr)), float(np.sum(col * xc)))
        if elim is None:  # a Schur complement that is not positive: the h-block solves lost their digits
            raise Stop("failed")
        dlt = elim[0]
        dH = xr - xc * dlt
        dsL = self._scaled_slack_step(sc, dH, dlt)
        dzL = -dsL
        if affine:
            idx = np.arange(2 * m)
            dzL[:, idx, idx] += tL
        else:
            dzL += tL
        dsq = _soc_winv(sc.beta, sc.v, self._vec(0.0, -self.f.project(self.f.apply(dH))))
        dzq = tq - dsq
        return dH, dlt, dsL, dzL, dsq, dzq, parts

    def _scaled_slack_step(self, sc: _Scaling, dH, dlt):
        """``ds̃_k = R⁻¹_k F(dh_k, dδ) R⁻ᵀ_k = dδ M_k + X_k + X_kᵀ``, ``X_k = D_k T(dh_k) C_kᵀ`` (R⁻¹ = [C D] by columns)."""
        m = self.m
        C, D = sc.Rinv[:, :, :m], sc.Rinv[:, :, m:]
        dT = toeplitz_stack(dH)
        out = np.empty_like(sc.M)

        def work(s):
            X = D[s] @ (dT[s] @ _tr(C[s]))
            np.add(X, _tr(X), out=out[s])
            out[s] += dlt * sc.M[s]

        self.chunks.map(work, self.j, out.size)
        return out

    def _max_step(self, sc: _Scaling, dsL, dzL, dsq, dzq) -> float:
        """Largest step keeping both scaled points in their cones."""
        self.factorisations += 2
        steps = self.chunks.map(lambda s: min(sdp_step_stack(sc.lam[s], dsL[s]), sdp_step_stack(sc.lam[s], dzL[s])),
                                self.j, dsL.size)
        return min(min(steps), _soc_step(sc.lq, dsq), _soc_step(sc.lq, dzq))

    # ---- one predictor–corrector iteration -----------------------------------------------------------
    def centre(self, t, p: _Point, deadline: Deadline):
        """One Mehrotra predictor–corrector iteration from ``p``; returns the new point and its step length."""
        deadline.check()
        if self.steps >= self.max_iter:
            raise Stop("max_iter")
        sc = self._scaling(p)
        lam, lq = sc.lam, sc.lq
        schur = self._schur(sc)
        rx = self._residual_x(p)
        gap = float(np.vdot(lam, lam) + lq @ lq)
        mu = gap / self.nu
        # predictor (affine scaling): ds̃ + dz̃ = −λ
        _, _, dsL, dzL, dsq, dzq, parts = self._direction(sc, schur, None, rx, -lam, -lq, affine=True)
        a = min(1.0, self._max_step(sc, dsL, dzL, dsq, dzq))
        diag_sum = np.diagonal(dsL, axis1=1, axis2=2) + np.diagonal(dzL, axis1=1, axis2=2)
        gap_a = (float(np.vdot(dsL, dzL)) * a * a + a * float(np.vdot(lam, diag_sum)) + float(np.vdot(lam, lam))
                 + float((lq + a * dsq) @ (lq + a * dzq)))
        sigma = min(1.0, max(0.0, gap_a / gap)) ** 3
        # corrector: λ∘(ds̃ + dz̃) = σμe − λ∘λ − ds̃_a∘dz̃_a
        tL = self.chunks.matmul(dsL, dzL)
        tL += _tr(tL)
        tL *= -0.5
        idx = np.arange(2 * self.m)
        tL[:, idx, idx] += sigma * mu - lam * lam
        tL /= lam[:, :, None] + lam[:, None, :]
        tL *= 2.0
        Rq = -_soc_prod(lq, lq) - _soc_prod(dsq, dzq)
        Rq[0] += sigma * mu
        tq = _soc_div(lq, Rq)
        dH, dlt, dsL, dzL, dsq, dzq, _ = self._direction(sc, schur, parts, rx, tL, tq)
        a = min(1.0, self.eta * self._max_step(sc, dsL, dzL, dsq, dzq))
        dZ = self.chunks.matmul(self.chunks.matmul(_tr(sc.Rinv), dzL), sc.Rinv)
        dz = _soc_winv(sc.beta, sc.v, dzq)
        for _ in range(30):  # rounding at the boundary: back off until every block factorises
            Z = p.Z + a * dZ
            Z += _tr(Z)
            Z *= 0.5
            H, d = p.H + a * dH, p.d + a * dlt
            ok = self._feasible(H, d, Z)
            if ok is not None:
                break
            a *= 0.5
        else:
            raise Stop("failed")
        Lz, T, TtT, r = ok
        new = _Point(H, d, T, TtT, r, Z, p.z0 + a * dz[0], p.z1 + a * self._mat(dz), Lz)
        self.steps += 1
        self.last_gap = gap
        if not (np.isfinite(a) and np.all(np.isfinite(new.H)) and np.isfinite(new.d)):
            raise Stop("failed")
        self.small_steps = self.small_steps + 1 if a < 1e-8 else 0
        return new, a

    # ---- the rest of run_barrier's contract ----------------------------------------------------------
    def upper(self, p: _Point) -> float:
        return _max_norm(p.TtT, self.chunks)

    def impulses(self, p: _Point) -> np.ndarray:
        return p.H.copy()

    def dual(self, t, p: _Point, step):
        """``V = −z₁``, ``W_k = −2Z_k,₂₁`` (module docstring) for :meth:`ColumnForm.lower_bound`."""
        m = self.m
        return -p.z1.copy(), -2.0 * p.Z[:, m:, :m]

    def start(self, B0) -> _Point:
        """The barrier method's ridge start (module docstring) with a strictly feasible dual point."""
        svd = operator_svd(self.Tu, split=lambda work: self.chunks.map(work, self.j, self.Tu.size))
        H = self._cold_impulses(svd, B0)
        T, TtT = self._gram(H)
        up = _max_norm(TtT, self.chunks)
        d = 1.2 * up + 1e-3 * (1.0 + up)
        Z = np.broadcast_to(np.eye(2 * self.m) / self.N, (self.j, 2 * self.m, 2 * self.m)).copy()
        # ⟨s_Q, z_Q⟩ = ρ z₀ = the LMI blocks' complementarity per degree, d/N
        return _Point(H, d, T, TtT, self._resid(H), Z, d / (self.N * self.f.rho), np.zeros((self.m, self.j)))

    def run(self, p: _Point) -> dict:
        deadline = Deadline(self.time_limit)
        return run_barrier(self, self.f, p, np.inf, deadline, self.upper(p))


def solve_columns_pd(form: ColumnForm, B0: np.ndarray, *, tol=1e-6, time_limit=None, progress=True,
                     workers: int | None = 1) -> dict:
    """Run the primal–dual method on the column form ``form`` (program (C) of (7.5)).

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
        tqdm bar for solves longer than about 2 s.
    workers : int or None
        Threads over the column stack; ``None``: ``os.cpu_count()``.  BLAS is held to one thread per worker, as in
        :func:`~unfalsify.solvers.column_barrier.solve_columns_barrier`.

    Returns
    -------
    dict
        The bracket of :func:`~unfalsify.solvers.barrier.run_barrier` (scaled units: ``lower``, ``upper``, ``H``,
        ``V``, ``W``, ``status``, ``newton`` and ``outer`` both counting predictor–corrector iterations, ``time``),
        plus ``factorisations`` (batched Cholesky stacks, eigendecompositions and step-length stacks) and ``cg``.
        Ctrl-C returns the bracket so far with status ``interrupted``.
    """
    return _on_threads(workers, lambda chunks: _solve(form, B0, tol, time_limit, progress, chunks))


def _solve(form, B0, tol, time_limit, progress, chunks: _Chunks) -> dict:
    solver = _ColumnPrimalDual(form, tol=tol, time_limit=time_limit, progress=progress, chunks=chunks)
    clock = Deadline()
    try:
        p = solver.start(B0)
    except KeyboardInterrupt:
        return dict(status="interrupted", lower=0.0, upper=float("nan"), H=np.zeros((form.m, form.j)), V=None,
                    W=None, outer=0, newton=0, cg=0, factorisations=0, time=clock.elapsed())
    out = solver.run(p)
    out.pop("last", None)
    out.update(factorisations=solver.factorisations, cg=solver.cg_iters)
    return out


def solve(problem, *, tol: float = 1e-6, time_limit=None, progress: bool = True,
          workers: int | None = 1) -> SolverOutput:
    """Registered solver ``"column_pd"``: (7.5) of an :class:`unfalsify.SubspaceProblem` (one channel, L optimised
    or fixed), certified to the relative gap ``tol`` by the primal–dual method of the module docstring; the answer
    in data units.

    Examples
    --------
    >>> import numpy as np
    >>> import unfalsify as uf
    >>> from unfalsify import solvers
    >>> rng = np.random.default_rng(0)
    >>> u = rng.choice([-1.0, 1.0], 60)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:60] + 0.05 * rng.standard_normal(60)
    >>> P = uf.SubspaceProblem.from_data(u, y, 4, 0.02)
    >>> pd = solvers.run("column_pd", P, tol=1e-6, progress=False)
    >>> barrier = solvers.run("column_barrier", P, tol=1e-6, progress=False)
    >>> pd.status.value, bool(abs(pd.delta - barrier.delta) <= 2e-6 * barrier.delta)
    ('optimal', True)
    """
    f = problem.column_form(scaled=True)
    clock = Deadline()
    if zero_answer(f):
        return unscaled(problem, np.zeros(f.U.shape), 0.0, "optimal", clock.elapsed())
    out = solve_columns_pd(f, f.noise_floor()[1], tol=float(tol), time_limit=time_limit, progress=progress,
                           workers=workers)
    return unscaled(problem, out["H"], out["upper"], out["status"], clock.elapsed(), V=out["V"], W=out["W"],
                    stats={k: out[k] for k in ("newton", "outer", "factorisations", "cg")})
