"""Inputs with exact zeros (a quantised input passing through 0, a record starting at rest) in (7.4) and (7.5).

A column whose input starts with p zero samples leaves its first p errors to the noise, and the column form
with full-length impulses stays exact (Parrott's theorem).  Every answer is checked against an independent
cvxpy model written here from the definitions, which takes such a column as the *shorter* column it is: p
errors pinned to the noise and an operator of i − p Markov parameters on the samples after the zeros.
"""
import warnings
from concurrent.futures import ThreadPoolExecutor

import cvxpy as cp
import numpy as np
import pytest

import synthesis
import unfalsify as uf
from synthesis import DataError
from unfalsify.solvers.columns import ColumnForm


def _quantised_record(n, seed, zeros, m=1, l=1, noise=0.05):
    """A record of a stable plant driven by a quantised input with exact zero samples at ``zeros`` (on every input
    channel), a run of two among them; outputs with sensor noise."""
    rng = np.random.default_rng(seed)
    u = np.round(4.0 * rng.standard_normal((n, m))) / 4.0
    u[u == 0.0] = 0.25  # the zeros are placed, not drawn
    for z in zeros:
        u[z] = 0.0
    y = np.zeros((n, l))
    G = [0.3 * rng.standard_normal((l, m)) + 0.3, 0.5 * rng.standard_normal((l, m))]
    for t in range(n):
        y[t] = 0.6 * (y[t - 1] if t else 0.0) + sum(G[d] @ u[t - d] for d in range(2) if t - d >= 0)
    return u, y + noise * rng.standard_normal((n, l))


def _shorter_columns_delta(u, y, i, sigma, L=None):
    """(7.5) with every column taken at its own length: column k (input samples u_{i+k} … u_{2i−1+k}) with p_k
    leading zero input vectors has its first p_k error vectors in the noise and ‖T_{i−p_k}(h_k)‖₂ ≤ δ on the rest.
    L (il × i(2m + l)) fixed, or None: a variable.  Hankel rows and Toeplitz blocks by loops."""
    n, m = u.shape
    l = y.shape[1]
    j = n - 2 * i + 1
    col = lambda x, k, start: np.concatenate([x[start + k + s] for s in range(i)])  # noqa: E731
    A = np.column_stack([np.concatenate([col(u, k, 0), col(y, k, 0), col(u, k, i)]) for k in range(j)])
    Yf = np.column_stack([col(y, k, i) for k in range(j)])
    Lv = cp.Variable((i * l, A.shape[0])) if L is None else L
    d = cp.Variable()
    noise, cons = [], []
    E = Yf - Lv @ A
    for k in range(j):
        uk = [u[i + k + s] for s in range(i)]
        p = next((s for s in range(i) if np.any(uk[s] != 0.0)), i)
        ek = [E[s * l:(s + 1) * l, k] for s in range(i)]
        noise += ek[:p]
        if p == i:
            continue
        hs = [cp.Variable((l, m)) for _ in range(i - p)]
        for s in range(p, i):
            noise.append(ek[s] - sum(hs[t] @ uk[s - t] for t in range(s - p + 1)))
        T = cp.bmat([[hs[r - c] if c <= r else np.zeros((l, m)) for c in range(i - p)] for r in range(i - p)])
        cons.append(cp.bmat([[d * np.eye((i - p) * m), T.T], [T, d * np.eye((i - p) * l)]]) >> 0)
    cons.append(cp.norm(cp.hstack(noise), 2) <= sigma * np.sqrt(i * l * j))
    cp.Problem(cp.Minimize(d), cons).solve(solver="CLARABEL")
    return float(d.value)


