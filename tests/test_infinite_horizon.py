"""Discrete ∞-horizon H∞ mixed sensitivity (bilinear map + SB10AD + bisection)."""
import control as ct
import numpy as np
import pytest

import synthesis
from experiments.lab.plants import servo
from synthesis.infinite_horizon import discrete_mixsyn, mixsyn_closed_loop, peak_gain

s = ct.tf("s")


def _grid_norm(P, K, W1, W2, n=20000):
    """‖[W1 S; W2 K S]‖∞ by brute force on the transfer functions (SISO), independent of the LFT code."""
    w = np.linspace(1e-6, np.pi, n)
    z = np.exp(1j * w)
    Pz, Kz, W1z, W2z = (np.array([np.squeeze(G(zz)) for zz in z]) for G in (P, K, W1, W2))
    S = 1.0 / (1.0 + Pz * Kz)
    return np.sqrt(np.abs(W1z * S) ** 2 + np.abs(W2z * Kz * S) ** 2).max(), w, Pz, W1z, W2z


def test_static_problem_closed_form():
    # P = p, W1 = w1, W2 = w2: min_k sqrt(w1^2 + w2^2 k^2)/|1 + p k| = w1 w2 / sqrt(w2^2 + p^2 w1^2)
    p, w1, w2 = 2.0, 3.0, 0.5
    P = ct.ss([[0.5]], [[0.0]], [[0.0]], [[p]], 0.1)  # one stable, uncontrollable state
    res = discrete_mixsyn(P, w1, w2, rtol=1e-6)
    expect = w1 * w2 / np.sqrt(w2**2 + p**2 * w1**2)
    assert res.epsilon == 0.0
    np.testing.assert_allclose(res.gamma_opt, expect, rtol=1e-4)
    assert res.gamma_opt >= expect * (1 - 1e-9)
    assert res.norm <= res.gamma * (1 + 1e-9)


def _servo_weights(dt=0.1):
    W1 = synthesis.tustin(100 * (0.01 / 5) * (s + 5) / (s + 0.01), dt)
    W2 = synthesis.tustin(0.05 * (10 / 0.5) * (s + 0.5) / (s + 10), dt)
    return W1, W2


@pytest.mark.slow
def test_servo_design_is_verified_independently():
    P = servo()
    W1, W2 = _servo_weights()
    res = discrete_mixsyn(P, W1, W2, gamma_ratio=1.1)
    K = res.controller
    assert K.dt == P.dt and (K.ninputs, K.noutputs) == (1, 1)
    assert res.epsilon > 0  # integrator: fictitious input disturbance used
    # closed loop stable (python-control feedback route)
    T = ct.feedback(P * K, 1)
    assert np.max(np.abs(T.poles())) < 1
    grid, w, Pz, W1z, W2z = _grid_norm(P, K, W1, W2)
    assert grid <= res.gamma * (1 + 1e-9)
    np.testing.assert_allclose(grid, res.norm, rtol=1e-4)
    pg = peak_gain(mixsyn_closed_loop(P, W1, W2, K))  # grid estimate: a lower bound
    assert res.bracket.lower >= pg * (1 - 1e-12) and pg <= res.norm == res.bracket.upper
    assert res.bracket.gap < 1e-7
    # pointwise (non-causal) lower bound max_w |W1 W2| / sqrt(|W2|^2 + |P W1|^2) <= gamma_opt
    lower = np.max(np.abs(W1z * W2z) / np.sqrt(np.abs(W2z) ** 2 + np.abs(Pz * W1z) ** 2))
    assert lower <= res.gamma_opt
    assert res.gamma_opt <= res.gamma <= 1.1 * res.gamma_opt * (1 + 1e-12)
    # a smaller epsilon changes gamma_opt very little (upper bounds converging)
    res2 = discrete_mixsyn(P, W1, W2, epsilon=1e-5, rtol=1e-3)
    assert abs(res2.gamma_opt - res.gamma_opt) < 2e-3 * res.gamma_opt
    # infeasible level
    with pytest.raises(synthesis.InfeasibleGammaError, match="gamma_opt = ") as err:
        discrete_mixsyn(P, W1, W2, gamma=0.9 * res.gamma_opt, rtol=1e-2)
    # the message is this problem's, not the finite-horizon game's saddle condition (3.29) it had cited
    assert "(3.29)" not in str(err.value) and "gamma_min" not in str(err.value)


