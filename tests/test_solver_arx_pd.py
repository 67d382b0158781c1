"""Solver ``"arx_pd"``: the primal–dual interior-point method for the ARX program (7.4).

Its NT-scaled Schur complement against a dense construction, its SOC scaling against the defining identities,
its answer against ``arx_barrier`` and the cvxpy model to the certified gap on random ARX problems, the
certificates, several channels, and an early stop (time limit, Ctrl-C, numerical failure) that keeps a certified
bracket."""

import numpy as np
import pytest
import scipy.signal

import unfalsify as uf
import unfalsify.solvers.arx_pd as apd
import unfalsify.solvers.barrier as barrier
from unfalsify import solvers
from unfalsify.solvers.toeplitz import toeplitz_matrix

from _quiet import quiet  # tests/ helper
from _servo_arx import servo_arx_data  # tests/ helper

try:
    from hypothesis import given, settings
    from hypothesis import strategies as st
except ImportError:  # pragma: no cover - hypothesis is a dev dependency
    given = None


def _random_arx(seed, n):
    """A random stable low-order ARX plant (poles inside 0.9), a PRBS or Gaussian input, white noise; σ a
    random fraction of the least-squares residual (δ > 0)."""
    rng = np.random.default_rng(seed)
    na, nb = int(rng.integers(1, 3)), int(rng.integers(1, 3))
    poles = 0.9 * rng.uniform(-1, 1, na)
    a = np.poly(poles)
    b = np.r_[0.0, rng.standard_normal(nb)]
    u = np.sign(rng.standard_normal(n)) if rng.random() < 0.5 else rng.standard_normal(n)
    if u[0] == 0:
        u[0] = 1.0
    e = 0.05 * rng.standard_normal(n) + 0.05 * scipy.signal.lfilter([0, 0, 0, 1.0], [1.0], u)  # unmodelled delay
    y = scipy.signal.lfilter(b, a, u) + scipy.signal.lfilter([1.0], a, e)
    _, rms = uf.arx_least_squares(u, y, na, nb)
    return u, y, na, nb, float(rng.uniform(0.3, 0.8)) * rms


