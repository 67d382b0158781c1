"""The four H∞ laws (Ch. 3) from the engine, against the thesis's closed forms written out here,
the full saddle system (3.31), and Theorems 3.3, 3.5, 3.6 as identities."""
import warnings

import control
import numpy as np
import pytest
from scipy import signal

from synthesis import (
    Additive,
    DataError,
    InfeasibleGammaError,
    Multiplicative,
    NearGammaMinWarning,
    WeightError,
    fit_predictor,
    gamma_min,
    hinf_design,
    markov_toeplitz,
    observability,
    tustin,
)

DT = 0.1
inv = np.linalg.inv


def lam_max(M):
    return float(np.max(np.real(np.linalg.eigvals(M))))


# ------------------------------------------------------------------------------------------ fixtures
def _servo_predictor(i=6, n=500, seed=0):
    rng = np.random.default_rng(seed)
    Pd = control.c2d(control.tf([1], [1, 1, 0]), DT)
    den = np.ravel(Pd.den[0][0])
    num = np.ravel(Pd.num[0][0])
    num = np.r_[np.zeros(len(den) - len(num)), num]
    u = rng.choice([-1.0, 1.0], n)
    y = signal.lfilter(num, den, u + 0.05 * rng.standard_normal(n)) + 0.05 * rng.standard_normal(n)
    return fit_predictor(u, y, i)


def _mimo_predictor(i=4, n=400, seed=1):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((3, 3))
    A *= 0.8 / max(abs(np.linalg.eigvals(A)))
    B, C = rng.standard_normal((3, 2)), rng.standard_normal((2, 3))
    u = rng.choice([-1.0, 1.0], (n, 2))
    _, y, _ = signal.dlsim((A, B, C, np.zeros((2, 2)), DT), u)
    y = y + 0.02 * rng.standard_normal(y.shape)
    return fit_predictor(u, y, i)


def _siso_weights():
    s = control.tf("s")
    W1 = tustin(100 * (0.01 / 5) * (s + 5) / (s + 0.01), DT)
    W2 = tustin(0.05 * (10 / 0.5) * (s + 0.5) / (s + 10), DT)
    return W1, W2


def _mimo_weights():
    s = control.tf("s")
    a = control.ss(tustin(2 * (s + 2) / (s + 0.1), DT))
    b = control.ss(tustin(0.5 * (s + 1) / (s + 5), DT))
    W1 = control.append(a, control.ss(tustin(3 * (s + 1) / (s + 0.2), DT)))
    W1 = control.ss(W1.A, W1.B, W1.C, W1.D + np.array([[0, 0.3], [0, 0]]), DT)  # couple the channels
    W2 = control.append(b, b)
    return W1, W2


@pytest.fixture(scope="module", params=["siso", "mimo"])
def case(request):
    if request.param == "siso":
        pred = _servo_predictor()
        W1, W2 = _siso_weights()
        s = control.tf("s")
        W3 = tustin(0.3 * (s + 1) / (s + 10), DT)
        W4 = tustin(0.5 * (s + 2) / (s + 4), DT)
        W3a = tustin(0.2 * (s + 3) / (s + 6), DT)
    else:
        pred = _mimo_predictor()
        W1, W2 = _mimo_weights()
        W3 = np.array([[0.3, 0.1], [0.0, 0.2]])
        s = control.tf("s")
        W4 = control.append(control.ss(tustin(0.5 * (s + 2) / (s + 4), DT)), control.ss(tustin(0.4 * (s + 1) / (s + 3), DT)))
        W3a = 0.2 * np.eye(2)
    return pred, W1, W2, W3, W4, W3a


def _mats(pred, W):
    i = pred.horizon
    Ws = [w if isinstance(w, control.StateSpace) else control.ss([], [], [], np.atleast_2d(w), DT) for w in W]
    return [(markov_toeplitz(w, i), observability(w, i)) for w in Ws]


