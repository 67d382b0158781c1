"""The §7.4 pipeline's loop side for several inputs and outputs: steps per channel, the small gain with
the largest singular value, per-channel tracking floors, MIMO persistence and record windows, weights."""
import warnings

import control
import numpy as np
import pytest

import synthesis as sy
import unfalsify as uf
from synthesis import DataError, WeightError
from unfalsify import robust, tracking


def _mixing_plant(G, a=0.7, dt=1.0):
    """``y = G · (1 − a)/(z − a) u``: unit-DC first-order lags mixed by the static ``G`` (l × m)."""
    G = np.asarray(G, float)
    l, m = G.shape
    return control.ss(a * np.eye(m), (1 - a) * np.eye(m), G, np.zeros((l, m)), dt)


def _static_controller(k: float, l: int, m: int, dt=1.0):
    """``u = k·(r − y)`` (m = l), inputs ``[r; y]``."""
    D = np.hstack([k * np.eye(m, l), -k * np.eye(m, l)])
    return control.ss([], [], [], D, dt)


@pytest.mark.parametrize("G", [[[1.0, 0.3], [0.2, 0.8]], [[1.0, -0.5], [0.4, 1.2]]])
def test_step_per_channel_equals_the_closed_form_dc_error(G):
    G = np.asarray(G)
    P, K = _mixing_plant(G), _static_controller(0.5, 2, 2)
    step = uf.step_metrics(uf.closed_loop_ry(P, K), 400)
    T1 = np.linalg.solve(np.eye(2) + 0.5 * G, 0.5 * G)             # closed form of T(1)
    assert step.channel_errors.shape == (2, 2)
    np.testing.assert_allclose(step.channel_errors, np.abs(np.eye(2) - T1), atol=1e-6)
    assert step.final_error == pytest.approx(np.max(np.abs(np.eye(2) - T1)), abs=1e-6)
    np.testing.assert_allclose(step.output_errors(), np.max(np.abs(np.eye(2) - T1), axis=1), atol=1e-6)


def test_step_per_channel_sees_coupling_that_a_joint_step_hides():
    # T(1) = [[0.5, 0.5], [0.5, 0.5]] maps r = [1, 1] to y = [1, 1] but r = e_0 to [0.5, 0.5]
    loop = control.ss([], [], [], [[0.5, 0.5], [0.5, 0.5]], 1.0)
    step = uf.step_metrics(loop, 40)
    assert step.final_error == pytest.approx(0.5)
    y_joint = loop.D @ np.ones(2)
    assert np.allclose(y_joint, 1.0)                                   # the joint step looked perfect


def test_siso_step_is_unchanged():
    P, K = _mixing_plant([[1.0]]), _static_controller(2.0, 1, 1)
    step = uf.step_metrics(uf.closed_loop_ry(P, K), 300)
    assert step.final_error == pytest.approx(abs(1 - 2.0 / 3.0), abs=1e-9)   # T(1) = 2/(1 + 2)
    assert step.channel_errors.shape == (1, 1)


@pytest.mark.parametrize("shape", [(2, 2), (2, 1), (1, 2)])
def test_certify_loop_small_gain_is_the_largest_singular_value(shape):
    l, m = shape
    rng = np.random.default_rng(l + 3 * m)
    A = rng.standard_normal((3, 3))
    A *= 0.5 / np.max(np.abs(np.linalg.eigvals(A)))                 # spectral radius 0.5
    P = control.ss(A, rng.standard_normal((3, m)), 0.3 * rng.standard_normal((l, 3)), np.zeros((l, m)), 1.0)
    K = control.ss([], [], [], 0.2 * rng.standard_normal((m, 2 * l)), 1.0)
    cert = uf.certify_loop(P, K, 0.01, tracking_floor=10.0)
    assert cert.stable
    M = uf.additive_channel(P, K)
    w = np.linspace(0, np.pi, 2001)
    grid = max(np.linalg.norm(np.atleast_2d(M(np.exp(1j * x))), 2) for x in w)
    assert cert.norm.lower <= grid * (1 + 1e-9) and grid <= cert.norm.upper * (1 + 1e-9)
    assert cert.small_gain == pytest.approx(0.01 * cert.norm.upper)


