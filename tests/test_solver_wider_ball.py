"""The lower bound of a failed (7.5) solve from larger noise balls (unfalsify.solvers.wider_ball)."""
import warnings

import numpy as np
import pytest

import unfalsify as uf
from unfalsify.solvers import column_barrier as cb
from unfalsify.solvers import wider_ball as wb
from unfalsify.subspace import SubspaceProblem

from _servo_arx import servo_arx_data  # tests/ helper

I, J = 4, 38


def _tiny_sigma_record(seed=1, frac=1e-8):
    """Servo data whose σ is ``frac`` × the least-squares residual rms (noise-free simulation's scale)."""
    u, y = servo_arx_data(2 * I + J - 1, seed)
    A, _, Yf = uf.subspace_data(u, y, I)
    L = np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T
    return u, y, frac * float(np.sqrt(np.mean((Yf - L @ A) ** 2)))


def test_a_dual_point_of_a_larger_ball_bounds_delta_at_the_smaller_one_by_its_tangent():
    # (⟨V, B⟩ − ρ‖V‖)/d is the bound at every ρ; from ρ' down to ρ it grows by (ρ' − ρ)‖V‖/d, and it stays below the
    # primal value δ*(ρ) ≥ δ*(ρ') (weak duality, the smaller ball admits fewer points)
    u, y, sigma = _tiny_sigma_record(frac=0.05)
    f = SubspaceProblem.from_data(u, y, I, sigma).column_form(scaled=True)
    B0 = f.project(f.B)
    wide = wb.with_rho(f, 2.0 * f.rho)
    assert wide.rho == 2.0 * f.rho and f.rho == pytest.approx(wide.rho / 2) and wide.B is f.B
    at_wide = cb._solve(wide, B0, 1e-6, None, False, 5.0, None, cb._SERIAL, wider=False)
    at_rho = cb._solve(f, B0, 1e-6, None, False, 5.0, None, cb._SERIAL, wider=False)
    assert at_wide["status"] == at_rho["status"] == "optimal"
    V = np.asarray(at_wide["V"]).reshape(f.m, f.j, order="F")
    lower_wide, lower_here = wide.lower_bound(at_wide["V"], at_wide["W"]), f.lower_bound(at_wide["V"], at_wide["W"])
    d = (float(np.sum(f.project(V) * f.B)) - wide.rho * float(np.linalg.norm(f.project(V)))) / lower_wide
    assert lower_here - lower_wide == pytest.approx((wide.rho - f.rho) * np.linalg.norm(f.project(V)) / d, rel=1e-9)
    assert lower_wide < lower_here <= at_rho["upper"] * (1 + 1e-12)
    assert at_wide["upper"] <= at_rho["upper"] * (1 + 1e-6)  # δ* does not increase with the ball


@pytest.mark.parametrize("retry", [True, False])
def test_a_noise_ball_the_barrier_cannot_resolve_is_certified_from_larger_balls(retry, monkeypatch):
    # σ = 1e-9 × the least-squares rms, solver column_barrier itself (the front end takes the primal–dual route first
    # on such balls): the barrier reaches δ (its upper bound) but its dual point does not certify; the dual point of
    # the ball at 1e-3 × the residual, evaluated at σ, does.  Without the retries the same solve ends "failed": the
    # check can fail.
    from unfalsify._common import certify

    u, y, sigma = _tiny_sigma_record(frac=1e-9)
    P = SubspaceProblem.from_data(u, y, I, sigma)
    if not retry:
        monkeypatch.setattr(wb, "SMALL_BALL", 0.0)
    out = cb.solve(P, tol=1e-4, progress=False)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        cert, _ = certify(P, out, "test")
    assert any(issubclass(w.category, uf.SolverWarning) for w in caught) != retry
    assert cert.verify()
    if not retry:
        assert out.status == "failed" and cert.relative_gap > 1e-4
        return
    assert out.status == "optimal" and cert.relative_gap <= 1e-4
    factor, status, _ = out.stats["wider"][0]
    assert status == "optimal" and factor > 1e4
    # second route: Clarabel's δ (its own certificate does not verify at this σ: its noise leaves the ball)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", uf.SolverWarning)
        ref = uf.subspace_unfalsify(u, y, I, sigma, backend="cvxpy")
    assert cert.lower_bound * (1 - 1e-6) <= ref.delta <= cert.upper_bound * (1 + 1e-6)


