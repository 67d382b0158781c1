"""Coprime-factor uncertainty of P̂ (issue 24, item 4): factors, channel, Theorem 7.1 on the equation error,
the pointwise gaps, and the pipeline's coprime form on an integrating plant.

Every number is checked by a second route: the factors against ``predictor_model`` and the predictor's own
one-step error, the channel against ``[C_y; I](M̂ − N̂C_y)⁻¹`` evaluated pointwise, ε against the cvxpy model,
the gaps against least-norm solutions by ``lstsq`` and against sampled plants.
"""
import pickle

import control
import numpy as np
import pytest
import scipy.signal

import synthesis as sy
import unfalsify as uf
from synthesis.validation import DataError

SHAPES = [(1, 1), (2, 2), (2, 1), (1, 2)]  # (l, m)


def _arx_data(l, m, n=400, noise=0.01, seed=0):
    """A stable l × m plant with output noise; u white."""
    rng = np.random.default_rng(seed)
    A = np.diag(np.linspace(0.5, 0.8, 2 * l))[:2 * l, :2 * l]
    B = rng.standard_normal((2 * l, m))
    C = rng.standard_normal((l, 2 * l))
    P = control.ss(A, B, C, np.zeros((l, m)), 1.0)
    u = rng.standard_normal((n, m))
    y = np.asarray(control.forced_response(P, T=np.arange(n), U=u.T).outputs).reshape(l, n).T
    return P, u, y + noise * rng.standard_normal((n, l))


def _predictor_error(pred, u, y):
    """The first block row's one-step error, by loops over the delay line (second route to the residual)."""
    i, m, l = pred.horizon, pred.m, pred.l
    C, D = pred.Lw[:l], pred.Lu[:l, :m]
    out = []
    for k in range(i, u.shape[0]):
        wp = np.concatenate([u[k - i:k].reshape(-1), y[k - i:k].reshape(-1)])
        out.append(y[k] - C @ wp - D @ u[k])
    return np.array(out)


@pytest.mark.parametrize("l,m", SHAPES)
def test_factors_are_the_predictor_model(l, m):
    _, u, y = _arx_data(l, m)
    pred = sy.fit_predictor(u, y, 3)
    F = uf.coprime_factors(pred, 1.0)
    assert F.N.shape == (4, l, m) and F.M.shape == (4, l, l) and np.allclose(F.M[0], np.eye(l))
    P = uf.predictor_model(pred, 1.0)
    w = np.linspace(0.05, 3.0, 7)
    G = np.moveaxis(np.asarray(P.horner(np.exp(1j * w)), complex).reshape(l, m, -1), -1, 0)
    Nw, Mw = F.response(w)
    assert np.allclose(Mw @ G, Nw, atol=1e-9)                     # M̂ P̂ = N̂
    G2 = np.moveaxis(np.asarray(F.model().horner(np.exp(1j * w)), complex).reshape(l, m, -1), -1, 0)
    assert np.allclose(G2, G, atol=1e-9)
    e = F.residual(u, y).reshape(-1, l)
    assert np.allclose(e, _predictor_error(pred, u, y), atol=1e-10)
    assert pickle.loads(pickle.dumps(F)) == F


@pytest.mark.parametrize("l,m", SHAPES)
def test_coprime_channel_matches_its_formula(l, m):
    _, u, y = _arx_data(l, m, seed=1)
    F = uf.coprime_factors(sy.fit_predictor(u, y, 2), 1.0)
    rng = np.random.default_rng(4)
    Cy = -0.2 * rng.standard_normal((m, l))
    K = control.ss([[0.3]], rng.standard_normal((1, 2 * l)) * 0.1, rng.standard_normal((m, 1)) * 0.1,
                   np.hstack([-Cy, Cy]), 1.0)
    H = uf.coprime_channel(F, K)
    assert (H.ninputs, H.noutputs) == (l, m + l)
    w = np.linspace(0.01, 3.1, 9)
    z = np.exp(1j * w)
    got = np.moveaxis(np.asarray(H.horner(z), complex).reshape(m + l, l, -1), -1, 0)
    Kc = np.moveaxis(np.asarray(K.horner(z), complex).reshape(m, 2 * l, -1), -1, 0)[:, :, l:]
    Nw, Mw = F.response(w)
    inv = np.linalg.inv(Mw - Nw @ Kc)
    want = np.concatenate([Kc @ inv, inv], axis=1)
    assert np.allclose(got, want, atol=1e-8)


