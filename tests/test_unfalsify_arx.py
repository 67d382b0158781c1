"""ARX uncertainty-model unfalsification (7.4): both LMI forms, certificates, known-Δ data, errors."""
import warnings

import cvxpy as cp
import numpy as np
import pytest
import scipy.linalg
import scipy.signal

import unfalsify as uf
from synthesis import DataError

from _quiet import quiet  # tests/ helper
from _servo_arx import A_SERVO, B_SERVO, servo_arx_data  # tests/ helper

# servo 1/(s(s+1)) ZOH at 10 Hz, as an ARX(2, 2) model (coefficients rounded)
_data = servo_arx_data


def test_regressor_matches_thesis_definition():
    u, y = _data(12, 0)
    na, nb = 2, 3
    Phi, Y = uf.arx_regressor(u, y, na, nb)
    ref = np.zeros((12, na + nb))
    for t in range(12):
        for k in range(1, na + 1):
            ref[t, k - 1] = y[t - k] if t - k >= 0 else 0.0
        for k in range(1, nb + 1):
            ref[t, na + k - 1] = -u[t - k] if t - k >= 0 else 0.0
    np.testing.assert_array_equal(Phi, ref)
    np.testing.assert_array_equal(Y, y)
    # least squares (7.2): θ = −(ΦᵀΦ)⁻¹ΦᵀY, an independent route via the normal equations
    theta, rms = uf.arx_least_squares(u, y, na, nb)
    np.testing.assert_allclose(theta, -np.linalg.solve(Phi.T @ Phi, Phi.T @ Y), rtol=1e-8)
    assert rms == pytest.approx(np.linalg.norm(Phi @ theta + Y) / np.sqrt(12))


def test_sigma_above_least_squares_residual_gives_zero_delta():
    u, y = _data(25, 1)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    res = uf.arx_unfalsify(u, y, 2, 2, 1.01 * rms)
    assert res.status == "optimal"
    assert abs(res.delta) < 1e-6
    assert np.abs(res.impulse).max() < 1e-5
    assert res.certificate.noise_rms <= 1.01 * rms * (1 + 1e-6)


def test_delta_decreases_with_sigma_and_is_certified():
    u, y = _data(25, 2)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    deltas = []
    for frac in (0.3, 0.6, 0.9):
        res = uf.arx_unfalsify(u, y, 2, 2, frac * rms)
        assert res.status == "optimal"
        cert = res.certificate
        # independent check: ‖T(h)‖₂ and the rms of ξ = Φθ + Y − T(u)h
        assert cert.ok(1e-5), cert
        Phi, Y = uf.arx_regressor(u, y, 2, 2)
        np.testing.assert_allclose(res.noise, Phi @ res.theta + Y - uf.toeplitz_matrix(u) @ res.impulse, atol=1e-12)
        deltas.append(res.delta)
    assert deltas[0] > deltas[1] > deltas[2] > 0


def test_known_perturbation_bounds_delta():
    # data from an ARX(2,2) model plus Δ(q)u with ‖Δ‖∞ = δ₀ (a delay beyond nb, not absorbable by B)
    # plus noise ξ; σ = rms(ξ) makes (θ_true, ξ_true, h_Δ) feasible, so δ_unf ≤ ‖T(h_Δ)‖ ≤ δ₀
    rng = np.random.default_rng(3)
    n, delta0 = 28, 0.05
    u = np.sign(rng.standard_normal(n))
    xi = 0.01 * rng.standard_normal(n)
    dlt_b = delta0 * np.array([0, 0, 0, 0, 0.6, 0.4])  # ‖·‖∞ = δ₀ (at DC; positive taps)
    e = xi + scipy.signal.lfilter(dlt_b, [1.0], u)
    y = scipy.signal.lfilter(B_SERVO, A_SERVO, u) + scipy.signal.lfilter([1.0], A_SERVO, e)
    sigma = np.linalg.norm(xi) / np.sqrt(n)
    res = uf.arx_unfalsify(u, y, 2, 2, sigma)
    assert res.status == "optimal"
    assert res.delta <= delta0 * (1 + 1e-5)
    assert res.delta > 0.1 * delta0  # measured 0.68 δ₀ (seed 3): the perturbation is detected
    # the true θ is a feasible point: e(θ_true) − ξ = Δu, so the certificate of the truth is ≤ δ₀
    theta_true = np.r_[A_SERVO[1:], B_SERVO[1:]]
    Phi, Y = uf.arx_regressor(u, y, 2, 2)
    h_true = uf.deconvolve(u, Phi @ theta_true + Y - xi, exact=True)
    assert uf.toeplitz_norm(h_true) <= delta0 * (1 + 1e-6)


