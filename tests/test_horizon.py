"""``synthesis.choose_horizon``: the horizon from the data, by a stated rule (issue 29, item 3)."""
import pickle
import warnings

import control
import numpy as np
import pytest

import synthesis as sy
from experiments.lab.servo_setup import design_weights
from experiments.lab.plants import nonminimum_phase, servo, third_order, three_disk
from experiments.lab.signals import prbs
from experiments.lab.simulate import closed_loop_system, collect_data
from experiments.lab.torsional_setup import torsional_weights

DT = 0.1


def _radius(P, K):
    return float(np.max(np.abs(np.linalg.eigvals(np.asarray(closed_loop_system(P, K).A, float)))))


@pytest.fixture(scope="module")
def nmp():
    P = nonminimum_phase()
    W = design_weights(DT)
    d = collect_data(P, prbs(1000, seed=3), process_noise=0.05, sensor_noise=0.05, seed=103)
    return P, W["W11"], W["W21"], d


def test_on_the_non_minimum_phase_plant_the_chosen_loop_is_stable_where_i_20_is_not(nmp):
    P, W1, W2, d = nmp
    choice = sy.choose_horizon(d.u, d.y, W1, W2, dt=DT)
    assert choice.ok and choice.horizon > 20
    assert _radius(P, choice.design.controller) < 1                     # stable on the TRUE plant
    # the §5.4 horizon on the same data is unstable on the plant (measured: a real closed-loop pole near 1.16 and
    # a controller pole at 1.24, none on the zero at e^{0.1}: not a cancellation)
    short = sy.hinf_design(sy.fit_predictor(d.u, d.y, 20), W1, W2, dt=DT)
    assert _radius(P, short.controller) > 1
    assert f"i = {choice.horizon}" in choice.reason and "i = 20" in choice.reason