def test_retries_leave_a_time_limited_or_ordinary_answer_alone():
    u, y, sigma = _tiny_sigma_record(frac=0.5)
    f = SubspaceProblem.from_data(u, y, I, sigma).column_form(scaled=True)
    calls = []

    def solve_at(g, tol, left):
        calls.append(g.rho)
        return dict(status="optimal", V=None, W=None)

    out = dict(status="time_limit", lower=0.0, upper=1.0, V=None, W=None)
    assert wb.tighten_lower(f, out, solve_at, tol=1e-4) is out
    failed = dict(out, status="failed")  # σ at half the rms: not a small ball
    assert wb.tighten_lower(f, failed, solve_at, tol=1e-4) is failed
    assert calls == []


def test_the_front_end_solves_a_small_ball_by_the_primal_dual_method_first():
    # one channel, σ = 1e-9 × the rms: the primal–dual method certifies where the barrier crawls (measured: 8–9
    # iterations against 150–470 Newton steps); its answer equals the barrier's retried bracket
    u, y, sigma = _tiny_sigma_record(frac=1e-9)
    res = uf.subspace_unfalsify(u, y, I, sigma, backend="structured", tol=1e-4, progress=False)
    assert res.status == "optimal" and res.certificate.verify() and res.certificate.relative_gap <= 1e-4
    assert res.solver_stats["route"].startswith("primal_dual")
    out = cb.solve(SubspaceProblem.from_data(u, y, I, sigma), tol=1e-4, progress=False)  # the barrier and its retries
    assert out.status == "optimal" and abs(out.delta - res.delta) <= 2e-4 * res.delta


def test_best_of_keeps_the_smaller_certified_norm_and_the_larger_bound():
    from unfalsify.solvers import run
    from unfalsify.solvers.combine import best_of

    u, y, sigma = _tiny_sigma_record(frac=0.3)
    P = SubspaceProblem.from_data(u, y, I, sigma)
    loose = run("column_barrier", P, tol=1e-2, progress=False)
    tight = run("column_pd", P, tol=1e-7, progress=False)
    both = best_of(P, [loose, tight], tol=1e-6)
    up = [P.evaluate_primal(o.impulses, o.params)[0] for o in (loose, tight)]
    lo = [P.evaluate_dual(o.dual_v, o.dual_W) for o in (loose, tight)]
    assert P.evaluate_primal(both.impulses, both.params)[0] == min(up)
    assert P.evaluate_dual(both.dual_v, both.dual_W) == max(lo)
    assert both.status == "optimal" and both.stats["combined"][0][0] == loose.status.value
    # the other order: the same bracket
    again = best_of(P, [tight, loose], tol=1e-6)
    assert P.evaluate_primal(again.impulses, again.params)[0] == min(up)


def test_a_warm_start_on_the_small_ball_route_is_reported_unused():
    # the same data at σ = 0.3 × the rms, then at 1e-9 × the rms from it: the primal–dual route has no warm start
    u, y, sigma = _tiny_sigma_record(frac=1e-9)
    near = uf.subspace_unfalsify(u, y, I, sigma * 3e8, backend="structured", tol=1e-4, progress=False)
    again = uf.subspace_unfalsify(u, y, I, sigma, backend="structured", tol=1e-4, progress=False, warm_start=near)
    assert again.start == "cold (warm start not used: a noise ball far inside the residual takes the primal–dual route)"
    assert again.status == "optimal" and again.certificate.verify()


def test_a_failed_solve_inside_a_small_ball_says_so_and_names_the_fix():
    from unfalsify._common import Certificate, _failure_reason
    from unfalsify.solvers import SolverOutput, SolverStatus

    def reason(P, status="failed"):
        H = np.zeros(P.Uf.shape)
        out = SolverOutput(delta=1.0, impulses=H, params=np.zeros((I, 3 * I)), status=SolverStatus(status),
                           solve_time=0.0, bracketed=True, stats={"newton": 31})
        bound = P.sigma * np.sqrt(P.n_noise)
        cert = Certificate(delta=1.0, upper_bound=1.0, lower_bound=0.5, noise_norm=0.9 * bound, noise_bound=bound,
                           sigma=P.sigma, n_noise=P.n_noise, problem=P)
        return _failure_reason(P, cert, out)

    u, y, sigma = _tiny_sigma_record(frac=1e-8)
    i = I
    why = reason(SubspaceProblem.from_data(u, y, i, sigma))
    assert "1e-08 of the least-squares residual rms" in why and "A larger σ certifies" in why
    # second route: the residual rms that the message names is the least-squares fit's, computed here by lstsq
    A, _, Yf = uf.subspace_data(u, y, i)
    L = np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T
    assert f"{np.sqrt(np.mean((Yf - L @ A) ** 2)):.3g}" in why
    # not where the ball is ordinary, and not for a time limit (the user's stop)
    assert reason(SubspaceProblem.from_data(u, y, i, sigma * 1e7)) == ""
    assert reason(SubspaceProblem.from_data(u, y, i, sigma), status="time_limit") == ""