def test_tracking_floor_per_channel():
    G = np.array([[1.0, 0.0], [0.0, 1.0]])
    P, K = _mixing_plant(G), _static_controller(4.0, 2, 2)   # T(1) = 0.8 I: error 0.2 on each channel
    assert not uf.certify_loop(P, K, 0.0, tracking_floor=0.1).certified
    cert = uf.certify_loop(P, K, 0.0, tracking_floor=[0.3, 0.25])
    assert cert.certified and cert.tracking_floor == (0.3, 0.25) and cert.tracks
    cert = uf.certify_loop(P, K, 0.0, tracking_floor=[0.3, 0.1])
    assert not cert.certified and "on output 1" in cert.reason
    with pytest.raises(DataError, match="one per output channel"):
        uf.certify_loop(P, K, 0.0, tracking_floor=[0.3, 0.1, 0.2])
    with pytest.raises(DataError, match=r"tracking_floor\[1\]"):
        uf.tracking_floors([0.1, -1.0], 2)
    for bad in (2.0, 0, "2", True):  # 2.0 had been taken as two channels
        with pytest.raises(DataError, match=r"channels \(the plant's outputs l\) must be an integer ≥ 1"):
            uf.tracking_floors(0.1, bad)


def test_steady_state_across_the_ball_is_judged_per_channel():
    G = np.eye(2)
    P, K = _mixing_plant(G), _static_controller(4.0, 2, 2)
    assert tracking._steady_state_reason(P, K, 0.01, 0.25) == ""
    why = tracking._steady_state_reason(P, K, 0.01, [0.25, 0.1])
    assert "on output" in why and "steady-state tracking error" in why
    # the data's gain: with G_data = 0.2 I the loop leaves 1 − 0.8/1.8 on each channel
    why = tracking._steady_state_reason(P, K, 0.01, 0.25, data_gain=0.2 * np.eye(2))
    assert "low-frequency gain the data show" in why
    np.testing.assert_allclose(tracking._dc_errors_at_gain(K, 0.2 * np.eye(2), uf.tracking_floors(0.25, 2)),
                               [1 - 0.8 / 1.8] * 2)


def test_persistence_of_a_mimo_window():
    rng = np.random.default_rng(0)
    u = np.sign(rng.standard_normal((200, 2)))
    assert robust._persistence_reason(object(), u, 4, "predictor") == ""
    twin = np.column_stack([u[:, 0], u[:, 0]])                   # both inputs the same: rank 2i, not 4i
    why = robust._persistence_reason(object(), twin, 4, "predictor")
    assert "not persistently exciting" in why and "of 16" in why


def test_record_mode_auto_window_counts_the_regressors_of_several_channels():
    rng = np.random.default_rng(1)
    u, y = rng.standard_normal((600, 2)), rng.standard_normal((600, 2))
    uw, yw, val, pred, _, span = robust._record_mode(u, y, 3, "auto", None, None, None)
    assert span == (0, uw.shape[0])
    j = uw.shape[0] - 2 * 3 + 1
    assert j == 3 * 3 * (2 * 2 + 2) and uw.shape[1] == 2 and yw.shape[1] == 2
    assert val[0].shape == (200, 2) and pred.m == 2 and pred.l == 2


def test_solve_estimate_grows_with_the_channels():
    t1, m1 = uf.solve_estimate(10, 200, "structured")
    t4, m4 = uf.solve_estimate(10, 200, "structured", channels=(2, 2))
    assert t4 > 5 * t1 and m4 > m1


