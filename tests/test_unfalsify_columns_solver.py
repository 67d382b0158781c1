"""The column barrier solver of (7.5) (``unfalsify.solvers.column_barrier``): against Clarabel, against
dense linear algebra and finite differences, and its behaviour on time limits and interrupts."""
import numpy as np
import pytest
import scipy.signal

import unfalsify as uf
from synthesis import fit_predictor
from unfalsify.solvers import capacitance, stacks
from unfalsify.solvers import column_barrier as sc
from unfalsify.solvers.toeplitz import adjoint, corr_hessian, toeplitz_matrix
from unfalsify.subspace import SubspaceProblem

from _servo_arx import servo_arx_data  # tests/ helper


def _sigma(u, y, i, frac=0.5):
    A, _, Yf = uf.subspace_data(u, y, i)
    L = np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T
    return frac * float(np.linalg.norm(Yf - L @ A) / np.sqrt(Yf.size))


def _other_plant(n, seed):
    rng = np.random.default_rng(seed)
    u = np.sign(rng.standard_normal(n))
    y = scipy.signal.lfilter([0.0, 0.5, 0.3], [1.0, -0.6], u) + 0.05 * rng.standard_normal(n)
    return u, y


CASES = [  # (data, i, j, σ fraction)
    ("servo", 3, 14, 0.5, 0),
    ("servo", 4, 20, 0.3, 1),
    ("other", 3, 18, 0.6, 2),
    ("other", 5, 16, 0.5, 3),
]


@pytest.mark.parametrize("fixed", [True, False])
@pytest.mark.parametrize("plant,i,j,frac,seed", CASES)
def test_columns_solver_equals_clarabel(plant, i, j, frac, seed, fixed):
    n = 2 * i + j - 1
    u, y = servo_arx_data(n, seed) if plant == "servo" else _other_plant(n, seed)
    sigma = _sigma(u, y, i, frac)
    kw = {"predictor": fit_predictor(u, y, i)} if fixed else {}
    rc = uf.subspace_unfalsify(u, y, i, sigma, **kw)
    rs = uf.subspace_unfalsify(u, y, i, sigma, backend="structured", tol=1e-7, progress=False, **kw)
    assert rs.status == "optimal" and rs.backend == "structured"
    assert rs.delta == pytest.approx(rc.delta, rel=1e-6)
    c = rs.certificate
    assert c.verify() and c.ok()
    assert c.lower_bound <= c.upper_bound and c.relative_gap <= 1e-7
    # the certified lower bound never exceeds the independent (Clarabel) optimum
    assert c.lower_bound <= rc.delta * (1 + 1e-7)
    # primal point re-checked by dense matrices: every column's ‖T(h_k)‖₂ and the noise
    A, Uf, Yf = uf.subspace_data(u, y, i)
    Ht = np.column_stack([toeplitz_matrix(Uf[:, k]) @ rs.impulses[:, k] for k in range(j)])
    Xi = Yf - np.hstack([rs.Lw, rs.Lu]) @ A - Ht
    assert np.linalg.norm(Xi) <= sigma * np.sqrt(i * j) * (1 + 1e-9)
    assert max(np.linalg.norm(toeplitz_matrix(rs.impulses[:, k]), 2) for k in range(j)) <= rs.delta * (1 + 1e-12)


def _barrier(fixed, i=4, j=20, seed=0):
    u, y = servo_arx_data(2 * i + j - 1, seed)
    P = SubspaceProblem.from_data(u, y, i, _sigma(u, y, i), predictor=fit_predictor(u, y, i) if fixed else None)
    f = P.column_form(scaled=True)
    s = sc._ColumnBarrier(f, tol=1e-6, time_limit=None, progress=False)
    return s, s.start(f.project(f.B))


def _dense_f(s, t, x, i, j):
    p = s._point(x[:-1].reshape(i, j, order="F"), x[-1])
    return t * p.d - p.logdet - s.wn * np.log(p.psi)


def _dense_hessian(s, p, i, j):
    """Hessian of f_t in (vec_F H, δ) from its definition: ``tr(S_k E_a S_k E_b)`` with dense 2i × 2i
    matrices per column, the δ entries with ``∂F/∂δ = I``, and the noise term assembled densely."""
    n = i * j
    Hd = np.zeros((n + 1, n + 1))
    Es = []
    for a in range(i):
        Z = np.eye(i, k=-a)
        Es.append(np.block([[np.zeros((i, i)), Z.T], [Z, np.zeros((i, i))]]))
    for k in range(j):
        T = toeplitz_matrix(p.H[:, k])
        S = np.linalg.inv(np.block([[p.d * np.eye(i), T.T], [T, p.d * np.eye(i)]]))
        sl = slice(k * i, (k + 1) * i)
        Hd[sl, sl] = [[np.trace(S @ Ea @ S @ Eb) for Eb in Es] for Ea in Es]
        Hd[sl, n] = Hd[n, sl] = [np.trace(S @ S @ Ea) for Ea in Es]
        Hd[n, n] += np.trace(S @ S)
    M = np.zeros((n, n))  # vec_F(H) -> vec_F(H̃)
    for k in range(j):
        M[k * i:(k + 1) * i, k * i:(k + 1) * i] = toeplitz_matrix(s.f.U[:, k])
    Pp = np.eye(n) if s.Q is None else np.kron(np.eye(j) - s.Q @ s.Q.T, np.eye(i))
    g = M.T @ p.r.ravel(order="F")
    Hd[:n, :n] += s.wn * (2.0 / p.psi * M.T @ Pp @ M + 4.0 / p.psi**2 * np.outer(g, g))
    return Hd


