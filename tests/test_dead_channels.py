"""A record without a response is refused where the predictor is fitted, and the messages name the fix."""
import numpy as np
import pytest

import synthesis as sy
import unfalsify as uf


@pytest.fixture
def fir():
    rng = np.random.default_rng(0)
    u = rng.standard_normal(300)
    y = np.convolve(u, [0.0, 1.0, 0.5])[:300] + 0.01 * rng.standard_normal(300)
    return u, y


@pytest.fixture
def weights():
    return sy.makeweight(10.0, (0.3, 1.0), 0.5, 1.0), sy.makeweight(0.1, (2.0, 0.3), 1.0, 1.0)


@pytest.mark.parametrize("method", ["cholesky", "qr", "lstsq"])
def test_an_input_of_zeros_is_refused_not_fitted_to_a_zero_lu(fir, method):
    _, y = fir
    # before: a PersistenceWarning and L_u ≈ 0, from which hinf_design built a controller without a word
    with pytest.raises(sy.DataError, match=r"the input is zero on every sample of the record"):
        sy.fit_predictor(np.zeros(300), y, 4, method=method)
    u2 = np.column_stack([fir[0], np.zeros(300)])
    with pytest.raises(sy.DataError, match=r"input u\[:, 1\] is zero on every sample of the record"):
        sy.fit_predictor(u2, y, 4, method=method)


@pytest.mark.parametrize("level", [0.0, 2.5])
def test_a_constant_output_is_refused(fir, level):
    u, _ = fir
    with pytest.raises(sy.DataError, match=r"the output is constant .* on every sample of the record"):
        sy.fit_predictor(u, np.full(300, level), 4)


def test_a_moving_record_is_fitted_as_before(fir):
    u, y = fir
    pred = sy.fit_predictor(u, y, 4)
    assert np.allclose(pred.Lu[1:3, 0], [1.0, 0.5], atol=0.02)   # the plant's Markov parameters, second route: FIR taps
    u1 = u.copy()
    u1[:150] = 0.0                                               # an input at rest for half the record still moves
    sy.fit_predictor(u1, y, 4)


def test_a_recursive_predictor_passed_for_a_predictor_names_its_predictor_method(fir, weights):
    u, y = fir
    rp = sy.RecursivePredictor(4, 1, 1)
    W1, W2 = weights
    with pytest.raises(sy.DataError, match=r"pass its rp\.predictor\(\)"):
        sy.hinf_design(rp, W1, W2, dt=1.0)
    with pytest.raises(sy.DataError, match="use fit_predictor"):
        sy.hinf_design(object(), W1, W2, dt=1.0)


def test_a_weight_for_other_channels_says_what_to_build(fir, weights):
    u, y = fir
    pred = sy.fit_predictor(u, y, 4)
    W1, W2 = weights
    with pytest.raises(sy.WeightError, match=r"build W1 for the predictor's 1 channel"):
        sy.hinf_design(pred, sy.diagonal_weight(W1, channels=2), W2, dt=1.0)


def test_a_predictor_of_another_horizon_names_both_fixes(fir, weights):
    u, y = fir
    pred = sy.fit_predictor(u, y, 5)
    W1, W2 = weights
    with pytest.raises(sy.DataError, match=r"fit_predictor\(u, y, 3\)\) or pass horizon=5"):
        uf.robust_design_from_data(u[:45], y[:45], 3, W1, W2, "auto", predictor=pred, dt=1.0)


def test_a_past_window_with_time_along_axis_1_is_told_to_transpose(fir):
    u, y = fir
    pred = sy.fit_predictor(u, y, 3)
    with pytest.raises(sy.DataError, match=r"with time along axis 1 \(shape \(1, 3\)\) pass u_past\.T"):
        pred.past_vector(u[:3][None, :], y[:3, None])
    assert np.array_equal(pred.past_vector(u[:3, None], y[:3, None]), np.concatenate([u[:3], y[:3]]))
    with pytest.raises(sy.DataError, match="channel") as info:                   # a real channel mismatch
        pred.past_vector(np.zeros((5, 2)), y[:5, None])
    assert ".T" not in str(info.value)