@pytest.mark.parametrize("n", [12, 20])
def test_conditioned_and_thesis_forms_agree(n):
    u, y = _data(n, 4 + n)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    rc = uf.arx_unfalsify(u, y, 2, 2, 0.5 * rms)
    rt = quiet(uf.arx_unfalsify, u, y, 2, 2, 0.5 * rms, form="thesis")
    assert rc.status == "optimal"
    assert rt.status in ("optimal", "optimal_inaccurate")
    assert rt.delta == pytest.approx(rc.delta, rel=1e-4)
    np.testing.assert_allclose(rt.theta, rc.theta, atol=1e-3)
    # the literal solution, checked through the generalised pencil of (7.4): the smallest δ that
    # its own ξ certifies, λ_max(T(e−ξ)ᵀT(e−ξ), T(u)ᵀT(u)), is its certificate value
    Phi, Y = uf.arx_regressor(u, y, 2, 2)
    g = Phi @ rt.theta + Y - rt.noise
    Tu, Tg = uf.toeplitz_matrix(u), uf.toeplitz_matrix(g)
    lam = scipy.linalg.eigh(Tg.T @ Tg, Tu.T @ Tu, eigvals_only=True)[-1]
    assert np.sqrt(lam) == pytest.approx(rt.certificate.delta_certified, rel=1e-4)
    assert rt.certificate.delta_certified == pytest.approx(rc.delta, rel=1e-3)


def test_pencil_check_of_conditioned_solution():
    # independent of the Toeplitz-norm route: δ² T(u)ᵀT(u) − T(e−ξ)ᵀT(e−ξ) ⪰ 0 (7.4) at the returned point
    u, y = _data(14, 9)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    res = uf.arx_unfalsify(u, y, 2, 2, 0.5 * rms)
    Phi, Y = uf.arx_regressor(u, y, 2, 2)
    g = Phi @ res.theta + Y - res.noise
    Tu, Tg = uf.toeplitz_matrix(u), uf.toeplitz_matrix(g)
    lam = scipy.linalg.eigh(Tg.T @ Tg, Tu.T @ Tu, eigvals_only=True)[-1]
    assert np.sqrt(lam) <= res.delta * (1 + 1e-5)
    assert np.sqrt(lam) >= res.delta * (1 - 1e-3)  # optimal: the bound is active


def test_problem_is_exposed_and_solver_is_explicit():
    u, y = _data(12, 10)
    res = uf.arx_unfalsify(u, y, 1, 1, 0.01)
    assert isinstance(res.problem, cp.Problem)
    assert res.problem.solver_stats.solver_name == "CLARABEL"
    assert res.form == "conditioned" and res.a.shape == (1,) and res.b.shape == (1,)
    assert res.solve_time > 0 and np.isfinite(res.cond_Tu)


def test_non_optimal_status_is_warned_and_delta_is_nan():
    u, y = _data(20, 11)
    with pytest.warns(uf.SolverWarning):
        res = uf.arx_unfalsify(u, y, 2, 2, 0.01, solver_options={"max_iter": 1})
    assert res.status == "user_limit"  # Clarabel's MaxIterations
    assert np.isnan(res.delta)  # never a δ from a failed solve


