"""Solver ``"column_pd"``: the primal–dual interior-point method for the subspace program (7.5).

Its batched NT scaling against the one-pair scaling, its Newton direction against the linearised cone-program
equations (the Schur complement and its solve by the barrier method's block/Woodbury code), its answer against
``column_barrier`` and the cvxpy model to the certified gap on random problems (L fixed and optimised), the
certificates, the front end's ``method="primal_dual"``, threads, and an early stop (time limit, Ctrl-C, numerical
failure) that keeps a certified bracket."""

import numpy as np
import pytest

import synthesis as sy
import unfalsify as uf
import unfalsify.solvers.column_pd as cpd
from unfalsify import solvers
from unfalsify.solvers.cones import nt_scaling, nt_scaling_stack
from unfalsify.solvers.toeplitz import adjoint

from _quiet import quiet  # tests/ helper

try:
    from hypothesis import given, settings
    from hypothesis import strategies as st
except ImportError:  # pragma: no cover - hypothesis is a dev dependency
    given = None


def _random_data(seed, n):
    """A random FIR plant of order 2–5 with a ±1 or Gaussian input, white noise and an unmodelled delay term."""
    rng = np.random.default_rng(seed)
    order = int(rng.integers(2, 6))
    g = np.r_[0.0, rng.standard_normal(order) * 0.7 ** np.arange(order)]
    u = np.sign(rng.standard_normal(n)) if rng.random() < 0.5 else rng.standard_normal(n)
    u[u == 0] = 1.0
    y = np.convolve(u, g)[:n] + 0.05 * rng.standard_normal(n) + 0.05 * np.r_[np.zeros(4), u[:-4]]
    return u, y, float(rng.uniform(0.3, 0.8))


def _problem(seed, i, j, fixed):
    u, y, frac = _random_data(seed, 2 * i + j - 1)
    pred = sy.fit_predictor(u, y, i)
    A, _, Yf = uf.subspace_data(u, y, i)
    rms = float(np.linalg.norm(Yf - np.hstack([pred.Lw, pred.Lu]) @ A) / np.sqrt(Yf.size))
    return u, y, pred if fixed else None, frac * rms


# ---- the linear algebra -------------------------------------------------------------------------------------
def test_nt_scaling_stack_equals_the_one_pair_scaling():
    rng = np.random.default_rng(3)
    X, Y = rng.standard_normal((2, 5, 6, 6))
    S, Z = X @ X.transpose(0, 2, 1) + 0.1 * np.eye(6), Y @ Y.transpose(0, 2, 1) + 0.1 * np.eye(6)
    Rinv, lam, Winv = nt_scaling_stack(S, Z)
    for k in range(5):
        r1, l1, w1 = nt_scaling(S[k], Z[k])
        np.testing.assert_allclose(Winv[k], w1, rtol=1e-9, atol=1e-12 * np.abs(w1).max())
        np.testing.assert_allclose(lam[k], l1, rtol=1e-9)
        np.testing.assert_allclose(Rinv[k] @ S[k] @ Rinv[k].T, np.diag(lam[k]), atol=1e-9 * lam[k].max())
    with pytest.raises(np.linalg.LinAlgError):
        nt_scaling_stack(S, -Z)


def _an_interior_iterate(method, seed):
    """A strictly feasible primal point (the start) with a random strictly feasible-cone dual point (Z_k ≻ 0, z in
    the noise cone's interior) that does NOT satisfy the dual equalities: the residual r_x is then far from 0."""
    rng = np.random.default_rng(seed)
    p = method.start(method.f.project(method.f.B))
    m2 = 2 * method.m
    X = rng.standard_normal((method.j, m2, m2))
    p.Z = X @ X.transpose(0, 2, 1) / m2 + 0.2 * np.eye(m2)
    p.z1 = rng.standard_normal((method.m, method.j))
    p.z0 = float(np.linalg.norm(p.z1)) + 0.5
    p.Lz = None
    return p


