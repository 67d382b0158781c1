"""Subspace uncertainty-model unfalsification (7.5): forms, elimination of L, certificates, errors."""
import dataclasses
import warnings

import numpy as np
import pytest
import scipy.signal

import synthesis
import unfalsify as uf
from synthesis import DataError

from _servo_arx import servo_arx_data  # tests/ helper

_servo = servo_arx_data


def _ls_rms(u, y, i):
    A, Uf, Yf = uf.subspace_data(u, y, i)
    L = np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T
    return np.linalg.norm(Yf - L @ A) / np.sqrt(Yf.size)


def test_data_layout_matches_synthesis_predictor():
    u, y = _servo(40, 0)
    i = 4
    A, Uf, Yf = uf.subspace_data(u, y, i)
    j = 40 - 2 * i + 1
    assert A.shape == (3 * i, j) and Uf.shape == (i, j) and Yf.shape == (i, j)
    assert Uf[0, 5] == u[i + 5] and Yf[2, 7] == y[i + 2 + 7]
    # least squares on (A, Y_f) is the synthesis predictor (same column order [U_p; Y_p; U_f])
    pred = synthesis.fit_predictor(u, y, i, method="qr")
    L = np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T
    np.testing.assert_allclose(L, np.hstack([pred.Lw, pred.Lu]), atol=1e-8)


def test_sigma_above_least_squares_residual_gives_zero_delta():
    u, y = _servo(30, 1)
    i = 3
    rms = _ls_rms(u, y, i)
    res = uf.subspace_unfalsify(u, y, i, 1.01 * rms)
    assert res.status == "optimal"
    assert abs(res.delta) < 1e-6
    # the returned L is then (close to) a least-squares predictor
    assert res.certificate.noise_rms <= 1.01 * rms * (1 + 1e-6)


def test_noise_free_fir_plant_needs_no_uncertainty():
    # FIR plant of length ≤ i: y_f = L_true [W_p; U_f] exactly, any σ > 0 gives δ = 0
    rng = np.random.default_rng(2)
    u = np.sign(rng.standard_normal(30))
    y = scipy.signal.lfilter([0.0, 0.7, -0.3], [1.0], u)
    with warnings.catch_warnings():
        warnings.simplefilter("error", uf.SolverWarning)  # a zero answer at rounding level is attained, not a failure
        res = uf.subspace_unfalsify(u, y, 4, 1e-3)
    assert abs(res.delta) < 1e-6
    cert = res.certificate
    assert cert.ok() and cert.verify() and cert.max_violation <= 0.0
    # the zero level is rounding only: impulses of norm 1e-9 against a reported 0 are a violation
    worse = dataclasses.replace(cert, delta=0.0, upper_bound=1e-9)
    assert not worse.ok() and worse.max_violation == float("inf")


@pytest.mark.slow
def test_delta_decreases_with_sigma_and_is_certified():
    u, y = _servo(5 * 2 + 30 - 1, 3)
    i = 5
    rms = _ls_rms(u, y, i)
    deltas = []
    for frac in (0.3, 0.6, 0.9):
        res = uf.subspace_unfalsify(u, y, i, frac * rms)
        assert res.status == "optimal"
        assert res.certificate.ok(1e-5), res.certificate
        # independent re-check of the noise and every column's Toeplitz norm
        A, Uf, Yf = uf.subspace_data(u, y, i)
        Htil = np.column_stack([uf.toeplitz_matrix(Uf[:, k]) @ res.impulses[:, k] for k in range(Uf.shape[1])])
        Xi = Yf - np.hstack([res.Lw, res.Lu]) @ A - Htil
        np.testing.assert_allclose(res.noise, Xi, atol=1e-10)
        assert np.linalg.norm(Xi) / np.sqrt(Xi.size) <= frac * rms * (1 + 1e-5)
        norms = [np.linalg.norm(uf.toeplitz_matrix(res.impulses[:, k]), 2) for k in range(Uf.shape[1])]
        assert max(norms) <= res.delta * (1 + 1e-5)
        deltas.append(res.delta)
    assert deltas[0] > deltas[1] > deltas[2] > 0


