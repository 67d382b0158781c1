"""Chapter 7 with several inputs and outputs (issue 28): Theorem 7.1 and (7.5) for l × m operators Δ.

Every MIMO answer is checked against an independent cvxpy formulation written here from the definitions
(block Toeplitz matrices built by loops, the data relation written sample by sample), at small sizes.
"""
import warnings

import cvxpy as cp
import numpy as np
import pytest
import scipy.signal

import unfalsify as uf
from _references import SHAPES, block_toeplitz_by_loops
from synthesis import DataError
from unfalsify.solvers.toeplitz import (block_adjoint, block_conv_cols, block_conv_cols_T, block_toeplitz_matrix,
                                        block_toeplitz_norm, conv_cols, conv_cols_T, toeplitz_matrix, toeplitz_norm)



_bt = block_toeplitz_by_loops


def _cvx_bt(hs, n, l, m):
    return cp.bmat([[hs[r - c] if c <= r else np.zeros((l, m)) for c in range(n)] for r in range(n)])


def _cvx_gain(u, y):
    """min ‖T(h)‖₂ s.t. y_s = Σ_t h_t u_{s−t}: Theorem 7.1 for l × m Markov parameters, written out."""
    n, m = u.shape
    l = y.shape[1]
    hs = [cp.Variable((l, m)) for _ in range(n)]
    d = cp.Variable()
    cons = [sum(hs[t] @ u[s - t] for t in range(s + 1)) == y[s] for s in range(n)]
    T = _cvx_bt(hs, n, l, m)
    cons.append(cp.bmat([[d * np.eye(n * m), T.T], [T, d * np.eye(n * l)]]) >> 0)
    cp.Problem(cp.Minimize(d), cons).solve(solver="CLARABEL")
    return float(d.value)


# ---- the block Toeplitz toolkit --------------------------------------------------------------------

@pytest.mark.parametrize("l, m", SHAPES + [(3, 2)])
def test_block_toolkit_matches_dense_definitions(l, m):
    rng = np.random.default_rng(l + 10 * m)
    for n in (5, 70):  # 70 > 64: the FFT products
        h = rng.standard_normal((n, l, m))
        T = _bt(h)
        np.testing.assert_array_equal(block_toeplitz_matrix(h), T)
        assert block_toeplitz_norm(h, method="lanczos") == pytest.approx(np.linalg.norm(T, 2), rel=1e-9)
        assert block_toeplitz_norm(h) == pytest.approx(np.linalg.norm(T, 2), rel=1e-12)
        W = rng.standard_normal((n * l, n * m))
        assert np.sum(W * T) == pytest.approx(np.sum(block_adjoint(W, n, l, m) * h), rel=1e-10)
        j = 3
        U = rng.standard_normal((n * m, j))
        H = rng.standard_normal((n, l, m, j))
        V = rng.standard_normal((n * l, j))
        ref = np.column_stack([_bt(H[..., k]) @ U[:, k] for k in range(j)])
        np.testing.assert_allclose(block_conv_cols(U, H, m), ref, atol=1e-10)
        assert np.sum(V * ref) == pytest.approx(np.sum(block_conv_cols_T(U, V, m) * H), rel=1e-10)


def test_block_toolkit_with_one_channel_is_the_siso_toolkit():
    rng = np.random.default_rng(3)
    h = rng.standard_normal(9)
    np.testing.assert_array_equal(block_toeplitz_matrix(h[:, None, None]), toeplitz_matrix(h))
    assert block_toeplitz_norm(h) == toeplitz_norm(h)
    assert block_toeplitz_norm(h[:, None, None]) == pytest.approx(toeplitz_norm(h), rel=1e-14)
    U, H = rng.standard_normal((9, 4)), rng.standard_normal((9, 4))
    np.testing.assert_allclose(block_conv_cols(U, H[:, None, None], 1), conv_cols(U, H), atol=1e-14)
    np.testing.assert_allclose(block_conv_cols_T(U, H, 1)[:, 0, 0], conv_cols_T(U, H), atol=1e-14)


# ---- Theorem 7.1 -------------------------------------------------------------------------------------

