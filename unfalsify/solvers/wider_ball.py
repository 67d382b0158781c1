"""The lower bound of a failed (7.5) solve from the same program with a larger noise ball.

δ*(ρ), the optimum of the column form (C) of :mod:`unfalsify.solvers.columns` as a function of its noise budget ρ,
is non-increasing (a larger ball admits more points) and convex (the constraints are jointly convex in the
impulses, δ and ρ).  The weak-duality bound of :meth:`~unfalsify.solvers.columns.ColumnForm.lower_bound`,

    δ*(ρ) ≥ (⟨V, B⟩ − ρ‖V‖) / d(V, W),

holds for every dual point (V, W) at every ρ, and is larger at ρ than at ρ' > ρ by ``(ρ' − ρ)‖V‖/d``: at the dual
optimum of the program at ρ' it is the tangent of δ*(·) at ρ', extended back to ρ.  The closer ρ' is to ρ, the
tighter the bound (δ* is convex, so tangents at larger ρ' lie lower at ρ).

Where this helps: a noise ball far inside the least-squares residual (ρ ≪ ‖P B‖, e.g. a tiny σ on noise-free
simulated data, whose residual is model error).  There the barrier's noise term ``−w log ψ`` is about
``(‖P B‖/ρ)²`` times as curved as the LMIs; the iterates still reach a good primal point (the upper bound), but the
Newton systems lose the digits the dual point is built from, and the lower bound lags.  Measured on servo data at
(i, j) = (4, 38), L optimised, σ at 1e-8 and 1e-9 of the least-squares rms: 8 of 16 records ended ``failed``; with
the retries all 16 are certified to 1e-4 (δ within 1e-7 of Clarabel's, whose own certificate does not verify
there).  On a fuzzed record (σ = 1.3e-8 of the rms, tol 1e-3) the bracket [0.05178, 0.054135] became
[0.0541335, 0.054135].

:func:`tighten_lower` solves at ρ' = :data:`SMALL_BALL` ‖P B‖ first: well conditioned, and δ* is nearly linear
below it, so its tangent is nearly exact at ρ.  It goes on at ρ'/10, ρ'/100, … (never closer than 10ρ) while those
solves certify, raise the bound and leave the gap open.  The retries solve to a tenth of the caller's tolerance,
since their dual points carry their own gap into the bound.  The certificate the front end builds recomputes the
bound from (V, W) at the user's σ, so nothing here is taken on trust.
"""
from __future__ import annotations

import copy

import numpy as np

from .barrier import Deadline

__all__ = ["SMALL_BALL", "small_ball", "tighten_lower", "with_rho"]

#: The first retry's noise budget, as a fraction of the least-squares residual ‖P B‖; retries are at least
#: :data:`_FACTOR` times the failed solve's ρ, so a failed solve is retried where ρ < SMALL_BALL/_FACTOR × ‖P B‖.
SMALL_BALL = 1e-3
#: The ratio of one retry's ρ' to the next one's, and the least ratio of a retry's ρ' to ρ.
_FACTOR = 10.0
#: The retries' relative gap, as a fraction of the caller's: the tangent's value at ρ is only as good as the retry's
#: dual point (measured: retries to the caller's tol 1e-3 gave bounds 7.6e-4 apart, the nearer balls the lower ones).
_RETRY_TOL = 0.1
#: The statuses whose bracket this improves (a time limit or an interruption is the user's: no extra solve).
_RETRIED = ("failed", "max_iter")


def small_ball(form) -> bool:
    """Whether the noise budget ρ of ``form`` is below ``SMALL_BALL/10`` of the least-squares residual ‖P B‖: where
    :func:`tighten_lower` retries, and where the front end solves a one-channel problem by the primal–dual method
    first."""
    rho = float(form.rho)
    return bool(rho > 0.0 and SMALL_BALL * float(np.linalg.norm(form.project(form.B))) > _FACTOR * rho)


def with_rho(form, rho: float):
    """A shallow copy of a column form with the noise budget ρ (the data arrays shared, not copied)."""
    wider = copy.copy(form)
    wider.rho = float(rho)
    return wider


def tighten_lower(form, out: dict, solve_at, *, tol: float, clock: Deadline | None = None) -> dict:
    """``out`` (a column solver's answer at ``form.rho``, scaled units) with its lower bound raised by the dual points
    of the same program at larger noise balls (module docstring).

    Parameters
    ----------
    form : ColumnForm or BlockColumnForm
        The program ``out`` answers.
    out : dict
        ``status``, ``lower``, ``upper``, ``V``, ``W`` of that solve; returned unchanged unless its status is
        ``failed`` or ``max_iter``, its upper bound finite and ρ below ``SMALL_BALL/10`` × ‖P B‖.
    solve_at : callable
        ``solve_at(wider_form, tol, time_limit) -> dict`` with the same keys: the same solver, no retry of its own.
    tol : float
        The relative gap at which the answer becomes ``optimal``.
    clock : Deadline, optional
        The caller's time limit, started with its solve: the retries get what is left of it.

    Returns
    -------
    dict
        ``out`` with ``lower``, ``V``, ``W`` from the best retry, ``status`` ``"optimal"`` if the gap closed, and
        ``wider``: a list of ``(ρ'/ρ, status, lower bound at ρ)`` per retry (the bound in scaled units).
    """
    if out.get("status") not in _RETRIED or not np.isfinite(out.get("upper", np.nan)):
        return out
    if not small_ball(form):
        return out
    rho = float(form.rho)
    wide = SMALL_BALL * float(np.linalg.norm(form.project(form.B)))
    clock = clock if clock is not None else Deadline()
    out, tried = dict(out), []
    while wide > _FACTOR * rho:
        left = None if clock.limit is None else clock.limit - clock.elapsed()
        if left is not None and left <= 0.0:
            break
        other = solve_at(with_rho(form, wide), _RETRY_TOL * tol, left)
        lower = form.lower_bound(other["V"], other["W"]) if other.get("V") is not None else float("nan")
        tried.append((wide / rho, str(other.get("status")), lower))
        better = np.isfinite(lower) and lower > out["lower"]
        if better:
            out.update(lower=lower, V=other["V"], W=other["W"])
        if out["upper"] - out["lower"] <= tol * out["upper"]:
            out["status"] = "optimal"
            break
        if other.get("status") != "optimal" or not better:  # a smaller ball is harder still, or gave nothing
            break
        wide /= _FACTOR
    out["wider"] = tried
    return out
