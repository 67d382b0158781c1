"""Subspace uncertainty-model unfalsification, thesis §7.3 and program (7.5), for one or several channels.

Error model: ``Y_f − [L_w L_u][W_p; U_f] = E = Ξ + Δ̄(q) U_f``, where ``Δ̄`` is a set of j
causal LTI operators, operator k acting on column k of ``U_f`` (system at rest at the
start of each column), and ``(1/(ij))‖Ξ‖_F² ≤ σ²``.  The smallest common bound δ on
``‖Δ_k‖∞`` that unfalsifies the data is (7.5):

    δ = min δ  s.t.  T((E − Ξ)_{:,k})ᵀ T(·) ⪯ δ² T((U_f)_{:,k})ᵀ T((U_f)_{:,k})   ∀k.

``form="conditioned"`` (default)
    Per column ``(E − Ξ)_{:,k} = T((U_f)_{:,k}) h_k`` with ``‖T(h_k)‖₂ ≤ δ`` (an exact
    reformulation of Theorem 7.1), and ``‖Ξ‖_F ≤ σ√(ij)``.  A column whose input starts with p zeros
    leaves its first p errors to the noise (a causal operator at rest gives no output there) and is
    exact too: the last p entries of h_k do not reach the data and can be chosen so that ‖T(h_k)‖₂ is
    the norm of the shorter section (Parrott's theorem; see
    :meth:`~unfalsify.solvers.columns.ColumnForm.noise_floor`).  If the noise budget cannot hold those
    errors, no δ unfalsifies the data and :meth:`SubspaceProblem.from_data` says which σ would.
    With ``eliminate_L=True`` the predictor is eliminated analytically: for given impulses
    the smallest ``‖Ξ‖_F`` over ``L`` is ``‖(Y_f − H̃) N‖_F`` with ``N`` an orthonormal basis
    of the null space of ``A = [W_p; U_f]`` (``NNᵀ = I − P_A``), ``H̃_{:,k} = T((U_f)_{:,k}) h_k``.
    ``L = (Y_f − H̃) A⁺`` is recovered afterwards (then ``Ξ = (Y_f − H̃)(I − P_A)``).
``form="thesis"``
    The literal LMIs of §7.3: ``[σ vec(Ξ)ᵀ/√(ij); vec(Ξ)/√(ij) σI] ⪰ 0`` and, per column,
    ``[δ T(U_f,k)ᵀT(U_f,k)  T((E−Ξ)_k)ᵀ; T((E−Ξ)_k)  δI] ⪰ 0``.  Tiny sizes only.

Layout follows :class:`synthesis.Predictor`: ``W_p = [U_p; Y_p]``, ``L_w`` is ``i × 2i`` and
``L_u`` is ``i × i`` (SISO); column k of ``U_f`` is ``[u_{i+k} … u_{2i−1+k}]`` (0-based k).

Several channels (u: (n, m), y: (n, l), time along axis 0; issue 28).  ``U_f`` is im × j and ``Y_f`` is
il × j (block Hankel, the samples of column k stacked), ``L_w`` is ``il × i(m + l)`` and ``L_u`` is
``il × im``.  Δ̄ is a set of j causal LTI operators with l outputs and m inputs, operator k acting on
column k of ``U_f``; its first i Markov parameters ``h_k`` (i, l, m) give ``(E − Ξ)_{:,k} = T(h_k) (U_f)_{:,k}``
with the il × im block lower-triangular Toeplitz matrix ``T(h_k)``, whose spectral norm is the least
H∞ norm of such an operator (matrix Carathéodory–Fejér).  The program is (C) of
:class:`~unfalsify.solvers.columns.BlockColumnForm`: ``‖T(h_k)‖₂ ≤ δ`` for every k and
``‖Ξ‖_F ≤ σ√(ilj)`` (the rms budget σ over all il·j noise entries); its dual (lower) bound is derived
there.  The reparametrisation is exact, as with one channel; a column whose first input vectors ``u_{i+k}, …``
are zero leaves its first outputs to the noise.  Several channels take ``form="conditioned"``
on both backends: cvxpy (the reference model) and ``backend="structured"``, which is the solver
``block_barrier`` there (:mod:`unfalsify.solvers.block_barrier`); ``executor=`` (the split solver) is
SISO only and names ``backend="cvxpy"``.  With one channel each the SISO code runs unchanged.
"""
from __future__ import annotations

import contextlib
import dataclasses
import warnings
from dataclasses import dataclass, field
from typing import ClassVar

import cvxpy as cp
import numpy as np

from synthesis import DataError, Predictor, block_hankel
from synthesis.results import result
from synthesis.validation import (InputTypeError, as_signal, check_flag, check_horizon, check_inputs_move,
                                  check_output_moves)

from ._common import (COND_WARN, Certificate, certify, check_form, check_noise_floor, check_noise_resolution,
                      check_predictor, check_sigma, check_solver_options, into_ball, rms_or_one)
