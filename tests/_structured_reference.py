"""The SVD barrier solver of the column form (C) of (7.4)/(7.5): the tests' independent reference.

It was the first ``backend="structured"``; the Cholesky solvers of :mod:`unfalsify.solvers` replaced it,
and it stays here as a second route to the same optimum (``tests/test_unfalsify_arx_large.py``).

Barrier method (Boyd & Vandenberghe §11.3) on the n + 1 (resp. ij + 1) variables (h, δ), the
model parameters eliminated by projection:

    f_t(h, δ) = t δ − Σ_k log det F_k(h_k, δ) − log(ρ² − ‖P(B − H̃)‖²_F),
    F_k = [δI T(h_k)ᵀ; T(h_k) δI],

P the projection onto 𝓛^⊥ (see :mod:`unfalsify.solvers.columns`).  Structure used (the references are
Vandenberghe, Balakrishnan, Wallin & Hansson on structured/KYP LMIs and Genin, Hachez, Nesterov &
Van Dooren on Toeplitz structure):

* ``T(h) = U diag(s) Vᵀ`` gives ``F⁻¹`` in closed form, ``S11 = V D₁ Vᵀ``, ``S22 = U D₁ Uᵀ``,
  ``S21 = −U D₂ Vᵀ`` with ``D₁ = δ/(δ² − s²)``, ``D₂ = s/(δ² − s²)``, and ``log det F = Σ log(δ² − s²)``;
* the Hessian ``tr(F⁻¹F_a F⁻¹F_b)``, F_a the shift matrices, is
  ``2 tr(S12 Z_a S12 Z_b) + 2 tr(S11 Z_aᵀ S22 Z_b)``: two 2-D cross-correlations, all m² entries by
  one 2-D FFT each, O(m² log m) after the O(m³) SVD (instead of O(m⁴) for a generic solver);
* the noise term's Hessian ``(2/ψ) BᵀPB`` is fixed (ARX: one dense n × n matrix; subspace: a block
  diagonal plus a low-rank Kronecker correction, handled by Woodbury).

On the central path ``G = F⁻¹/t`` and ``v = 2 r/(ψ t)`` is dual feasible; the dual point read off
every centred iterate (``W_k = 2 U D₂ Vᵀ/t``, ``V = 2 r/(ψ t)``) is repaired and bounded by
:meth:`ColumnForm.lower_bound`, so the gap used by the stopping rule is a certified one.  Memory
O(j m²).
"""
from __future__ import annotations

import time

import numpy as np
import scipy.linalg

from unfalsify.solvers.barrier import SOLVE_ERRORS, Stop, cholesky_retry, gap_closed, stop_status, tick_progress
from unfalsify.solvers.columns import ColumnForm
from unfalsify.solvers.toeplitz import adjoint, ridge_lambda, toeplitz_stack

__all__ = ["solve_structured"]


def _corr_hessian(S11, S21, S22, m):
    """``2 tr(S12 Z_a S12 Z_b) + 2 tr(S11 Z_aᵀ S22 Z_b)`` for all (a, b), by 2-D FFT (batched)."""
    N = 2 * m
    s = (N, N)
    F21 = np.fft.rfft2(S21, s)
    F12 = np.fft.rfft2(np.swapaxes(S21, -1, -2), s)
    R1 = np.fft.irfft2(F12 * np.conj(F21), s)  # R_{S12,S21}(p, q)
    R2 = np.fft.irfft2(np.fft.rfft2(S11, s) * np.conj(np.fft.rfft2(S22, s)), s)  # R_{S11,S22}
    neg = (-np.arange(m)) % N
    pos = np.arange(m)
    # H[a, b] = 2 R1(−b, a) + 2 R2(−b, −a)
    H1 = R1[..., neg, :][..., :, pos]
    H2 = R2[..., neg, :][..., :, neg]
    return 2.0 * np.swapaxes(H1 + H2, -1, -2)


