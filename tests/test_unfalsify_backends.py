"""Structured backend vs the cvxpy reference; the two-sided certificate and its verify()."""
import dataclasses
import re
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import unfalsify as uf
from synthesis import DataError

from _servo_arx import servo_arx_data  # tests/ helper


def _sub_data(i, j, seed):
    u, y = servo_arx_data(2 * i + j - 1, seed)
    A, _, Yf = uf.subspace_data(u, y, i)
    L = np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T
    return u, y, 0.5 * float(np.linalg.norm(Yf - L @ A) / np.sqrt(Yf.size))


@pytest.mark.parametrize("seed,n,frac", [(0, 20, 0.5), (1, 25, 0.3), (2, 30, 0.8)])
def test_structured_arx_equals_cvxpy(seed, n, frac):
    u, y = servo_arx_data(n, seed)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    rc = uf.arx_unfalsify(u, y, 2, 2, frac * rms)
    rs = uf.arx_unfalsify(u, y, 2, 2, frac * rms, backend="structured", tol=1e-8)
    assert rs.status == "optimal" and rs.backend == "structured"
    assert rs.delta == pytest.approx(rc.delta, rel=1e-6)
    for r in (rc, rs):
        c = r.certificate
        assert c.verify() and c.ok()
        assert c.lower_bound <= c.upper_bound * (1 + 1e-9)
        assert c.lower_bound == pytest.approx(c.upper_bound, rel=1e-4)


def test_structured_arx_other_plant_and_orders():
    rng = np.random.default_rng(5)
    n = 24
    u = np.sign(rng.standard_normal(n))
    y = np.convolve(u, [0.0, 1.0, -0.5, 0.2])[:n] + 0.05 * rng.standard_normal(n)
    _, rms = uf.arx_least_squares(u, y, 1, 3)
    rc = uf.arx_unfalsify(u, y, 1, 3, 0.5 * rms)
    rs = uf.arx_unfalsify(u, y, 1, 3, 0.5 * rms, backend="structured", tol=1e-8)
    assert rs.delta == pytest.approx(rc.delta, rel=1e-6)


@pytest.mark.parametrize("fixed", [False, True])
def test_structured_subspace_equals_cvxpy(fixed):
    from synthesis import fit_predictor

    u, y, sigma = _sub_data(3, 14, 0)
    kw = {"predictor": fit_predictor(u, y, 3)} if fixed else {}
    rc = uf.subspace_unfalsify(u, y, 3, sigma, **kw)
    rs = uf.subspace_unfalsify(u, y, 3, sigma, backend="structured", tol=1e-8, **kw)
    assert rs.delta == pytest.approx(rc.delta, rel=1e-6)
    assert rs.certificate.verify() and rc.certificate.verify()


def test_verify_fails_on_corrupted_certificates():
    u, y = servo_arx_data(20, 3)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    c = uf.arx_unfalsify(u, y, 2, 2, 0.5 * rms, backend="structured").certificate
    assert c.verify()
    h = np.array(c.impulses, float)
    h[3] += 1e-3
    assert not dataclasses.replace(c, impulses=h).verify()
    assert not dataclasses.replace(c, dual_v=2.0 * c.dual_v).verify()
    assert not dataclasses.replace(c, dual_G=2.0 * c.dual_G).verify()
    assert not dataclasses.replace(c, sigma=1.1 * c.sigma).verify()
    assert not dataclasses.replace(c, sigma=0.9 * c.sigma).verify()
    # scaling the dual point together leaves the bound unchanged (it is homogeneous)
    assert dataclasses.replace(c, dual_v=3.0 * c.dual_v, dual_G=3.0 * c.dual_G).verify()


def test_certificate_units_noise_violation_is_not_hidden_by_large_delta():
    u, y = servo_arx_data(20, 4)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    c = uf.arx_unfalsify(u, y, 2, 2, 0.01 * rms).certificate
    bad = dataclasses.replace(c, noise_norm=2.0 * c.noise_bound)
    assert c.ok() and not bad.ok()


