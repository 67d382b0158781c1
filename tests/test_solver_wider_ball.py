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
    # σ = 1e-8 × the least-squares rms: the barrier reaches δ (its upper bound) but its dual point does not certify;
    # the dual point of the ball at 1e-3 × the residual, evaluated at σ, does.  Without the retries the same solve
    # ends "failed": the check can fail.
    u, y, sigma = _tiny_sigma_record()
    if not retry:
        monkeypatch.setattr(wb, "SMALL_BALL", 0.0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = uf.subspace_unfalsify(u, y, I, sigma, backend="structured", tol=1e-4, progress=False)
    warned = any(issubclass(w.category, uf.SolverWarning) for w in caught)
    assert warned != retry
    cert = res.certificate
    assert cert.verify()
    if not retry:
        assert res.status == "failed" and cert.relative_gap > 1e-4
        return
    assert res.status == "optimal" and cert.relative_gap <= 1e-4
    factor, status, _ = res.solver_stats["wider"][0]
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
