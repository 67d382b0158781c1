"""Plants of §5.4 and §6.1: discretisation, poles, zeros, integrator, DC behaviour."""
import control as ct
import numpy as np
import pytest

from experiments.lab.plants import THREE_DISK, servo, three_disk


def _tf_coeffs(sys):
    g = ct.tf(sys)
    num, den = np.asarray(g.num[0][0], float), np.asarray(g.den[0][0], float)
    num = np.trim_zeros(np.where(np.abs(num) < 1e-12 * np.abs(den).max(), 0.0, num), "f")
    return num / den[0], den / den[0]


def test_servo_zoh_equals_thesis_5_6():
    num, den = _tf_coeffs(servo())
    # (5.6), printed to 4 significant digits
    np.testing.assert_allclose(num, [0.004837, 0.004679], atol=5e-7)
    np.testing.assert_allclose(den, [1.0, -1.905, 0.9048], atol=5e-4)
    assert abs(den[2] - 0.9048) < 5e-5


def test_servo_zoh_closed_form():
    # ZOH of 1/(s(s+1)): num [T-1+e^-T, 1-e^-T-T e^-T], den [1, -(1+e^-T), e^-T]
    for T in (0.1, 0.05, 0.5):
        q = np.exp(-T)
        num, den = _tf_coeffs(servo(dt=T))
        np.testing.assert_allclose(num, [T - 1 + q, 1 - q - T * q], rtol=1e-9)
        np.testing.assert_allclose(den, [1, -(1 + q), q], rtol=1e-12)


def test_servo_continuous():
    P = servo(continuous=True)
    assert P.dt == 0
    s = 2.0j
    np.testing.assert_allclose(P(s), 1 / (s * (s + 1)), rtol=1e-12)


def _tf_formula(output, s, p=THREE_DISK):
    q = lambda z, w: s * s + 2 * z * w * s + w * w  # noqa: E731
    den = s * (s + p.alpha) * q(p.zeta_p1, p.omega_p1) * q(p.zeta_p2, p.omega_p2)
    num = {
        "y1": p.k * q(p.zeta_z1, p.omega_z1) * q(p.zeta_z2, p.omega_z2),
        "y2": p.k * p.omega_z2**2 * q(p.zeta_z1, p.omega_z1),
        "y3": p.k * p.omega_z1**2 * p.omega_z2**2,
    }[output]
    return num / den


@pytest.mark.parametrize("output", ["y1", "y2", "y3"])
def test_three_disk_frequency_response_matches_transfer_function(output):
    P = three_disk(output, continuous=True)
    for w in np.r_[np.logspace(-2, 2.5, 60), [10.65, 15.85, 42.0, 43.5]]:
        np.testing.assert_allclose(P(1j * w), _tf_formula(output, 1j * w), rtol=1e-7)


def test_three_disk_all_outputs_stack_the_siso_models():
    P = three_disk("all", continuous=True)
    assert (P.ninputs, P.noutputs, P.nstates) == (1, 3, 6)
    for w in (0.3, 16.0, 44.0):
        col = P(1j * w)[:, 0]
        np.testing.assert_allclose(col, [_tf_formula(o, 1j * w) for o in ("y1", "y2", "y3")], rtol=1e-9)


