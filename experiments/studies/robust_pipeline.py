"""The §7.4 pipeline on plants it was not designed on: certified or not, and checked on the true plant.

For each plant (stable third order, lightly damped resonant, non-minimum phase, and the §5.4
servo), noise seed and (i, j):

1. a 1000-sample open-loop experiment (PRBS ±1, process and sensor noise σ = 0.05, 10 Hz), and a second
   500-sample experiment on the same plant, held out for the premise test (``validation=``);
2. the least-squares predictor on the whole record (horizon i); δ by (7.5) for that predictor on
   the first ``2i + j − 1`` samples, with σ = ``sigma_ratio`` × the residual rms on that window; the
   premise tested on the held-out experiment (δ of P̂'s output error by Theorem 7.1, the frequency
   response of P − P̂, excitation where the loop is sensitive): δ is the larger of the two δ's;
3. :func:`unfalsify.robust_design_from_data` with the design search (other γ ratios, W3 gains,
   causal laws, horizon 2i through ``predictor_for``) and its certificate on the data-based
   models P̂ (horizon i) and P̂_ref (the longest horizon the record supports, ``rd.reference_horizon``);
4. independently of the pipeline, on the **true** plant: the loop's stability and
   ``δ‖K(I+PK)⁻¹‖∞`` (proven upper bound), a unit step, and the spectral radius of the loop with
   each of the size-δ additive perturbations ``δz⁻¹``, ``−δ`` and an all-pass of size δ
   phase-aligned at the peak of ``|K(I+PK)⁻¹|`` -- for the returned (robust) controller and for
   the nominal Theorem 3.1 design at γ = 1.1 γ_min.

The invariant checked (and asserted by the tests): certified ⇒ the true loop is stable, tracks
the step (mean error over the last quarter ≤ the floor) and survives the three perturbations;
not certified ⇒ a :class:`unfalsify.NotCertifiedWarning` with the reason.

Writes ``robust_pipeline.md``, ``.json`` and ``.csv`` under ``--out``, flushed after every run.
"""
from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import control
import numpy as np
from tqdm import tqdm

import synthesis
import unfalsify as uf
from synthesis.validation import DataError

from ..lab.plants import PLANT_CATALOGUE, nonminimum_phase, resonant, servo, third_order
from ..lab.report import LiveTable, Report, finish_report, write_csv
from ..lab.servo_setup import closed_loop_matrix, design_weights
from ..lab.signals import prbs
from ..lab.simulate import collect_data
from .chapter7 import worst_phase_allpass

__all__ = ["run", "run_case", "plant_and_weights", "premise_ratio", "result_premise_ratio", "true_factors",
           "PIPELINE_PLANTS", "Config"]

#: The 10 Hz plants of this experiment: name -> factory.
PIPELINE_PLANTS = {
    "third_order": third_order,
    "resonant": resonant,
    "nonminimum_phase": nonminimum_phase,
    "servo": servo,
}

NOISE = 0.05
RECORD = 1000
#: samples of a second experiment (PRBS seed + 50, noise seed + 150), held out for the premise test
HELD_OUT = 500


@dataclass(frozen=True)
class Config:
    plants: tuple = tuple(PIPELINE_PLANTS)
    seeds: tuple = (0, 1, 2)
    sizes: tuple = ((10, 30), (20, 40))
    sigma_ratio: float = 0.5

    @classmethod
    def quick(cls) -> "Config":
        return cls(plants=("third_order", "resonant", "nonminimum_phase"), seeds=(0,), sizes=((10, 30),))


def _true_loop(P, K, delta: float, tracking_floor: float, uncertainty: str = "additive", factors=None) -> dict:
    """Checks on the true plant, independent of the pipeline's models.

    Additive form with several inputs or outputs: stability, the small gain and tracking (a floor per output) only;
    the size-δ perturbations are scalar and are tried on one-channel plants (they had raised IndexError on a
    two-input plant, and a floor per output TypeError).

    ``uncertainty="coprime"`` (``delta`` is then ε, ``factors`` P̂'s), any number of outputs and inputs: ε-balls
    of different factorisations of one plant are not comparable, so the true plant is factored *like P̂*
    (:func:`true_factors` with ``like=factors``); the small gain is ``ε‖[K; I](M + NK)⁻¹‖∞`` of those factors and
    the perturbations are the size-ε coprime ones of :func:`_coprime_perturbations` (``N + εz⁻¹``, ``N − ε``,
    ``M ± ε`` on the first channel; with several outputs also the all-pass one along the channel's worst direction
    at its peak).
    """
    rob = uf.additive_robustness(P, K)
    out = {"stable": rob.stable, "spectral_radius": rob.spectral_radius,
           "small_gain": float(delta * rob.peak) if rob.stable else float("inf")}
    step = uf.step_metrics(uf.closed_loop_ry(P, K))
    # a floor per output (inf: not tracked), as the certificate takes it: a tuple had raised TypeError here
    floors = uf.tracking_floors(tracking_floor, P.noutputs)
    errors = step.output_errors(np.isfinite(floors))
    out.update(step_error=step.final_error, overshoot_pct=100.0 * step.overshoot,
               tracks=bool(rob.stable and np.all(errors <= floors)))
    radii = []
    if rob.stable and delta > 0 and uncertainty == "coprime":
        F = true_factors(P, like=factors)
        H = uf.coprime_channel(F, K)
        peak = synthesis.hinf_norm(H)
        out["small_gain"] = float(delta * peak.upper)
        # one output: the four perturbations, as before; no peak frequency (H not proven stable): none to aim at
        worst = (H, peak.frequency) if F.outputs > 1 and np.isfinite(peak.frequency) else None
        radii = [_loop_radius(pd, K) for pd in _coprime_perturbations(F, delta, worst)]
    elif rob.stable and delta > 0 and P.ninputs == P.noutputs == 1:  # scalar perturbations: one channel only
        dt = P.dt
        perts = [control.tf([delta], [1.0, 0.0], dt), control.tf([-delta], [1.0], dt),
                 worst_phase_allpass(P, K, delta)[0]]
        radii = [_loop_radius(control.ss(P) + control.ss(pd), K) for pd in perts]
    out["perturbed_max_radius"] = float(max(radii)) if radii else float("nan")
    out["survives"] = bool(rob.stable and (not radii or max(radii) < 1.0))
    return out


