"""The path steps of ``arx_barrier``: the predictor, when the bounds are evaluated, and their BLAS threads."""
import numpy as np
import pytest

import unfalsify as uf
from unfalsify.solvers import arx_barrier
from unfalsify.solvers.barrier import path_predictor


def _problem(n, seed):
    from experiments.bench.bench_unfalsify import _data

    u, y = _data(n, seed)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    return u, y, 0.5 * rms


def test_the_predictor_without_a_previous_centre_is_the_tangent_linear_in_one_over_t():
    x, xdot = np.random.default_rng(0).standard_normal((2, 5))
    assert np.allclose(path_predictor(7.5, (3.0, x, xdot)), (1.0 - 3.0 / 7.5) * 3.0 * xdot, rtol=1e-14)


@pytest.mark.parametrize("mu", [2.0, 3.0, 8.0])
def test_the_predictor_is_exact_on_a_path_cubic_in_one_over_t(mu):
    c = np.random.default_rng(int(mu)).standard_normal((4, 3))

    def x(t):
        s = 1.0 / t
        return c[0] + c[1] * s + c[2] * s**2 + c[3] * s**3

    def xdot(t):  # dx/dt = −(dx/ds)/t²
        s = 1.0 / t
        return -(c[1] + 2.0 * c[2] * s + 3.0 * c[3] * s**2) / t**2

    tp, t0 = 0.7, 0.7 * mu
    step = path_predictor(t0 * mu, (t0, x(t0), xdot(t0)), (tp, x(tp), xdot(tp)))
    assert np.allclose(x(t0) + step, x(t0 * mu), rtol=1e-12, atol=1e-12)
    # the tangent alone misses the curvature
    assert not np.allclose(x(t0) + path_predictor(t0 * mu, (t0, x(t0), xdot(t0))), x(t0 * mu), rtol=1e-3)


def test_each_path_step_takes_the_prediction_with_the_lower_barrier_value(monkeypatch):
    """Both predictions are formed after the first centring, the returned point is the one with the lower
    f_{μt}, and the cubic wins at some steps (the reason for it); the solve is certified."""
    tried, chosen = [], []
    feasible_along, advance = arx_barrier._ArxBarrier._feasible_along, arx_barrier._ArxBarrier.advance

    def spy_feasible(self, s, p, t):
        out = feasible_along(self, s, p, t)
        tried[-1].append(out.phi(t))
        return out

    def spy_advance(self, t, s, *args):
        tried.append([])
        t_new, out = advance(self, t, s, *args)
        chosen.append((out.phi(t_new), s.phi(t_new)))
        return t_new, out

    monkeypatch.setattr(arx_barrier._ArxBarrier, "_feasible_along", spy_feasible)
    monkeypatch.setattr(arx_barrier._ArxBarrier, "advance", spy_advance)
    u, y, sigma = _problem(arx_barrier._STRUCTURED_FROM + 20, 3)
    r = uf.arx_unfalsify(u, y, 2, 2, sigma, backend="structured", tol=1e-5, progress=False)
    assert r.status == "optimal" and r.certificate.verify()
    assert [len(c) for c in tried] == [1] + [2] * (len(tried) - 1)
    for candidates, (phi, phi_centre) in zip(tried, chosen):
        assert phi == min(candidates + [phi_centre])
    assert sum(c[1] < c[0] for c in tried[1:]) >= 1  # the cubic taken at least once


def test_the_bounds_wait_for_the_tolerance_then_for_the_predicted_gap():
    u, y, sigma = _problem(60, 1)
    form = uf.ArxProblem.from_data(u, y, 2, 2, sigma).column_form(scaled=True)
    solver = arx_barrier._ArxBarrier(form, tol=1e-4, time_limit=None, progress=False)
    nu, factor = solver.nbar, arx_barrier._BOUND_FACTOR
    t = nu / (0.5 * factor * 1e-4)  # the path's gap ν/t within _BOUND_FACTOR·tol of δ = 1
    assert not solver.bound_due(nu / (2.0 * factor * 1e-4), 1.0)  # not yet
    assert solver.bound_due(t, 1.0)  # no bound seen yet
    solver.evaluated(t, 1.0, 1.0 - 3e-4)  # certified gap 3e-4 there
    assert not solver.bound_due(2.0 * t, 1.0)  # predicted 1.5e-4 > tol
    assert solver.bound_due(3.0 * t, 1.0)  # predicted 1e-4 ≤ tol
    assert solver.bound_due(30.0 * t, 1.0)
    solver._delta = 0.1  # the centred point's δ is the scale when the best upper bound is stale
    assert not solver.bound_due(3.0 * t, 1.0)