# ------------------------------------------------------------------------------------------ Thm 3.1
def test_strictly_causal_closed_form(case):
    pred, W1, W2, *_ = case
    (H1, G1), (H2, G2) = _mats(pred, [W1, W2])
    Lw, Lu = pred.Lw, pred.Lu
    Q1, Q2 = H1.T @ H1, H2.T @ H2
    gm_ref = np.sqrt(lam_max(inv(inv(Q1) + Lu @ inv(Q2) @ Lu.T)))  # (3.8)
    d = hinf_design(pred, W1, W2)
    assert d.gamma_min == pytest.approx(gm_ref, rel=1e-9)
    assert gamma_min(pred, W1, W2) == pytest.approx(gm_ref, rel=1e-9)
    assert d.gamma == pytest.approx(1.1 * gm_ref)
    g = d.gamma
    Qt = inv(inv(Q1) - g**-2 * np.eye(len(Q1)))  # (3.7)
    G = -inv(Lu.T @ Qt @ Lu + Q2) @ np.hstack(
        [Lu.T @ Qt @ Lw, -Lu.T @ (g**-2 * Qt + np.eye(len(Q1))) @ H1.T @ G1, H2.T @ G2])  # (3.6)
    assert [c for c, _ in d.columns] == ["w_p", "x_w1", "x_w2"]
    assert d.gain.shape == (pred.horizon * pred.m, Lw.shape[1] + G1.shape[1] + G2.shape[1])
    assert np.allclose(d.gain, G, rtol=1e-7, atol=1e-9 * np.abs(G).max())


def test_gain_equals_full_saddle_system(case):
    pred, W1, W2, *_ = case
    (H1, G1), (H2, G2) = _mats(pred, [W1, W2])
    Lw, Lu = pred.Lw, pred.Lu
    Q1, Q2 = H1.T @ H1, H2.T @ H2
    d = hinf_design(pred, W1, W2, gamma_ratio=1.5)
    g2 = d.gamma**2
    KKT = np.block([[Q1 - g2 * np.eye(len(Q1)), -Q1 @ Lu], [-Lu.T @ Q1, Lu.T @ Q1 @ Lu + Q2]])
    rhs = np.block([[Q1 @ Lw, -H1.T @ G1, np.zeros((len(Q1), G2.shape[1]))],
                    [-Lu.T @ Q1 @ Lw, Lu.T @ H1.T @ G1, -H2.T @ G2]])  # (3.31)
    sol = np.linalg.solve(KKT, rhs)
    il = len(Q1)
    scale = np.abs(sol).max()
    assert np.allclose(d.disturbance_gain, sol[:il], atol=1e-8 * scale)
    assert np.allclose(d.gain, sol[il:], atol=1e-8 * scale)


@pytest.mark.parametrize("ratio,ok", [(1.0005, True), (0.9995, False)])
def test_saddle_inertia_nominal(case, ratio, ok):
    pred, W1, W2, *_ = case
    (H1, _), (H2, _) = _mats(pred, [W1, W2])
    Lu = pred.Lu
    Q1, Q2 = H1.T @ H1, H2.T @ H2
    g = ratio * gamma_min(pred, W1, W2)
    Hs = np.block([[Q1 - g**2 * np.eye(len(Q1)), -Q1 @ Lu], [-Lu.T @ Q1, Lu.T @ Q1 @ Lu + Q2]])
    ev = np.linalg.eigvalsh(Hs)
    i, m, l = pred.horizon, pred.m, pred.l
    assert ((np.sum(ev > 0), np.sum(ev < 0)) == (i * m, i * l)) is ok