def test_diagonal_weight():
    W = sy.makeweight(10.0, (0.3, 1.0), 0.5, 1.0)
    D = sy.diagonal_weight(W, channels=3)
    assert (D.ninputs, D.noutputs, D.nstates) == (3, 3, 3)
    z = np.exp(0.4j)
    np.testing.assert_allclose(np.atleast_2d(D(z)), np.diag([complex(W(z))] * 3))
    with pytest.raises(WeightError, match="one weight"):
        sy.diagonal_weight(W, W, channels=2)
    with pytest.raises(WeightError, match="single-channel"):
        sy.diagonal_weight(D)
    with pytest.raises(WeightError, match="diagonal_weight"):
        sy.as_weight(W, "W1", inputs=2)


def test_mimo_pipeline_runs_to_a_verdict():
    """2 × 2 data: δ of (7.5), P̂ with 2 inputs and 2 outputs, a verdict with a reason when refused."""
    rng = np.random.default_rng(0)
    n = 900
    P = _mixing_plant([[1.0, 0.3], [0.2, 0.8]])
    u = np.sign(rng.standard_normal((n, 2)))
    y = control.forced_response(P, T=np.arange(n), U=u.T).outputs.T + 0.01 * rng.standard_normal((n, 2))
    W1 = sy.diagonal_weight(sy.makeweight(100, (np.pi / 30, 1), 0.2, 1.0), channels=2)
    W2 = sy.diagonal_weight(sy.makeweight(0.05, (np.pi / 10, 0.3), 1, 1.0), channels=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rd = uf.robust_design_from_data(u, y, 2, W1, W2, "auto", window="auto", dt=1.0, search=False)
    assert rd.model.ninputs == 2 and rd.model.noutputs == 2
    assert rd.delta >= rd.unfalsification.delta * (1 - 1e-9)
    assert rd.unfalsification.certificate.verify()
    assert rd.certified or rd.reason


@pytest.mark.filterwarnings("ignore:regressor")  # noise-free data: the rank warning is expected
@pytest.mark.parametrize("shape", [(2, 2), (2, 1), (1, 2)])
def test_predictor_model_reproduces_a_mimo_plant_from_noise_free_data(shape):
    l, m = shape
    P = control.ss(np.diag([0.8, 0.5]), np.arange(1.0, 1.0 + 2 * m).reshape(2, m) / 3,
                   np.arange(1.0, 1.0 + 2 * l).reshape(l, 2)[:, ::-1] / 4, np.zeros((l, m)), 1.0)
    rng = np.random.default_rng(5)
    u = rng.standard_normal((400, m))
    y = control.forced_response(P, T=np.arange(400), U=u.T).outputs.reshape(l, 400).T
    Ph = uf.predictor_model(sy.fit_predictor(u, y, 3), 1.0)
    assert (Ph.noutputs, Ph.ninputs, Ph.nstates) == (l, m, 3 * (m + l))
    for w in (0.05, 0.7, 2.5):
        z = np.exp(1j * w)
        np.testing.assert_allclose(np.atleast_2d(Ph(z)), np.atleast_2d(P(z)).reshape(l, m), atol=1e-7)


def test_untracked_outputs_of_a_tall_plant():
    """2 × 1: one input cannot track two independent references; inf marks the output not tracked."""
    P = _mixing_plant([[1.0], [0.5]])
    K = control.ss([], [], [], [[2.0, 0.0, -2.0, 0.0]], 1.0)       # u = 2(r0 − y0), output 1 ignored
    cert = uf.certify_loop(P, K, 0.0, tracking_floor=0.4)
    assert not cert.certified and "fewer inputs (1) than outputs (2)" in cert.reason
    cert = uf.certify_loop(P, K, 0.0, tracking_floor=[0.4, float("inf")])
    assert cert.certified and cert.tracks, cert.reason              # T(1) = 2/3 on output 0: error 1/3
    assert cert.step.output_errors([True, False])[0] == pytest.approx(1 / 3, abs=1e-6)
    assert tracking._steady_state_reason(P, K, 0.01, [0.4, float("inf")]) == ""
    with pytest.raises(DataError, match="at least one output"):
        uf.tracking_floors([float("inf")] * 2, 2)