@pytest.mark.parametrize("l, m", SHAPES)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_gain_equals_the_cvxpy_program(l, m, seed):
    rng = np.random.default_rng(seed)
    n = 6
    u = rng.standard_normal((n, m))
    y = rng.standard_normal((n, l))
    r = uf.unfalsified_gain_result(u, y, warn=False)
    assert r.gamma == pytest.approx(_cvx_gain(u, y), rel=1e-6)
    if m == 1:  # h unique: γ is the norm of its block Toeplitz matrix, and h reproduces y
        assert r.impulse.shape == (n, l, 1)
        np.testing.assert_allclose(_bt(r.impulse) @ u[:, 0], y.reshape(-1), atol=1e-10)
        assert r.gamma == pytest.approx(np.linalg.norm(_bt(r.impulse), 2), rel=1e-12)
    else:
        assert r.impulse is None and r.method == "qr"


def test_gain_with_one_channel_is_the_siso_gain():
    rng = np.random.default_rng(5)
    u = np.sign(rng.standard_normal(30))
    y = scipy.signal.lfilter([0, 0.5], [1, -0.8], u) + 0.05 * rng.standard_normal(30)
    a = uf.unfalsified_gain_result(u, y)
    b = uf.unfalsified_gain_result(u[:, None], y[:, None])
    assert a == b  # the same code path: bit for bit
    # the MIMO routes agree with SISO when handed one channel as a degenerate MIMO problem
    u2 = np.column_stack([u, np.zeros(30)])  # a second input that never moves
    assert uf.unfalsified_gain(u2, y, warn=False) == pytest.approx(a.gamma, rel=1e-8)
    y2 = np.column_stack([y, np.zeros(30)])  # a second output that stays at rest
    assert uf.unfalsified_gain(u, y2, warn=False) == pytest.approx(a.gamma, rel=1e-10)


def _plant_2x2():
    """A stable 2 × 2 discrete plant (state space) and its response to a PRBS-like input."""
    A = np.array([[0.9, 0.1, 0.0], [0.0, 0.7, 0.2], [0.0, 0.0, 0.5]])
    B = np.array([[1.0, 0.0], [0.0, 1.0], [0.5, 0.5]])
    C = np.array([[1.0, 0.0, 0.5], [0.0, 1.0, -0.3]])
    D = np.zeros((2, 2))
    return A, B, C, D


def _simulate(A, B, C, D, u):
    x = np.zeros(A.shape[0])
    y = np.empty((u.shape[0], C.shape[0]))
    for t, ut in enumerate(u):
        y[t] = C @ x + D @ ut
        x = A @ x + B @ ut
    return y


def test_gain_of_the_exact_models_residual_is_zero():
    A, B, C, D = _plant_2x2()
    u = np.sign(np.random.default_rng(0).standard_normal((60, 2)))
    y = _simulate(A, B, C, D, u)
    assert uf.unfalsified_gain(u, y - _simulate(A, B, C, D, u)) == 0.0
    g = uf.unfalsified_gain(u, y)  # the plant itself explains the data: γ at most its H∞ norm
    w = np.exp(1j * np.linspace(0, np.pi, 2000))
    peak = max(np.linalg.norm(C @ np.linalg.solve(z * np.eye(3) - A, B) + D, 2) for z in w)
    assert 0 < g <= peak * (1 + 1e-6)


@pytest.mark.parametrize("u, y, match", [
    (np.ones((2, 40)), np.ones((40, 2)), r"u\.T"),  # time along axis 1
    (np.ones((40, 2)), np.ones((2, 40)), r"y\.T"),
    (np.ones((40, 2)), np.ones((39, 2)), "samples"),
])
def test_gain_bad_shapes_name_the_fix(u, y, match):
    with pytest.raises(DataError, match=match):
        uf.unfalsified_gain(u, y)


# ---- (7.5) with l × m operators Δ_k ----------------------------------------------------------------

def _mimo_data(l, m, seed, i=3, j=24, noise=0.1):
    rng = np.random.default_rng(seed)
    n = 2 * i + j - 1
    u = np.sign(rng.standard_normal((n, m)))
    mix = rng.standard_normal((l, m))
    y = np.stack([scipy.signal.lfilter([0, 0.5, 0.3], [1, -0.6], u[:, b]) for b in range(m)], axis=1) @ mix.T
    y = y + noise * rng.standard_normal((n, l))
    A, _, Yf = uf.subspace_data(u, y, i)
    L = np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T
    sigma = 0.5 * float(np.sqrt(np.mean((Yf - L @ A) ** 2)))
    return u, y, i, sigma