from .cost import _guard_subspace
from .exceptions import FewDataWarning, IllConditionedWarning, UnknownSolverError
from .solvers import check_workers, resolve, run
from .solvers.base import SolverOutput, one_blas_thread
from .solvers.combine import best_of
from .solvers.columns import BlockColumnForm, ColumnForm
from .solvers.wider_ball import small_ball
from .solvers.toeplitz import (block_certified_norm, block_conv_cols, certified_norm, conv_cols, signal_toeplitz,
                               toeplitz_cond)

__all__ = ["SubspaceProblem", "SubspaceResult", "subspace_unfalsify", "subspace_data"]


@result
@dataclass(frozen=True, eq=False)
class SubspaceResult:
    """Solution of the subspace unfalsification program (7.5).

    Attributes
    ----------
    delta : float
        δ_unf (NaN if the solve failed).
    Lw : ndarray, shape (i, 2i)
    Lu : ndarray, shape (i, i)
        Predictor of the unfalsified model, same layout as :class:`synthesis.Predictor`
        (m inputs, l outputs: ``il × i(m + l)`` and ``il × im``).
    noise : ndarray, shape (i, j)
        Ξ (il × j).
    impulses : ndarray, shape (i, j)
        Column k is h_k, the first i Markov parameters of Δ_k:
        ``(E − Ξ)_{:,k} = T((U_f)_{:,k}) h_k``.  Several channels: shape (i, l, m, j),
        ``impulses[..., k]`` the l × m Markov parameters of Δ_k.
    status : str
    solve_time : float
        Wall time of ``problem.solve`` (includes cvxpy compilation).
    problem : cvxpy.Problem or None
        The problem as solved (in rms-scaled units, see ``scale``); None for the structured and split
        backends.  A by-product: not compared by ``==``, and stored as None when the result is
        pickled (a cvxpy problem holds a solver object that does not pickle); everything else, the
        certificate included, survives.
    form : str
    eliminate_L : bool
        Whether the predictor was eliminated analytically (conditioned form).
    sigma : float
    horizon, n_columns : int
        i and j.
    cond_Tu : float
        ``max_k cond₂ T((U_f)_{:,k})``.
    certificate : Certificate
        δ recomputed as ``max_k ‖T(h_k)‖₂`` from the returned Ξ and L, and ``‖Ξ‖_F/√(ij)``.
    scale : tuple of float
        ``(s_u, s_y)``: the problem was posed on ``u/s_u``, ``y/s_y`` (``s_u`` = rms of u,
        ``s_y`` = rms of the predictor residual).
    regressor_singular_values : ndarray
        Singular values of ``A = [W_p; U_f]``.
    backend : str
    n_inputs, n_outputs : int
        m and l.
    start : str
        How the solve started: ``"cold"``, ``"warm (window advanced by k samples)"``, or ``"cold (warm start
        not used: <why>)"`` when a ``warm_start`` was passed that the solver could not use.
    solver_stats : dict
        The structured solvers' counts (``newton``, ``outer``, ``cg``, ``trials``: Cholesky stacks tried)
        and, for ``column_barrier``, ``state["path"]``: the centred points (impulses, δ, relative gap,
        slacks; data units) that a ``warm_start`` resumes from.  A by-product: not compared.
    """

    delta: float
    Lw: np.ndarray
    Lu: np.ndarray
    noise: np.ndarray
    impulses: np.ndarray
    status: str
    solve_time: float
    problem: cp.Problem | None = field(compare=False)
    form: str
    eliminate_L: bool
    sigma: float
    horizon: int
    n_columns: int
    cond_Tu: float
    certificate: Certificate
    scale: tuple
    regressor_singular_values: np.ndarray
    backend: str = "cvxpy"
    n_inputs: int = 1
    n_outputs: int = 1
    start: str = "cold"
    solver_stats: dict = field(default_factory=dict, compare=False)

    @property
    def max_violation(self) -> float:
        """Shortcut for ``certificate.max_violation``."""
        return self.certificate.max_violation

    @property
    def predictor(self) -> Predictor:
        """``(L_w, L_u)`` as a :class:`synthesis.Predictor` (e.g. for :func:`synthesis.hinf_design`)."""
        s = self.regressor_singular_values
        tol = max(3 * self.horizon, self.n_columns) * np.finfo(float).eps * (s[0] if s.size else 1.0)
        return Predictor(
            Lw=self.Lw,
            Lu=self.Lu,
            horizon=self.horizon,
            m=self.n_inputs,
            l=self.n_outputs,
            n_columns=self.n_columns,
            singular_values=s,
            rank=int(np.count_nonzero(s > tol)),
            method=f"unfalsified-{self.form}",
        )


