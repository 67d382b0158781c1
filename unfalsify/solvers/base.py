"""The contract every solver meets: the shared status enum and the typed output (data units).

A solver is a function ``solve(problem, **options) -> SolverOutput`` registered under a name in
:data:`unfalsify.solvers.SOLVERS`.  ``problem`` is an :class:`unfalsify.ArxProblem` or
:class:`unfalsify.SubspaceProblem` (its ``program`` says which); the structured solvers take its
``column_form()`` in scaled units and hand their answer back in data units with :func:`unscaled`.
"""
from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np

from synthesis.results import result

from .columns import ColumnForm, scale_dual

__all__ = ["SolverStatus", "SolverOutput", "unscaled", "zero_answer", "one_blas_thread"]


class SolverStatus(str, enum.Enum):
    """How a solve ended, shared by all solvers (cvxpy's status strings and the structured solvers' own).

    A ``str`` subclass: ``SolverStatus.OPTIMAL == "optimal"``.  The result classes store ``.value``.
    """

    OPTIMAL = "optimal"
    OPTIMAL_INACCURATE = "optimal_inaccurate"
    #: the two sides of a certified bracket finished, the gap between them is not closed (``method="bracket"``)
    BRACKET = "bracket"
    TIME_LIMIT = "time_limit"
    INTERRUPTED = "interrupted"
    MAX_ITER = "max_iter"
    MAX_ROUNDS = "max_rounds"
    FAILED = "failed"
    USER_LIMIT = "user_limit"
    INFEASIBLE = "infeasible"
    INFEASIBLE_INACCURATE = "infeasible_inaccurate"
    UNBOUNDED = "unbounded"
    UNBOUNDED_INACCURATE = "unbounded_inaccurate"
    INFEASIBLE_OR_UNBOUNDED = "infeasible_or_unbounded"
    SOLVER_ERROR = "solver_error"

    @property
    def keeps_bracket(self) -> bool:
        """Whether a structured solve that ended so still holds a certified bracket (δ = its upper end)."""
        return self in (SolverStatus.OPTIMAL, SolverStatus.BRACKET, SolverStatus.TIME_LIMIT, SolverStatus.INTERRUPTED)


@result
@dataclass(frozen=True, eq=False)
class SolverOutput:
    """What a registered solver returns, in data units.

    Attributes
    ----------
    delta : float
        The solver's δ (NaN when it has none).
    impulses : ndarray
        h (n,) or H (i, j).
    params : ndarray
        θ (ARX) or ``[L_w L_u]`` (subspace).
    status : SolverStatus
    solve_time : float
        Wall time in seconds.
    dual_v, dual_W : object
        The dual point of the certificate (None if the solver has none); see :class:`unfalsify.Certificate`.
    bracketed : bool
        True for the structured solvers: δ is the upper end of a certified bracket, and the front end
        warns for any status but ``optimal`` with the certificate's gap.
    problem : cvxpy.Problem or None
        The cvxpy problem as solved (a by-product; not compared, not pickled).
    stats : dict
        Iteration counts (``newton``, ``outer``, ``cg``, ``rounds``) where the solver has them.
    """

    delta: float
    impulses: np.ndarray
    params: np.ndarray
    status: SolverStatus
    solve_time: float
    dual_v: object = None
    dual_W: object = None
    bracketed: bool = False
    problem: object = field(default=None, compare=False)
    stats: dict = field(default_factory=dict)


#: Relative slack of every noise check: a point whose noise, recomputed from the data, exceeds σ√N by less than this
#: is inside the ball up to rounding (the default tolerance of ``Certificate.verify``).
NOISE_RTOL = 1e-6

#: Relative slack of :func:`zero_answer`: far above the rounding of ``‖PB‖`` (1e-15), far below the certificate's
#: noise tolerance (1e-6).
_ZERO_SLACK = 1e-12


def zero_answer(form: ColumnForm) -> bool:
    """True when the model directions alone explain the data within the noise budget: δ = 0, no solve.

    σ equal to the least-squares residual rms (a natural choice) puts ``‖PB‖`` on ρ up to rounding (measured
    ``‖PB‖/ρ − 1`` = 2e-16 … 4e-15): the answer is δ = 0, whose interior is empty, and the barrier and primal–dual
    methods failed there; so ``‖PB‖ ≤ ρ(1 + 1e-12)`` counts, and the zero answer's noise is within the
    certificate's tolerance."""
    return bool(np.linalg.norm(form.project(form.B)) <= form.rho * (1.0 + _ZERO_SLACK))


def unscaled(problem, H_s, upper_s: float, status, elapsed: float, *, V=None, W=None, bracketed=True,
             stats=None) -> SolverOutput:
    """A structured solver's answer in scaled units (``problem.column_form()``) as a :class:`SolverOutput`.

    Impulses and δ scale by ``s_y/s_u``, the norm multiplier W by ``s_u`` (V is scale-free); the model
    parameters are refitted to the impulses by the problem itself (``problem.params_for``).
    """
    su, sy = problem.scale
    H = np.asarray(H_s) * (sy / su)
    return SolverOutput(delta=float(upper_s) * sy / su, impulses=H, params=problem.params_for(H),
                        status=SolverStatus(status), solve_time=float(elapsed), dual_v=V, dual_W=scale_dual(W, su),
                        bracketed=bracketed, stats=dict(stats or {}))


def one_blas_thread():
    """A context holding BLAS to one thread (threadpoolctl), for code whose BLAS calls are many and small.

    OpenBLAS's other threads spin between such calls and, on a loaded machine, take the cores the work needs:
    measured on 2 cores with another job running, the set-up and certificate of a (7.5) solve at (i, j) = (50, 500)
    took 6.5–9 s around a 14 s solve with BLAS as configured, 0.33 s with one BLAS thread (an SVD of the 150 × 500
    regressor 2.5 s against milliseconds); idle, a record-mode :func:`unfalsify.robust_design_from_data` of a
    1500-sample record at i = 8 took 14 s with two threads and 6.5 s with one.
    """
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")