def _cvx_subspace(u, y, i, sigma, L_fixed=None):
    """(7.5) for l × m operators written from the definitions: per column k, Markov parameters
    h_{k,0..i−1} (l × m variables), the data relation sample by sample, ‖T(h_k)‖₂ ≤ δ by the LMI,
    ‖Ξ‖_F ≤ σ√(ilj), L free (or fixed)."""
    n, m = u.shape
    l = y.shape[1]
    j = n - 2 * i + 1
    # block Hankel columns: block row r of column k holds sample k + r of every channel
    Uf = np.array([u[k + i:k + 2 * i].ravel() for k in range(j)]).T
    Yf = np.array([y[k + i:k + 2 * i].ravel() for k in range(j)]).T
    Up = np.array([u[k:k + i].ravel() for k in range(j)]).T
    Yp = np.array([y[k:k + i].ravel() for k in range(j)]).T
    A = np.vstack([Up, Yp, Uf])
    d = cp.Variable()
    L = cp.Variable((i * l, A.shape[0])) if L_fixed is None else L_fixed
    cols, cons = [], []
    for k in range(j):
        hs = [cp.Variable((l, m)) for _ in range(i)]
        uk = u[k + i:k + 2 * i]
        cols.append(cp.hstack([sum(hs[t] @ uk[s - t] for t in range(s + 1)) for s in range(i)]))
        T = _cvx_bt(hs, i, l, m)
        cons.append(cp.bmat([[d * np.eye(i * m), T.T], [T, d * np.eye(i * l)]]) >> 0)
    Htil = cp.vstack(cols).T  # (il, j)
    Xi = Yf - L @ A - Htil
    cons.append(cp.norm(cp.vec(Xi, order="F"), 2) <= sigma * np.sqrt(i * l * j))
    cp.Problem(cp.Minimize(d), cons).solve(solver="CLARABEL")
    return float(d.value)


@pytest.mark.parametrize("l, m", SHAPES)
@pytest.mark.parametrize("seed", [0, 1])
def test_subspace_equals_the_cvxpy_program_with_two_sided_certificate(l, m, seed):
    u, y, i, sigma = _mimo_data(l, m, seed)
    r = uf.subspace_unfalsify(u, y, i, sigma)
    ref = _cvx_subspace(u, y, i, sigma)
    assert r.status == "optimal" and r.delta > 0
    assert r.delta == pytest.approx(ref, rel=2e-5)
    c = r.certificate
    assert c.verify() and c.ok(1e-5)
    assert c.lower_bound <= ref * (1 + 1e-6) and c.relative_gap < 1e-4
    j = u.shape[0] - 2 * i + 1
    assert r.impulses.shape == (i, l, m, j) and r.noise.shape == (i * l, j)
    assert r.Lw.shape == (i * l, i * (m + l)) and r.Lu.shape == (i * l, i * m)
    assert (r.predictor.m, r.predictor.l) == (m, l)
    re = uf.subspace_unfalsify(u, y, i, sigma, eliminate_L=True)
    assert re.delta == pytest.approx(r.delta, rel=2e-5) and re.certificate.verify()
    rs = uf.subspace_unfalsify(u, y, i, sigma, backend="structured", progress=False)  # block_barrier
    cs = rs.certificate
    assert rs.status == "optimal" and rs.backend == "structured" and cs.verify() and cs.relative_gap <= 1e-6
    assert cs.lower_bound <= ref * (1 + 2e-5) and cs.upper_bound >= ref * (1 - 2e-5)
    assert rs.delta == pytest.approx(ref, rel=2e-5) and rs.impulses.shape == r.impulses.shape


@pytest.mark.parametrize("l, m", [(2, 2)])
def test_subspace_with_a_fixed_predictor_equals_the_cvxpy_program(l, m):
    import synthesis as sy

    u, y, i, sigma = _mimo_data(l, m, 5, j=30)
    pred = sy.fit_predictor(u, y, i)
    r = uf.subspace_unfalsify(u, y, i, sigma, predictor=pred)
    ref = _cvx_subspace(u, y, i, sigma, L_fixed=np.hstack([pred.Lw, pred.Lu]))
    assert r.delta == pytest.approx(ref, rel=2e-5)
    assert r.certificate.verify() and r.certificate.relative_gap < 1e-4
    np.testing.assert_array_equal(np.hstack([r.Lw, r.Lu]), np.hstack([pred.Lw, pred.Lu]))
    rs = uf.subspace_unfalsify(u, y, i, sigma, predictor=pred, backend="structured", progress=False)
    assert rs.status == "optimal" and rs.certificate.verify() and rs.certificate.relative_gap <= 1e-6
    assert rs.delta == pytest.approx(ref, rel=2e-5)


