"""Warm starts of the subspace program (7.5) (issue 27, item 4): ``subspace_unfalsify(..., warm_start=result)``.

A warm re-solve must land on the same δ as a cold solve to the certified gap (the two certified brackets
overlap), carry a certificate that verifies, take fewer Newton steps than cold on an advanced window, and
refuse or report the warm starts it cannot use.  No timing assertions.
"""
import dataclasses

import numpy as np
import pytest

import unfalsify as uf
from synthesis import DataError
from unfalsify.solvers import column_barrier

I, J, SHIFT_MAX = 6, 60, 10
TOL = 1e-6


def _record(seed, n):
    """±1 input (no zero sample), a short FIR plant, white noise."""
    rng = np.random.default_rng(seed)
    u = rng.choice([-1.0, 1.0], size=n)
    y = np.convolve(u, [0.0, 0.8, 0.4, -0.2])[:n] + 0.1 * rng.standard_normal(n)
    return u, y


def _sigma(u, y, i):
    A, _, Yf = uf.subspace_data(u, y, i)
    L = np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T
    return 0.5 * float(np.linalg.norm(Yf - L @ A) / np.sqrt(Yf.size))


def _solve(u, y, sigma, **kw):
    return uf.subspace_unfalsify(u, y, I, sigma, backend="structured", tol=TOL, progress=False, workers=1, **kw)


@pytest.fixture(scope="module", params=[0, 1, 2])
def case(request):
    n = 2 * I + J - 1
    u, y = _record(request.param, n + SHIFT_MAX)
    sigma = _sigma(u[:n], y[:n], I)
    return dict(u=u, y=y, n=n, sigma=sigma, first=_solve(u[:n], y[:n], sigma))


def _same_delta(a, b):
    """Both certified: the optimum lies in both brackets, so they overlap (up to the arithmetic's rounding)."""
    ca, cb = a.certificate, b.certificate
    assert ca.verify() and cb.verify()
    assert max(ca.lower_bound, cb.lower_bound) <= min(ca.upper_bound, cb.upper_bound) * (1 + 1e-9)
    assert abs(a.delta - b.delta) <= TOL * max(a.delta, b.delta) * 1.01


@pytest.mark.parametrize("k", [1, 5, SHIFT_MAX])
def test_advanced_window_equals_cold(case, k):
    u, y, n, sigma = case["u"], case["y"], case["n"], case["sigma"]
    cold = _solve(u[k : n + k], y[k : n + k], sigma)
    warm = _solve(u[k : n + k], y[k : n + k], sigma, warm_start=case["first"])
    assert warm.start == f"warm (window advanced by {k} sample{'s' if k > 1 else ''})"
    assert cold.start == "cold"
    assert warm.status == "optimal"
    _same_delta(warm, cold)


@pytest.mark.parametrize("factor", [1.05, 1 / 1.05])
def test_nearby_sigma_equals_cold(case, factor):
    u, y = case["u"][: case["n"]], case["y"][: case["n"]]
    sigma = case["sigma"] * factor
    cold = _solve(u, y, sigma)
    warm = _solve(u, y, sigma, warm_start=case["first"])
    assert warm.start == "warm (same window)"
    _same_delta(warm, cold)


def test_warm_takes_fewer_newton_steps(case):
    u, y, n, sigma = case["u"], case["y"], case["n"], case["sigma"]
    k = 1
    cold = _solve(u[k : n + k], y[k : n + k], sigma)
    warm = _solve(u[k : n + k], y[k : n + k], sigma, warm_start=case["first"])
    assert warm.solver_stats["warm"] == "used"
    assert warm.solver_stats["newton"] < cold.solver_stats["newton"]


def test_warm_chain(case):
    """Each re-solve warm-starts the next, as δ tracked online would."""
    u, y, n, sigma = case["u"], case["y"], case["n"], case["sigma"]
    prev = case["first"]
    for k in (2, 4, 6):
        prev = _solve(u[k : n + k], y[k : n + k], sigma, warm_start=prev)
        assert prev.start == "warm (window advanced by 2 samples)"
        assert prev.certificate.verify()


@pytest.fixture(scope="module")
def small():
    n = 2 * I + J - 1
    u, y = _record(7, n)
    sigma = _sigma(u, y, I)
    return dict(u=u, y=y, sigma=sigma, first=_solve(u, y, sigma))


@pytest.mark.parametrize("bad, fix", [
    (lambda r: r.certificate, "pass that result, or warm_start=None"),
    (lambda r: dataclasses.replace(r, horizon=I + 1), f"horizon={I}"),
    (lambda r: dataclasses.replace(r, n_inputs=2), "same channels"),
    (lambda r: dataclasses.replace(r, impulses=r.impulses[:, :-1]), "as subspace_unfalsify returned it"),
])
def test_invalid_warm_start_raises_with_the_fix(small, bad, fix):
    with pytest.raises(DataError, match="warm_start") as err:
        _solve(small["u"], small["y"], small["sigma"], warm_start=bad(small["first"]))
    assert fix in str(err.value)