def test_the_rule_is_applied_as_stated(nmp):
    P, W1, W2, d = nmp
    choice = sy.choose_horizon(d.u, d.y, W1, W2, dt=DT)
    rows = choice.candidates
    assert [r.horizon for r in rows] == sorted(r.horizon for r in rows)
    assert rows[-1].horizon == choice.horizon and rows[-1].passes        # the scan stops at the first pass
    assert not any(r.passes for r in rows[:-1])                           # ... which is the smallest
    assert not rows[0].settled and np.isnan(rows[0].change)
    for prev, r in zip(rows, rows[1:]):
        assert r.change == pytest.approx(abs(r.gamma_min - prev.gamma_min) / r.gamma_min)
        assert r.settled == (r.change <= 0.05)
    # the stability check is the loop with the data-based model P̂, recomputed here
    for r in rows:
        K = sy.hinf_design(sy.fit_predictor(d.u, d.y, r.horizon, dt=DT), W1, W2, dt=DT).controller
        assert r.spectral_radius == pytest.approx(_radius(choice.model, K), rel=1e-9)
        assert r.stable == (r.spectral_radius < 1)
    # P̂ is the subspace model of the data: the plant's order, and the zero outside the unit circle
    assert choice.model_order == 2
    zeros = control.ss(choice.model).zeros()
    assert np.any(np.abs(zeros) > 1.05)
    # the margin check, recomputed: models of P̂'s order from each half, at the largest horizon <= P̂'s with
    # 3 columns per regressor in 500 samples (found by search here, by formula there)
    half = len(d.u) // 2
    h = max(k for k in range(2, 65) if half - 2 * k + 1 >= 3 * k * 3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        split = [sy.subspace_id(d.u[s], d.y[s], h, order=2, dt=DT).model for s in (slice(0, half), slice(half, None))]
    for r in rows:
        K = sy.hinf_design(sy.fit_predictor(d.u, d.y, r.horizon, dt=DT), W1, W2, dt=DT).controller
        radii = [_radius(M, K) for M in split]
        assert r.split_radii == pytest.approx(radii, rel=1e-9)
        assert r.spread == pytest.approx(max(abs(x - r.spectral_radius) for x in radii), rel=1e-9)
        assert r.margin_clear == (1 - r.spectral_radius > r.spread)
        assert r.passes == (r.stable and r.margin_clear and not r.cancels and r.settled)
    # what the result claims is said to be about the data's models, not the plant
    assert "not on the plant" in choice.reason and "none on the plant" in choice.assumptions
    assert f"i = {h}" in choice.assumptions and "unfalsify.robust_design_from_data" in choice.assumptions


def test_a_margin_on_the_model_that_the_split_models_do_not_vouch_for_is_refused():
    # the case that passed the checks on P̂ alone (experiments compare, three-disk y3, n = 4096, seed 4,
    # 1.35 γ_min): at i = 50 the loop with P̂ has radius 0.9997, the split models move it by 0.004, and the
    # loop with the plant is unstable
    P = three_disk("y3")
    dt = float(P.dt)
    W1, W2 = torsional_weights("noncollocated", dt)
    d = collect_data(P, prbs(4096, 10), process_noise=0.05, sensor_noise=0.01, seed=104)
    with pytest.warns(sy.HorizonChoiceWarning, match="no candidate horizon passes") as caught:
        choice = sy.choose_horizon(d.u, d.y, W1, W2, dt=dt, gamma_ratio=1.35)
    assert str(caught[0].message) == f"choose_horizon: {choice.reason}"  # the fallback is not silent
    row = {r.horizon: r for r in choice.candidates}[50]
    assert row.stable and row.settled and not row.cancels and not row.margin_clear
    K = sy.hinf_design(sy.fit_predictor(d.u, d.y, 50, dt=dt), W1, W2, gamma_ratio=1.35, dt=dt).controller
    assert _radius(P, K) > 1                                              # unstable on the TRUE plant
    assert not choice.ok and "i = 50: margin on P̂ not clear of the split spread" in choice.reason
    assert not any(r.passes for r in choice.candidates)


def test_a_record_too_short_to_split_fails_the_margin_check_and_says_how_long():
    W = design_weights(DT)
    d = collect_data(third_order(), prbs(200, seed=0))                    # noise-free: P̂ has the plant's order 3
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")                                   # noise-free: rank-deficient regressors
        short = sy.choose_horizon(d.u[:85], d.y[:85], W["W11"], W["W21"], dt=DT, horizons=(6, 7))
        enough = sy.choose_horizon(d.u[:86], d.y[:86], W["W11"], W["W21"], dt=DT, horizons=(6, 7))
    assert short.model_order == enough.model_order == 3
    # 42-sample halves support i = 3 at 3 columns per regressor, which cannot carry order 3; 43 support i = 4
    assert short.split_models == () and not short.ok
    assert all(r.split_radii == () and r.spread == np.inf and not r.margin_clear for r in short.candidates)
    assert "too short to split" in short.reason and "collect at least 86 samples" in short.reason
    assert "could not run" in short.assumptions
    assert len(enough.split_models) == 2 and "too short to split" not in enough.reason
    assert all(len(r.split_radii) == 2 and np.isfinite(r.spread) for r in enough.candidates)


def test_a_tight_settling_tolerance_is_not_met_and_says_so(nmp):
    _, W1, W2, d = nmp
    with pytest.warns(sy.HorizonChoiceWarning):
        choice = sy.choose_horizon(d.u, d.y, W1, W2, dt=DT, horizons=(10, 20, 30), settle_tol=1e-6)
    assert not choice.ok and "no candidate horizon passes" in choice.reason
    assert len(choice.candidates) == 3 and not any(r.settled for r in choice.candidates)


def test_an_easy_plant_takes_a_short_horizon_and_the_result_pickles():
    P = servo()
    W = design_weights(DT)
    d = collect_data(P, prbs(1000, seed=1), process_noise=0.05, sensor_noise=0.05, seed=101)
    with warnings.catch_warnings():
        warnings.simplefilter("error", sy.HorizonChoiceWarning)          # a passing choice does not warn
        choice = sy.choose_horizon(d.u, d.y, W["W11"], W["W21"], dt=DT)
    assert choice.ok and choice.horizon <= 20 and _radius(P, choice.design.controller) < 1
    again = pickle.loads(pickle.dumps(choice))
    assert again == choice and again.horizon == choice.horizon


def test_bad_input_names_the_fix(nmp):
    _, W1, W2, d = nmp
    with pytest.raises(sy.DataError, match="collect at least"):
        sy.choose_horizon(d.u[:150], d.y[:150], W1, W2, dt=DT)
    with pytest.raises(sy.DataError, match="distinct integers"):
        sy.choose_horizon(d.u, d.y, W1, W2, dt=DT, horizons=(10, 10.5))
    with pytest.raises(sy.DataError, match="two or more"):  # no candidate at all had raised IndexError
        sy.choose_horizon(d.u, d.y, W1, W2, dt=DT, horizons=())
    with pytest.raises(sy.DataError, match="two or more"):  # one had been refused as needing a longer record
        sy.choose_horizon(d.u, d.y, W1, W2, dt=DT, horizons=(3,))
    with pytest.raises(sy.DataError, match="dt"):
        sy.choose_horizon(d.u, d.y, W1, W2, dt=0)


def test_the_cancellation_check_sees_a_controller_pole_on_a_right_half_plane_zero():
    from synthesis.horizon import _cancels

    P = control.ss(control.tf([1.0, -1.2], [1.0, -0.5, 0.06], DT))     # zero at z = 1.2
    assert _cancels(P, control.ss(control.tf([1.0], [1.0, -1.21], DT)), 0.02)
    assert not _cancels(P, control.ss(control.tf([1.0], [1.0, -1.3], DT)), 0.02)
    assert not _cancels(control.ss(control.tf([1.0, -0.8], [1.0, -0.5, 0.06], DT)),   # a zero inside: no check
                        control.ss(control.tf([1.0], [1.0, -0.8], DT)), 0.02)