@pytest.mark.parametrize("fixed", [True, False])
def test_newton_direction_solves_the_linearised_cone_equations(fixed):
    # the direction must satisfy G dx + ds = 0 (by construction) and Gᵀ dz = −r_x, i.e. the dual equalities after
    # a full step: −2T*(Z_k,21 + dZ_k,21) + T(u_k)ᵀ(P(z₁ + dz₁))_k = 0 and Σ_k tr(Z_k + dZ_k) = 1.  This checks the
    # Schur complement (FFT Hessian of W⁻¹, the noise cone's curvature, the δ row) and its block/Woodbury solve.
    u, y, pred, sigma = _problem(5, 4, 30, fixed)
    P = uf.SubspaceProblem.from_data(u, y, 4, sigma, predictor=pred)
    f = P.column_form(scaled=True)
    method = cpd._ColumnPrimalDual(f, tol=1e-8, time_limit=None, progress=False)
    method.cg_tol = 1e-12
    p = _an_interior_iterate(method, 1)
    sc = method._scaling(p)
    schur = method._schur(sc)
    rx = method._residual_x(p)
    rng = np.random.default_rng(2)
    tL = rng.standard_normal(p.Z.shape)
    tL = tL + tL.transpose(0, 2, 1)
    tq = rng.standard_normal(1 + f.m * f.j)
    dH, dlt, dsL, dzL, dsq, dzq, parts = method._direction(sc, schur, None, rx, tL, tq)
    np.testing.assert_allclose(dsL + dzL, tL, atol=1e-10 * np.abs(tL).max())
    m = f.m
    dZ = sc.Rinv.transpose(0, 2, 1) @ dzL @ sc.Rinv
    dz = cpd._soc_winv(sc.beta, sc.v, dzq)
    Z, z1 = p.Z + dZ, p.z1 + dz[1:].reshape(m, f.j)
    res_h = -2.0 * adjoint(Z[:, m:, :m]) + f.apply_T(f.project(z1))
    scale = np.abs(2.0 * adjoint(dZ[:, m:, :m])).max() + np.abs(rx[0]).max()
    assert np.abs(res_h).max() <= 1e-7 * scale
    assert abs(1.0 - float(np.trace(Z, axis1=1, axis2=2).sum())) <= 1e-9 * (1 + abs(rx[1]))
    # the primal slack step is F(dh_k, dδ) in the scaled space: R⁻ᵀ ds̃ R⁻¹... back to F
    Rt = np.linalg.inv(sc.Rinv)
    dS = Rt @ dsL @ Rt.transpose(0, 2, 1)
    from unfalsify.solvers.toeplitz import toeplitz_stack
    dT = toeplitz_stack(dH)
    np.testing.assert_allclose(dS[:, m:, :m], dT, atol=1e-8 * max(np.abs(dT).max(), abs(dlt)))
    np.testing.assert_allclose(np.diagonal(dS, axis1=1, axis2=2), dlt, atol=1e-8 * max(np.abs(dT).max(), abs(dlt)))
    # a second right-hand side (the corrector's) solved with the first's Woodbury parts and h–δ column: the same
    # direction as a solve from scratch
    tL2 = rng.standard_normal(p.Z.shape)
    tL2 = tL2 + tL2.transpose(0, 2, 1)
    tq2 = rng.standard_normal(1 + f.m * f.j)
    reused = method._direction(sc, schur, parts, rx, tL2, tq2)
    fresh = method._direction(sc, schur, None, rx, tL2, tq2)
    np.testing.assert_allclose(reused[0], fresh[0], rtol=1e-7, atol=1e-9 * np.abs(fresh[0]).max())
    assert reused[1] == pytest.approx(fresh[1], rel=1e-7)


# ---- against the barrier method and cvxpy ---------------------------------------------------------------
def _check_against_references(seed, i, j, fixed, tol=1e-6):
    u, y, pred, sigma = _problem(seed, i, j, fixed)
    kw = dict(predictor=pred, backend="structured", tol=tol, progress=False)
    rp = quiet(uf.subspace_unfalsify, u, y, i, sigma, method="primal_dual", **kw)
    rb = quiet(uf.subspace_unfalsify, u, y, i, sigma, **kw)
    rc = quiet(uf.subspace_unfalsify, u, y, i, sigma, predictor=pred)
    assert rp.status == "optimal" and rb.status == "optimal"
    cp_, cb = rp.certificate, rb.certificate
    assert cp_.verify() and cp_.ok() and cb.verify()
    assert cp_.relative_gap <= tol * (1 + 1e-6)
    assert cp_.lower_bound <= cb.upper_bound * (1 + 1e-12) and cb.lower_bound <= cp_.upper_bound * (1 + 1e-12)
    assert rp.delta == pytest.approx(rb.delta, rel=2 * tol)
    assert rp.delta == pytest.approx(rc.delta, rel=max(2 * tol, 1e-5))  # Clarabel's own accuracy
    assert rp.delta == pytest.approx(cp_.upper_bound, rel=1e-12)
    assert rp.solver_stats["newton"] < rb.solver_stats["newton"]  # fewer iterations than barrier Newton steps