def _solve(u, y, i, sigma, predictor, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return uf.subspace_unfalsify(u, y, i, sigma, predictor=predictor, progress=False, tol=1e-7, **kw)


ZEROS = (9, 15, 16, 24, 31)  # u[15] and u[16]: a column that starts with two zeros


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("fixed", [False, True], ids=["L optimised", "L fixed"])
def test_subspace_columns_starting_at_zero_equal_the_shorter_columns(seed, fixed):
    i = 4
    u, y = _quantised_record(44, seed, ZEROS)
    predictor = synthesis.fit_predictor(u[:, 0], y[:, 0], i) if fixed else None
    L = np.hstack([predictor.Lw, predictor.Lu]) if fixed else None
    ref = _shorter_columns_delta(u, y, i, 0.03, L)
    P = uf.SubspaceProblem.from_data(u[:, 0], y[:, 0], i, 0.03, predictor=predictor)
    assert set(P.zero_start_columns) == {z - i for z in ZEROS}
    routes = [dict(backend="cvxpy"), dict(backend="structured"), dict(backend="structured", method="primal_dual")]
    with ThreadPoolExecutor(2) as pool:
        for kw in routes + ([dict(backend="cvxpy", executor=pool)] if fixed else []):  # the split needs L fixed
            r = _solve(u[:, 0], y[:, 0], i, 0.03, predictor, **kw)
            assert r.status == "optimal", kw
            assert r.certificate.verify()
            assert r.certificate.lower_bound <= ref * (1 + 1e-6) and r.delta == pytest.approx(ref, rel=2e-5), kw


@pytest.mark.parametrize("shape", [(2, 1), (1, 2)])
def test_several_channels_columns_starting_at_zero_equal_the_shorter_columns(shape):
    l, m = shape
    i = 3
    u, y = _quantised_record(34, 2, ZEROS, m=m, l=l)
    ref = _shorter_columns_delta(u, y, i, 0.01)
    assert ref > 0.01
    for backend in ("cvxpy", "structured"):
        r = _solve(u, y, i, 0.01, None, backend=backend)
        assert r.status == "optimal" and r.certificate.verify(), backend
        assert r.delta == pytest.approx(ref, rel=2e-5), backend


def _shorter_record_arx_delta(u, y, na, nb, sigma):
    """(7.4) of a one-channel record whose input is zero up to sample p: the equation errors e_s = y_s + Σ a_k y_{s−k}
    − Σ b_k u_{s−k} before p are noise, after it e_s − ξ_s = Σ_t h_t u_{s−t} with ‖T_{n−p}(h)‖₂ ≤ δ."""
    n = u.size
    p = int(np.argmax(u != 0.0))
    a, b, d = cp.Variable(na), cp.Variable(nb), cp.Variable()
    h = cp.Variable(n - p)
    xi = []
    for s in range(n):
        e = y[s] + sum(a[k - 1] * y[s - k] for k in range(1, na + 1) if s >= k) \
            - sum(b[k - 1] * u[s - k] for k in range(1, nb + 1) if s >= k)
        xi.append(e - sum(h[t] * u[s - t] for t in range(s - p + 1)) if s >= p else e)
    T = cp.bmat([[h[r - c] if c <= r else 0.0 for c in range(n - p)] for r in range(n - p)])
    cons = [cp.norm(cp.hstack(xi), 2) <= sigma * np.sqrt(n),
            cp.bmat([[d * np.eye(n - p), T.T], [T, d * np.eye(n - p)]]) >> 0]
    cp.Problem(cp.Minimize(d), cons).solve(solver="CLARABEL")
    return float(d.value)


@pytest.mark.parametrize("seed", [0, 1])
def test_arx_record_starting_at_rest_equals_the_record_after_the_zeros(seed):
    """A record that starts before the excitation (three zero input samples, outputs of sensor noise alone)."""
    u, y = _quantised_record(36, seed, (0, 1, 2))
    u, y = u[:, 0], y[:, 0]
    ref = _shorter_record_arx_delta(u, y, 1, 2, 0.04)
    for method in ("barrier", "primal_dual"):
        for backend in ("cvxpy", "structured"):
            if backend == "cvxpy" and method != "barrier":
                continue
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                r = uf.arx_unfalsify(u, y, 1, 2, 0.04, backend=backend, method=method, tol=1e-7, progress=False)
            assert r.status == "optimal" and r.certificate.verify(), (backend, method)
            assert r.delta == pytest.approx(ref, rel=2e-5), (backend, method)


def test_noise_floor_two_routes():
    """The least noise norm with δ free: the row-by-row least squares of ``ColumnForm.noise_floor`` against one dense
    least-squares problem in vec(L) (L optimised), and the pinned entries themselves (L fixed)."""
    i = 4
    u, y = _quantised_record(44, 3, ZEROS)
    P = uf.SubspaceProblem.from_data(u[:, 0], y[:, 0], i, 1.0)
    f = P.column_form(scaled=False)
    Z = f.pinned()
    assert Z.sum() == 6 and Z[:2].any() and not Z[2:].any()  # five columns, one of them pinned twice
    floor, B0 = f.noise_floor()
    A, _, Yf = uf.subspace_data(u[:, 0], y[:, 0], i)
    rows, cols = np.nonzero(Z)
    D = np.zeros((rows.size, i * A.shape[0]))  # entry (a, k) of L A is Σ_c L[a, c] A[c, k]
    for e, (a, k) in enumerate(zip(rows, cols)):
        D[e, a * A.shape[0]:(a + 1) * A.shape[0]] = A[:, k]
    vecL = np.linalg.lstsq(D, Yf[rows, cols], rcond=None)[0]
    assert floor == pytest.approx(np.linalg.norm(Yf[rows, cols] - D @ vecL), rel=1e-8, abs=1e-10)
    assert np.linalg.norm(B0[Z]) == pytest.approx(floor, rel=1e-8, abs=1e-10)
    np.testing.assert_allclose(f.project(B0), f.project(f.B), atol=1e-10)  # B0 lies in B + 𝓛
    Lfix = np.hstack([synthesis.fit_predictor(u[:, 0], y[:, 0], i).Lw, synthesis.fit_predictor(u[:, 0], y[:, 0], i).Lu])
    g = ColumnForm(f.U, Yf - Lfix @ A, 1.0)
    assert g.noise_floor()[0] == pytest.approx(np.linalg.norm((Yf - Lfix @ A)[Z]), rel=1e-12)


def test_a_budget_below_the_floor_is_refused_with_the_sigma_that_would_do():
    """L fixed: the floor is the pinned errors' norm, so σ_min = ‖(Y_f − L A)_Z‖/√(ij) in closed form; 1 % below
    it the data are refused with that number, 5 % above it every route certifies."""
    i = 4
    u, y = _quantised_record(44, 4, ZEROS, noise=0.2)
    u, y = u[:, 0], y[:, 0]
    pred = synthesis.fit_predictor(u, y, i)
    A, Uf, Yf = uf.subspace_data(u, y, i)
    E = Yf - np.hstack([pred.Lw, pred.Lu]) @ A
    pinned = np.concatenate([E[: int(np.argmax(Uf[:, k] != 0)), k] for k in range(Uf.shape[1])])
    sigma_min = np.linalg.norm(pinned) / np.sqrt(E.size)
    with pytest.raises(DataError, match="no δ unfalsifies") as info:
        uf.SubspaceProblem.from_data(u, y, i, 0.99 * sigma_min, predictor=pred)
    assert f"{sigma_min:.4g}" in str(info.value) and "--window" in str(info.value)
    with ThreadPoolExecutor(2) as pool:
        for kw in (dict(backend="cvxpy"), dict(backend="structured"), dict(backend="structured", method="primal_dual"),
                   dict(backend="cvxpy", executor=pool)):
            r = _solve(u, y, i, 1.05 * sigma_min, pred, **kw)
            assert r.status == "optimal" and r.certificate.verify(), kw


def test_arx_budget_below_the_floor_is_refused():
    u, y = _quantised_record(36, 5, (0, 1))
    u, y = u[:, 0], y[:, 0].copy()
    y[:2] = [1.0, -1.0]  # outputs before the input moves: the noise's alone (na = 0: no regressor reaches them)
    with pytest.raises(DataError, match="first non-zero input"):
        uf.arx_unfalsify(u, y, 0, 1, 0.99 * np.sqrt(2.0 / u.size), progress=False)
    r = uf.arx_unfalsify(u, y, 0, 1, 1.05 * np.sqrt(2.0 / u.size), backend="structured", progress=False)
    assert r.status == "optimal" and r.certificate.verify()


def test_the_literal_forms_refuse_them_by_name():
    """form='thesis' recovers h by inverting T(u_k)."""
    u, y = _quantised_record(44, 0, ZEROS)
    u, y = u[:, 0], y[:, 0]
    with pytest.raises(DataError, match="form='conditioned'"):
        uf.subspace_unfalsify(u, y, 4, 0.03, form="thesis", progress=False)
    with pytest.raises(DataError, match="form='conditioned'"):
        uf.arx_unfalsify(np.r_[0.0, u[1:]], y, 1, 1, 0.03, form="thesis", progress=False)


def test_an_input_that_never_moves_is_named_not_sigma():
    # every output is noise then: the floor refusal had blamed σ and the window (and --detrend mean, already used)
    y = np.random.default_rng(0).standard_normal(120)
    with pytest.raises(DataError, match="the input is zero on every sample of the window's future inputs"):
        uf.subspace_unfalsify(np.zeros(120), y, 4, 0.1)
    with pytest.raises(DataError, match="the input is zero on every sample of the record"):
        uf.arx_unfalsify(np.zeros(40), y[:40], 1, 1, 0.1)
    u = np.zeros(120)
    u[:3] = 1.0  # moves, but only in the past rows of the first columns: U_f is still zero
    with pytest.raises(DataError, match="U_f"):
        uf.subspace_unfalsify(u, y, 4, 0.1)
