"""Solver ``"bracket"``: a certified bracket [lower, upper] of the ARX program (7.4) where barriers cannot go.

``arx_unfalsify(..., backend="structured", method="bracket")``.  The search forms no O(n²) matrix:
every operation is a convolution by FFT, O(n log n) (measured: n = 2000 in 75 s under load).  The one
O(n²) object is the proof of the upper bound (below): ``‖T_n(h)‖₂`` of the point found, by a dense SVD up
to n = 4000 and above it by a Cholesky factorisation of one n × n matrix (0.8 GB and about 10 s at
n = 10⁴; the O(n) symbol bound alone was 16 % higher at n = 6000 on the servo data).  The
price is a gap, reported by the certificate: the two sides below are optimal for two *different*
tractable problems that sandwich (7.4), not for (7.4) itself (measured relative gap 0.47–0.52 at
n = 200–2000 on the servo data; at n = 400, where the barrier optimum δ* is known, the upper side
is 13 % above δ* and the lower side 40 % below).

Upper side (a feasible point).  ``‖T_n(h)‖₂ ≤ max_ω |ĥ(e^{jω})|`` (T_n(h) is a block of the
Laurent operator of h), so any h with ``‖P(B − T(u)h)‖ ≤ ρ`` and a small peak of its spectrum has
a small ``‖T_n(h)‖₂``.  We minimise a weighted energy of the spectrum on an N-point grid,
``Σ_k w_k |ĥ_k|²``, subject to the fit (ridge normal equations, preconditioned conjugate gradients
with FFT products, λ by bisection so that the fit is 0.999 ρ) and update the weights by Lawson's rule
``w ← w |ĥ|`` (the iteratively reweighted least-squares route to the minimax spectrum).  The certified
upper bound is ``‖T_n(h)‖₂`` recomputed by :func:`unfalsify.solvers.toeplitz.certified_norm` (Lanczos with FFT
products above n = 4000 proven by a Cholesky of c²I − TᵀT, else the symbol bound), the fit by the certificate.

Lower side (a dual point).  The weak-duality bound of :mod:`unfalsify.solvers.columns` holds for any
(v, W).  Take W = the leading n × n block of the N × N circulant whose first column is
``[c; 0]`` (N ≥ n): its nuclear norm is at most that of the circulant, ``‖fft(c, N)‖₁`` (a
compression does not increase the nuclear norm), and ``T*(W)_d = (n − d) c_d``, so
``c_d = (T(u)ᵀ v)_d/(n − d)`` satisfies the dual equation exactly and

    δ ≥ (⟨v, B⟩ − ρ‖v‖) / ‖fft(c(v), N)‖₁        (v projected orthogonally to range Φ).

This is :class:`unfalsify.solvers.columns.CirculantDual`, evaluated by :meth:`ColumnForm.lower_bound`.  We
maximise the right-hand side over v by L-BFGS on a smoothed ``|·|`` (the bound itself is then
recomputed exactly; the smoothing only steers the search).  The maximum equals the optimum of a
relaxed program (the spectral norm replaced by a windowed-spectrum peak), so it is a true lower bound
but not tight: the gap is that of the two relaxations and is reported, never hidden.
"""
from __future__ import annotations

import numpy as np
import scipy.optimize

from .barrier import Deadline, Stop, pcg
from .base import SolverOutput, unscaled, zero_answer
from .columns import CirculantDual, ColumnForm
from .toeplitz import certified_norm, nfft, spectrum_product

__all__ = ["solve", "solve_bracket", "upper_point", "lower_point", "circulant_dual"]


class _Ops:
    """FFT products of the ARX column form: ``M = T(u)``, ``P`` the projection off range Φ.

    The spectrum of u is computed once per grid N (every product reuses it), the products are
    :func:`~unfalsify.solvers.toeplitz.spectrum_product`.
    """

    def __init__(self, form: ColumnForm, N: int):
        self.f = form
        self.n = form.m
        self.N = N
        self.U = np.fft.rfft(form.U[:, 0], N)
        self.b = form.project(form.B)[:, 0]

    def M(self, h):
        return spectrum_product(self.U, h, self.N, self.n)

    def Mt(self, x):
        return self.M(x[::-1])[::-1]

    def P(self, x):
        return self.f.project(x[:, None])[:, 0]

    def resid(self, h):
        return self.P(self.b - self.M(h))

    def R(self, w, x):
        """``R_w x``: the Toeplitz matrix of the weighted spectrum (n × n) times x."""
        return spectrum_product(w, x, self.N, self.n)


