"""Exceptions, warnings, thresholds and solver plumbing shared by the unfalsification modules."""
from __future__ import annotations

import numbers
import time
import warnings
from dataclasses import dataclass

import cvxpy as cp
import numpy as np

from synthesis._validation import DataError, as_signal

__all__ = [
    "UnfalsificationError",
    "IllConditionedWarning",
    "SolverWarning",
    "COND_WARN",
    "SOLVER_TOL",
]

#: cond₂ T(u) above which Theorem 7.1 / the literal LMIs are flagged.  Chosen as
#: ≈ 1/√eps: beyond it the Gram matrix ``T(u)ᵀT(u)`` that (7.1), (7.4) and (7.5) use has
#: condition number above 1/eps, i.e. it is numerically singular in double precision,
#: and the gain of Theorem 7.1 may change by 100 % under relative data perturbations
#: of ~1/cond (far below any sensor's resolution): the number then describes the
#: rounding of the data, not the plant.
COND_WARN = 1e8

#: Absolute/relative tolerance used when reading solver answers (δ = 0, feasibility checks).
SOLVER_TOL = 1e-6


class UnfalsificationError(ValueError):
    """The unfalsification problem could not be solved (infeasible/unbounded/solver failure)."""


class IllConditionedWarning(UserWarning):
    """cond T(u) is so large that the literal Chapter 7 quantities are numerically meaningless."""


class SolverWarning(UserWarning):
    """The conic solver returned a status other than ``optimal``."""


def check_sigma(sigma) -> float:
    """σ of ``‖ξ‖_rms ≤ σ`` (§7.2.2) as a float; raises DataError unless finite and > 0."""
    if isinstance(sigma, bool) or not isinstance(sigma, numbers.Real):
        raise DataError(f"sigma must be a positive real number (the admissible rms noise level), got {sigma!r}")
    s = float(sigma)
    if not np.isfinite(s) or s <= 0.0:
        raise DataError(
            f"sigma (the admissible rms noise level) must be finite and > 0, got {sigma!r}; "
            "for the pure-uncertainty limit use a small positive value (σ = 0 leaves the noise "
            "constraint without an interior, which interior-point solvers cannot handle)"
        )
    return s


def siso_signal(x, name: str, n: int | None = None) -> np.ndarray:
    """A single-channel signal as a 1-D float array (raises DataError otherwise)."""
    arr = as_signal(x, name, n=n)
    if arr.shape[1] != 1:
        raise DataError(f"{name} must be a single channel (SISO, as in Chapter 7); got {arr.shape[1]} channels")
    return arr[:, 0].copy()


def rms_or_one(x: np.ndarray) -> float:
    """Root mean square of ``x``, or 1 when it is 0 (a safe scale factor for the LMIs)."""
    r = float(np.sqrt(np.mean(np.asarray(x, float) ** 2)))
    return r if r > 0 else 1.0


def check_form(form: str) -> str:
    """``form`` of (7.4)/(7.5): ``"conditioned"`` or ``"thesis"`` (raises ValueError otherwise)."""
    if form not in ("conditioned", "thesis"):
        raise ValueError(f"unknown form {form!r}; use 'conditioned' (default) or 'thesis'")
    return form


def solve(problem: cp.Problem, solver: str, solver_options: dict | None, what: str) -> tuple[str, float]:
    """Solve ``problem`` with an explicit solver; return (status, wall time).

    Raises :class:`UnfalsificationError` on solver failure or infeasible/unbounded status;
    warns :class:`SolverWarning` for any other non-optimal status.
    """
    opts = dict(solver_options or {})
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            # cvxpy's own "Solution may be inaccurate" warning: replaced by our SolverWarning below
            warnings.filterwarnings("ignore", message="Solution may be inaccurate", category=UserWarning)
            problem.solve(solver=solver, **opts)
    except cp.error.SolverError as exc:
        raise UnfalsificationError(f"{what}: solver {solver} failed ({exc}); try another solver or smaller data") from exc
    elapsed = time.perf_counter() - t0
    status = problem.status
    if status in (cp.INFEASIBLE, cp.INFEASIBLE_INACCURATE, cp.UNBOUNDED, cp.UNBOUNDED_INACCURATE):
        raise UnfalsificationError(
            f"{what}: solver {solver} reports '{status}', which is impossible for this problem in exact "
            "arithmetic (it is always feasible and δ ≥ 0): the data are too ill-conditioned for the solver; "
            "use form='conditioned', fewer samples or rescale the data"
        )
    if status != cp.OPTIMAL:
        warnings.warn(
            f"{what}: solver {solver} returned status '{status}'; check the result's certificate",
            SolverWarning,
            stacklevel=3,
        )
    return status, elapsed


def solved_value(status: str, value) -> float:
    """δ from a solve: NaN unless the status is optimal or optimal_inaccurate."""
    if status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) or value is None:
        return float("nan")
    return float(value)


@dataclass(frozen=True)
class Certificate:
    """Independent check of an unfalsification answer, recomputed from the returned variables.

    What is certified is the pair (noise, impulses): ``e − ξ = T(u) h`` (to rounding of one
    multiplication by ``T(u)``; exactly, for the literal form, where h is the exact rational
    deconvolution of the returned ``e − ξ``) and ``‖T(h)‖₂ ≤ δ_certified``, which by Theorem 7.1
    is the thesis inequality.  Checking the thesis inequality from the rounded ξ *alone* is
    ill-posed for long records: rounding errors of ξ are amplified by ``T(u)⁻¹`` (cond up to
    1e17 at n = 80).

    Attributes
    ----------
    delta : float
        δ reported by the solver.
    delta_certified : float
        The smallest δ that the returned noise and impulse(s) actually certify: ``max_k ‖T(h_k)‖₂``
        with ``h_k`` recomputed from the returned noise (exactly, in rational arithmetic, for the
        literal form) -- by Theorem 7.1 this is the exact left-hand side of (7.4)/(7.5).
    noise_rms : float
        rms of the returned noise (``‖ξ‖₂/√n`` or ``‖Ξ‖_F/√(ij)``), to compare with σ.
    sigma : float
        The admissible rms noise level.
    """

    delta: float
    delta_certified: float
    noise_rms: float
    sigma: float

    @property
    def max_violation(self) -> float:
        """``max(δ_certified − δ, noise_rms − σ)`` (≤ 0 means the answer satisfies the original inequalities)."""
        return float(max(self.delta_certified - self.delta, self.noise_rms - self.sigma))

    def ok(self, rtol: float = 1e-5) -> bool:
        """True when the violation is within ``rtol`` relative to ``max(δ, σ)``."""
        scale = max(abs(self.delta), self.sigma)
        return bool(np.isfinite(self.delta_certified) and self.max_violation <= rtol * scale)
