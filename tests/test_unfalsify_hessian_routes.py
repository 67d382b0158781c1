"""The pruned FFT Hessian (issue 27, item 2) against the former route kept in ``unfalsify.solvers.baselines``:
the same Hessians to rounding, and the same solves (δ to 1e-10 relative, Newton steps, certificates)."""
import contextlib

import numpy as np
import pytest

import unfalsify as uf
from unfalsify import solvers
from unfalsify.solvers import baselines
from unfalsify.solvers.toeplitz import _HESSIAN_ROUTE, corr_hessian


@pytest.mark.parametrize("j, m", [(1, 1), (1, 2), (3, 5), (7, 20), (2, 65), (1, 130)])
def test_corr_hessian_equals_former_route(j, m):
    rng = np.random.default_rng(m + j)
    S11, S22 = (A + np.swapaxes(A, -1, -2) for A in rng.standard_normal((2, j, m, m)))
    S21 = rng.standard_normal((j, m, m))
    H = corr_hessian(S11, S21, S22, m)
    F = baselines.former_corr_hessian(S11, S21, S22, m)
    assert H.shape == (j, m, m)
    assert np.max(np.abs(H - F)) <= 1e-12 * np.max(np.abs(F))


@pytest.mark.parametrize("route", ["pruned", "former"])
@pytest.mark.parametrize("j, m", [(1, 1), (1, 2), (2, 7), (1, 64), (3, 33)])
def test_corr_hessian_cross_column_equals_the_dense_product(j, m, route):
    """``cross=True``: ``T*(S21 S11)`` read off the spectra equals the adjoint of the dense product (S11 symmetric)."""
    from unfalsify.solvers.toeplitz import adjoint

    rng = np.random.default_rng(7 * m + j)
    A = rng.standard_normal((j, m, m))
    S11, S21, S22 = A + np.swapaxes(A, -1, -2), rng.standard_normal((j, m, m)), rng.standard_normal((j, m, m))
    with baselines.former_hessian() if route == "former" else contextlib.nullcontext():
        H, x = corr_hessian(S11, S21, S22, m, cross=True)
    ref = adjoint(S21 @ S11).T
    assert x.shape == (j, m) and np.max(np.abs(x - ref)) <= 1e-12 * np.max(np.abs(ref))
    assert np.allclose(H, corr_hessian(S11, S21, S22, m), rtol=0, atol=1e-12 * np.max(np.abs(H)))


def test_former_hessian_context_restores_the_route():
    with pytest.raises(RuntimeError):
        with baselines.former_hessian():
            assert _HESSIAN_ROUTE["route"] == "former"
            raise RuntimeError
    assert _HESSIAN_ROUTE["route"] == "pruned"


def _servo(n, seed):
    rng = np.random.default_rng(seed)
    u = np.sign(rng.standard_normal(n))
    y = np.convolve(u, [0.0, 0.6, 0.25, -0.1])[:n] + 0.05 * rng.standard_normal(n)
    return u, y


def _same(run, name):
    """The front end's answer (certificate verified) and the registry solver's (δ, Newton steps), by both routes."""
    answers = {}
    for route in ("pruned", "former"):
        with baselines.former_hessian() if route == "former" else contextlib.nullcontext():
            res = run()
            out = solvers.run(name, res.certificate.problem, tol=1e-6, progress=False)
        assert res.certificate.verify()
        answers[route] = (res.delta, out.delta, out.stats["newton"])
    (d_new, s_new, n_new), (d_old, s_old, n_old) = answers["pruned"], answers["former"]
    assert abs(d_new - d_old) <= 1e-10 * abs(d_old) and abs(s_new - s_old) <= 1e-10 * abs(s_old)
    assert n_new == n_old


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_arx_solve_equals_former_route(seed):
    u, y = _servo(60 + 20 * seed, seed)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    _same(lambda: uf.arx_unfalsify(u, y, 2, 2, 0.5 * rms, backend="structured", tol=1e-6, progress=False), "arx_barrier")


def _subspace_problem(i, j, seed, fixed):
    import synthesis as sy

    u, y = _servo(2 * i + j - 1, seed)
    pred = sy.fit_predictor(u, y, i)
    A, _, Yf = uf.subspace_data(u, y, i)
    sigma = 0.5 * float(np.linalg.norm(Yf - np.hstack([pred.Lw, pred.Lu]) @ A) / np.sqrt(Yf.size))
    return uf.SubspaceProblem.from_data(u, y, i, sigma, predictor=pred if fixed else None)


