"""Solvers of the unfalsification programs (7.4) and (7.5), behind one contract.

Every solver is a function ``solve(problem, **options) -> SolverOutput`` registered by name in
:data:`SOLVERS` (the way cvxpy maps names to its conic solvers in ``SOLVER_MAP_CONIC``); the front
ends (:func:`unfalsify.arx_unfalsify`, :func:`unfalsify.subspace_unfalsify`) validate, build the
problem, call :func:`run` and build the certificate from the :class:`SolverOutput`.

==================  =========================================================================  ==========
name                what                                                                       programs
==================  =========================================================================  ==========
``cvxpy``           the reference LMI models through cvxpy and a conic solver                  arx, subspace
``arx_barrier``     Cholesky barrier method, certified to a relative gap (O(n²) memory)        arx
``arx_pd``          primal–dual interior point (NT scaling, Mehrotra), same certificate        arx
``bracket``         FFT-only certified bracket, gap reported (n = 10⁴; norm proof: one n × n)   arx
``column_barrier``  column barrier method with threads over the columns                        subspace
``column_pd``       primal–dual interior point (NT scaling, Mehrotra), same certificate        subspace
``block_barrier``   barrier method for several channels (l × m operators, dense block Hessians)  subspace
``split``           fixed predictor: columns as tasks on an ``Executor``, 1-D outer problem     subspace
==================  =========================================================================  ==========

Several channels (u: (n, m), y: (n, l), issue 28): ``cvxpy``, ``arx_barrier``, ``arx_pd`` and ``block_barrier``
(:data:`CHANNELS`) take them, ``backend="structured"`` of (7.5) resolves to ``block_barrier`` there; the others raise
:class:`~unfalsify.UnknownSolverError` naming ``backend="cvxpy"``.

Shared parts: :mod:`~unfalsify.solvers.base` (:class:`SolverStatus`, :class:`SolverOutput`),
:mod:`~unfalsify.solvers.columns` (the column form every structured solver takes and its dual bound),
:mod:`~unfalsify.solvers.barrier` (the one barrier skeleton, time limit, progress, CG),
:mod:`~unfalsify.solvers.start` (the barrier solvers' ridge starting point),
:mod:`~unfalsify.solvers.toeplitz` (products, adjoint, stacks, Gram, norms, the FFT Hessian) and
:mod:`~unfalsify.solvers.displacement` (the barrier Hessian, the blocks of F⁻¹ and K's Cholesky factor from
displacement generators, O(m²)).

The front ends' ``backend=`` and ``method=`` resolve to these names (:func:`resolve`): ``"cvxpy"`` →
``cvxpy``; ``"structured"`` → ``arx_barrier`` (``method="barrier"``), ``arx_pd`` (``method="primal_dual"``)
or ``bracket`` (``method="bracket"``) for (7.4), ``column_barrier`` (``method="barrier"``) or ``column_pd``
(``method="primal_dual"``) for (7.5); ``executor=`` → ``split``.

>>> from unfalsify import solvers
>>> sorted(solvers.SOLVERS)
['arx_barrier', 'arx_pd', 'block_barrier', 'bracket', 'column_barrier', 'column_pd', 'cvxpy', 'split']
>>> solvers.resolve("arx", "structured", "bracket")
'bracket'
>>> solvers.resolve("arx", "structured", "primal_dual")
'arx_pd'
>>> solvers.resolve("subspace", "structured", "primal_dual")
'column_pd'
"""
from __future__ import annotations

import numbers

from synthesis.validation import DataError

from ..exceptions import UnknownSolverError
from . import arx_barrier, arx_pd, block_barrier, bracket, column_barrier, column_pd, cvxpy_models, split
from .base import SolverOutput, SolverStatus
from .column_barrier import check_workers

# the registry and its contract, re-exported by ``unfalsify``; resolve, run, PROGRAMS, METHODS and
# check_workers serve the front ends
__all__ = ["SOLVERS", "BACKENDS", "SolverOutput", "SolverStatus"]

#: name → ``solve(problem, **options) -> SolverOutput``
SOLVERS = {
    "cvxpy": cvxpy_models.solve,
    "arx_barrier": arx_barrier.solve,
    "arx_pd": arx_pd.solve,
    "bracket": bracket.solve,
    "column_barrier": column_barrier.solve,
    "column_pd": column_pd.solve,
    "block_barrier": block_barrier.solve,
    "split": split.solve,
}