class _Solver:
    def __init__(self, form: ColumnForm, *, tol, time_limit, progress, max_newton=5000):
        self.f = form
        self.m, self.j = form.m, form.j
        self.tol = tol
        self.time_limit = time_limit
        self.progress = progress
        self.max_newton = max_newton
        self.center_tol = 0.1
        self.mu = 4.0
        f = form
        m, j = self.m, self.j
        Tu = toeplitz_stack(f.U)  # (j, m, m)
        self.Tu = Tu
        if j == 1:
            PM = f.project(Tu[0])
            self.MtPM = PM.T @ PM
        else:
            self.MtM = np.einsum("kia,kib->kab", Tu, Tu)
        self.Qr = f.Qr if (f.Qr is not None and f.Qr.shape[1]) else None
        self.nbar = 2 * m * j + 1

    # ---- evaluation --------------------------------------------------------------------------
    def _svd(self, H):
        T = toeplitz_stack(H)
        Uk, s, Vt = np.linalg.svd(T)
        return Uk, s, Vt

    def _resid(self, H):
        return self.f.project(self.f.B - self.f.apply(H))

    def _phi(self, t, H, d, s, r):
        psi = self.f.rho**2 - float(np.sum(r * r))
        if not (psi > 0 and d > s.max()):
            return np.inf
        return t * d - float(np.sum(np.log(d * d - s * s))) - np.log(psi)

    # ---- Newton step -------------------------------------------------------------------------
    def _newton(self, t, H, d, svd, r):
        m, j = self.m, self.j
        Uk, s, Vt = svd
        V = np.swapaxes(Vt, -1, -2)
        den = d * d - s * s
        D1, D2 = d / den, s / den
        S11 = (V * D1[:, None, :]) @ Vt
        S22 = (Uk * D1[:, None, :]) @ np.swapaxes(Uk, -1, -2)
        UD2V = (Uk * D2[:, None, :]) @ Vt
        psi = self.f.rho**2 - float(np.sum(r * r))
        g_noise = self.f.apply_T(r)  # Bᵀ r  (m, j)
        grad_h = 2.0 * adjoint(UD2V) - 2.0 * g_noise / psi  # (m, j)
        grad_d = t - 2.0 * float(D1.sum())
        c = -4.0 * adjoint((Uk * (D1 * D2)[:, None, :]) @ Vt)  # (m, j)
        dd = 2.0 * float(np.sum(D1 * D1 + D2 * D2))
        HF = np.empty((j, m, m))
        step = max(1, int(2e7 // (4 * m * m)))
        for k0 in range(0, j, step):
            sl = slice(k0, k0 + step)
            HF[sl] = _corr_hessian(S11[sl], -UD2V[sl], S22[sl], m)
        gv = g_noise.reshape(-1, order="F")
        if j == 1:
            Hm = HF[0] + (2.0 / psi) * self.MtPM + (4.0 / psi**2) * np.outer(gv, gv)
            cf = cholesky_retry(Hm)
            sol = scipy.linalg.cho_solve(cf, np.column_stack([grad_h[:, 0], c[:, 0]]))
            X_g, X_c = sol[:, 0:1], sol[:, 1:2]
        else:
            X_g, X_c = self._woodbury(HF, psi, g_noise, grad_h, c)
        gh = grad_h.reshape(-1, order="F")
        cv = c.reshape(-1, order="F")
        xg = X_g.reshape(-1, order="F")
        xc = X_c.reshape(-1, order="F")
        dd_eff = dd - cv @ xc
        dlt = (-grad_d + cv @ xg) / dd_eff
        dh = -xg - xc * dlt
        lam2 = -(gh @ dh + grad_d * dlt)
        tangent = (X_c.reshape(m, j, order="F") / dd_eff, -1.0 / dd_eff)  # dx/dt on the central path
        return dh.reshape(m, j, order="F"), dlt, lam2, tangent

    def _woodbury(self, HF, psi, g_noise, grad_h, c):
        """Solve ``(K − (2/ψ) Uw Uwᵀ + (4/ψ²) g gᵀ) X = [grad, c]`` with K block diagonal."""
        m, j = self.m, self.j
        K = HF + (2.0 / psi) * self.MtM
        L = np.stack([np.tril(cholesky_retry(Kk)[0]) if cholesky_retry(Kk)[1] else np.triu(cholesky_retry(Kk)[0]).T for Kk in K])

        def Kinv(X):  # X (m, j, p) -> (m, j, p)
            Y = np.linalg.solve(L, np.moveaxis(X, 1, 0))  # (j, m, p)
            Y = np.linalg.solve(np.swapaxes(L, -1, -2), Y)
            return np.moveaxis(Y, 0, 1)

        rhs = np.stack([grad_h, c], axis=-1)  # (m, j, 2)
        cols = [g_noise[..., None]]
        coef = [4.0 / psi**2]
        if self.Qr is not None:
            Q = self.Qr  # (j, r)
            rr = Q.shape[1]
            # Uw[:, (a, row)] column k = Q[k, a] * T(u_k)ᵀ e_row  ->  (m, j, r*m)
            TuT = np.swapaxes(self.Tu, -1, -2)  # (j, m, m): TuT[k][:, row] = T(u_k)ᵀ e_row
            Uw = np.einsum("ka,kir->ikar", Q, TuT).reshape(m, j, rr * m)
            cols.insert(0, Uw)
            coef = [-2.0 / psi] * (rr * m) + coef
        Wl = np.concatenate(cols, axis=-1)  # (m, j, q)
        coef = np.asarray(coef)
        KW = Kinv(Wl)
        Kr = Kinv(rhs)
        Cap = np.diag(1.0 / coef) + np.einsum("ikp,ikq->pq", Wl, KW)
        corr = np.linalg.solve(Cap, np.einsum("ikp,ikq->pq", Wl, Kr))
        X = Kr - np.einsum("ikp,pq->ikq", KW, corr)
        return X[..., 0], X[..., 1]

    def _dual(self, t, d, svd, r, dh, dlt):
        """Dual point of the Newton-linearised centrality conditions (exact on the central path).

        ``G = (S − S ΔF S)/t`` (S = F⁻¹) and the linearised noise multiplier; the Newton equations make
        them satisfy ``T*(W) = T(u)ᵀ v`` to first order, so the repair in the bound is small even
        off the path.  Neither needs to be PSD: the bound uses ``‖W‖_*``.
        """
        Uk, s, Vt = svd
        V = np.swapaxes(Vt, -1, -2)
        Ut = np.swapaxes(Uk, -1, -2)
        den = d * d - s * s
        D1, D2 = d / den, s / den
        S11 = (V * D1[:, None, :]) @ Vt
        S22 = (Uk * D1[:, None, :]) @ Ut
        S21 = -(Uk * D2[:, None, :]) @ Vt
        dT = toeplitz_stack(dh)
        dTt = np.swapaxes(dT, -1, -2)
        SdFS21 = dlt * (S21 @ S11 + S22 @ S21) + S21 @ dTt @ S21 + S22 @ dT @ S11
        W = -2.0 * (S21 - SdFS21) / t
        psi = self.f.rho**2 - float(np.sum(r * r))
        dr = -self.f.project(self.f.apply(dh))
        v = (2.0 / t) * (r / psi + dr / psi + 2.0 * r * float(np.sum(r * dr)) / psi**2)
        return v, W

    def _max_step(self, H, d, dh, dlt, r, svd):
        """min(1, 0.95 × the exact step to the boundary of the noise ball and of every F_k ⪰ 0)."""
        a = 1.0
        # F ⪰ 0: with T(h) = U S Vᵀ, F = Ω diag(δ ± s) Ωᵀ, Ω = [V V; U −U]/√2; the step to the
        # boundary is −1/λ_min(D^{-1/2} Ωᵀ ΔF Ω D^{-1/2})
        Uk, s, Vt = svd
        K = np.swapaxes(Uk, -1, -2) @ toeplitz_stack(dh) @ np.swapaxes(Vt, -1, -2)  # UᵀΔT V
        Ks, Ka = 0.5 * (K + np.swapaxes(K, -1, -2)), 0.5 * (K - np.swapaxes(K, -1, -2))
        M = np.block([[Ks, Ka], [-Ka, -Ks]])
        ev = np.concatenate([d + s, d - s], axis=-1)  # (j, 2m)
        w = 1.0 / np.sqrt(ev)
        M = M * w[:, :, None] * w[:, None, :]
        M[:, np.arange(M.shape[1]), np.arange(M.shape[1])] += dlt / ev
        lmin = float(np.linalg.eigvalsh(M)[:, 0].min())
        if lmin < 0:
            a = min(a, 0.95 / -lmin)
        # noise ball: ‖r − a q‖ ≤ ρ with q = P(H̃(dh))
        q = self.f.project(self.f.apply(dh))
        qq, rq, rr = float(np.sum(q * q)), float(np.sum(r * q)), float(np.sum(r * r))
        if qq > 0:
            disc = rq * rq + qq * (self.f.rho**2 - rr)
            a = min(a, 0.95 * (rq + np.sqrt(max(disc, 0.0))) / qq)
        return a

    # ---- starting point ----------------------------------------------------------------------
    def start(self, B0):
        """Ridge impulses with ``‖B0 − H̃‖_F = 0.7 ρ`` (B0 = B minus a point of 𝓛), and δ0."""
        f = self.f
        Us, s, Vt = np.linalg.svd(self.Tu)
        beta = np.einsum("kia,ik->ka", Us, B0)  # (j, m)
        target = (0.7 * f.rho) ** 2

        lam = ridge_lambda(s, beta, target)
        H = np.einsum("kai,ka->ik", Vt, s / (s * s + lam) * beta)
        return H

    # ---- main loop ---------------------------------------------------------------------------
    def run(self, H):
        f = self.f
        t_start = time.perf_counter()
        svd = self._svd(H)
        d = 1.2 * float(svd[1].max()) + 1e-3 * (1.0 + float(svd[1].max()))
        r = self._resid(H)
        t = self.nbar / d
        best = dict(lower=0.0, upper=float(svd[1].max()), H=H.copy(), V=None, W=None, newton=0, outer=0)
        status = "optimal"
        bar = None
        n_newton = 0
        try:
            while True:
                # centre
                for _ in range(60):
                    if self.time_limit is not None and time.perf_counter() - t_start > self.time_limit:
                        raise Stop("time_limit")
                    dh, dlt, lam2, aux = self._newton(t, H, d, svd, r)
                    n_newton += 1
                    if not np.isfinite(lam2) or n_newton > self.max_newton:
                        raise Stop("failed" if not np.isfinite(lam2) else "max_iter")
                    if lam2 <= self.center_tol:
                        break
                    phi0 = self._phi(t, H, d, svd[1], r)
                    a = self._max_step(H, d, dh, dlt, r, svd)
                    if lam2 > 1.0:  # damped Newton: stay inside the Dikin ellipsoid (no dive into a corner)
                        a = min(a, 1.0 / (1.0 + np.sqrt(lam2)))
                    for _ls in range(60):
                        Hn, dn = H + a * dh, d + a * dlt
                        svdn = self._svd(Hn)
                        rn = self._resid(Hn)
                        phin = self._phi(t, Hn, dn, svdn[1], rn)
                        if phin <= phi0 - 0.25 * a * lam2 + 1e-13 * abs(phi0):
                            break
                        a *= 0.5
                    else:
                        raise Stop("failed")
                    H, d, svd, r = Hn, dn, svdn, rn
                # bounds at the (approximately) centred point
                upper = float(svd[1].max())
                if upper < best["upper"]:
                    best.update(upper=upper, H=H.copy())
                Vd, Wd = self._dual(t, d, svd, r, dh, dlt)
                lower = f.lower_bound(Vd, Wd)
                if lower > best["lower"]:
                    best.update(lower=lower, V=Vd, W=Wd)
                best.update(newton=n_newton, outer=best["outer"] + 1)
                bar = tick_progress(bar, self.progress, time.perf_counter() - t_start,
                                     f"structured unfalsification ({self.m}×{self.j})", n_newton, best)
                if gap_closed(best, self.tol):
                    break
                t_new = t * self.mu
                # predictor: follow the tangent of the central path to t_new (then re-centre)
                th, tdl = aux
                ph, pdl = (t_new - t) * th, (t_new - t) * tdl
                a = self._max_step(H, d, ph, pdl, r, svd) * 0.9
                if a > 0:
                    Hn, dn = H + a * ph, d + a * pdl
                    svdn = self._svd(Hn)
                    rn = self._resid(Hn)
                    if np.isfinite(self._phi(t_new, Hn, dn, svdn[1], rn)):
                        H, d, svd, r = Hn, dn, svdn, rn
                t = t_new
        except (Stop, KeyboardInterrupt, *SOLVE_ERRORS) as exc:
            status = stop_status(exc, best)
        finally:
            if bar is not None:
                bar.close()
        best.update(status=status, newton=n_newton, time=time.perf_counter() - t_start)
        return best


def solve_structured(form: ColumnForm, B0: np.ndarray, *, tol=1e-7, time_limit=None, progress=True) -> dict:
    """Run the barrier method on ``form``; ``B0 = B − X₀`` (X₀ ∈ 𝓛) seeds the starting point.

    Returns a dict: status (``optimal``, ``time_limit``, ``interrupted``, ``max_iter``, ``failed``),
    the best upper bound and its impulses ``H`` (m × j), the best lower bound and its dual point
    ``V`` (m × j), ``W`` (j × m × m), Newton and outer iteration counts, wall time.
    """
    solver = _Solver(form, tol=tol, time_limit=time_limit, progress=progress)
    H0 = solver.start(B0)
    return solver.run(H0)