def subspace_data(u, y, horizon: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A, U_f, Y_f)`` with ``A = [U_p; Y_p; U_f]`` (3i × j for SISO), j = n − 2i + 1 (§2.1).

    u (n, m) and y (n, l), time along axis 0 (1-D: one channel): ``A`` is ``i(2m + l) × j``, ``U_f`` is
    ``im × j`` and ``Y_f`` is ``il × j`` (block Hankel, :func:`synthesis.block_hankel`).

    Examples
    --------
    >>> import numpy as np
    >>> import unfalsify as uf
    >>> A, Uf, Yf = uf.subspace_data(np.ones((30, 2)), np.ones((30, 3)), 4)
    >>> A.shape, Uf.shape, Yf.shape
    ((28, 23), (8, 23), (12, 23))
    """
    u = as_signal(u, "u")
    y = as_signal(y, "y", n=u.shape[0])
    i = check_horizon(horizon, u.shape[0])
    j = u.shape[0] - 2 * i + 1
    Up = block_hankel(u, i, j, 0)
    Yp = block_hankel(y, i, j, 0)
    Uf = block_hankel(u, i, j, i)
    Yf = block_hankel(y, i, j, i)
    return np.vstack([Up, Yp, Uf]), Uf, Yf


@result
@dataclass(frozen=True, eq=False)
class SubspaceProblem:
    """Program (7.5) on given data: validation, scaling, the fixed predictor and the bounds.

    Build with :meth:`from_data`.  ``evaluate_primal(H, L)`` / ``evaluate_dual(V, W)`` are the two
    sides of :class:`Certificate` (data units); ``column_form`` is what the backends solve.
    """

    u: np.ndarray
    y: np.ndarray
    horizon: int
    sigma: float
    L_fixed: np.ndarray | None
    scale: tuple
    cond_Tu: float
    A: np.ndarray
    Uf: np.ndarray
    Yf: np.ndarray
    n_inputs: int = 1
    n_outputs: int = 1
    #: which program the solvers see (:data:`unfalsify.solvers.PROGRAMS`)
    program: ClassVar[str] = "subspace"

    @property
    def n_columns(self) -> int:
        """j."""
        return int(self.Uf.shape[1])

    @property
    def n_noise(self) -> int:
        """Number of noise samples ``ilj`` the budget ``σ√(ilj)`` covers (``ij`` for SISO)."""
        return int(self.horizon * self.n_outputs * self.n_columns)

    @property
    def siso(self) -> bool:
        """One input and one output (the SISO code paths)."""
        return self.n_inputs == 1 and self.n_outputs == 1

    @property
    def zero_start_columns(self) -> np.ndarray:
        """Columns of ``U_f`` whose first input sample is zero (on every channel): their first outputs are the
        noise's alone (:meth:`~unfalsify.solvers.columns.ColumnForm.noise_floor`)."""
        return np.flatnonzero(np.all(self.Uf[: self.n_inputs] == 0.0, axis=0))

    @classmethod
    def from_data(cls, u, y, horizon, sigma, predictor=None) -> "SubspaceProblem":
        """Validate (raises :class:`DataError`) and scale; u (n, m), y (n, l), time along axis 0."""
        u = as_signal(u, "u")
        y = as_signal(y, "y", n=u.shape[0])
        m, l = u.shape[1], y.shape[1]
        if m == 1 and l == 1:  # SISO: 1-D signals, as before several channels were accepted
            u, y = u[:, 0].copy(), y[:, 0].copy()
        check_output_moves(y, "the window")  # a zero output had given δ = NaN with status 'optimal' (cvxpy)
        sigma = check_sigma(sigma)
        A, Uf, Yf = subspace_data(u, y, horizon)
        i, j = Uf.shape[0] // m, Uf.shape[1]
        check_noise_resolution(sigma, Yf.size, Yf, "Y_f")
        L_fixed = None if predictor is None else _fixed_predictor(predictor, i, m, l)
        if m == 1:
            cond = max(toeplitz_cond(Uf[:, k]) for k in range(j))
        else:
            sv = [np.linalg.svd(signal_toeplitz(Uf[:, k].reshape(i, m)), compute_uv=False) for k in range(j)]
            cond = max(float(s[0] / s[-1]) if s[-1] > 0 else float("inf") for s in sv)
        # u to unit rms; y so that the residual of the predictor (least squares, or the fixed one)
        # has unit rms: that is the error the program splits between Ξ and Δ̄U_f
        su = rms_or_one(u)
        Lref = L_fixed if L_fixed is not None else np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T
        sy = rms_or_one(Yf - Lref @ A)
        if not sy > 1e-12 * rms_or_one(y):
            sy = rms_or_one(y)
        problem = cls(u=u, y=y, horizon=i, sigma=sigma, L_fixed=L_fixed, scale=(su, sy), cond_Tu=float(cond),
                      A=A, Uf=Uf, Yf=Yf, n_inputs=m, n_outputs=l)
        zero_cols = problem.zero_start_columns
        if zero_cols.size == j:
            check_inputs_move(Uf, f"the window's future inputs U_f (samples {i} … {i + j + i - 2})",
                              each_channel=False)
        if zero_cols.size:
            where = ", ".join(f"u[{i + c}]" for c in zero_cols[:5]) + (", …" if zero_cols.size > 5 else "")
            check_noise_floor(
                problem.column_form(scaled=False), sigma,
                f"{zero_cols.size} column(s) of U_f start with a zero input (first: column {zero_cols[0]}; zero at "
                f"{where})",
                f"move the window so that its samples {i} … {i + j - 1} (the columns' first samples) hold fewer zeros "
                "(`--window START:LEN` of `python -m experiments design`; for a record that starts at rest, start i "
                "samples before the input moves, as window='auto' does); for an input that switches between 0 and "
                "a level, subtract its operating point (u − mean(u), y − mean(y); `--detrend mean`)")
        return problem

    def scaled_A(self) -> np.ndarray:
        """``A`` with rows scaled as the data (``u/s_u``, ``y/s_y``)."""
        i = self.horizon
        su, sy = self.scale
        As = self.A.copy()
        if not self.siso:
            im, il = i * self.n_inputs, i * self.n_outputs
            As[:im] /= su
            As[im : im + il] /= sy
            As[im + il :] /= su
            return As
        As[:i] /= su
        As[i : 2 * i] /= sy
        As[2 * i :] /= su
        return As

    def _conv(self, H) -> np.ndarray:
        """``H̃``: column k is ``T(h_k) (U_f)_{:,k}`` (SISO: ``conv_cols``)."""
        return conv_cols(self.Uf, H) if self.siso else block_conv_cols(self.Uf, H, self.n_inputs)

    def column_form(self, scaled: bool = True) -> ColumnForm:
        """(7.5) as the column form (C) (𝓛 = {L A}, or {0} with the predictor fixed)."""
        su, sy = self.scale if scaled else (1.0, 1.0)
        if not self.siso:
            return self._block_form(su, sy, scaled)
        i, j = self.Uf.shape
        rho = self.sigma / sy * np.sqrt(i * j)
        if self.L_fixed is not None:
            return ColumnForm(self.Uf / su, (self.Yf - self.L_fixed @ self.A) / sy, rho)
        return ColumnForm(self.Uf / su, self.Yf / sy, rho, basis_right=self._row_basis(scaled))

    def _block_form(self, su, sy, scaled) -> BlockColumnForm:
        rho = self.sigma / sy * np.sqrt(self.n_noise)
        kw = dict(n_inputs=self.n_inputs, n_outputs=self.n_outputs)
        if self.L_fixed is not None:
            return BlockColumnForm(self.Uf / su, (self.Yf - self.L_fixed @ self.A) / sy, rho, **kw)
        return BlockColumnForm(self.Uf / su, self.Yf / sy, rho, basis_right=self._row_basis(scaled), **kw)

    def _row_basis(self, scaled: bool = True) -> np.ndarray:
        """Orthonormal basis (j × rank) of the row space of ``A = [W_p; U_f]`` (scaled or not): 𝓛 = {X Qᵀ}."""
        As = self.scaled_A() if scaled else self.A
        _, sv, Vt = np.linalg.svd(As, full_matrices=False)
        rank = int(np.count_nonzero(sv > max(As.shape) * np.finfo(float).eps * (sv[0] if sv.size else 1.0)))
        return Vt[:rank].T

    def evaluate_primal(self, H, L, near=None) -> tuple[float, float]:
        """``(max_k ‖T(h_k)‖₂, ‖Y_f − L A − H̃‖_F)`` recomputed from the data.

        ``near`` (the reported δ) is accepted for the interface :class:`Certificate` shares with ARX and not
        used: the columns' norms differ, and a shift helps only the column whose norm it is close to.

        The norms are the certificate's upper side, so they are never estimates: a dense SVD (the same
        numbers as before for ``i·max(l, m) ≤ 4000``), above that a bound proven by a Cholesky factor or
        the symbol (:func:`~unfalsify.solvers.toeplitz.certified_norm`) -- a Lanczos value alone can lie below.
        """
        H = np.asarray(H, float)
        L = np.asarray(L, float)
        if not (np.all(np.isfinite(H)) and np.all(np.isfinite(L))):
            return float("inf"), float("nan")
        if not self.siso:
            Xi = self.Yf - L @ self.A - self._conv(H)
            d = max(block_certified_norm(H[..., k]) for k in range(H.shape[-1]))
            return float(d), float(np.linalg.norm(Xi))
        Xi = self.Yf - L @ self.A - conv_cols(self.Uf, H)
        d = max(certified_norm(H[:, k]) for k in range(H.shape[1]))
        return float(d), float(np.linalg.norm(Xi))

    def params_for(self, H) -> np.ndarray:
        """``[L_w L_u]`` the impulses H leave (data units): the fixed predictor, or the least-squares fit."""
        if self.L_fixed is not None:
            return self.L_fixed.copy()
        return np.linalg.lstsq(self.A.T, (self.Yf - self._conv(H)).T, rcond=None)[0].T

    def evaluate_dual(self, V, W, sigma=None) -> float:
        """The weak-duality lower bound of :class:`Certificate` for any ``V`` (i, j) and ``W``."""
        sigma = self.sigma if sigma is None else float(sigma)
        if not self.siso:
            return self.column_form(scaled=False).lower_bound(V, W, rho=sigma * np.sqrt(self.n_noise))
        return self.column_form(scaled=False).lower_bound(V, W, rho=sigma * np.sqrt(self.Uf.size))