def _loop_radius(P, K) -> float:
    """Spectral radius of the loop of ``P`` and ``K`` (inputs ``[r; y]``, :func:`~experiments.lab.closed_loop_matrix`).
    Only the eigenvalues: ``additive_robustness`` would also prove the additive channel's H∞ norm, which the perturbed
    loops do not need (measured on the coprime judge at i = 32, plants of 1036 states: 63–70 s a perturbation against
    0.8 s, the same radius to 1e-14)."""
    A = closed_loop_matrix(control.ss(P), K)
    return float(np.max(np.abs(np.linalg.eigvals(A)))) if A.size else 0.0


#: :func:`true_factors` results of the last plants factored like a model, keyed by the numbers they depend on: the
#: judge and :func:`result_premise_ratio` factor the same plant like the same P̂ (at i = 32 the search for Q took 60 s)
_FACTORS_CACHE: dict = {}
_FACTORS_CACHE_SIZE = 8


def true_factors(P, like: uf.CoprimeFactors | None = None, points: int = 1024) -> uf.CoprimeFactors:
    """FIR left factors ``P = M(q⁻¹)⁻¹N(q⁻¹)``, ``M(∞) = I``, of a plant with any number of outputs and inputs.

    From a realisation ``(A, B, C, D)`` of order n: ``M = det(zI − A) z^{−n} I`` and, entry by entry,
    ``N_kj = (det(zI − A + b_j c_k) − det(zI − A) + d_kj det(zI − A)) z^{−n}`` (``c_k adj(zI − A) b_j =
    det(zI − A + b_j c_k) − det(zI − A)``, row ``c_k`` of C).  With several outputs these factors share the plant's
    poles (``M`` is scalar), so they are not coprime; the ε-ball is only meaningful in the factorisation P̂'s
    certificate was measured in, which ``like`` supplies.  With ``like`` (P̂'s factors, degree i) both are multiplied
    on the left by the FIR ``Q``, ``Q(∞) = I`` (l × l; a scalar for one output), that brings ``[QN  QM]`` closest to
    ``[N̂  M̂]``: P̂'s factors carry a near-common factor (an ARX model of order i above the plant's).
    ``[QN − N̂  QM − M̂]`` is then one admissible perturbation: its H∞ norm (largest singular value over a dense
    grid) bounds the plant's distance from the family from above (:func:`result_premise_ratio`), and the pointwise
    distance (:func:`unfalsify.coprime_distance`) from below.

    One output: Q minimises the largest ``‖[NQ − N̂  MQ − M̂]‖₂`` over ``points`` frequencies (a second-order cone
    program, Clarabel) at degrees i, 2i, 4i, … 16i until the bound meets the pointwise one to 1 %, or the
    least-squares Q where that is closer.  Measured on four coprime certificates of the adversarial catalogue: the
    least-squares Q of degree i (the former rule) bounded the premise ratio by 5.9, 7.0, 6.4 and 21; these Q by
    0.39, 0.91, 0.78 and 0.38, each equal to the pointwise lower bound (degree 2i for the first three, 16i for a
    mode of damping 0.02 that P̂ misses).

    Several outputs: the same ladder, each rung minimising the largest *Frobenius* norm of
    ``[QN − N̂  QM − M̂]`` over the grid (one second-order cone per frequency) rather than its largest singular
    value (a semidefinite cone of size 2(2l + m) per frequency).  Measured on a 2 × 2 plant at 1024 frequencies
    (2026-11-29, judgeM scripts): 0.56 s against 17 s at degree 4, 4.0 s against 42 s at degree 16, with σ̄ gaps
    equal to 4 digits (0.9092, 0.06244).  The norm the bracket reports is the singular value one, measured on the
    result, and since ``σ̄ ≤ ‖·‖_F ≤ √l σ̄`` it is at most √l times the least the σ̄ program would reach at that
    degree: the upper end of the bracket is a proven bound of the distance either way, at worst less tight.
    Factors made ``like`` a model are kept for the last few plants: the judge and :func:`result_premise_ratio` ask
    for the same ones.

    Examples
    --------
    >>> import control, numpy as np
    >>> P = control.ss([[0.5, 0.1], [0.0, 0.8]], [[1.0, 0.0], [0.5, 1.0]], [[1.0, 0.0], [0.0, 1.0]],
    ...                np.zeros((2, 2)), 1.0)
    >>> F = true_factors(P)
    >>> z = np.exp(0.3j)
    >>> N, M = F.response([0.3])
    >>> bool(np.allclose(np.linalg.solve(M[0], N[0]), P.horner(z)[:, :, 0]))
    True
    """
    sys = control.ss(P)
    A, B, C, D = (np.atleast_2d(np.asarray(X, float)) for X in control.ssdata(sys))
    key = None if like is None else (*(X.tobytes() + bytes(str(X.shape), "ascii") for X in (A, B, C, D)),
                                     float(sys.dt), like.N.tobytes(), like.M.tobytes(), like.N.shape, float(like.dt),
                                     int(points))
    if key in _FACTORS_CACHE:
        return _FACTORS_CACHE[key]
    if like is not None and (like.outputs, like.inputs) != (sys.noutputs, sys.ninputs):
        raise DataError(f"the plant is {sys.noutputs} × {sys.ninputs} but P̂'s factors (like=) {like.outputs} × "
                        f"{like.inputs} (outputs × inputs): pass the factors of a model of this plant")
    F = _factors(sys, A, B, C, D, like, points) if sys.noutputs == 1 else _factors_mimo(sys, A, B, C, D, like, points)
    if key is not None:
        if len(_FACTORS_CACHE) >= _FACTORS_CACHE_SIZE:
            _FACTORS_CACHE.pop(next(iter(_FACTORS_CACHE)))
        _FACTORS_CACHE[key] = F
    return F