# ---- the linear algebra -------------------------------------------------------------------------------
def test_nt_schur_block_is_corr_hessian_of_the_inverse_scaling():
    # tr(W⁻¹E_a W⁻¹E_b) for the NT point W of a random (S, Z) pair, built densely, against the solver's Schur
    # complement (corr_hessian of the blocks of W⁻¹) and its h–δ / δ–δ entries
    rng = np.random.default_rng(4)
    n = 7
    T = toeplitz_matrix(rng.standard_normal(n))
    S = apd._lmi(T, 1.1 * np.linalg.norm(T, 2))
    X = rng.standard_normal((2 * n, 2 * n))
    Z = X @ X.T + 0.1 * np.eye(2 * n)
    Rinv, lam, Winv = apd.nt_scaling(S, Z)
    np.testing.assert_allclose(Winv @ S @ Winv, Z, rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(Rinv @ S @ Rinv.T, np.diag(lam), atol=1e-9 * lam.max())
    np.testing.assert_allclose(np.linalg.inv(Rinv).T @ Z @ np.linalg.inv(Rinv), np.diag(lam), atol=1e-9 * lam.max())
    E = [apd._lmi(toeplitz_matrix(e), 0.0) for e in np.eye(n)] + [np.eye(2 * n)]  # ∂F/∂h_a, ∂F/∂δ
    dense = np.array([[np.trace(Winv @ Ea @ Winv @ Eb) for Eb in E] for Ea in E])
    u = rng.standard_normal(n)
    form = uf.solvers.columns.ColumnForm(u[:, None], rng.standard_normal((n, 1)), 1.0)
    method = apd._ArxPrimalDual(form, tol=1e-6, time_limit=None, progress=False)
    s, z = rng.standard_normal((2, n + 1))
    s[0], z[0] = np.linalg.norm(s[1:]) + 0.5, np.linalg.norm(z[1:]) + 0.3  # interior points of the SOC
    beta, v = apd.soc_scaling(s, z)
    H = method._schur(Winv, beta, v)
    Wq = np.column_stack([apd._soc_w(beta, v, e) for e in np.eye(n + 1)])
    Gq = np.vstack([np.zeros((1, n)), method.A])  # the SOC part of G acting on h
    soc = Gq.T @ np.linalg.inv(Wq @ Wq) @ Gq
    dense[:n, :n] += soc
    np.testing.assert_allclose(H, dense, rtol=1e-9, atol=1e-10 * np.abs(dense).max())


def test_soc_scaling_meets_its_identities():
    rng = np.random.default_rng(1)
    for _ in range(20):
        k = int(rng.integers(2, 8))
        s, z = rng.standard_normal((2, k))
        s[0] = np.linalg.norm(s[1:]) + rng.uniform(0.01, 2)
        z[0] = np.linalg.norm(z[1:]) + rng.uniform(0.01, 2)
        beta, v = apd.soc_scaling(s, z)
        W = np.column_stack([apd._soc_w(beta, v, e) for e in np.eye(k)])
        Winv = np.column_stack([apd._soc_winv(beta, v, e) for e in np.eye(k)])
        np.testing.assert_allclose(W @ Winv, np.eye(k), atol=1e-10)
        np.testing.assert_allclose(W @ z, Winv @ s, rtol=1e-9, atol=1e-12)  # λ
        lam = W @ z
        r = rng.standard_normal(k)
        np.testing.assert_allclose(apd._soc_prod(lam, apd._soc_div(lam, r)), r, atol=1e-9)
        d = rng.standard_normal(k)
        a = apd._soc_step(s, d)
        if np.isfinite(a):  # the boundary: J-norm zero there, interior just before
            x = s + a * d
            assert abs(x[0] ** 2 - x[1:] @ x[1:]) <= 1e-8 * (s @ s + a * a * (d @ d))
            y = s + 0.99 * a * d
            assert y[0] > np.linalg.norm(y[1:])


# ---- against the barrier method and cvxpy ---------------------------------------------------------------
def _check_against_references(seed, n, tol=1e-6):
    u, y, na, nb, sigma = _random_arx(seed, n)
    rp = quiet(uf.arx_unfalsify, u, y, na, nb, sigma, backend="structured", method="primal_dual", tol=tol,
                progress=False)
    rb = quiet(uf.arx_unfalsify, u, y, na, nb, sigma, backend="structured", tol=tol, progress=False)
    rc = quiet(uf.arx_unfalsify, u, y, na, nb, sigma)
    assert rp.status == "optimal" and rb.status == "optimal"
    cp_, cb = rp.certificate, rb.certificate
    assert cp_.verify() and cp_.ok() and cb.verify()
    assert cp_.relative_gap <= tol * (1 + 1e-6)
    # the two certified brackets overlap, and each contains the other's δ to the certified gap
    assert cp_.lower_bound <= cb.upper_bound * (1 + 1e-12) and cb.lower_bound <= cp_.upper_bound * (1 + 1e-12)
    assert rp.delta == pytest.approx(rb.delta, rel=2 * tol)
    assert rp.delta == pytest.approx(rc.delta, rel=max(2 * tol, 1e-5))  # Clarabel's own accuracy
    assert rp.delta == pytest.approx(cp_.upper_bound, rel=1e-12)


@pytest.mark.parametrize("seed, n", [(0, 30), (1, 45), (2, 40)])
def test_primal_dual_equals_barrier_and_cvxpy_to_the_certified_gap(seed, n):
    _check_against_references(seed, n)


if given is not None:
    @settings(max_examples=6, deadline=None, derandomize=True)
    @given(seed=st.integers(0, 10**6), n=st.integers(20, 40))
    def test_primal_dual_on_random_arx_problems(seed, n):
        _check_against_references(seed, n)


def test_registry_contract_and_stats():
    u, y = servo_arx_data(40, 0)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    P = uf.ArxProblem.from_data(u, y, 2, 2, 0.5 * rms)
    out = solvers.run("arx_pd", P, progress=False)
    assert out.status is uf.SolverStatus.OPTIMAL and out.bracketed
    assert set(out.stats) == {"newton", "outer", "factorisations"}
    assert 0 < out.stats["newton"] < 60 and out.stats["factorisations"] > out.stats["newton"]
    up, noise = P.evaluate_primal(out.impulses, out.params)
    assert noise <= P.sigma * np.sqrt(P.n_noise) * (1 + 1e-6) and up <= out.delta * (1 + 1e-6)
    assert 0 < P.evaluate_dual(out.dual_v, out.dual_W) <= up * (1 + 1e-6)


def test_zero_delta_when_sigma_covers_the_least_squares_residual():
    u, y = servo_arx_data(30, 1)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    r = uf.arx_unfalsify(u, y, 2, 2, 1.01 * rms, backend="structured", method="primal_dual", progress=False)
    assert r.status == "optimal" and r.delta == 0.0


@pytest.mark.parametrize("l, m, na, free_rows", [(2, 1, 1, 0), (1, 2, 1, 0), (2, 2, 0, 3)])
def test_several_channels_equal_the_barrier_method_and_cvxpy(l, m, na, free_rows):
    # block-Toeplitz T(h) (nl × nm), the channel operator, block_corr_hessian of W⁻¹'s blocks
    rng = np.random.default_rng(l + 2 * m)
    n = 16
    u = np.sign(rng.standard_normal((n, m)))
    H = [np.zeros((l, m)), rng.standard_normal((l, m)), 0.5 * rng.standard_normal((l, m))]
    y = sum(np.vstack([np.zeros((k, l)), u[: n - k] @ Hk.T]) for k, Hk in enumerate(H))
    y = y + 0.1 * rng.standard_normal((n, l))
    _, rms = uf.arx_least_squares(u, y, na, na)
    sigma = 0.5 * rms if na else 0.15 * float(np.sqrt(np.mean(y[free_rows:] ** 2)))
    kw = dict(free_rows=free_rows, progress=False)
    rp = quiet(uf.arx_unfalsify, u, y, na, na, sigma, backend="structured", method="primal_dual", **kw)
    rb = quiet(uf.arx_unfalsify, u, y, na, na, sigma, backend="structured", **kw)
    rc = quiet(uf.arx_unfalsify, u, y, na, na, sigma, free_rows=free_rows)
    c = rp.certificate
    assert rp.status == rb.status == "optimal" and c.verify() and c.ok() and c.relative_gap <= 1e-6
    assert rp.impulse.shape == (n, l, m) and (rp.n_outputs, rp.n_inputs) == (l, m)
    assert rp.delta == pytest.approx(rb.delta, rel=2e-6)
    assert c.lower_bound * (1 - 1e-6) <= rc.delta <= c.upper_bound * (1 + 1e-6)


def test_nt_schur_block_of_several_channels_is_the_dense_sum():
    # the (p + 1)² Schur complement for a 2 × 1 problem against tr(W⁻¹E_aW⁻¹E_b) built from block_toeplitz_matrix
    from unfalsify.solvers.toeplitz import block_toeplitz_matrix

    rng = np.random.default_rng(7)
    n, l, m = 5, 2, 1
    u = np.sign(rng.standard_normal((n, m)))
    y = rng.standard_normal((n, l))
    f = uf.ArxProblem.from_data(u, y, 0, 0, 0.1).column_form(scaled=True)
    method = apd._ArxPrimalDual(f, tol=1e-6, time_limit=None, progress=False)
    p = n * l * m
    T = block_toeplitz_matrix(rng.standard_normal((n, l, m)))
    S = apd._lmi(T, 1.1 * np.linalg.norm(T, 2))
    X = rng.standard_normal(S.shape)
    _, _, Winv = apd.nt_scaling(S, X @ X.T + 0.1 * np.eye(S.shape[0]))
    E = [apd._lmi(block_toeplitz_matrix(e.reshape(n, l, m)), 0.0) for e in np.eye(p)] + [np.eye(S.shape[0])]
    dense = np.array([[np.trace(Winv @ Ea @ Winv @ Eb) for Eb in E] for Ea in E])
    s, z = rng.standard_normal((2, n * l + 1))
    s[0], z[0] = np.linalg.norm(s[1:]) + 0.5, np.linalg.norm(z[1:]) + 0.3
    beta, v = apd.soc_scaling(s, z)
    Wq = np.column_stack([apd._soc_w(beta, v, e) for e in np.eye(n * l + 1)])
    Gq = np.vstack([np.zeros((1, p)), method.A])
    dense[:p, :p] += Gq.T @ np.linalg.inv(Wq @ Wq) @ Gq
    np.testing.assert_allclose(method._schur(Winv, beta, v), dense, rtol=1e-9, atol=1e-10 * np.abs(dense).max())


# ---- early stops keep a certified bracket -----------------------------------------------------------------
def _record_brackets(monkeypatch):
    seen = []
    orig = barrier.tick_progress

    def spy(bar, enabled, elapsed, desc, newton, best):
        seen.append((best["lower"], best["upper"]))
        return orig(bar, enabled, elapsed, desc, newton, best)

    monkeypatch.setattr(barrier, "tick_progress", spy)
    return seen


def test_time_limit_returns_a_certified_bracket_and_warns(monkeypatch, one_second_clock):
    # a fake clock (one second per reading) makes a 12 s limit expire after a few iterations, deterministically
    u, y = servo_arx_data(60, 1)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    seen = _record_brackets(monkeypatch)
    with pytest.warns(uf.SolverWarning, match="time_limit"):
        r = uf.arx_unfalsify(u, y, 2, 2, 0.5 * rms, backend="structured", method="primal_dual", tol=1e-12,
                             time_limit=12.0, progress=False)
    assert r.status == "time_limit"
    c = r.certificate
    assert c.verify() and c.ok() and 0 < c.lower_bound <= c.upper_bound
    assert c.relative_gap > 1e-12 and r.delta == pytest.approx(c.upper_bound, rel=1e-12)
    assert len(seen) >= 1


def test_ctrl_c_returns_the_best_certified_bracket(monkeypatch):
    u, y = servo_arx_data(60, 1)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    calls = [0]
    orig = apd._ArxPrimalDual.centre

    def centre(self, mu, p, deadline):
        calls[0] += 1
        if calls[0] == 6:
            raise KeyboardInterrupt
        return orig(self, mu, p, deadline)

    monkeypatch.setattr(apd._ArxPrimalDual, "centre", centre)
    with pytest.warns(uf.SolverWarning, match="interrupted"):
        r = uf.arx_unfalsify(u, y, 2, 2, 0.5 * rms, backend="structured", method="primal_dual", tol=1e-12,
                             progress=False)
    assert r.status == "interrupted" and calls[0] == 6
    c = r.certificate
    assert c.verify() and c.ok() and 0 < c.lower_bound <= c.upper_bound


def test_a_real_tiny_time_limit_stops_before_the_first_iteration_with_the_start_certified():
    # no iteration finishes: the start's impulses are the certified upper side; there is no dual point yet
    # (lower NaN, as for arx_barrier), and the front end warns
    u, y = servo_arx_data(100, 1)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    with pytest.warns(uf.SolverWarning, match="time_limit"):
        r = uf.arx_unfalsify(u, y, 2, 2, 0.5 * rms, backend="structured", method="primal_dual", time_limit=1e-9,
                             progress=False)
    c = r.certificate
    assert r.status == "time_limit" and c.verify() and c.ok()
    assert np.isfinite(c.upper_bound) and not c.lower_bound > c.upper_bound


@pytest.mark.parametrize("free_rows, frac", [(0, 0.9), (3, 0.2), (3, 0.5)])
def test_free_rows_and_tight_tolerance_against_the_barrier_method(free_rows, frac):
    # 𝓛 with whole rows (free equation errors) and tol 1e-7: the same δ as arx_barrier to the certified gaps
    u, y = servo_arx_data(60, 3)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    kw = dict(backend="structured", free_rows=free_rows, progress=False, tol=1e-7)
    rp = uf.arx_unfalsify(u, y, 2, 2, frac * rms, method="primal_dual", **kw)
    rb = uf.arx_unfalsify(u, y, 2, 2, frac * rms, **kw)
    assert rp.status == rb.status == "optimal"
    assert rp.certificate.verify() and rp.certificate.relative_gap <= 1e-7
    assert rp.delta == pytest.approx(rb.delta, rel=2e-7)


def test_a_numerical_failure_mid_solve_keeps_the_certified_bracket(monkeypatch):
    # a LinAlgError in the 5th NT scaling ends the solve with status "failed" and the best bracket so far
    u, y = servo_arx_data(60, 1)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    calls = [0]
    orig = apd._ArxPrimalDual._scaling

    def scaling(self, p):
        calls[0] += 1
        if calls[0] == 5:
            raise np.linalg.LinAlgError("injected")
        return orig(self, p)

    monkeypatch.setattr(apd._ArxPrimalDual, "_scaling", scaling)
    with pytest.warns(uf.SolverWarning, match="failed"):
        r = uf.arx_unfalsify(u, y, 2, 2, 0.5 * rms, backend="structured", method="primal_dual", tol=1e-12,
                             progress=False)
    assert r.status == "failed"
    c = r.certificate
    assert c.verify() and c.ok() and 0 < c.lower_bound <= c.upper_bound