def _small_ball_solve(P, options: dict, time_limit, tol) -> SolverOutput:
    """(7.5) with one channel and a noise ball far inside the least-squares residual
    (:func:`~unfalsify.solvers.wider_ball.small_ball`): the primal–dual method first, then, if it does not certify,
    the barrier method, keeping the best primal and dual points of the two (:func:`~unfalsify.solvers.combine.best_of`).

    There the barrier's noise term is far more curved than its LMIs and its Newton steps crawl.  Measured, servo data,
    L optimised, tol 1e-4: at (i, j) = (4, 38) and σ = 1e-8 or 1e-9 × the rms (seeds 0–7) the primal–dual method
    certified 16 of 16 records in 8–9 iterations (≤ 0.1 s), where the barrier took 150–500 Newton steps and did not
    certify 11; at (20, 400) and σ = 1e-5 × the rms it certified in 21 iterations (6–8 s), where the barrier crawled
    until a 300 s time limit.  A warm start is not used on this route."""
    options = {k: v for k, v in options.items() if k != "warm_start"}
    first = run("column_pd", P, **options)
    if first.status == "optimal":
        return dataclasses.replace(first, stats=dict(first.stats, route="primal_dual: a noise ball far inside the "
                                                                         "residual"))
    left = None if time_limit is None else float(time_limit) - first.solve_time
    if left is not None and left <= 0.0:
        return first
    return best_of(P, [first, run("column_barrier", P, **dict(options, time_limit=left))], tol=float(tol))


