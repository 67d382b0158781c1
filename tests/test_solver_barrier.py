"""The pieces of ``unfalsify.solvers.barrier`` every barrier solver shares: the δ elimination of a Newton system and
the numerical failures the outer loop turns into status ``"failed"``."""
import numpy as np
import pytest

from unfalsify.solvers.barrier import SOLVE_ERRORS, Deadline, Stop, delta_step, run_barrier


@pytest.mark.parametrize("seed", range(5))
def test_delta_step_equals_the_bordered_newton_solve(seed):
    # second route: the whole (n + 1) × (n + 1) system [H c; cᵀ d] (dh, dδ) = −(g_h, g_δ) by numpy's solve
    rng = np.random.default_rng(seed)
    n = 6
    A = rng.standard_normal((n + 1, n + 1))
    K = A @ A.T + 0.1 * np.eye(n + 1)
    g = rng.standard_normal(n + 1)
    Hh, c, dd = K[:n, :n], K[:n, n], K[n, n]
    xg, xc = np.linalg.solve(Hh, g[:n]), np.linalg.solve(Hh, c)
    dlt, schur = delta_step(dd, g[n], c @ xg, c @ xc)
    full = np.linalg.solve(K, -g)
    assert dlt == pytest.approx(full[n], rel=1e-10)
    assert schur == pytest.approx(1.0 / np.linalg.inv(K)[n, n], rel=1e-10)
    np.testing.assert_allclose(-xg - xc * dlt, full[:n], rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("dd, c_xc", [(1.0, 1.0), (1.0, 2.0), (np.nan, 0.0), (np.inf, 1.0), (5e25, 5e25)])
def test_delta_step_refuses_a_schur_complement_that_is_not_positive(dd, c_xc):
    assert delta_step(dd, 1.0, 0.5, c_xc) is None


class _Failing:
    """A method whose second centring raises ``error``: the first one gave a bracket."""

    steps, tol, progress, desc = 0, 1e-6, False, "test"

    def __init__(self, error):
        self.error = error

    def centre(self, t, point, deadline):
        self.steps += 1
        if self.steps > 1:
            raise self.error
        return point, None

    def upper(self, point):
        return 2.0

    def impulses(self, point):
        return np.zeros(1)

    def dual(self, t, point, step):
        return np.ones(1), np.ones((1, 1))

    def advance(self, t, point, step, bounds, deadline):
        return 5.0 * t, point


class _Form:
    def lower_bound(self, V, W):
        return 1.0


@pytest.mark.parametrize("error", [ZeroDivisionError("float division by zero"), OverflowError("overflow"),
                                   FloatingPointError("invalid"), np.linalg.LinAlgError("not positive definite")])
def test_a_numerical_failure_ends_the_loop_as_failed_with_the_bracket_so_far(error):
    assert isinstance(error, SOLVE_ERRORS)
    best = run_barrier(_Failing(error), _Form(), object(), 1.0, Deadline(), 3.0)
    assert best["status"] == "failed" and best["error"].startswith(type(error).__name__)
    assert (best["lower"], best["upper"]) == (1.0, 2.0)


def test_bounds_evaluated_after_a_stop_that_close_the_gap_make_it_optimal():
    # the bounds of the last centring wait until due (bound_due); a stop in the next centring evaluates them, and if
    # they close the certified gap the answer is the certified one (measured: ARX at σ = the least-squares rms, the
    # upper bound 1e-15 after the stop, reported "failed")
    class Pending(_Failing):
        def bound_due(self, t, upper):
            return False

    for error in (Stop("failed"), Stop("max_iter"), Stop("time_limit"), ZeroDivisionError("x")):
        m = Pending(error)
        m.upper = lambda point: 1.0
        best = run_barrier(m, _Form(), object(), 1.0, Deadline(), 3.0)
        assert best["status"] == "optimal" and (best["lower"], best["upper"]) == (1.0, 1.0)
    best = run_barrier(Pending(KeyboardInterrupt()), _Form(), object(), 1.0, Deadline(), 3.0)
    assert best["status"] == "interrupted"


def test_a_stop_keeps_its_own_status():
    best = run_barrier(_Failing(Stop("max_iter")), _Form(), object(), 1.0, Deadline(), 3.0)
    assert best["status"] == "max_iter" and "error" not in best


def _siso(n, seed):
    from experiments.bench.bench_unfalsify import _data

    return _data(n, seed)


@pytest.mark.parametrize("solver", ["arx_barrier", "column_barrier", "block_barrier"])
def test_every_barrier_solver_fails_on_a_lost_schur_complement(solver, monkeypatch):
    # the wiring of delta_step in each barrier solver: its refusal ends the solve as failed (warned, δ NaN), where a
    # Python float division by the cancelled Schur complement had raised ZeroDivisionError
    import importlib

    import unfalsify as uf

    monkeypatch.setattr(importlib.import_module(f"unfalsify.solvers.{solver}"), "delta_step", lambda *a: None)
    kw = dict(backend="structured", progress=False)
    with pytest.warns(uf.SolverWarning, match="failed"):
        if solver == "arx_barrier":
            u, y = _siso(450, 0)
            r = uf.arx_unfalsify(u, y, 2, 2, 0.5 * uf.arx_least_squares(u, y, 2, 2)[1], **kw)
        elif solver == "column_barrier":
            u, y = _siso(2 * 3 + 20 - 1, 1)
            r = uf.subspace_unfalsify(u, y, 3, 0.02, **kw)
        else:
            rng = np.random.default_rng(2)
            u = np.sign(rng.standard_normal((2 * 3 + 24 - 1, 2)))
            y = u @ rng.standard_normal((2, 2)) + 0.1 * rng.standard_normal(u.shape)
            r = uf.subspace_unfalsify(u, y, 3, 0.05, **kw)
    assert r.status == "failed" and np.isnan(r.delta)


@pytest.mark.parametrize("solver", ["arx_barrier", "column_barrier"])
def test_one_refused_elimination_moves_the_solve_to_the_precise_routes(solver, monkeypatch):
    # the solvers with two Hessian routes retry a refused elimination by the precise one (the FFT Hessian, dense
    # blocks) and keep it: the solve goes on and certifies
    import importlib

    import unfalsify as uf

    module = importlib.import_module(f"unfalsify.solvers.{solver}")
    calls = []

    def refuse_once(*args):
        calls.append(args)
        return None if len(calls) == 1 else delta_step(*args)

    monkeypatch.setattr(module, "delta_step", refuse_once)
    if solver == "arx_barrier":
        u, y = _siso(450, 0)
        r = uf.arx_unfalsify(u, y, 2, 2, 0.5 * uf.arx_least_squares(u, y, 2, 2)[1], backend="structured",
                             progress=False)
    else:
        from experiments.bench.bench_unfalsify import _half_ls_sigma

        u, y = _siso(2 * 24 + 120 - 1, 1)  # m = 24: the displacement Hessian, so there is a precise route to move to
        r = uf.subspace_unfalsify(u, y, 24, _half_ls_sigma(u, y, 24)[1], backend="structured", progress=False)
    assert r.status == "optimal" and r.certificate.verify() and r.delta > 0
    assert len(calls) == r.solver_stats["newton"] + 1  # the refused step was taken again, by the other route


def _far_records(seed):
    """16 samples of Gaussian input and 50 % output noise, σ = 2 % of the least-squares rms: δ about 1e6 times the
    data's scale with cond T(u) about 1e7 (the Newton system's barrier part 1e-21 of its noise part)."""
    import scipy.signal

    import unfalsify as uf

    rng = np.random.default_rng(seed)
    u = rng.standard_normal(16)
    y = scipy.signal.lfilter([0.2, 0.5], [1.0, -0.5], u)
    y = y + 0.5 * np.sqrt(np.mean(y**2)) * rng.standard_normal(16)
    return u, y, 0.02 * uf.arx_least_squares(u, y, 0, 4)[1]


def test_a_stalled_arx_barrier_stops_with_the_reason_and_the_primal_dual_method_certifies():
    # before: 3001 Newton steps in one centring (steps of 2⁻¹⁵ accepted by Armijo's rounding slack) until max_iter
    import unfalsify as uf

    u, y, sigma = _far_records(0)
    with pytest.warns(uf.SolverWarning, match="stalled.*method='primal_dual'"):
        r = uf.arx_unfalsify(u, y, 0, 4, sigma, backend="structured", progress=False)
    assert r.status == "failed" and r.solver_stats["newton"] <= 410 and "stalled" in r.solver_stats["reason"]
    assert r.certificate.verify()
    pd = uf.arx_unfalsify(u, y, 0, 4, sigma, backend="structured", method="primal_dual", progress=False)
    assert pd.status == "optimal" and pd.certificate.verify()
    assert r.certificate.lower_bound <= pd.certificate.upper_bound * (1 + 1e-9)


def test_a_stall_first_moves_to_the_precise_routes_then_stops():
    import unfalsify as uf
    from unfalsify.solvers import arx_barrier as ab

    u, y, sigma = _far_records(0)
    f = uf.ArxProblem.from_data(u, y, 0, 4, sigma).column_form()
    s = ab._ArxBarrier(f, tol=1e-6, time_limit=None, progress=False)
    for k in range(1, ab._STALL_STEPS + 1):
        s._check_stall(2.0**-30, k)  # short steps in a row
    assert s._precise and s.reason is None
    s._check_stall(1.0, 1)  # a full step resets the count
    for k in range(2, ab._STALL_STEPS + 1):
        s._check_stall(2.0**-30, k)
    assert s.reason is None
    with pytest.raises(Stop, match="failed"):
        s._check_stall(2.0**-30, ab._STALL_STEPS + 1)
    assert "cut below 1e-6" in s.reason
    t = ab._ArxBarrier(f, tol=1e-6, time_limit=None, progress=False)
    t._precise = True
    with pytest.raises(Stop, match="failed"):
        t._check_stall(1.0, ab._CENTRING_STEPS)  # one centring too long
    assert f"a centring took {ab._CENTRING_STEPS} Newton steps" in t.reason