@pytest.mark.parametrize("seed, i, j, fixed", [(0, 3, 25, True), (1, 4, 30, False), (2, 5, 40, True),
                                               (3, 4, 40, False)])
def test_primal_dual_equals_barrier_and_cvxpy_to_the_certified_gap(seed, i, j, fixed):
    _check_against_references(seed, i, j, fixed)


if given is not None:
    @settings(max_examples=6, deadline=None, derandomize=True)
    @given(seed=st.integers(0, 10**6), i=st.integers(2, 5), extra=st.integers(15, 35), fixed=st.booleans())
    def test_primal_dual_on_random_subspace_problems(seed, i, extra, fixed):
        _check_against_references(seed, i, i * 3 + extra, fixed)


def test_tight_tolerance_against_the_barrier_method():
    u, y, pred, sigma = _problem(7, 5, 50, False)
    kw = dict(backend="structured", progress=False, tol=1e-8)
    rp = quiet(uf.subspace_unfalsify, u, y, 5, sigma, method="primal_dual", **kw)
    rb = quiet(uf.subspace_unfalsify, u, y, 5, sigma, **kw)
    assert rp.status == rb.status == "optimal"
    assert rp.certificate.verify() and rp.certificate.relative_gap <= 1e-8
    assert rp.delta == pytest.approx(rb.delta, rel=2e-8)


def test_registry_contract_stats_and_threads():
    u, y, pred, sigma = _problem(4, 4, 60, False)
    P = uf.SubspaceProblem.from_data(u, y, 4, sigma)
    out = solvers.run("column_pd", P, tol=1e-7, progress=False)
    assert out.status is uf.SolverStatus.OPTIMAL and out.bracketed
    assert set(out.stats) == {"newton", "outer", "factorisations", "cg"}
    assert 0 < out.stats["newton"] < 60 and out.stats["factorisations"] > out.stats["newton"]
    up, noise = P.evaluate_primal(out.impulses, out.params)
    assert noise <= P.sigma * np.sqrt(P.n_noise) * (1 + 1e-9) and up <= out.delta * (1 + 1e-6)
    assert 0 < P.evaluate_dual(out.dual_v, out.dual_W) <= up * (1 + 1e-6)
    # two threads over the column stack: the same iterates up to the order of floating-point sums
    two = solvers.run("column_pd", P, tol=1e-7, progress=False, workers=2)
    assert two.stats["newton"] == out.stats["newton"] and two.delta == pytest.approx(out.delta, rel=1e-9)


def test_zero_delta_when_sigma_covers_the_least_squares_residual():
    u, y, pred, sigma = _problem(6, 3, 25, True)
    r = uf.subspace_unfalsify(u, y, 3, 1e3 * sigma, predictor=pred, backend="structured", method="primal_dual",
                              progress=False)
    assert r.status == "optimal" and r.delta == 0.0


def test_several_channels_are_refused_with_the_fix_named():
    rng = np.random.default_rng(0)
    u, y = np.sign(rng.standard_normal((60, 2))), rng.standard_normal((60, 2))
    with pytest.raises(uf.UnknownSolverError, match="method='barrier'"):
        uf.subspace_unfalsify(u, y, 3, 0.1, backend="structured", method="primal_dual", progress=False)


def test_a_warm_start_is_not_used_and_says_why():
    u, y, pred, sigma = _problem(8, 4, 40, True)
    first = quiet(uf.subspace_unfalsify, u[:-5], y[:-5], 4, sigma, predictor=pred, backend="structured",
                   progress=False)
    r = quiet(uf.subspace_unfalsify, u[5:], y[5:], 4, sigma, predictor=pred, backend="structured",
               method="primal_dual", progress=False, warm_start=first)
    assert r.start.startswith("cold (warm start not used") and "column_pd" in r.start
    assert r.status == "optimal" and r.certificate.verify()


