"""The best certified bracket of several structured answers to one problem.

A certificate's two sides come from two independent points: any primal point inside the noise ball bounds δ from
above by its norm, and any dual point bounds it from below (weak duality).  So the answers of two solvers to the
same problem combine: the primal point with the smaller norm and the dual point with the larger bound, both
recomputed from the data by the problem (``evaluate_primal``, ``evaluate_dual``).  The front end's certificate
recomputes them again.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .base import NOISE_RTOL, SolverOutput, SolverStatus

__all__ = ["best_of"]


def best_of(problem, outputs, *, tol: float) -> SolverOutput:
    """The answer whose upper side is the smallest certified norm among ``outputs`` and whose lower side is the
    largest certified bound; status ``optimal`` if that bracket's relative gap is at most ``tol``, else the status of
    the last output.  ``stats`` are the first output's, with ``combined``: one ``(status, lower, upper)`` per output
    (data units) and which output gave each side.

    ``outputs`` are :class:`SolverOutput` of structured solvers (``bracketed``) for the same ``problem``.
    """
    outputs = list(outputs)
    bound = problem.sigma * np.sqrt(problem.n_noise)
    uppers, lowers = [], []
    for out in outputs:
        up, noise = problem.evaluate_primal(out.impulses, out.params)
        inside = bool(np.isfinite(up) and noise <= bound * (1.0 + NOISE_RTOL))
        uppers.append(up if inside else np.inf)
        lowers.append(problem.evaluate_dual(out.dual_v, out.dual_W) if out.dual_v is not None else 0.0)
    a, b = int(np.argmin(uppers)), int(np.argmax(lowers))
    primal, dual = outputs[a], outputs[b]
    up, lo = uppers[a], lowers[b]
    status = outputs[-1].status  # the last solve's end (e.g. the time limit it ran into)
    if np.isfinite(up) and up - lo <= tol * up:
        status = SolverStatus.OPTIMAL
    stats = dict(outputs[0].stats,
                 combined=[(o.status.value, float(lw), float(u)) for o, lw, u in zip(outputs, lowers, uppers)],
                 upper_from=a, lower_from=b)
    return dataclasses.replace(primal, status=status, dual_v=dual.dual_v, dual_W=dual.dual_W,
                               solve_time=float(sum(o.solve_time for o in outputs)), stats=stats)
