"""Model-based finite-horizon H∞ / LQR recursions (§4.2) against batch solutions and the subspace laws."""
import control as ct
import numpy as np
import pytest

import synthesis
from experiments.lab.plants import servo
from experiments.lab.signals import prbs
from experiments.lab.simulate import collect_data
from synthesis.riccati import StageSaddleError, generalized_plant, hinf_riccati, lqr_riccati


def _batch(A, B, C, D, i):
    """Γ = [C; CA; …] and block lower-triangular Toeplitz H of Markov parameters (built directly)."""
    p, q = B.shape[1], C.shape[0]
    Gam = np.vstack([C @ np.linalg.matrix_power(A, t) for t in range(i)])
    H = np.zeros((i * q, i * p))
    for t in range(i):
        for s in range(t + 1):
            blk = D if t == s else C @ np.linalg.matrix_power(A, t - s - 1) @ B
            H[t * q:(t + 1) * q, s * p:(s + 1) * p] = blk
    return Gam, H


def _weights(dt=0.1):
    W1 = synthesis.tustin(ct.tf([100 * 0.01 / 5 * 1, 100 * 0.01 / 5 * 5], [1, 0.01]), dt)
    W2 = synthesis.tustin(ct.tf([0.05 * 20, 0.05 * 20 * 0.5], [1, 10]), dt)
    return W1, W2


def _random_system(rng, n, p, q):
    A = rng.standard_normal((n, n))
    A *= 0.9 / max(abs(np.linalg.eigvals(A)))
    return A, rng.standard_normal((n, p)), rng.standard_normal((q, n)), rng.standard_normal((q, p))


def test_generalized_plant_transfer_function():
    P = servo()
    W1, W2 = _weights()
    gp = generalized_plant(P, W1, W2)
    assert (gp.n_p, gp.n_w1, gp.n_w2, gp.l, gp.m) == (2, 1, 1, 1, 1)
    G = gp.system
    for w in (0.1, 1.0, 10.0):
        z = np.exp(1j * w * 0.1)
        expect = np.array([[W1(z), -W1(z) * P(z)], [0.0, W2(z)]])
        np.testing.assert_allclose(G(z), expect, rtol=1e-10, atol=1e-12)
    with pytest.raises(ValueError, match="continuous"):
        generalized_plant(servo(continuous=True), W1, W2)
    with pytest.raises(ValueError):
        generalized_plant(P, ct.ss([[0.5]], [[1]], [[1]], [[0]], 0.1), W2)  # W1 relative degree 1


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_lqr_recursion_equals_batch_least_squares(seed):
    # Theorem 4.4: (4.21)-(4.24) with P_{k+i-1} = 0 reproduce (4.20)
    rng = np.random.default_rng(seed)
    n, m, l, i = 4, 2, 2, 7
    A, B, C, D = _random_system(rng, n, m, l)
    Q = np.diag([1.0, 2.0])
    R = np.array([[0.5, 0.1], [0.1, 0.3]])
    x0 = rng.standard_normal(n)
    Gam, H = _batch(A, B, C, D, i)
    Qd, Rd = np.kron(np.eye(i), Q), np.kron(np.eye(i), R)
    u_batch = -np.linalg.solve(H.T @ Qd @ H + Rd, H.T @ Qd @ Gam @ x0)
    law = lqr_riccati(A, B, C, D, Q, R, horizon=i)
    np.testing.assert_allclose(law.controls(x0), u_batch, rtol=1e-9, atol=1e-12)
    # optimal cost x0' P_{k-1} x0
    y = Gam @ x0 + H @ u_batch
    np.testing.assert_allclose(x0 @ law.value @ x0, y @ Qd @ y + u_batch @ Rd @ u_batch, rtol=1e-9)
    # the literal (4.21) terminal C'QC adds a cost on y_{k+i}: a different law (erratum)
    lit = lqr_riccati(A, B, C, D, Q, R, horizon=i, terminal=C.T @ Q @ C)
    assert np.max(np.abs(lit.controls(x0) - u_batch)) > 1e-6