def test_infeasible_status_raises(monkeypatch):
    u, y = _data(10, 12)

    def fake_solve(self, *a, **k):
        self._status = cp.INFEASIBLE
        return None

    monkeypatch.setattr(cp.Problem, "solve", fake_solve)
    monkeypatch.setattr(cp.Problem, "status", property(lambda self: self._status))
    with pytest.raises(uf.UnfalsificationError):
        uf.arx_unfalsify(u, y, 1, 1, 0.01)


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(u=[0.0, 1, 1, -1, 1], y=[5.0, 0, 1, 1, 0]),  # u0 = 0 and an output there beyond the noise budget
        dict(u=[1.0, np.nan, 1, -1, 1], y=[0.0, 0, 1, 1, 0]),  # NaN
        dict(u=[1.0, 1, 1, -1, 1], y=[0.0, 0, 1, 1]),  # lengths
        dict(u=[1.0, 1, 1, -1, 1], y=[0.0, 0, 1, 1, 0], sigma=0.0),  # σ ≤ 0
        dict(u=[1.0, 1, 1, -1, 1], y=[0.0, 0, 1, 1, 0], sigma=-1.0),
        dict(u=[1.0, 1, 1], y=[0.0, 0, 1], na=2, nb=2),  # n ≤ na + nb
        dict(u=[1.0, 1, 1, -1, 1], y=[0.0, 0, 1, 1, 0], na=-1),
        dict(u=[1.0, 1, 1, -1, 1], y=[0.0, 0, 1, 1, 0], na=1.5),
    ],
)
def test_bad_input_raises(kwargs):
    args = dict(na=1, nb=1, sigma=0.1)
    args.update(kwargs)
    with pytest.raises(DataError):
        uf.arx_unfalsify(args.pop("u"), args.pop("y"), args.pop("na"), args.pop("nb"), args.pop("sigma"))


@pytest.mark.parametrize("na, nb", [(2, 40), (31, 0), (30, 1), (0, 30)])
def test_lags_beyond_the_record_name_the_least_length(na, nb):
    # nb = 40 on 30 samples had raised numpy's "could not broadcast input array from shape (29,) into shape (0,)"
    rng = np.random.default_rng(0)
    u, y = rng.standard_normal(30), rng.standard_normal(30)
    need = max(na, nb) + 1
    for f in (uf.arx_regressor, uf.arx_least_squares):
        with pytest.raises(DataError, match=rf"n = 30 samples but the lags reach back max\(na, nb\) = {need - 1}: "
                                            rf"record at least {need} samples"):
            f(u, y, na, nb)
        with pytest.raises(DataError, match="record at least"):
            f(np.column_stack([u, u]), y, na, nb)  # several channels: the same rule
    Phi, _ = uf.arx_regressor(u, y, 29, 2)  # the longest lag one sample inside the record: its column is y[0] alone
    assert Phi[:, 28].tolist() == [0.0] * 29 + [y[0]]


def test_unknown_form_raises():
    u, y = _data(8, 13)
    with pytest.raises(ValueError, match="form"):
        uf.arx_unfalsify(u, y, 1, 1, 0.1, form="inverse")


def test_record_not_at_rest_is_warned():
    """(7.4) takes the samples before the record as zero: a window cut mid-record is flagged."""
    from experiments.lab.plants import servo
    from experiments.lab.signals import prbs
    from experiments.lab.simulate import collect_data

    d = collect_data(servo(), prbs(1000, seed=0), process_noise=0.05, sensor_noise=0.05, seed=1)
    u, y = d.u[:, 0], d.y[:, 0]
    with warnings.catch_warnings():
        warnings.simplefilter("error", uf.NotAtRestWarning)
        uf.ArxProblem.from_data(u[:40], y[:40], 2, 2, 0.01)  # from rest: silent
    with pytest.warns(uf.NotAtRestWarning, match="does not start at rest"):
        uf.ArxProblem.from_data(u[500:540], y[500:540], 2, 2, 0.01)
