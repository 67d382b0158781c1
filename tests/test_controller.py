"""LTI controller (5.3)–(5.4) vs the step-by-step receding-horizon loop of §5.1, for every law."""
import dataclasses

import control
import numpy as np
import pytest
from scipy import signal

from synthesis import (
    Additive,
    DataError,
    Multiplicative,
    RecedingHorizonController,
    fit_predictor,
    hinf_design,
    tustin,
)
from synthesis.lqg import lqg_design

DT = 0.1


@pytest.fixture(scope="module")
def servo():
    rng = np.random.default_rng(0)
    Pd = control.ss(control.c2d(control.tf([1], [1, 1, 0]), DT))
    n = 2 * 20 + 600 - 1
    u = rng.choice([-1.0, 1.0], n)
    _, y, _ = signal.dlsim((Pd.A, Pd.B, Pd.C, Pd.D, DT), u + 0.05 * rng.standard_normal(n))
    y = y.ravel() + 0.05 * rng.standard_normal(n)
    pred = fit_predictor(u, y, 20)  # i = 20: §5.4.2, shorter horizons destabilise the loop
    s = control.tf("s")
    W1 = tustin(100 * (0.01 / 5) * (s + 5) / (s + 0.01), DT)
    W2 = tustin(0.05 * (10 / 0.5) * (s + 0.5) / (s + 10), DT)
    return Pd, pred, W1, W2


def _designs(pred, W1, W2):
    s = control.tf("s")
    W3 = tustin(0.3 * (s + 1) / (s + 10), DT)
    W4 = tustin(0.5 * (s + 2) / (s + 4), DT)
    return {
        "nominal": hinf_design(pred, W1, W2),
        "causal": hinf_design(pred, W1, W2, causal=True),
        "multiplicative": hinf_design(pred, W1, W2, uncertainty=Multiplicative(W3, W4)),
        "additive": hinf_design(pred, W1, W2, uncertainty=Additive(tustin(0.2 * (s + 3) / (s + 6), DT), W4)),
        "lqg": lqg_design(pred, 1.0, 0.01, dt=DT),
    }


def _closed_loop_two_ways(Pd, design, r, noise):
    """Simulate the plant by hand with (a) the LTI controller, (b) the receding-horizon loop."""
    K = design.controller
    Ak, Bk, Ck, Dk = (np.asarray(M) for M in (K.A, K.B, K.C, K.D))
    Ap, Bp, Cp = (np.asarray(M) for M in (Pd.A, Pd.B, Pd.C))
    N = len(r)
    # (a) LTI
    xp, xk = np.zeros(Ap.shape[0]), np.zeros(Ak.shape[0])
    ua, ya, states = np.zeros(N), np.zeros(N), []
    for k in range(N):
        y = (Cp @ xp).item() + noise[k]
        # strictly causal laws: u_k depends on the state only; the causal law also on r_k
        v = np.array([r[k], y])
        u = (Ck @ xk + Dk[:, :1] @ v[:1]).item()  # no feedthrough from y (Dk[:, 1] = 0)
        states.append(xk.copy())
        xk = Ak @ xk + Bk @ v
        xp = Ap @ xp + (Bp * u).ravel()
        ua[k], ya[k] = u, y
    # (b) receding horizon
    rh = RecedingHorizonController(design)
    xp = np.zeros(Ap.shape[0])
    ub = np.zeros(N)
    for k in range(N):
        y = (Cp @ xp).item() + noise[k]
        assert np.allclose(rh.state, states[k], atol=1e-9 * max(1, np.abs(states[k]).max()))
        u = rh.control(r[k]).item()
        rh.observe(u, y, r[k])
        xp = Ap @ xp + (Bp * u).ravel()
        ub[k] = u
    return ua, ub, ya


@pytest.mark.parametrize("law", ["nominal", "causal", "multiplicative", "additive", "lqg"])
def test_lti_and_receding_horizon_give_identical_controls(servo, law):
    Pd, pred, W1, W2 = servo
    design = _designs(pred, W1, W2)[law]
    assert np.all(np.asarray(design.controller.D)[:, 1:] == 0)  # no feedthrough from y
    N = 120
    r = np.where(np.arange(N) >= 5, 1.0, 0.0)
    noise = 0.01 * np.random.default_rng(3).standard_normal(N)
    ua, ub, ya = _closed_loop_two_ways(Pd, design, r, noise)
    assert np.max(np.abs(ua)) > 1e-3  # the loop actually did something
    assert np.allclose(ua, ub, rtol=1e-9, atol=1e-10 * np.abs(ua).max())