@pytest.mark.parametrize("seed", [0, 3])
def test_hinf_recursion_equals_batch_minimax(seed):
    # (4.16)-(4.19) vs w = -(H'H - R_gd)^{-1} H' Γ x (4.29) on the interlaced matrices
    rng = np.random.default_rng(seed)
    n, l, m, i = 5, 1, 2, 6
    A, B, C, D = _random_system(rng, n, l + m, 3)
    D[:, l:] += np.vstack([np.zeros((1, m)), np.eye(m)])  # control channel full column rank
    Gam, H = _batch(A, B, C, D, i)
    rcols = np.concatenate([np.arange(t * (l + m), t * (l + m) + l) for t in range(i)])
    ucols = np.setdiff1d(np.arange(i * (l + m)), rcols)
    Md, Mu = H[:, rcols], H[:, ucols]
    Pu = Mu @ np.linalg.pinv(Mu)
    gmin = np.sqrt(np.linalg.eigvalsh(Md.T @ (np.eye(len(Pu)) - Pu) @ Md).max())
    assert np.isclose(gmin, synthesis.minimax_gamma_min(Md, Mu), rtol=1e-9)
    gamma = 1.3 * gmin
    Rgd = np.kron(np.eye(i), np.diag([gamma**2] * l + [0.0] * m))
    x0 = rng.standard_normal(n)
    w_batch = -np.linalg.solve(H.T @ H - Rgd, H.T @ Gam @ x0)
    law = hinf_riccati(A, B, C, D, gamma=gamma, horizon=i, n_disturbances=l)
    w, xs = law.rollout(x0)
    np.testing.assert_allclose(w.reshape(-1), w_batch, rtol=1e-8, atol=1e-10)
    z = Gam @ x0 + H @ w_batch
    np.testing.assert_allclose(x0 @ law.value @ x0, z @ z - w_batch @ Rgd @ w_batch, rtol=1e-8)
    # Theorem 4.3's reduction: the same numbers from the LQR recursion with Q = I, R = -R_gamma
    lq = lqr_riccati(A, B, C, D, np.eye(3), -np.diag([gamma**2] * l + [0.0] * m), horizon=i)
    np.testing.assert_allclose(lq.rollout(x0)[0], w, rtol=1e-8, atol=1e-10)
    # the stage saddle conditions hold exactly when gamma exceeds the batch gamma_min
    hinf_riccati(A, B, C, D, gamma=1.001 * gmin, horizon=i, n_disturbances=l)
    with pytest.raises(StageSaddleError):
        hinf_riccati(A, B, C, D, gamma=0.999 * gmin, horizon=i, n_disturbances=l)


def _noise_free_data(i, n=400, seed=0):
    P = servo()
    u = prbs(n, seed=seed)
    d = collect_data(P, u)
    # true plant state along the record (same realisation as P)
    x = np.zeros((n + 1, P.nstates))
    for k in range(n):
        x[k + 1] = P.A @ x[k] + P.B[:, 0] * u[k]
    return P, d, x


def _w_p(d, k, i):
    return np.concatenate([d.u[k - i:k].reshape(-1), d.y[k - i:k].reshape(-1)])  # (3.13)