@pytest.mark.parametrize("fixed", [True, False])
def test_newton_step_equals_dense_newton_step(fixed):
    # independent route: gradient of f_t by central differences of its value, Hessian from its
    # definition with dense matrices, Newton step by a dense solve
    i, j, t = 3, 14, 5.0
    s, p = _barrier(fixed, i, j)
    x0 = np.r_[p.H.ravel(order="F"), p.d]
    n, e = x0.size, 1e-6
    I = np.eye(n)
    g = np.array([(_dense_f(s, t, x0 + e * I[a], i, j) - _dense_f(s, t, x0 - e * I[a], i, j)) / (2 * e)
                  for a in range(n)])
    step = -np.linalg.solve(_dense_hessian(s, p, i, j), g)
    dh, dlt, lam2, _ = s._newton(t, p)
    mine = np.r_[dh.ravel(order="F"), dlt]
    np.testing.assert_allclose(mine, step, atol=1e-5 * np.abs(step).max())
    assert lam2 == pytest.approx(-g @ step, rel=1e-5)
    q = s.f.project(s.f.apply(dh))
    assert s._slope(t, p, dh, dlt, q) == pytest.approx(g @ mine, rel=1e-5)


def test_fft_hessian_equals_trace_formula():
    rng = np.random.default_rng(1)
    m = 6
    h = 0.1 * rng.standard_normal(m)
    d = 1.0
    T = toeplitz_matrix(h)
    F = np.block([[d * np.eye(m), T.T], [T, d * np.eye(m)]])
    S = np.linalg.inv(F)
    H = corr_hessian(S[None, :m, :m], S[None, m:, :m], S[None, m:, m:], m)[0]
    E = []
    for a in range(m):
        Z = np.eye(m, k=-a)
        E.append(np.block([[np.zeros((m, m)), Z.T], [Z, np.zeros((m, m))]]))
    ref = np.array([[np.trace(S @ Ea @ S @ Eb) for Eb in E] for Ea in E])
    np.testing.assert_allclose(H, ref, atol=1e-12)


def test_woodbury_pcg_solve_equals_dense_solve():
    # L optimised: the Newton system D − c U Uᵀ + α g gᵀ assembled densely, solved by numpy
    i, j = 3, 20
    s, p = _barrier(False, i, j)
    S11, S21, S22 = p.blocks()
    G, cross = sc._chunked_hessian(S11, S21, S22)
    np.testing.assert_allclose(cross, adjoint(S21 @ S11), rtol=0, atol=1e-12 * np.max(np.abs(cross)))
    g_noise = s.f.apply_T(p.r)
    rng = np.random.default_rng(0)
    R = rng.standard_normal((i, j, 2))
    X, parts = s._solve_h(G, 2 * s.wn / p.psi, 4 * s.wn / p.psi**2, g_noise, R)
    n = i * j
    M = np.zeros((n, n))  # vec_F(H) -> vec_F(H̃)
    for k in range(j):
        M[k * i:(k + 1) * i, k * i:(k + 1) * i] = toeplitz_matrix(s.f.U[:, k])
    Q = s.Q
    Pperp = np.kron(np.eye(j) - Q @ Q.T, np.eye(i))
    gv = g_noise.ravel(order="F")
    D = np.zeros((n, n))
    for k in range(j):
        D[k * i:(k + 1) * i, k * i:(k + 1) * i] = G[k]
    A = D + (2 * s.wn / p.psi) * M.T @ Pperp @ M + (4 * s.wn / p.psi**2) * np.outer(gv, gv)
    ref = np.linalg.solve(A, R.reshape(n, 2, order="F"))
    np.testing.assert_allclose(X.reshape(n, 2, order="F"), ref, rtol=1e-6, atol=1e-8 * np.abs(ref).max())
    # the primal–dual method solves twice per iteration with the same system: the Woodbury parts reused
    R2 = rng.standard_normal((i, j, 1))
    X2, again = s._solve_h(G, 2 * s.wn / p.psi, 4 * s.wn / p.psi**2, g_noise, R2, woodbury=parts)
    assert again is parts
    ref2 = np.linalg.solve(A, R2.reshape(n, 1, order="F"))
    np.testing.assert_allclose(X2.reshape(n, 1, order="F"), ref2, rtol=1e-6, atol=1e-8 * np.abs(ref2).max())


def test_time_limit_returns_certified_bracket_with_warning():
    u, y = servo_arx_data(2 * 4 + 30 - 1, 2)
    with pytest.warns(uf.SolverWarning, match="time_limit"):
        r = uf.subspace_unfalsify(u, y, 4, _sigma(u, y, 4), backend="structured", time_limit=0.0, progress=False)
    assert r.status == "time_limit"
    c = r.certificate
    assert c.verify() and c.ok() and r.delta == pytest.approx(c.upper_bound)