def test_three_disk_poles_zeros_integrator():
    p = THREE_DISK
    Pc = three_disk("y1", continuous=True)
    poles = np.sort_complex(np.linalg.eigvals(Pc.A))
    expect = [0.0, -p.alpha]
    for z, w in ((p.zeta_p1, p.omega_p1), (p.zeta_p2, p.omega_p2)):
        expect += list(np.roots([1, 2 * z * w, w * w]))
    np.testing.assert_allclose(poles, np.sort_complex(np.array(expect)), atol=1e-10)
    # resonances at the given omega_p (|pole| = omega_n, damping ratio zeta)
    osc = poles[np.abs(poles.imag) > 0]
    np.testing.assert_allclose(np.sort(np.unique(np.round(np.abs(osc), 8))), [p.omega_p1, p.omega_p2], rtol=1e-9)
    zeros = np.sort_complex(ct.zeros(Pc))
    ez = []
    for z, w in ((p.zeta_z1, p.omega_z1), (p.zeta_z2, p.omega_z2)):
        ez += list(np.roots([1, 2 * z * w, w * w]))
    np.testing.assert_allclose(zeros, np.sort_complex(np.array(ez)), rtol=1e-7)
    assert ct.zeros(three_disk("y3", continuous=True)).size == 0
    # discrete: ZOH maps poles to exp(p dt); integrator -> z = 1
    dt = 1 / 64
    Pd = three_disk("all", dt=dt)
    assert Pd.dt == dt
    np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(Pd.A)),
                               np.sort_complex(np.exp(np.array(expect) * dt)), atol=1e-12)
    assert np.min(np.abs(np.linalg.eigvals(Pd.A) - 1.0)) < 1e-12


@pytest.mark.parametrize("output", ["y1", "y2", "y3"])
def test_three_disk_dc_velocity_gain(output):
    p = THREE_DISK
    kv = p.k * p.omega_z1**2 * p.omega_z2**2 / (p.alpha * p.omega_p1**2 * p.omega_p2**2)
    Pc = three_disk(output, continuous=True)
    s = 1e-7j
    np.testing.assert_allclose(s * Pc(s), kv, rtol=1e-5)
    # ZOH preserves the ramp slope: (z - 1)/dt P(z) -> kv as z -> 1
    dt = 1 / 64
    Pd = three_disk(output, dt=dt)
    z = np.exp(1e-7j * dt)
    np.testing.assert_allclose((z - 1) / dt * Pd(z), kv, rtol=1e-5)


def test_three_disk_discrete_is_well_conditioned():
    Pd = three_disk("all")
    _, V = np.linalg.eig(Pd.A)
    assert np.linalg.cond(V) < 10  # near-normal modal blocks
    assert np.all(np.abs(np.linalg.eigvals(Pd.A)) <= 1 + 1e-12)
    # low-frequency ZOH response close to the continuous one (lightly damped modes preserved)
    Pc = three_disk("y3", continuous=True)
    Py3 = three_disk("y3")
    for w in (1.0, 5.0):
        z = np.exp(1j * w / 64)
        assert abs(Py3(z) / Pc(1j * w) - 1) < 0.1


def test_bad_arguments():
    with pytest.raises(ValueError, match="output"):
        three_disk("y4")
    with pytest.raises(ValueError, match="dt"):
        servo(dt=0.0)
    with pytest.raises(ValueError, match="dt"):
        three_disk(dt=-1.0)


@pytest.mark.parametrize("make", [servo, lambda: three_disk("y1"), lambda: three_disk("all")])
def test_plants_use_the_signal_names_of_the_toolkits_controllers(make):
    # a plant named "u"/"y" did not connect by name to a controller with inputs "r[0]", "y[0]" and output "u[0]"
    P = make()
    assert P.input_labels == ["u[0]"]
    assert P.output_labels == [f"y[{k}]" for k in range(P.noutputs)]


def test_interconnect_by_name_closes_the_same_loop_as_closed_loop_system():
    import synthesis as sy
    from experiments import closed_loop_system, collect_data, prbs

    P = servo()
    data = collect_data(P, prbs(400, seed=0), sensor_noise=0.01, seed=1)
    K = sy.hinf_design(sy.fit_predictor(data.u, data.y, 6, dt=P.dt), 1.0, 0.1).controller
    loop = ct.interconnect([P, K], inplist=["r[0]"], outlist=["y[0]", "u[0]"])
    ref = closed_loop_system(P, K)
    w = np.linspace(0.01, 3.0, 7) / P.dt
    np.testing.assert_allclose(loop.frequency_response(w).complex, ref.frequency_response(w).complex,
                               rtol=1e-9, atol=1e-12)