@pytest.mark.filterwarnings("ignore::synthesis.PersistenceWarning")
@pytest.mark.parametrize("k", [250, 371])
def test_theorem_4_3_subspace_hinf_equals_riccati(k):
    i = 6
    P, d, x = _noise_free_data(i)
    pred = synthesis.fit_predictor(d.u, d.y, i)
    np.testing.assert_allclose(pred.Lu, synthesis.markov_toeplitz(P, i), atol=1e-7)
    W1, W2 = _weights()
    gmin = synthesis.gamma_min(pred, W1, W2)
    gamma = 1.5 * gmin
    design = synthesis.hinf_design(pred, W1, W2, gamma=gamma)
    rng = np.random.default_rng(k)
    xw1, xw2 = rng.standard_normal(1), rng.standard_normal(1)
    u_sub = design.gain @ np.concatenate([_w_p(d, k, i), xw1, xw2])
    gp = generalized_plant(P, W1, W2)
    law = hinf_riccati(gp, gamma=gamma, horizon=i)
    u_ric = law.controls(gp.state(x[k], xw1, xw2))
    scale = np.abs(u_ric).max()
    np.testing.assert_allclose(u_sub, u_ric, atol=1e-6 * max(scale, 1.0))
    # worst-case references agree too
    r_ric = law.rollout(gp.state(x[k], xw1, xw2))[0][:, 0]
    r_sub = design.disturbance_gain @ np.concatenate([_w_p(d, k, i), xw1, xw2])
    np.testing.assert_allclose(r_sub, r_ric, atol=1e-6 * max(np.abs(r_ric).max(), 1.0))


@pytest.mark.filterwarnings("ignore::synthesis.PersistenceWarning")
def test_theorem_4_4_subspace_lqg_equals_lqr():
    lqg_design = getattr(synthesis, "lqg_design", None)
    if lqg_design is None:
        lqg = pytest.importorskip("synthesis.lqg")
        lqg_design = lqg.lqg_design
    i, k = 6, 300
    P, d, x = _noise_free_data(i, seed=4)
    pred = synthesis.fit_predictor(d.u, d.y, i)
    Q, R = 2.0, 0.3
    des = lqg_design(pred, Q, R, dt=0.1)
    u_sub = des.gain @ _w_p(d, k, i)
    law = lqr_riccati(P.A, P.B, P.C, P.D, Q, R, horizon=i)
    u_ric = law.controls(x[k])
    np.testing.assert_allclose(u_sub, u_ric, atol=1e-6 * max(np.abs(u_ric).max(), 1.0))


def test_bad_input():
    A, B, C, D = _random_system(np.random.default_rng(0), 3, 2, 2)
    with pytest.raises(ValueError):
        hinf_riccati(A, B, C, D, gamma=-1.0, horizon=3, n_disturbances=1)
    with pytest.raises(ValueError):
        hinf_riccati(A, B, C, D, gamma=1.0, horizon=0, n_disturbances=1)
    with pytest.raises(ValueError):
        hinf_riccati(A, B, C, D, gamma=1.0, horizon=3, n_disturbances=2)
    with pytest.raises(ValueError):
        lqr_riccati(A, B, C, D, np.eye(3), 1.0, horizon=3)
    with pytest.raises(ValueError):
        lqr_riccati(A, B, C, D, 1.0, 1.0, horizon=3).rollout([np.nan, 0, 0])