def test_channel_is_finite_for_an_integrator_and_certify_uses_it():
    F = uf.CoprimeFactors(N=np.array([[[0.0]], [[0.1]]]), M=np.array([[[1.0]], [[-1.0]]]), dt=1.0)
    K = control.ss([], [], [], [[2.0, -2.0]], 1.0)
    H = uf.coprime_channel(F, K)
    w = np.linspace(0.0, np.pi, 20001)
    grid = np.max(np.linalg.norm(np.asarray(H.horner(np.exp(1j * w)), complex).reshape(2, -1), axis=0))
    cert = uf.certify_loop(F.model(), K, 0.05, factors=F)
    assert cert.uncertainty == "coprime" and cert.certified
    assert cert.norm.lower <= grid * (1 + 1e-9) and cert.norm.upper >= grid * (1 - 1e-6)
    assert cert.small_gain == pytest.approx(0.05 * cert.norm.upper)
    assert cert.bounded_real is not None and cert.bounded_real.verify()
    too_big = uf.certify_loop(F.model(), K, 1.0 / grid, factors=F)
    assert not too_big.certified and too_big.reason.startswith("small gain: ε")
    other = uf.CoprimeFactors(N=np.array([[[0.0]], [[0.2]]]), M=F.M, dt=1.0)
    with pytest.raises(DataError, match="not those of the model"):
        uf.certify_loop(F.model(), K, 0.05, factors=other)


@pytest.mark.parametrize("l,m", [(1, 1), (2, 1)])
def test_coprime_gap_is_the_least_norm_perturbation(l, m):
    F = uf.coprime_factors(sy.fit_predictor(*_arx_data(l, m, seed=2)[1:], 2), 1.0)
    rng = np.random.default_rng(5)
    w = np.array([0.1, 0.7, 2.0])
    G = rng.standard_normal((3, l, m)) + 1j * rng.standard_normal((3, l, m))
    gap = uf.coprime_gap(F, w, G if l * m > 1 else G[:, 0, 0])
    Nw, Mw = F.response(w)
    for k in range(3):
        Z = np.vstack([np.eye(m), G[k]])                              # X Z = M̂G − N̂, X = [Δ_N  −Δ_M]
        R = Mw[k] @ G[k] - Nw[k]
        X = np.linalg.lstsq(Z.T, R.T, rcond=None)[0].T               # the least-norm solution
        assert gap[k] == pytest.approx(np.linalg.norm(X, 2), rel=1e-9)
    # with a radius: a lower bound over the whole region (sampled plants in it all need at least that much)
    r = np.full(3, 0.3)
    low = uf.coprime_gap(F, w, G if l * m > 1 else G[:, 0, 0], r)
    for _ in range(200):
        E = rng.standard_normal((3, l, m)) + 1j * rng.standard_normal((3, l, m))
        E *= (0.3 * rng.uniform(size=3) / np.linalg.norm(E, 2, axis=(1, 2)))[:, None, None]
        exact = uf.coprime_gap(F, w, (G + E) if l * m > 1 else (G + E)[:, 0, 0])
        assert np.all(low <= exact + 1e-12)


def test_error_gap_is_a_lower_bound_of_the_distance():
    """From an estimate of R = M̂P − N̂ alone (no estimate of P), below the exact distance of every P it allows."""
    F = uf.coprime_factors(sy.fit_predictor(*_arx_data(1, 1, seed=3)[1:], 3), 1.0)
    rng = np.random.default_rng(6)
    w = np.linspace(0.05, 3.0, 12)
    Nw, Mw = F.response(w)
    R0 = 0.3 * (rng.standard_normal(12) + 1j * rng.standard_normal(12))
    est = uf.LowBandEstimate(frequency=w, response=R0, radius=np.full(12, 0.1), confidence=0.99, window=16,
                             degree=2, samples=100, dt=1.0)
    low = uf.error_gap(F, est)
    for _ in range(100):
        R = R0 + 0.1 * rng.uniform(size=12) * np.exp(2j * np.pi * rng.uniform(size=12))
        P = (Nw[:, 0, 0] + R) / Mw[:, 0, 0]
        assert np.all(low <= uf.coprime_gap(F, w, P) + 1e-12)



