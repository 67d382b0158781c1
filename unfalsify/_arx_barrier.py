"""Cholesky-based barrier solver for the ARX program (7.4) in column form (C) (j = 1).

The same barrier method as :mod:`unfalsify._structured` (Boyd & Vandenberghe §11.3) on the n + 1
variables (h, δ) of (C) with ``𝓛 = range Φ`` projected out,

    f_t(h, δ) = t δ − log det F(h, δ) − log(ρ² − ‖P(B − T(u)h)‖²),   F = [δI T(h)ᵀ; T(h) δI],

but every quantity is read off one Cholesky factorisation instead of an SVD of T(h):

* ``det F = det(δ²I − TᵀT)`` (Schur complement), so with ``K = δ²I − T(h)ᵀT(h) = L Lᵀ``,
  ``log det F = 2 Σ log L_ii`` and F ≻ 0 ⟺ (δ > 0 and the Cholesky factorisation succeeds);
* ``F⁻¹ = [S11 S12; S21 S22]`` with ``S11 = δK⁻¹``, ``S21 = −T K⁻¹``, ``S22 = (I + T K⁻¹ Tᵀ)/δ``;
* the gradient ``∂/∂h_a = 2 T*(T K⁻¹)_a``, ``∂/∂δ = t − 2δ tr K⁻¹``; the Hessian's h–h block is the
  2-D-FFT correlation of :func:`unfalsify._structured_columns._corr_hessian`, its δ–δ entry
  ``2(δ²‖K⁻¹‖²_F + ‖T K⁻¹‖²_F)`` and its h–δ column ``−4δ T*(T K⁻²)``.

A trial point of the line search costs one Cholesky (n³/3 flops) instead of an SVD (~20 n³), so
no step-to-the-boundary computation is needed: the line search starts from the full Newton step,
backtracks (Armijo) where f_t does not decrease or the Cholesky factorisation fails, and, when the
full step is accepted, tries 2, 4, … times it while f_t keeps decreasing.  The predictor (tangent
of the central path to the next t) backtracks on feasibility.  t grows by μ = 3 per outer
iteration above n = 200 (8 below): with μ = 8 a re-centring near the optimum zig-zags for 30–80
Newton steps (most singular values of T(h) cluster at δ and the Newton step runs into the
boundary); measured at n = 400: 47 Newton steps with μ = 3, 45 with μ = 2, 86 with μ = 8 (the SVD
solver of :mod:`unfalsify._structured`: 102).

The dual point read off each centred iterate (the Newton-linearised ``G = (S − S ΔF S)/t`` and noise
multiplier, as in :mod:`unfalsify._structured`) is bounded by :meth:`ColumnForm.lower_bound`; the upper
bound ``‖T(h)‖₂`` is recomputed by :func:`unfalsify.arx.certified_norm`.  The stopping rule uses
these certified bounds only.  Memory O(n²).
"""
from __future__ import annotations

import time

import numpy as np
import scipy.linalg

from ._columns import (_SOLVE_ERRORS, ColumnForm, _gap_closed, _ridge_lambda, _Stop, _stop_status,
                       _tick_progress)
from ._structured import _cho
from ._structured_columns import _corr_hessian
from ._toeplitz import _toeplitz_gram, toeplitz_matrix

__all__: list[str] = []


def _norm(h) -> float:
    from .arx import certified_norm  # the certificate's own route (dense SVD up to n = 4000)

    return certified_norm(h)


def _clock() -> float:
    """Wall clock of the time limit (a function, so that tests can substitute a deterministic one)."""
    return time.perf_counter()



