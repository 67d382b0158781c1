"""Solver ``"split"``: (7.5) with the predictor fixed, split by columns (tasks on any ``concurrent.futures.Executor``).

With ``[L_w L_u]`` fixed, (7.5) in the column form of :mod:`unfalsify.solvers.columns` is

    min δ   s.t.   ‖T(h_k)‖₂ ≤ δ  (k = 0 … j−1),   Σ_k ‖b_k − T(u_k) h_k‖₂² ≤ ρ²,

``b_k`` the k-th column of ``Y_f − L A``, ``u_k`` that of ``U_f`` and ρ = σ√(ij).  The columns
are coupled only through δ and the shared noise budget ρ², so for a fixed δ column k has the
least noise

    f_k(δ) = min_h ‖b_k − T(u_k) h‖₂²   s.t.   ‖T(h)‖₂ ≤ δ,

each ``f_k`` convex and non-increasing in δ (a partial minimisation of a jointly convex function),
and δ* is the least δ with ``g(δ) = Σ_k f_k(δ) − ρ² ≤ 0``.  The column problems are solved in
blocks as tasks on an executor (local processes, or Dask's ``Client.get_executor()``); the
one-dimensional outer problem runs locally on ``g``, convex and decreasing:

* a chord of g between a point with g ≥ 0 and one with g ≤ 0 crosses zero at an **upper** bound
  of δ* (g lies below its chords);
* a tangent of g crosses zero at a **lower** bound of δ* (g lies above its tangents), and
  ``f_k'(δ) = −tr G_k``, ``G_k`` the multiplier of the LMI ``[δI T(h)ᵀ; T(h) δI] ⪰ 0``;

so tangent steps from the left (Newton, quadratic) and the chord close the bracket; the answer is
the primal point of the last upper end (feasible: noise ≤ ρ, ``max_k ‖T(h_k)‖₂ ≤ δ``).

Each column problem is solved by a small primal barrier method (``−log det`` of the 2i × 2i LMI,
Newton steps, duality gap ``2i/t``), whose central-path multiplier ``G = F⁻¹/t`` gives both
``f_k'`` and the dual point of the certificate: with ``r_k`` the residual and ``G21`` the
lower-left block, stationarity reads ``T*(−G21) = T(u_k)ᵀ r_k``, so ``(V, W) = (R, −G21)`` is a
dual point of the joint problem (all columns share the noise multiplier), and its weak-duality
bound is computed from the data by :meth:`unfalsify.solvers.columns.ColumnForm.lower_bound`, exactly as
for the other backends.  Every column is solved by the same deterministic code whatever the
executor, the number of workers or the block size, so the answer does not depend on them.
"""
from __future__ import annotations

import math
import warnings
from functools import lru_cache

import numpy as np
import scipy.linalg

from synthesis.validation import DataError, check_count, check_level

from ..exceptions import SolverWarning
from .barrier import Deadline
from .base import SolverOutput, SolverStatus
from .columns import ColumnForm
from .toeplitz import adjoint, toeplitz_matrix, toeplitz_norm, toeplitz_stack

__all__ = ["split_solve", "solve", "solve_columns", "solve_column"]

#: Default relative width of the final bracket on δ*.
SPLIT_RTOL = 1e-8
#: Per-column duality gap, relative to the average noise budget per column ρ²/j.
_GAP_REL = 1e-9
_MU = 12.0


@lru_cache(maxsize=16)
def _indices(m: int) -> dict:
    """Flat index arrays for the Hessian gathers (size m)."""
    a = np.arange(m)[:, None, None]
    p = np.arange(m)[None, :, None]
    r = np.arange(m)[None, None, :]
    w = 2 * m  # row length of the zero-padded m × 2m matrices
    return {
        "p_r_plus_a": (p * w + r + a).ravel(),  # X[p, r+a] on [X 0]
        "p_r_minus_a": (p * w + r - a + m).ravel(),  # X[p, r−a] on [0 X]
        "r_p_plus_b": (r * w + p + a).ravel(),  # W[r, p+b] on [W 0] (a plays b)
    }