def test_matches_continuous_hinfsyn_on_bilinear_equivalent_problem():
    dt = 0.05
    Pc = ct.ss(2 / (s + 1))
    W1c = ct.ss(0.5 * (s + 4) / (s + 0.2))
    W2c = ct.ss(0.2 * (s + 1) / (0.1 * s + 1))
    # continuous generalized plant [r; u] -> [W1 e; W2 u; e]
    Pgen = ct.interconnect(
        [ct.ss(Pc, inputs="u", outputs="y"), ct.ss(W1c, inputs="e", outputs="z1"),
         ct.ss(W2c, inputs="u", outputs="z2"), ct.summing_junction(["r", "-y"], "e")],
        inplist=["r", "u"], outlist=["z1", "z2", "e"])
    _, _, gam_c, _ = ct.hinfsyn(Pgen, 1, 1)
    tus = lambda G: ct.ss(ct.sample_system(G, dt, method="bilinear"))  # noqa: E731  (z = (1+s dt/2)/(1-s dt/2))
    res = discrete_mixsyn(tus(Pc), tus(W1c), tus(W2c), rtol=1e-5)
    assert res.epsilon == 0.0
    np.testing.assert_allclose(res.gamma_opt, gam_c, rtol=2e-3)


def test_refuses_bad_input():
    W1, W2 = _servo_weights()
    with pytest.raises(ValueError, match="continuous"):
        discrete_mixsyn(servo(continuous=True), W1, W2)
    with pytest.raises(ValueError):
        discrete_mixsyn(servo(), ct.ss([[0.5]], [[1.0]], [[1.0]], [[0.0]], 0.1), W2)  # W1 strictly proper
    with pytest.raises(ValueError):
        discrete_mixsyn(servo(), W1, W2, epsilon=0.0)  # unit-circle pole needs epsilon > 0


def test_peak_gain_checks_its_system():
    G = ct.tf([0.5], [1, -0.5], 0.1)  # |G| peaks at z = 1: 0.5 / 0.5 = 1
    assert peak_gain(G) == pytest.approx(1.0, rel=1e-9)  # a TransferFunction is accepted
    assert peak_gain(ct.ss(G)) == pytest.approx(1.0, rel=1e-9)
    assert peak_gain(ct.tf([1], [1, -1.5], 0.1)) == np.inf  # unstable: the H∞ norm is infinite
    assert peak_gain(ct.ss([[1.0]], [[1.0]], [[1.0]], [[0.0]], 0.1)) == np.inf  # pole on the unit circle
    assert peak_gain(ct.ss([], [], [], [[3.0, 4.0]], 0.1)) == pytest.approx(5.0)
    with pytest.raises(ValueError, match="continuous"):
        peak_gain(ct.tf([1], [1, 1]))


def test_closed_loop_checks_the_controller():
    P = servo()
    W1, W2 = _servo_weights()
    K = discrete_mixsyn(P, W1, W2).controller
    assert mixsyn_closed_loop(P, W1, W2, ct.tf(K)).dt == P.dt  # a TransferFunction controller is accepted
    with pytest.raises(ValueError, match="continuous"):
        mixsyn_closed_loop(P, W1, W2, ct.ss(-1.0, 1.0, 1.0, 0.0))
    with pytest.raises(ValueError, match="sample time"):
        mixsyn_closed_loop(P, W1, W2, ct.ss(0.5, 1.0, 1.0, 0.0, 0.2))
    with pytest.raises(ValueError, match="input"):
        mixsyn_closed_loop(P, W1, W2, ct.ss(0.5, [[1.0, 1.0]], 1.0, [[0.0, 0.0]], 0.1))


def test_bad_levels_are_refused_before_the_bisection(monkeypatch):
    import slycot

    def forbidden(*args, **kwargs):
        raise AssertionError("the level arguments must be checked before any synthesis")

    monkeypatch.setattr(slycot, "sb10ad", forbidden)
    W1, W2 = _servo_weights()
    for kw in (dict(gamma_ratio=0.5), dict(gamma_ratio="x"), dict(gamma=-1.0), dict(gamma="big"),
               dict(epsilon=-1e-4), dict(epsilon="small"), dict(rtol=0.0), dict(rtol=1.0)):
        with pytest.raises(synthesis.DataError):
            discrete_mixsyn(servo(), W1, W2, **kw)
