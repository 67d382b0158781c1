"""Weighting filters: Tustin, checks, Markov Toeplitz (3.10) and observability (3.12) matrices."""
import control
import numpy as np
import pytest
from scipy import signal

from synthesis import DataError, InputTypeError, WeightError, as_weight, markov_toeplitz, observability, tustin
from synthesis.weights import common_dt, is_zero_weight

DT = 0.1


def _random_dss(n, p, q, seed):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    A *= 0.9 / max(abs(np.linalg.eigvals(A)))
    return control.ss(A, rng.standard_normal((n, q)), rng.standard_normal((p, n)), rng.standard_normal((p, q)), DT)


def test_tustin_matches_bilinear_frequency_map():
    s = control.tf("s")
    Wc = 100 * (0.01 / 5) * (s + 5) / (s + 0.01)
    Wd = tustin(Wc, DT)
    assert isinstance(Wd, control.StateSpace) and Wd.dt == DT
    # Tustin: Wd(e^{jωT}) = Wc(j (2/T) tan(ωT/2))
    for w in [0.01, 0.3, 3.0, 20.0]:
        z = np.exp(1j * w * DT)
        wc = 2 / DT * np.tan(w * DT / 2)
        assert np.isclose(Wd(z), Wc(1j * wc), rtol=1e-9)
    # DC gain 100 and Nyquist gain 0.2 (W1 is 100 at DC, 0.2 at high frequency)
    assert np.isclose(Wd(1.0), 100.0, rtol=1e-9)
    assert np.isclose(Wd(-1.0), 0.2, rtol=1e-9)


def test_tustin_keeps_a_high_order_weight_sampled_fast():
    # a sixth-order transfer function at dt = 1e-3: sampling its polynomial coefficients (the former route) gave a
    # frequency response off by up to 790 % (poles crowding z = 1); the state-space route is exact to rounding
    s = control.tf("s")
    Wc = 0.5
    for wn, zeta in [(1.0, 0.5), (5.0, 0.3), (20.0, 0.7)]:
        Wc = Wc * (s**2 + 1.8 * wn * s + wn**2) / (s**2 + 2 * zeta * wn * s + wn**2)
    dt = 1e-3
    Wd = tustin(Wc, dt)
    for w in [0.0, 0.1, 1.0, 5.0, 20.0, 300.0, 3000.0]:
        z = np.exp(1j * w * dt)
        assert np.isclose(complex(Wd(z)), complex(Wc(2 / dt * (z - 1) / (z + 1))), rtol=1e-10, atol=0)


def test_tustin_takes_a_mimo_transfer_function():
    # python-control cannot sample a MIMO transfer function (ControlMIMONotImplemented had escaped)
    Wc = control.tf([[[1, 1], [0.5]], [[0.2], [2, 1]]], [[[1, 3], [1, 2]], [[1, 4], [1, 5]]])
    Wd = tustin(Wc, DT)
    assert Wd.dt == DT and (Wd.noutputs, Wd.ninputs) == (2, 2)
    z = np.exp(0.7j * DT)
    assert np.allclose(Wd(z), Wc(2 / DT * (z - 1) / (z + 1)), rtol=1e-12, atol=0)


def test_tustin_rejects_discrete_and_bad_dt():
    s = control.tf("s")
    with pytest.raises(WeightError):
        tustin(control.ss(control.c2d(1 / (s + 1), DT)), DT)
    with pytest.raises(WeightError):
        tustin(1 / (s + 1), -1.0)


@pytest.mark.parametrize("p,q,n", [(1, 1, 2), (2, 3, 3), (3, 2, 4)])
def test_markov_toeplitz_equals_simulated_impulse_responses(p, q, n):
    sys = _random_dss(n, p, q, seed=p * 10 + q)
    i = 7
    H = markov_toeplitz(sys, i)
    assert H.shape == (i * p, i * q)
    for r in range(i):
        for c in range(r + 1, i):
            assert np.all(H[r * p:(r + 1) * p, c * q:(c + 1) * q] == 0)  # block lower triangular
    dsys = (sys.A, sys.B, sys.C, sys.D, DT)
    for c in range(q):
        for start in range(i):
            u = np.zeros((i, q))
            u[start, c] = 1.0  # unit pulse (no 1/dt scaling)
            _, y, _ = signal.dlsim(dsys, u)
            assert np.allclose(H[:, start * q + c], y.reshape(-1), atol=1e-12)


def test_observability_equals_free_response():
    sys = _random_dss(3, 2, 1, seed=5)
    i = 6
    G = observability(sys, i)
    assert G.shape == (12, 3)
    x0 = np.array([0.3, -1.0, 2.0])
    _, y, _ = signal.dlsim((sys.A, sys.B, sys.C, sys.D, DT), np.zeros((i, 1)), x0=x0)
    assert np.allclose(G @ x0, y.reshape(-1), atol=1e-12)
    # static weight: no states
    assert observability(as_weight(2.0, "W"), 4).shape == (4, 0)


def test_markov_toeplitz_of_unstable_integrator():
    # control.markov assumes stability; the servo plant has an integrator: h_k = C A^{k-1} B
    P = control.ss(control.c2d(control.tf([1], [1, 1, 0]), DT))
    H = markov_toeplitz(P, 40)
    h = H[:, 0]
    # ZOH pulse response = increments of the continuous step response t - 1 + e^{-t}
    t = np.arange(41) * DT
    step = t - 1 + np.exp(-t)
    assert h[0] == 0.0
    assert np.allclose(h[1:], np.diff(step)[:39], atol=1e-12)