#: A warm start resumes from the last centred point of the earlier solve whose relative gap ν/(tδ) is at least this.
#: Measured at (20, 400), seeds 0–4, windows advanced by 1, 10 and 50 samples, both L modes (Newton steps of the
#: warm solve, its abandoned warm path included, over the cold solve's): 0.3 (the centring at gap ≈ 0.5) gives means
#: 0.69–0.82 and at most 1.03; 0.1 (the centring at gap ≈ 0.12) gave means 0.77–1.45 and up to 3.43, where 5 of the
#: 30 warm paths stalled and re-solved cold and one crawled.  At (50, 500) with L fixed the old rule cost 3.2–4.0
#: cold solves (every warm path re-solved cold), the new one 0.91–1.16.
_WARM_GAP = 0.3


def _window_shift(old: SubspaceProblem, new: SubspaceProblem) -> int | None:
    """The k ≥ 0 with ``new`` samples ``0…`` equal to ``old`` samples ``k…`` (u and y, over their overlap), or None.

    Exact equality: a window advanced on the same record holds the very same floats.  Candidates are the
    samples of the old record equal to the new first one (few: y is not quantised), each checked in O(n).
    """
    zo = np.hstack([old.u.reshape(old.u.shape[0], -1), old.y.reshape(old.y.shape[0], -1)])
    zn = np.hstack([new.u.reshape(new.u.shape[0], -1), new.y.reshape(new.y.shape[0], -1)])
    if zo.shape[1] != zn.shape[1]:
        return None
    for k in np.flatnonzero(np.all(zo == zn[0], axis=1)):
        n = min(zn.shape[0], zo.shape[0] - int(k))
        if np.array_equal(zo[k : k + n], zn[:n]):
            return int(k)
    return None


def _fixed_predictor(predictor, i: int, m: int, l: int) -> np.ndarray:
    """``[L_w L_u]`` of a given predictor, checked against data of horizon ``i``, ``m`` inputs and ``l`` outputs:
    :class:`InputTypeError` for an object that is no predictor, :class:`DataError` for another horizon, other
    channels or non-finite entries (the window check of :func:`unfalsify.estimate_delta` uses it too)."""
    if not all(hasattr(predictor, name) for name in ("Lw", "Lu", "horizon")):  # by what it offers, not its class
        raise InputTypeError(f"predictor must be a synthesis.Predictor (synthesis.fit_predictor(u, y, {i})), "
                             f"got {type(predictor).__name__}")
    L = np.hstack([np.asarray(predictor.Lw, float), np.asarray(predictor.Lu, float)])
    if int(predictor.horizon) != i or L.shape != (i * l, i * (2 * m + l)) or not np.all(np.isfinite(L)):
        raise DataError(
            f"predictor must be a finite predictor of horizon {i} for {m} input(s) and {l} output(s) "
            f"(Lw {i * l}×{i * (m + l)}, Lu {i * l}×{i * m}); got horizon {predictor.horizon}, [Lw Lu] of "
            f"shape {L.shape} (fit it on the same data: synthesis.fit_predictor(u, y, {i}))"
        )
    return L


