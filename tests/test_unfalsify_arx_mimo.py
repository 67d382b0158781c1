"""ARX program (7.4) and the output-error premise test with several inputs and outputs (issue 28).

Every MIMO answer is checked against an independent cvxpy formulation written here from the definitions
(the regressor and the data relation written sample by sample, block Toeplitz matrices built by loops),
at small sizes.
"""
import cvxpy as cp
import numpy as np
import pytest
import synthesis

import unfalsify as uf
from _references import SHAPES, block_toeplitz_by_loops
from synthesis import DataError
from unfalsify.solvers import CHANNELS, arx_barrier
from unfalsify.solvers import toeplitz as tz



_bt = block_toeplitz_by_loops


def _fir(u, H):
    """y_s = Σ_t H[t] u_{s−t} (system at rest)."""
    y = np.zeros((u.shape[0], H[0].shape[0]))
    for s in range(u.shape[0]):
        for t in range(min(len(H), s + 1)):
            y[s] += H[t] @ u[s - t]
    return y


def _data(n, l, m, seed, noise=0.1):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n, m))
    H = [0.5 * rng.standard_normal((l, m)) for _ in range(3)]
    return u, _fir(u, H) + noise * rng.standard_normal((n, l))


def _cvx_arx(u, y, na, nb, sigma, free_rows):
    """(7.4) written out: e_s = y_s + Σ A_k y_{s−k} − Σ B_k u_{s−k} + f_s (f free on the first rows),
    e_s − ξ_s = Σ_t h_t u_{s−t}, ‖ξ‖_F ≤ σ√((n − free_rows) l), min ‖T(h)‖₂."""
    n, m = u.shape
    l = y.shape[1]
    A = [cp.Variable((l, l)) for _ in range(na)]
    B = [cp.Variable((l, m)) for _ in range(nb)]
    f = [cp.Variable(l) for _ in range(free_rows)]
    hs = [cp.Variable((l, m)) for _ in range(n)]
    d = cp.Variable()
    xi = []
    for s in range(n):
        e = y[s] + sum(A[k - 1] @ y[s - k] for k in range(1, na + 1) if s - k >= 0) \
            - sum(B[k - 1] @ u[s - k] for k in range(1, nb + 1) if s - k >= 0)
        if s < free_rows:
            e = e + f[s]
        xi.append(e - sum(hs[t] @ u[s - t] for t in range(s + 1)))
    T = cp.bmat([[hs[r - c] if c <= r else np.zeros((l, m)) for c in range(n)] for r in range(n)])
    cons = [cp.norm(cp.hstack(xi), 2) <= sigma * np.sqrt((n - free_rows) * l),
            cp.bmat([[d * np.eye(n * m), T.T], [T, d * np.eye(n * l)]]) >> 0]
    cp.Problem(cp.Minimize(d), cons).solve(solver="CLARABEL")
    return float(d.value)


# ---- the block toolkit the structured solver adds ------------------------------------------------

@pytest.mark.parametrize("n, l, m", [(4, 1, 1), (5, 2, 1), (4, 1, 2), (5, 2, 2), (3, 3, 2)])
def test_block_hessian_is_the_barrier_hessian(n, l, m):
    rng = np.random.default_rng(n + 10 * l + 100 * m)
    N = n * (l + m)
    X = rng.standard_normal((N, N))
    S = X @ X.T
    S11, S21, S22 = S[:n * m, :n * m], S[n * m:, :n * m], S[n * m:, n * m:]
    E = []
    for a in range(n * l * m):
        h = np.zeros(n * l * m)
        h[a] = 1.0
        T = _bt(h.reshape(n, l, m))
        E.append(np.block([[np.zeros((n * m, n * m)), T.T], [T, np.zeros((n * l, n * l))]]))
    ref = np.array([[np.trace(S @ Ea @ S @ Eb) for Eb in E] for Ea in E])
    np.testing.assert_allclose(tz.block_corr_hessian(S11, S21, S22, n, l, m), ref, atol=1e-10 * np.abs(ref).max())
    if l == m == 1:
        np.testing.assert_allclose(tz.block_corr_hessian(S11, S21, S22, n, 1, 1),
                                   tz.corr_hessian(S11[None], S21[None], S22[None], n)[0], atol=1e-12)


def test_block_certified_norm_never_underestimates(monkeypatch):
    h = np.random.default_rng(1).standard_normal((40, 2, 3))
    exact = np.linalg.norm(_bt(h), 2)
    assert tz.block_certified_norm(h) == pytest.approx(exact, rel=1e-12)
    assert tz.block_certified_norm(h[:, 0, 0]) == tz.certified_norm(h[:, 0, 0])  # 1-D: the SISO route
    monkeypatch.setattr(tz, "DENSE_NORM_LIMIT", 10)  # the symbol bound: sup_ω σ_max(ĥ) is larger for white h
    assert exact <= tz.block_certified_norm(h) < np.inf