def test_known_perturbation_bounds_delta():
    # FIR plant + LTI Δ (‖Δ‖∞ = δ₀) + noise: (L_true, Ξ_true, h_Δ) is feasible with σ = rms(Ξ_true),
    # so δ_unf ≤ max_k ‖T(h_Δ[:i])‖ ≤ δ₀
    rng = np.random.default_rng(4)
    i, j, delta0 = 4, 30, 0.2
    n = 2 * i + j - 1
    u = np.sign(rng.standard_normal(n))
    noise = 0.02 * rng.standard_normal(n)
    d_taps = delta0 * np.array([0.0, 0.0, 0.5, -0.5])  # ‖·‖∞ = δ₀ (at ω = π)
    y = scipy.signal.lfilter([0.0, 1.0, 0.5], [1.0], u) + scipy.signal.lfilter(d_taps, [1.0], u) + noise
    Nf = synthesis.block_hankel(noise, i, j, i)
    sigma = np.linalg.norm(Nf) / np.sqrt(i * j)
    res = uf.subspace_unfalsify(u, y, i, sigma)
    assert res.status == "optimal"
    assert res.delta <= delta0 * (1 + 1e-5)


@pytest.mark.parametrize("seed", [5, 6])
def test_forms_agree_on_tiny_problems(seed):
    u, y = _servo(2 * 3 + 12 - 1, seed)
    i = 3
    sigma = 0.5 * _ls_rms(u, y, i)
    rc = uf.subspace_unfalsify(u, y, i, sigma)
    re = uf.subspace_unfalsify(u, y, i, sigma, eliminate_L=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", uf.SolverWarning)
        rt = uf.subspace_unfalsify(u, y, i, sigma, form="thesis")
    assert rc.status == "optimal" and re.status == "optimal"
    assert rt.status in ("optimal", "optimal_inaccurate")
    assert re.delta == pytest.approx(rc.delta, rel=1e-5)
    assert rt.delta == pytest.approx(rc.delta, rel=1e-4)
    assert rt.certificate.delta_certified == pytest.approx(rc.delta, rel=1e-3)
    assert re.certificate.ok(1e-5) and rc.certificate.ok(1e-5)


def test_predictor_property_feeds_synthesis():
    u, y = _servo(30, 7)
    res = uf.subspace_unfalsify(u, y, 3, 0.02)
    pred = res.predictor
    assert isinstance(pred, synthesis.Predictor)
    np.testing.assert_array_equal(pred.Lw, res.Lw)
    np.testing.assert_array_equal(pred.Lu, res.Lu)
    assert (pred.horizon, pred.m, pred.l, pred.n_columns) == (3, 1, 1, 30 - 5)
    assert res.impulses.shape == (3, 25) and res.noise.shape == (3, 25)


def test_zero_first_inputs_beyond_the_noise_budget_are_refused_with_the_window():
    """Columns of U_f that start with a zero input leave their first output to the noise (exact, see
    tests/test_unfalsify_zero_start.py); with the predictor fixed and those outputs far beyond σ√N, no δ
    unfalsifies the data, and the message lists the zero samples and the window that would avoid them."""
    u, y = _servo(20, 8)
    u[3 + 4] = u[3 + 9] = 0.0  # (U_f)_{0,4} = u_{i+4}, (U_f)_{0,9}: a quantised input passes through 0 exactly
    y[3 + 4] = y[3 + 9] = 50.0
    pred = synthesis.fit_predictor(u, y, 3)
    with pytest.raises(DataError, match=r"zero at u\[7\], u\[12\]\).*samples 3 … 17 "):
        uf.subspace_unfalsify(u, y, 3, 0.05, predictor=pred)


@pytest.mark.parametrize(
    "u, y, i, sigma",
    [
        (np.r_[1.0, np.nan, np.ones(18)], np.ones(20), 3, 0.1),
        (np.ones(20), np.ones(19), 3, 0.1),
        (np.ones(20), np.ones(20), 11, 0.1),  # too few samples
        (np.ones(20), np.ones(20), 0, 0.1),
        (np.ones(20), np.ones(20), 3, 0.0),
        (np.ones((2, 20)), np.ones(20), 3, 0.1),  # time along axis 1 (several channels are accepted since issue 28)
    ],
)
def test_bad_input_raises(u, y, i, sigma):
    with pytest.raises(DataError):
        uf.subspace_unfalsify(u, y, i, sigma)


def test_eliminate_with_thesis_form_is_rejected():
    u, y = _servo(20, 9)
    with pytest.raises(ValueError):
        uf.subspace_unfalsify(u, y, 3, 0.05, form="thesis", eliminate_L=True)


@pytest.mark.slow
def test_fixed_predictor_delta_is_at_least_the_joint_delta():
    # (7.5) optimises over L; fixing L to the least-squares predictor can only increase δ
    u, y = _servo(2 * 4 + 30 - 1, 10)
    i = 4
    pred = synthesis.fit_predictor(u, y, i, method="qr")
    rms_ls = _ls_rms(u, y, i)
    sigma = 0.5 * rms_ls
    joint = uf.subspace_unfalsify(u, y, i, sigma)
    fixed = uf.subspace_unfalsify(u, y, i, sigma, predictor=pred)
    assert fixed.delta >= joint.delta * (1 - 1e-6)
    np.testing.assert_array_equal(fixed.Lw, pred.Lw)
    assert fixed.certificate.ok(1e-5)
    # σ above the fixed predictor's own residual rms: δ = 0
    zero = uf.subspace_unfalsify(u, y, i, 1.01 * rms_ls, predictor=pred)
    assert abs(zero.delta) < 1e-6


def test_fixed_predictor_with_wrong_horizon_raises():
    u, y = _servo(40, 11)
    pred = synthesis.fit_predictor(u, y, 3, method="qr")
    with pytest.raises(DataError, match="horizon"):
        uf.subspace_unfalsify(u, y, 4, 0.05, predictor=pred)


def _few_columns(i=24, j=40, seed=1):
    """A window with fewer columns than the rank of [W_p; U_f] (±1 servo input): L optimised fits it exactly."""
    u, y = servo_arx_data(2 * i + j - 1, seed)
    A, _, Yf = uf.subspace_data(u, y, i)
    assert np.linalg.matrix_rank(A) >= j
    return u, y, i, j, A, Yf


@pytest.mark.parametrize("backend", ["structured", "cvxpy"])
def test_no_more_columns_than_the_rank_warns_that_delta_is_zero_for_any_sigma(backend):
    # L optimised on j ≤ rank [W_p; U_f]: the projection onto 𝓛^⊥ = {0} is exactly zero, δ = 0 is certified, and the
    # user is told why the answer says nothing
    u, y, i, j, A, Yf = _few_columns()
    with pytest.warns(uf.FewDataWarning, match=rf"j = {j} columns: \[W_p; U_f\] has rank \d+ ≥ j"):
        r = uf.subspace_unfalsify(u, y, i, 0.05, backend=backend, progress=False)
    assert r.status == "optimal" and r.certificate.verify()
    assert r.delta <= 1e-9 and r.certificate.upper_bound <= 1e-9


def test_a_sigma_at_the_rounding_level_of_the_data_is_refused():
    # σ = ½ the least-squares residual rms of data a predictor fits exactly: rounding (2e-16). The structured solver had
    # raised its internal Stop out of subspace_unfalsify, and no certificate could be checked (noise 2× its budget)
    u, y, i, j, A, Yf = _few_columns()
    L = np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T
    sigma = 0.5 * float(np.linalg.norm(Yf - L @ A) / np.sqrt(Yf.size))
    assert sigma < 1e-13 * float(np.sqrt(np.mean(Yf**2)))
    for backend in ("structured", "cvxpy"):
        with pytest.raises(DataError, match="rounding level of the data .*pass sigma >"):
            uf.subspace_unfalsify(u, y, i, sigma, backend=backend, progress=False)
    with pytest.raises(DataError, match="rounding level"):
        uf.arx_unfalsify(u, y, 2, 2, 1e-18)
    floor = uf._common.NOISE_RESOLUTION * float(np.linalg.norm(Yf)) / np.sqrt(Yf.size)
    uf.SubspaceProblem.from_data(u, y, i, 1.01 * floor)  # just above the floor: accepted
    with pytest.raises(DataError):
        uf.SubspaceProblem.from_data(u, y, i, 0.99 * floor)


def test_a_fixed_predictor_on_few_columns_does_not_warn():
    # with L fixed (fitted on a longer record) the columns must be explained by the impulses alone: not vacuous
    i, j = 6, 12
    u, y = servo_arx_data(2 * i + 200 - 1, 2)
    pred = synthesis.fit_predictor(u, y, i)
    u, y = u[: 2 * i + j - 1], y[: 2 * i + j - 1]
    assert np.linalg.matrix_rank(uf.subspace_data(u, y, i)[0]) >= j
    with warnings.catch_warnings():
        warnings.simplefilter("error", uf.FewDataWarning)
        r = uf.subspace_unfalsify(u, y, i, 0.01, backend="structured", progress=False, predictor=pred)
    assert r.delta > 0 and r.certificate.verify()