def _warm_state(prev, P: SubspaceProblem, name: str) -> tuple[dict | None, str]:
    """The warm start of solver ``name`` for problem ``P`` from the earlier result ``prev``, and the start note.

    Raises :class:`DataError` for a ``prev`` that cannot belong to this kind of problem (not a
    :class:`SubspaceResult`, another horizon or other channels, impulses of the wrong shape); returns
    ``(None, "cold (warm start not used: …)")`` for one this solver cannot use.  A window advanced by k
    samples shifts the Hankel columns by k: old columns ``k…`` are the new columns ``0…``, the new last
    columns are NaN (the solver gives them ridge impulses capped at the old δ).
    """
    if not isinstance(prev, SubspaceResult):
        raise DataError(f"warm_start must be the SubspaceResult of an earlier subspace_unfalsify call; got "
                        f"{type(prev).__name__} (pass that result, or warm_start=None)")
    i, m, l = P.horizon, P.n_inputs, P.n_outputs
    if prev.horizon != i:
        raise DataError(f"warm_start comes from a solve with horizon {prev.horizon}, this one has horizon {i}: pass "
                        f"the result of a solve with horizon={i}, or warm_start=None")
    if (prev.n_inputs, prev.n_outputs) != (m, l):
        raise DataError(f"warm_start comes from data with {prev.n_inputs} input(s) and {prev.n_outputs} output(s), "
                        f"these have {m} and {l}: pass the result of a solve on the same channels, or warm_start=None")
    shape = (i, prev.n_columns) if P.siso else (i, l, m, prev.n_columns)
    if np.shape(prev.impulses) != shape:
        raise DataError(f"warm_start.impulses has shape {np.shape(prev.impulses)}, not {shape} (horizon {i}, its "
                        f"{prev.n_columns} columns): pass a SubspaceResult as subspace_unfalsify returned it")

    def cold(why):
        return None, f"cold (warm start not used: {why})"

    if name != "column_barrier":
        return cold(f"solver {name!r} has no warm start; it needs backend='structured' on one channel "
                    "without executor=")
    if not (np.isfinite(prev.delta) and np.all(np.isfinite(prev.impulses))):
        return cold("the earlier solve has no finite δ")
    old = getattr(prev.certificate, "problem", None)
    k = _window_shift(old, P) if isinstance(old, SubspaceProblem) else None
    if k is None:
        return cold("these data do not continue the earlier window (its samples k… are not this window's first "
                    "samples for any k)")
    j, jp = P.n_columns, prev.n_columns
    if k >= jp:
        return cold(f"the window advanced by {k} samples, at least the {jp} columns of the earlier one: none in common")
    path = list((prev.solver_stats.get("state") or {}).get("path") or [])
    # resume from the last centred point at least _WARM_GAP from the optimum: close enough to save the path's
    # early centrings, far enough inside for the changed problem (the last one hugs the boundaries)
    state = next((dict(c) for c in reversed(path) if c["gap"] >= _WARM_GAP), dict(path[0]) if path else {})
    if not {"H", "d", "gap", "psi"} <= state.keys():
        # no barrier path (e.g. a cvxpy result): its optimum, resumed at the same gap as a path point would be,
        # with slacks as large as those of the path's centre there (an optimum hugs its boundaries, and a
        # resume at its own tiny gap stalled in the tests)
        cert = prev.certificate
        psi = 1.0 - (cert.noise_norm / cert.noise_bound) ** 2 if cert.noise_bound > 0 else 0.0
        state = dict(H=prev.impulses, d=prev.delta, gap=_WARM_GAP, psi=max(psi, 1e-3), slack=1e-3)
    H = np.full((i, j), np.nan)
    c = min(j, jp - k)
    H[:, :c] = np.asarray(state["H"], float)[:, k : k + c]
    state["H"] = H
    return state, ("warm (same window)" if k == 0 else f"warm (window advanced by {k} sample{'s' if k > 1 else ''})")