# ------------------------------------------------------------------------------------------ Thm 3.2
def test_causal_closed_form(case):
    pred, W1, W2, *_ = case
    (H1, G1), (H2, G2) = _mats(pred, [W1, W2])
    Lw, Lu = pred.Lw, pred.Lu
    l = pred.l
    H11, H12 = H1[:, :l], H1[:, l:]  # (3.37)
    Q1, Q2, Q12 = H1.T @ H1, H2.T @ H2, H12.T @ H12
    gmc_ref = np.sqrt(lam_max(H12.T @ inv(np.eye(len(H1)) + H1 @ Lu @ inv(Q2) @ Lu.T @ H1.T) @ H12))  # (3.41)
    d = hinf_design(pred, W1, W2, causal=True)
    assert d.gamma_min == pytest.approx(gmc_ref, rel=1e-9)
    g = d.gamma
    Qbar = inv(Q12 - g**2 * np.eye(len(Q12)))  # (3.40)
    # (3.39) as printed multiplies Q12 (size (i-1)l) into Q1 (size il); the derivation gives
    # Q~12 = Q1 - H1' H12 Qbar12 H12' H1 (consistent with the w_p block of (3.38)).
    Qt = Q1 - H1.T @ H12 @ Qbar @ H12.T @ H1
    P = np.eye(len(H1)) - H12 @ Qbar @ H12.T
    G = inv(Lu.T @ Qt @ Lu + Q2) @ np.hstack(
        [Lu.T @ H1.T @ P @ H11, -Lu.T @ Qt @ Lw, Lu.T @ H1.T @ P @ G1, -H2.T @ G2])  # (3.38)
    assert [c for c, _ in d.columns] == ["r_k", "w_p", "x_w1", "x_w2"]
    assert np.allclose(d.gain, G, rtol=1e-7, atol=1e-9 * np.abs(G).max())
    # the LTI controller has a feedthrough from r_k only
    D = np.asarray(d.controller.D)
    assert np.allclose(D[:, :l], G[: pred.m, :l]) and np.all(D[:, l:] == 0)


def test_theorem_3_3_causal_not_worse(case):
    pred, W1, W2, *_ = case
    assert gamma_min(pred, W1, W2) >= gamma_min(pred, W1, W2, causal=True)


# ------------------------------------------------------------------------------------------ Thms 3.4, 3.7
@pytest.mark.parametrize("kind", [Multiplicative, Additive])
def test_robust_closed_form(case, kind):
    """γ_min (3.46)/(3.64) and the saddle system (3.45)/(3.63) written out from the thesis.

    The two laws share the r and s rows; they differ in z3: H3(L_u u + L_w w_p) + Γ3 x_w3
    (multiplicative, W3 on the output) or H3 u + Γ3 x_w3 (additive, W3 on the control; (3.63)
    drops the right-hand matrix, derived here from the proof of Thm 3.7).
    """
    pred, W1, W2, W3m, W4, W3a = case
    W3 = W3m if kind is Multiplicative else W3a
    (H1, G1), (H2, G2), (H3, G3), (H4, G4) = _mats(pred, [W1, W2, W3, W4])
    Lw, Lu = pred.Lw, pred.Lu
    Q1, Q2, Q3 = H1.T @ H1, H2.T @ H2, H3.T @ H3
    Q4o = H4 @ H4.T
    if kind is Multiplicative:
        X = inv(inv(Q1) + Lu @ inv(Q2 + Lu.T @ Q3 @ Lu) @ Lu.T)  # (3.46)
        Quu = Lu.T @ (Q1 + Q3) @ Lu + Q2
        u_wp, u_x3 = -Lu.T @ (Q1 + Q3) @ Lw, -Lu.T @ H3.T @ G3  # (3.45)
    else:
        X = inv(inv(Q1) + Lu @ inv(Q2 + Q3) @ Lu.T)  # (3.64)
        Quu = Lu.T @ Q1 @ Lu + Q2 + Q3
        u_wp, u_x3 = -Lu.T @ Q1 @ Lw, -H3.T @ G3  # from z3 = H3 u + Γ3 x_w3
    gm_ref = np.sqrt(lam_max((np.eye(len(Q4o)) + Q4o) @ X))
    d = hinf_design(pred, W1, W2, uncertainty=kind(W3, W4), gamma_ratio=1.2)
    assert d.gamma_min == pytest.approx(gm_ref, rel=1e-9)
    g2 = d.gamma**2
    n_r, n_s = len(Q1), H4.shape[1]
    Hs = np.block([
        [Q1 - g2 * np.eye(n_r), -Q1 @ H4, -Q1 @ Lu],
        [-H4.T @ Q1, H4.T @ Q1 @ H4 - g2 * np.eye(n_s), H4.T @ Q1 @ Lu],
        [-Lu.T @ Q1, Lu.T @ Q1 @ H4, Quu]])
    Z = lambda a, b: np.zeros((a, b))  # noqa: E731
    n2, n3 = G2.shape[1], G3.shape[1]
    rhs = np.block([
        [Q1 @ Lw, -H1.T @ G1, Z(n_r, n2), Z(n_r, n3), Q1 @ G4],
        [-H4.T @ Q1 @ Lw, H4.T @ H1.T @ G1, Z(n_s, n2), Z(n_s, n3), -H4.T @ Q1 @ G4],
        [u_wp, Lu.T @ H1.T @ G1, -H2.T @ G2, u_x3, -Lu.T @ Q1 @ G4]])
    sol = np.linalg.solve(Hs, rhs)
    scale = np.abs(sol).max()
    assert [c for c, _ in d.columns] == ["w_p", "x_w1", "x_w2", "x_w3", "x_w4"]
    assert np.allclose(d.gain, sol[n_r + n_s:], atol=1e-8 * scale)
    assert np.allclose(d.disturbance_gain, sol[: n_r + n_s], atol=1e-8 * scale)
    # saddle inertia: im positive, i(l + m_w4) negative eigenvalues just above gamma_min, not below
    i, m = pred.horizon, pred.m
    for ratio, ok in [(1.0005, True), (0.9995, False)]:
        gg = (ratio * d.gamma_min) ** 2
        Hr = Hs.copy()
        Hr[: n_r + n_s, : n_r + n_s] += (g2 - gg) * np.eye(n_r + n_s)
        ev = np.linalg.eigvalsh(Hr)
        assert ((np.sum(ev > 0), np.sum(ev < 0)) == (i * m, n_r + n_s)) is ok


