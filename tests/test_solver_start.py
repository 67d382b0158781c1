"""The barrier solvers' starting point, written once in :mod:`unfalsify.solvers.start` (issue 25).

Each solver's ridge start (``arx_barrier.ridge_start``, ``_ColumnBarrier.start``, ``_BlockBarrier.start``) is
compared with a straightforward implementation written here: dense operators built by applying the column
form to unit impulses (not the solvers' own operator code), the projection onto 𝓛^⊥ as a matrix, the ridge
fit by least squares on the augmented system ``[M; √λ I] h ≈ [b; 0]`` and λ by Brent's method on the
residual.  The shared helpers are checked the same way at a fixed λ.  (That merging the three copies changed
no number of any solve, start point, δ, lower bound or Newton step count, was checked bitwise before and
after, on the problems below and more seeds; see the commit message.)
"""
import types

import numpy as np
import pytest
import scipy.optimize
import scipy.signal

import synthesis as sy
import unfalsify as uf
from unfalsify.solvers import arx_barrier, block_barrier, column_barrier
from unfalsify.solvers.columns import BlockColumnForm
from unfalsify.solvers.start import coordinates, impulses, operator_svd, ridge_fit, ridge_fit_gram


# ---- the reference ----------------------------------------------------------------------------------------
def _dense_operators(f):
    """``M_k`` (j, r, p) with ``M_k h = (column k of f.apply(H))`` for H holding h in column k."""
    if isinstance(f, BlockColumnForm):
        i, l, m, j = f.i, f.n_out, f.n_in, f.j
        p = i * l * m
        M = np.zeros((j, i * l, p))
        for a in range(p):
            E = np.zeros((p, j))
            E[a] = 1.0
            M[:, :, a] = f.apply(E.reshape(i, l, m, j)).T
        return M
    m, j = f.U.shape
    M = np.zeros((j, m, m))
    for a in range(m):
        E = np.zeros((m, j))
        E[a] = 1.0
        M[:, :, a] = f.apply(E).T
    return M


def _ridge(M, b, lam):
    """``argmin ‖b − M h‖² + λ‖h‖²`` by least squares on ``[M; √λ I] h ≈ [b; 0]``."""
    p = M.shape[1]
    A = np.vstack([M, np.sqrt(lam) * np.eye(p)])
    return np.linalg.lstsq(A, np.concatenate([b, np.zeros(p)]), rcond=None)[0]


def _reference_start(M, B0, target, P=None):
    """Ridge impulses (p, j) with one λ and ``Σ_k ‖b_k − P M_k h_k‖² = target``, λ by Brent on log₁₀ λ."""
    if P is not None:
        M = P @ M
    j = M.shape[0]

    def fit(x):
        return np.stack([_ridge(M[k], B0[:, k], 10.0**x) for k in range(j)], axis=1)

    def excess(x):
        H = fit(x)
        r = B0 - np.stack([M[k] @ H[:, k] for k in range(j)], axis=1)
        return float(np.sum(r * r)) / target - 1.0

    x = scipy.optimize.brentq(excess, -20.0, 10.0, xtol=1e-13, rtol=1e-15)
    return fit(x)


def _close(H, ref, rtol=1e-7):
    assert H.shape == ref.shape
    assert np.max(np.abs(H - ref)) <= rtol * np.max(np.abs(ref))


# ---- the problems -----------------------------------------------------------------------------------------
def _arx(seed, free_rows, channels=None):
    rng = np.random.default_rng(seed)
    n = 30
    if channels is None:
        u = rng.standard_normal(n)
        y = np.convolve(u, [0.0, 1.0, 0.5, -0.3])[:n] + 0.1 * rng.standard_normal(n)
    else:
        l, m = channels
        u = rng.standard_normal((n, m))
        y = np.stack([np.convolve(u[:, b], [0, 0.5, 0.3])[:n] for b in range(m)], 1) @ rng.standard_normal((l, m)).T
        y = y + 0.1 * rng.standard_normal((n, l))
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    P = uf.ArxProblem.from_data(u, y, 2, 2, 0.5 * float(np.sqrt(np.mean(np.square(rms)))), free_rows=free_rows)
    return P.column_form(scaled=True)


