"""ARX (7.4) at large n: the Cholesky barrier route, the FFT-only bracket route, the circulant dual,
and long solves that are interrupted or run out of time (issue 15)."""
import warnings

import numpy as np
import pytest
import scipy.linalg

import unfalsify as uf
import unfalsify.solvers.arx_barrier as ab
import unfalsify.solvers.barrier as barrier
import unfalsify.solvers.bracket as br
import unfalsify.solvers.toeplitz as tk
from unfalsify.solvers.columns import CirculantDual
from unfalsify.solvers.toeplitz import toeplitz_gram

from _servo_arx import servo_arx_data  # tests/ helper
from _structured_reference import solve_structured  # tests/ helper: the SVD barrier solver


def _problem(n, seed, frac=0.5):
    u, y = servo_arx_data(n, seed)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    return u, y, frac * rms


@pytest.mark.parametrize("seed,n", [(0, 40), (3, 60)])
def test_cholesky_barrier_equals_svd_barrier(seed, n):
    # independent route: the SVD-based reference solver (tests/_structured_reference.py) on the same column form
    u, y, sigma = _problem(n, seed)
    f = uf.ArxProblem.from_data(u, y, 2, 2, sigma).column_form()
    B0 = f.project(f.B)
    new = ab.solve_arx_barrier(f, ab.ridge_start(f, B0), tol=1e-9, progress=False)
    old = solve_structured(f, B0, tol=1e-9, progress=False)
    assert new["status"] == old["status"] == "optimal"
    assert new["upper"] == pytest.approx(old["upper"], rel=1e-7)
    assert new["lower"] <= old["upper"] * (1 + 1e-12) and old["lower"] <= new["upper"] * (1 + 1e-12)


def test_circulant_dual_bound_equals_the_dense_circulant_block():
    # the O(N log N) bound of a CirculantDual against the dense-W route on the same matrix
    u, y, sigma = _problem(24, 1)
    f = uf.ArxProblem.from_data(u, y, 2, 2, sigma).column_form()
    m = f.m
    rng = np.random.default_rng(0)
    v = f.project(f.B)[:, 0] + 0.1 * rng.standard_normal(m)  # ⟨v, B⟩ − ρ‖v‖ > 0: a non-trivial bound
    for N, tail in ((m, 0), (2 * m, m), (3 * m, 5)):
        # the column that needs no repair (T*(W) = T(u)ᵀv already), so both routes bound the same matrix
        W = br.circulant_dual(f, v, N, tail=rng.standard_normal(tail))
        col = W.column
        C = scipy.linalg.circulant(np.r_[col, np.zeros(N - col.size)])[:m, :m]
        assert np.allclose(tk.adjoint(C), f.apply_T(f.project(v[:, None]))[:, 0])
        lo_c = f.lower_bound(v, W)
        lo_d = f.lower_bound(v, C)
        assert lo_c > 0
        if N == m:  # the block is the circulant: same nuclear norm after the same repair
            assert lo_c == pytest.approx(lo_d, rel=1e-10)
        else:  # a compression: its nuclear norm is smaller, its bound larger
            assert lo_c <= lo_d * (1 + 1e-12)
    assert np.isnan(f.lower_bound(v, CirculantDual(column=np.ones(m - 1), size=m)))  # too short: no bound


@pytest.mark.parametrize("seed,n,frac", [(0, 30, 0.5), (2, 40, 0.7)])
def test_bracket_contains_the_clarabel_optimum(seed, n, frac):
    u, y, sigma = _problem(n, seed, frac)
    rc = uf.arx_unfalsify(u, y, 2, 2, sigma)
    with pytest.warns(uf.SolverWarning, match="bracket"):
        rb = uf.arx_unfalsify(u, y, 2, 2, sigma, backend="structured", method="bracket", progress=False)
    c = rb.certificate
    assert rb.status == "bracket" and c.verify() and c.ok()
    assert isinstance(c.dual_G, CirculantDual)
    assert 0.0 < c.lower_bound <= rc.delta * (1 + 1e-6)
    assert rc.delta <= c.upper_bound * (1 + 1e-6)
    assert rb.delta == pytest.approx(c.upper_bound, rel=1e-12)
    assert c.relative_gap < 0.9  # a bracket, not a trivial one


def test_bad_method_raises():
    u, y, sigma = _problem(20, 0)
    with pytest.raises(ValueError, match="'barrier', 'bracket'"):
        uf.arx_unfalsify(u, y, 2, 2, sigma, backend="structured", method="admm")
    with pytest.raises(ValueError, match="structured"):
        uf.arx_unfalsify(u, y, 2, 2, sigma, method="bracket")