class _State:
    """Everything the method needs at one strictly feasible point (h, δ): T(h), the Cholesky factor
    of ``K = δ²I − TᵀT``, the projected residual and the barrier value (``phi`` = inf if infeasible)."""

    __slots__ = ("h", "d", "T", "L", "logdet", "r", "psi", "ok")

    def __init__(self, h, d, form: ColumnForm):
        self.h, self.d = h, float(d)
        self.r = form.project(form.B[:, 0] - form.apply(h[:, None])[:, 0])
        self.psi = form.rho**2 - float(self.r @ self.r)
        self.T = toeplitz_matrix(h)
        self.ok = False
        self.L = None
        self.logdet = -np.inf
        if not (self.d > 0.0 and self.psi > 0.0):
            return
        K = _toeplitz_gram(h)
        K *= -1.0
        K[np.diag_indices_from(K)] += self.d * self.d
        try:
            self.L = scipy.linalg.cholesky(K, lower=True, overwrite_a=True, check_finite=False)
        except np.linalg.LinAlgError:
            return
        diag = np.diag(self.L)
        if not np.all(diag > 0):
            return
        self.logdet = 2.0 * float(np.sum(np.log(diag)))
        self.ok = True

    def phi(self, t: float) -> float:
        """``f_t`` at this point (inf outside the domain)."""
        if not self.ok:
            return np.inf
        return t * self.d - self.logdet - np.log(self.psi)


def _adjoint(A: np.ndarray, lower_d: np.ndarray, lower_mask: np.ndarray, n: int) -> np.ndarray:
    """``T*(A)_d = Σ_i A[i+d, i]`` (sum of the d-th subdiagonal) by one bincount."""
    return np.bincount(lower_d, weights=A[lower_mask], minlength=n)


