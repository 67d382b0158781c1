"""The one barrier skeleton the barrier solvers plug into, and what they share.

Both barrier solvers (:mod:`~unfalsify.solvers.arx_barrier`, :mod:`~unfalsify.solvers.column_barrier`)
follow the central path of ``f_t = t δ − Σ_k log det F_k − w log ψ`` (Boyd & Vandenberghe §11.3) and
read a certified bracket off every centred point.  :func:`run_barrier` is that outer loop, written once:

* centre (the method's Newton steps), then the **upper bound** (the method's norm of its impulses) and
  the **lower bound** (:meth:`ColumnForm.lower_bound` of the method's dual point), each kept when it
  improves;
* **stop on the certified gap** (:func:`gap_closed`), never on the solver's own duality gap;
* the **time limit** (:class:`Deadline`, checked by the method between Newton steps), **Ctrl-C** and
  numerical failures (:data:`SOLVE_ERRORS`) end the loop with the best bracket so far and a status
  (:func:`stop_status`);
* a **progress** bar once the solve has run 2 s (:func:`tick_progress`).

The ``advance`` step shared by the column methods is the mix-in :class:`PathAdvance`; the primal–dual methods
(one predictor–corrector iteration per "centring") share :class:`PrimalDualSteps`.
A method provides ``centre(t, point, deadline) -> (point, step)``, ``upper(point)``,
``impulses(point)``, ``dual(t, point, step) -> (V, W)``, ``advance(t, point, step, bounds, deadline)
-> (t, point)`` and the attributes ``steps`` (Newton steps so far), ``tol``, ``progress`` and ``desc``.
The linearised dual point (:func:`linearised_dual`) and conjugate gradients (:func:`pcg`) are shared the
same way.
"""
from __future__ import annotations

import contextlib
import time

import numpy as np
import scipy.linalg

__all__ = [
    "Stop",
    "SOLVE_ERRORS",
    "Deadline",
    "stop_status",
    "tick_progress",
    "gap_closed",
    "run_barrier",
    "linearised_dual",
    "pcg",
    "delta_step",
    "cholesky_retry",
    "path_predictor",
    "path_steps",
    "best_along",
    "PathAdvance",
    "PrimalDualSteps",
]


def _clock() -> float:
    """Wall clock of every time limit (a function, so that tests can substitute a deterministic one)."""
    return time.perf_counter()


class Stop(Exception):
    """A solver's own stop (time limit, iteration cap, failure); the message is the status."""


#: numerical failures a barrier solver turns into status ``"failed"`` (the best bracket so far is kept);
#: ArithmeticError covers a Python float divided by zero as well as numpy's FloatingPointError
SOLVE_ERRORS = (np.linalg.LinAlgError, ArithmeticError, ValueError, RuntimeError)


class Deadline:
    """The time limit of one solve: ``time_limit`` seconds (None: none) from construction."""

    def __init__(self, time_limit=None):
        self.limit = None if time_limit is None else float(time_limit)
        self.start = _clock()

    def elapsed(self) -> float:
        """Seconds since the solve started."""
        return _clock() - self.start

    def expired(self) -> bool:
        """Whether the limit has passed."""
        return self.limit is not None and self.elapsed() > self.limit

    def check(self) -> None:
        """Raise :class:`Stop` ``("time_limit")`` once the limit has passed."""
        if self.expired():
            raise Stop("time_limit")


def stop_status(exc: BaseException, best: dict) -> str:
    """The status of a solve ended by ``exc`` (:class:`Stop`, Ctrl-C or one of :data:`SOLVE_ERRORS`);
    a numerical failure is also recorded in ``best["error"]``."""
    if isinstance(exc, Stop):
        return str(exc)
    if isinstance(exc, KeyboardInterrupt):
        return "interrupted"
    best["error"] = f"{type(exc).__name__}: {exc}"
    return "failed"