def test_subspace_with_one_channel_through_the_mimo_machinery_is_siso():
    """The block model and block dual bound at l = m = 1 give the SISO δ and the SISO bound."""
    from unfalsify import solvers
    from unfalsify.solvers import cvxpy_models
    from unfalsify.solvers.columns import BlockColumnForm

    u, y, i, sigma = _mimo_data(1, 1, 7)
    r = uf.subspace_unfalsify(u[:, 0], y[:, 0], i, sigma)
    r2 = uf.subspace_unfalsify(u, y, i, sigma)  # (n, 1) arrays: the same SISO code path
    assert r2.delta == r.delta and r2.impulses.shape == r.impulses.shape
    P = uf.SubspaceProblem.from_data(u, y, i, sigma)
    out = cvxpy_models._subspace_channels_model(P, "CLARABEL", None)
    assert out.delta == pytest.approx(r.delta, rel=1e-6)
    np.testing.assert_allclose(out.impulses[:, 0, 0], r.impulses, atol=1e-5 * np.abs(r.impulses).max())
    rb = solvers.run("block_barrier", P, progress=False)  # the structured MIMO solver on one channel
    rc = solvers.run("column_barrier", P, progress=False)
    assert rb.impulses.shape == rc.impulses.shape == r.impulses.shape
    assert rb.delta == pytest.approx(rc.delta, rel=2e-6) and rb.delta == pytest.approx(r.delta, rel=2e-6)
    c = r.certificate
    f = P.column_form(scaled=False)
    g = BlockColumnForm(f.U, f.B, f.rho, n_inputs=1, n_outputs=1, basis_right=f.Qr)
    assert g.lower_bound(c.dual_v, c.dual_G) == pytest.approx(f.lower_bound(c.dual_v, c.dual_G), rel=1e-12)


def test_subspace_noise_free_2x2_exact_model_gives_zero():
    import synthesis as sy

    A, B, C, D = _plant_2x2()
    u = np.sign(np.random.default_rng(2).standard_normal((80, 2)))
    y = _simulate(A, B, C, D, u)
    i = 4  # ≥ the plant order: the least-squares predictor is exact on noise-free data
    with pytest.warns(sy.PersistenceWarning):  # noise free: the regressor is rank deficient, as it should be
        pred = sy.fit_predictor(u, y, i)
    r = uf.subspace_unfalsify(u, y, i, 1e-6, predictor=pred)
    assert abs(r.delta) < 1e-6 and r.certificate.verify()
    r2 = uf.subspace_unfalsify(u, y, i, 1e-6)  # L optimised: the exact model is in the search
    assert abs(r2.delta) < 1e-6 and r2.certificate.verify()
    r3 = uf.subspace_unfalsify(u, y, i, 1e-6, backend="structured", progress=False)
    assert r3.delta == 0.0 and r3.status == "optimal" and r3.certificate.verify()


def test_subspace_refusals_name_the_fix():
    from unfalsify import UnknownSolverError

    from concurrent.futures import ThreadPoolExecutor

    import synthesis as sy

    u, y, i, sigma = _mimo_data(2, 2, 0)
    with ThreadPoolExecutor(1) as ex, pytest.raises(UnknownSolverError, match="backend='cvxpy'"):
        uf.subspace_unfalsify(u, y, i, sigma, predictor=sy.fit_predictor(u, y, i), executor=ex)
    with pytest.raises(ValueError, match="form='conditioned'"):
        uf.subspace_unfalsify(u, y, i, sigma, form="thesis")
    with pytest.raises(DataError, match=r"u\.T"):
        uf.subspace_unfalsify(u.T, y, i, sigma)
    with pytest.raises(DataError, match=r"y\.T"):
        uf.subspace_unfalsify(u, y.T, i, sigma)
    with pytest.raises(DataError, match="samples"):
        uf.subspace_unfalsify(u, y[:-1], i, sigma)
    with pytest.raises(DataError, match="fit_predictor"):
        uf.subspace_unfalsify(u, y, i, sigma, predictor=sy.fit_predictor(u[:, 0], y[:, 0], i))


def test_structured_time_limit_returns_certified_bracket_with_warning():
    u, y, i, sigma = _mimo_data(2, 2, 3)
    with pytest.warns(uf.SolverWarning, match="time_limit"):
        r = uf.subspace_unfalsify(u, y, i, sigma, backend="structured", time_limit=0.0, progress=False)
    assert r.status == "time_limit"
    c = r.certificate
    assert c.verify() and c.ok() and r.delta == pytest.approx(c.upper_bound)