def _least_over_disk(R0, r, N, M, rings=60, angles=2000):
    """The least ``|X||M|/√(|M|² + |N + X|²)`` over ``|X − R0| ≤ r`` by a dense grid (from above)."""
    X = (R0[:, None, None] + np.linspace(0.0, r, rings)[None, :, None]
         * np.exp(2j * np.pi * np.arange(angles) / angles)[None, None, :])
    m, n = np.abs(M)[:, None, None], N[:, None, None]
    g = np.abs(X) * m / np.sqrt(m ** 2 + np.abs(n + X) ** 2)
    return g.min(axis=(1, 2))


def test_error_gap_one_channel_is_the_least_distance_over_the_disk():
    """One channel: the bound is the least pointwise distance over the confidence disk of R (a dense grid from above
    is at most 1e-4 higher, never lower), and never below the bound the triangle inequality gave, x μ/√(μ² + (ν + x)²)
    with x = |R̂| − r, which a slow mode cancelling P's gain left 3.3 times below the true distance
    (the 2026-11-29 hunt: 0.088 against 0.29, and against ε = 0.091)."""
    F = uf.coprime_factors(sy.fit_predictor(*_arx_data(1, 1, seed=3)[1:], 3), 1.0)
    rng = np.random.default_rng(11)
    w = np.linspace(0.02, 3.0, 40)
    Nw, Mw = F.response(w)
    N, M = Nw[:, 0, 0], Mw[:, 0, 0]
    R0 = np.where(np.arange(40) % 2 == 0, -N + 0.3 * M * np.exp(2j * np.pi * rng.uniform(size=40)),  # P near 0
                  rng.standard_normal(40) + 1j * rng.standard_normal(40))
    r = 0.4 * np.abs(R0) * rng.uniform(size=40)
    est = uf.LowBandEstimate(frequency=w, response=R0, radius=r, confidence=0.99, window=16, degree=2, samples=100,
                             dt=1.0)
    low = uf.error_gap(F, est)
    grid = np.array([_least_over_disk(R0[k:k + 1], r[k], N[k:k + 1], M[k:k + 1])[0] for k in range(40)])
    assert np.all(low <= grid + 1e-12) and np.all(low >= grid - 1e-4)
    x, mu, nu = np.abs(R0) - r, np.abs(M), np.abs(N)
    former = x * mu / np.sqrt(mu ** 2 + (nu + x) ** 2)
    assert np.all(low >= former - 1e-12)
    assert np.median(low[::2] / former[::2]) > 1.5                  # where P is small the former bound was loose


def test_error_gap_several_channels_bounds_sigma_of_n_plus_r_from_the_estimate():
    """Several channels: σ̄(N̂ + R) ≤ σ̄(N̂ + R̂) + r enters beside ν + σ̄(R), so where the plant's response is small
    the bound is larger than the triangle inequality's, and still below the distance of every sampled plant."""
    F = uf.coprime_factors(sy.fit_predictor(*_arx_data(2, 2, seed=4)[1:], 2), 1.0)
    rng = np.random.default_rng(12)
    w = np.linspace(0.05, 2.0, 6)
    Nw, Mw = F.response(w)
    R0 = -Nw + 0.05 * (rng.standard_normal((6, 2, 2)) + 1j * rng.standard_normal((6, 2, 2)))  # M̂P = N̂ + R small
    r = np.full(6, 0.02)
    est = uf.LowBandEstimate(frequency=w, response=R0, radius=r, confidence=0.99, window=16, degree=2, samples=100,
                             dt=1.0)
    low = uf.error_gap(F, est)
    x = np.linalg.norm(R0, 2, axis=(1, 2)) - r
    mu, nu = np.linalg.svd(Mw, compute_uv=False)[:, -1], np.linalg.norm(Nw, 2, axis=(1, 2))
    assert np.all(low > 1.2 * x * mu / np.sqrt(mu ** 2 + (nu + x) ** 2))
    for _ in range(200):
        E = rng.standard_normal((6, 2, 2)) + 1j * rng.standard_normal((6, 2, 2))
        E *= (0.02 * rng.uniform(size=6) / np.linalg.norm(E, 2, axis=(1, 2)))[:, None, None]
        P = np.linalg.solve(Mw, Nw + R0 + E)
        assert np.all(low <= uf.coprime_gap(F, w, P) + 1e-12)