def _barrier_terms(Y: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Gradient (k, m) and Hessian (k, m, m) of ``−log det F(h)`` at ``Y = F⁻¹`` (a stack (k, 2m, 2m)).

    ``∂/∂h_a = −2 T*(Y21)_a`` and ``∂²/∂h_a∂h_b = tr(Y E_a Y E_b)`` with ``E_a = ∂F/∂h_a``, which by the
    block structure is ``2 Σ_{p,r} (Y12[p, r+a] Y12[r, p+b] + Y11[p, r−a] Y22[r, p+b])``.
    """
    ix = _indices(m)
    k = Y.shape[0]
    grad = -2.0 * adjoint(Y[:, m:, :m]).T
    z = np.zeros((k, m, m))
    P12 = np.concatenate([Y[:, :m, m:], z], axis=2).reshape(k, -1)
    P11 = np.concatenate([z, Y[:, :m, :m]], axis=2).reshape(k, -1)
    P22 = np.concatenate([Y[:, m:, m:], z], axis=2).reshape(k, -1)
    X12 = P12[:, ix["p_r_plus_a"]].reshape(k, m, -1)
    W12 = P12[:, ix["r_p_plus_b"]].reshape(k, m, -1)
    X11 = P11[:, ix["p_r_minus_a"]].reshape(k, m, -1)
    W22 = P22[:, ix["r_p_plus_b"]].reshape(k, m, -1)
    return grad, 2.0 * (X12 @ W12.transpose(0, 2, 1) + X11 @ W22.transpose(0, 2, 1))


def _lmi(Hs: np.ndarray, delta: float) -> np.ndarray:
    """``F(h_k) = [δI T(h_k)ᵀ; T(h_k) δI]`` for the rows of Hs (k, m): a stack (k, 2m, 2m)."""
    k, m = Hs.shape
    T = toeplitz_stack(Hs.T)
    F = np.zeros((k, 2 * m, 2 * m))
    F[:, m:, :m] = T
    F[:, :m, m:] = T.transpose(0, 2, 1)
    idx = np.arange(2 * m)
    F[:, idx, idx] = delta
    return F


def _inverse(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(F_k⁻¹, positive definite?)`` for a stack; entries of the non-definite ones are NaN."""
    try:
        np.linalg.cholesky(F)
        ok = np.ones(F.shape[0], bool)
    except np.linalg.LinAlgError:
        ok = np.linalg.eigvalsh(F)[:, 0] > 0.0
    Y = np.full_like(F, np.nan)
    if ok.any():
        Y[ok] = np.linalg.inv(F[ok])
    return Y, ok


def solve_columns(U, B, delta: float, gap: float) -> dict:
    """``f_k(δ) = min ‖b_k − T(u_k) h‖₂²`` s.t. ``‖T(h)‖₂ ≤ δ`` for every column: one task of the split.

    A primal barrier method on ``t f − log det F(h)``, ``F(h) = [δI T(h)ᵀ; T(h) δI]``, vectorised over
    the columns (each column has its own path parameter t and stops on its own).

    Parameters
    ----------
    U, B : ndarray, shape (m, k)
        Input columns and target columns.
    delta : float
        The bound δ > 0.
    gap : float
        Duality gap ``2m/t`` at which each column stops (absolute, units of ``f``).

    Returns
    -------
    dict
        ``f`` (k,) residual norms² of the returned impulses (each within ``gap`` above f_k(δ)),
        ``df`` (k,) slopes ``f_k'(δ) = −tr G_k`` (from the central-path identity, see the code), ``H`` (m, k) strictly feasible impulses, ``R`` (m, k)
        residuals and ``W`` (k, m, m) the multipliers ``−G21`` of the certificate, ``G = F⁻¹/t``.
    """
    U = np.asarray(U, float)
    B = np.asarray(B, float)
    m, k = U.shape
    A = toeplitz_stack(U)  # T(u_c), (k, m, m)
    At = A.transpose(0, 2, 1)
    AtA2 = 2.0 * At @ A
    Atb2 = 2.0 * np.einsum("kij,jk->ki", At, B)
    nu = 2.0 * m
    f0 = np.sum(B * B, axis=0)
    Hs = np.zeros((k, m))
    t_final = nu / gap
    # start t so that the objective's and the barrier's parts of the Newton system are of one size
    t = np.where(f0 > 0, nu / np.where(f0 > 0, f0, 1.0), t_final).clip(max=t_final)
    done = f0 == 0.0
    steps = np.zeros(k, int)  # Newton steps in the current stage (capped: rounding may stall the last ones)
    Y, _ = _inverse(_lmi(Hs, delta))
    for _ in range(2000):
        act = np.flatnonzero(~done)
        if act.size == 0:
            break
        ta = t[act][:, None]
        gb, Hb = _barrier_terms(Y[act], m)
        grad = ta * (np.einsum("kij,kj->ki", AtA2[act], Hs[act]) - Atb2[act]) + gb
        Hess = ta[:, :, None] * AtA2[act] + Hb
        step = -np.linalg.solve(Hess, grad[:, :, None])[:, :, 0]
        dec = -np.sum(grad * step, axis=1)  # λ², the squared Newton decrement
        final = t[act] >= t_final
        centred = (dec <= np.where(final, 1e-8, 1e-3)) | (steps[act] >= 40)  # loose on the way, tight at the end
        done[act[centred & final]] = True
        up = act[centred & ~final]
        t[up] = np.minimum(t[up] * _MU, t_final)
        steps[up] = 0
        steps[act[~centred]] += 1
        mv = ~centred
        if not mv.any():
            continue
        # line search on the slope (function values lose their digits at large t): the barrier function is
        # convex along the step, so a point with F ≻ 0 and a non-positive slope there lies before the line
        # minimum and decreases it
        cols, step, tc = act[mv], step[mv], ta[mv]
        s = np.ones(cols.size)
        newH, newY = Hs[cols].copy(), Y[cols].copy()
        pending = np.arange(cols.size)
        while pending.size and s[pending[0]] > 1e-12:
            c = cols[pending]
            hn = Hs[c] + s[pending, None] * step[pending]
            Yn, ok = _inverse(_lmi(hn, delta))
            slope = np.sum((tc[pending] * (np.einsum("kij,kj->ki", AtA2[c], hn) - Atb2[c])
                            - 2.0 * adjoint(Yn[:, m:, :m]).T) * step[pending], axis=1)
            acc = ok & ((slope <= 0.0) | (s[pending] < 0.1))
            newH[pending[acc]] = hn[acc]
            newY[pending[acc]] = Yn[acc]
            pending = pending[~acc]
            s[pending] *= 0.5
        done[cols[pending]] = True  # no feasible progress: stop there (still strictly feasible)
        Hs[cols], Y[cols] = newH, newY
    AH = np.einsum("kij,kj->ik", A, Hs)
    R = B - AH
    G = Y / t[:, None, None]
    # f'(δ) = −tr G; on the central path ⟨G, F⟩ = 2m/t and T*(G21) = −T(u)ᵀr, so
    # tr G = (2m/t + 2⟨T(u)h, r⟩)/δ: primal quantities only (tr F⁻¹/t loses its digits at large t)
    df = -(nu / t + 2.0 * np.sum(AH * R, axis=0)) / delta
    return dict(f=np.sum(R * R, axis=0), df=df, H=Hs.T.copy(), R=R, W=-G[:, m:, :m])


def solve_column(u, b, delta: float, gap: float) -> dict:
    """:func:`solve_columns` for one column: ``f``, ``df`` (floats), ``h``, ``r`` (m,) and ``W`` (m, m)."""
    out = solve_columns(np.asarray(u, float)[:, None], np.asarray(b, float)[:, None], delta, gap)
    return dict(f=float(out["f"][0]), df=float(out["df"][0]), h=out["H"][:, 0], r=out["R"][:, 0], W=out["W"][0])


def _map_blocks(executor, U, B, delta, gap, blocks) -> dict:
    if executor is None:
        parts = [solve_columns(U[:, s], B[:, s], delta, gap) for s in blocks]
    else:
        futures = [executor.submit(solve_columns, U[:, s], B[:, s], delta, gap) for s in blocks]
        parts = [f.result() for f in futures]
    return dict(f=np.concatenate([p["f"] for p in parts]), df=np.concatenate([p["df"] for p in parts]),
                H=np.hstack([p["H"] for p in parts]), R=np.hstack([p["R"] for p in parts]),
                W=np.concatenate([p["W"] for p in parts]))


def _exact_fit_norm(u: np.ndarray, b: np.ndarray, p: int) -> float:
    """``‖T(h)‖₂`` of the impulses h that fit b exactly after the p leading zeros of u (b's first p entries no impulse
    reaches: they are noise).  The impulse entries beyond the shorter section can keep the norm at that section's
    (Parrott's theorem: see :meth:`~unfalsify.solvers.columns.ColumnForm.noise_floor`)."""
    if p == u.size:
        return 0.0
    return toeplitz_norm(scipy.linalg.solve_triangular(toeplitz_matrix(u[p:]), b[p:], lower=True))


def split_solve(U, B, rho: float, executor=None, *, rtol: float = SPLIT_RTOL, block_size: int | None = None,
                max_rounds: int = 60) -> dict:
    """δ* of the column form with 𝓛 = {0}: column blocks on ``executor``, the outer problem here.

    Parameters
    ----------
    U, B : ndarray, shape (m, j)
        Input columns and targets (``Y_f − L A``), preferably scaled.  A column whose input starts with p zeros
        leaves its first p targets to the noise.
    rho : float
        Noise budget ρ (2-norm of the whole noise matrix).
    executor : concurrent.futures.Executor, optional
        Where the column blocks run (``submit`` is all that is used: any object with ``submit(fn, *args)``
        returning a future will do); None runs them here.
    rtol : float
        Relative width of the final bracket on δ*.
    block_size : int, optional
        Columns per task (default: j/16 rounded up, at least 1).
    max_rounds : int
        Bound on the outer iterations (one parallel round of column solves each), ≥ 1.

    Returns
    -------
    dict
        ``delta`` (upper end of the final bracket), ``lower`` (its lower end), ``H``, ``V``, ``W``
        (certificate's primal impulses and dual point, in the units of U and B), ``status``
        (``"optimal"`` or ``"max_rounds"``), ``rounds`` and ``time``.

    Examples
    --------
    >>> import numpy as np
    >>> import synthesis as sy
    >>> import unfalsify as uf
    >>> rng = np.random.default_rng(0)
    >>> u = rng.choice([-1.0, 1.0], 40)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:40] + 0.05 * rng.standard_normal(40)
    >>> pred = sy.fit_predictor(u, y, 2)                             # the fixed predictor (i = 2)
    >>> A, Uf, Yf = uf.subspace_data(u[:7], y[:7], 2)                # a window of j = 4 columns
    >>> B = Yf - np.hstack([pred.Lw, pred.Lu]) @ A
    >>> out = split_solve(Uf, B, 0.02 * np.sqrt(B.size), rtol=1e-3)  # ρ = σ√(ij), σ = 0.02
    >>> out["status"], bool(out["lower"] <= out["delta"])
    ('optimal', True)
    >>> sub = uf.subspace_unfalsify(u[:7], y[:7], 2, 0.02, predictor=pred, backend="structured", progress=False)
    >>> bool(abs(sub.delta - out["delta"]) <= 1e-2 * sub.delta)     # the same δ as (7.5) with L fixed
    True
    """
    clock = Deadline()
    try:
        U = np.asarray(U, float)
        B = np.asarray(B, float)
    except (TypeError, ValueError) as exc:
        raise DataError(f"U and B must be numeric matrices of one shape (m, j): {exc}") from None
    if U.ndim != 2 or U.shape != B.shape:
        raise DataError(f"U and B must be matrices of one shape (m, j); got {U.shape} and {B.shape}")
    if not (np.all(np.isfinite(U)) and np.all(np.isfinite(B))):
        raise DataError("U and B contain NaN or infinite values; clean the data (and refit the predictor that "
                        "made B) first")
    rho = check_level(rho, "rho (the noise budget σ√N)")
    if not (isinstance(rtol, float) and 0 < rtol < 1):
        raise DataError(f"rtol must be a float in (0, 1), got {rtol!r}")
    max_rounds = check_count(max_rounds, "max_rounds", 1)
    if block_size is not None:
        block_size = check_count(block_size, "block_size", 1)
    if executor is not None and not callable(getattr(executor, "submit", None)):
        raise DataError(f"executor must be a concurrent.futures.Executor (an object with submit(fn, *args)) or "
                        f"None to solve here, got {executor!r}")
    m, j = U.shape
    rho2 = float(rho) ** 2
    g0 = float(np.sum(B * B)) - rho2
    if g0 <= 0.0:  # zero impulses already fit within the budget
        return dict(delta=0.0, lower=0.0, H=np.zeros((m, j)), V=None, W=None, status="optimal", rounds=0,
                    time=clock.elapsed())
    bs = block_size if block_size is not None else max(1, math.ceil(j / 16))
    blocks = [slice(s, min(s + bs, j)) for s in range(0, j, bs)]
    gap = _GAP_REL * rho2 / j
    # exact fit of every row an impulse reaches (the rest, before a column's first non-zero input, is noise):
    # feasible, an upper end of the bracket
    form = ColumnForm(U, B, rho)
    zeros = form.leading_zeros()
    hi = max(_exact_fit_norm(U[:, k], B[:, k], zeros[k]) for k in range(j))
    floor = form.noise_floor()[0]
    if not floor < rho:
        raise DataError(f"the targets before each column's first non-zero input (no impulse reaches them) need noise "
                        f"of norm {floor:.4g}, not below rho = {rho:.4g}: no δ is feasible")
    ghi = floor**2 - rho2
    lo, glo, dlo = 0.0, g0, None
    dhi, best, best_gap = None, None, None
    stuck = 0  # chord steps in a row that found only upper ends (Illinois: the lower end's weight halves each time)
    rounds, status = 0, "max_rounds"
    while rounds < max_rounds:
        chord = lo + glo * (hi - lo) / (glo - ghi)
        tang = [lo]
        if dlo is not None and dlo < 0:
            tang.append(lo - glo / dlo)
        if dhi is not None and dhi < 0:
            tang.append(hi - ghi / dhi)
        lower = min(max(tang), chord)
        slopes = [abs(d) for d in (dlo, dhi) if d is not None]
        # far from the answer g is only needed to a fraction of the bracket: loose columns, fewer barrier stages
        loose = min(max(gap, 1e-3 * max(slopes) * (chord - lower) / j), 1e-3 * rho2 / j) if slopes else 1e-3 * rho2 / j
        if best is not None and hi - lower <= rtol * hi:
            if best_gap <= gap:
                status = "optimal"
                break
            x, gx_tol = hi, gap  # the answer's primal and dual points at full precision
        elif chord - lower <= rtol * chord:
            x, gx_tol = chord, gap  # confirm the upper end: the candidate answer
        elif lower <= lo * (1 + 1e-12):  # no tangent progress yet
            # a false-position step from the lower end stalls where g is flat above δ* (a noise floor near ρ:
            # measured 60 rounds without a lower end), so the lower end's weight halves after each step that
            # found only an upper end; it stays 1 until then
            w = glo * 0.5**stuck
            x, gx_tol = lo + w * (hi - lo) / (w - ghi), loose
        else:
            x, gx_tol = lower, loose
        ev = _map_blocks(executor, U, B, x, gx_tol, blocks)
        rounds += 1
        gx = float(np.sum(ev["f"])) - rho2
        dx = float(np.sum(ev["df"]))
        if gx <= 0.0:
            hi, ghi, dhi, best, best_gap = x, gx, dx, ev, gx_tol
            stuck += 1
        else:
            lo, glo, dlo = x, gx, dx
            stuck = 0
    if best is None:  # pragma: no cover - max_rounds too small to reach an upper end
        best = _map_blocks(executor, U, B, hi, gap, blocks)
    return dict(delta=float(hi), lower=float(lower), H=best["H"], V=best["R"], W=best["W"], status=status,
                rounds=rounds, time=clock.elapsed())


def solve(problem, *, executor=None, rtol: float = SPLIT_RTOL, block_size: int | None = None) -> SolverOutput:
    """Registered solver ``"split"``: (7.5) of an :class:`unfalsify.SubspaceProblem` with a fixed predictor,
    split by columns over ``executor``; the answer in data units.

    Warns :class:`~unfalsify.SolverWarning` when the rounds ran out before the bracket on δ closed.
    """
    if problem.L_fixed is None:
        raise DataError("the column split of (7.5) needs the predictor fixed: pass predictor=... "
                        "(with L free the columns are coupled through L)")
    su, sy = problem.scale
    f = problem.column_form(scaled=True)
    out = split_solve(f.U, f.B, f.rho, executor, rtol=rtol, block_size=block_size)
    if out["status"] != "optimal":
        warnings.warn(f"column split of (7.5): stopped after {out['rounds']} rounds with the bracket on δ still "
                      "wider than rtol; check the result's certificate", SolverWarning, stacklevel=4)
    H = out["H"] * (sy / su)
    W = None if out["W"] is None else out["W"] * su
    return SolverOutput(delta=out["delta"] * sy / su, impulses=H, params=problem.L_fixed.copy(),
                        status=SolverStatus(out["status"]), solve_time=out["time"], dual_v=out["V"], dual_W=W,
                        stats=dict(rounds=out["rounds"]))
