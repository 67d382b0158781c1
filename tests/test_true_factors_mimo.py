"""The coprime judge with several outputs: the true plant's FIR factors ``P = M⁻¹N`` for any shape
(:func:`experiments.studies.robust_pipeline.true_factors`), the premise ratio's bracket and the small gain of a coprime
certificate on a plant with several outputs (which had raised DataError, so such certificates were judged on
stability and tracking only)."""
from __future__ import annotations

from types import SimpleNamespace

import control
import numpy as np
import pytest

import synthesis as sy
import unfalsify as uf
from experiments.studies import robust_pipeline as rp
from experiments.studies.adversarial import judge


def _plant(l: int, m: int, seed: int, order: int = 4) -> control.StateSpace:
    """A random stable l × m plant (spectral radius 0.8, a direct term), dt = 1."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((order, order))
    A *= 0.8 / np.max(np.abs(np.linalg.eigvals(A)))
    return control.ss(A, rng.standard_normal((order, m)), rng.standard_normal((l, order)),
                      0.3 * rng.standard_normal((l, m)), 1.0)


def _response(P, w):
    return np.moveaxis(np.asarray(P.horner(np.exp(1j * w * P.dt)), complex), -1, 0)


def _model_factors(P, horizon: int, seed: int = 0) -> uf.CoprimeFactors:
    """P̂'s factors from a noisy white-input record of P."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((800, P.ninputs))
    y = np.asarray(control.forced_response(P, T=np.arange(800) * P.dt, U=u.T).outputs).T.reshape(800, -1)
    y = y + 0.01 * rng.standard_normal(y.shape)
    return uf.coprime_factors(sy.fit_predictor(u, y, horizon), P.dt)


@pytest.mark.parametrize("shape", [(2, 2), (3, 2), (2, 3)])
def test_true_factors_reproduce_plants_with_several_outputs(shape):
    """``M(e^{jω})⁻¹N(e^{jω}) = P(e^{jω})`` at random frequencies with ``M(∞) = I``, unaligned and aligned to a
    model's factors (the old code refused every plant with several outputs)."""
    P = _plant(*shape, seed=sum(shape))
    w = np.random.default_rng(1).uniform(0.0, np.pi, 7)
    for F in (rp.true_factors(P), rp.true_factors(P, like=_model_factors(P, 2), points=256)):
        N, M = F.response(w)
        assert (F.outputs, F.inputs) == shape and np.allclose(F.M[0], np.eye(shape[0]), atol=1e-12)
        assert np.allclose(np.linalg.solve(M, N), _response(P, w), rtol=1e-8, atol=1e-10)


def test_the_several_output_factoriser_meets_the_one_output_one_on_a_one_output_plant():
    """The l-output formula (entry by entry, ``M = det(zI − A)·I``) is the one-output one for l = 1: same taps to
    rounding, so the one-output path (kept as it was) and the new one describe one factorisation."""
    P = _plant(1, 2, seed=3)
    A, B, C, D = (np.atleast_2d(np.asarray(X, float)) for X in control.ssdata(P))
    one = rp.true_factors(P)
    several = rp._factors_mimo(P, A, B, C, D, None, 256)
    assert np.allclose(one.N, several.N, atol=1e-12) and np.allclose(one.M, several.M, atol=1e-12)


def test_the_premise_bracket_holds_a_known_perturbation_with_several_outputs():
    """A plant ``(M̂ + Δ_M)⁻¹(N̂ + Δ_N)`` with a known small FIR ``[Δ_N Δ_M]``: the pointwise lower end is at most
    ``‖[Δ_N Δ_M]‖∞`` (Δ reaches the plant) and at most the upper end (an admissible perturbation's norm), the
    upper end is near ``‖Δ‖∞`` (Q aligns the factorisations), and :func:`result_premise_ratio` reports the
    bracket over ε instead of raising."""
    Ph = _plant(2, 2, seed=5, order=3)
    Fh = _model_factors(Ph, 2)
    rng = np.random.default_rng(7)
    dN, dM = 0.01 * rng.standard_normal(Fh.N.shape), 0.01 * rng.standard_normal(Fh.M.shape)
    dM[0] = 0.0  # M̂ + Δ_M keeps M(∞) = I
    P = uf.CoprimeFactors(N=Fh.N + dN, M=Fh.M + dM, dt=Fh.dt).model()
    size = rp._fir_gap(uf.CoprimeFactors(N=Fh.N + dN, M=Fh.M + dM, dt=Fh.dt), Fh)   # ‖[Δ_N Δ_M]‖∞
    aligned = rp.true_factors(P, like=Fh)
    low, high = uf.coprime_distance(Fh, P)[0], rp._fir_gap(aligned, Fh)
    assert 0 < low <= size * (1 + 1e-9) and low <= high * (1 + 1e-9)
    assert high <= 1.5 * size, (low, size, high)
    eps = 2.0 * size
    rd = SimpleNamespace(uncertainty="coprime", epsilon=eps, coprime=SimpleNamespace(factors=Fh))
    ratio, note = rp.result_premise_ratio(P, rd)
    # the smaller of two admissible perturbations' norms: Q's alignment, and [M̂P − N̂, 0] (P is stable)
    assert ratio == pytest.approx(min(high, rp._equation_error_norm(P, Fh)) / eps, rel=1e-12)
    assert f"{low / eps:.3g}" in note and low <= ratio * eps * (1 + 1e-9)