def test_lti_matrices_are_5_3_literally(servo):
    """Build (5.3)–(5.4) block by block from k1..k4 and compare."""
    _, pred, W1, W2 = servo
    d = hinf_design(pred, W1, W2)
    i, m, l = pred.horizon, pred.m, pred.l
    A1, B1 = np.asarray(W1.A), np.asarray(W1.B)
    A2, B2 = np.asarray(W2.A), np.asarray(W2.B)
    n1, n2 = A1.shape[0], A2.shape[0]
    G = d.gain[:m]
    k1, k2 = G[:, : i * m], G[:, i * m: i * (m + l)]
    k3, k4 = G[:, i * (m + l): i * (m + l) + n1], G[:, i * (m + l) + n1:]
    Sm = np.eye(i * m)[m:]
    Sl = np.eye(i * l)[l:]
    Z = np.zeros
    A = np.block([
        [np.vstack([Sm, k1]), np.vstack([Z(((i - 1) * m, i * l)), k2]), np.vstack([Z(((i - 1) * m, n1)), k3]),
         np.vstack([Z(((i - 1) * m, n2)), k4])],
        [Z((i * l, i * m)), np.vstack([Sl, Z((l, i * l))]), Z((i * l, n1)), Z((i * l, n2))],
        [Z((n1, i * m)), Z((n1, i * l)), A1, Z((n1, n2))],
        [B2 @ k1, B2 @ k2, B2 @ k3, A2 + B2 @ k4]])
    B = np.block([[Z((i * m, l)), Z((i * m, l))],
                  [Z((i * l, l)), np.vstack([Z(((i - 1) * l, l)), np.eye(l)])],
                  [B1, -B1],
                  [Z((n2, l)), Z((n2, l))]])
    K = d.controller
    assert np.allclose(K.A, A) and np.allclose(K.B, B)
    assert np.allclose(K.C, np.hstack([k1, k2, k3, k4])) and np.allclose(K.D, 0)
    assert K.nstates == i * (m + l) + n1 + n2 and K.dt == DT


def test_closed_loop_design1_is_stable(servo):
    Pd, pred, W1, W2 = servo
    d = hinf_design(pred, W1, W2)
    K = d.controller
    # negative feedback through the controller's y input, r as the reference
    cl = control.interconnect(
        [control.ss(Pd.A, Pd.B, Pd.C, Pd.D, DT, inputs="u", outputs="y", name="P"),
         control.ss(K.A, K.B, K.C, K.D, DT, inputs=["r", "y"], outputs="u", name="K")],
        inputs="r", outputs="y")
    assert max(abs(np.linalg.eigvals(cl.A))) < 1
    t, y = control.step_response(cl, T=np.arange(400) * DT)
    assert abs(y[-1] - 1) < 0.02  # the integral weight W1 makes the step error vanish


def test_set_design_swaps_gain_keeps_state(servo):
    _, pred, W1, W2 = servo
    d1 = hinf_design(pred, W1, W2, gamma_ratio=1.1)
    d2 = hinf_design(pred, W1, W2, gamma_ratio=2.0)
    rh = RecedingHorizonController(d1)
    rng = np.random.default_rng(0)
    for _ in range(15):
        u = rh.control()
        rh.observe(u, rng.standard_normal(), 1.0)
    before = rh.state.copy()
    rh.set_design(d2)
    assert np.array_equal(rh.state, before)
    u2 = rh.control()
    v = np.concatenate([before[: pred.horizon * 2], before[pred.horizon * 2:]])
    assert np.allclose(u2, d2.gain[:1] @ v)
    assert rh.plan.shape == (pred.horizon, 1) and np.allclose(rh.plan.ravel(), d2.gain @ v)
    with pytest.raises(DataError):
        rh.set_design(dataclasses.replace(d2, horizon=d2.horizon + 1))
    with pytest.raises(DataError, match="weight states"):
        rh.set_design(lqg_design(pred, 1.0, 0.01, dt=DT))


def test_receding_horizon_inputs(servo):
    _, pred, W1, W2 = servo
    rh = RecedingHorizonController(hinf_design(pred, W1, W2, causal=True))
    with pytest.raises(DataError, match="causal"):
        rh.control()
    with pytest.raises(DataError):
        rh.control([1.0, 2.0])
    with pytest.raises(DataError):
        rh.observe(np.nan, 0.0, 0.0)
    with pytest.raises(DataError, match="r_k"):  # a dynamic W1 needs r_k − y_k: omitting r_k would track 0
        rh.observe(0.0, 0.0)
    static = RecedingHorizonController(hinf_design(pred, 2.0, 0.5, dt=W1.dt))
    static.observe(0.0, 1.0)  # static W1: r_k cannot matter and may be omitted
    u_past = np.arange(20.0)
    y_past = -np.arange(20.0)
    rh.reset(u_past, y_past)
    i = pred.horizon
    assert np.allclose(rh.state[: 2 * i], np.r_[u_past[-i:], y_past[-i:]])
    with pytest.raises(DataError):
        rh.reset(u_past[:3])