def _record_brackets(monkeypatch):
    """Record (lower, upper) after every outer iteration of the barrier loop."""
    seen = []
    orig = barrier.tick_progress

    def spy(bar, enabled, elapsed, desc, newton, best):
        seen.append((best["lower"], best["upper"]))
        return orig(bar, enabled, elapsed, desc, newton, best)

    monkeypatch.setattr(barrier, "tick_progress", spy)
    return seen


def test_ctrl_c_returns_the_best_certified_bracket(monkeypatch):
    # KeyboardInterrupt raised inside the loop (in the 25th Newton step) ends the solve with the bracket so far
    u, y, sigma = _problem(60, 1)
    seen = _record_brackets(monkeypatch)
    calls = [0]
    orig = ab._ArxBarrier.newton

    def newton(self, t, s):
        calls[0] += 1
        if calls[0] == 25:
            raise KeyboardInterrupt
        return orig(self, t, s)

    monkeypatch.setattr(ab._ArxBarrier, "newton", newton)
    with pytest.warns(uf.SolverWarning, match="interrupted"):
        r = uf.arx_unfalsify(u, y, 2, 2, sigma, backend="structured", tol=1e-9, progress=False)
    assert r.status == "interrupted" and calls[0] == 25
    c = r.certificate
    assert c.verify() and c.ok() and r.delta == pytest.approx(c.upper_bound, rel=1e-12)
    assert len(seen) >= 1  # at least one outer iteration had finished
    lo, up = seen[-1]
    # that bracket or a better one: bounds not yet due at the last centring are evaluated when the solve ends
    assert c.relative_gap <= (up - lo) / up * (1 + 1e-6)
    assert 0 < c.lower_bound <= c.upper_bound <= up


def test_time_limit_mid_solve_returns_the_best_certified_bracket(monkeypatch, one_second_clock):
    # a fake clock (one second per reading) makes the limit expire mid-solve, deterministically
    u, y, sigma = _problem(60, 1)
    seen = _record_brackets(monkeypatch)
    with pytest.warns(uf.SolverWarning, match="time_limit"):
        r = uf.arx_unfalsify(u, y, 2, 2, sigma, backend="structured", tol=1e-12, time_limit=30.0, progress=False)
    assert r.status == "time_limit"
    c = r.certificate
    assert c.verify() and c.ok()
    lo, up = seen[-1]
    assert c.lower_bound > 0 and c.relative_gap <= (up - lo) / up * (1 + 1e-6)  # that bracket or a better one


def test_time_limit_before_the_first_centring_keeps_the_trivial_lower_bound(monkeypatch):
    """A limit that expires before the first dual point: the bracket is [0, ‖T(h0)‖₂], not [NaN, …]."""
    u, y, sigma = _problem(60, 1)

    def expired(self, t, s, deadline):
        raise barrier.Stop("time_limit")

    monkeypatch.setattr(ab._ArxBarrier, "centre", expired)
    with pytest.warns(uf.SolverWarning, match="time_limit.*relative gap 1"):
        r = uf.arx_unfalsify(u, y, 2, 2, sigma, backend="structured", tol=1e-6, time_limit=1.0, progress=False)
    c = r.certificate
    assert r.status == "time_limit" and c.dual_v is None
    assert c.lower_bound == 0.0 and np.isfinite(c.upper_bound) and c.relative_gap == 1.0 and c.verify()


@pytest.mark.parametrize("where", ["lower", "upper"])
def test_bracket_interrupted_keeps_the_work(monkeypatch, where):
    # Ctrl-C in the dual search keeps the upper side and the unoptimised circulant bound; Ctrl-C in the
    # 3rd reweighted fit of the upper side keeps the best earlier iterate
    u, y, sigma = _problem(30, 0)
    if where == "lower":
        def boom(*a, **k):
            raise KeyboardInterrupt

        monkeypatch.setattr(br, "lower_point", boom)
    else:
        calls = [0]
        orig = br._ridge_fit

        def fit(*a, **k):
            calls[0] += 1
            if calls[0] == 3:
                raise KeyboardInterrupt
            return orig(*a, **k)

        monkeypatch.setattr(br, "_ridge_fit", fit)
    with pytest.warns(uf.SolverWarning, match="interrupted"):
        r = uf.arx_unfalsify(u, y, 2, 2, sigma, backend="structured", method="bracket", progress=False)
    assert r.status == "interrupted" and np.isfinite(r.delta)
    c = r.certificate
    assert c.ok() and c.verify() and 0 < c.lower_bound <= c.upper_bound
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rc = uf.arx_unfalsify(u, y, 2, 2, sigma)
    assert c.lower_bound <= rc.delta * (1 + 1e-6) and rc.delta <= c.upper_bound * (1 + 1e-6)