def test_registry_lists_the_solvers_that_take_several_channels():
    assert set(CHANNELS) == {"cvxpy", "arx_barrier", "arx_pd", "block_barrier"}


# ---- (7.4) against the independent program -------------------------------------------------------

@pytest.mark.parametrize("l, m", SHAPES)
@pytest.mark.parametrize("seed", [0, 1])
def test_output_error_program_equals_the_cvxpy_program(l, m, seed):
    """na = nb = 0 with free rows: the program of the premise test."""
    n = 16 if l * m == 4 else 20
    u, y = _data(n, l, m, seed)
    sigma = 0.5 * float(np.sqrt(np.mean(y[3:] ** 2))) * 0.3
    ref = _cvx_arx(u, y, 0, 0, sigma, 3)
    for backend in ("cvxpy", "structured"):
        r = uf.arx_unfalsify(u, y, 0, 0, sigma, backend=backend, free_rows=3, progress=False)
        c = r.certificate
        assert r.status == "optimal" and c.verify()
        assert r.impulse.shape == (n, l, m) and r.noise.shape == (n, l) and r.theta.shape == (3, l)
        assert (r.n_outputs, r.n_inputs) == (l, m)
        # the reference lies in the certified bracket (up to the conic solver's own accuracy)
        assert c.lower_bound - 1e-6 * ref <= ref <= c.upper_bound + 1e-6 * ref
        assert c.relative_gap <= (1e-6 if backend == "structured" else 1e-4)  # tol; Clarabel's multipliers
        # the certificate's primal side, recomputed here: ‖T(h)‖₂ and the noise of the rows that count
        assert np.linalg.norm(_bt(r.impulse), 2) == pytest.approx(r.delta, rel=1e-6)
        assert np.linalg.norm(r.noise[3:]) <= sigma * np.sqrt((n - 3) * l) * (1 + 1e-6)


@pytest.mark.parametrize("l, m", [(2, 1), (2, 2)])
def test_multi_output_arx_equals_the_cvxpy_program(l, m):
    n = 16
    u, y = _data(n, l, m, 5)
    _, rms = uf.arx_least_squares(u, y, 1, 1)
    ref = _cvx_arx(u, y, 1, 1, 0.5 * rms, 0)
    for backend in ("cvxpy", "structured"):
        r = uf.arx_unfalsify(u, y, 1, 1, 0.5 * rms, backend=backend, progress=False)
        c = r.certificate
        assert r.status == "optimal" and c.verify()
        assert c.lower_bound - 1e-6 * ref <= ref <= c.upper_bound + 1e-6 * ref
        assert r.a.shape == (1, l, l) and r.b.shape == (1, l, m)


def test_least_squares_recovers_a_multi_output_arx_model():
    rng = np.random.default_rng(3)
    A1 = np.array([[-0.5, 0.1], [0.0, -0.3]])
    B1 = np.array([[1.0, 0.5], [0.2, 1.0], ])
    u = rng.standard_normal((60, 2))
    y = np.zeros((60, 2))
    for k in range(1, 60):
        y[k] = -A1 @ y[k - 1] + B1 @ u[k - 1]  # y_k + A₁y_{k−1} = B₁u_{k−1}
    theta, rms = uf.arx_least_squares(u, y, 1, 1)
    assert rms < 1e-12
    np.testing.assert_allclose(theta[:2].T, A1, atol=1e-10)  # Θ = [A₁ᵀ; B₁ᵀ]
    np.testing.assert_allclose(theta[2:].T, B1, atol=1e-10)


def test_one_channel_reproduces_siso():
    rng = np.random.default_rng(4)
    u = rng.standard_normal(30)
    y = np.convolve(u, [0.0, 1.0, 0.5])[:30] + 0.1 * rng.standard_normal(30)
    _, rms = uf.arx_least_squares(u, y, 1, 1)
    siso = uf.arx_unfalsify(u, y, 1, 1, 0.5 * rms, backend="structured", progress=False)
    col = uf.arx_unfalsify(u[:, None], y[:, None], 1, 1, 0.5 * rms, backend="structured", progress=False)
    assert col.delta == siso.delta and col.impulse.shape == (30,)  # (n, 1) data are SISO data
    # the block machinery with l = m = 1 solves the same program
    P = uf.ArxProblem.from_data(u, y, 1, 1, 0.5 * rms)
    f = P.column_form()
    Q = np.linalg.qr(P.regressor(scaled=True)[0])[0]
    block = arx_barrier.ArxBlockForm(f.U, f.B, f.rho, n_inputs=1, n_outputs=1, basis=Q)
    out_s = arx_barrier.solve_arx_barrier(f, arx_barrier.ridge_start(f, f.project(f.B)), tol=1e-8, progress=False)
    out_b = arx_barrier.solve_arx_barrier(block, arx_barrier.ridge_start(block, block.project(block.B)), tol=1e-8,
                                          progress=False)
    assert out_b["status"] == out_s["status"] == "optimal"
    assert out_b["upper"] == pytest.approx(out_s["upper"], rel=1e-7)
    assert block.lower_bound(out_s["V"], out_s["W"]) == pytest.approx(f.lower_bound(out_s["V"], out_s["W"]), rel=1e-12)