def test_error_gap_several_inputs_reads_the_region_directions():
    """Several inputs: σ̄(R) ≥ ‖R̂v‖ − ‖Qv‖ for each unit v (Q the region's factor), so an equation error the record
    shows in its well-excited input direction bounds the distance from below although the other direction's
    confidence is wide (σ̄(R̂) − σ̄(Q) < 0: the isotropic bound was 0); still below the distance of every sampled
    plant of the region (R = R̂ + WQ, σ̄(W) ≤ 1)."""
    import dataclasses

    F = uf.coprime_factors(sy.fit_predictor(*_arx_data(2, 2, seed=4)[1:], 2), 1.0)
    rng = np.random.default_rng(5)
    w = np.linspace(0.05, 2.0, 6)
    Nw, Mw = F.response(w)
    R0 = np.tile(np.diag([0.0, 0.3]).astype(complex), (6, 1, 1))  # on input 1
    Q = np.diag([0.5, 0.02])  # input 0 barely excited
    est = uf.LowBandEstimate(frequency=w, response=R0, radius=np.full(6, 0.5), confidence=0.99, window=16, degree=2,
                             samples=100, dt=1.0, region=np.tile(Q, (6, 1, 1)))
    low = uf.error_gap(F, est)
    assert np.all(uf.error_gap(F, dataclasses.replace(est, region=None)) == 0.0)  # 0.3 − 0.5 < 0
    assert np.all(low > 0.02)
    for _ in range(200):
        W = rng.standard_normal((6, 2, 2)) + 1j * rng.standard_normal((6, 2, 2))
        W /= np.linalg.norm(W, 2, axis=(1, 2))[:, None, None] / rng.uniform(size=6)[:, None, None]
        P = np.linalg.solve(Mw, Nw + R0 + W @ Q)
        assert np.all(low <= uf.coprime_gap(F, w, P) + 1e-12)


def test_error_gap_refuses_an_estimate_of_another_sample_time():
    """The estimate's frequencies are rad/s of its own dt: read with the factors' dt they named other points of the
    unit circle, and the bound was that of another frequency without a word.  With the same dt it is unchanged."""
    F = uf.coprime_factors(sy.fit_predictor(*_arx_data(1, 1, seed=3)[1:], 3), 0.1)
    w = np.linspace(0.5, 30.0, 8)                      # rad/s at dt = 0.1
    kw = dict(response=np.full(8, 0.3 + 0.1j), radius=np.full(8, 0.02), confidence=0.99, window=16, degree=2,
              samples=100)
    same = uf.error_gap(F, uf.LowBandEstimate(frequency=w, dt=0.1, **kw))
    Nw, Mw = F.response(w)
    assert same == pytest.approx(_least_over_disk(np.full(8, 0.3 + 0.1j), 0.02, Nw[:, 0, 0], Mw[:, 0, 0]), abs=1e-4)
    with pytest.raises(DataError, match=r"estimated with dt = 1 but the sample time of the factors is 0.1.*dt=0.1"):
        uf.error_gap(F, uf.LowBandEstimate(frequency=w / 10, dt=1.0, **kw))