def test_interrupt_returns_best_certified_bracket(monkeypatch):
    u, y = servo_arx_data(2 * 4 + 30 - 1, 3)
    sigma = _sigma(u, y, 4)
    full = uf.subspace_unfalsify(u, y, 4, sigma, backend="structured", tol=1e-7, progress=False)
    calls = {"n": 0}
    orig = sc._ColumnBarrier._newton

    def newton(self, t, p):
        calls["n"] += 1
        if calls["n"] > 12:
            raise KeyboardInterrupt
        return orig(self, t, p)

    monkeypatch.setattr(sc._ColumnBarrier, "_newton", newton)
    with pytest.warns(uf.SolverWarning, match="interrupted"):
        r = uf.subspace_unfalsify(u, y, 4, sigma, backend="structured", tol=1e-7, progress=False)
    assert r.status == "interrupted"
    c = r.certificate
    assert c.verify() and c.ok()
    assert c.lower_bound > 0 and c.lower_bound <= full.delta * (1 + 1e-9) <= c.upper_bound * (1 + 1e-9)


def test_failed_solve_gives_nan_and_warning(monkeypatch):
    u, y = servo_arx_data(2 * 3 + 20 - 1, 4)

    def bad(self, t, p):
        return p.H, float("nan"), float("nan"), (p.H, float("nan"))

    monkeypatch.setattr(sc._ColumnBarrier, "_newton", bad)
    with pytest.warns(uf.SolverWarning, match="failed"):
        r = uf.subspace_unfalsify(u, y, 3, _sigma(u, y, 3), backend="structured", progress=False)
    assert r.status == "failed" and np.isnan(r.delta)


@pytest.mark.parametrize("fixed", [True, False])
def test_a_lost_delta_schur_complement_fails_the_solve_not_raises(fixed, monkeypatch):
    # Σ‖F_k⁻¹‖² (the δ–δ entry of the Hessian) forced to zero: the δ Schur complement is negative at every step,
    # as when its two terms cancel at a point pressed against the boundary (it raised ZeroDivisionError there)
    u, y = servo_arx_data(2 * 3 + 20 - 1, 4)
    blocks = sc._Point.blocks

    def zero_norm(self):
        out = blocks(self)
        self._norm2 = 0.0
        return out

    monkeypatch.setattr(sc._Point, "blocks", zero_norm)
    with pytest.warns(uf.SolverWarning, match="failed"):
        r = uf.subspace_unfalsify(u, y, 3, _sigma(u, y, 3), backend="structured", progress=False,
                                  predictor=fit_predictor(u, y, 3) if fixed else None)
    assert r.status == "failed" and np.isnan(r.delta)
    assert r.solver_stats["newton"] == 1  # the first step stops the solve (its FFT retry included)


@pytest.mark.parametrize("solver", ["column_barrier", "block_barrier"])
def test_a_start_outside_the_domain_fails_the_solve_not_raises(solver, monkeypatch):
    # the ridge start is strictly feasible by construction unless the noise budget is at the data's rounding level;
    # if it is not, the solver's internal Stop must not leave subspace_unfalsify
    from unfalsify.solvers import block_barrier

    u, y = servo_arx_data(2 * 3 + 20 - 1, 4)
    if solver == "column_barrier":
        monkeypatch.setattr(sc._ColumnBarrier, "_point", lambda self, H, d, gram=None: None)
    else:
        monkeypatch.setattr(block_barrier._BlockBarrier, "_point", lambda self, H, d: None)
        rng = np.random.default_rng(4)
        u = np.column_stack([u, np.sign(rng.standard_normal(u.size))])
        y = np.column_stack([y, y + 0.1 * rng.standard_normal(u.shape[0])])
    with pytest.warns(uf.SolverWarning, match="failed"):
        r = uf.subspace_unfalsify(u, y, 3, 0.01, backend="structured", progress=False)
    assert r.status == "failed" and np.isnan(r.delta) and r.certificate.lower_bound == 0.0


def test_projection_onto_the_complement_of_the_whole_space_is_exactly_zero():
    rng = np.random.default_rng(0)
    X = rng.standard_normal((4, 6))
    Q = np.linalg.qr(rng.standard_normal((6, 6)))[0]
    assert not np.any(uf.solvers.columns.ColumnForm(X, X, 1.0, basis_right=Q).project(X))
    assert np.abs(X - X @ Q @ Q.T).max() > 0  # what the formula leaves: rounding
    Q5 = Q[:, :5]  # a proper subspace: the formula, X minus its part in the row space
    P = uf.solvers.columns.ColumnForm(X, X, 1.0, basis_right=Q5).project(X)
    np.testing.assert_allclose(P, np.outer(X @ Q[:, 5], Q[:, 5]), atol=1e-14)
    Ql = np.linalg.qr(rng.standard_normal((4, 4)))[0]
    assert not np.any(uf.solvers.columns.ColumnForm(X[:, :1], X[:, :1], 1.0, basis_left=Ql).project(X[:, :1]))


@pytest.mark.parametrize("fixed", [True, False])
def test_column_threads_equal_serial_solve(fixed):
    # the chunked, threaded stack operations against the serial ones on the same problem: the same
    # per-column kernels, so the same iterates (sums of chunk sums are the only reordering)
    from concurrent.futures import ThreadPoolExecutor

    u, y = servo_arx_data(2 * 4 + 24 - 1, 5)
    P = SubspaceProblem.from_data(u, y, 4, _sigma(u, y, 4), predictor=fit_predictor(u, y, 4) if fixed else None)
    f = P.column_form(scaled=True)
    B0 = f.project(f.B)
    serial = sc._solve(f, B0, 1e-7, None, False, 5.0, None, sc._SERIAL)
    with ThreadPoolExecutor(3) as pool:
        chunks = sc._Chunks(pool, 3, min_size=0)
        assert len(chunks.slices(24, 1)) == 3
        threaded = sc._solve(f, B0, 1e-7, None, False, 5.0, None, chunks)
    assert serial["status"] == threaded["status"] == "optimal"
    assert threaded["newton"] == serial["newton"]
    assert threaded["upper"] == pytest.approx(serial["upper"], rel=1e-10)
    assert threaded["lower"] == pytest.approx(serial["lower"], rel=1e-10)
    np.testing.assert_allclose(threaded["H"], serial["H"], rtol=1e-8, atol=1e-12 * np.abs(serial["H"]).max())