# ------------------------------------------------------------------------------------------ Thms 3.5, 3.6
def test_theorem_3_5_robust_is_worse(case):
    pred, W1, W2, W3, W4, W3a = case
    g = gamma_min(pred, W1, W2)
    assert gamma_min(pred, W1, W2, uncertainty=Multiplicative(W3, W4)) > g * (1 + 1e-6)
    assert gamma_min(pred, W1, W2, uncertainty=Additive(W3a, W4)) > g * (1 + 1e-6)


@pytest.mark.parametrize("kind", [Multiplicative, Additive])
def test_theorem_3_6_zero_uncertainty_weights_reduce_to_nominal(case, kind):
    pred, W1, W2, *_ = case
    ms = 2  # the fictitious s may have any width; W4 = 0 maps it to l outputs
    W3 = np.zeros((1, pred.l if kind is Multiplicative else pred.m))
    W4 = np.zeros((pred.l, ms))
    nom = hinf_design(pred, W1, W2, gamma=2.0 * gamma_min(pred, W1, W2))
    rob = hinf_design(pred, W1, W2, gamma=nom.gamma, uncertainty=kind(W3, W4))
    assert rob.gamma_min == pytest.approx(nom.gamma_min, rel=1e-10)
    n = nom.gain.shape[1]
    assert rob.gain.shape[1] == n  # static zero W3, W4: no x_w3, x_w4 columns
    assert np.allclose(rob.gain, nom.gain, rtol=1e-9, atol=1e-12)
    il = pred.horizon * pred.l
    assert np.allclose(rob.disturbance_gain[:il], nom.disturbance_gain, rtol=1e-9, atol=1e-12)
    assert np.allclose(rob.disturbance_gain[il:], 0.0)  # s_wc = 0