def test_structured_newton_system_matches_the_dense_hessian():
    """One Newton step of block_barrier (L optimised: Woodbury + Sherman–Morrison + δ Schur complement)
    against the dense Hessian of f_t assembled from finite differences of its gradient."""
    from unfalsify.solvers.block_barrier import _BlockBarrier

    u, y, i, sigma = _mimo_data(2, 2, 1, i=2, j=20)
    f = uf.SubspaceProblem.from_data(u, y, i, sigma).column_form(scaled=True)
    s = _BlockBarrier(f, tol=1e-6, time_limit=None, progress=False)
    p = s.start()
    t = 3.0

    def grad(x):
        H, d = x[:-1].reshape(s.p, s.j), x[-1]
        q = s._point(H, d)
        im = s.i * s.m
        from unfalsify.solvers.block_barrier import _block_adjoint_stack

        gh = -2.0 * _block_adjoint_stack(q.S[:, im:, :im], s.i, s.l, s.m) - 2.0 * s.wn * s._apply_T(q.r) / q.psi
        return np.r_[gh.ravel(), t - np.trace(q.S, axis1=1, axis2=2).sum()]

    x0 = np.r_[p.H.ravel(), p.d]
    g0 = grad(x0)
    eps = 1e-6
    Hess = np.column_stack([(grad(x0 + eps * e) - grad(x0 - eps * e)) / (2 * eps) for e in np.eye(x0.size)])
    step = -np.linalg.solve(0.5 * (Hess + Hess.T), g0)
    dH, dlt, _ = s._newton(t, p)
    np.testing.assert_allclose(np.r_[dH.ravel(), dlt], step, rtol=1e-4, atol=1e-6 * np.abs(step).max())


def _multisine_2x2(seed, n=64):
    """Two multisine inputs (four tones each) through a random 2 × 2 FIR plant, 5 % noise."""
    r = np.random.default_rng(seed)
    t = np.arange(n)
    u = np.zeros((n, 2))
    for ch in range(2):
        for _ in range(4):
            u[:, ch] += np.sin(2 * np.pi * r.uniform(0.01, 0.45) * t + r.uniform(0, 2 * np.pi))
    y = np.zeros((n, 2))
    for a in range(2):
        for b in range(2):
            y[:, a] += np.convolve(u[:, b], r.standard_normal(3))[:n]
    return u, y + 0.05 * np.sqrt(np.mean(y**2)) * r.standard_normal((n, 2))


def test_structured_multisine_to_a_tight_tolerance_is_certified_as_cvxpy():
    # near the end of the path c·M_kᵀM_k (rank il < ilm) swamps the barrier block of a Newton system: its Cholesky
    # failed in floating point (measured: 15 of 15 such records ended 'failed' after about 50 Newton steps at
    # tol 1e-8); the factor is now retried with a rounding-level shift, as the capacitance's is
    u, y = _multisine_2x2(0)
    A, _, Yf = uf.subspace_data(u, y, 2)
    L = np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T
    sigma = 0.9 * float(np.sqrt(np.mean((Yf - L @ A) ** 2)))
    r = uf.subspace_unfalsify(u, y, 2, sigma, backend="structured", tol=1e-8, progress=False)
    assert r.status == "optimal" and r.certificate.verify() and r.certificate.relative_gap <= 1e-8
    ref = uf.subspace_unfalsify(u, y, 2, sigma).certificate
    c = r.certificate
    assert max(c.lower_bound, ref.lower_bound) <= min(c.upper_bound, ref.upper_bound) * (1 + 1e-7)


def test_primal_norms_are_exact_above_the_lanczos_size():
    """The certificate's upper side: i·max(l, m) = 420 > 400 used to switch to a Lanczos estimate."""
    from unfalsify.subspace import SubspaceProblem

    i, l, m = 210, 2, 2
    rng = np.random.default_rng(0)
    n = 2 * i + 3
    P = SubspaceProblem.from_data(rng.standard_normal((n, m)), rng.standard_normal((n, l)), i, 0.1)
    H = rng.standard_normal((i, l, m, P.Uf.shape[1])) / i
    L = np.zeros((i * l, P.A.shape[0]))
    d, _ = P.evaluate_primal(H, L)
    dense = max(np.linalg.norm(block_toeplitz_matrix(H[..., k]), 2) for k in range(H.shape[-1]))
    assert d == dense                                              # the dense SVD, bit for bit