@pytest.mark.parametrize("workers", [0, -2, 1.5, True, "2"])
def test_bad_workers_is_value_error_naming_workers(workers):
    u, y = servo_arx_data(2 * 3 + 14 - 1, 0)
    with pytest.raises(ValueError, match="workers"):
        uf.subspace_unfalsify(u, y, 3, _sigma(u, y, 3), backend="structured", progress=False, workers=workers)


def test_workers_two_equals_one_through_public_api():
    u, y = servo_arx_data(2 * 3 + 16 - 1, 6)
    sigma = _sigma(u, y, 3)
    r1 = uf.subspace_unfalsify(u, y, 3, sigma, backend="structured", tol=1e-7, progress=False, workers=1)
    r2 = uf.subspace_unfalsify(u, y, 3, sigma, backend="structured", tol=1e-7, progress=False, workers=2)
    assert r1.status == r2.status == "optimal"
    assert r2.delta == pytest.approx(r1.delta, rel=1e-10) and r2.certificate.verify()


def test_nonpositive_newton_decrement_is_a_stall_not_a_centre(monkeypatch):
    # a Newton solve that lost its digits (λ² ≤ 0) must not count as centred: before, t grew by μ
    # on every such step until it overflowed (hundreds of outer iterations); now each one is a stall,
    # and the solve stops as "failed" once a stall brings no better bound
    u, y = servo_arx_data(2 * 3 + 20 - 1, 4)
    orig = sc._ColumnBarrier._newton
    calls = {"n": 0}

    def newton(self, t, p):
        calls["n"] += 1
        dh, dlt, lam2, tangent = orig(self, t, p)
        return dh, dlt, -abs(lam2), tangent

    monkeypatch.setattr(sc._ColumnBarrier, "_newton", newton)
    with pytest.warns(uf.SolverWarning, match="failed"):
        r = uf.subspace_unfalsify(u, y, 3, _sigma(u, y, 3), backend="structured", progress=False)
    assert r.status == "failed" and np.isnan(r.delta)
    assert calls["n"] < 60


def test_cg_tolerance_is_loose_only_far_from_the_centre(monkeypatch):
    # inexact Newton: the CG residual is relaxed (sc._CG_TOL_FAR) only on the first step after t
    # grows and after a step whose decrement exceeded sc._FAR_DECREMENT; otherwise cg_tol holds
    u, y = servo_arx_data(2 * 4 + 24 - 1, 7)
    seen = []
    orig = sc._ColumnBarrier._newton

    def newton(self, t, p):
        out = orig(self, t, p)
        seen.append((t, self.pcg_tol(), out[2]))
        return out

    monkeypatch.setattr(sc._ColumnBarrier, "_newton", newton)
    r = uf.subspace_unfalsify(u, y, 4, _sigma(u, y, 4), backend="structured", tol=1e-7, progress=False)
    assert r.status == "optimal" and r.certificate.verify()
    loose = max(sc._CG_TOL_FAR, 1e-8)
    for k, (t, tol, _) in enumerate(seen):
        first = k == 0 or seen[k - 1][0] != t
        far = first or seen[k - 1][2] > sc._FAR_DECREMENT
        assert tol == (loose if far else 1e-8)
    assert any(tol == 1e-8 for _, tol, _ in seen) and any(tol == loose for _, tol, _ in seen)


def test_common_impulse_directions_are_free_for_the_noise_term():
    # the deflated directions: a common impulse change dh_k = l moves H̃ by T(l) U, inside 𝓛, so the
    # projected residual does not see it; the basis spans exactly {T(l) U Q}
    s, _ = _barrier(False, 4, 20)
    f, m = s.f, s.m
    rng = np.random.default_rng(3)
    l = rng.standard_normal(m)
    moved = f.apply(np.repeat(l[:, None], f.j, axis=1))
    assert np.linalg.norm(f.project(moved)) <= 1e-12 * np.linalg.norm(moved)
    W = s.W.reshape(m, -1)
    np.testing.assert_allclose(W @ W.T, np.eye(m), atol=1e-12)
    Y = (toeplitz_matrix(l) @ f.U @ s.Q).ravel()  # the capacitance coordinates of that move
    assert np.linalg.norm(Y - W.T @ (W @ Y)) <= 1e-12 * np.linalg.norm(Y)


def _spd_capacitance(rng, j=30, m=4, r=6):
    Q, _ = np.linalg.qr(rng.standard_normal((j, r)))
    X = rng.standard_normal((j, m, m))
    E = X @ np.swapaxes(X, 1, 2) * np.logspace(-4, 0, j)[:, None, None] + 1e-6 * np.eye(m)
    dense = sum(np.kron(np.outer(Q[k], Q[k]), E[k]) for k in range(j))  # vec_F order: index a·m + α

    def Cmul(Y3):
        Z = np.moveaxis(Y3 @ Q.T, 2, 0)
        return np.moveaxis(Z @ np.swapaxes(E, 1, 2), 0, 2) @ Q

    return Q, E, dense, Cmul