def test_robust_controller_order_and_drives(case):
    pred, W1, W2, W3, W4, W3a = case
    i, m, l = pred.horizon, pred.m, pred.l
    n1, n2 = control.ss(W1).nstates, control.ss(W2).nstates
    for unc, w3 in [(Multiplicative(W3, W4), W3), (Additive(W3a, W4), W3a)]:
        d = hinf_design(pred, W1, W2, uncertainty=unc)
        n3 = control.ss(w3).nstates if isinstance(w3, control.StateSpace) else 0
        assert d.controller.nstates == i * (m + l) + n1 + n2 + n3
        drives = {ws.name: ws.drive for ws in d.weight_states}
        assert drives == {"x_w1": "e", "x_w2": "u", "x_w3": "y" if isinstance(unc, Multiplicative) else "u"}


# ------------------------------------------------------------------------------------------ API / errors
def test_design_api(case):
    pred, W1, W2, *_ = case
    d = hinf_design(pred, W1, W2)
    i, m, l = pred.horizon, pred.m, pred.l
    K = d.controller
    assert K.dt == DT and K.ninputs == 2 * l and K.noutputs == m
    assert K.nstates == i * (m + l) + control.ss(W1).nstates + control.ss(W2).nstates
    assert np.allclose(hinf_design(pred, W1, W2, gamma=d.gamma).gain, d.gain)
    assert np.allclose(d.block("w_p"), d.gain[:, : i * (m + l)])
    assert d.disturbance_gain.shape == (i * l, d.gain.shape[1])


def test_gamma_policy_callable_receives_gamma_min(case):
    pred, W1, W2, *_ = case
    seen = []

    def policy(gmin):
        seen.append(gmin)
        return gmin + 0.5

    d = hinf_design(pred, W1, W2, gamma=policy)
    gmin = gamma_min(pred, W1, W2)
    assert seen == [pytest.approx(gmin, rel=1e-12)]
    assert d.gamma == pytest.approx(gmin + 0.5, rel=1e-12)
    np.testing.assert_allclose(d.gain, hinf_design(pred, W1, W2, gamma=gmin + 0.5).gain, rtol=1e-10, atol=1e-12)
    with pytest.raises(InfeasibleGammaError):
        hinf_design(pred, W1, W2, gamma=lambda g: 0.5 * g)


def test_gamma_errors_and_warning():
    pred = _servo_predictor()
    W1, W2 = _siso_weights()
    gm = gamma_min(pred, W1, W2)
    with pytest.raises(InfeasibleGammaError, match=f"gamma_min = {gm:.6g}"):
        hinf_design(pred, W1, W2, gamma=gm)
    with pytest.raises(InfeasibleGammaError):
        hinf_design(pred, W1, W2, gamma=0.9 * gm)
    with pytest.raises(ValueError):
        hinf_design(pred, W1, W2, gamma_ratio=1.0)
    with pytest.warns(NearGammaMinWarning):
        hinf_design(pred, W1, W2, gamma_ratio=1.01)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        hinf_design(pred, W1, W2, gamma_ratio=1.1)


def test_bad_weights_and_predictor():
    pred = _servo_predictor()
    W1, W2 = _siso_weights()
    s = control.tf("s")
    with pytest.raises(WeightError, match="sample times"):
        hinf_design(pred, W1, tustin(0.05 * 20 * (s + 0.5) / (s + 10), 0.2))
    with pytest.raises(WeightError, match="continuous"):
        hinf_design(pred, 100 * (0.01 / 5) * (s + 5) / (s + 0.01), W2)
    with pytest.raises(WeightError, match="relative degree 0"):
        hinf_design(pred, W1, control.tf([1], [1, -0.5], DT))  # strictly proper
    with pytest.raises(WeightError, match="input"):
        hinf_design(pred, np.eye(2), W2)  # W1 must have l = 1 input
    with pytest.raises(WeightError, match="input"):
        hinf_design(pred, W1, W2, uncertainty=Additive(np.eye(2), 1.0))
    with pytest.raises(WeightError, match="NaN"):
        hinf_design(pred, W1, control.ss([[0.5]], [[1.0]], [[np.nan]], [[1.0]], DT))
    with pytest.raises(WeightError):
        hinf_design(pred, W1, W2, uncertainty=(0.1, 0.1))
    bad = type("P", (), dict(Lw=pred.Lw[:, :-1], Lu=pred.Lu, horizon=pred.horizon, m=1, l=1))()
    with pytest.raises(DataError, match="shapes"):
        hinf_design(bad, W1, W2)
    nan = type("P", (), dict(Lw=pred.Lw * np.nan, Lu=pred.Lu, horizon=pred.horizon, m=1, l=1))()
    with pytest.raises(DataError, match="NaN"):
        gamma_min(nan, W1, W2)
    with pytest.raises(DataError):
        gamma_min(object(), W1, W2)