def tick_progress(bar, enabled: bool, elapsed: float, desc: str, newton: int, best: dict):
    """One outer iteration of a barrier solve on its tqdm bar (iteration, Newton steps, bounds).

    The bar is opened only once the solve has run 2 s (``enabled``: the solver's ``progress``);
    returns it (or ``None``) for the next call.
    """
    if bar is None and enabled and elapsed > 2.0:
        from tqdm import tqdm

        bar = tqdm(desc=desc, unit=" outer", leave=False)
    if bar is not None:
        bar.update(1)
        bar.set_postfix(newton=newton, lower=f"{best['lower']:.8g}", upper=f"{best['upper']:.8g}")
    return bar


def gap_closed(best: dict, tol: float) -> bool:
    """The stopping rule of the barrier solvers: certified relative gap ≤ ``tol`` (or δ = 0 reached)."""
    return best["upper"] - best["lower"] <= tol * best["upper"] or best["upper"] <= 1e-14


def run_barrier(method, form, point, t: float, deadline: Deadline, upper: float) -> dict:
    """The outer loop of the module docstring from ``point`` at path parameter ``t``.

    ``upper`` is the certified norm of the starting point's impulses.  Returns the best bracket:
    ``lower``, ``upper``, the impulses ``H`` of the upper side, the dual point ``V``, ``W`` of the lower
    side, ``status``, ``newton``, ``outer`` and ``time``; and the last centred point ``last`` with its path
    parameter ``t`` (None before the first centring).  A method with a ``record(t, point)`` method is shown
    every centred point (what a warm start of a related problem resumes from); one with ``bound_due(t, upper)``
    has its dual point formed and the lower bound evaluated only where that is true (the rest of the loop sees the best bound so far;
    a bound skipped at the last centring is evaluated when the loop ends, whatever ended it); one with
    ``upper_due(t, point)`` has the upper bound treated the same way; one with ``evaluated(t, upper, lower)`` is
    shown the best bracket after every centring at which both bounds were evaluated; one with ``bound_threads()``
    (a context manager) has the bounds evaluated inside it.
    """
    best = dict(lower=0.0, upper=upper, H=method.impulses(point), V=None, W=None, newton=0, outer=0, last=None,
                t=None)
    status, bar, pending, pending_upper = "optimal", None, None, None
    bound_due = getattr(method, "bound_due", lambda t, upper: True)
    upper_due = getattr(method, "upper_due", lambda t, point: True)
    bound_threads = getattr(method, "bound_threads", contextlib.nullcontext)

    def improve_upper(point):
        with bound_threads():
            upper = method.upper(point)
        if upper < best["upper"]:
            best.update(upper=upper, H=method.impulses(point))
        return upper

    def improve_lower(t, point, step):
        with bound_threads():
            V, W = method.dual(t, point, step)
            lower = form.lower_bound(V, W)
        if lower > best["lower"]:
            best.update(lower=lower, V=V, W=W)
        return lower

    try:
        while True:
            point, step = method.centre(t, point, deadline)
            best.update(last=point, t=t)
            if hasattr(method, "record"):
                method.record(t, point)
            if upper_due(t, point):
                upper, pending_upper = improve_upper(point), None
            else:  # far from the tolerance: the norm (an SVD) can wait, as the lower bound below
                upper, pending_upper = best["upper"], point
            if bound_due(t, upper):
                lower, pending = improve_lower(t, point, step), None
            else:  # far from the tolerance: the dual point and its bound (SVDs) wait; formed if the loop ends here
                lower, pending = best["lower"], (t, point, step)
            if pending is None and pending_upper is None and hasattr(method, "evaluated"):
                method.evaluated(t, best["upper"], best["lower"])
            best.update(newton=method.steps, outer=best["outer"] + 1)
            bar = tick_progress(bar, method.progress, deadline.elapsed(), method.desc, method.steps, best)
            if gap_closed(best, method.tol):
                break
            t, point = method.advance(t, point, step, (upper, lower), deadline)
    except (Stop, KeyboardInterrupt, *SOLVE_ERRORS) as exc:
        status = stop_status(exc, best)
    finally:
        if bar is not None:
            bar.close()
    if pending_upper is not None:  # a stop before the bounds were due: the last centring's bounds
        try:
            improve_upper(pending_upper)
        except (KeyboardInterrupt, *SOLVE_ERRORS):
            pass
    if pending is not None:
        try:
            improve_lower(*pending)
        except (KeyboardInterrupt, *SOLVE_ERRORS):
            pass
    if status in ("failed", "max_iter", "time_limit") and gap_closed(best, method.tol):
        status = "optimal"  # the bounds of the last centring, evaluated after the stop, close the certified gap
    best.update(status=status, newton=method.steps, time=deadline.elapsed())
    return best