def test_deflated_cg_solves_the_same_system_in_fewer_iterations():
    rng = np.random.default_rng(0)
    Q, E, dense, Cmul = _spd_capacitance(rng)
    m, r = E.shape[1], Q.shape[1]
    B = rng.standard_normal((2, m, r))
    ref = np.linalg.solve(dense, B.transpose(0, 2, 1).reshape(2, -1).T).T.reshape(2, r, m).transpose(0, 2, 1)
    w, V = np.linalg.eigh(dense)
    W = V[:, :5].T.reshape(5, r, m).transpose(0, 2, 1)  # the five smallest eigenvectors, as (k, m, r)
    counts = {}
    for name, defl in [("plain", None), ("deflated", capacitance._deflation(Cmul, W))]:
        s = sc._ColumnBarrier.__new__(sc._ColumnBarrier)
        s.cg_tol, s.cg_maxiter, s.far, s.cg_iters = 1e-12, 500, False, 0
        X, iterations = s._pcg(Cmul, lambda Y: Y, B, defl)
        assert iterations < s.cg_maxiter
        np.testing.assert_allclose(X, ref, rtol=1e-7, atol=1e-9 * np.abs(ref).max())
        counts[name] = s.cg_iters
    assert counts["deflated"] < counts["plain"]


def _capacitance_rhs(B):
    """(p, m, r) stacks in the vec_F order of :func:`_spd_capacitance`'s dense matrix, one column each."""
    return B.transpose(0, 2, 1).reshape(B.shape[0], -1).T


def test_dense_capacitance_solve_equals_the_assembled_system():
    rng = np.random.default_rng(3)
    Q, E, dense, _ = _spd_capacitance(rng)
    m, r = E.shape[1], Q.shape[1]
    B = rng.standard_normal((2, m, r))
    X = capacitance._dense_capacitance_apply(capacitance._dense_capacitance_factor(E, Q), B)
    np.testing.assert_allclose(dense @ _capacitance_rhs(X), _capacitance_rhs(B), rtol=0,
                               atol=1e-9 * np.abs(B).max())
    # a capacitance with a null direction (Q of rank r − 1): the solution of the consistent part, finite
    Qs = Q.copy()
    Qs[:, -1] = Qs[:, 0]
    dense_s = sum(np.kron(np.outer(Qs[k], Qs[k]), E[k]) for k in range(Qs.shape[0]))
    Bs = (dense_s @ _capacitance_rhs(B)).T.reshape(2, r, m).transpose(0, 2, 1)
    Xs = capacitance._dense_capacitance_apply(capacitance._dense_capacitance_factor(E, Qs), Bs)
    assert np.all(np.isfinite(Xs))
    np.testing.assert_allclose(dense_s @ _capacitance_rhs(Xs), _capacitance_rhs(Bs), rtol=0,
                               atol=1e-8 * np.abs(Bs).max())


@pytest.mark.parametrize("fallback", [True, False])
def test_cg_stopped_at_the_capacitance_order_is_redone_densely(fallback, monkeypatch):
    # CG converges within the capacitance's order in exact arithmetic; a solve stopped short of convergence (here
    # after one iteration) is redone by the dense capacitance, and the Newton solve equals the assembled one.  Without
    # the fallback the truncated CG leaves a wrong solve: the check fails, so it can.
    i, j = 3, 20
    s, p = _barrier(False, i, j)
    monkeypatch.setattr(sc, "_DENSE_CAPACITANCE", 10**6 if fallback else 0)
    s.cg_maxiter = 1
    S11, S21, S22 = p.blocks()
    G, _ = sc._chunked_hessian(S11, S21, S22)
    g_noise = s.f.apply_T(p.r)
    R = np.random.default_rng(0).standard_normal((i, j, 2))
    X, _ = s._solve_h(G, 2 * s.wn / p.psi, 4 * s.wn / p.psi**2, g_noise, R)
    n = i * j
    M = np.zeros((n, n))
    for k in range(j):
        M[k * i:(k + 1) * i, k * i:(k + 1) * i] = toeplitz_matrix(s.f.U[:, k])
    D = np.zeros((n, n))
    for k in range(j):
        D[k * i:(k + 1) * i, k * i:(k + 1) * i] = G[k]
    gv = g_noise.ravel(order="F")
    A = D + (2 * s.wn / p.psi) * M.T @ np.kron(np.eye(j) - s.Q @ s.Q.T, np.eye(i)) @ M \
        + (4 * s.wn / p.psi**2) * np.outer(gv, gv)
    ref = np.linalg.solve(A, R.reshape(n, 2, order="F"))
    close = np.allclose(X.reshape(n, 2, order="F"), ref, rtol=1e-6, atol=1e-8 * np.abs(ref).max())
    assert close == fallback
    assert (s.dense_solves > 0) == fallback


def test_deflation_declines_a_singular_coarse_matrix():
    rng = np.random.default_rng(1)
    _, E, _, Cmul = _spd_capacitance(rng)
    W = np.zeros((2, E.shape[1], 6))
    assert capacitance._deflation(Cmul, W) is None