def test_gram_in_quadratic_time_equals_the_matrix_product():
    for n in (1, 2, 7, 300):
        h = np.random.default_rng(n).standard_normal(n)
        T = uf.toeplitz_matrix(h)
        assert np.allclose(toeplitz_gram(h), T.T @ T, rtol=0, atol=1e-12 * max(1.0, float(h @ h)))


def test_certified_norm_routes():
    from unfalsify.solvers.toeplitz import certified_norm, symbol_bound

    rng = np.random.default_rng(4)
    for n in (5, 60, 500):
        h = rng.standard_normal(n) * 0.9 ** np.arange(n)
        dense = float(np.linalg.norm(uf.toeplitz_matrix(h), 2))
        assert certified_norm(h) == pytest.approx(dense, rel=1e-12)
        # the symbol bound is an upper bound on ‖T_n(h)‖ and on the peak of |ĥ| on a 16× finer grid
        sb = symbol_bound(h)
        fine = float(np.abs(np.fft.rfft(h, 1024 * 2 ** int(np.ceil(np.log2(n))))).max())
        assert dense <= sb and fine <= sb * (1 + 1e-12)
        assert sb <= fine * 1.06  # and not loose: the Bernstein factor at M = 64n is ≤ 1/(1 − π/64)
    assert certified_norm(np.r_[1.0, np.nan]) == np.inf


def test_certified_norm_falls_back_to_the_symbol_bound_when_lanczos_fails(monkeypatch):
    import unfalsify.solvers.toeplitz as arx
    from scipy.sparse.linalg import ArpackNoConvergence

    def no_convergence(h, method="auto", tol=1e-12):
        raise ArpackNoConvergence("no convergence", [], [])

    h = np.random.default_rng(1).standard_normal(50)
    monkeypatch.setattr(arx, "DENSE_NORM_LIMIT", 10)
    monkeypatch.setattr(arx, "toeplitz_norm", no_convergence)
    assert arx.certified_norm(h) == arx.symbol_bound(h) >= np.linalg.norm(uf.toeplitz_matrix(h), 2)


def test_certified_norm_above_the_dense_limit_is_proven_never_a_bare_lanczos_value(monkeypatch):
    """Above the dense limit the Lanczos value is returned only once a Cholesky proves it."""
    import unfalsify.solvers.toeplitz as arx

    monkeypatch.setattr(arx, "DENSE_NORM_LIMIT", 10)
    rng = np.random.default_rng(7)
    h = rng.standard_normal(300) * 0.97 ** np.arange(300)
    true = float(np.linalg.norm(uf.toeplitz_matrix(h), 2))
    c = arx.certified_norm(h)
    assert true <= c <= true * (1 + 2e-6)  # proven Lanczos route, tighter than the symbol bound
    assert c < arx.symbol_bound(h)
    # a Lanczos value that is too small is refused by the Cholesky test: the symbol bound is returned
    monkeypatch.setattr(arx, "toeplitz_norm", lambda h, method="auto", tol=1e-12: 0.9 * true)
    assert arx.certified_norm(h) == arx.symbol_bound(h) >= true


@pytest.fixture(scope="module")
def clustered_impulses():
    """Impulses at the optimum of (7.4) (n = 300, certified to 1e-8): their top singular values cluster at δ
    (relative spacing 1e-9 to 1e-8), where Lanczos on TᵀT does not converge."""
    u, y, sigma = _problem(300, 0)
    r = uf.arx_unfalsify(u, y, 2, 2, sigma, backend="structured", tol=1e-8, progress=False)
    h = np.asarray(r.certificate.impulses, float).reshape(-1)
    sv = np.linalg.svd(uf.toeplitz_matrix(h), compute_uv=False)
    assert (sv[0] - sv[3]) / sv[0] < 1e-6  # the case the route is for
    return h, float(sv[0]), r.delta


def test_shift_invert_norm_is_proven_and_tight_on_a_clustered_spectrum(clustered_impulses):
    # second route: LAPACK's dense SVD; the result is never below it and within the proof's margin above it
    h, exact, delta = clustered_impulses
    for near in (delta, exact * (1 + 1e-4), exact * (1 + 1e-2), exact * (1 - 1e-3)):
        c = tk.norm_by_shift_invert(h, near)
        assert exact <= c <= exact * (1 + 1e-8), near / exact - 1
    assert tk.norm_by_shift_invert(h, 0.5 * float(np.linalg.norm(h))) is None  # no shift is above the norm