def _integrator(n, seed, noise=0.02):
    rng = np.random.default_rng(seed)
    u = np.sign(rng.standard_normal(n))
    y = np.zeros(n)
    for k in range(1, n):
        y[k] = 0.95 * y[k - 1] + 0.05 * y[k - 2 if k > 1 else 0] + 0.1 * u[k - 1]   # a pole at 1
    return u, y + noise * rng.standard_normal(n)


FAST = uf.PremiseOptions(coprime_samples=120)  # short held-out segments keep these tests to seconds


def test_coprime_unfalsify_certificate_and_second_route():
    u, y = _integrator(700, 0)
    F = uf.coprime_factors(sy.fit_predictor(u[:400], y[:400], 3), 1.0)
    cu = uf.coprime_unfalsify(F, u[400:], y[400:], held_out=True, options=FAST)
    assert cu.held_out and cu.unfalsification.certificate.verify()
    assert 0.0 <= cu.epsilon < 0.05
    # the same program (Theorem 7.1 on w = [u; y] → e) through the cvxpy model, short segment
    e = F.residual(u[400:433], y[400:433])   # 30 rows: the cvxpy model of two input channels grows fast
    w = np.column_stack([u[403:433], y[403:433]])
    sigma = 0.5 * np.std(e)
    short = uf.coprime_unfalsify(F, u[400:433], y[400:433], held_out=True, sigma=sigma,
                                 options=uf.PremiseOptions(tol=1e-7))
    ref = uf.arx_unfalsify(w, e[:, None], 0, 0, sigma, free_rows=3, solver="CLARABEL")
    assert short.epsilon == pytest.approx(ref.delta, rel=1e-4, abs=1e-7)
    # wrong factors (twice the gain) need a much larger ε on the same data
    wrong = uf.CoprimeFactors(N=2.0 * F.N, M=F.M, dt=1.0)
    assert uf.coprime_unfalsify(wrong, u[400:], y[400:], held_out=True, sigma=cu.sigma,
                                options=FAST).epsilon > 10 * cu.epsilon
    with pytest.raises(DataError, match="longer record"):
        uf.coprime_unfalsify(F, u[:12], y[:12], held_out=True)


def test_check_coprime_premise_grows_with_the_model_error():
    """ε of a biased P̂ grows to the size of its distance from the plant (the smallest unfalsified ε, so it may sit
    below the distance by what the noise ball absorbs: the certificate's margin is for that), or it is refused."""
    u, y = _integrator(1200, 1)
    F = uf.coprime_factors(sy.fit_predictor(u[:700], y[:700], 3), 1.0)
    good = uf.check_coprime_premise(F, u[:60], y[:60], 0.01, validation=(u[700:], y[700:]), options=FAST)
    assert good.ok and good.epsilon == max(good.in_sample.epsilon, good.held_out.epsilon)
    assert good.error_frf is not None and good.inconsistency < 1
    assert pickle.loads(pickle.dumps(good)).epsilon == good.epsilon
    plant = control.tf([0.1, 0.0], [1.0, -0.95, -0.05], 1.0)
    biased = uf.CoprimeFactors(N=0.5 * F.N, M=F.M, dt=1.0)   # half the gain
    bad = uf.check_coprime_premise(biased, u[:60], y[:60], 0.01, validation=(u[700:], y[700:]), options=FAST)
    distance, _ = uf.coprime_distance(biased, plant)
    assert distance > 5 * uf.coprime_distance(F, plant)[0]
    assert not bad.ok or (bad.epsilon > 0.5 * distance and bad.epsilon > 2 * good.epsilon)