def test_the_judge_measures_the_coprime_margin_of_a_several_output_loop():
    """judge() on a coprime certificate of a 2 × 2 plant returns the finite small gain ``ε‖coprime_channel‖∞`` of
    the true plant factored like P̂ (it had raised DataError); at ε just above 1/‖H‖∞ the all-pass perturbation
    along H's worst direction destabilises the loop, just below it none does."""
    P = _plant(2, 2, seed=11, order=3)
    F = _model_factors(P, 2)
    K = control.ss([], [], [], np.hstack([0.2 * np.eye(2), -0.2 * np.eye(2)]), 1.0)   # u = 0.2 (r − y)
    assert uf.additive_robustness(P, K).stable
    peak = sy.hinf_norm(uf.coprime_channel(rp.true_factors(P, like=F), K)).upper
    below = judge(P, K, 0.95 / peak, 1e6, "coprime", F)  # tracking not judged here
    assert below["small_gain"] == pytest.approx(0.95, rel=1e-6) and below["ok"], below["fails"]
    above = judge(P, K, 1.05 / peak, 1e6, "coprime", F)
    assert above["small_gain"] == pytest.approx(1.05, rel=1e-6) and not above["ok"]
    assert above["perturbed_max_radius"] >= 1.0 and not above["survives"]


def test_the_worst_direction_perturbation_has_size_epsilon():
    """The rank-one all-pass ``[Δ_N −Δ_M] = ε β αᵀ`` is ε away from the factors (pointwise distance ≤ ε) and
    reaches ``I − ΔH`` singular at ε = 1/σ̄(H(ω)): the loop's spectral radius crosses 1 there."""
    P = _plant(2, 2, seed=11, order=3)
    F = rp.true_factors(P, like=_model_factors(P, 2))
    K = control.ss([], [], [], np.hstack([0.2 * np.eye(2), -0.2 * np.eye(2)]), 1.0)
    H = uf.coprime_channel(F, K)
    b = sy.hinf_norm(H)
    for scale, stable in ((0.98, True), (1.02, False)):
        Pd = rp._worst_direction_plant(F, scale / b.lower, H, b.frequency)
        assert uf.coprime_distance(F, Pd)[0] <= scale / b.lower * (1 + 1e-6)
        assert (rp._loop_radius(Pd, K) < 1.0) is stable


def test_one_output_coprime_judgements_are_the_former_ones():
    """One output keeps its code path: the four FIR perturbations (no worst-direction one even when the channel is
    offered), and the judge's small gain and radius are exactly those recomputed from them (bit for bit against
    the former code: /work/scratch/judgeM_scripts/siso_same.py, 2026-11-29)."""
    from experiments.lab.plants import servo

    P = servo()
    F = _model_factors(P, 4, seed=1)
    K = control.ss([], [], [], [[0.3, -0.3]], P.dt)
    Ft = rp.true_factors(P, like=F)
    H = uf.coprime_channel(Ft, K)
    b = sy.hinf_norm(H)
    plants = rp._coprime_perturbations(Ft, 0.01, (H, b.frequency))
    assert len(plants) == 4
    t = judge(P, K, 0.01, 1.0, "coprime", F)
    assert t["small_gain"] == 0.01 * b.upper
    assert t["perturbed_max_radius"] == max(rp._loop_radius(pd, K) for pd in rp._coprime_perturbations(Ft, 0.01))


@pytest.mark.parametrize("shape", [(1, 1), (2, 2)])
def test_the_equation_error_bounds_the_premise_where_p_hat_misses_a_slow_pole(shape):
    """A slow pole P̂ misses (0.995): the FIR multiplier of true_factors cannot carry it, and the second upper end,
    ``‖M̂P − N̂‖∞`` by a proven H∞ norm, is the tighter one.  Second route: the same norm on a dense grid, from the
    factors' and the plant's frequency responses, within the bound and close to it; and never below the pointwise
    lower end."""
    l, m = shape
    fast = _plant(l, m, seed=3, order=3)
    slow = control.ss([[0.995]], 0.005 * np.ones((1, m)), -np.ones((l, 1)), np.zeros((l, m)), 1.0)
    P = control.ss(fast + slow)
    F = _model_factors(P, 3)
    bound = rp._equation_error_norm(P, F)
    w = np.concatenate([[0.0], np.geomspace(1e-5, np.pi, 6000)])
    Nw, Mw = F.response(w)
    grid = np.linalg.norm(Mw @ _response(P, w) - Nw, ord=2, axis=(1, 2)).max()
    assert grid <= bound * (1 + 1e-9) and grid >= 0.99 * bound
    low = uf.coprime_distance(F, P)[0]
    rd = SimpleNamespace(uncertainty="coprime", epsilon=1.0, coprime=SimpleNamespace(factors=F))
    ratio, note = rp.result_premise_ratio(P, rd)
    assert low <= ratio * (1 + 1e-9) and ratio == pytest.approx(bound) and "M̂P − N̂" in note
    assert rp._equation_error_norm(control.ss([[1.0]], [[1.0] * m], [[1.0]] * l, np.zeros((l, m)), 1.0), F) \
        == float("inf")  # an integrator: R is not stable, no such perturbation