def _subspace(seed, l, m, fixed, i=4, j=30):
    rng = np.random.default_rng(seed)
    n = 2 * i + j - 1
    u = np.sign(rng.standard_normal((n, m)))
    mix = rng.standard_normal((l, m))
    y = np.stack([scipy.signal.lfilter([0, 0.5, 0.3], [1, -0.6], u[:, b]) for b in range(m)], axis=1) @ mix.T
    y = y + 0.1 * rng.standard_normal((n, l))
    A, _, Yf = uf.subspace_data(u, y, i)
    L = np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T
    sigma = 0.5 * float(np.sqrt(np.mean((Yf - L @ A) ** 2)))
    predictor = None
    if fixed and l == m == 1:
        predictor = sy.fit_predictor(u[:, 0], y[:, 0], i)
    elif fixed:
        k = i * (l + m)
        predictor = types.SimpleNamespace(Lw=L[:, :k], Lu=L[:, k:], horizon=i)
    return uf.SubspaceProblem.from_data(u, y, i, sigma, predictor=predictor).column_form(scaled=True)


# ---- the solvers' starts against the reference ------------------------------------------------------------
@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("free_rows, channels", [(0, None), (3, None), (0, (2, 2)), (2, (2, 2))])
def test_arx_ridge_start_is_the_projected_ridge_fit(seed, free_rows, channels):
    f = _arx(seed, free_rows, channels)
    B0 = f.project(f.B)
    P = np.eye(B0.shape[0]) - f.Ql @ f.Ql.T
    h = arx_barrier.ridge_start(f, B0)
    ref = _reference_start(_dense_operators(f), B0, (0.9 * f.rho) ** 2, P)[:, 0]
    _close(h, ref)
    # strictly inside the noise ball, with the intended residual (the bisection keeps the side below)
    r = B0[:, 0] - P @ f.apply(h.reshape(-1, 1) if channels is None else h.reshape(f.i, f.n_out, f.n_in, 1))[:, 0]
    assert float(r @ r) == pytest.approx((0.9 * f.rho) ** 2, rel=1e-9) and float(r @ r) < f.rho**2


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("fixed", [False, True])
def test_column_barrier_start_is_the_ridge_fit(seed, fixed):
    f = _subspace(seed, 1, 1, fixed)
    B0 = f.project(f.B)
    p = column_barrier._ColumnBarrier(f, tol=1e-8, time_limit=None, progress=False).start(B0)
    _close(p.H, _reference_start(_dense_operators(f), B0, (0.7 * f.rho) ** 2))
    assert p.psi > 0.0


def test_column_barrier_start_split_over_threads_is_bitwise_the_serial_one():
    from concurrent.futures import ThreadPoolExecutor

    f = _subspace(2, 1, 1, False)
    B0 = f.project(f.B)
    serial = column_barrier._ColumnBarrier(f, tol=1e-8, time_limit=None, progress=False).start(B0)
    with ThreadPoolExecutor(2) as pool:
        chunks = column_barrier._Chunks(pool, 2, min_size=0)
        assert len(chunks.slices(f.j, f.U.size)) == 2
        split = column_barrier._ColumnBarrier(f, tol=1e-8, time_limit=None, progress=False, chunks=chunks).start(B0)
    assert np.array_equal(serial.H, split.H)  # the SVDs per operator: the split changes no bit
    assert split.d == pytest.approx(serial.d, rel=1e-12)  # δ's norms: chunked products (rounding order)


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("fixed", [False, True])
def test_block_barrier_start_is_the_ridge_fit(seed, fixed):
    f = _subspace(seed, 2, 2, fixed, i=3, j=20)
    B0 = f.project(f.B)
    p = block_barrier._BlockBarrier(f, tol=1e-7, time_limit=None, progress=False).start()
    _close(p.H, _reference_start(_dense_operators(f), B0, (0.7 * f.rho) ** 2))
    assert p.psi > 0.0