def test_hand_made_factors_are_checked():
    """The realisations read M[0] = I and a degree of at least 1: factors that break either raise, naming the fix."""
    N, M = np.array([[[0.0]], [[0.1]]]), np.array([[[1.0]], [[-1.0]]])
    with pytest.raises(DataError, match=r"M\[0\] = I.*divide both factors"):
        uf.CoprimeFactors(N=2.0 * N, M=2.0 * M, dt=1.0)  # the same plant, but the realisation would read M[0] = 1
    with pytest.raises(DataError, match="degree i ≥ 1.*pad"):
        uf.CoprimeFactors(N=N[:1], M=M[:1], dt=1.0)
    with pytest.raises(DataError, match=r"shape \(i \+ 1, l, m\)"):
        uf.CoprimeFactors(N=N[:, 0], M=M, dt=1.0)
    with pytest.raises(DataError, match="NaN"):
        uf.CoprimeFactors(N=np.array([[[0.0]], [[np.nan]]]), M=M, dt=1.0)
    with pytest.raises(DataError, match="dt must be"):
        uf.CoprimeFactors(N=N, M=M, dt=0.0)
    F = uf.CoprimeFactors(N=N.tolist(), M=M, dt=1)  # lists and an integer dt are taken as arrays and a float
    assert F.N.dtype == float and F.dt == 1.0 and F.horizon == 1
    z = np.exp(0.5j)
    assert complex(F.model()(z)) == pytest.approx(0.1 / (z - 1.0), rel=1e-12)  # the integrator 0.1/(z − 1)


def test_coprime_distance_checks_the_plant():
    """A continuous-time plant had been evaluated as if it were discrete (a number, no warning)."""
    F = uf.CoprimeFactors(N=np.array([[[0.0]], [[0.1]]]), M=np.array([[[1.0]], [[-1.0]]]), dt=1.0)
    with pytest.raises(DataError, match="continuous-time"):
        uf.coprime_distance(F, control.tf([1.0], [1.0, 1.0]))
    with pytest.raises(DataError, match="sample time 0.1"):
        uf.coprime_distance(F, control.tf([0.1], [1.0, -1.0], 0.1))
    with pytest.raises(DataError, match="2 × 2"):
        uf.coprime_distance(F, control.ss([], [], [], np.eye(2), 1.0))
    assert uf.coprime_distance(F, control.tf([0.1], [1.0, -1.0], 1.0))[0] == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("bad", [0, 1, -3, 5.5, "512", True])
def test_coprime_distance_checks_the_grid_size(bad):
    # points=0 had raised IndexError (argmax of an empty grid), 5.5 numpy's TypeError
    F = uf.CoprimeFactors(N=np.array([[[0.0]], [[0.1]]]), M=np.array([[[1.0]], [[-1.0]]]), dt=1.0)
    with pytest.raises(DataError, match=r"points must be an integer ≥ 2"):
        uf.coprime_distance(F, control.tf([0.2], [1.0, -1.0], 1.0), bad)
    # 2 points are the grid's two ends, 10⁻⁴ of Nyquist and Nyquist
    d, w = uf.coprime_distance(F, control.tf([0.2], [1.0, -1.0], 1.0), 2)
    assert d > 0 and (w == pytest.approx(np.pi) or w == pytest.approx(1e-4 * np.pi))


def test_hand_made_factors_refuse_strings_and_complex_taps():
    # N="x" had raised numpy's "could not convert string to float"; complex taps lost their imaginary part silently
    M = np.array([[[1.0]], [[-1.0]]])
    with pytest.raises(DataError, match=r"numeric taps: N must be an array of shape \(i \+ 1, l, m\), got str"):
        uf.CoprimeFactors(N="x", M=M, dt=1.0)
    with pytest.raises(DataError, match=r"numeric taps: M must be an array .*got ndarray"):   # text is not parsed
        uf.CoprimeFactors(N=np.array([[[0.0]], [[0.1]]]), M=M.astype(str), dt=1.0)
    with pytest.raises(DataError, match="real taps; M is complex"):
        uf.CoprimeFactors(N=np.array([[[0.0]], [[0.1]]]), M=M + 0.5j, dt=1.0)


def _gap_factors(l=1, m=1, dt=1.0):
    N = np.zeros((2, l, m))
    N[1] = 0.1
    M = np.stack([np.eye(l), -np.eye(l)])
    return uf.CoprimeFactors(N=N, M=M, dt=dt)