# ---- early stops keep a certified bracket -----------------------------------------------------------------
def test_time_limit_returns_a_certified_bracket_and_warns(one_second_clock):
    # a fake clock (one second per reading) makes the limit expire after a few iterations, deterministically
    u, y, pred, sigma = _problem(9, 4, 40, False)
    with pytest.warns(uf.SolverWarning, match="time_limit"):
        r = uf.subspace_unfalsify(u, y, 4, sigma, backend="structured", method="primal_dual", tol=1e-12,
                                  time_limit=12.0, progress=False)
    assert r.status == "time_limit"
    c = r.certificate
    assert c.verify() and c.ok() and 0 < c.lower_bound <= c.upper_bound
    assert c.relative_gap > 1e-12 and r.delta == pytest.approx(c.upper_bound, rel=1e-12)


def test_ctrl_c_returns_the_best_certified_bracket(monkeypatch):
    u, y, pred, sigma = _problem(10, 4, 40, True)
    calls = [0]
    orig = cpd._ColumnPrimalDual.centre

    def centre(self, t, p, deadline):
        calls[0] += 1
        if calls[0] == 8:
            raise KeyboardInterrupt
        return orig(self, t, p, deadline)

    monkeypatch.setattr(cpd._ColumnPrimalDual, "centre", centre)
    with pytest.warns(uf.SolverWarning, match="interrupted"):
        r = uf.subspace_unfalsify(u, y, 4, sigma, predictor=pred, backend="structured", method="primal_dual",
                                  tol=1e-12, progress=False)
    assert r.status == "interrupted" and calls[0] == 8
    c = r.certificate
    assert c.verify() and c.ok() and 0 < c.lower_bound <= c.upper_bound


def test_a_numerical_failure_mid_solve_keeps_the_certified_bracket(monkeypatch):
    u, y, pred, sigma = _problem(11, 4, 40, False)
    calls = [0]
    orig = cpd._ColumnPrimalDual._scaling

    def scaling(self, p):
        calls[0] += 1
        if calls[0] == 8:
            raise np.linalg.LinAlgError("injected")
        return orig(self, p)

    monkeypatch.setattr(cpd._ColumnPrimalDual, "_scaling", scaling)
    with pytest.warns(uf.SolverWarning, match="failed"):
        r = uf.subspace_unfalsify(u, y, 4, sigma, backend="structured", method="primal_dual", tol=1e-12,
                                  progress=False)
    assert r.status == "failed"
    c = r.certificate
    assert c.verify() and c.ok() and 0 < c.lower_bound <= c.upper_bound


@pytest.mark.parametrize("fixed", [True, False])
def test_a_lost_delta_schur_complement_fails_the_solve_and_takes_no_step(fixed, monkeypatch):
    # the δ–δ entry forced to zero from the 4th iteration: the δ Schur complement is then negative, i.e. the h-block
    # solves have lost their digits; the method must stop there (the barrier's rule), not step along that direction
    u, y, pred, sigma = _problem(12, 4, 30, fixed)
    orig = cpd._ColumnPrimalDual._schur
    calls = [0]

    def schur(self, sc):
        calls[0] += 1
        G, col, dd, cc, alpha, g = orig(self, sc)
        return G, col, (0.0 if calls[0] >= 4 else dd), cc, alpha, g

    monkeypatch.setattr(cpd._ColumnPrimalDual, "_schur", schur)
    with pytest.warns(uf.SolverWarning, match="failed"):
        r = uf.subspace_unfalsify(u, y, 4, sigma, backend="structured", method="primal_dual", tol=1e-12,
                                  progress=False, predictor=pred)
    assert r.status == "failed" and r.solver_stats["newton"] == 3
    c = r.certificate
    assert c.verify() and 0 <= c.lower_bound <= c.upper_bound


def test_a_real_tiny_time_limit_stops_before_the_first_iteration_with_the_start_certified():
    # no iteration finishes: the start's impulses are the certified upper side, there is no dual point yet (lower 0),
    # and the front end warns
    u, y, pred, sigma = _problem(12, 4, 40, False)
    with pytest.warns(uf.SolverWarning, match="time_limit"):
        r = uf.subspace_unfalsify(u, y, 4, sigma, backend="structured", method="primal_dual", time_limit=0.0,
                                  progress=False)
    c = r.certificate
    assert r.status == "time_limit" and c.verify() and c.ok()
    assert np.isfinite(c.upper_bound) and not c.lower_bound > c.upper_bound