def test_chol_logdet_and_spd_inverse_match_numpy_and_reject_indefinite_or_nan():
    rng = np.random.default_rng(2)
    X = rng.standard_normal((7, 5, 5))
    K = X @ np.swapaxes(X, 1, 2) + 0.1 * np.eye(5)
    logdet = sc._chol_logdet(K)
    inv = sc._spd_inverse(K)
    np.testing.assert_allclose(inv, np.linalg.inv(K), rtol=1e-10, atol=1e-12)
    assert np.array_equal(inv, np.swapaxes(inv, 1, 2))
    assert logdet == pytest.approx(float(np.linalg.slogdet(K)[1].sum()), rel=1e-12)
    bad = K.copy()
    bad[3] = -bad[3]
    assert sc._chol_logdet(bad) is None
    bad = K.copy()
    bad[2, 0, 0] = np.nan
    assert sc._chol_logdet(bad) is None


def test_shifted_stacks_block_by_block_equal_the_whole_stack(monkeypatch):
    """``_chol_logdet`` and ``_spd_inverse`` of ``shift·I − X`` formed in blocks of a few columns (as at large
    stacks) equal the whole-stack results."""
    rng = np.random.default_rng(5)
    X = rng.standard_normal((9, 6, 6))
    G = X @ np.swapaxes(X, 1, 2)
    shift = 1.1 * float(np.linalg.eigvalsh(G).max())
    K = shift * np.eye(6) - G
    monkeypatch.setattr(stacks, "_BLOCK_BYTES", 2 * 6 * 6 * 8)  # two columns a block
    assert sc._chol_logdet(G, shift=shift) == pytest.approx(float(np.linalg.slogdet(K)[1].sum()), rel=1e-12)
    np.testing.assert_allclose(sc._spd_inverse(G, shift=shift), np.linalg.inv(K), rtol=1e-10, atol=1e-12)
    assert sc._chol_logdet(G, shift=0.5 * shift) is None


def test_noise_step_keeps_half_the_slack():
    s, p = _barrier(False, 4, 20)
    r = p.r
    q = -40.0 * r  # moving along -q grows the residual: the slack's boundary is close
    a = s._noise_step(r, q)
    psi = lambda a: s.f.rho**2 - float(np.sum((r - a * q) ** 2))
    assert 0 < a < 1
    assert psi(a) == pytest.approx(sc._NOISE_KEEP * psi(0.0), rel=1e-9)
    assert s._noise_step(r, 1e-6 * r) == 1.0  # far from the boundary: the full step


def test_chunked_dot_equals_matmul():
    from concurrent.futures import ThreadPoolExecutor

    rng = np.random.default_rng(4)
    A, B = rng.standard_normal((37, 5)), rng.standard_normal((5, 8))
    with ThreadPoolExecutor(3) as pool:
        out = sc._Chunks(pool, 3, min_size=0).dot(A, B)
    np.testing.assert_allclose(out, A @ B, rtol=1e-13)


@pytest.mark.parametrize("workers", [1, 2])
def test_blas_is_pinned_to_one_thread_per_worker(monkeypatch, workers):
    import threadpoolctl

    import unfalsify.solvers.column_barrier as cb

    seen = []
    real = cb._solve

    def spy(*args):
        seen.append(max((p["num_threads"] for p in threadpoolctl.threadpool_info() if p["user_api"] == "blas"),
                        default=1))
        return real(*args)

    monkeypatch.setattr(cb, "_solve", spy)
    u, y = _other_plant(2 * 4 + 20 - 1, 0)
    uf.subspace_unfalsify(u, y, 4, _sigma(u, y, 4), backend="structured", progress=False, workers=workers)
    assert seen == [1]


@pytest.mark.parametrize("backend", ["structured", "cvxpy"])
def test_the_structured_call_holds_blas_to_one_thread_from_set_up_to_certificate(monkeypatch, backend):
    # the set-up (SVDs of the regressor, cond T(u_k)) and the certificate too: with BLAS as configured they took
    # 6.5–9 s around a 14 s solve at (50, 500) on a loaded machine, 0.33 s with one thread. The cvxpy backend keeps
    # the configured threads.
    import threadpoolctl

    import unfalsify.subspace as sub

    def blas_threads():
        return max((p["num_threads"] for p in threadpoolctl.threadpool_info() if p["user_api"] == "blas"), default=1)

    seen = {}
    from_data, certify = sub.SubspaceProblem.from_data.__func__, sub.certify

    def spy_from_data(cls, *args, **kw):
        seen["set-up"] = blas_threads()
        return from_data(cls, *args, **kw)

    def spy_certify(*args, **kw):
        seen["certificate"] = blas_threads()
        return certify(*args, **kw)

    monkeypatch.setattr(sub.SubspaceProblem, "from_data", classmethod(spy_from_data))
    monkeypatch.setattr(sub, "certify", spy_certify)
    u, y = _other_plant(2 * 4 + 20 - 1, 0)
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        configured = blas_threads()
        uf.subspace_unfalsify(u, y, 4, _sigma(u, y, 4), backend=backend, progress=False, workers=1)
    expected = 1 if backend == "structured" else configured
    assert seen == {"set-up": expected, "certificate": expected}


@pytest.mark.parametrize("m, j", [(1, 3), (2, 1), (7, 5), (40, 9), (100, 3)])
def test_gram_stack_recursion_equals_the_products_and_is_symmetric(m, j):
    from unfalsify.solvers.toeplitz import toeplitz_gram_stack, toeplitz_stack

    rng = np.random.default_rng(m + j)
    H = rng.standard_normal((m, j)) * np.exp(-0.05 * np.arange(m))[:, None]
    T = toeplitz_stack(H)
    G = toeplitz_gram_stack(H)
    ref = np.swapaxes(T, 1, 2) @ T
    assert G.shape == (j, m, m)
    assert np.abs(G - ref).max() <= 1e-13 * np.abs(ref).max()
    assert np.array_equal(G, np.swapaxes(G, 1, 2))  # the same sums in the same order on both sides