def linearised_dual(t: float, blocks, dT, dlt: float, r, dr, psi: float, weight: float = 1.0, out=None):
    """Dual point of the Newton-linearised centrality conditions (exact on the central path).

    ``G = (S − S ΔF S)/t`` (``S = F⁻¹`` with blocks ``(S11, S21, S22)``, ``ΔF`` the last Newton step
    ``(dT, dδ)``) gives ``W = −2 G21``; the noise multiplier ``2w r/(ψ t)`` (weight w of the noise
    barrier, ``r`` the projected residual, ``dr`` its change along the step) is linearised the same way.
    The Newton equations make them satisfy ``T*(W) = T(u)ᵀ v`` to first order, so the repair in the
    bound is small even off the path; neither needs to be PSD (the bound uses ``‖W‖_*``).
    Works on one matrix or on a stack ``(j, m, m)``.  ``dT`` is the step's Toeplitz matrix, or a function
    ``dT(X, transpose)`` returning ``dT X`` or ``dTᵀ X`` (such as FFT products, which leave four dense
    products of the six).  W is written into ``out`` if given.
    """
    S11, S21, S22 = blocks
    if callable(dT):
        dT_S11, dTt_S21 = dT(S11, False), dT(S21, True)
    else:
        dT_S11, dTt_S21 = dT @ S11, np.swapaxes(dT, -1, -2) @ S21
    SdFS21 = dlt * (S21 @ S11 + S22 @ S21) + S21 @ dTt_S21 + S22 @ dT_S11
    W = np.subtract(S21, SdFS21, out=out)
    W *= -2.0
    W /= t
    v = (2.0 * weight / t) * (r / psi + dr / psi + 2.0 * r * float(np.sum(r * dr)) / psi**2)
    return v, W


def pcg(A, Minv, B, *, tol: float, maxiter: int, start=None, project=None, dot=None):
    """Preconditioned conjugate gradients on ``A X = B`` (A symmetric positive definite), one or many
    right-hand sides at once; returns ``(X, iterations)``.

    ``start``: ``(X0, B − A X0)`` (default ``(0, B)``); ``project``: applied to every preconditioned
    residual (deflation: keeps the search directions A-orthogonal to a subspace); ``dot``: the inner
    product (default the plain one; for a stack of right-hand sides one value per stack entry).
    Stops when every residual is within ``tol`` of its right-hand side's norm.
    """
    if dot is None:
        def dot(X, Y):
            return float(np.sum(X * Y))
    X, R = (np.zeros_like(B), B.copy()) if start is None else start
    Z = Minv(R)
    P = Z.copy() if project is None else project(Z)
    rz = dot(R, Z)
    bn = np.sqrt(dot(B, B))
    bn = np.where(bn == 0, 1.0, bn)
    iterations = 0
    for _ in range(maxiter):
        if np.all(np.sqrt(dot(R, R)) <= tol * bn):
            break
        AP = A(P)
        pap = dot(P, AP)
        a = np.where(pap > 0, rz / np.where(pap > 0, pap, 1.0), 0.0)
        X += a * P
        R -= a * AP
        iterations += 1
        Z = Minv(R)
        rz_new = dot(R, Z)
        P = (Z if project is None else project(Z)) + np.where(rz > 0, rz_new / np.where(rz > 0, rz, 1.0), 0.0) * P
        rz = rz_new
    return X, iterations