#: the programs each solver accepts (``problem.program``)
PROGRAMS = {
    "cvxpy": ("arx", "subspace"),
    "arx_barrier": ("arx",),
    "arx_pd": ("arx",),
    "bracket": ("arx",),
    "column_barrier": ("subspace",),
    "column_pd": ("subspace",),
    "block_barrier": ("subspace",),
    "split": ("subspace",),
}

#: the solvers that take several channels (``problem.siso`` False: u (n, m), y (n, l) with m + l > 2)
CHANNELS = ("cvxpy", "arx_barrier", "arx_pd", "block_barrier")

#: ``backend=`` of the front ends
BACKENDS = ("cvxpy", "structured")

#: ``method=`` of the structured backend (the bracket is for (7.4) only)
METHODS = ("barrier", "bracket", "primal_dual")

# (program, method) of backend="structured" -> solver
_STRUCTURED = {("arx", "barrier"): "arx_barrier", ("arx", "bracket"): "bracket", ("arx", "primal_dual"): "arx_pd",
               ("subspace", "barrier"): "column_barrier", ("subspace", "primal_dual"): "column_pd"}


def _names(xs) -> str:
    return ", ".join(repr(x) for x in xs)


def resolve(program: str, backend: str, method: str = "barrier") -> str:
    """The registry name of ``backend=`` / ``method=`` for ``program`` (``"arx"`` or ``"subspace"``).

    Raises
    ------
    UnknownSolverError
        Unknown ``backend`` or ``method`` (the message lists the valid names).
    ValueError
        ``method`` other than ``"barrier"`` without ``backend="structured"``.
    """
    if backend not in BACKENDS:
        raise UnknownSolverError(f"unknown backend {backend!r}; use one of {_names(BACKENDS)} "
                                 f"(solvers behind them: {_names(SOLVERS)})")
    if method not in METHODS:
        raise UnknownSolverError(f"unknown method {method!r}; use one of {_names(METHODS)}")
    if backend == "cvxpy":
        if method != "barrier":
            raise DataError(f"method={method!r} needs backend='structured'")
        return "cvxpy"
    name = _STRUCTURED.get((program, method))
    if name is None:
        raise UnknownSolverError(f"method={method!r} is not available for the {program} program; "
                                 f"use {_names(m for p, m in _STRUCTURED if p == program)}")
    return name


def run(name: str, problem, **options) -> SolverOutput:
    """``SOLVERS[name](problem, **options)``, after checking that the solver takes this program."""
    if name not in SOLVERS:
        raise UnknownSolverError(f"unknown solver {name!r}; use one of {_names(SOLVERS)}")
    if problem.program not in PROGRAMS[name]:
        raise UnknownSolverError(f"solver {name!r} does not solve the {problem.program} program; "
                                 f"use one of {_names(n for n in SOLVERS if problem.program in PROGRAMS[n])}")
    if not getattr(problem, "siso", True) and name not in CHANNELS:
        raise UnknownSolverError(
            f"solver {name!r} solves single-channel data only; for {problem.n_outputs}×{problem.n_inputs} data "
            "(several inputs or outputs) use backend='cvxpy' or backend='structured'"
            + (" without executor=" if name == "split" else "")
            + f" (the solvers that take several channels: {_names(n for n in CHANNELS if problem.program in PROGRAMS[n])})")
    _check_stopping(options)
    return SOLVERS[name](problem, **options)


def _check_stopping(options: dict) -> None:
    """``tol`` a relative gap in (0, 1) and ``time_limit`` None or a number ≥ 0, where given: a negative tolerance
    can never be met (the solve ended 'failed' without saying why)."""
    tol = options.get("tol")
    if tol is not None and (isinstance(tol, bool) or not isinstance(tol, numbers.Real) or not 0.0 < tol < 1.0):
        raise DataError(f"tol must be a relative gap in (0, 1), e.g. 1e-6, got {tol!r}")
    limit = options.get("time_limit")
    if limit is not None and (isinstance(limit, bool) or not isinstance(limit, numbers.Real) or not limit >= 0.0):
        raise DataError(f"time_limit must be None or a number of seconds ≥ 0, got {limit!r}")