def _ridge_fit(ops: _Ops, w, target, h0, deadline):
    """h minimising ``Σ w_k |ĥ_k|² + ‖P(b − Mh)‖²/λ`` with λ such that ``‖P(b − Mh)‖ = target``."""
    Uabs2 = np.abs(ops.U) ** 2

    def solve(lam, x0):
        def apply(x):
            return ops.Mt(ops.P(ops.M(x))) + lam * ops.R(w, x)

        def precond(x):
            return np.fft.irfft(np.fft.rfft(x, ops.N) / (Uabs2 + lam * w), ops.N)[: ops.n]

        rhs = ops.Mt(ops.b)
        return pcg(apply, precond, rhs, tol=1e-9, maxiter=400, start=(x0.copy(), rhs - apply(x0)), dot=np.dot)[0]

    lo, hi = -12.0, 6.0  # log10 λ: small λ fits the data (residual small), large λ shrinks h
    h = h0
    best = None
    for _ in range(30):
        deadline.check()
        mid = 0.5 * (lo + hi)
        h = solve(10.0**mid, h)
        rn = np.linalg.norm(ops.resid(h))
        if rn <= target:
            lo, best = mid, h.copy()
        else:
            hi = mid
        if hi - lo < 0.01:
            break
    return best


def upper_point(form: ColumnForm, *, iterations=12, deadline: Deadline | None = None, log=None):
    """A feasible h (``‖P(B − T(u)h)‖ ≤ 0.999 ρ``) with a small spectral peak (Lawson IRLS), and its
    certified ``‖T_n(h)‖₂``.

    The iterate kept is the one with the smallest grid peak of ``|ĥ|`` (the proxy the iteration
    minimises); only that one's norm is recomputed.  Returns ``(h, upper, peaks, stopped)`` with
    ``stopped`` None, ``"time_limit"`` or ``"interrupted"`` (a KeyboardInterrupt keeps the best iterate).
    """
    deadline = Deadline() if deadline is None else deadline
    n = form.m
    N = 2 * nfft(n)  # grid ≥ 4n: the grid peak is within a few per cent of the continuous one
    ops = _Ops(form, N)
    w = np.ones(N // 2 + 1)
    h = np.zeros(n)
    best_h, best_peak, peaks, stopped = None, np.inf, [], None
    for it in range(iterations):
        try:
            hn = _ridge_fit(ops, w, 0.999 * form.rho, h, deadline)
        except Stop as exc:
            stopped = str(exc)
            break
        except KeyboardInterrupt:
            stopped = "interrupted"
            break
        if hn is None:
            break
        h = hn
        mag = np.abs(np.fft.rfft(h, N))
        peaks.append(float(mag.max()))
        if log is not None:
            log(f"bracket, upper side: IRLS iteration {it}: spectral peak {peaks[-1]:.6g}")
        if peaks[-1] < best_peak:
            best_h, best_peak = h.copy(), peaks[-1]
        w = w * (mag / mag.mean() + 1e-3)
        w /= w.mean()
    if best_h is None:
        return None, np.inf, peaks, stopped
    return best_h, certified_norm(best_h), peaks, stopped


def _smooth_den(ops: _Ops, v, tail, N, eps):
    """Smoothed ``‖fft([c(v); tail], N)‖₁`` and its gradients in v and tail (c = D⁻¹ T(u)ᵀ P v)."""
    n = ops.n
    Dinv = 1.0 / (n - np.arange(n))
    c = np.concatenate([Dinv * ops.Mt(ops.P(v)), tail])
    z = np.fft.fft(c, N)
    a = np.sqrt(np.abs(z) ** 2 + eps**2)
    val = float(a.sum())
    # d/dc Σ sqrt(|z|²+ε²) = Re(N · ifft(z/a)) (c real)
    gc = np.fft.ifft(z / a).real * N
    gv = ops.P(ops.M(Dinv * gc[:n]))
    return val, gv, gc[n : n + tail.size]


def lower_point(form: ColumnForm, v0, *, N=None, free_tail=True, maxiter=300, deadline: Deadline | None = None):
    """Maximise the circulant-dual bound over v (and the free tail of the column) from ``v0``.

    Returns ``(v, CirculantDual, bound)``, the bound recomputed exactly by :meth:`ColumnForm.lower_bound`.
    """
    n = form.m
    N = n if N is None else int(N)
    deadline = Deadline() if deadline is None else deadline
    ops = _Ops(form, nfft(n))
    b, rho = ops.b, form.rho
    nt = N - n if free_tail else 0

    def neg_log_bound(x, eps):
        v, tail = ops.P(x[:n]), x[n:]
        nv = np.linalg.norm(v)
        num = b @ v - rho * nv
        if not num > 0:
            return 1e3 + nv, np.concatenate([-b, np.zeros(nt)])
        den, gv, gt = _smooth_den(ops, v, tail, N, eps)
        gnum = b - rho * v / nv
        g = np.concatenate([-(ops.P(gnum) / num) + gv / den, gt / den])
        return float(-np.log(num) + np.log(den)), g

    v = ops.P(np.asarray(v0, float))
    x = np.concatenate([v / np.linalg.norm(v), np.zeros(nt)])
    for eps_rel in (1e-2, 1e-3, 1e-4):
        if deadline.expired():
            break
        den0 = _smooth_den(ops, x[:n], x[n:], N, 0.0)[0]
        eps = eps_rel * den0 / N
        res = scipy.optimize.minimize(neg_log_bound, x, jac=True, args=(eps,), method="L-BFGS-B",
                                      options=dict(maxiter=maxiter))
        x = res.x
        x[:n] = ops.P(x[:n])
        x /= np.linalg.norm(x[:n])
    v = x[:n]
    W = circulant_dual(form, v, N, tail=x[n:])
    return v, W, form.lower_bound(v, W)


def circulant_dual(form: ColumnForm, v, N, tail=()) -> CirculantDual:
    """The circulant dual point of v: column ``c_d = (T(u)ᵀ P v)_d/(n − d)`` then ``tail``, grid N."""
    n = form.m
    g = form.apply_T(form.project(np.asarray(v, float).reshape(n, 1)))[:, 0]
    return CirculantDual(column=np.concatenate([g / (n - np.arange(n)), np.asarray(tail, float)]), size=int(N))


def solve_bracket(form: ColumnForm, *, time_limit=None, progress=True) -> dict:
    """The bracket of the module docstring for the ARX column form (j = 1).

    Returns the dict of :func:`unfalsify.solvers.arx_barrier.solve_arx_barrier`: ``status`` (``"bracket"``
    when both sides finished, ``"time_limit"``/``"interrupted"`` otherwise), ``upper``, ``H``, ``lower``,
    ``V``, ``W`` (a :class:`CirculantDual`), ``time``.
    """
    deadline = Deadline(time_limit)
    log = None
    if progress:
        from tqdm import tqdm

        log = tqdm.write
    out = dict(status="bracket", upper=np.inf, H=None, lower=0.0, V=None, W=None)
    h, up, peaks, stopped = upper_point(form, deadline=deadline, log=log)
    if h is None:
        out["status"] = stopped or "failed"
        out["time"] = deadline.elapsed()
        return out
    out.update(upper=up, H=h[:, None], peaks=peaks)
    v0 = _Ops(form, nfft(form.m)).resid(h)  # the KKT direction of the upper point
    out.update(lower=0.0, V=v0[:, None], W=circulant_dual(form, v0, form.m))  # unoptimised, already valid
    out["lower"] = form.lower_bound(v0, out["W"])
    if stopped is None:
        try:
            for N in (form.m, 2 * form.m):
                v, W, lo = lower_point(form, v0, N=N, deadline=deadline)
                if lo > out["lower"]:
                    out.update(lower=lo, V=v[:, None], W=W)
        except KeyboardInterrupt:
            stopped = "interrupted"
    if stopped is None and deadline.expired():
        stopped = "time_limit"
    out["status"] = stopped or "bracket"
    out["time"] = deadline.elapsed()
    return out


def solve(problem, *, time_limit=None, progress: bool = True) -> SolverOutput:
    """Registered solver ``"bracket"``: the FFT-only bracket of (7.4) for an :class:`unfalsify.ArxProblem`
    (status ``"bracket"`` when both sides finished); the answer in data units."""
    f = problem.column_form(scaled=True)
    clock = Deadline()
    if zero_answer(f):  # the least-squares model already explains the data: δ = 0
        return unscaled(problem, np.zeros(problem.n), 0.0, "optimal", clock.elapsed())
    out = solve_bracket(f, time_limit=time_limit, progress=progress)
    h = out["H"][:, 0] if out["H"] is not None else np.full(problem.n, np.nan)
    V = None if out["V"] is None else out["V"][:, 0]
    return unscaled(problem, h, out["upper"], out["status"], clock.elapsed(), V=V, W=out["W"])