#: The diagonal shifts (relative to the largest diagonal entry) of :func:`cholesky_retry`'s retries.
_RETRY_SHIFTS = (1e-14, 1e-12, 1e-10, 1e-8)


def delta_step(dd: float, grad_d: float, c_xg: float, c_xc: float):
    """The δ part of a Newton step whose h block was solved first, and the δ Schur complement of the Hessian.

    With the Hessian ``[H_hh c; cᵀ dd]``, gradient ``(g_h, g_δ)``, ``x_g = H_hh⁻¹ g_h`` and ``x_c = H_hh⁻¹ c``:
    ``dδ = (−g_δ + cᵀx_g) / (dd − cᵀx_c)``; returns ``(dδ, dd − cᵀx_c)``, or None when that Schur complement is not
    a positive finite number.  The Hessian is positive definite, so its Schur complement is too; a non-positive one
    means the h-block solves have lost their digits.  Measured: a warm path pressed against ``‖T(h_k)‖₂ = δ`` to
    4e-14 relative, where ``dd`` and ``cᵀx_c`` (both 5e25) cancelled to exactly zero.  The callers then report a
    non-finite decrement, which ends the solve with status ``"failed"`` and the best bracket so far.

    Examples
    --------
    >>> delta_step(4.0, 1.0, 0.5, 2.0)
    (-0.25, 2.0)
    >>> delta_step(2.0, 1.0, 0.5, 2.0) is None
    True
    """
    dd_eff = float(dd) - float(c_xc)
    if not (np.isfinite(dd_eff) and dd_eff > 0.0):
        return None
    return (float(c_xg) - float(grad_d)) / dd_eff, dd_eff


def cholesky_retry(Hm, *, overwrite: bool = False):
    """Cholesky factor (``cho_factor``); on a (rounding-level) failure, retry with a growing diagonal shift.

    ``overwrite=True`` factorises Hm (symmetric, C- or Fortran-ordered) in place: no copy of it, which at
    n = 10⁴ is an 800 MB array, whose fresh pages cost up to a second on this machine's virtual memory.  The
    factor then lives in one triangle; the other, which LAPACK does not touch, restores Hm before a retry.
    """
    if overwrite:
        return _cholesky_in_place(Hm)
    try:
        return scipy.linalg.cho_factor(Hm)
    except np.linalg.LinAlgError:
        scale = float(np.max(np.abs(np.diag(Hm))))
        for e in _RETRY_SHIFTS:
            try:
                return scipy.linalg.cho_factor(Hm + e * scale * np.eye(Hm.shape[0]))
            except np.linalg.LinAlgError:
                pass
        raise


def _cholesky_in_place(Hm):
    """:func:`cholesky_retry` in place (``overwrite=True``)."""
    F = Hm if Hm.flags.f_contiguous else Hm.T  # the same symmetric matrix, in LAPACK's order
    diag = np.diag(F).copy()
    scale = float(np.max(np.abs(diag))) if diag.size else 0.0
    for e in (0.0, *_RETRY_SHIFTS):
        if e:  # the failed attempt overwrote the lower triangle: restore it from the upper one, shifted
            for j in range(F.shape[0] - 1):
                F[j + 1:, j] = F[j, j + 1:]
            np.fill_diagonal(F, diag + e * scale)
        c, info = scipy.linalg.lapack.dpotrf(F, lower=1, overwrite_a=1, clean=0)
        if info == 0:
            return c, True
    raise np.linalg.LinAlgError("the Newton system is not positive definite")