def test_a_solve_evaluates_the_bounds_only_where_they_are_due(monkeypatch):
    """Every centring whose dual point is formed after the first was due by the predicted gap, and with the
    first evaluation far from the tolerance (_BOUND_FACTOR raised) centrings in between skip it; certified."""
    log = []
    dual, evaluated = arx_barrier._ArxBarrier.dual, arx_barrier._ArxBarrier.evaluated
    monkeypatch.setattr(arx_barrier._ArxBarrier, "dual", lambda self, t, *a: log.append(("dual", t)) or dual(self, t, *a))
    monkeypatch.setattr(arx_barrier._ArxBarrier, "evaluated",
                        lambda self, t, up, lo: log.append(("seen", t, (up - lo) / up)) or evaluated(self, t, up, lo))
    monkeypatch.setattr(arx_barrier, "_MU", 2.0)  # several centrings near the tolerance
    monkeypatch.setattr(arx_barrier, "_BOUND_FACTOR", 100.0)
    u, y, sigma = _problem(arx_barrier._STRUCTURED_FROM + 20, 0)
    tol = 1e-4
    r = uf.arx_unfalsify(u, y, 2, 2, sigma, backend="structured", tol=tol, progress=False)
    assert r.status == "optimal" and r.certificate.verify()
    duals = [e[1] for e in log if e[0] == "dual"]
    seen = [e for e in log if e[0] == "seen"]
    assert len(duals) == len(seen) >= 1
    for (_, t_before, gap), t in zip(seen, duals[1:]):
        assert gap * t_before / t <= tol
    assert any(t > 1.5 * t_before for (_, t_before, _), t in zip(seen, duals[1:]))