def _factors(sys, A, B, C, D, like, points: int) -> uf.CoprimeFactors:
    """:func:`true_factors` of a one-output plant, computed (not cached)."""
    den = np.poly(A) if A.size else np.ones(1)
    num = np.array([np.poly(A - np.outer(B[:, j], C[0])) - den + D[0, j] * den if A.size else D[0, j] * den
                    for j in range(sys.ninputs)])                                  # (m, n + 1)
    if like is not None:
        q = _closest_multiplier(num, den, like, sys, points)
        num = np.array([np.convolve(c, q) for c in num])
        den = np.convolve(den, q)
    scale = den[0]
    return uf.CoprimeFactors(N=(num.T / scale)[:, None, :], M=(den / scale).reshape(-1, 1, 1), dt=float(sys.dt))


def _factors_mimo(sys, A, B, C, D, like, points: int) -> uf.CoprimeFactors:
    """:func:`true_factors` of a plant with several outputs, computed (not cached): taps ``(n + 1, l, m)`` and
    ``(n + 1, l, l)`` (at least two: :class:`unfalsify.CoprimeFactors` needs degree ≥ 1), then aligned by ``Q``."""
    l, m = sys.noutputs, sys.ninputs
    den = np.poly(A) if A.size else np.ones(1)
    N = np.zeros((den.size, l, m))
    for k in range(l):
        for j in range(m):
            N[:, k, j] = (np.poly(A - np.outer(B[:, j], C[k])) - den + D[k, j] * den) if A.size else D[k, j] * den
    M = den[:, None, None] * np.eye(l)[None]
    if den.size < 2:  # a static plant: pad with a zero tap
        N, M = np.concatenate([N, np.zeros_like(N)]), np.concatenate([M, np.zeros_like(M)])
    if like is not None:
        Q = _closest_multiplier_mimo(N, M, like, sys, points)
        N, M = _left_multiply(Q, N), _left_multiply(Q, M)
    return uf.CoprimeFactors(N=N, M=M, dt=float(sys.dt))