def path_predictor(t_new: float, centre, previous=None) -> np.ndarray:
    """The step from a centred point towards the centre at ``t_new``: a cubic in ``s = 1/t``.

    ``centre`` and ``previous`` are ``(t, x, ẋ)`` of the last two centred points (``ẋ = dx/dt``, the path's
    tangent).  Without ``previous`` the step is the tangent's, linear in 1/t:
    ``x(1/t_new) − x ≈ (1 − t/t_new) t ẋ`` (near the optimum ``x(t) − x* = O(1/t)``).  With it, the Hermite cubic
    through both points with both tangents (``dx/ds = −t² ẋ``) is extrapolated to ``1/t_new``: it follows the
    path's curvature, where the tangent alone overshoots (measured for ARX (7.4) at n = 1000: the largest
    feasible fraction of the tangent's step was ½ or ¼ at 10 of 13 path steps).

    Examples
    --------
    A path that is a cubic in 1/t is predicted exactly:

    >>> import numpy as np
    >>> x = lambda t: np.array([1 + 2 / t - 3 / t**3]); dx = lambda t: np.array([-2 / t**2 + 9 / t**4])
    >>> step = path_predictor(8.0, (4.0, x(4.0), dx(4.0)), (2.0, x(2.0), dx(2.0)))
    >>> bool(np.allclose(x(4.0) + step, x(8.0)))
    True
    """
    t0, x0, xdot0 = centre
    q1 = 1.0 / t_new - 1.0 / t0
    d0 = -t0 * t0 * xdot0  # dx/ds at the centre
    if previous is None:
        return d0 * q1
    tp, xp, xdotp = previous
    span = 1.0 / tp - 1.0 / t0  # the previous centre at q = span
    tau = q1 / span
    r1 = xp - x0 - d0 * span  # what the tangent misses at the previous centre
    r2 = (-tp * tp * xdotp - d0) * span  # and the change of dx/ds (times the span)
    return d0 * span * tau + (3.0 * r1 - r2) * tau**2 + (r2 - 2.0 * r1) * tau**3


def path_steps(t_new: float, centre, previous=None) -> list:
    """The steps of :func:`path_predictor` a path step tries: the tangent's, and with ``previous`` the cubic's."""
    steps = [path_predictor(t_new, centre)]
    if previous is not None:
        steps.append(path_predictor(t_new, centre, previous))
    return steps


def best_along(start, steps, along, f):
    """Of ``start`` and ``along(x)`` for each step x (a point backtracked to feasibility; None or ``start`` where
    there is none), the one with the lowest ``f`` (the earlier of equals): the barrier solvers' path step.

    Examples
    --------
    >>> best_along(0.0, [1.0, -2.0, 5.0], lambda x: None if x > 3 else x, lambda q: (q + 1.5) ** 2)
    -2.0
    """
    best, f_best = start, f(start)
    for x in steps:
        q = along(x)
        if q is not None and q is not start:
            f_q = f(q)
            if f_q < f_best:
                best, f_best = q, f_q
    return best


class PathAdvance:
    """The ``advance`` step both column barrier methods share (a mix-in; needs ``stalled``, ``_prev``, ``mu``).

    ``μt`` from the centred point (its first Newton step is the tangent of the central path); a stall (no
    step possible) that brought no better bound is the end of double precision: status ``"failed"``.
    """

    def advance(self, t, p, step, bounds, deadline: Deadline):
        upper, lower = bounds
        if self.stalled and not (upper < self._prev[0] or lower > self._prev[1]):
            raise Stop("failed")
        self._prev, self.stalled = (min(self._prev[0], upper), max(self._prev[1], lower)), 0
        deadline.check()
        return t * self.mu, p


class PrimalDualSteps:
    """What the primal–dual methods (``arx_pd``, ``column_pd``) share of :func:`run_barrier`'s contract (a mix-in;
    needs ``tol``, ``last_gap``, the complementarity sᵀz of the last iteration, and ``small_steps``, the count of
    consecutive steps below 1e-8 that ``centre`` keeps).

    The bounds are evaluated only once the method's own gap could meet ``tol`` (the lower bound costs SVDs); three
    consecutive steps below 1e-8 are the end of double precision: status ``"failed"`` with the best bracket."""

    def bound_due(self, t, upper) -> bool:
        return self.last_gap <= max(10.0 * self.tol, 1e-2) * max(upper, 1e-300)

    def advance(self, t, p, step, bounds, deadline: Deadline):
        if self.small_steps >= 3:  # no progress possible
            raise Stop("failed")
        return t, p