def test_unknown_backend_and_thesis_structured_raise():
    u, y = servo_arx_data(20, 0)
    with pytest.raises(ValueError, match="'cvxpy', 'structured'"):
        uf.arx_unfalsify(u, y, 2, 2, 0.1, backend="mosek")
    with pytest.raises(ValueError, match="conditioned"):
        uf.arx_unfalsify(u, y, 2, 2, 0.1, backend="structured", form="thesis")
    with pytest.raises(DataError, match="no δ unfalsifies"), pytest.warns(uf.NotAtRestWarning):
        uf.arx_unfalsify(np.r_[0.0, u[1:]], np.r_[100.0, y[1:]], 2, 2, 0.1, backend="structured")  # y[0]: noise
    with pytest.raises(ValueError, match="backends|'cvxpy'"):
        uf.subspace_unfalsify(u, y, 3, 0.1, backend="x")


@pytest.mark.parametrize("bad", ["x", ["max_iters", 5], {1: 5}])
def test_solver_options_must_be_a_mapping_of_keywords(bad):
    # a string had reached dict() inside the cvxpy model: "dictionary update sequence element #0 has length 1"
    u, y = servo_arx_data(20, 0)
    for call in (lambda: uf.arx_unfalsify(u, y, 2, 2, 0.1, solver_options=bad),
                 lambda: uf.subspace_unfalsify(u, y, 3, 0.1, solver_options=bad)):
        with pytest.raises(DataError, match=r"solver_options must be a mapping of keyword arguments.*or None"):
            call()


def test_time_limit_returns_certified_bracket_with_warning():
    u, y = servo_arx_data(60, 1)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    with pytest.warns(uf.SolverWarning, match="time_limit"):
        r = uf.arx_unfalsify(u, y, 2, 2, 0.5 * rms, backend="structured", time_limit=0.0)
    assert r.status == "time_limit"
    c = r.certificate
    assert c.verify() and c.ok()
    assert r.delta == pytest.approx(c.upper_bound)


def test_cvxpy_delta_is_never_negative():
    # σ above the least-squares residual: δ = 0, which Clarabel reached as −6.3e-12 (servo seed 1, σ = 1.2 × the rms)
    u, y = servo_arx_data(40, 1)
    r = uf.arx_unfalsify(u, y, 2, 2, 1.2 * uf.arx_least_squares(u, y, 2, 2)[1])
    assert r.status == "optimal" and 0.0 <= r.delta <= 1e-9 and r.certificate.verify()
    from unfalsify.solvers.cvxpy_models import _solved_value

    assert _solved_value("optimal", -6.3e-12) == 0.0 and _solved_value("optimal", 0.25) == 0.25
    assert np.isnan(_solved_value("infeasible", 0.25)) and np.isnan(_solved_value("optimal", None))


def test_an_optimal_status_whose_point_is_not_certified_is_warned():
    # Clarabel's "optimal" holds to its own tolerances: measured (fuzz), σ = 1e-10 on data of rms 0.16 came back
    # "optimal" with the noise at 1.52 σ√N. The mechanism, deterministically: a cvxpy answer for σ certified
    # against the same data at σ/2, where its point's noise is about twice the budget.
    from unfalsify._common import certify
    from unfalsify.solvers import run

    u, y = servo_arx_data(40, 3)
    sigma = 0.5 * uf.arx_least_squares(u, y, 2, 2)[1]
    P, P_half = uf.ArxProblem.from_data(u, y, 2, 2, sigma), uf.ArxProblem.from_data(u, y, 2, 2, sigma / 2)
    out = run("cvxpy", P, form="conditioned", solver="CLARABEL", solver_options=None)
    with warnings.catch_warnings():
        warnings.simplefilter("error", uf.SolverWarning)
        cert, _ = certify(P, out, "test")  # its own problem: certified, no warning
    assert cert.ok()
    with pytest.warns(uf.SolverWarning) as caught:
        cert_half, delta = certify(P_half, out, "test")
    said = [str(w.message) for w in caught]
    assert any(re.search(r"reported 'optimal', but its point .*\(noise ‖ξ‖ = 2(\.0+)? σ√N", m) for m in said)
    # its δ also lies below the dual bound of the σ/2 problem, which holds whatever the primal point: not δ_unf
    assert out.delta < cert_half.lower_bound and any("lies below the bracket" in m for m in said)
    assert not cert_half.ok() and np.isnan(delta)