class _ArxBarrier:
    """The barrier path-following loop (see the module docstring)."""

    def __init__(self, form: ColumnForm, *, tol, time_limit, progress, mu=3.0, center_tol=0.1, max_newton=3000):
        if form.j != 1:
            raise ValueError("the Cholesky barrier solver is for the ARX program (j = 1)")
        self.f = form
        self.n = form.m
        self.tol, self.time_limit, self.progress = tol, time_limit, progress
        self.mu, self.center_tol, self.max_newton = mu, center_tol, max_newton
        Tu = toeplitz_matrix(form.U[:, 0])
        PM = form.project(Tu)
        self.MtPM = PM.T @ PM
        self.nbar = 2 * self.n + 1
        ar = np.arange(self.n)
        dmat = np.subtract.outer(ar, ar)
        self._mask = dmat >= 0
        self._dlow = dmat[self._mask]

    def _Tstar(self, A):
        return _adjoint(A, self._dlow, self._mask, self.n)

    # ---- one Newton step ---------------------------------------------------------------------
    def _inverse_blocks(self, s: _State):
        """``K⁻¹`` and ``A = T K⁻¹`` (so ``S11 = δK⁻¹``, ``S21 = −A``, ``S22 = (I + A Tᵀ)/δ``)."""
        Kinv = scipy.linalg.cho_solve((s.L, True), np.eye(self.n), check_finite=False)
        A = s.T @ Kinv
        return Kinv, A

    def newton(self, t: float, s: _State):
        """Newton direction ``(dh, dδ)``, decrement λ², the central-path tangent and the blocks of F⁻¹."""
        n, d = self.n, s.d
        Kinv, A = self._inverse_blocks(s)
        S11 = d * Kinv
        S22 = A @ s.T.T
        S22[np.diag_indices_from(S22)] += 1.0
        S22 /= d
        g_noise = self.f.apply_T(s.r[:, None])[:, 0]
        psi = s.psi
        grad_h = 2.0 * self._Tstar(A) - 2.0 * g_noise / psi
        grad_d = t - 2.0 * d * float(np.trace(Kinv))
        c = -4.0 * d * self._Tstar(A @ Kinv)
        dd = 2.0 * (d * d * float(np.sum(Kinv * Kinv)) + float(np.sum(A * A)))
        HF = _corr_hessian(S11[None], -A[None], S22[None], n)[0]
        Hm = HF + (2.0 / psi) * self.MtPM + (4.0 / psi**2) * np.outer(g_noise, g_noise)
        cf = _cho(Hm)
        sol = scipy.linalg.cho_solve(cf, np.column_stack([grad_h, c]), check_finite=False)
        xg, xc = sol[:, 0], sol[:, 1]
        dd_eff = dd - c @ xc
        dlt = (-grad_d + c @ xg) / dd_eff
        dh = -xg - xc * dlt
        lam2 = -(grad_h @ dh + grad_d * dlt)
        tangent = (xc / dd_eff, -1.0 / dd_eff)  # d(h, δ)/dt on the central path
        return dh, dlt, lam2, tangent, (S11, -A, S22)

    def dual(self, t: float, s: _State, blocks, dh, dlt):
        """Dual point of the Newton-linearised centrality conditions (as in :mod:`unfalsify._structured`)."""
        S11, S21, S22 = blocks
        dT = toeplitz_matrix(dh)
        SdFS21 = dlt * (S21 @ S11 + S22 @ S21) + S21 @ dT.T @ S21 + S22 @ dT @ S11
        W = -2.0 * (S21 - SdFS21) / t
        psi, r = s.psi, s.r
        dr = -self.f.project(self.f.apply(dh[:, None])[:, 0])
        v = (2.0 / t) * (r / psi + dr / psi + 2.0 * r * float(r @ dr) / psi**2)
        return v, W

    # ---- loop --------------------------------------------------------------------------------
    def _check_time(self, t_start):
        if self.time_limit is not None and _clock() - t_start > self.time_limit:
            raise _Stop("time_limit")

    def _centre(self, t, s, t_start, counter):
        """Damped Newton on ``f_t`` from ``s`` until λ² ≤ center_tol; returns the state and last step."""
        while True:
            self._check_time(t_start)
            dh, dlt, lam2, tangent, blocks = self.newton(t, s)
            counter[0] += 1
            if not np.isfinite(lam2):
                raise _Stop("failed")
            if counter[0] > self.max_newton:
                raise _Stop("max_iter")
            if lam2 <= self.center_tol:
                return s, (dh, dlt, tangent, blocks)
            phi0 = s.phi(t)
            a = 1.0  # Armijo backtracking; a trial outside the domain fails its Cholesky factorisation
            for _ls in range(40):
                sn = _State(s.h + a * dh, s.d + a * dlt, self.f)
                if sn.phi(t) <= phi0 - 0.25 * a * lam2 + 1e-13 * abs(phi0):
                    break
                a *= 0.5
            else:
                raise _Stop("failed")
            if a == 1.0:  # the full step was accepted: try longer ones while f_t decreases
                phin = sn.phi(t)
                for _ex in range(6):
                    a *= 2.0
                    sx = _State(s.h + a * dh, s.d + a * dlt, self.f)
                    if not sx.phi(t) < phin:
                        break
                    sn, phin = sx, sx.phi(t)
            s = sn

    def _predict(self, t, t_new, s, tangent):
        """Step along the central-path tangent towards ``t_new``, backtracking on feasibility."""
        th, tdl = tangent
        ph, pdl = (t_new - t) * th, (t_new - t) * tdl
        a = 1.0
        for _ in range(8):
            sn = _State(s.h + a * ph, s.d + a * pdl, self.f)
            if np.isfinite(sn.phi(t_new)):
                return sn
            a *= 0.5
        return s

    def run(self, h0):
        f = self.f
        t_start = _clock()
        up0 = _norm(h0)
        d0 = 1.2 * up0 + 1e-3 * (1.0 + up0)
        s = _State(h0, d0, f)
        t = self.nbar / d0
        best = dict(lower=0.0, upper=up0, H=h0[:, None].copy(), V=None, W=None, newton=0, outer=0)
        status, bar, counter = "optimal", None, [0]
        try:
            if not s.ok:
                raise _Stop("failed")
            while True:
                s, (dh, dlt, tangent, blocks) = self._centre(t, s, t_start, counter)
                upper = _norm(s.h)
                if upper < best["upper"]:
                    best.update(upper=upper, H=s.h[:, None].copy())
                v, W = self.dual(t, s, blocks, dh, dlt)
                lower = f.lower_bound(v, W)
                if lower > best["lower"]:
                    best.update(lower=lower, V=v[:, None], W=W[None])
                best.update(newton=counter[0], outer=best["outer"] + 1)
                bar = self._progress(bar, t_start, best)
                if _gap_closed(best, self.tol):
                    break
                t_new = t * self.mu
                s = self._predict(t, t_new, s, tangent)
                t = t_new
        except (_Stop, KeyboardInterrupt, *_SOLVE_ERRORS) as exc:
            status = _stop_status(exc, best)
        finally:
            if bar is not None:
                bar.close()
        best.update(status=status, newton=counter[0], time=_clock() - t_start)
        return best

    def _progress(self, bar, t_start, best):
        return _tick_progress(bar, self.progress, _clock() - t_start,
                              f"structured ARX unfalsification (n={self.n})", best["newton"], best)


