"""``synthesis.choose_horizon``: the horizon from the data, by a stated rule (issue 29, item 3)."""
import pickle

import control
import numpy as np
import pytest

import synthesis as sy
from experiments.lab.servo_setup import design_weights
from experiments.lab.plants import nonminimum_phase, servo
from experiments.lab.signals import prbs
from experiments.lab.simulate import closed_loop_system, collect_data

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
    # the §5.4 horizon on the same data: the design cancels the zero at e^{0.1} and is unstable
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


def test_a_tight_settling_tolerance_is_not_met_and_says_so(nmp):
    _, W1, W2, d = nmp
    choice = sy.choose_horizon(d.u, d.y, W1, W2, dt=DT, horizons=(10, 20, 30), settle_tol=1e-6)
    assert not choice.ok and "no candidate horizon passes" in choice.reason
    assert len(choice.candidates) == 3 and not any(r.settled for r in choice.candidates)


def test_an_easy_plant_takes_a_short_horizon_and_the_result_pickles():
    P = servo()
    W = design_weights(DT)
    d = collect_data(P, prbs(1000, seed=1), process_noise=0.05, sensor_noise=0.05, seed=101)
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
