"""Open/closed-loop simulation against python-control's own interconnection routes."""
import control as ct
import numpy as np
import pytest

from experiments.lab.plants import servo, three_disk
from experiments.lab.signals import prbs, step
from experiments.lab.simulate import AlgebraicLoopError, closed_loop, closed_loop_system, collect_data


def _forced(sys, u):
    return np.atleast_2d(ct.forced_response(sys, U=np.asarray(u).T).outputs).T


def test_collect_data_noise_free_matches_forced_response():
    P = three_disk("all")
    u = prbs(300, seed=0)
    d = collect_data(P, u)
    assert d.u.shape == (300, 1) and d.y.shape == (300, 3)
    np.testing.assert_allclose(d.y, _forced(P, u), atol=1e-9)
    np.testing.assert_allclose(d.t[1], 1 / 64)


def test_collect_data_noise_injection_points():
    P = servo()
    u = prbs(200, seed=1)
    d = collect_data(P, u, process_noise=0.05, sensor_noise=0.05, seed=7)
    rng = np.random.default_rng(7)  # documented order: process noise, then sensor noise
    w = 0.05 * rng.standard_normal((200, 1))
    v = 0.05 * rng.standard_normal((200, 1))
    np.testing.assert_allclose(d.y_clean, _forced(P, u + w[:, 0]), atol=1e-10)
    np.testing.assert_allclose(d.y, d.y_clean + v, atol=1e-12)
    np.testing.assert_array_equal(d.u[:, 0], u)


def _lead(dt):
    return ct.c2d(ct.tf([2.0, 2.0], [0.1, 1.0]), dt, "tustin")


@pytest.mark.parametrize("form", ["error", "ry"])
def test_closed_loop_matches_feedback_interconnection(form):
    P = servo()
    Ke = ct.ss(_lead(0.1))
    K = Ke if form == "error" else ct.ss(Ke.A, np.hstack([Ke.B, -Ke.B]), Ke.C, np.hstack([Ke.D, -Ke.D]), 0.1)
    r = step(120, at=5)
    res = closed_loop(P, K, r)
    T = ct.feedback(P * Ke, 1)
    np.testing.assert_allclose(res.y[:, 0], _forced(T, r)[:, 0], atol=1e-9)
    Sk = ct.feedback(Ke, P)  # u = K S r
    np.testing.assert_allclose(res.u[:, 0], _forced(Sk, r)[:, 0], atol=1e-9)
    np.testing.assert_allclose(res.e, res.r - res.y)


def test_object_controller_equals_lti_path():
    P = servo()
    K = ct.ss(_lead(0.1))

    class Obj:  # u_k = C xc + D (r - y) needs y_k, so use a strictly proper K here
        def __init__(self, sys):
            self.s, self.x = sys, np.zeros(sys.nstates)

        def control(self, r_k):
            return self.s.C @ self.x

        def observe(self, u_k, y_k, r_k):
            self.x = self.s.A @ self.x + self.s.B @ (np.atleast_1d(r_k) - np.atleast_1d(y_k))

    Kp = ct.ss(K.A, K.B, K.C, 0 * K.D, 0.1)  # strictly proper version
    r = step(80, at=3)
    a = closed_loop(P, Kp, r, sensor_noise=0.01, process_noise=0.02, seed=3)
    b = closed_loop(P, Obj(Kp), r, sensor_noise=0.01, process_noise=0.02, seed=3)
    np.testing.assert_allclose(a.y, b.y, atol=1e-12)
    np.testing.assert_allclose(a.u, b.u, atol=1e-12)
    assert not np.allclose(a.y_measured, a.y)


def test_additive_perturbation_equals_perturbed_plant():
    P = servo()
    delta = ct.ss(ct.tf([0.02], [1, -0.5], 0.1))
    K = ct.ss(_lead(0.1))
    r = step(100, at=1)
    a = closed_loop(P, K, r, perturbation=delta)
    b = closed_loop(ct.parallel(P, delta), K, r)
    np.testing.assert_allclose(a.y, b.y, atol=1e-10)
    assert not np.allclose(a.y, closed_loop(P, K, r).y)


def test_feedthrough_plant_with_reference_feedthrough_controller():
    # plant D != 0 is fine when the controller's D acts on r only (causal law)
    P = ct.ss(ct.tf([1.0, 0.3], [1.0, -0.5], 0.1))
    Kr = ct.ss([[0.2]], [[1.0, -1.0]], [[0.3]], [[0.5, 0.0]], 0.1)
    r = step(50)
    res = closed_loop(P, Kr, r)
    # second route: loop by hand with the transfer-function interconnection
    Kyy = ct.ss([[0.2]], [[-1.0]], [[0.3]], [[0.0]], 0.1)
    Krr = ct.ss([[0.2]], [[1.0]], [[0.3]], [[0.5]], 0.1)
    T = ct.feedback(P, Kyy, sign=+1) * Krr  # y = P u, u = Krr r + Kyy y
    np.testing.assert_allclose(res.y[:, 0], _forced(T, r)[:, 0], atol=1e-9)