def test_complex_and_text_input_is_refused():
    """Complex plants and weights had lost their imaginary part (ComplexWarning) or raised a bare TypeError; a
    text Q had been parsed as a number; a text x0 had raised numpy's ValueError."""
    import warnings

    from synthesis import DataError

    A, B, C, D = _random_system(np.random.default_rng(0), 3, 2, 2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # refused before numpy's ComplexWarning
        with pytest.raises(DataError, match=r"A is complex.*take the real part"):
            hinf_riccati(A * (1 + 1j), B, C, D, gamma=5.0, horizon=3, n_disturbances=1)
        with pytest.raises(DataError, match="D is complex"):
            lqr_riccati(A, B, C, D + 0j, 1.0, 1.0, horizon=3)
        with pytest.raises(DataError, match="Q is complex"):
            lqr_riccati(A, B, C, D, 1j, 1.0, horizon=3)
    with pytest.raises(DataError, match=r"R must be real numbers, not text \('1'\)"):
        lqr_riccati(A, B, C, D, 1.0, "1", horizon=3)
    law = lqr_riccati(A, B, C, D, 1.0, 1.0, horizon=3)
    with pytest.raises(DataError, match="x0 must be real numbers, not text"):
        law.controls("a")
    with pytest.raises(DataError, match="x0 is complex"):
        law.controls([1j, 0, 0])


@pytest.mark.filterwarnings("ignore::synthesis.PersistenceWarning")
def test_theorem_4_3_mimo_three_disk():
    # one input, three outputs (order 6 < i = 10), diagonal dynamic W1
    from experiments.lab.plants import three_disk

    P, i, n, k = three_disk("all"), 10, 800, 600
    u = prbs(n, seed=0)
    d = collect_data(P, u)
    x = np.zeros((n + 1, P.nstates))
    for t in range(n):
        x[t + 1] = P.A @ x[t] + P.B[:, 0] * u[t]
    pred = synthesis.fit_predictor(d.u, d.y, i)
    w1 = synthesis.tustin(ct.tf([0.5, 20.0], [1.0, 1.0]), 1 / 64)
    W1a = ct.append(w1, w1, w1)
    W1 = ct.ss(W1a.A, W1a.B, W1a.C, W1a.D, 1 / 64)
    W2 = synthesis.tustin(ct.tf([0.05, 0.05], [1.0, 100.0]), 1 / 64)
    gamma = 1.5 * synthesis.gamma_min(pred, W1, W2)
    design = synthesis.hinf_design(pred, W1, W2, gamma=gamma)
    gp = generalized_plant(P, W1, W2)
    assert (gp.l, gp.m, gp.n_w1) == (3, 1, 3)
    rng = np.random.default_rng(1)
    xw1, xw2 = rng.standard_normal(gp.n_w1), rng.standard_normal(gp.n_w2)
    w_p = np.concatenate([d.u[k - i:k].ravel(), d.y[k - i:k].ravel()])  # (3.13), y_t stacked per time
    u_sub = design.gain @ np.concatenate([w_p, xw1, xw2])
    law = hinf_riccati(gp.A, gp.B, gp.C, gp.D, gamma=gamma, horizon=i, n_disturbances=gp.l)
    u_ric = law.controls(gp.state(x[k], xw1, xw2))
    np.testing.assert_allclose(u_sub, u_ric, atol=1e-6 * np.abs(u_ric).max())


def test_non_finite_weights_and_levels_are_named():
    from synthesis import DataError

    A, B, C, D = _random_system(np.random.default_rng(0), 3, 2, 2)
    with pytest.raises(DataError, match="Q"):
        lqr_riccati(A, B, C, D, np.nan, 1.0, horizon=3)
    with pytest.raises(DataError, match="R"):
        lqr_riccati(A, B, C, D, 1.0, np.full((2, 2), np.inf), horizon=3)
    with pytest.raises(DataError, match="terminal"):
        lqr_riccati(A, B, C, D, 1.0, 1.0, horizon=3, terminal=np.full((3, 3), np.nan))
    for bad in ("1.0", None, np.nan):
        with pytest.raises(DataError, match="gamma"):
            hinf_riccati(A, B, C, D, gamma=bad, horizon=3, n_disturbances=1)


def test_non_symmetric_weights_are_refused_not_misread():
    """A non-symmetric Q had given, with a feedthrough D, the gains of another cost (1.46 off those of its
    symmetric part, which has the same cost ``yᵀQy``): the recursion's ``CᵀQD`` and ``DᵀQD`` assume ``Q = Qᵀ``."""
    from synthesis import DataError

    A, B, C, D = np.array([[0.5, 0.1], [0.0, 0.3]]), np.eye(2), np.eye(2), np.array([[1.0, 0.5], [0.2, 1.0]])
    Q = np.array([[1.0, 2.0], [0.0, 1.0]])
    with pytest.raises(DataError, match=r"Q must be symmetric.*\(Q \+ Qᵀ\)/2"):
        lqr_riccati(A, B, C, D, Q, np.eye(2), horizon=3)
    with pytest.raises(DataError, match="R must be symmetric"):
        lqr_riccati(A, B, C, D, np.eye(2), Q, horizon=3)
    with pytest.raises(DataError, match="terminal must be symmetric"):
        lqr_riccati(A, B, C, D, np.eye(2), np.eye(2), horizon=3, terminal=Q)
    # the symmetric part is accepted, and an indefinite symmetric R (Thm 4.3's −R_γ) still is
    lqr_riccati(A, B, C, D, 0.5 * (Q + Q.T), np.eye(2), horizon=3)
    lqr_riccati(A, B, C, D, np.eye(2), np.diag([1.0, -0.01]), horizon=3)


@pytest.mark.parametrize("bad", [1.5, True, "1", np.float64(1.0)])
def test_n_disturbances_must_be_an_integer(bad):
    """int() had read 1.5, True and "1" as 1: the split of w = [r; u] was not the one asked for."""
    from synthesis import DataError

    A, B, C, D = _random_system(np.random.default_rng(1), 2, 2, 2)
    with pytest.raises(DataError, match="n_disturbances must be an integer"):
        hinf_riccati(A, B, C, D, gamma=50.0, horizon=3, n_disturbances=bad)
    assert hinf_riccati(A, B, C, D, gamma=50.0, horizon=3, n_disturbances=np.int64(1)).n_disturbances == 1


def test_refusal_just_above_the_batch_gamma_min_names_the_exact_route():
    """Near γ_min the stage test is decided by rounding: at 1 + 1e-6 times the batch γ_min (where the exact
    saddle exists) this plant's recursion refuses; the refusal says so and names the batch route."""
    P = ct.ss([[0.65]], [[0.32, 1.34]], [[1.13]], [[0.0, 0.0]], 1.0)
    W1 = ct.ss([[0.74]], [[1.0]], [[4.66]], [[8.51]], 1.0)
    W2 = ct.ss(np.diag([0.42, 0.43]), np.diag([1.0, 0.1]), np.diag([3.01, -0.67]), np.diag([6.4, 0.28]), 1.0)
    i = 15
    gp = generalized_plant(P, W1, W2)
    H = synthesis.markov_toeplitz(gp.system, i)
    Md, Mu = H[:, 0::3], np.hstack([H[:, 1::3], H[:, 2::3]])  # w_t = [r_t; u_t]
    gmin = synthesis.minimax_gamma_min(Md, Mu)
    with pytest.warns(synthesis.NearGammaMinWarning):  # the batch saddle exists there
        synthesis.solve_minimax(Md, Mu, synthesis.observability(gp.system, i), (1 + 1e-6) * gmin)
    with pytest.raises(StageSaddleError, match=r"rounding.*minimax_gamma_min"):
        hinf_riccati(gp, gamma=(1 + 1e-6) * gmin, horizon=i)
    hinf_riccati(gp, gamma=1.1 * gmin, horizon=i)


@pytest.mark.parametrize("big", [1e3, 1e7])
def test_stage_test_does_not_depend_on_channel_scales(big):
    """The stage saddle test is made on the diagonally scaled stage matrix (a congruence: same inertia). Its
    tolerance had been relative to max|M|, so a control weight diag(0.1, 1e7) refused the diagonal control block
    diag(0.26, 1e14) as "not positive definite" at 1.1 γ_min, where the batch law exists and equals the recursion's."""
    P = ct.ss([[0.5]], [[1.0, 1.0]], [[1.0]], [[0.5, 0.0]], 1.0)
    gp = generalized_plant(P, 1.0, np.diag([0.1, big]))
    i = 3
    Gam, H = _batch(gp.A, gp.B, gp.C, gp.D, i)
    Md, Mu = H[:, 0::3], np.hstack([H[:, 1::3], H[:, 2::3]])  # w_t = [r_t; u1_t; u2_t]
    gamma = 1.1 * synthesis.minimax_gamma_min(Md, Mu)
    law = hinf_riccati(gp, gamma=gamma, horizon=i)
    x0 = np.ones(gp.A.shape[0])
    u = synthesis.solve_minimax(Md, Mu, Gam, gamma).u_gain @ x0  # [u1 over the horizon; u2 over the horizon]
    np.testing.assert_allclose(law.controls(x0), u.reshape(2, i).T.reshape(-1), rtol=1e-9, atol=1e-12 * np.abs(u).max())