@pytest.mark.parametrize("cc", [1e2, 1e6])
def test_block_newton_solve_equals_the_assembled_system(cc):
    # (G + c 𝓜ᵀP𝓜) X = R assembled densely from the operators, against the Woodbury route whose capacitance blocks are
    # E_k = (cI + c²M_kG_k⁻¹M_kᵀ)⁻¹ (no cancellation); c where the assembled matrix is well conditioned
    from unfalsify.solvers import block_barrier as bb
    u, y, i, sigma = _mimo_data(2, 2, 0)
    f = uf.SubspaceProblem.from_data(u, y, i, sigma).column_form(scaled=True)
    s = bb._BlockBarrier(f, tol=1e-6, time_limit=None, progress=False)
    G = bb._barrier_hessian(s.start().S, i, s.l, s.m)
    R = np.random.default_rng(1).standard_normal((s.p, s.j, 2))
    X = s._solve_lowrank(G, cc, R)
    n = s.p * s.j

    def apply(H):  # the Newton system's operator on H (p, j)
        return np.einsum("kab,bk->ak", G, H) + cc * s._apply_T(f.project(s._apply(H)))

    A = np.stack([apply(e.reshape(s.p, s.j)).ravel() for e in np.eye(n)], axis=1)
    ref = np.linalg.solve(A, R.reshape(n, 2))
    rounding = 100 * np.linalg.cond(A) * np.finfo(float).eps  # both solves are accurate to about cond(A)·eps
    assert rounding < 1e-5
    np.testing.assert_allclose(X.reshape(n, 2), ref, rtol=0, atol=rounding * np.abs(ref).max())


def test_several_channels_with_sigma_far_inside_the_residual_are_certified():
    # σ = 1e-8 × the least-squares rms: with the capacitance blocks c⁻¹I − M_kD_k⁻¹M_kᵀ (cancelling) this solve ended
    # "failed" with its best δ 5.7 times the lower bound; by (cI + c²M_kG_k⁻¹M_kᵀ)⁻¹ it is certified
    u, y, i, sigma = _mimo_data(2, 2, 0, i=4, j=40)
    res = uf.subspace_unfalsify(u, y, i, 2e-8 * sigma, backend="structured", tol=1e-4, progress=False)
    assert res.status == "optimal" and res.certificate.verify() and res.certificate.relative_gap <= 1e-4
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", uf.SolverWarning)  # Clarabel's own point leaves the noise ball here
        ref = uf.subspace_unfalsify(u, y, i, 2e-8 * sigma)
    assert abs(ref.delta - res.delta) <= 1e-4 * res.delta


def test_two_phases_of_one_prbs_are_named_as_one_input_delayed():
    """``prbs(1500, seed=0)`` and ``prbs(1500, seed=17)`` are one maximum-length sequence 13 samples apart: a 2 × 2
    record driven by them is not persistently exciting of order 2i = 16, and the refusal had said "excite more
    frequencies (white PRBS)", which they are.  It names the delay and the horizon that would do (i ≤ 6)."""
    import synthesis
    from experiments.lab.signals import prbs
    from unfalsify.robust import _persistence_reason

    u = np.c_[prbs(1500, seed=0), prbs(1500, seed=17)]
    y = np.c_[np.convolve(u[:, 0], [0.0, 0.5, 0.25])[:1500], np.convolve(u[:, 1], [0.0, 1.0])[:1500]]
    y = y + 0.01 * np.random.default_rng(0).standard_normal(y.shape)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pred = synthesis.fit_predictor(u, y, 8)
    assert pred.persistently_exciting is False
    reason = _persistence_reason(pred, u, 8, "predictor of P̂")
    assert "input 1 is input 0 delayed by 13 samples" in reason and "i ≤ 6" in reason
    assert "excite more frequencies" not in reason
    independent = np.sign(np.random.default_rng(1).standard_normal((1500, 2)))
    assert _persistence_reason(synthesis.fit_predictor(independent, y, 8), independent, 8, "predictor") == ""
    # the reference predictor (horizon 2i = 12 for i = 6) sees the same delay: the horizon proposed is the design's
    ref = _persistence_reason(synthesis.fit_predictor(u, y, 12), u, 12, "reference predictor", design=6)
    assert "delayed by 13 samples" in ref and "i ≤ 3" in ref