def test_algebraic_loop_and_bad_input_raise():
    P = servo()
    with pytest.raises(AlgebraicLoopError):
        closed_loop(P, ct.ss([], [], [], [[1.0]], 0.1), step(10), perturbation=ct.ss([], [], [], [[0.1]], 0.1))
    with pytest.raises(ValueError, match="continuous"):
        closed_loop(P, ct.ss(ct.tf([1], [1, 1])), step(10))
    with pytest.raises(ValueError, match="sample times"):
        closed_loop(P, ct.ss([], [], [], [[1.0]], 0.2), step(10))
    with pytest.raises(ValueError, match="NaN"):
        closed_loop(P, ct.ss([], [], [], [[1.0]], 0.1), np.array([0.0, np.nan]))
    with pytest.raises(ValueError, match="inputs"):
        closed_loop(P, ct.ss([], [], [], [[1.0, 1.0, 1.0]], 0.1), step(10))
    with pytest.raises(ValueError, match="continuous"):
        collect_data(servo(continuous=True), np.ones(5))


def test_collect_data_continues_from_final_state():
    P = three_disk("y1")
    u = prbs(200, seed=2)
    whole = collect_data(P, u)
    a = collect_data(P, u[:120])
    b = collect_data(P, u[120:], x0=a.x_final)
    np.testing.assert_allclose(np.vstack([a.y, b.y]), whole.y, atol=1e-12)
    # closed loop continues the same way (zero controller = open loop with u = 0)
    c = closed_loop(P, ct.ss([], [], [], [[0.0, 0.0]], P.dt), np.zeros(10), x0=whole.x_final)
    np.testing.assert_allclose(c.y, collect_data(P, np.zeros(10), x0=whole.x_final).y, atol=1e-12)


def _freq(sys, w, dt):
    return np.asarray(sys(np.exp(1j * w * dt))).reshape(sys.noutputs, -1)


@pytest.mark.parametrize("form", ["[r; y]", "e = r - y"])
def test_closed_loop_system_matches_feedback_with_feedthroughs(form):
    # a proper plant (D ≠ 0) and a controller with y-feedthrough: the well-posed loop, second route
    # by python-control's feedback of the transfer functions, poles and frequency response
    dt = 0.1
    P = ct.ss([[0.9, 0.1], [0.0, 0.7]], [[0.0], [1.0]], [[1.0, 0.5]], [[0.3]], dt)
    k = ct.ss([[0.5]], [[1.0]], [[0.2]], [[0.4]], dt)  # error feedback u = k (r − y)
    K = k if form == "e = r - y" else ct.ss(k.A, np.hstack([k.B, -k.B]), k.C, np.hstack([k.D, -k.D]), dt)
    cl = closed_loop_system(P, K)
    ref_y = ct.feedback(P * k, 1)  # r → y
    ref_u = ct.feedback(k, P)  # r → u
    assert np.sort_complex(np.linalg.eigvals(cl.A)) == pytest.approx(np.sort_complex(ct.poles(ct.ss(ref_y))))
    w = np.array([0.1, 1.0, 5.0, 20.0])
    G = _freq(cl, w, dt)
    assert G[0] == pytest.approx(_freq(ref_y, w, dt)[0], rel=1e-9)
    assert G[1] == pytest.approx(_freq(ref_u, w, dt)[0], rel=1e-9)
    # and the time loop of closed_loop (strictly proper plant, same controller) agrees with it
    Ps = ct.ss(P.A, P.B, P.C, 0 * P.D, dt)
    r = step(40)
    res = closed_loop(Ps, K, r)
    yu = _forced(closed_loop_system(Ps, K), r)
    np.testing.assert_allclose(np.hstack([res.y, res.u]), yu, atol=1e-10)


def test_closed_loop_system_ill_posed_loop_raises():

    dt = 0.1
    P = ct.ss([[0.5]], [[1.0]], [[1.0]], [[2.0]], dt)
    K = ct.ss([[0.5]], [[0.0, 1.0]], [[0.0]], [[0.0, 0.5]], dt)  # D_y D_p = 1: I − D_y D_p singular
    with pytest.raises(AlgebraicLoopError, match="not well posed"):
        closed_loop_system(P, K)
    with pytest.raises(ValueError, match="inputs"):
        closed_loop_system(P, ct.ss([[0.5]], [[1.0, 1.0, 1.0]], [[1.0]], [[0.0, 0.0, 0.0]], dt))