def test_receding_horizon_refuses_text_and_complex_samples(servo):
    """Text had raised numpy's bare ValueError, a complex sample its TypeError; both name the sample now."""
    _, pred, W1, W2 = servo
    rh = RecedingHorizonController(hinf_design(pred, W1, W2, causal=True))
    with pytest.raises(DataError, match=r"r_k must be real numbers, not text \('a'\)"):
        rh.control("a")
    with pytest.raises(DataError, match=r"r_k is complex.*take the real part"):
        rh.control(1 + 1j)
    with pytest.raises(DataError, match="u_k must be real numbers, not text"):
        rh.observe("a", 0.0, 0.0)
    with pytest.raises(DataError, match="y_k is complex"):
        rh.observe(0.0, 1j, 0.0)
    with pytest.raises(DataError, match="r_k is complex"):
        rh.observe(0.0, 0.0, 1j)
    rh.observe(np.float32(0.5), 1, 0.0)  # numpy and integer samples stay accepted
    assert rh.control(np.int64(1)).shape == (pred.m,)


@pytest.mark.parametrize("law", ["nominal", "causal", "multiplicative", "additive"])
def test_mimo_lti_and_receding_horizon_agree_on_arbitrary_signals(law):
    """m = 2, l = 3: the stacking of u_p, y_p and the weight states must agree channel by channel.

    Both forms are driven by the same arbitrary (r, y) sequences (no plant needed): the LTI
    system (5.3)–(5.4) by a hand-written state recursion, the receding-horizon loop by control/observe.
    """
    rng = np.random.default_rng(7)
    m, l, i = 2, 3, 4
    n = 2 * i + 300 - 1
    A = rng.standard_normal((4, 4))
    A *= 0.8 / max(abs(np.linalg.eigvals(A)))
    Bp, Cp = rng.standard_normal((4, m)), rng.standard_normal((l, 4))
    u = rng.standard_normal((n, m))
    _, y, _ = signal.dlsim((A, Bp, Cp, np.zeros((l, m)), DT), u)
    pred = fit_predictor(u, y + 0.05 * rng.standard_normal(y.shape), i)
    s = control.tf("s")
    w = lambda k, z, p: control.ss(tustin(k * (s + z) / (s + p), DT))  # noqa: E731
    W1 = control.append(w(2, 2, 0.1), w(3, 1, 0.2), w(1, 3, 0.5))
    W2 = control.append(w(0.5, 1, 5), w(0.4, 2, 6))
    unc = {"multiplicative": Multiplicative(control.append(w(0.3, 1, 10), w(0.2, 1, 9), w(0.1, 2, 8)),
                                            control.append(w(0.5, 2, 4), w(0.4, 1, 3), w(0.3, 1, 2))),
           "additive": Additive(control.append(w(0.2, 3, 6), w(0.1, 2, 5)),
                                control.append(w(0.5, 2, 4), w(0.4, 1, 3), w(0.3, 1, 2)))}.get(law)
    d = hinf_design(pred, W1, W2, causal=law == "causal", uncertainty=unc)
    K = d.controller
    assert (K.ninputs, K.noutputs) == (2 * l, m)
    Ak, Bk, Ck, Dk = (np.asarray(M) for M in (K.A, K.B, K.C, K.D))
    rh = RecedingHorizonController(d)
    xk = np.zeros(K.nstates)
    for _ in range(40):
        r_k, y_k = rng.standard_normal(l), rng.standard_normal(l)
        v = np.r_[r_k, y_k]
        u_lti = Ck @ xk + Dk @ v
        u_rh = rh.control(r_k)
        np.testing.assert_allclose(u_rh, u_lti, rtol=1e-9, atol=1e-10 * max(1.0, np.abs(u_lti).max()))
        rh.observe(u_rh, y_k, r_k)
        xk = Ak @ xk + Bk @ v
        np.testing.assert_allclose(rh.state, xk, rtol=1e-9, atol=1e-10 * max(1.0, np.abs(xk).max()))


def test_lti_controller_refuses_non_designs():
    from synthesis import lti_controller

    with pytest.raises(DataError, match="HinfDesign or LqgDesign"):
        lti_controller(object())