def test_other_horizon_result_raises(small):
    other = uf.subspace_unfalsify(small["u"], small["y"], I - 1, small["sigma"], backend="structured", progress=False)
    with pytest.raises(ValueError, match=f"horizon={I}"):
        _solve(small["u"], small["y"], small["sigma"], warm_start=other)


def test_unrelated_data_fall_back_cold_with_a_note(small):
    u, y = _record(8, small["u"].size)
    res = _solve(u, y, small["sigma"], warm_start=small["first"])
    assert res.start.startswith("cold (warm start not used: these data do not continue the earlier window")
    assert res.certificate.verify()
    _same_delta(res, _solve(u, y, small["sigma"]))


def test_solver_without_warm_start_notes_it(small):
    res = uf.subspace_unfalsify(small["u"], small["y"], I, small["sigma"], warm_start=small["first"])  # cvxpy
    assert res.start.startswith("cold (warm start not used: solver 'cvxpy' has no warm start")
    assert res.certificate.verify()


def test_a_stalled_warm_path_is_resolved_cold(small, monkeypatch):
    run = column_barrier._ColumnBarrier.run

    def failing(self, p, t=None):
        out = run(self, p, t)
        if self.warm_started:
            out["status"] = "failed"
        return out

    monkeypatch.setattr(column_barrier._ColumnBarrier, "run", failing)
    res = _solve(small["u"][1:], small["y"][1:], small["sigma"], warm_start=small["first"])
    assert "re-solved cold" in res.start and res.status == "optimal"
    assert res.solver_stats["warm_newton"] > 0
    assert res.certificate.verify()


def test_a_warm_path_that_stagnates_twice_is_given_up_for_a_cold_solve(small, monkeypatch):
    """Newton decrements that stop halving (λ² held at 3 on a warm path, the pattern of the failed warm paths at
    (20, 400)) end the warm path at the second stagnating centring; the solve is redone cold and says so."""
    newton = column_barrier._ColumnBarrier._newton
    seen = []

    def plateau(self, t, p):
        dh, dlt, lam2, tangent = newton(self, t, p)
        if self.warm_started:
            seen.append(self.stagnated)
            return 1e-3 * dh, 1e-3 * dlt, 3.0, tangent  # short steps at a constant decrement
        return dh, dlt, lam2, tangent

    monkeypatch.setattr(column_barrier._ColumnBarrier, "_newton", plateau)
    res = _solve(small["u"][1:], small["y"][1:], small["sigma"], warm_start=small["first"])
    limit = column_barrier._WARM_MAX_STAGNATIONS
    assert f"stagnated in {limit} centrings" in res.start and "re-solved cold" in res.start
    assert res.status == "optimal" and res.certificate.verify()
    # the rule needs _WARM_STAGNATION steps a centring: the warm path ran exactly limit centrings of them
    assert res.solver_stats["warm_newton"] == len(seen) == limit * column_barrier._WARM_STAGNATION
    assert seen[-1] == limit - 1
    _same_delta(res, _solve(small["u"][1:], small["y"][1:], small["sigma"]))


def test_a_warm_path_whose_newton_solves_lose_their_digits_is_resolved_cold(small, monkeypatch):
    """The δ Schur complement of the Newton system cancelled to exactly zero on a warm path pressed against
    ‖T(h_k)‖₂ = δ (measured at (20, 400)), and the solve raised ZeroDivisionError.  Now the decrement is non-finite,
    the warm path stops as failed and the solve is redone cold (here forced: the Schur complement made non-positive
    on the warm path only)."""
    newton_at = column_barrier._ColumnBarrier._newton_at
    calls = []

    def cancelled(self, t, p, precise):
        if self.warm_started:
            p.blocks()
            p._norm2 = 0.0  # Σ‖F_k⁻¹‖²: the δ–δ entry, so the Schur complement is −cᵀx_c < 0
            calls.append(precise)
        return newton_at(self, t, p, precise)

    monkeypatch.setattr(column_barrier._ColumnBarrier, "_newton_at", cancelled)
    res = _solve(small["u"][1:], small["y"][1:], small["sigma"], warm_start=small["first"])
    assert "stopped with status 'failed'" in res.start and "re-solved cold" in res.start
    assert calls == [False, True]  # the displacement Hessian's step, then the FFT Hessian's, then the stop
    assert res.status == "optimal" and res.certificate.verify()
    _same_delta(res, _solve(small["u"][1:], small["y"][1:], small["sigma"]))


def test_state_of_a_cvxpy_result_is_usable(small):
    """A result without a barrier path (cvxpy) still warm-starts the structured solver (its point and gap)."""
    ref = uf.subspace_unfalsify(small["u"], small["y"], I, small["sigma"])
    res = _solve(small["u"], small["y"], small["sigma"] * 1.05, warm_start=ref)
    assert res.start == "warm (same window)"
    _same_delta(res, _solve(small["u"], small["y"], small["sigma"] * 1.05))


