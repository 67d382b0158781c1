"""ARX uncertainty-model unfalsification, thesis §7.2 and program (7.4).

Model (7.3): ``A(q) y − B(q) u = e(θ) = ξ + Δ(q) u`` with ``e(θ) = Φθ + Y`` (§7.2.1, system at
rest before t = 0), noise ``‖ξ‖_rms = ‖ξ‖₂/√n ≤ σ`` and ``Δ`` causal LTI.  By Theorem 7.1 the
smallest ``‖Δ‖∞`` that unfalsifies the data is

    δ = min_{δ, θ, ξ} δ   s.t.   T(e(θ) − ξ)ᵀ T(e(θ) − ξ) ⪯ δ² T(u)ᵀ T(u).            (7.4)

Two cvxpy formulations of the same program:

``form="conditioned"`` (default)
    Substitute ``e − ξ = T(u) h`` (exact when ``u₀ ≠ 0``: ``T(e − ξ) = T(h) T(u)`` because
    lower-triangular Toeplitz matrices commute, so the inequality is ``‖T(h)‖₂ ≤ δ``).
    Variables θ, h, δ; constraints ``[δI T(h)ᵀ; T(h) δI] ⪰ 0`` (2n×2n) and the cone
    ``‖Φθ + Y − T(u) h‖₂ ≤ σ√n``.  Only multiplies by ``T(u)``; never inverts it.
``form="thesis"``
    The literal LMIs of §7.2.2, ``[σ ξᵀ/√n; ξ/√n σI] ⪰ 0`` and
    ``[δ T(u)ᵀT(u) T(e−ξ)ᵀ; T(e−ξ) δI] ⪰ 0``.  Kept for fidelity; ``T(u)ᵀT(u)`` has condition
    number ``cond(T(u))²`` (≈ 1e17 at n = 40 for a ±1 PRBS) so the solver's answer cannot be
    trusted in the near-null directions of ``T(u)`` -- see the result's ``certificate``.

The tempting substitution ``h = T(u)⁻¹(e − ξ)`` is not offered: it inverts ``T(u)`` and is
wrong by orders of magnitude for n ≥ 40 (measured: Clarabel δ = 1.31 instead of 0.0861 at n = 80,
SCS δ = 6.3 instead of 0.170 at n = 40).

Several channels (u: (n, m), y: (n, l), time along axis 0; issue 28)
    Δ is a causal LTI operator with l outputs and m inputs and l × m Markov parameters h_0 … h_{n−1}.
    The data relation is linear in h, ``e_s − ξ_s = Σ_{t≤s} h_t u_{s−t}`` (samples stacked:
    ``vec(E − Ξ) = T(h)u = M(u)h``), and the least H∞ norm of a causal Δ with those Markov parameters
    is ``‖T(h)‖₂``, T(h) the nl × nm block lower-triangular Toeplitz matrix (matrix Carathéodory–Fejér:
    ``‖Δ‖∞ ≥ ‖T(h)‖₂`` because T(h) is a compression of the multiplication operator of Δ, with equality
    attained by a suitable extension of h).  So (7.4) becomes

        δ = min δ  s.t.  ‖T(h)‖₂ ≤ δ,   ‖vec(ΦΘ + Y) − M(u)h‖₂ ≤ σ√((n − free_rows)·l),

    the conditioned form with ``[δI_nm T(h)ᵀ; T(h) δI_nl] ⪰ 0``.  The noise ball is one Frobenius ball
    ``‖Ξ‖_F ≤ σ√(N·l)`` (N = n − free_rows non-free rows): σ is the rms of every entry of the noise,
    pooled over the outputs, as in (7.5)'s ``σ√(ilj)``.  ``form="thesis"`` is written for one channel.

    Multi-output equation-error ARX is included because it extends at no cost: with
    ``e_t = y_t + Σ_k A_k y_{t−k} − Σ_k B_k u_{t−k}`` (A_k l × l, B_k l × m, fully coupled) the model
    directions are ``{ΦΘ}``, Θ = [A₁ᵀ; …; B_nbᵀ] (:func:`arx_regressor`), i.e. the same subspace range Φ
    acting on each output column, and every solver only ever projects onto its complement (``range(Q ⊗ I_l)``
    in the stacked vectors).  It is useful as the multi-output generalisation of the thesis' ARX test of a
    fitted model, and na = nb = 0 with free rows is the output-error premise test of the §7.4 pipeline
    (:func:`unfalsify.output_error_unfalsify`).  Not offered: structured A(q) (diagonal, or common
    denominators), which would make 𝓛 depend on the output and lose the Kronecker form.

    The lower bound (weak duality), as for one channel (:class:`~unfalsify.solvers.columns.BlockColumnForm`
    with i = n, j = 1).  Write ``T*`` for the adjoint of h ↦ T(h) (``T*(W)_d`` the sum of the d-th block
    subdiagonal of W) and ``M*`` for that of h ↦ M(u)h (``(M*v)_t = Σ_{s≥t} v_s u_{s−t}ᵀ``).  For ANY v (nl)
    and ANY W (nl × nm): (1) project v off ``range(Q ⊗ I_l)`` (Q an orthonormal basis of range Φ, the
    free rows included), so ``⟨v, vec(ΦΘ)⟩ = 0``; (2) add ``T(c)``, ``c_d = ((M*v)_d − T*(W)_d)/(n − d)``,
    to W, so that ``T*(W) = M*v`` exactly; (3) for every feasible (δ, h, Θ, ξ),
    ``⟨v, M(u)h⟩ = ⟨M*v, h⟩ = ⟨T*(W), h⟩ = ⟨W, T(h)⟩ ≤ ‖W‖_* ‖T(h)‖₂ ≤ δ‖W‖_*`` and
    ``⟨v, M(u)h⟩ = ⟨v, vec(ΦΘ + Y) − ξ⟩ ≥ ⟨v, vec Y⟩ − σ√(N·l)‖v‖₂``; hence

        δ ≥ (⟨v, vec Y⟩ − σ√(N·l)‖v‖₂) / ‖W‖_*     (and δ ≥ 0),

    for any (v, W), exact or not.  The solvers' (v, W) are the noise cone's multiplier along ξ and
    ``W = −2 Z21`` of the LMI multiplier Z (cvxpy), or the Newton-linearised central-path point
    (:mod:`unfalsify.solvers.arx_barrier`); the certificate recomputes the bound from them and the data.
    With one channel each the SISO code runs unchanged.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import ClassVar

import cvxpy as cp
import numpy as np

from synthesis import DataError
from synthesis.validation import check_count, check_flag, check_inputs_move, check_output_moves
from synthesis.results import result

from ._common import (COND_WARN, Certificate, certify, channel_pair, check_form, check_noise_floor,
                      check_noise_resolution, check_sigma, check_solver_options, into_ball, rms_or_one)
from .cost import _guard_arx
from .exceptions import IllConditionedWarning, NotAtRestWarning, UnknownSolverError
from .solvers import CHANNELS, resolve, run
from .solvers.arx_barrier import ArxBlockForm
from .solvers.columns import ColumnForm
from .solvers.toeplitz import (block_certified_norm, block_conv_cols, certified_norm, conv_cols, signal_toeplitz,
                               toeplitz_cond)

__all__ = ["ArxProblem", "ArxResult", "arx_unfalsify", "arx_regressor", "arx_least_squares"]


@result
@dataclass(frozen=True, eq=False)
class ArxResult:
    """Solution of the ARX unfalsification program (7.4).

    Attributes
    ----------
    delta : float
        δ_unf, the smallest ``‖Δ‖∞`` (NaN if the solve failed).
    theta : ndarray, shape (na + nb + free_rows,)
        ``[a₁ … a_na, b₁ … b_nb]`` (§7.2.1), followed by the free equation errors of the first
        ``free_rows`` rows when there are any.  Several channels: Θ of shape
        (na·l + nb·m + free_rows, l), ``[A₁ᵀ; …; A_naᵀ; B₁ᵀ; …; B_nbᵀ; free rows]`` (:func:`arx_regressor`).
    noise : ndarray, shape (n,)
        ξ.  For the conditioned form ``ξ = Φθ + Y − T(u) h`` exactly.  Several channels: (n, l).
    impulse : ndarray, shape (n,)
        h, the first n Markov parameters of Δ: ``e − ξ = T(u) h`` (for the thesis form
        recomputed from ξ in exact rational arithmetic).  Several channels: (n, l, m), ``impulse[t]``
        the l × m Markov parameter h_t.
    status : str
        cvxpy status (``"optimal"``, ``"optimal_inaccurate"``, ...), or for the structured backend
        ``"optimal"``, ``"time_limit"``, ``"interrupted"``, ``"max_iter"``, ``"failed"``.
    solve_time : float
        Wall time of the solve in seconds (cvxpy: ``problem.solve``, incl. compilation).
    problem : cvxpy.Problem or None
        The cvxpy problem as solved (in scaled units, see ``scale``); None for the structured backend
        (the data are in ``certificate.problem``, an :class:`ArxProblem`).  A by-product: not
        compared by ``==``, and stored as None when the result is pickled (a cvxpy problem holds a
        solver object that does not pickle); everything else, the certificate included, survives.
    form : str
        ``"conditioned"`` or ``"thesis"``.
    sigma : float
        Admissible rms noise level σ.
    na, nb : int
        Orders of ``A(q)`` and ``B(q)``.
    cond_Tu : float
        cond₂ ``T(u)`` (several inputs: of the nm × n block Toeplitz signal matrix, as in
        :func:`unfalsify.unfalsified_gain_result`).
    certificate : Certificate
        Two-sided certificate: ``upper_bound = ‖T(h)‖₂`` and the noise recomputed from
        ``(theta, impulse)``, ``lower_bound`` from the dual point; ``verify()`` recomputes both.
    scale : tuple of float
        ``(s_u, s_y)``: the problem was posed on ``u/s_u`` and ``y/s_y`` (``s_u`` = rms of u,
        ``s_y`` = rms of the least-squares equation error).
    backend : str
    n_inputs, n_outputs : int
        m and l (1 and 1 for SISO data).
    solver_stats : dict
        The solver's counts where it keeps them (``newton``, ``outer``; ``trials``: Cholesky factorisations tried
        by ``arx_barrier``; ``factorisations`` by ``arx_pd``); empty for cvxpy.
    """

    delta: float
    theta: np.ndarray
    noise: np.ndarray
    impulse: np.ndarray
    status: str
    solve_time: float
    problem: cp.Problem | None = field(compare=False)
    form: str
    sigma: float
    na: int
    nb: int
    cond_Tu: float
    certificate: Certificate
    scale: tuple
    backend: str = "cvxpy"
    n_inputs: int = 1
    n_outputs: int = 1
    solver_stats: dict = field(default_factory=dict, compare=False)

    @property
    def a(self) -> np.ndarray:
        """``[a₁ … a_na]``; several channels: the stack (na, l, l) of A₁ … A_na."""
        if self.theta.ndim == 2:
            l = self.n_outputs
            return self.theta[: self.na * l].reshape(self.na, l, l).transpose(0, 2, 1)
        return self.theta[: self.na]

    @property
    def b(self) -> np.ndarray:
        """``[b₁ … b_nb]``; several channels: the stack (nb, l, m) of B₁ … B_nb."""
        if self.theta.ndim == 2:
            l, m, k = self.n_outputs, self.n_inputs, self.na * self.n_outputs
            return self.theta[k : k + self.nb * m].reshape(self.nb, m, l).transpose(0, 2, 1)
        return self.theta[self.na : self.na + self.nb]

    @property
    def max_violation(self) -> float:
        """Shortcut for ``certificate.max_violation``."""
        return self.certificate.max_violation


def _order(v, name: str) -> int:
    return check_count(v, name, 0)


def arx_regressor(u, y, na: int, nb: int) -> tuple[np.ndarray, np.ndarray]:
    """``(Φ, Y)`` of §7.2.1 with zero initial conditions, so that ``e(θ) = Φθ + Y``.

    Row t of Φ is ``[y_{t−1} … y_{t−na}, −u_{t−1} … −u_{t−nb}]`` (samples before t = 0 are zero).
    Several channels (u (n, m), y (n, l)): row t is ``[y_{t−1}ᵀ … y_{t−na}ᵀ, −u_{t−1}ᵀ … −u_{t−nb}ᵀ]``
    (na·l + nb·m columns) and Y is (n, l), so ``e(Θ) = ΦΘ + Y`` with ``Θ = [A₁ᵀ; …; A_naᵀ; B₁ᵀ; …; B_nbᵀ]``
    (the multi-output equation error ``e_t = y_t + Σ A_k y_{t−k} − Σ B_k u_{t−k}``).

    Raises
    ------
    DataError
        Bad data, orders that are not integers ≥ 0, or a record of no more than ``max(na, nb)`` samples.

    Examples
    --------
    >>> Phi, Y = arx_regressor([1.0, 2.0, 3.0], [0.5, 1.0, 1.5], 1, 2)
    >>> Phi.tolist()                       # rows [y_{t−1}, −u_{t−1}, −u_{t−2}]
    [[0.0, 0.0, 0.0], [0.5, -1.0, 0.0], [1.0, -2.0, -1.0]]
    >>> Y.tolist()
    [0.5, 1.0, 1.5]
    >>> import numpy as np
    >>> Phi, Y = arx_regressor(np.ones((3, 2)), np.ones((3, 3)), 1, 1)      # m = 2 inputs, l = 3 outputs
    >>> Phi.shape, Y.shape                                                  # na·l + nb·m = 5 columns
    ((3, 5), (3, 3))
    """
    u, y = channel_pair(u, y)
    na, nb = _order(na, "na"), _order(nb, "nb")
    n = u.shape[0]
    if n <= max(na, nb):
        # a lag of n or more reaches no sample of the record (its column is zero); beyond n numpy broadcast
        raise DataError(f"the record has n = {n} samples but the lags reach back max(na, nb) = {max(na, nb)}: record "
                        f"at least {max(na, nb) + 1} samples or lower the orders (na = {na}, nb = {nb})")
    if u.ndim == 2:
        m, l = u.shape[1], y.shape[1]
        Phi = np.zeros((n, na * l + nb * m))
        for k in range(1, na + 1):
            Phi[k:, (k - 1) * l : k * l] = y[: n - k]
        for k in range(1, nb + 1):
            Phi[k:, na * l + (k - 1) * m : na * l + k * m] = -u[: n - k]
        return Phi, y.copy()
    Phi = np.zeros((n, na + nb))
    for k in range(1, na + 1):
        Phi[k:, k - 1] = y[: n - k]
    for k in range(1, nb + 1):
        Phi[k:, na + k - 1] = -u[: n - k]
    return Phi, y.copy()


def arx_least_squares(u, y, na: int, nb: int) -> tuple[np.ndarray, float]:
    """Classical ARX (7.2): ``θ = −Φ⁺Y`` and the rms of the residual ``e(θ)``.

    Several channels: ``Θ = −Φ⁺Y`` (na·l + nb·m, l), one least-squares fit per output, and the rms over
    all n·l entries of the residual.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(50)
    >>> y = np.zeros(50)
    >>> for k in range(1, 50):
    ...     y[k] = 0.5 * y[k - 1] + u[k - 1]                # (1 − 0.5q⁻¹) y = q⁻¹ u, no noise
    >>> theta, rms = arx_least_squares(u, y, 1, 1)
    >>> np.round(theta, 6).tolist(), bool(rms < 1e-12)      # θ = [a₁, b₁]
    ([-0.5, 1.0], True)
    """
    Phi, Y = arx_regressor(u, y, na, nb)
    if Phi.shape[1] == 0:
        return np.zeros((0,) + Y.shape[1:]), float(np.linalg.norm(Y) / np.sqrt(Y.size))
    theta = -np.linalg.lstsq(Phi, Y, rcond=None)[0]
    e = Phi @ theta + Y
    return theta, float(np.linalg.norm(e) / np.sqrt(Y.size))


def _warn_if_not_at_rest(u, y, na: int, nb: int, sigma: float) -> None:
    """(7.4) takes the samples before the record as zero (system at rest).  Warn when the first
    ``max(na, nb)`` equation errors of the least-squares model -- the rows that use those zeros --
    are an order of magnitude above both σ and the other rows' errors: the record starts mid-motion."""
    k0 = max(na, nb)
    if k0 == 0 or u.shape[0] <= 2 * k0:
        return
    Phi, Y = arx_regressor(u, y, na, nb)
    theta = -np.linalg.lstsq(Phi[k0:], Y[k0:], rcond=None)[0]
    e = Phi @ theta + Y
    head = float(np.sqrt(np.mean(e[:k0] ** 2)))
    rest = float(np.sqrt(np.mean(e[k0:] ** 2)))
    if head > 10.0 * max(rest, sigma):
        warnings.warn(
            f"the record does not start at rest: the first {k0} equation errors (rms {head:.3g}) use the zero "
            f"samples (7.4) assumes before the record and are {head / max(rest, sigma):.0f}× the others; δ will "
            "be inflated. Start the record at rest, or use the subspace program (7.5), which carries the past "
            "data in W_p", NotAtRestWarning, stacklevel=4)