def test_non_numeric_levels_are_named():
    pred = _servo_predictor()
    W1, W2 = _siso_weights()
    for kw in (dict(gamma="big"), dict(gamma_ratio="x"), dict(gamma_ratio=None), dict(gamma=lambda g: "x")):
        with pytest.raises(DataError, match="gamma"):
            hinf_design(pred, W1, W2, **kw)


def test_data_sample_time_is_checked_against_the_weights():
    pred = _servo_predictor()
    W1, W2 = _siso_weights()  # discretised at DT = 0.1
    d = hinf_design(pred, W1, W2, dt=DT)
    assert d.controller.dt == DT
    assert gamma_min(pred, W1, W2, dt=DT) == pytest.approx(d.gamma_min, rel=1e-12)
    for fn in (hinf_design, gamma_min):
        with pytest.raises(WeightError, match="data's is 0.05"):
            fn(pred, W1, W2, dt=0.05)  # data sampled at 20 Hz, weights at 10 Hz
    with pytest.raises(DataError, match="dt"):
        hinf_design(pred, W1, W2, dt=0.0)
    # static weights take the data's sample time (without it the controller's dt is unspecified)
    assert hinf_design(pred, 2.0, 0.5).controller.dt is True
    assert hinf_design(pred, 2.0, 0.5, dt=0.05).controller.dt == 0.05


# ------------------------------------------------------------------ cached weight blocks (issue 12)
@pytest.mark.parametrize("kw", [dict(), dict(causal=True), dict(uncertainty=Multiplicative(0.3, 0.4)),
                                dict(uncertainty=Additive(0.2, 0.5), causal=True)])
def test_map_plan_fill_equals_the_map_built_from_scratch(case, kw):
    from synthesis.hinf import _map_plan, performance_map

    pred, W1, W2 = case[:3]
    if pred.m == 2:  # scalar uncertainty weights → identity blocks of the right size
        kw = {k: (type(v)(v.W3 * np.eye(2), v.W4 * np.eye(2)) if k == "uncertainty" else v) for k, v in kw.items()}
    plan = _map_plan(pred.horizon, pred.m, pred.l, W1, W2, **kw)
    ref = performance_map(pred, W1, W2, **kw)
    got = plan.fill(pred.Lw, pred.Lu)
    for a, b in ((got.Md, ref.Md), (got.Mu, ref.Mu), (got.Mx, ref.Mx)):
        np.testing.assert_array_equal(a, b)
    assert got.columns == ref.columns and got.disturbances == ref.disturbances
    # the template is not modified by filling
    again = plan.fill(pred.Lw, pred.Lu)
    np.testing.assert_array_equal(again.Mu, ref.Mu)


@pytest.mark.parametrize("kw", [dict(), dict(causal=True), dict(uncertainty=Multiplicative(0.3, 0.4)),
                                dict(uncertainty=Additive(0.2, 0.5), causal=True)])