def test_the_bounds_get_the_configured_blas_threads_back(monkeypatch):
    from threadpoolctl import threadpool_info, threadpool_limits

    def blas_threads():
        return max(lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas")

    newton, upper, dual = arx_barrier._ArxBarrier.newton, arx_barrier._ArxBarrier.upper, arx_barrier._ArxBarrier.dual
    u, y, sigma = _problem(60, 2)

    def threads_seen(limit):
        seen = {"step": set(), "bound": set()}
        with monkeypatch.context() as m:
            m.setattr(arx_barrier._ArxBarrier, "newton", lambda self, *a: seen["step"].add(blas_threads()) or newton(self, *a))
            m.setattr(arx_barrier._ArxBarrier, "upper", lambda self, *a: seen["bound"].add(blas_threads()) or upper(self, *a))
            m.setattr(arx_barrier._ArxBarrier, "dual", lambda self, *a: seen["bound"].add(blas_threads()) or dual(self, *a))
            with threadpool_limits(limits=limit, user_api="blas"):
                r = uf.arx_unfalsify(u, y, 2, 2, sigma, backend="structured", tol=1e-6, progress=False)
        assert r.status == "optimal"
        return seen

    assert threads_seen(2) == {"step": {1}, "bound": {2}}
    assert threads_seen(1) == {"step": {1}, "bound": {1}}  # a limit of one thread is kept in the bounds too


def test_an_indefinite_newton_system_moves_the_solve_to_the_precise_routes(monkeypatch):
    """A Newton system that the structured routes' rounding leaves indefinite is rebuilt by the precise routes,
    which serve every later step; the solve is certified (it had stopped with status "failed")."""
    routes = []
    hessian, cholesky = arx_barrier._Siso.hessian_and_column, arx_barrier.cholesky_retry

    def spy_hessian(self, *args, precise=False, generators=None):
        routes.append(precise)
        return hessian(self, *args, precise=precise, generators=generators)

    def failing_cholesky(Hm, **options):  # the sixth structured system fails, as rounding made it indefinite
        if routes.count(False) == 6 and not routes[-1]:
            raise np.linalg.LinAlgError("not positive definite")
        return cholesky(Hm, **options)

    monkeypatch.setattr(arx_barrier._Siso, "hessian_and_column", spy_hessian)
    monkeypatch.setattr(arx_barrier, "cholesky_retry", failing_cholesky)
    u, y, sigma = _problem(60, 4)
    r = uf.arx_unfalsify(u, y, 2, 2, sigma, backend="structured", tol=1e-7, progress=False)
    assert r.status == "optimal" and r.certificate.verify()
    assert routes[:7] == [False] * 6 + [True] and all(routes[6:])


def test_the_in_place_cholesky_equals_the_copying_one_and_restores_before_a_retry():
    import scipy.linalg

    from unfalsify.solvers.barrier import cholesky_retry

    rng = np.random.default_rng(0)
    X = rng.standard_normal((60, 60))
    H, b = X @ X.T + np.eye(60), rng.standard_normal(60)
    x = scipy.linalg.cho_solve(cholesky_retry(H.copy(), overwrite=True), b)
    assert np.allclose(H @ x, b, rtol=1e-12, atol=1e-10)
    # singular to rounding: the first attempt fails, the retry factorises the restored matrix plus a shift
    w, V = np.linalg.eigh(H)
    w[0] = -1e-14 * w[-1]
    A = (V * w) @ V.T
    A = 0.5 * (A + A.T)
    c, lower = cholesky_retry(A.copy(), overwrite=True)
    L = np.tril(c)
    shift = np.diag(L @ L.T - A)
    assert lower and np.allclose(L @ L.T - np.diag(shift), A, rtol=0, atol=1e-12 * w[-1])
    assert np.all(shift > 0) and np.allclose(shift, shift[0]) and shift[0] <= 1e-8 * np.abs(np.diag(A)).max() * 1.01
    with pytest.raises(np.linalg.LinAlgError):
        cholesky_retry(-H, overwrite=True)


def test_the_adjoint_row_by_row_equals_the_strided_route(monkeypatch):
    from unfalsify.solvers import toeplitz

    W = np.random.default_rng(1).standard_normal((40, 40))
    strided = toeplitz.adjoint(W)
    monkeypatch.setattr(toeplitz, "_ADJOINT_BY_ROWS", 10)
    by_rows = toeplitz.adjoint(W)
    assert np.allclose(by_rows, strided, rtol=1e-13, atol=1e-13)
    assert np.allclose(by_rows, [np.trace(W, offset=-d) for d in range(40)], rtol=1e-13, atol=1e-13)


def test_toeplitz_products_by_fft_blocks_equal_the_dense_products(monkeypatch):
    from unfalsify.solvers import toeplitz as tk

    monkeypatch.setattr(tk, "_PRODUCT_BLOCK", 7)  # several column blocks and a short last one
    rng = np.random.default_rng(3)
    h, X = rng.standard_normal(50), rng.standard_normal((50, 30))
    T = uf.toeplitz_matrix(h)
    assert np.allclose(tk.toeplitz_times(h, X), T @ X, rtol=0, atol=1e-12 * np.abs(T @ X).max())
    assert np.allclose(tk.toeplitz_times(h, X, transpose=True), T.T @ X, rtol=0, atol=1e-12 * np.abs(T.T @ X).max())


def test_the_linearised_dual_with_fft_products_equals_the_dense_one():
    from unfalsify.solvers.barrier import linearised_dual
    from unfalsify.solvers.toeplitz import toeplitz_times

    rng = np.random.default_rng(0)
    n = 60
    A = rng.standard_normal((2 * n, 2 * n))
    S = A @ A.T / n + np.eye(2 * n)
    blocks = (S[:n, :n], S[n:, :n], S[n:, n:])
    dh, r, dr = rng.standard_normal((3, n))
    v1, W1 = linearised_dual(2.0, blocks, uf.toeplitz_matrix(dh), 0.3, r, dr, 5.0, weight=3.0)
    v2, W2 = linearised_dual(2.0, blocks, lambda X, tr: toeplitz_times(dh, X, transpose=tr), 0.3, r, dr, 5.0,
                             weight=3.0)
    assert np.array_equal(v1, v2)
    assert np.allclose(W2, W1, rtol=0, atol=1e-13 * np.abs(W1).max())


def test_the_structured_route_forms_its_dual_without_the_steps_dense_toeplitz(monkeypatch):
    calls = []
    times = arx_barrier.toeplitz_times
    monkeypatch.setattr(arx_barrier, "toeplitz_times", lambda *a, **k: calls.append(1) or times(*a, **k))
    toeplitz = arx_barrier._Siso.toeplitz
    monkeypatch.setattr(arx_barrier._Siso, "toeplitz", lambda self, h: calls.append("dense") or toeplitz(self, h))
    dual = arx_barrier._ArxBarrier.dual

    def dual_only_fft(self, *a):
        before = calls.count("dense")
        out = dual(self, *a)
        assert calls.count("dense") == before  # no dense T(dh) in the dual
        return out

    monkeypatch.setattr(arx_barrier._ArxBarrier, "dual", dual_only_fft)
    u, y, sigma = _problem(arx_barrier._STRUCTURED_FROM + 20, 1)
    r = uf.arx_unfalsify(u, y, 2, 2, sigma, backend="structured", tol=1e-6, progress=False)
    assert r.status == "optimal" and r.certificate.verify() and r.certificate.relative_gap <= 1e-6
    assert calls.count(1) >= 2  # both products of each dual point