def solve_arx_barrier(form: ColumnForm, h0: np.ndarray, *, tol=1e-7, time_limit=None, progress=True, mu=None) -> dict:
    """Run the Cholesky barrier method on the ARX column form ``form`` (j = 1) from impulses ``h0``.

    Parameters
    ----------
    form : ColumnForm
        Program (C) with j = 1 (see :mod:`unfalsify._columns`).
    h0 : ndarray, shape (n,)
        Strictly feasible start: ``‖P(B − T(u)h0)‖ < ρ``.
    tol : float
        Stop when the certified relative gap ``(upper − lower)/upper ≤ tol``.
    time_limit : float, optional
        Wall-clock limit in seconds (status ``"time_limit"``).
    progress : bool
        tqdm bar for solves longer than ~2 s.
    mu : float, optional
        Factor of t per outer iteration; default 8 for n ≤ 200, 3 above (measured: n = 80, tol 1e-7:
        33 Newton steps with μ = 8, 56 with μ = 3; n = 400, tol 1e-4: 86 with μ = 8, 47 with μ = 3).

    Returns
    -------
    dict
        ``status`` (``optimal``, ``time_limit``, ``interrupted``, ``max_iter``, ``failed``), the best
        certified ``upper`` and its impulses ``H`` (n × 1), the best ``lower`` and its dual point ``V``
        (n × 1), ``W`` (1 × n × n), ``newton``, ``outer``, ``time``.  A KeyboardInterrupt inside the loop
        ends it with status ``"interrupted"`` and the bracket found so far.
    """
    if mu is None:
        mu = 8.0 if form.m <= 200 else 3.0
    solver = _ArxBarrier(form, tol=tol, time_limit=time_limit, progress=progress, mu=float(mu))
    return solver.run(np.asarray(h0, float).reshape(-1))


def ridge_start(form: ColumnForm, B0: np.ndarray, frac: float = 0.9) -> np.ndarray:
    """Ridge impulses ``h = argmin ‖B0 − P T(u)h‖² + λ‖h‖²`` with ``‖B0 − P T(u)h‖ = frac·ρ`` (λ by bisection).

    ``B0 = P B`` (B with its component in 𝓛 removed, P the projector onto 𝓛^⊥); the result is strictly
    feasible for (C).  Fitting through P matters when 𝓛 holds whole rows (free equation errors): an
    unprojected fit would force ``(T(u)h)`` to vanish on them and start from an enormous ‖T(h)‖ (measured:
    ‖T(h0)‖ ≈ 1e13 and a failed solve where the optimum is 0.4).
    """
    Tu = toeplitz_matrix(form.U[:, 0])
    if form.Ql is not None:
        Tu = Tu - form.Ql @ (form.Ql.T @ Tu)
    Us, sv, Vt = np.linalg.svd(Tu)
    beta = Us.T @ B0[:, 0]
    target = (frac * form.rho) ** 2
    lam = _ridge_lambda(sv, beta, target)
    return Vt.T @ (sv / (sv * sv + lam) * beta)