@pytest.mark.parametrize("lead", [(4,), (2, 3)])
def test_adjoint_of_a_stack_equals_the_subdiagonal_sums(lead):
    rng = np.random.default_rng(len(lead))
    m = 9
    W = rng.standard_normal(lead + (m, m))
    ref = np.stack([np.array([np.trace(w, offset=-d) for d in range(m)]) for w in W.reshape(-1, m, m)], axis=-1)
    np.testing.assert_allclose(adjoint(W), ref.reshape((m,) + lead), rtol=0, atol=1e-13)


@pytest.mark.parametrize("fixed", [True, False])
def test_displacement_hessian_gives_the_fft_newton_step(fixed, monkeypatch):
    """The Newton step by the displacement Hessian (the default from i = 24; here from 1) equals the one by the
    FFT Hessian (the precise route) to rounding, and a decrement the displacement route leaves non-positive is
    recomputed by the FFT."""
    monkeypatch.setattr(sc, "_DISPLACEMENT_FROM", 1)
    used = {"displacement": 0}
    real = sc.displacement_hessian

    def counted(*args, **kwargs):
        used["displacement"] += 1
        return real(*args, **kwargs)

    monkeypatch.setattr(sc, "displacement_hessian", counted)
    s, p = _barrier(fixed, 5, 16)
    s.cg_tol, s.cg_maxiter = 1e-14, 10_000  # L optimised: the CG solves to rounding, not to its default 1e-8
    t = 50.0
    fast = s._newton_at(t, p, False)
    assert used["displacement"] >= 1
    precise = s._newton_at(t, p, True)
    np.testing.assert_allclose(fast[0], precise[0], rtol=0, atol=1e-9 * np.abs(precise[0]).max())
    assert fast[2] == pytest.approx(precise[2], rel=1e-9)
    calls = []  # the route of each Newton system: precise or not
    orig = s._newton_at

    def newton_at(t, p, precise):
        calls.append(precise)
        out = orig(t, p, precise)
        return out if precise else (out[0], out[1], -1.0, out[3])

    s._newton_at = newton_at
    assert s._newton(t, p)[2] > 0 and calls == [False, True] and s.precise
    s._newton(t, p)
    assert calls == [False, True, True]  # the precise route from then on


def test_path_step_is_the_best_of_the_centre_and_its_predictions():
    """``advance`` returns a strictly feasible point whose f at μt is no higher than the centred point's."""
    s, p = _barrier(True, 4, 20)
    t = s.nu / p.d
    deadline = sc.Deadline()
    s._prev = (p.upper(), 0.0)
    p1, step = s.centre(t, p, deadline)
    t2, q = s.advance(t, p1, step, (p1.upper(), 0.0), deadline)
    assert t2 == pytest.approx(s.mu * t) and q is not None
    assert s._f(t2, q) <= s._f(t2, p1)
    K = q.d**2 * np.eye(q.H.shape[0]) - q.TtT
    assert q.psi > 0 and np.all(np.linalg.eigvalsh(K) > 0)


@pytest.mark.parametrize("m, j", [(0, 3), (1, 2), (4, 1), (7, 5), (64, 9)])
def test_toeplitz_stack_is_c_ordered_and_equals_each_matrix(m, j):
    """Each slice is ``T(H[:, k])``, and the stack is C-ordered (a strided stack made every batched product with
    it, and every stack made from it by ``empty_like``, strided)."""
    from unfalsify.solvers.toeplitz import toeplitz_stack

    H = np.random.default_rng(m + 10 * j).standard_normal((m, j))
    T = toeplitz_stack(H)
    assert T.shape == (j, m, m) and T.flags["C_CONTIGUOUS"]
    for k in range(j):
        assert np.array_equal(T[k], toeplitz_matrix(H[:, k]) if m else np.zeros((0, 0)))


def test_stack_pool_gives_a_stack_again_only_when_nothing_else_refers_to_it(monkeypatch):
    from unfalsify.solvers import baselines

    monkeypatch.setattr(stacks, "_POOL_FROM", 0)
    pool = sc._StackPool()
    a = pool.take((3, 4, 4))
    b = pool.take((3, 4, 4))
    assert a is not b and pool.made == 2
    first = id(a)
    del a
    c = pool.take((3, 4, 4))
    assert id(c) == first and pool.made == 2  # a's stack, free again
    view = c[1:]
    del c
    d = pool.take((3, 4, 4))  # the view keeps c's stack busy, b is still held
    assert id(d) not in (first, id(b)) and pool.made == 3
    assert view.base is not None and id(view.base) == first
    assert pool.take((2, 4, 4)).shape == (2, 4, 4) and pool.made == 4  # another shape, another stack
    with baselines.former_routes():  # a solve's pool on the former route allocates afresh
        former = sc._new_pool()
        assert former.bypass and former.take((3, 4, 4)) is not None and former.made == 0
    assert not sc._new_pool().bypass
    monkeypatch.setattr(stacks, "_POOL_FROM", 10**9)  # small stacks too
    assert pool.take((3, 4, 4)) is not None and pool.made == 4