def test_refusals_name_the_fix():
    u, y = _data(20, 2, 2, 0)
    with pytest.raises(DataError, match=r"u\.T"):
        uf.arx_unfalsify(u.T, y, 0, 0, 0.1)
    with pytest.raises(DataError, match="samples"):
        uf.arx_unfalsify(u, y[:-1], 0, 0, 0.1)
    u0, y0 = u.copy(), y.copy()
    u0[0], y0[0] = 0.0, 10.0  # an output no causal Δ(q) at rest gives, beyond the whole noise budget
    with pytest.raises(DataError, match="first non-zero input"):
        uf.arx_unfalsify(u0, y0, 0, 0, 0.1)
    with pytest.raises(DataError, match="longer record"):
        uf.arx_unfalsify(u, y, 5, 5, 0.1)
    with pytest.raises(ValueError, match="form='conditioned'"):
        uf.arx_unfalsify(u, y, 0, 0, 0.1, form="thesis")
    with pytest.raises(uf.UnknownSolverError, match="method='barrier'"):
        uf.arx_unfalsify(u, y, 0, 0, 0.1, backend="structured", method="bracket")


# ---- the output-error premise test on a 2 × 2 plant ----------------------------------------------

_H = [np.zeros((2, 2)), np.array([[0.5, 0.2], [0.1, 0.4]]), np.array([[0.25, 0.0], [0.05, 0.2]])]


def _plant_record(n, noise, seed):
    rng = np.random.default_rng(seed)
    u = np.sign(rng.standard_normal((n, 2)))
    return u, _fir(u, _H) + noise * rng.standard_normal((n, 2))


@pytest.mark.filterwarnings("ignore::synthesis.PersistenceWarning")  # noise-free data: expected rank deficiency
def test_exact_model_has_zero_output_error_and_zero_delta():
    u, y = _plant_record(200, 0.0, 6)
    model = uf.predictor_model(synthesis.fit_predictor(u, y, 3, rcond=1e-12), 1.0)
    assert model.nstates == 3 * (2 + 2)
    e = uf.output_error_residual(model, u, y, 3)
    assert e.shape == (197, 2) and np.abs(e).max() < 1e-8
    r = uf.arx_unfalsify(u[3:], e, 0, 0, 1e-6, backend="structured", free_rows=3, progress=False)
    assert r.delta <= 1e-6 and r.certificate.verify()


def test_output_error_delta_small_for_the_model_and_large_for_a_wrong_one():
    u, y = _plant_record(500, 0.01, 7)
    opts = uf.PremiseOptions(samples=80)
    good = uf.predictor_model(synthesis.fit_predictor(u[:250], y[:250], 3), 1.0)
    oe = uf.output_error_unfalsify(good, u[250:], y[250:], 3, held_out=True, options=opts)
    assert oe.residual.shape == (247, 2) and oe.inputs.shape == (247, 2)
    assert 0.005 < oe.sigma < 0.02 and "pooled over the 2 outputs" in oe.sigma_rule
    assert oe.delta < 0.05 and oe.unfalsification.certificate.verify()
    assert oe.unfalsification.certificate.n_noise == 80 * 2  # ‖Ξ‖_F ≤ σ√(N·l), N = samples
    # a model with 70 % of the plant's gain: the missing 30 % is a 2 × 2 operator of H∞ norm ≈ 0.3 ‖H‖∞
    y_wrong = _fir(u, [0.7 * h for h in _H]) + 0.01 * np.random.default_rng(9).standard_normal(y.shape)
    wrong = uf.predictor_model(synthesis.fit_predictor(u[:250], y_wrong[:250], 3), 1.0)
    bad = uf.output_error_unfalsify(wrong, u[250:], y[250:], 3, held_out=False, options=opts)
    assert bad.delta > 0.15 and bad.unfalsification.certificate.verify()


def test_output_error_residual_refuses_a_model_of_other_channels():
    u, y = _plant_record(60, 0.01, 8)
    siso = uf.predictor_model(synthesis.fit_predictor(u[:, 0], y[:, 0], 3), 1.0)
    with pytest.raises(DataError, match="predictor_model of horizon 3 for 2 input"):
        uf.output_error_residual(siso, u, y, 3)