def test_a_stopped_solve_whose_point_leaves_the_noise_ball_certifies_only_its_lower_bound():
    # measured (fuzz): an ARX solve stopped `failed` with its point's noise at 1.0000049 σ√N once recomputed from the
    # data (cond T(u) about 1e24), and the warning called its bracket certified.  Deterministically: a stopped
    # structured answer for σ, certified against the same data at σ(1 − 1e-5).
    from unfalsify._common import certify
    from unfalsify.solvers import SolverStatus, run

    u, y = servo_arx_data(40, 3)
    sigma = 0.5 * uf.arx_least_squares(u, y, 2, 2)[1]
    P, P_less = (uf.ArxProblem.from_data(u, y, 2, 2, s) for s in (sigma, sigma * (1 - 1e-5)))
    out = dataclasses.replace(run("arx_barrier", P, tol=1e-6, progress=False), status=SolverStatus.TIME_LIMIT)
    with pytest.warns(uf.SolverWarning, match="the certified bracket has relative gap"):
        cert, delta = certify(P, out, "test")
    assert cert.verify() and delta == cert.delta == min(out.delta, cert.upper_bound)  # its δ, at most the attained
    with pytest.warns(uf.SolverWarning, match=r"leaves the noise ball \(‖ξ‖ = 1\.0000\d+ σ√N\), so its δ .* is not "
                                              r"certified; the lower bound .* is$"):
        cert, delta = certify(P_less, out, "test")
    assert not cert.verify() and np.isnan(delta)


def _subspace_problem(i, j, seed, sigma_factor=1.0, channels=(1, 1), fixed=False):
    import synthesis

    m, l = channels
    n = 2 * i + j - 1
    if channels == (1, 1):
        u, y = servo_arx_data(n, seed)
    else:
        rng = np.random.default_rng(seed)
        u = np.sign(rng.standard_normal((n, m)))
        y = np.zeros((n, l))
        for k in range(2, n):
            y[k] = 0.6 * y[k - 1] + u[k - 1].sum() * np.arange(1, l + 1) * 0.3 + 0.2 * u[k - 2, 0]
        y += 0.05 * rng.standard_normal((n, l))
    A, _, Yf = uf.subspace_data(u, y, i)
    L = np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T
    sigma = 0.5 * float(np.linalg.norm(Yf - L @ A) / np.sqrt(Yf.size)) * sigma_factor
    pred = synthesis.fit_predictor(u, y, i) if fixed else None
    return uf.SubspaceProblem.from_data(u, y, i, sigma, predictor=pred)