def test_shift_invert_norm_refuses_a_low_estimate(clustered_impulses, monkeypatch):
    # a Lanczos value far too small (or none) is never returned: the proof climbs to a bound it can prove
    h, exact, _ = clustered_impulses
    monkeypatch.setattr(tk, "_largest_inverse_eigenvalue", lambda L, tol: 1e-30)  # estimate ‖h‖ < ‖T‖
    assert exact <= tk.norm_by_shift_invert(h, exact * (1 + 1e-3)) <= exact * (1 + 1e-3)
    monkeypatch.setattr(tk, "_largest_inverse_eigenvalue", lambda L, tol: float("nan"))  # ARPACK failed
    assert tk.norm_by_shift_invert(h, exact * (1 + 1e-3)) == exact * (1 + 1e-3)


def test_certified_norm_with_a_near_value_uses_the_shift_not_lanczos_on_the_gram(clustered_impulses, monkeypatch):
    h, exact, delta = clustered_impulses
    monkeypatch.setattr(tk, "DENSE_NORM_LIMIT", 10)

    def no_plain_lanczos(*a, **k):
        raise AssertionError("Lanczos on TᵀT was called")

    monkeypatch.setattr(tk, "toeplitz_norm", no_plain_lanczos)
    assert exact <= tk.certified_norm(h, delta) <= exact * (1 + 1e-8)
    with pytest.raises(AssertionError, match="Lanczos on TᵀT"):  # a hint above the symbol bound is no help
        tk.certified_norm(h, 1e6 * exact)


def test_certified_norm_without_a_near_value_shifts_from_a_rough_lanczos_value(clustered_impulses, monkeypatch):
    # a caller with no δ at hand (evaluate_primal from a script, the bracket route): Lanczos on TᵀT only to 1e-3
    h, exact, _ = clustered_impulses
    monkeypatch.setattr(tk, "DENSE_NORM_LIMIT", 10)
    tols, real = [], tk.toeplitz_norm

    def rough_only(h, method="auto", tol=1e-12):
        tols.append(tol)
        assert tol >= 1e-3, "Lanczos on TᵀT to full accuracy was called"
        return real(h, method=method, tol=tol)

    monkeypatch.setattr(tk, "toeplitz_norm", rough_only)
    assert exact <= tk.certified_norm(h) <= exact * (1 + 1e-8)
    assert tols == [1e-3]


def test_certificate_above_the_dense_limit_verifies(monkeypatch):
    # the front end hands the reported δ to the norm's shift, for the certificate and for verify()
    monkeypatch.setattr(tk, "DENSE_NORM_LIMIT", 10)
    u, y, sigma = _problem(300, 1)
    r = uf.arx_unfalsify(u, y, 2, 2, sigma, backend="structured", tol=1e-6, progress=False)
    c = r.certificate
    exact = float(np.linalg.norm(uf.toeplitz_matrix(np.asarray(c.impulses, float).reshape(-1)), 2))
    assert r.status == "optimal" and c.verify()
    assert exact <= c.upper_bound <= exact * (1 + 1e-8)
    assert c.relative_gap <= 1e-6


def test_cholesky_norm_test_decides_both_ways():
    from unfalsify.solvers.toeplitz import norm_below_by_cholesky as _norm_below_by_cholesky

    h = np.random.default_rng(3).standard_normal(200)
    true = float(np.linalg.norm(uf.toeplitz_matrix(h), 2))
    assert _norm_below_by_cholesky(h, true * (1 + 1e-6))
    assert not _norm_below_by_cholesky(h, true * (1 - 1e-6))
    assert not _norm_below_by_cholesky(h, 0.5 * float(np.linalg.norm(h)))


def test_cholesky_norm_proof_holds_one_n_by_n_array():
    # the proof factorises TᵀT's shifted complement in place: one n × n array (no Fortran copy), which is all
    # the memory above O(n) that the bracket route needs at n > 4000
    import tracemalloc

    from unfalsify.solvers.toeplitz import norm_below_by_cholesky

    n = 1500
    h = np.random.default_rng(4).standard_normal(n) / np.sqrt(n)
    c = 1.01 * float(np.linalg.norm(uf.toeplitz_matrix(h), 2))
    tracemalloc.start()
    try:
        assert norm_below_by_cholesky(h, c)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert 8 * n * n <= peak < 1.2 * 8 * n * n


@pytest.mark.parametrize("progress", [True, False])
def test_a_long_solve_shows_its_progress_on_stderr(one_second_clock, capsys, progress):
    # a fake clock (one second per reading): past 2 s the barrier opens a tqdm bar with the bracket so far
    u, y, sigma = _problem(60, 1)
    r = uf.arx_unfalsify(u, y, 2, 2, sigma, backend="structured", tol=1e-6, progress=progress)
    err = capsys.readouterr().err
    if progress:
        assert "outer" in err and "lower=" in err and "upper=" in err and "newton=" in err
    else:
        assert "outer" not in err
    assert r.certificate.verify()  # the bar does not change the answer