def test_point_passes_in_blocks_on_threads_equal_the_dense_inverse_of_F(monkeypatch):
    """K⁻¹, the blocks of F⁻¹, Σ tr F⁻¹, ‖F⁻¹‖² and T*(S21) from the two blocked passes of ``_Point`` (two columns a
    block, three threads) against the inverse of the dense F = [δI Tᵀ; T δI] of each column."""
    from concurrent.futures import ThreadPoolExecutor

    from unfalsify.solvers.toeplitz import toeplitz_stack

    rng = np.random.default_rng(11)
    m, j = 6, 9
    H = rng.standard_normal((m, j))
    T = toeplitz_stack(H)
    TtT = np.swapaxes(T, 1, 2) @ T
    d = 1.2 * float(np.sqrt(np.linalg.eigvalsh(TtT).max()))
    monkeypatch.setattr(stacks, "_BLOCK_BYTES", 2 * m * m * 8)
    monkeypatch.setattr(stacks, "_POOL_FROM", 0)
    F = np.block([[d * np.broadcast_to(np.eye(m), T.shape), np.swapaxes(T, 1, 2)],
                  [T, d * np.broadcast_to(np.eye(m), T.shape)]])
    S = np.linalg.inv(F)
    with ThreadPoolExecutor(3) as threads:
        p = sc._Point(H, d, T, TtT, 0.0, None, None, sc._Chunks(threads, 3, min_size=0))
        np.testing.assert_allclose(p.Kinv, np.linalg.inv(d * d * np.eye(m) - TtT), rtol=1e-10, atol=1e-12)
        assert p.trace_S() == pytest.approx(float(np.trace(S, axis1=1, axis2=2).sum()), rel=1e-12)
        np.testing.assert_allclose(p.adjoint_S21(), adjoint(S[:, m:, :m]), rtol=1e-10, atol=1e-12)
        S11, S21, S22 = p.blocks()
        assert p.norm2() == pytest.approx(float(np.sum(S * S)), rel=1e-12)
    np.testing.assert_allclose(S11, S[:, :m, :m], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(S21, S[:, m:, :m], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(S22, S[:, m:, m:], rtol=1e-10, atol=1e-12)
    assert np.array_equal(S22, np.swapaxes(S22, 1, 2))


@pytest.mark.parametrize("threads", [0, 3])
@pytest.mark.parametrize("fixed", [True, False])
def test_solve_from_pooled_stacks_equals_the_solve_from_fresh_ones(fixed, threads, monkeypatch):
    # pooling changes where the stacks live, not one operation: the same iterates bit for bit (serial, and on three
    # threads in blocks of two columns); and the pool makes far fewer stacks than are taken
    from concurrent.futures import ThreadPoolExecutor

    u, y = servo_arx_data(2 * 4 + 24 - 1, 5)
    P = SubspaceProblem.from_data(u, y, 4, _sigma(u, y, 4), predictor=fit_predictor(u, y, 4) if fixed else None)
    f = P.column_form(scaled=True)
    B0 = f.project(f.B)
    executor = ThreadPoolExecutor(threads) if threads else None
    chunks = sc._Chunks(executor, threads, min_size=0) if threads else sc._SERIAL
    if threads:
        monkeypatch.setattr(stacks, "_BLOCK_BYTES", 2 * 4 * 4 * 8)
    fresh = sc._solve(f, B0, 1e-7, None, False, 5.0, None, chunks)
    taken, made = [], []
    take, init = sc._StackPool.take, sc._StackPool.__init__

    def counted(self, shape):
        taken.append(shape)
        return take(self, shape)

    def remembered(self, bypass=False):
        init(self, bypass)
        made.append(self)

    monkeypatch.setattr(stacks, "_POOL_FROM", 0)
    monkeypatch.setattr(sc._StackPool, "take", counted)
    monkeypatch.setattr(sc._StackPool, "__init__", remembered)
    pooled = sc._solve(f, B0, 1e-7, None, False, 5.0, None, chunks)
    if executor is not None:
        executor.shutdown()
    assert pooled["status"] == fresh["status"] == "optimal"
    assert pooled["newton"] == fresh["newton"]
    assert pooled["upper"] == fresh["upper"] and pooled["lower"] == fresh["lower"]
    assert np.array_equal(pooled["H"], fresh["H"])
    n_made = sum(pool.made for pool in made)
    assert 0 < n_made < len(taken) / 5


@pytest.mark.parametrize("frac", [0.01, 0.001])
def test_dense_capacitance_route_equals_the_cg_route_where_the_noise_ball_is_small(frac, monkeypatch):
    # σ a small fraction of the least-squares rms: the noise curvature makes the capacitance ill-conditioned and CG
    # long, so the solve switches to the dense factor once CG costs more; the CG-only route (the dense limit set to 0)
    # reaches the same δ.  Both certified, brackets overlapping.
    i, j = 6, 60
    u, y = servo_arx_data(2 * i + j - 1, 0)
    sigma = _sigma(u, y, i, frac)
    runs = {}
    for route, limit in [("dense", sc._DENSE_CAPACITANCE), ("cg", 0)]:
        monkeypatch.setattr(sc, "_DENSE_CAPACITANCE", limit)
        runs[route] = uf.subspace_unfalsify(u, y, i, sigma, backend="structured", tol=1e-6, progress=False)
    assert runs["dense"].solver_stats["cg_dense"] > 0 and runs["cg"].solver_stats["cg_dense"] == 0
    for r in runs.values():
        assert r.status == "optimal" and r.certificate.verify()
    lo = max(r.certificate.lower_bound for r in runs.values())
    up = min(r.certificate.upper_bound for r in runs.values())
    assert lo <= up * (1 + 1e-9)