@pytest.mark.parametrize("seed, fixed, i, j", [(0, False, 4, 30), (1, True, 5, 30), (2, False, 6, 30), (3, True, 36, 120)])
def test_subspace_solve_equals_former_route_to_the_certified_gap(seed, fixed, i, j):
    """``column_barrier`` today (displacement Hessian, path predictor, the Gram recursion from m = 32) against
    :func:`baselines.former_routes` (FFT Hessian, t × 5 from the centred point, the Gram by products): both
    certified to tol from the data, their brackets overlap."""
    P = _subspace_problem(i, j, 10 + seed, fixed)
    brackets = []
    for route in ("current", "former"):
        with baselines.former_routes() if route == "former" else contextlib.nullcontext():
            out = solvers.run("column_barrier", P, tol=1e-6, progress=False)
        assert out.status == "optimal"
        lo, up = P.evaluate_dual(out.dual_v, out.dual_W), P.evaluate_primal(out.impulses, out.params)[0]
        assert 0 < lo <= up and up - lo <= 1e-6 * up * (1 + 1e-6)
        brackets.append((lo, up))
    (lo_n, up_n), (lo_o, up_o) = brackets
    assert max(lo_n, lo_o) <= min(up_n, up_o) * (1 + 1e-12)


def test_subspace_front_end_certificate_by_the_former_hessian_verifies():
    """The pruned and former FFT Hessians inside ``column_barrier``'s precise route: the same solve to rounding."""
    from unfalsify.solvers import column_barrier

    P = _subspace_problem(5, 30, 11, False)
    answers = []
    for route in ("pruned", "former"):
        with baselines.former_hessian() if route == "former" else contextlib.nullcontext():
            with _precise(column_barrier):
                out = solvers.run("column_barrier", P, tol=1e-6, progress=False)
        answers.append((out.delta, out.stats["newton"]))
    (d_new, n_new), (d_old, n_old) = answers
    assert abs(d_new - d_old) <= 1e-10 * abs(d_old) and n_new == n_old


@contextlib.contextmanager
def _precise(column_barrier):
    """``column_barrier`` with the FFT Hessian at every step (its precise route)."""
    gap = column_barrier._PRECISE_GAP
    column_barrier._PRECISE_GAP = np.inf
    try:
        yield
    finally:
        column_barrier._PRECISE_GAP = gap


def test_former_routes_context_restores_both_switches():
    from unfalsify.solvers import arx_barrier

    from unfalsify.solvers import column_barrier

    with pytest.raises(RuntimeError):
        with baselines.former_routes():
            assert _HESSIAN_ROUTE["route"] == "former" and arx_barrier._STEP_ROUTE["route"] == "former"
            assert column_barrier._STEP_ROUTE["route"] == "former"
            raise RuntimeError
    assert _HESSIAN_ROUTE["route"] == "pruned" and arx_barrier._STEP_ROUTE["route"] == "blas3"
    assert column_barrier._STEP_ROUTE["route"] == "current"


def _routes(problem, tol=1e-6):
    """``arx_barrier`` on ``problem`` by today's route and by :func:`baselines.former_routes`."""
    out = {}
    for route in ("blas3", "former"):
        with baselines.former_routes() if route == "former" else contextlib.nullcontext():
            out[route] = solvers.run("arx_barrier", problem, tol=tol, progress=False)
    return out["blas3"], out["former"]


def _bracket(P, out):
    upper, _ = P.evaluate_primal(out.impulses, out.params)
    return P.evaluate_dual(out.dual_v, out.dual_W), upper


@pytest.mark.parametrize("seed, n", [(0, 40), (1, 90), (2, 250)])
def test_arx_step_equals_former_route_to_the_certified_gap(seed, n):
    """potri/trmm, the h–δ column off the spectra, the bounds near the tolerance only and the predictor in 1/t:
    both routes certified to tol from the data, their brackets overlap, so their δ agree to tol."""
    u, y = _servo(n, 20 + seed)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    P = uf.ArxProblem.from_data(u, y, 2, 2, 0.5 * rms)
    new, old = _routes(P)
    (lo_n, up_n), (lo_o, up_o) = _bracket(P, new), _bracket(P, old)
    for lo, up in ((lo_n, up_n), (lo_o, up_o)):
        assert 0 < lo <= up and up - lo <= 1e-6 * up * (1 + 1e-6)
    assert max(lo_n, lo_o) <= min(up_n, up_o) * (1 + 1e-12)
    assert abs(new.delta - old.delta) <= 1e-6 * old.delta