def test_plan_route_equals_the_engine_on_the_full_map(case, kw):
    """hinf_design solves the game for [M_x without w_p | B] and expands the w_p gain as G_B L_w;
    the engine on the full map (performance_map, SVD route of the disturbance gain) is the second route."""
    from synthesis.hinf import _map_plan, performance_map
    from synthesis.minimax import _gains, _saddle

    pred, W1, W2 = case[:3]
    if pred.m == 2:
        kw = {k: (type(v)(v.W3 * np.eye(2), v.W4 * np.eye(2)) if k == "uncertainty" else v) for k, v in kw.items()}
    d = hinf_design(pred, W1, W2, gamma_ratio=1.4, **kw)
    pm = performance_map(pred, W1, W2, **kw)
    u_ref, d_ref, route = _gains(_saddle(pm.Md, pm.Mu, pm.Mx), d.gamma, route="svd")
    assert route == "svd"
    assert d.gamma_min == gamma_min(pred, W1, W2, **kw)  # the same computation, to the last bit
    assert np.linalg.norm(d.gain - u_ref) <= 1e-10 * np.linalg.norm(u_ref)
    assert np.linalg.norm(d.disturbance_gain - d_ref) <= 1e-10 * np.linalg.norm(d_ref)
    # B is read off the reference columns of the map except for the multiplicative law (H3 L_u in z3)
    plan = _map_plan(pred.horizon, pred.m, pred.l, W1, W2, **kw)
    assert plan.b_is_reference == (not isinstance(kw.get("uncertainty"), Multiplicative))


# ------------------------------------------------------------------------------------------ horizon vs delay
def _fir_record(taps, noise, n=400, seed=0):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    return u, np.convolve(u, taps)[:n] + noise * rng.standard_normal(n)


def _lqg(pred):
    from synthesis import lqg_design
    return lqg_design(pred, 1.0, 0.01)


def _designs(pred):
    return gamma_min(pred, 1.0, 0.1), hinf_design(pred, 1.0, 0.1), _lqg(pred)


@pytest.mark.parametrize("taps, noise", [([0.0, 0.5, 0.2], 0.01), ([0.0, 0.5, 0.2], 0.0), ([0.0, 0.8], 0.0)])
def test_a_horizon_the_control_cannot_act_in_warns_naming_the_horizon(taps, noise):
    """i = 1 on a strictly proper plant: u_k reaches no output of the horizon, and L_u is noise (1.3e-3 for
    0.5 z⁻¹ + 0.2 z⁻², exactly 0 to rounding for 0.8 z⁻¹) on which the laws had acted without a warning (H∞ gain
    0.37 there); gamma_min, hinf_design and lqg_design each warn, naming i >= 2."""
    from synthesis import HorizonWarning, PersistenceWarning
    u, y = _fir_record(taps, noise)
    pred = fit_predictor(u, y, 1)
    assert pred.control_pvalue > 0.01
    for design in (lambda p: gamma_min(p, 1.0, 0.1), lambda p: hinf_design(p, 1.0, 0.1), _lqg):
        with pytest.warns(HorizonWarning, match=r"horizon i=1 .*i >= 2 for a strictly proper plant"):
            design(pred)
    with warnings.catch_warnings():
        warnings.simplefilter("error", HorizonWarning)
        warnings.simplefilter("ignore", PersistenceWarning)  # 0.8 z⁻¹ at i = 2: noise-free, rank deficient
        longer = fit_predictor(u, y, 2)
        # a rank-deficient regressor (0.8 z⁻¹ noise free) is tested in the space it spans: exact, p = 0
        assert longer.control_pvalue < 1e-6
        _designs(longer)


@pytest.mark.parametrize("i", [1, 3])
def test_a_plant_with_feedthrough_designs_at_horizon_1_without_a_warning(i):
    from synthesis import HorizonWarning, RecursivePredictor
    u, y = _fir_record([0.3, 0.5, 0.2], 0.01)
    with warnings.catch_warnings():
        warnings.simplefilter("error", HorizonWarning)
        pred = fit_predictor(u, y, i)
        assert pred.control_pvalue < 1e-6
        _designs(pred)
        _designs(RecursivePredictor.from_data(u, y, i).predictor())  # the recursive predictor carries the test too
    assert fit_predictor(u, y, i, method="qr").control_pvalue < 1e-6
    assert fit_predictor(u, y, i, method="lstsq").control_pvalue < 1e-6  # from the data (tests/test_predictor_control)