@pytest.mark.slow
def test_bench_warm_table_quick(tmp_path):
    """``bench-unfalsify --backend structured --series warm --quick``: every case warm, same δ, verified."""
    import json

    from experiments.cli import main

    assert main(["bench-unfalsify", "--quick", "--backend", "structured", "--series", "warm",
                 "--out", str(tmp_path)]) == 0
    st = json.loads((tmp_path / "bench_unfalsify" / "bench_unfalsify.json").read_text())["structured"]
    assert st["series"] == [] and st["comparison"] is None
    rows = st["warm"]["rows"]
    assert len(rows) == 7  # k = 1, 10, 50 with L optimised and with L fixed, and σ × 1.05
    assert sorted(r["L_fixed"] for r in rows) == [False] * 4 + [True] * 3
    for r in rows:
        assert r["overlap"] and r["cold"]["verify"] and r["warm"]["verify"]
        assert r["warm"]["start"].startswith("warm (") and r["cold"]["start"] == "cold"
    assert "Warm starts at (i, j) = (6, 60)" in (tmp_path / "bench_unfalsify" / "bench_unfalsify.md").read_text()


def test_bench_warm_floor_table_quick(tmp_path):
    """``--series warm-floor --quick``: both L modes resumed from every centre of their own path, each resumed solve
    certified to the same δ; resuming later on the path never takes more Newton steps than the cold solve."""
    import json

    from experiments.cli import main

    assert main(["bench-unfalsify", "--quick", "--backend", "structured", "--series", "warm-floor",
                 "--out", str(tmp_path)]) == 0
    st = json.loads((tmp_path / "bench_unfalsify" / "bench_unfalsify.json").read_text())["structured"]
    assert st["warm"] is None and st["series"] == []
    cases = st["warm_floor"]["cases"]
    assert [c["L_fixed"] for c in cases] == [False, True]
    for c in cases:
        assert len(c["rows"]) >= 3 and c["delta_old"] > 0 and c["delta_new"] > 0
        gaps = [r["gap"] for r in c["rows"]]
        assert gaps == sorted(gaps, reverse=True)  # the path's centres in order
        for r in c["rows"]:
            assert r["status"] == "optimal" and r["used"] and r["overlap"] and r["certified_gap"] <= 1e-4
            assert r["newton"] <= c["cold_newton"] + 2
        assert c["rows"][-1]["newton"] < c["cold_newton"]
    assert "The floor of a warm start" in (tmp_path / "bench_unfalsify" / "bench_unfalsify.md").read_text()


def test_fixed_predictor_warm_equals_cold(small):
    """L fixed (the predictor of each window): the same mapping of the columns, the same certified δ."""
    import synthesis as sy

    u, y, sigma = small["u"], small["y"], small["sigma"]
    first = _solve(u[:-3], y[:-3], sigma, predictor=sy.fit_predictor(u[:-3], y[:-3], I))
    pred = sy.fit_predictor(u[3:], y[3:], I)
    cold = _solve(u[3:], y[3:], sigma, predictor=pred)
    warm = _solve(u[3:], y[3:], sigma, predictor=pred, warm_start=first)
    assert warm.start == "warm (window advanced by 3 samples)"
    _same_delta(warm, cold)


def test_several_channels_note_the_solver_without_warm_start():
    rng = np.random.default_rng(3)
    n = 2 * 3 + 40 - 1
    u = rng.choice([-1.0, 1.0], size=(n, 2))
    y = np.column_stack([np.convolve(u[:, 0], [0.0, 0.7, 0.2])[:n], np.convolve(u[:, 1], [0.0, 0.5])[:n]])
    y = y + 0.1 * rng.standard_normal((n, 2))
    kw = dict(backend="structured", progress=False)
    first = uf.subspace_unfalsify(u, y, 3, 0.03, **kw)
    res = uf.subspace_unfalsify(u, y, 3, 0.03 * 1.05, warm_start=first, **kw)
    assert res.start.startswith("cold (warm start not used: solver 'block_barrier' has no warm start")
    assert res.certificate.verify()


@pytest.mark.parametrize("k", [0, 1, 7])
def test_columns_k_onwards_become_columns_0_onwards(case, k):
    """The mapping itself (a solve converges from a wrongly mapped point too, so the δ tests cannot see it)."""
    from unfalsify import subspace

    u, y, n = case["u"], case["y"], case["n"]
    P = uf.SubspaceProblem.from_data(u[k : n + k], y[k : n + k], I, case["sigma"])
    assert subspace._window_shift(case["first"].certificate.problem, P) == k
    state, note = subspace._warm_state(case["first"], P, "column_barrier")
    path = case["first"].solver_stats["state"]["path"]
    resumed = next(c for c in reversed(path) if c["gap"] >= subspace._WARM_GAP)
    assert state["gap"] == resumed["gap"] and state["d"] == resumed["d"]
    assert np.array_equal(state["H"][:, : J - k], resumed["H"][:, k:])
    assert np.all(np.isnan(state["H"][:, J - k :]))