def _range_basis(Phi: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the numerical range of Φ, cut at the rank rule of ``numpy.linalg.lstsq`` (singular values
    above ``max(Φ.shape)·eps·σ₁``), the fit the certificate's θ comes from.  A QR factor without that cut kept a
    direction of rounding when na, nb exceed the order of noise-free data (cond Φ 1.8e16): the solver then projected
    away more than the certificate's θ can explain and stopped "optimal" with the noise 5e-4 over its bound."""
    U, sv, _ = np.linalg.svd(Phi, full_matrices=False)
    rank = int(np.count_nonzero(sv > max(Phi.shape) * np.finfo(float).eps * (sv[0] if sv.size else 1.0)))
    return U[:, :rank]


@result
@dataclass(frozen=True, eq=False)
class ArxProblem:
    """Program (7.4) on given data: validation, scaling and the independent bounds.

    Build with :meth:`from_data`.  ``evaluate_primal`` and ``evaluate_dual`` are the two sides of
    :class:`Certificate` (data units); ``column_form`` is the scaled program the backends solve:
    ``u/s_u``, ``y/s_y`` with ``s_u`` = rms(u), ``s_y`` = rms of the least-squares equation error.

    ``free_rows`` (default 0): the first ``free_rows`` equation errors are free parameters (appended
    to θ as unit columns of Φ), and the noise budget counts the other rows only, ``σ√(n − free_rows)``.
    That is the program for a record that does not start at rest: whatever the samples before the
    record did to the first rows (Δ's own initial state) is not charged to Δ or to the noise.

    Several channels (u (n, m), y (n, l), ``siso`` False): Θ is (na·l + nb·m + free_rows, l), h is
    (n, l, m), the noise (n, l) and its budget ``σ√((n − free_rows)·l)`` (σ an rms over all entries);
    ``column_form`` is an :class:`~unfalsify.solvers.arx_barrier.ArxBlockForm` (see :func:`arx_unfalsify`).
    """

    u: np.ndarray
    y: np.ndarray
    na: int
    nb: int
    sigma: float
    scale: tuple
    cond_Tu: float
    free_rows: int = 0
    n_inputs: int = 1
    n_outputs: int = 1
    #: which program the solvers see (:data:`unfalsify.solvers.PROGRAMS`)
    program: ClassVar[str] = "arx"

    @classmethod
    def from_data(cls, u, y, na, nb, sigma, free_rows: int = 0) -> "ArxProblem":
        """Validate (raises :class:`DataError`) and scale; u (n,) or (n, m), y (n,) or (n, l)."""
        u, y = channel_pair(u, y)
        na, nb = _order(na, "na"), _order(nb, "nb")
        free_rows = _order(free_rows, "free_rows")
        check_output_moves(y, "the record")  # a zero output had given δ = NaN with status 'optimal'
        sigma = check_sigma(sigma)
        n = u.shape[0]
        m, l = (1, 1) if u.ndim == 1 else (u.shape[1], y.shape[1])
        params = (na * l + nb * m + free_rows) if u.ndim == 2 else (na + nb + free_rows)
        check_noise_resolution(sigma, y[free_rows:].size, y, "y")
        if n <= params:
            what = "na·l + nb·m + free_rows" if u.ndim == 2 else "na + nb + free_rows"
            raise DataError(f"need more samples than parameters: n = {n} <= {what} = {params}; pass a longer "
                            "record or lower the orders")
        # u to unit rms, y so that the least-squares equation error has unit rms: the program splits
        # exactly that error between ξ and Δu (measured: fewer 'optimal_inaccurate')
        su = rms_or_one(u)
        sy = arx_least_squares(u[free_rows:], y[free_rows:], na, nb)[1]
        if free_rows == 0:
            _warn_if_not_at_rest(u, y, na, nb, sigma)
        if not sy > 1e-12 * rms_or_one(y):
            sy = rms_or_one(y)
        if u.ndim == 1 or m == 1:
            cond = toeplitz_cond(u if u.ndim == 1 else u[:, 0])
        else:  # T(u) is nm × n: its singular values (as in unfalsified_gain)
            sv = np.linalg.svd(signal_toeplitz(u), compute_uv=False)
            cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
        problem = cls(u=u, y=y, na=na, nb=nb, sigma=sigma, scale=(su, sy), cond_Tu=cond, free_rows=free_rows,
                      n_inputs=m, n_outputs=l)
        if not np.any(u[0] != 0.0):
            check_inputs_move(u, "the record", each_channel=False)
            form = problem.column_form(scaled=False)
            check_noise_floor(form, sigma, f"the input is zero at t = 0 … {form.leading_zeros()[0] - 1}",
                              "start the record at the first non-zero input sample if the system was at rest before it")
        return problem

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.u.shape[0])

    @property
    def siso(self) -> bool:
        """One input and one output (the SISO code paths)."""
        return self.u.ndim == 1

    @property
    def n_noise(self) -> int:
        """Number of noise entries the budget ``σ√n_noise`` covers: ``(n − free_rows)·l``."""
        return (self.n - int(self.free_rows)) * int(self.n_outputs)

    def regressor(self, scaled: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """``(Φ, Y)`` with ``e(θ) = Φθ + Y``: :func:`arx_regressor` plus one unit column per free row."""
        su, sy = self.scale if scaled else (1.0, 1.0)
        Phi, Y = arx_regressor(self.u / su, self.y / sy, self.na, self.nb)
        if self.free_rows:
            Phi = np.hstack([Phi, np.eye(self.n, self.free_rows)])
        return Phi, Y

    def column_form(self, scaled: bool = True) -> ColumnForm:
        """(7.4) as the column form (C) of :mod:`unfalsify.solvers.columns` (j = 1, 𝓛 = range Φ).

        Several channels: :class:`~unfalsify.solvers.arx_barrier.ArxBlockForm` (i = n, j = 1, the samples
        stacked, 𝓛 = range(Q ⊗ I_l) with Q an orthonormal basis of range Φ)."""
        su, sy = self.scale if scaled else (1.0, 1.0)
        Phi, Y = self.regressor(scaled)
        Q = _range_basis(Phi) if Phi.shape[1] else None
        rho = self.sigma / sy * np.sqrt(self.n_noise)
        if not self.siso:
            m, l = self.n_inputs, self.n_outputs
            return ArxBlockForm((self.u / su).reshape(-1, 1), Y.reshape(-1, 1), rho, n_inputs=m, n_outputs=l,
                                basis=Q)
        return ColumnForm((self.u / su)[:, None], Y[:, None], rho, basis_left=Q)

    def _conv(self, h) -> np.ndarray:
        """``T(u)h`` (the ``Δu`` of the data relation): (n,), or (n, l) for several channels."""
        if self.siso:
            return conv_cols(self.u[:, None], h[:, None])[:, 0]
        m, l = self.n_inputs, self.n_outputs
        return block_conv_cols(self.u.reshape(-1, 1), h.reshape(self.n, l, m, 1), m).reshape(self.n, l)

    def noise(self, h, theta) -> np.ndarray:
        """``ξ = Φθ + Y − T(u)h`` (data units): (n,), or (n, l) for several channels."""
        Phi, Y = self.regressor()
        return (Phi @ theta if Phi.shape[1] else 0.0) + Y - self._conv(h)

    def evaluate_primal(self, h, theta, near=None) -> tuple[float, float]:
        """``(‖T(h)‖₂, ‖Φθ + Y − T(u)h‖₂)`` recomputed from the data (inf/NaN for non-finite input).

        ``‖T(h)‖₂`` is a proven upper bound (:func:`~unfalsify.solvers.toeplitz.certified_norm`); ``near``, a
        value just above it such as the reported δ, makes its route above n = 4000 fast (one channel) and is
        never trusted."""
        if self.siso:
            h = np.asarray(h, float).reshape(-1)
            theta = np.asarray(theta, float).reshape(-1)
        else:
            h = np.asarray(h, float).reshape(self.n, self.n_outputs, self.n_inputs)
            theta = np.asarray(theta, float).reshape(-1, self.n_outputs)
        if not (np.all(np.isfinite(h)) and np.all(np.isfinite(theta))):
            return float("inf"), float("nan")
        xi = self.noise(h, theta)
        norm = certified_norm(h, near) if self.siso else block_certified_norm(h)
        return norm, float(np.linalg.norm(xi))

    def params_for(self, h) -> np.ndarray:
        """θ of the least-squares fit of ``e(θ) = T(u)h`` (data units): the model the impulses h leave."""
        Phi, Y = self.regressor()
        if not Phi.shape[1]:
            return np.zeros((0,) + Y.shape[1:])
        if not self.siso:
            h = np.asarray(h, float).reshape(self.n, self.n_outputs, self.n_inputs)
        return -np.linalg.lstsq(Phi, Y - self._conv(h), rcond=None)[0]

    def evaluate_dual(self, v, W, sigma=None) -> float:
        """The weak-duality lower bound of :class:`Certificate` for any ``v`` (n,) (n·l for several
        channels, the samples stacked) and ``W`` (n × n; nl × nm)."""
        sigma = self.sigma if sigma is None else float(sigma)
        return self.column_form(scaled=False).lower_bound(v, W, rho=sigma * np.sqrt(self.n_noise))


def arx_unfalsify(
    u,
    y,
    na: int,
    nb: int,
    sigma: float,
    *,
    form: str = "conditioned",
    solver: str = "CLARABEL",
    solver_options: dict | None = None,
    backend: str = "cvxpy",
    tol: float = 1e-6,
    time_limit: float | None = None,
    progress: bool = True,
    method: str = "barrier",
    free_rows: int = 0,
) -> ArxResult:
    """Smallest ``‖Δ‖∞`` unfalsifying the ARX model (7.3) with ``‖ξ‖_rms ≤ σ``: program (7.4).

    Parameters
    ----------
    u, y : array_like, shape (n,) or (n, m) and (n, l)
        Data, time along axis 0, system at rest before t = 0.  Where the input is zero at the start, the
        equation errors up to its first non-zero sample are noise (a causal Δ(q) at rest gives no output there; the
        program stays exact, see :meth:`~unfalsify.solvers.columns.ColumnForm.noise_floor`); ``form="thesis"``
        needs ``u[0] ≠ 0``.  Several channels: see the module docstring (conditioned form, both backends,
        ``method="barrier"``).
    na, nb : int
        Orders of ``A(q) = 1 + a₁q⁻¹ + …`` and ``B(q) = b₁q⁻¹ + …`` (several channels: l × l and l × m
        matrix coefficients).
    sigma : float
        Admissible rms noise level σ > 0 (same units as y); several outputs: the rms over all entries,
        the noise ball ``‖Ξ‖_F ≤ σ√((n − free_rows)·l)``.
    form : {"conditioned", "thesis"}
        See the module docstring.  ``"conditioned"`` is exact and well conditioned;
        ``"thesis"`` is the literal §7.2.2 LMI (small n only, cvxpy backend only).
    solver : str
        cvxpy solver name, passed explicitly (cvxpy may otherwise choose SCS); cvxpy backend.
    solver_options : dict, optional
        Extra keyword arguments for ``Problem.solve``; cvxpy backend.
    backend : {"cvxpy", "structured"}
        ``"cvxpy"``: the generic LMI models above (the reference; solver ``"cvxpy"`` of
        :mod:`unfalsify.solvers`).  ``"structured"``: a solver that exploits the Toeplitz structure,
        chosen by ``method`` (see :func:`unfalsify.solvers.resolve`).
    tol : float
        Structured backend: stop when the certified relative gap ``(upper − lower)/upper ≤ tol``, or when the upper
        bound is below 1e-14 in the solver's units (y scaled to a unit least-squares residual): δ = 0 to rounding,
        where the relative gap says nothing (it can read 1).
    time_limit : float, optional
        Structured backend: wall-clock limit in seconds; on expiry (or Ctrl-C) the best certified
        bracket so far is returned with status ``"time_limit"`` (``"interrupted"``) and a warning.
    progress : bool
        Structured backend: a tqdm bar (outer iteration, bounds) for solves longer than ~2 s.
    method : {"barrier", "bracket", "primal_dual"}
        Structured backend.  ``"barrier"``: the Cholesky barrier method of :mod:`unfalsify.solvers.arx_barrier`
        (O(n²) memory, O(n³) per Newton step), certified to the relative gap ``tol``.  ``"primal_dual"``: the
        primal–dual interior-point method of :mod:`unfalsify.solvers.arx_pd` (NT scaling, Mehrotra
        predictor–corrector; one channel or several), the same certificate and stopping rule.  ``"bracket"``:
        FFT-only bounds of :mod:`unfalsify.solvers.bracket` (n = 10⁴ in minutes; the search O(n) memory, the
        upper bound's proof one n × n array, 0.8 GB at n = 10⁴): a feasible h
        with a small spectral peak (upper) and a circulant dual point (lower); the result has status
        ``"bracket"``, δ = the certified upper bound and a :class:`SolverWarning` stating the relative
        gap, which is NOT small (measured 0.47–0.53 at n = 200 … 10⁴).
    free_rows : int
        The first ``free_rows`` equation errors are free (neither Δu nor noise): the program for a
        record that does not start at rest, whose first rows carry the response to samples before it.
        The noise budget is then ``σ√(n − free_rows)``.  Conditioned form only.

    Returns
    -------
    ArxResult
        With a two-sided ``certificate`` (:class:`Certificate`): ``upper_bound = ‖T(h)‖₂`` and the
        noise recomputed from ``(theta, impulse)``, ``lower_bound`` from the dual point.

    Raises
    ------
    DataError
        Bad data (NaN, lengths, time along axis 1, too few samples, a σ below the noise of the outputs
        before the input's first non-zero sample, ``u[0] = 0`` with ``form="thesis"``), bad orders, σ ≤ 0; a cvxpy
        solve whose estimated memory (:func:`~unfalsify.arx_solve_estimate`) exceeds half the memory available
        (the message names ``backend="structured"``).
    UnknownSolverError
        Unknown ``backend`` or ``method`` (a ``ValueError``; the message lists the valid names), or
        ``method="bracket"`` with several channels (the message names ``method="barrier"``).
    ValueError
        Unknown ``form``, ``form="thesis"`` with the structured backend or several channels, or
        ``method="bracket"`` with the cvxpy backend.
    UnfalsificationError
        cvxpy: solver failure or an infeasible/unbounded status (impossible in exact arithmetic).

    Warns
    -----
    SolverWarning
        Status other than optimal (δ is NaN unless ``optimal_inaccurate``, or, for the structured
        backend, ``bracket``/``time_limit``/``interrupted``, where δ is the certified upper bound); a cvxpy δ
        outside the bracket of its own certificate (then NaN: it is provably not the answer).
    IllConditionedWarning
        ``form="thesis"`` with ``cond T(u) > COND_WARN``.
    LongSolveWarning
        A cvxpy solve estimated above :data:`unfalsify.cost.LONG_SOLVE_SECONDS` (60 s: above n ≈ 80 on one channel).

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(30)
    >>> y = np.zeros(30)
    >>> for k in range(1, 30):
    ...     y[k] = 0.5 * y[k - 1] + u[k - 1]
    >>> y += 0.05 * rng.standard_normal(30)
    >>> _, rms = arx_least_squares(u, y, 1, 1)
    >>> res = arx_unfalsify(u, y, 1, 1, 0.5 * rms)
    >>> res.status, bool(res.delta > 0), bool(res.certificate.verify())
    ('optimal', True, True)
    >>> fast = arx_unfalsify(u, y, 1, 1, 0.5 * rms, backend="structured", progress=False)
    >>> bool(abs(fast.delta - res.delta) <= 1e-4 * res.delta)
    True

    Two inputs, two outputs (l × m Markov parameters; output error with the first 2 rows free):

    >>> U = rng.standard_normal((20, 2))
    >>> E = 0.3 * np.roll(U, 1, axis=0) @ np.array([[1.0, 0.5], [0.0, 1.0]]).T + 0.01 * rng.standard_normal((20, 2))
    >>> mimo = arx_unfalsify(U, E, 0, 0, 0.01, backend="structured", free_rows=2, progress=False)
    >>> mimo.impulse.shape, mimo.noise.shape, bool(mimo.certificate.verify())
    ((20, 2, 2), (20, 2), True)
    """
    form = check_form(form)
    progress = check_flag(progress, "progress")
    solver_options = check_solver_options(solver_options)
    name = resolve("arx", backend, method)
    if backend == "structured" and form != "conditioned":
        raise DataError("backend='structured' solves the conditioned form; use form='conditioned'")
    if free_rows and form != "conditioned":
        raise DataError("free_rows needs form='conditioned'")
    P = ArxProblem.from_data(u, y, na, nb, sigma, free_rows=free_rows)
    if not P.siso:
        shape = f"{P.n_outputs}×{P.n_inputs}"
        if form != "conditioned":
            raise DataError(f"form='thesis' is written for one channel; with {shape} data use form='conditioned'")
        if name not in CHANNELS:  # method="bracket"
            raise UnknownSolverError(f"method={method!r} solves single-channel data only; for {shape} data use "
                                     "method='barrier' (or backend='cvxpy')")
    if form == "thesis" and not np.any(P.u[0] != 0.0):
        raise DataError("form='thesis' recovers h by inverting T(u), which u[0] == 0 makes singular; "
                        "form='conditioned' solves such a record exactly (its first errors are noise)")
    if form == "thesis" and not P.cond_Tu <= COND_WARN:
        warnings.warn(
            f"form='thesis' with cond T(u) = {P.cond_Tu:.3g}: T(u)ᵀT(u) is numerically singular; the solver's δ "
            "is not certified by its own variables (see certificate); prefer form='conditioned'",
            IllConditionedWarning,
            stacklevel=2,
        )
    if name == "cvxpy":
        _guard_arx(P.n, (P.n_inputs, P.n_outputs))
        options = dict(form=form, solver=solver, solver_options=solver_options)
    elif name == "bracket":  # no tolerance: the bracket's gap is what it is, and reported
        options = dict(time_limit=time_limit, progress=progress)
    else:
        options = dict(tol=tol, time_limit=time_limit, progress=progress)
    out = run(name, P, **options)
    what = f"ARX unfalsification ({'' if P.siso else f'{P.n_outputs}×{P.n_inputs}, '}n={P.n})"
    out = into_ball(P, out)
    cert, delta = certify(P, out, what)
    xi = P.noise(out.impulses, out.params)
    return ArxResult(delta=delta, theta=out.params, noise=xi, impulse=out.impulses, status=out.status.value,
                     solve_time=out.solve_time, problem=out.problem, form=form, sigma=P.sigma, na=P.na, nb=P.nb,
                     cond_Tu=P.cond_Tu, certificate=cert, scale=P.scale, backend=backend, n_inputs=P.n_inputs,
                     n_outputs=P.n_outputs, solver_stats=dict(out.stats))