# ---- the helpers at a fixed λ -----------------------------------------------------------------------------
@pytest.mark.parametrize("shape", [(3, 6, 6), (2, 4, 9), (1, 5, 5)])
def test_helpers_equal_least_squares_at_fixed_lambda(shape):
    rng = np.random.default_rng(7)
    j, r, p = shape
    M = rng.standard_normal(shape)
    B0 = rng.standard_normal((r, j))
    lam = np.array([1e-3, 0.1, 2.0])[:j]
    U, s, Vt = operator_svd(M)
    H = impulses(s, Vt, coordinates(U, B0), lam)
    ref = np.stack([_ridge(M[k], B0[:, k], lam[k]) for k in range(j)], axis=1)
    _close(H, ref, 1e-10)
    H1 = impulses(s, Vt, coordinates(U, B0), 0.1)  # one λ for all
    _close(H1, np.stack([_ridge(M[k], B0[:, k], 0.1) for k in range(j)], axis=1), 1e-10)
    # one operator, one column: the matrix form
    U0, s0, Vt0 = operator_svd(M[0])
    _close(impulses(s0, Vt0, coordinates(U0, B0[:, 0]), 0.1), _ridge(M[0], B0[:, 0], 0.1), 1e-10)


def test_projection_and_split_of_operator_svd():
    rng = np.random.default_rng(3)
    M = rng.standard_normal((4, 6, 6))
    Q = np.linalg.qr(rng.standard_normal((6, 2)))[0]
    U, s, Vt = operator_svd(M, basis=Q)
    P = np.eye(6) - Q @ Q.T
    for k in range(4):
        np.testing.assert_allclose((U[k] * s[k]) @ Vt[k], P @ M[k], atol=1e-12)
    halves = operator_svd(M, basis=Q, split=lambda work: [work(slice(0, 1)), work(slice(1, 4))])
    assert all(np.array_equal(a, b) for a, b in zip((U, s, Vt), halves))


def test_ridge_fit_meets_the_target_from_below():
    rng = np.random.default_rng(5)
    M = rng.standard_normal((3, 8, 8))
    B0 = rng.standard_normal((8, 3))
    target = 0.3 * float(np.sum(B0 * B0))
    H = ridge_fit(operator_svd(M), B0, target)
    r = B0 - np.einsum("kab,bk->ak", M, H)
    assert float(np.sum(r * r)) <= target * (1.0 + 1e-12)  # below, up to the rounding of r
    assert float(np.sum(r * r)) == pytest.approx(target, rel=1e-9)
    _close(H, _reference_start(M, B0, target))


# ---- the ridge fit from the Gram (no SVD) -----------------------------------------------------------------
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_ridge_fit_from_the_gram_equals_the_svd_route(seed):
    rng = np.random.default_rng(seed)
    # square with graded columns (a wide range of λ matters); b in its range, as for the ARX operator P T(u) and
    # B0 = P B (the SVD route's residual counts only the part of b in the operator's range)
    M = rng.standard_normal((25, 25)) * np.logspace(0, -4, 25)
    b = rng.standard_normal(25)
    target = 0.3 * float(b @ b)

    def residual(h):
        return float(np.sum((b - M @ h) ** 2))

    h = ridge_fit_gram(M.T @ M, M.T @ b, residual, target, rel=1e-12)
    assert residual(h) == pytest.approx(target, rel=1e-12)
    _close(h, ridge_fit(operator_svd(M), b, target), rtol=1e-6)
    assert np.all(ridge_fit_gram(M.T @ M, M.T @ b, residual, 1.01 * float(b @ b)) == 0.0)  # h = 0 is inside


def test_the_arx_start_from_the_structured_size_on_comes_from_the_gram(monkeypatch):
    from experiments.bench.bench_unfalsify import _data

    u, y = _data(arx_barrier._STRUCTURED_FROM + 20, 0)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    f = uf.ArxProblem.from_data(u, y, 2, 2, 0.5 * rms).column_form(scaled=True)
    B0 = f.project(f.B)
    P = np.eye(B0.shape[0]) - f.Ql @ f.Ql.T
    ref = _reference_start(_dense_operators(f), B0, (0.9 * f.rho) ** 2, P)[:, 0]
    monkeypatch.setattr(arx_barrier, "operator_svd", lambda *a, **k: pytest.fail("no SVD from this size on"))
    h = arx_barrier.ridge_start(f, B0)
    r = B0[:, 0] - P @ f.apply(h.reshape(-1, 1))[:, 0]
    assert float(r @ r) == pytest.approx((0.9 * f.rho) ** 2, rel=0.05) and float(r @ r) < f.rho**2
    assert np.linalg.norm(h - ref) <= 0.1 * np.linalg.norm(ref)  # a ridge fit at a nearby λ