def _left_multiply(Q: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Taps of the product ``Q(q⁻¹) X(q⁻¹)`` of two FIR polynomial matrices (taps first)."""
    out = np.zeros((Q.shape[0] + X.shape[0] - 1, Q.shape[1], X.shape[2]))
    for d in range(Q.shape[0]):
        out[d:d + X.shape[0]] += np.einsum("ab,tbc->tac", Q[d], X)
    return out


#: :func:`true_factors`: the largest degree of Q, in multiples of P̂'s degree i
_Q_DEGREE_FACTOR = 16


def _closest_multiplier(num: np.ndarray, den: np.ndarray, like: uf.CoprimeFactors, sys, points: int) -> np.ndarray:
    """Q's taps for :func:`true_factors`: the candidate whose ``[NQ − N̂  MQ − M̂]`` has the least H∞ norm."""
    w = np.linspace(0.0, np.pi, points)
    zp = np.exp(-1j * np.outer(w, np.arange(den.size)))                          # the plant's taps, d = 0 … n
    plant = [zp @ c for c in (*num, den)]                                          # N_j(ω), M(ω)
    Nh, Mh = like.response(w / like.dt)
    target = [Nh[:, 0, j] for j in range(num.shape[0])] + [Mh[:, 0, 0]]
    return _multiplier_ladder(lambda q: _gap(num, den, q, like),
                              lambda d: _least_squares_multiplier(plant, target, w, d),
                              lambda d: _minimax_multiplier(plant, target, w, d),
                              like.horizon, uf.coprime_distance(like, sys)[0])


def _multiplier_ladder(gap, least_squares, minimax, horizon: int, lower: float):
    """The candidate Q of least ``gap``: least squares at degree ``horizon``, then the minimax at ``horizon``, twice
    that, … up to :data:`_Q_DEGREE_FACTOR` times it, stopping once a gap is within 1 % of the pointwise ``lower``
    bound (a failed minimax solve, None, is skipped).  Shared by one output and several."""
    q = least_squares(horizon)
    candidates = [(gap(q), q)]
    degree = horizon
    while degree <= _Q_DEGREE_FACTOR * horizon:
        q = minimax(degree)
        if q is not None:
            candidates.append((gap(q), q))
            if candidates[-1][0] <= 1.01 * lower:
                break
        degree *= 2
    return min(candidates, key=lambda c: c[0])[1]


def _least_squares_multiplier(plant, target, w: np.ndarray, degree: int) -> np.ndarray:
    """Q of ``degree`` fitting ``[N_j Q, M Q]`` to ``[N̂_j, M̂]`` in least squares over ``w`` (scaled to Q(∞) = 1)."""
    zq = np.exp(-1j * np.outer(w, np.arange(degree + 1)))
    Aq = np.vstack([p[:, None] * zq for p in plant])
    bq = np.concatenate(target)
    q = np.linalg.lstsq(np.vstack([Aq.real, Aq.imag]), np.concatenate([bq.real, bq.imag]), rcond=None)[0]
    return q / q[0]


def _minimax_multiplier(plant, target, w: np.ndarray, degree: int) -> np.ndarray | None:
    """Q of ``degree``, ``Q(∞) = 1``, minimising ``max_ω ‖[N_j Q − N̂_j, M Q − M̂]‖₂`` over ``w`` (None if the solve
    fails)."""
    import cvxpy as cp

    zq = np.exp(-1j * np.outer(w, np.arange(degree + 1)))
    q, t = cp.Variable(degree + 1), cp.Variable()
    rows = []
    for p, b in zip(plant, target):
        Aq = p[:, None] * zq
        rows += [Aq.real @ q - b.real, Aq.imag @ q - b.imag]
    return _optimal_value(cp.Problem(cp.Minimize(t), [cp.norm(cp.vstack(rows), 2, axis=0) <= t, q[0] == 1.0]), q)


def _optimal_value(problem, variable) -> np.ndarray | None:
    """``variable``'s value after solving ``problem`` with Clarabel, or None unless the solve is optimal and finite
    (the multiplier searches then fall back to another degree or to least squares)."""
    import cvxpy as cp

    try:
        problem.solve(solver="CLARABEL")
    except cp.error.SolverError:
        return None
    if problem.status != cp.OPTIMAL or variable.value is None or not np.all(np.isfinite(variable.value)):
        return None
    return np.asarray(variable.value, float)


def _gap(num: np.ndarray, den: np.ndarray, q: np.ndarray, like: uf.CoprimeFactors) -> float:
    """The H∞ norm (dense grid) of ``[NQ − N̂  MQ − M̂]`` with ``Q(∞) = 1``."""
    numq, denq = np.array([np.convolve(c, q) for c in num]), np.convolve(den, q)
    F = uf.CoprimeFactors(N=(numq.T / denq[0])[:, None, :], M=(denq / denq[0]).reshape(-1, 1, 1), dt=like.dt)
    return _fir_gap(F, like)


def _closest_multiplier_mimo(N: np.ndarray, M: np.ndarray, like: uf.CoprimeFactors, sys, points: int) -> np.ndarray:
    """Q's taps ``(d + 1, l, l)``, ``Q[0] = I``, for :func:`true_factors` of a plant with several outputs: the
    candidate (least squares at degree i, then the Frobenius minimax at i, 2i, … 16i until the σ̄ gap meets the
    pointwise lower bound to 1 %) whose ``[QN − N̂  QM − M̂]`` has the least H∞ norm."""
    w = np.linspace(0.0, np.pi, points)
    zp = np.exp(-1j * np.outer(w, np.arange(N.shape[0])))
    plant = np.concatenate([np.einsum("fd,dab->fab", zp, N), np.einsum("fd,dab->fab", zp, M)], axis=2)  # (F, l, m+l)
    Nh, Mh = like.response(w / like.dt)
    target = np.concatenate([Nh, Mh], axis=2)                                                          # (F, l, m+l)
    return _multiplier_ladder(
        lambda Q: _fir_gap(uf.CoprimeFactors(N=_left_multiply(Q, N), M=_left_multiply(Q, M), dt=like.dt), like),
        lambda d: _least_squares_multiplier_mimo(plant, target, w, d),
        lambda d: _minimax_multiplier_mimo(plant, target, w, d),
        like.horizon, uf.coprime_distance(like, sys)[0])


def _multiplier_basis(plant: np.ndarray, w: np.ndarray, degree: int) -> np.ndarray:
    """``basis[f, (d, r), c] = e^{−jω_f d} [N M]_{r c}(ω_f)``: row k of ``Q[N M]`` is ``basis @ x_k`` with
    ``x_k[(d, r)] = Q_d[k, r]``; shape (F, (degree + 1)·l, m + l)."""
    zq = np.exp(-1j * np.outer(w, np.arange(degree + 1)))                                   # (F, d + 1)
    return (zq[:, :, None, None] * plant[:, None, :, :]).reshape(w.size, -1, plant.shape[2])


def _least_squares_multiplier_mimo(plant: np.ndarray, target: np.ndarray, w: np.ndarray, degree: int) -> np.ndarray:
    """Q of ``degree``, ``Q[0] = I``, fitting ``Q[N M]`` to ``[N̂ M̂]`` in least squares over ``w`` (row by row: the
    constraint moves Q[0]'s known part to the right-hand side)."""
    l = plant.shape[1]
    basis = _multiplier_basis(plant, w, degree)                                             # (F, (d+1) l, m+l)
    A = np.swapaxes(basis, 1, 2).reshape(-1, basis.shape[1])                                # rows (f, c)
    rhs = (target - plant).reshape(-1, l)   # Q[0] = I contributes [N M] itself: row k of target minus row k of plant
    A, rhs = A[:, l:], rhs.astype(complex)
    X = np.linalg.lstsq(np.vstack([A.real, A.imag]), np.vstack([rhs.real, rhs.imag]), rcond=None)[0]
    return np.concatenate([np.eye(l)[None], X.reshape(degree, l, l).transpose(0, 2, 1)])


def _minimax_multiplier_mimo(plant: np.ndarray, target: np.ndarray, w: np.ndarray, degree: int) -> np.ndarray | None:
    """Q of ``degree``, ``Q[0] = I``, minimising ``max_ω ‖Q[N M] − [N̂ M̂]‖_F`` over ``w`` (None if the solve fails;
    the Frobenius norm: :func:`true_factors`)."""
    import cvxpy as cp

    l, c = plant.shape[1], plant.shape[2]
    basis = _multiplier_basis(plant, w, degree)
    X, t = cp.Variable(((degree + 1) * l, l)), cp.Variable()   # X[(d, r), k] = Q_d[k, r]
    parts = []
    for e in range(c):   # entry e of every row k: basis[:, :, e] @ X[:, k] − target[:, k, e]
        B, T = basis[:, :, e], target[:, :, e]
        parts += [B.real @ X - T.real, B.imag @ X - T.imag]
    value = _optimal_value(cp.Problem(cp.Minimize(t), [cp.norm(cp.hstack(parts), 2, axis=1) <= t,
                                                       X[:l, :] == np.eye(l)]), X)
    if value is None:
        return None
    Q = value.reshape(degree + 1, l, l).transpose(0, 2, 1)
    Q[0] = np.eye(l)  # exact: the solver meets the equality to its tolerance only
    return Q


def _fir_gap(F: uf.CoprimeFactors, G: uf.CoprimeFactors, points: int = 8192) -> float:
    """``max_ω σ̄([N_F − N_G  M_F − M_G])`` on a dense grid (FIR differences: the grid sees every peak)."""
    k = max(F.horizon, G.horizon) + 1
    if F.outputs == 1:  # one output: the vector norm, as before (its results are pinned by the tests)
        pad = lambda X: np.vstack([X[:, 0, :], np.zeros((k - X.shape[0], X.shape[2]))])  # noqa: E731
        diff = np.hstack([pad(F.N) - pad(G.N), pad(F.M) - pad(G.M)])                     # (k, m + 1)
        return float(np.max(np.linalg.norm(np.fft.rfft(diff, points, axis=0), axis=1)))
    pad = lambda X: np.concatenate([X, np.zeros((k - X.shape[0], *X.shape[1:]))])  # noqa: E731
    diff = np.concatenate([pad(F.N) - pad(G.N), pad(F.M) - pad(G.M)], axis=2)     # (k, l, m + l)
    return float(np.max(np.linalg.norm(np.fft.rfft(diff, points, axis=0), ord=2, axis=(1, 2))))


def _coprime_perturbations(F: uf.CoprimeFactors, eps: float, worst=None) -> list:
    """Plants ``(M + Δ_M)⁻¹(N + Δ_N)`` with ``‖[Δ_N Δ_M]‖∞ = ε``.

    One output: ``(Δ_N, Δ_M) = (εz⁻¹e₁ᵀ, 0), (−εe₁ᵀ, 0), (0, ε), (0, −ε)``.  Several outputs: the same with
    ``e₁e₁ᵀ`` for ``e₁ᵀ`` and ``±εI`` for ``±ε``, and, with ``worst = (H, ω)`` (the coprime channel of the loop and
    its peak frequency, rad/sample), the rank-one all-pass perturbation aligned with H's worst direction at ω
    (:func:`_worst_direction_plant`): the one that makes ``I − [Δ_N −Δ_M]H`` singular there at ``ε = 1/σ̄(H(ω))``.
    """
    if F.outputs == 1:
        plants = []
        for k, dN, dM in ((1, eps, 0.0), (0, -eps, 0.0), (0, 0.0, eps), (0, 0.0, -eps)):
            N, M = F.N[:, 0, :].copy(), F.M[:, 0, 0].copy()
            if M.size < 2:
                N, M = np.vstack([N, np.zeros((1, N.shape[1]))]), np.append(M, 0.0)
            N[k, 0] += dN
            M[0] += dM
            M = M / M[0]  # the realisation keeps M(∞) = 1: divide both factors by it
            N = N / (1.0 + dM)
            plants.append(uf.CoprimeFactors(N=N[:, None, :], M=M.reshape(-1, 1, 1), dt=F.dt).model())
        return plants
    plants = []
    for k, dN, dM in ((1, eps, 0.0), (0, -eps, 0.0), (0, 0.0, eps), (0, 0.0, -eps)):
        N, M = F.N.copy(), F.M.copy()
        N[k, 0, 0] += dN
        M[0] += dM * np.eye(F.outputs)
        # M(∞) = (1 + dM) I: dividing both factors by the scalar keeps the plant and M(∞) = I
        plants.append(uf.CoprimeFactors(N=N / (1.0 + dM), M=M / (1.0 + dM), dt=F.dt).model())
    if worst is not None:
        plants.append(_worst_direction_plant(F, eps, *worst))
    return plants


def _worst_direction_plant(F: uf.CoprimeFactors, eps: float, H, omega: float) -> control.StateSpace:
    """``(M + Δ_M)⁻¹(N + Δ_N)`` for the rank-one ``[Δ_N  −Δ_M] = ε β(z) α(z)ᵀ`` aimed at H's worst direction.

    With ``H(e^{jω}) = σ a bᴴ + …`` (``a`` of ``[u; y]``, ``b`` of ``v``): ``β_k = |b_k|·(all-pass of phase ∠b_k at
    ω)`` and ``α_j = |a_j|·(all-pass of phase −∠a_j)``, so ``‖Δ‖∞ = ε`` (``‖β(e^{jθ})‖ = ‖α(e^{jθ})‖ = 1`` at every
    θ) and ``Δ(e^{jω}) = ε b aᴴ``: the loop gain ``ΔH`` has the eigenvalue ``εσ`` there.  The plant is realised in
    the factors' delay-line state (:meth:`unfalsify.CoprimeFactors.equation`) closed with ``v = Δ[u; y]``, as the
    FIR perturbations are by :meth:`~unfalsify.CoprimeFactors.model`."""
    z = np.exp(1j * omega)
    U, _, Vh = np.linalg.svd(np.asarray(H.horner(z))[:, :, 0])
    a, b = U[:, 0], np.conj(Vh[0])
    phase = np.exp(-1j * np.angle(a[np.argmax(np.abs(a))]))  # b aᴴ is unchanged; a real H(ω) gives real a, b
    a, b = a * phase, b * phase
    alpha = _allpass_row(np.abs(a), -np.angle(a), omega, H.dt)                  # 1 × (m + l)
    row = _allpass_row(np.abs(b), np.angle(b), omega, H.dt)
    beta = control.ss(row.A.T, row.C.T, row.B.T, row.D.T, H.dt)                  # l × 1: the row transposed
    delta = eps * control.series(alpha, beta)
    return _close_equation(F.equation(), delta, F.inputs)


def _allpass_row(gains: np.ndarray, phases: np.ndarray, omega: float, dt) -> control.StateSpace:
    """A 1 × n system whose entry j is ``gains[j]·s(1 − a z)/(z − a)`` (|·| = gains[j] on the unit circle) with phase
    ``phases[j]`` at ``e^{jω}``; a static ``±gains[j]`` where that phase is 0 or π (or ω is, where only those are
    reachable).  One state per dynamic entry."""
    z = np.exp(1j * omega)
    n = gains.size
    poles, cols, C, D = [], [], [], np.zeros((1, n))
    for j, (g, th) in enumerate(zip(gains, phases)):
        target = np.exp(1j * th)
        if abs(target.imag) < 1e-9 or abs(np.sin(omega)) < 1e-9:
            D[0, j] = g if target.real >= 0 else -g
            continue
        # s(1 − az)/(z − a) = e^{jθ}  ⇔  a = (s e^{jθ} z − 1)/(s e^{jθ} − z), real for one of s = ±1
        found = [(s, a) for s in (1.0, -1.0) for a in [(s * target * z - 1.0) / (s * target - z)]
                 if abs(a.imag) < 1e-6 and abs(a.real) < 1.0]
        if not found:  # rounding at a phase next to 0 or π: the static gain of the nearer sign (still size g)
            D[0, j] = g if target.real >= 0 else -g
            continue
        s, a = found[0][0], float(found[0][1].real)
        poles.append(a)
        cols.append(j)
        C.append(g * s * (1.0 - a * a))
        D[0, j] = -g * s * a
    k = len(poles)
    B = np.zeros((k, n))
    B[np.arange(k), cols] = 1.0
    return control.ss(np.diag(poles).reshape(k, k), B, np.array(C).reshape(1, k), D, dt)


def _close_equation(G, delta, m: int) -> control.StateSpace:
    """``u ↦ y`` of ``y = G[u; v]`` closed with ``v = Δ[u; y]`` (G: :meth:`unfalsify.CoprimeFactors.equation`)."""
    Ag, Bg, Cg, Dg = (np.asarray(X, float) for X in control.ssdata(G))
    Ad, Bd, Cd, Dd = (np.asarray(X, float) for X in control.ssdata(control.ss(delta)))
    Bgu, Bgv, Dgu, Dgv = Bg[:, :m], Bg[:, m:], Dg[:, :m], Dg[:, m:]
    Bdu, Bdy, Ddu, Ddy = Bd[:, :m], Bd[:, m:], Dd[:, :m], Dd[:, m:]
    E = np.linalg.inv(np.eye(Cg.shape[0]) - Dgv @ Ddy)      # y = Cg x + Dgu u + Dgv (Cd xd + Ddu u + Ddy y)
    Yx, Yd, Yu = E @ Cg, E @ Dgv @ Cd, E @ (Dgu + Dgv @ Ddu)
    Vx, Vd, Vu = Ddy @ Yx, Cd + Ddy @ Yd, Ddu + Ddy @ Yu
    A = np.block([[Ag + Bgv @ Vx, Bgv @ Vd], [Bdy @ Yx, Ad + Bdy @ Yd]])
    B = np.vstack([Bgu + Bgv @ Vu, Bdu + Bdy @ Yu])
    return control.ss(A, B, np.hstack([Yx, Yd]), Yu, G.dt)


def result_premise_ratio(P, rd) -> tuple[float, str]:
    """The premise ratio of a pipeline result in the form it was certified in.

    Additive: ``‖P − P̂‖∞/δ`` (:func:`premise_ratio`).  Coprime: the upper end of the bracket of the true plant's
    distance from the family over ε -- the H∞ norm of the perturbation of :func:`true_factors` -- with the note
    giving the lower end, the largest pointwise distance (:func:`unfalsify.coprime_distance`).
    """
    if getattr(rd, "uncertainty", "additive") != "coprime":
        return premise_ratio(P, rd.model, rd.delta)
    eps = float(rd.epsilon)
    F = rd.coprime.factors
    low, w = uf.coprime_distance(F, P)
    high = _fir_gap(true_factors(P, like=F), F)
    how = "the true plant factored like P̂"
    direct = _equation_error_norm(P, F)
    if direct < high:
        high, how = direct, "the perturbation [M̂P − N̂, 0], P stable"
    ratio = high / eps if eps > 0 else float("inf")
    return ratio, (f"coprime: between {low / eps:.3g} (pointwise distance at {w:.3g} rad/s) and {ratio:.3g} "
                   f"({how})")


def _equation_error_norm(P, F: uf.CoprimeFactors) -> float:
    """``‖M̂P − N̂‖∞`` (proven upper bound, :func:`synthesis.hinf_norm`) for a stable ``P``, else ``inf``.

    ``(M̂, N̂ + R)`` with ``R = M̂P − N̂`` factors P (``M̂⁻¹(N̂ + R) = P``), so ``[Δ_N Δ_M] = [R 0]`` is an admissible
    perturbation when R is stable, and its norm bounds P's distance from the family from above.  Where P̂ misses a
    slow pole, the FIR multiplier of :func:`true_factors` cannot carry it and its bound was 4–17 times this one
    (measured on five 2 × 2 coprime certificates, slow modes at 0.99–0.997)."""
    sys = control.ss(P)
    if sys.nstates and not float(np.max(np.abs(np.linalg.eigvals(sys.A)))) < 1.0:
        return float("inf")
    R = _fir_system(F.M, F.dt) * sys - _fir_system(F.N, F.dt)
    return float(synthesis.hinf_norm(R).upper)


def _fir_system(taps: np.ndarray, dt) -> control.StateSpace:
    """``Σ_k T_k z^{−k}`` for taps ``(K, p, q)`` as a state space (a shift register of the input, ``(K − 1)q``
    states)."""
    K, p, q = taps.shape
    if K == 1:
        return control.ss([], [], [], taps[0], dt)
    n = (K - 1) * q
    A = np.zeros((n, n))
    A[q:, :-q] = np.eye(n - q)  # x = [u_{k−1}; …; u_{k−K+1}]
    B = np.zeros((n, q))
    B[:q] = np.eye(q)
    C = np.hstack(list(taps[1:]))
    return control.ss(A, B, C, taps[0], dt)


def premise_ratio(P, model, delta: float) -> tuple[float, str]:
    """``‖P − P̂‖∞ / δ`` (proven upper bound of the norm) and why it is ``inf`` when it is."""
    if not (P.dt and model.dt) or not np.isclose(float(P.dt), float(model.dt)):
        return float("inf"), f"sample times differ (P {P.dt}, P̂ {model.dt})"
    why = []
    for name, sys in (("P", P), ("P̂", model)):
        rho = float(np.max(np.abs(np.linalg.eigvals(sys.A)))) if sys.nstates else 0.0
        if rho >= 1.0 - 1e-9:
            why.append(f"{name} not stable (spectral radius {rho:.4g}): P − P̂ has no finite H∞ norm")
    if why:
        return float("inf"), "; ".join(why)
    b = synthesis.hinf_norm(control.ss(P) - control.ss(model))
    if not math.isfinite(b.upper):
        return float("inf"), b.reason
    return (float(b.upper / delta) if delta > 0 else float("inf")), ("δ = 0" if delta <= 0 else "")


def plant_and_weights(plant: str):
    """``(P, W1, W2)`` for a key of :data:`PIPELINE_PLANTS` or :data:`experiments.plants.PLANT_CATALOGUE`.

    The 10 Hz plants use the §5.4 weights W11/W21; the 64 Hz three-disk plant the Ch. 6 weights of
    :mod:`experiments.lab.torsional_setup` (collocated ``y1``: §6.3; ``y3``: §6.2).
    """
    if plant in PIPELINE_PLANTS:
        P = PIPELINE_PLANTS[plant]()
    elif plant in PLANT_CATALOGUE:
        P = PLANT_CATALOGUE[plant][0]()
    else:
        raise DataError(f"unknown plant {plant!r}; use one of {sorted(set(PIPELINE_PLANTS) | set(PLANT_CATALOGUE))}")
    if plant.startswith("three_disk"):
        from ..lab.torsional_setup import torsional_weights

        W1, W2 = torsional_weights("noncollocated" if plant.endswith("y3") else "collocated", float(P.dt))
    else:
        W = design_weights(float(P.dt))
        W1, W2 = W["W11"], W["W21"]
    return P, W1, W2


def run_case(plant: str, seed: int, i: int, j: int, sigma_ratio: float = 0.5) -> dict:
    """One run of the pipeline and its true-plant check; a JSON-serialisable dict.

    Parameters
    ----------
    plant : str
        A key of :data:`PIPELINE_PLANTS` or :data:`experiments.plants.PLANT_CATALOGUE` (weights by
        :func:`plant_and_weights`).
    seed : int
        Seeds the PRBS (``seed``) and the noises (``seed + 100``).
    i, j : int
        Horizon and (7.5) window columns.
    sigma_ratio : float
        σ of (7.5) as a fraction of the predictor's residual rms on the window.
    """
    P, W1, W2 = plant_and_weights(plant)
    dt = float(P.dt)
    data = collect_data(P, prbs(RECORD, seed=seed), process_noise=NOISE, sensor_noise=NOISE, seed=seed + 100)
    u, y = data.u[:, 0], data.y[:, 0]
    held = collect_data(P, prbs(HELD_OUT, seed=seed + 50), process_noise=NOISE, sensor_noise=NOISE, seed=seed + 150)
    n = 2 * i + j - 1
    pred = synthesis.fit_predictor(u, y, i)
    A, _, Yf = uf.subspace_data(u[:n], y[:n], i)
    rms = float(np.linalg.norm(Yf - np.hstack([pred.Lw, pred.Lu]) @ A) / np.sqrt(Yf.size))
    sigma = sigma_ratio * rms
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as log:
        warnings.simplefilter("always")
        rd = uf.robust_design_from_data(u[:n], y[:n], i, W1, W2, sigma, predictor=pred, dt=dt,
                                        predictor_for=lambda h: synthesis.fit_predictor(u, y, h),
                                        search=uf.DesignSearch(horizons=(2 * i,)),
                                        validation=(held.u[:, 0], held.y[:, 0]))
    seconds = time.perf_counter() - t0
    warned = [str(w.message) for w in log if issubclass(w.category, uf.NotCertifiedWarning)]
    floor = rd.certificate.tracking_floor
    size = rd.epsilon if rd.uncertainty == "coprime" else rd.delta
    robust = _true_loop(P, rd.controller, size, floor, rd.uncertainty,
                        rd.coprime.factors if rd.coprime is not None else None)
    ratio, ratio_note = result_premise_ratio(P, rd)
    nominal_design = synthesis.hinf_design(pred, W1, W2, dt=dt)
    nominal = _true_loop(P, nominal_design.controller, rd.delta, floor)
    d = rd.design
    return {
        "plant": plant, "seed": int(seed), "i": int(i), "j": int(j), "sigma": sigma, "delta": rd.delta,
        "delta_subspace": rd.delta_subspace, "delta_output_error": rd.delta_output_error,
        "uncertainty": rd.uncertainty, "epsilon": rd.epsilon, "additive_premise_reason": rd.premise.reason,
        "decided_by": rd.premise.decided_by, "premise_ratio": ratio, "premise_note": ratio_note,
        "certified": rd.certified, "reason": rd.reason, "warned": bool(warned), "designs_tried": len(rd.search),
        "chosen": {"horizon": d.horizon, "causal": d.causal, "gamma_ratio": rd.gamma / rd.gamma_min_a,
                   "w3_gain": rd.w3_gain, "gamma": rd.gamma},
        "small_gain_model": rd.certificate.small_gain,
        "small_gain_reference": (rd.reference_certificate.small_gain if rd.reference_certificate else float("nan")),
        # the second proof, re-checked here from its matrices: P ≻ 0, M(P) ≺ 0 (bounded-real lemma)
        "bounded_real_model": _rechecked(rd.certificate),
        "bounded_real_reference": _rechecked(rd.reference_certificate),
        "model_step_error": (rd.certificate.step.final_error if rd.certificate.step else float("inf")),
        # the data's evidence against the loop's δ (or ε) margin on the plant (check_excitation(..., delta=))
        "margin_evidence": (float(rd.excitation.margin) if rd.excitation is not None else float("nan")),
        "true": robust, "nominal_true": nominal, "seconds": seconds,
        "invariant_holds": bool((not rd.certified and warned) or
                                (rd.certified and robust["stable"] and robust["tracks"] and robust["survives"])),
    }


def _rechecked(cert) -> bool:
    """The certificate's bounded-real matrix ``P`` passes its check again (False when there is none)."""
    return bool(cert is not None and cert.bounded_real is not None and cert.bounded_real.verify())


_HEADERS = ["plant", "seed", "i", "j", "δ", "δ (7.5) / δ output error", "true ‖P − P̂‖∞/δ", "certified", "reason", "tried", "chosen (i, causal, γ/γ_min, W3)",
            "δ‖M̂‖ (P̂ / P̂_ref)", "KYP P re-checked (P̂ / P̂_ref)", "true: stable", "true δ‖M‖", "true: step err", "overshoot (%)",
            "worst perturbed radius", "nominal: stable", "nominal δ‖M‖", "nominal survives"]


def _row(c: dict) -> list:
    t, nt, ch = c["true"], c["nominal_true"], c["chosen"]
    reason = c["reason"].replace("|", "\\|") if c["reason"] else "—"
    return [c["plant"], c["seed"], c["i"], c["j"], c["delta"],
            f"{c['delta_subspace']:.4g} / {c['delta_output_error']:.4g}", c["premise_ratio"],
            "yes" if c["certified"] else "**no**", reason,
            c["designs_tried"], f"({ch['horizon']}, {ch['causal']}, {ch['gamma_ratio']:.3g}, {ch['w3_gain']:.3g})",
            f"{c['small_gain_model']:.3g} / {c['small_gain_reference']:.3g}",
            f"{'yes' if c['bounded_real_model'] else 'no'} / {'yes' if c['bounded_real_reference'] else 'no'}", t["stable"], t["small_gain"],
            t["step_error"], t["overshoot_pct"], t["perturbed_max_radius"], nt["stable"], nt["small_gain"],
            nt["survives"]]


TITLE = "§7.4 pipeline on plants it was not designed on"


def run(opts) -> dict:
    """Run every (plant, seed, size) case; write the report under ``opts.out``; return a summary."""
    cfg = Config.quick() if opts.quick else Config()
    out = Path(opts.out)
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    cases = [(p, s + opts.seed, i, j) for p in cfg.plants for s in cfg.seeds for (i, j) in cfg.sizes]
    results: list[dict] = []
    live = LiveTable(out, "robust_pipeline", TITLE, _HEADERS, intro=_intro(cfg))  # an interrupted run keeps its rows
    for p, s, i, j in tqdm(cases, desc="robust-pipeline", unit="run", leave=False):
        results.append(run_case(p, s, i, j, cfg.sigma_ratio))
        live.add(_row(results[-1]), record=results[-1])
    n_cert = sum(c["certified"] for c in results)
    violations = [c for c in results if not c["invariant_holds"]]
    summary = {"quick": bool(opts.quick), "runs": len(results), "certified": n_cert,
               "certified_fraction": n_cert / max(len(results), 1), "invariant_violations": len(violations),
               "cases": results}
    rep = Report(TITLE)
    rep.text(_intro(cfg))
    rep.table(_HEADERS, live.rows)
    rep.section("Summary", f"{n_cert} of {len(results)} runs certified; the invariant (certified ⇒ true loop stable, "
                           f"tracks, survives the size-δ perturbations; otherwise warned) was violated in "
                           f"{len(violations)} run(s). Nominal designs (Thm 3.1, γ = 1.1 γ_min, no search) stable on "
                           f"the true plant in {sum(c['nominal_true']['stable'] for c in results)} of {len(results)}.")
    write_csv(out / "robust_pipeline.csv", _HEADERS, live.rows)
    return finish_report(rep, summary, out, "robust_pipeline", t_start=t_start)


def _intro(cfg: Config) -> str:
    return (
        f"Plants {', '.join(cfg.plants)} (experiments.plants, ZOH at 10 Hz); {RECORD}-sample PRBS ±1 experiments with "
        f"process and sensor noise σ = {NOISE}; weights W11/W21 of §5.4; least-squares predictor on the whole record; "
        f"δ by (7.5) on the first 2i + j − 1 samples with σ = {cfg.sigma_ratio} × the residual rms; design search "
        "with horizons (i, 2i). 'δ‖M̂‖' is the proven small gain on the models P̂ (horizon i) and P̂_ref (2i); "
        "'KYP P re-checked': the second proof of it, a bounded-real matrix P ≻ 0 with M(P) ≺ 0 at the level "
        "1/((1 + margin)δ), checked again here from its matrices ('no' when the loop was refused before it); "
        "'true' columns are computed on the true plant, independently of the pipeline; 'true ‖P − P̂‖∞/δ' is the "
        "premise ratio measured on the true plant (above 1 + margin the premise was false, whatever the loop did); "
        f"the premise test ran on a second, held-out {HELD_OUT}-sample experiment and δ is the larger of δ (7.5) and "
        "δ of P̂'s output error (Theorem 7.1); 'worst perturbed radius' "
        "is the largest closed-loop spectral radius with δz⁻¹, −δ and a phase-aligned all-pass of size δ. "
        "Overshoot in percent of the step.")