@pytest.mark.parametrize("steepest", [2, 0])
@pytest.mark.parametrize("case", ["arx", "arx 2x1", "subspace", "subspace L fixed", "subspace 2x2"])
def test_a_conic_point_just_outside_the_noise_ball_is_moved_inside(case, steepest, monkeypatch):
    """A conic solver's 'optimal' point 1e-5 outside the ball (its feasibility tolerance, measured in a fuzz run:
    seven cvxpy answers 1.1e-6 to 1.4e-5 outside, status 'optimal', no warning, certificates that did not verify)
    is moved into the ball; its certificate verifies and δ rises by about dδ/dρ times the excess.  Deterministic: a
    structured answer for σ, taken as a conic one for σ(1 − 1e-5); second route, the structured solve at σ(1 − 1e-5)."""
    from unfalsify import _common
    from unfalsify._common import certify, into_ball
    from unfalsify.solvers import run

    monkeypatch.setattr(_common, "_BALL_STEEPEST", steepest)  # 0: the ridge step alone
    if case.startswith("arx"):
        if case == "arx":
            u, y = servo_arx_data(40, 3)
        else:
            rng = np.random.default_rng(4)
            u = np.sign(rng.standard_normal((40, 2)))
            y = np.convolve(u[:, 0], [0, 0.5, 0.3])[:40] - np.convolve(u[:, 1], [0, 0.2])[:40]
            y = y + 0.05 * rng.standard_normal(40)
        sigma = 0.5 * uf.arx_least_squares(u, y, 2, 2)[1]
        P, P_less = (uf.ArxProblem.from_data(u, y, 2, 2, s) for s in (sigma, sigma * (1 - 1e-5)))
    else:
        kw = dict(channels=(2, 2) if "2x2" in case else (1, 1), fixed="fixed" in case)
        P, P_less = (_subspace_problem(4, 40, 1, f, **kw) for f in (1.0, 1 - 1e-5))
    solver = "arx_barrier" if case.startswith("arx") else ("column_barrier" if P.siso else "block_barrier")
    out = dataclasses.replace(run(solver, P, tol=1e-8, progress=False), bracketed=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", uf.SolverWarning)
        outside, _ = certify(P_less, out, "test")
    assert outside.noise_norm > outside.noise_bound * (1 + 5e-6) and not outside.verify()
    moved = into_ball(P_less, out)
    assert moved.stats["into_ball"] == pytest.approx(outside.noise_norm / outside.noise_bound - 1, rel=1e-6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", uf.SolverWarning)  # the solver's own δ (not the moved point's) may be 4e-5 below
        cert, _ = certify(P_less, moved, "test")
    assert cert.noise_norm <= cert.noise_bound and cert.verify(rtol=1e-12)
    # the moved point's δ is a proven upper bound: not below the structured solve's certified lower bound at σ(1 − 1e-5)
    exact = run(solver, P_less, tol=1e-9, progress=False)
    ref, _ = certify(P_less, exact, "test")
    assert ref.lower_bound <= cert.upper_bound
    if steepest:  # the ridge step alone reaches too, at a cost
        assert cert.upper_bound <= ref.upper_bound * (1 + 1e-3)
    assert into_ball(P, out) is out and into_ball(P_less, dataclasses.replace(out, bracketed=True)).stats == out.stats


@pytest.mark.parametrize("case", ["arx", "subspace", "subspace 2x2"])
def test_ridge_step_fits_every_column(case):
    """The step of :func:`into_ball` that reaches where steepest descent cannot, at target 0: ``M_k d_k = r_k`` for
    square (one channel) and wide (two inputs) maps; second route, the maps applied by the form itself."""
    from unfalsify._common import _ridge_step

    if case == "arx":
        u, y = servo_arx_data(40, 3)
        form = uf.ArxProblem.from_data(u, y, 2, 2, 0.01).column_form(scaled=False)
    else:
        form = _subspace_problem(4, 30, 2, channels=(2, 2) if "2x2" in case else (1, 1)).column_form(scaled=False)
    R = np.random.default_rng(0).standard_normal(form.B.shape)
    D = _ridge_step(form, R, 0.0, form.apply_T(R).shape)
    assert D.shape == form.apply_T(R).shape
    assert np.allclose(form.apply(D), R, atol=1e-9 * np.abs(R).max())


@pytest.mark.parametrize("method", ["barrier", "primal_dual"])
def test_sigma_equal_to_the_least_squares_rms_gives_a_certified_zero(method):
    # ‖PB‖ on ρ up to rounding: δ = 0 with an empty interior, where the structured solvers had failed (fuzz run:
    # multisine and low-pass ARX records, a multilevel (7.5) window with its own predictor, ‖PB‖/ρ − 1 = 2e-16 …
    # 4e-15). σ is the least-squares rms shrunk by 3e-15, the rounding's side that needs a solve.
    shrink = 1.0 + 3e-15
    u, y = servo_arx_data(450, 5)
    sigma = uf.arx_least_squares(u, y, 2, 2)[1] / shrink
    r = uf.arx_unfalsify(u, y, 2, 2, sigma, backend="structured", method=method, progress=False)
    assert r.status == "optimal" and r.delta == 0.0 and r.certificate.verify()
    i = 4
    u, y = servo_arx_data(2 * i + 40 - 1, 6)
    A, _, Yf = uf.subspace_data(u, y, i)
    L = np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T
    sigma = float(np.sqrt(np.mean((Yf - L @ A) ** 2))) / shrink
    r = uf.subspace_unfalsify(u, y, i, sigma, backend="structured", method=method, progress=False)
    assert r.status == "optimal" and r.delta == 0.0 and r.certificate.verify()


def test_zero_answer_takes_rounding_not_more():
    from unfalsify.solvers.base import zero_answer
    from unfalsify.solvers.columns import ColumnForm

    B = np.random.default_rng(0).standard_normal((5, 3))
    rho = float(np.linalg.norm(B))
    assert zero_answer(ColumnForm(B, B, rho / (1 + 4e-15))) and zero_answer(ColumnForm(B, B, rho))
    assert not zero_answer(ColumnForm(B, B, rho / (1 + 1e-9)))


@pytest.mark.parametrize("method, tol", [("barrier", 1e-6), ("primal_dual", 1e-8)])
def test_structured_arx_with_a_rank_deficient_regressor_is_certified(method, tol):
    # noise-free data of an order-3 plant fitted with na = nb = 4: cond Φ 1.8e16. The unpivoted QR basis of range Φ
    # kept a direction of rounding, and the solve stopped "optimal" with gap 1.7e-3 and the noise 5e-4 over its bound
    # (fuzz run); the basis now has the rank of the least-squares fit
    import scipy.signal

    rng = np.random.default_rng(1)
    u = rng.standard_normal(149)
    y = scipy.signal.lfilter([1.0, -0.4, 0.3, 0.2], np.poly([0.9, 0.5 + 0.4j, 0.5 - 0.4j]).real, u)
    sigma = 0.01 * uf.arx_least_squares(u, y, 4, 4)[1]
    with warnings.catch_warnings():
        warnings.simplefilter("error", uf.SolverWarning)
        r = uf.arx_unfalsify(u, y, 4, 4, sigma, backend="structured", method=method, tol=tol, progress=False)
    c = r.certificate
    assert r.status == "optimal" and c.verify() and c.relative_gap <= tol


def test_a_structured_optimal_whose_certificate_fails_is_warned():
    from unfalsify._common import certify
    from unfalsify.solvers import run

    u, y = servo_arx_data(450, 3)
    sigma = 0.5 * uf.arx_least_squares(u, y, 2, 2)[1]
    P, P_half = uf.ArxProblem.from_data(u, y, 2, 2, sigma), uf.ArxProblem.from_data(u, y, 2, 2, sigma / 2)
    out = run("arx_barrier", P, tol=1e-6, progress=False)
    with pytest.warns(uf.SolverWarning, match="column form and the data disagree"):
        cert, _ = certify(P_half, out, "test")
    assert not cert.ok()


def test_zero_delta_structured():
    u, y = servo_arx_data(25, 1)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    r = uf.arx_unfalsify(u, y, 2, 2, 1.01 * rms, backend="structured")
    assert r.status == "optimal" and r.delta == 0.0 and r.certificate.verify()


@pytest.mark.slow
@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), n=st.integers(8, 16), frac=st.floats(0.1, 0.95))
def test_lower_bound_never_exceeds_clarabel_optimum(seed, n, frac):
    rng = np.random.default_rng(seed)
    u = np.sign(rng.standard_normal(n))
    u[0] = 1.0
    y = rng.standard_normal(n)
    _, rms = uf.arx_least_squares(u, y, 1, 1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rs = uf.arx_unfalsify(u, y, 1, 1, frac * rms, backend="structured")
        rc = uf.arx_unfalsify(u, y, 1, 1, frac * rms)
    c = rs.certificate
    assert c.lower_bound <= c.upper_bound * (1 + 1e-9) + 1e-12
    # independent optimum (Clarabel), solved to its own accuracy
    assert c.lower_bound <= rc.delta * (1 + 1e-6) + 1e-9
    assert rc.certificate.lower_bound <= rs.certificate.upper_bound * (1 + 1e-6) + 1e-9


def test_bounds_that_cross_at_the_rounding_level_of_the_data_are_warned_with_the_scale():
    # σ within 1e-11 of the least-squares residual rms: δ is 1e-12 of the data's scale, where the two sides, computed
    # from different points, hold only to the data's rounding (measured: lower above upper by 8.9e-6 relative)
    import scipy.signal

    rng = np.random.default_rng(0)
    u = np.sign(rng.standard_normal(120))
    y = scipy.signal.lfilter([0.0, 0.5, 0.3], [1.0, -0.6], u) + 0.05 * rng.standard_normal(120)
    A, _, Yf = uf.subspace_data(u, y, 4)
    L = np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T
    rms = float(np.sqrt(np.mean((Yf - L @ A) ** 2)))
    with pytest.warns(uf.SolverWarning, match="the certified bounds cross") as rec:
        r = uf.subspace_unfalsify(u, y, 4, rms * (1 - 1e-11), backend="structured", progress=False)
    c = r.certificate
    assert c.lower_bound > c.upper_bound and not c.verify()
    scale = np.linalg.norm(y) / np.linalg.norm(u)
    message = next(str(w.message) for w in rec if "cross" in str(w.message))
    assert f"‖y‖/‖u‖ = {scale:.3g}" in message
    # a well-scaled σ: no such warning
    with warnings.catch_warnings():
        warnings.simplefilter("error", uf.SolverWarning)
        r = uf.subspace_unfalsify(u, y, 4, 0.5 * rms, backend="structured", progress=False)
    assert r.certificate.lower_bound <= r.certificate.upper_bound


def _hand_bound(V, W, B, cert):
    """The certificate's dual formula written out: (⟨V, B⟩ − σ√N ‖V‖_F) / Σ_k ‖W_k‖_*."""
    return (np.sum(V * B) - cert.noise_bound * np.linalg.norm(V)) / sum(np.linalg.norm(w, "nuc") for w in W)


def _toeplitz_adjoint(Wk):
    return np.array([np.trace(Wk, offset=-d) for d in range(Wk.shape[0])])


@pytest.mark.parametrize("backend", ["cvxpy", "structured"])
def test_dual_point_gives_the_lower_bound_by_hand_subspace(backend):
    # The stored (dual_v, dual_G) of a conic solve satisfy T*(W_k) = T(u_k)ᵀ v_k only to the solver's tolerance: the
    # formula with them is no bound (measured above the upper bound); dual_point() is the repaired point.
    i = 4
    u, y, sigma = _sub_data(i, 30, 3)
    cert = uf.subspace_unfalsify(u, y, i, sigma, backend=backend, progress=False).certificate
    V, W, B = cert.dual_point()
    A, Uf, Yf = uf.subspace_data(u, y, i)
    assert V.shape == Yf.shape and W.shape == (Yf.shape[1], i, i) and np.array_equal(B, Yf)
    assert np.abs(V @ A.T).max() <= 1e-12 * np.abs(V).max() * np.abs(A).max()
    for k in range(Uf.shape[1]):
        Tu = np.array([[Uf[a - b, k] if a >= b else 0.0 for b in range(i)] for a in range(i)])
        np.testing.assert_allclose(_toeplitz_adjoint(W[k]), Tu.T @ V[:, k], rtol=1e-10,
                                   atol=1e-12 * np.abs(Tu.T @ V[:, k]).max())
    np.testing.assert_allclose(_hand_bound(V, W, B, cert), cert.lower_bound, rtol=1e-9)
    assert cert.lower_bound <= cert.upper_bound


def test_dual_point_gives_the_lower_bound_by_hand_arx():
    u, y = servo_arx_data(25, 1)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    cert = uf.arx_unfalsify(u, y, 2, 2, 0.5 * rms, backend="structured", tol=1e-8).certificate
    V, W, B = cert.dual_point()
    assert V.shape == B.shape == (25, 1) and W.shape == (1, 25, 25)
    assert cert.lower_bound > 0
    np.testing.assert_allclose(_hand_bound(V, W, B, cert), cert.lower_bound, rtol=1e-9)


def test_dual_point_without_a_dual_is_refused():
    u, y, sigma = _sub_data(3, 20, 0)
    cert = uf.subspace_unfalsify(u, y, 3, sigma, backend="structured", progress=False).certificate
    with pytest.raises(uf.UnfalsificationError, match="structured"):
        dataclasses.replace(cert, dual_v=None).dual_point()


def test_dual_point_gives_the_lower_bound_by_hand_two_channels():
    rng = np.random.default_rng(1)
    n, i = 40, 3
    u = rng.standard_normal((n, 2))
    y = np.column_stack([np.convolve(u[:, 0], [0, .5, .2])[:n], np.convolve(u[:, 1], [0, .3])[:n]])
    y = y + 0.05 * rng.standard_normal((n, 2))
    cert = uf.subspace_unfalsify(u, y, i, 0.03, progress=False).certificate
    V, W, B = cert.dual_point()
    assert V.shape == B.shape == (6, 35) and W.shape == (35, 6, 6) and cert.lower_bound > 0
    np.testing.assert_allclose(_hand_bound(V, W, B, cert), cert.lower_bound, rtol=1e-9)