@pytest.mark.parametrize("kw, fragment", [
    (dict(response=np.ones(2)), r"response has shape \(2,\) for 3 frequencies.*pass \(3, 1, 1\) or \(3,\)"),
    (dict(response="x"), "response must be a numeric array, got str"),
    (dict(radius=-0.1), "radius must be ≥ 0"),
    (dict(radius=[0.1, np.nan, 0.1]), "radius must be ≥ 0"),
    (dict(radius=[0.1, 0.1]), r"radius has shape \(2,\); pass one number or 3"),
    (dict(frequency=[0.1, np.nan, 1.0]), r"frequency\[1\] = nan lies outside \[0, π/dt\]"),
    (dict(frequency=[0.1, 4.0, 1.0]), r"frequency\[1\] = 4 lies outside \[0, π/dt\] = \[0, 3.14159\]"),
    (dict(frequency=[-0.1, 0.5, 1.0]), r"frequency\[0\] = -0.1 lies outside"),
    (dict(frequency="x"), "frequency must be a numeric array"),
])
def test_coprime_gap_checks_its_inputs(kw, fragment):
    """A response of another length had raised numpy's reshape error, a string numpy's conversion error; a negative
    radius, a NaN frequency or one above Nyquist had given numbers (a NaN or an aliased frequency's gap)."""
    args = dict(frequency=np.array([0.1, 0.5, 1.0]), response=np.ones(3, complex), radius=None)
    args.update(kw)
    with pytest.raises(DataError, match=fragment):
        uf.coprime_gap(_gap_factors(), args["frequency"], args["response"], args["radius"])


def test_coprime_gap_refuses_a_flat_response_for_several_channels_and_takes_nyquist():
    # (2F,) for a 2 × 1 model had been reshaped to (F, 2, 1) and read through its first entry only (the SISO path)
    F = _gap_factors(2, 1)
    w = np.array([0.1, 1.0])
    G = np.arange(1.0, 5.0).reshape(2, 2, 1) + 0j
    with pytest.raises(DataError, match=r"response has shape \(4,\).*2 × 1.*pass \(2, 2, 1\), one response"):
        uf.coprime_gap(F, w, G.ravel())
    np.testing.assert_allclose(uf.coprime_gap(F, w, G), uf.coprime_gap(F, w, G.tolist()), rtol=0)
    # the ends of [0, π/dt] are frequencies (dt = 0.5: Nyquist 2π rad/s), and the gap there the one at dt = 1 of ωdt
    w2 = np.array([0.0, 2.0 * np.pi])
    g2 = uf.coprime_gap(_gap_factors(dt=0.5), w2, np.array([0.3, -0.2 + 0j]))
    np.testing.assert_allclose(g2, uf.coprime_gap(_gap_factors(), w2 * 0.5, np.array([0.3, -0.2 + 0j])), rtol=1e-15)


@pytest.mark.parametrize("bad", ["x", -0.01, 0.0, float("nan"), True])
def test_coprime_noise_levels_are_checked(bad):
    # sigma="x" had reached float() (a bare ValueError), and in check_coprime_premise a "reason" of the result
    _, u, y = _arx_data(1, 1, n=300, seed=4)
    F = uf.coprime_factors(sy.fit_predictor(u[:200, 0], y[:200, 0], 2), 1.0)
    with pytest.raises(DataError, match=r"sigma (\(the admissible rms noise level\) )?must be"):
        uf.coprime_unfalsify(F, u[200:, 0], y[200:, 0], held_out=True, sigma=bad)
    with pytest.raises(DataError, match=r"sigma_window \(the admissible rms noise of \(7.5\).* must be a"):
        uf.check_coprime_premise(F, u[:60, 0], y[:60, 0], bad)