def test_static_weights_and_transfer_functions():
    W = as_weight(3.0, "W1", inputs=1)
    assert W.nstates == 0 and np.allclose(W.D, 3.0)
    W = as_weight(np.eye(2) * 2, "W1", inputs=2)
    assert np.allclose(markov_toeplitz(W, 3), 2 * np.eye(6))
    z = control.tf("z")
    Wtf = (z - 0.5) / (z - 0.9)
    Wtf = control.tf(Wtf.num, Wtf.den, DT)
    W = as_weight(Wtf, "W2", inputs=1)
    assert isinstance(W, control.StateSpace) and W.dt == DT and W.nstates == 1
    assert np.allclose(markov_toeplitz(W, 3)[:, 0], [1.0, 0.4, 0.36])


def test_rejects_bad_weights():
    s = control.tf("s")
    with pytest.raises(WeightError, match="continuous"):
        as_weight((s + 1) / (s + 2), "W1")
    z = control.tf([1], [1, -0.5], DT)  # strictly proper: D = 0
    with pytest.raises(WeightError, match="relative degree 0"):
        as_weight(z, "W2")
    with pytest.raises(WeightError, match="NaN"):
        as_weight(np.array([[np.nan]]), "W1")
    with pytest.raises(WeightError, match="input"):
        as_weight(np.eye(2), "W1", inputs=1)
    with pytest.raises(WeightError, match="outputs"):
        as_weight(np.ones((1, 2)), "W1")
    with pytest.raises(WeightError):
        as_weight("abc", "W1")
    assert issubclass(WeightError, DataError) and issubclass(WeightError, ValueError)


def test_zero_weight_only_when_allowed():
    with pytest.raises(WeightError):
        as_weight(0.0, "W1")
    W = as_weight(0.0, "W3", allow_zero=True)
    assert is_zero_weight(W)
    Wz = control.ss([[0.5]], [[0.0]], [[1.0]], [[0.0]], DT)  # identically zero transfer function
    assert is_zero_weight(as_weight(Wz, "W4", allow_zero=True))
    assert not is_zero_weight(as_weight(1.0, "W3", allow_zero=True))


def test_common_dt():
    s = control.tf("s")
    a = tustin((s + 1) / (s + 2), 0.1)
    b = tustin((s + 1) / (s + 2), 0.2)
    with pytest.raises(WeightError, match="sample times"):
        common_dt(a, b)
    assert common_dt(a, as_weight(1.0, "W")) == 0.1
    assert common_dt(as_weight(1.0, "W")) is True
    # raw static weights (a number, a matrix), as the §7.4 pipeline receives them, have no sample time either
    assert common_dt(a, 5, np.eye(2), None) == 0.1 and common_dt(2.0) is True


def test_tustin_refuses_boolean_sample_time():
    s = control.tf("s")
    with pytest.raises(WeightError, match="dt"):
        tustin(1 / (s + 1), True)


def test_tustin_refuses_improper_and_nan_weights():
    """python-control's sampling had failed on these with a bare ValueError."""
    s = control.tf("s")
    with pytest.raises(WeightError, match="not proper.*add poles"):
        tustin(s + 1, 0.1)
    with pytest.raises(WeightError, match="NaN or infinite.*check how"):
        tustin(control.tf([np.nan], [1.0, 1.0]), 0.1)
    with pytest.raises(WeightError, match="NaN or infinite.*check how"):
        tustin(control.ss([[np.nan]], [[1.0]], [[1.0]], [[1.0]]), 0.1)


@pytest.mark.parametrize("dt", [-1, "x", 0, np.nan])
def test_as_weight_refuses_a_bad_sample_time(dt):
    """python-control had refused these with a bare ValueError ("invalid timebase")."""
    with pytest.raises(WeightError, match="dt must be a positive finite sample time or True"):
        as_weight(0.5, "W2", dt=dt)
    assert as_weight(0.5, "W2", dt=True).dt is True


def test_is_zero_weight_takes_systems_and_refuses_the_rest():
    """A transfer function is a system (had raised AttributeError); a number or a string is no system: the
    message names as_weight, which makes one."""
    assert is_zero_weight(control.tf([0.0], [1.0], DT))
    assert not is_zero_weight(control.tf([1.0], [1.0, -0.5], DT))
    for W in (0.0, "W3", np.zeros((1, 1))):
        with pytest.raises(InputTypeError, match=r"W must be a python-control StateSpace.*as_weight\(W, name\)"):
            is_zero_weight(W)


def test_markov_toeplitz_and_observability_refuse_continuous_time():
    s = control.tf("s")
    for f in (markov_toeplitz, observability):
        with pytest.raises(DataError, match="continuous"):
            f(1 / (s + 1), 3)
        with pytest.raises(DataError, match="NaN"):
            f(control.ss([[0.5]], [[1.0]], [[np.nan]], [[1.0]], DT), 3)
    # a static gain is the same in either time domain; arrays are static gains
    np.testing.assert_array_equal(markov_toeplitz(np.array([[2.0]]), 2), 2.0 * np.eye(2))
    np.testing.assert_array_equal(markov_toeplitz(control.ss([], [], [], [[2.0]]), 2), 2.0 * np.eye(2))
    assert observability(3.0, 2).shape == (2, 0)