def test_arx_step_algebra_alone_gives_the_former_iterates(monkeypatch):
    """With the former predictor, μ and noise weight (the path unchanged), the new algebra reproduces the former
    route's Newton steps and δ: the algebra changes rounding only."""
    from unfalsify.solvers import arx_barrier

    u, y = _servo(70, 31)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    P = uf.ArxProblem.from_data(u, y, 2, 2, 0.5 * rms)
    old = _routes(P)[1]

    def former_advance(self, t, s, step, bounds, deadline):  # the linear-in-t predictor of the former route
        return self.mu * t, self._feasible_along(s, (self.mu - 1.0) * t * np.append(*step[2]), self.mu * t)

    monkeypatch.setattr(arx_barrier._ArxBarrier, "advance", former_advance)
    init = arx_barrier._ArxBarrier.__init__

    def former_weight(self, *args, **kwargs):  # the noise barrier's former weight 1
        init(self, *args, **kwargs)
        self.nbar, self.w = self.nbar - self.w + 1.0, 1.0

    monkeypatch.setattr(arx_barrier._ArxBarrier, "__init__", former_weight)
    monkeypatch.setattr(arx_barrier._ArxBarrier, "bound_due", lambda self, t, upper: True)
    monkeypatch.setattr(arx_barrier._ArxBarrier, "upper_due", lambda self, t, s: True)
    f = P.column_form(scaled=True)
    out = arx_barrier.solve_arx_barrier(f, arx_barrier.ridge_start(f, f.project(f.B)), tol=1e-6, progress=False,
                                        mu=8.0)
    assert out["newton"] == old.stats["newton"] and out["outer"] == old.stats["outer"]
    su, sy = P.scale
    assert abs(out["upper"] * sy / su - old.delta) <= 1e-9 * old.delta


@pytest.mark.parametrize("l, m", [(2, 2), (1, 2), (2, 1)])
def test_arx_step_algebra_equals_former_route_with_channels(l, m):
    rng = np.random.default_rng(10 * l + m)
    n = 50
    u = np.sign(rng.standard_normal((n, m)))
    G = rng.standard_normal((3, l, m))
    y = sum(np.roll(u, k + 1, axis=0) @ G[k].T for k in range(3)) + 0.05 * rng.standard_normal((n, l))
    _, rms = uf.arx_least_squares(u, y, 1, 2)
    P = uf.ArxProblem.from_data(u, y, 1, 2, 0.5 * rms)
    new, old = _routes(P)
    (lo_n, up_n), (lo_o, up_o) = _bracket(P, new), _bracket(P, old)
    assert max(lo_n, lo_o) <= min(up_n, up_o) * (1 + 1e-12) and 0 < lo_n
    assert abs(new.delta - old.delta) <= 1e-6 * old.delta


def test_bounds_deferred_to_the_tolerance_are_evaluated_when_a_time_limit_ends_the_solve(monkeypatch):
    """A stop far from the tolerance (before the bounds are due) still returns the last centring's certified
    bounds: the same bracket as a solve that evaluates them at every centring, verified from the data."""
    from unfalsify.solvers import arx_barrier, barrier

    centre = arx_barrier._ArxBarrier.centre
    u, y = _servo(120, 5)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    P = uf.ArxProblem.from_data(u, y, 2, 2, 0.5 * rms)
    answers = {}
    for due in (False, True):
        calls = []

        def stopped(self, t, s, deadline):
            calls.append(t)
            if len(calls) == 3:  # the third centring: a time limit, the bounds not yet due
                raise barrier.Stop("time_limit")
            return centre(self, t, s, deadline)

        monkeypatch.setattr(arx_barrier._ArxBarrier, "centre", stopped)
        monkeypatch.setattr(arx_barrier._ArxBarrier, "upper_due", lambda self, t, s, due=due: due)
        monkeypatch.setattr(arx_barrier._ArxBarrier, "bound_due", lambda self, t, upper, due=due: due)
        out = solvers.run("arx_barrier", P, tol=1e-8, progress=False)
        assert str(out.status.value) == "time_limit"
        upper, _ = P.evaluate_primal(out.impulses, out.params)
        lower = P.evaluate_dual(out.dual_v, out.dual_W)
        assert 0 < lower <= upper and abs(out.delta - upper) <= 1e-9 * upper
        answers[due] = (upper, lower)
    assert np.allclose(answers[False], answers[True], rtol=1e-9, atol=0)