def subspace_unfalsify(
    u,
    y,
    horizon: int,
    sigma: float,
    *,
    form: str = "conditioned",
    eliminate_L: bool = False,
    predictor=None,
    solver: str = "CLARABEL",
    solver_options: dict | None = None,
    backend: str = "cvxpy",
    method: str = "barrier",
    tol: float = 1e-6,
    time_limit: float | None = None,
    progress: bool = True,
    executor=None,
    workers: int | None = None,
    warm_start: SubspaceResult | None = None,
) -> SubspaceResult:
    """Smallest δ bounding the column operators ``Δ_k`` that unfalsify the subspace model: (7.5).

    Parameters
    ----------
    u : array_like, shape (n,) or (n, m)
    y : array_like, shape (n,) or (n, l)
        Data, time along axis 0; ``j = n − 2i + 1`` columns.  Several channels: see the module
        docstring (cvxpy backend, conditioned form).
    horizon : int
        The prediction horizon i.
    sigma : float
        Admissible rms noise level σ > 0 of Ξ (units of y).
    form : {"conditioned", "thesis"}
        See the module docstring (``"thesis"``: cvxpy backend only).
    eliminate_L : bool
        cvxpy conditioned form: eliminate ``[L_w L_u]`` analytically.  (The structured backend
        always eliminates L by projection.)
    predictor : synthesis.Predictor, optional
        Fix ``[L_w L_u]`` to a given predictor of horizon i (the data's channels) and compute the δ of that model:
        (7.5) with L a constant.  Default: L is optimised jointly, as in the thesis.
    solver, solver_options
        cvxpy backend: solver (passed explicitly) and extra ``Problem.solve`` arguments.
    backend : {"cvxpy", "structured"}
        See :func:`unfalsify.arx_unfalsify`; ``"structured"`` is the solver ``"column_barrier"`` of
        :mod:`unfalsify.solvers` (``"block_barrier"`` for several channels).
    method : {"barrier", "primal_dual"}
        Structured backend, one channel: the barrier method (``"column_barrier"``, default) or the primal–dual
        interior-point method (``"column_pd"``: NT scaling and Mehrotra's predictor–corrector, fewer iterations
        that each cost several barrier Newton steps; the same certificate and stop).  With ``"barrier"``, a noise
        ball below 1e-4 of the least-squares residual (σ far below its rms) is solved by the primal–dual method first,
        where the barrier's steps crawl, and by the barrier too if that does not certify; the best primal and dual
        points of the two are kept (``solver_stats["route"]``, ``solver_stats["combined"]``).
    tol, time_limit, progress
        Structured backend, as for :func:`unfalsify.arx_unfalsify`.
    executor : concurrent.futures.Executor, optional
        With ``predictor`` fixed, (7.5) splits by columns: blocks of columns are solved as tasks
        on this executor (local processes, ``distributed.Client.get_executor()``, …) and the
        one-dimensional outer problem in δ here (solver ``"split"``, :mod:`unfalsify.solvers.split`);
        ``backend`` is then ignored and the result's ``backend`` is ``"split"``.  Same δ and certificate
        as serial.
    workers : int or None
        Structured backend: threads over the column stack (default ``None``: every core,
        ``os.cpu_count()``).  BLAS is held to one thread for the whole call (set-up, solve and
        certificate), so the threads do not compete with BLAS's own and ``workers=1`` uses one
        core; the result equals the one-thread solve up to the order of floating-point sums.  One
        channel only: the solver for several channels (``block_barrier``) runs on one thread and
        ignores it.
    warm_start : SubspaceResult, optional
        An earlier result on related data: the same record with the window advanced by k ≥ 0 samples
        (found by matching the samples; its Hankel columns ``k…`` are this window's columns ``0…``), the
        same window at another σ, or both.  The structured backend (one channel, ``column_barrier``)
        resumes the barrier path from a centred point of that solve (the last one at relative gap ≥ 0.3),
        made strictly feasible for the new problem, instead of from the cold start; new columns get ridge
        impulses capped at the old δ.  The stop is the same certified gap, so the result equals a cold
        solve's to ``tol``.  A warm start the solver cannot use (another solver, unrelated data, no finite
        δ, a resumed path that stalls, or whose centrings stop converging twice, and is re-solved cold) says
        why in the result's ``start``.  It saves Newton steps for small changes (a few samples, a nearby σ);
        after larger advances it can cost as much as a cold solve, and a path given up costs about 1.5×.  A
        result of the cvxpy backend can warm-start the structured one.

    Returns
    -------
    SubspaceResult
        With a two-sided :class:`Certificate`.

    Raises
    ------
    DataError
        NaN/inf, lengths, time along axis 1 (the message names ``u.T``), bad horizon / too few samples,
        σ ≤ 0; columns of ``U_f`` starting with a zero input whose first outputs need more noise than σ√N holds
        (the message gives the least σ), or such columns with ``form="thesis"``; a solve
        whose estimated memory (:func:`~unfalsify.solve_estimate`) exceeds half the memory available (the message
        names a shorter window, and the other backend where it needs less).
    UnknownSolverError
        Unknown backend or method (a ``ValueError``; the message lists the valid names), several channels with
        ``executor=`` (the message names ``backend="cvxpy"``) or with ``method="primal_dual"`` (the message names
        ``method="barrier"``).
    DataError
        ``warm_start`` that is not a :class:`SubspaceResult` of this horizon and these channels (the message
        names the fix).
    ValueError
        Unknown form (``form="thesis"`` with several channels); incompatible options.
    UnfalsificationError
        cvxpy: solver failure or infeasible/unbounded status.

    Warns
    -----
    SolverWarning, IllConditionedWarning
        As for :func:`unfalsify.arx_unfalsify`.
    LongSolveWarning
        A solve estimated above :data:`unfalsify.cost.LONG_SOLVE_SECONDS` (60 s; :func:`~unfalsify.solve_estimate`).

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(40)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:40] + 0.05 * rng.standard_normal(40)
    >>> sub = subspace_unfalsify(u, y, 3, 0.02)                      # i = 3, j = 35 columns
    >>> sub.status, sub.impulses.shape, bool(sub.certificate.verify())
    ('optimal', (3, 35), True)
    >>> fast = subspace_unfalsify(u, y, 3, 0.02, backend="structured", progress=False)
    >>> bool(abs(fast.delta - sub.delta) <= 1e-4 * sub.delta)
    True

    The window advanced by 5 samples, re-solved from the solve above (same certified tolerance):

    >>> nxt = subspace_unfalsify(u[5:], y[5:], 3, 0.02, backend="structured", progress=False, warm_start=fast)
    >>> nxt.start, bool(nxt.certificate.verify())
    ('warm (window advanced by 5 samples)', True)
    """
    form = check_form(form)
    eliminate_L, progress = check_flag(eliminate_L, "eliminate_L"), check_flag(progress, "progress")
    solver_options = check_solver_options(solver_options)
    # here, not in SubspaceProblem.from_data: that one takes any object with Lw, Lu and horizon (tests build them)
    predictor = check_predictor(predictor)
    name = resolve("subspace", backend, method)
    if backend == "structured" and form != "conditioned":
        raise DataError("backend='structured' solves the conditioned form; use form='conditioned'")
    if form == "thesis" and eliminate_L:
        raise DataError("eliminate_L applies to form='conditioned' only")
    if predictor is not None and eliminate_L:
        raise DataError("eliminate_L and a fixed predictor exclude each other")
    workers = check_workers(workers)
    # the structured solvers' set-up and certificate as well as the solve: BLAS held to one thread (one_blas_thread)
    structured = executor is None and name in ("column_barrier", "block_barrier", "column_pd")
    with one_blas_thread() if structured else contextlib.nullcontext():
        P = SubspaceProblem.from_data(u, y, horizon, sigma, predictor=predictor)
        i, j, m, l = P.horizon, P.n_columns, P.n_inputs, P.n_outputs
        if not P.siso and form != "conditioned":
            raise DataError(f"form='thesis' is written for one channel; with {m} input(s) and {l} output(s) use "
                             "form='conditioned'")
        if not P.siso and name == "column_barrier":
            name = "block_barrier"  # the structured solver for several channels
        if name == "column_pd" and not P.siso:
            raise UnknownSolverError(f"method='primal_dual' of (7.5) solves single-channel data only; for {l}×{m} "
                                     "data use method='barrier' (solver 'block_barrier') or backend='cvxpy'")
        zero_cols = P.zero_start_columns
        if zero_cols.size and form == "thesis":
            raise DataError(f"form='thesis' recovers h_k by inverting T((U_f)_{{:,k}}), which {zero_cols.size} "
                            f"column(s) starting with a zero input make singular (first: column {zero_cols[0]}); "
                            "form='conditioned' solves them exactly (their first outputs are noise)")
        if form == "thesis" and not P.cond_Tu <= COND_WARN:
            warnings.warn(
                f"form='thesis' with max_k cond T((U_f)_k) = {P.cond_Tu:.3g}: the literal LMI is numerically "
                "singular; prefer form='conditioned'",
                IllConditionedWarning,
                stacklevel=2,
            )
        rank = np.linalg.matrix_rank(P.scaled_A()) if predictor is None else 0  # the rule of _row_basis
        if rank >= j:
            warnings.warn(
                f"(7.5) with L optimised on j = {j} columns: [W_p; U_f] has rank {rank} ≥ j, so a predictor fits "
                "every column exactly and δ = 0 for any σ (the data cannot falsify anything); use a longer record "
                f"(more than {rank} columns: n > {rank + 2 * i - 1} samples) or fix the predictor (predictor=..., "
                "fitted on a longer record)",
                FewDataWarning,
                stacklevel=2,
            )
        if executor is not None:  # a split solve's cost is its executor's, per column block: no guard here
            if predictor is None or form != "conditioned":
                raise DataError("executor= splits (7.5) by columns, which needs the predictor fixed and "
                                "form='conditioned': pass predictor=... (e.g. synthesis.fit_predictor(u, y, i))")
            name, backend, options = "split", "split", dict(executor=executor)
        elif name == "cvxpy":
            _guard_subspace(i, j, "cvxpy", (m, l))
            options = dict(form=form, solver=solver, solver_options=solver_options, eliminate_L=eliminate_L)
        else:
            _guard_subspace(i, j, "structured", (m, l))
            options = dict(tol=tol, time_limit=time_limit, progress=progress, workers=workers)
        start = "cold"
        if warm_start is not None:
            state, start = _warm_state(warm_start, P, name)
            if state is not None:
                options["warm_start"] = state
        if name == "column_barrier" and small_ball(P.column_form(scaled=True)):
            out = _small_ball_solve(P, options, time_limit, tol)
            if "warm_start" in options:
                start = "cold (warm start not used: a noise ball far inside the residual takes the primal–dual route)"
        else:
            out = run(name, P, **options)
        note = out.stats.get("warm")
        if note is not None and note != "used":
            start = f"cold (warm start not used: {note})"
        out = into_ball(P, out)
        cert, delta = certify(P, out, f"subspace unfalsification ({'' if P.siso else f'{l}×{m}, '}i={i}, j={j})")
        L = out.params
        w = i * (m + l)  # columns of L_w
        return SubspaceResult(
            delta=delta,
            Lw=L[:, :w].copy(),
            Lu=L[:, w:].copy(),
            noise=P.Yf - L @ P.A - P._conv(out.impulses),
            impulses=out.impulses,
            status=out.status.value,
            solve_time=out.solve_time,
            problem=out.problem,
            form=form,
            eliminate_L=bool(eliminate_L and form == "conditioned"),
            sigma=P.sigma,
            horizon=i,
            n_columns=j,
            cond_Tu=P.cond_Tu,
            certificate=cert,
            scale=P.scale,
            regressor_singular_values=np.linalg.svd(P.A, compute_uv=False),
            backend=backend,
            n_inputs=m,
            n_outputs=l,
            start=start,
            solver_stats=dict(out.stats),
        )