def test_an_unspecified_sample_time_is_kept():
    """``dt=True`` (unspecified) had been stored as ``float(True)`` = 1.0: a sample time of one second the data never
    had, which then contradicted a plant at any other sample time."""
    _, u, y = _arx_data(1, 1, n=400, seed=5)
    pred = sy.fit_predictor(u[:300, 0], y[:300, 0], 2)
    F_true, F_one = uf.coprime_factors(pred, True), uf.coprime_factors(pred, 1.0)
    assert F_true.dt is True and F_true.model().dt is True and F_true.equation().dt is True
    assert uf.CoprimeFactors(N=F_one.N, M=F_one.M, dt=True).dt is True
    np.testing.assert_array_equal(F_true.N, F_one.N)
    # True matches any sample time and reads frequencies in rad/sample: the distance of a plant at 0.5 from F_true is
    # that of the same coefficients at 1.0 from F_one (second route)
    plant = lambda dt: control.tf([0.3, 0.1], [1.0, -0.6], dt)  # noqa: E731
    assert uf.coprime_distance(F_true, plant(0.5)) == uf.coprime_distance(F_one, plant(1.0))
    with pytest.raises(DataError, match="sample time 0.5 but the factors 1.0"):
        uf.coprime_distance(F_one, plant(0.5))
    prem = uf.check_coprime_premise(F_true, u[:60, 0], y[:60, 0], 0.005, validation=(u[300:, 0], y[300:, 0]))
    assert prem.error_frf is not None and prem.error_frf.dt == 1.0 and "cannot run" not in prem.reason


def test_noise_free_record_certifies_epsilon_at_the_sigma_floor():
    """A noise-free record of factors perturbed by a known [ΔN ΔM]: the estimated σ was rounding (3e-14), a noise
    ball neither structured method resolved, and ε came back NaN.  σ now has a floor of 1e-8 × the error's rms, the
    rule says so, and ε is certified and not above the true perturbation's norm (the perturbation explains the
    record, so the least unfalsified ε is at most its norm)."""
    rng = np.random.default_rng(8)
    u = np.sign(rng.standard_normal(600))
    y = scipy.signal.lfilter(np.r_[0.0, rng.standard_normal(2)], np.poly(rng.uniform(-0.9, 0.9, 2)), u)
    F = uf.coprime_factors(sy.fit_predictor(u, y + 0.02 * rng.standard_normal(600), 3, dt=1.0))
    dN, dM = 0.03 * rng.standard_normal(2), np.r_[0.0, 0.03 * rng.standard_normal()]
    pad = np.zeros(F.horizon - 1)
    F2 = uf.CoprimeFactors(N=F.N + np.r_[dN, pad][:, None, None], M=F.M + np.r_[dM, pad][:, None, None], dt=1.0)
    u2 = np.sign(rng.standard_normal(400))
    y2 = np.asarray(control.forced_response(F2.model(), T=np.arange(400.0), U=u2).outputs).ravel()
    cu = uf.coprime_unfalsify(F, u2, y2, held_out=True, options=uf.PremiseOptions(coprime_samples=60))
    z = np.exp(-1j * np.linspace(0.0, np.pi, 20001))
    true_norm = np.max(np.hypot(np.abs(dN[0] + dN[1] * z), np.abs(dM[1] * z)))
    assert cu.unfalsification.status == "optimal" and cu.unfalsification.certificate.verify()
    assert 0.5 * true_norm < cu.epsilon <= true_norm * (1 + 1e-9)
    rows = cu.residual[cu.burn_in:cu.burn_in + 60]                      # the rows the noise ball covers
    assert "at its floor" in cu.sigma_rule and cu.sigma == pytest.approx(1e-8 * np.sqrt(np.mean(rows ** 2)))


def test_a_held_out_record_too_short_for_the_equation_error_is_a_reason_not_an_error():
    """A validation record of at most i samples: the coprime test on it could not run (a reason), and the frequency
    estimate after it then formed its residual anyway and raised ("the record has 3 samples; the equation error needs
    more than i = 4"), naming neither the validation record nor the fix, out of robust_design_from_data."""
    rng = np.random.default_rng(3)
    u = np.sign(rng.standard_normal(1200))
    y = np.zeros(1200)
    for k in range(1, 1200):
        y[k] = y[k - 1] + 0.1 * u[k - 1]
    y += 0.02 * rng.standard_normal(1200)
    F = uf.coprime_factors(sy.fit_predictor(u[:700], y[:700], 4), 1.0)
    p = uf.check_coprime_premise(F, u[:300], y[:300], 0.01, validation=(u[700:703], y[700:703]))
    assert not p.ok
    assert "the coprime test on the held-out record cannot run" in p.reason
    assert "equation error on the held-out record" in p.reason
