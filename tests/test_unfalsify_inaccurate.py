"""A conic solver stopped early: its δ must never be reported outside the bracket its own certificate proves."""
import warnings

import cvxpy as cp
import numpy as np
import pytest

import unfalsify as uf
from unfalsify.exceptions import SolverWarning

pytestmark = pytest.mark.skipif("SCS" not in cp.installed_solvers(), reason="needs the SCS solver")


def _record(n=30):
    rng = np.random.default_rng(0)
    u = np.sign(rng.standard_normal(n))
    return u, np.convolve(u, [0.0, 0.5, 0.3])[:n] + 0.05 * rng.standard_normal(n)


@pytest.mark.parametrize("iters", [2, 20])
def test_arx_delta_outside_its_bracket_is_nan_and_warned(iters):
    u, y = _record()
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    exact = uf.arx_unfalsify(u, y, 2, 2, 0.5 * rms).delta  # Clarabel, optimal
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = uf.arx_unfalsify(u, y, 2, 2, 0.5 * rms, solver="SCS", solver_options={"max_iters": iters})
    c = r.certificate
    assert r.status == "optimal_inaccurate"
    assert c.lower_bound <= exact * (1 + 1e-6) and exact <= c.upper_bound * (1 + 1e-6)  # the bracket holds
    assert np.isnan(r.delta) and np.isnan(c.delta)  # the solver's own δ lies outside it: no δ is reported
    assert any(issubclass(w.category, SolverWarning) and "lies below the bracket" in str(w.message) for w in caught)


def test_delta_inside_its_bracket_is_kept():
    u, y = _record()
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SolverWarning)
        r = uf.arx_unfalsify(u, y, 2, 2, 0.5 * rms, solver="SCS", solver_options={"eps_abs": 1e-9, "eps_rel": 1e-9})
    c = r.certificate
    assert np.isfinite(r.delta) and c.lower_bound * (1 - 1e-6) <= r.delta <= c.upper_bound * (1 + 1e-6)


def test_subspace_delta_outside_its_bracket_is_nan():
    rng = np.random.default_rng(1)
    u = np.sign(rng.standard_normal(40))
    y = np.convolve(u, [0.0, 0.5, 0.3])[:40] + 0.05 * rng.standard_normal(40)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = uf.subspace_unfalsify(u, y, 3, 0.02, solver="SCS", solver_options={"max_iters": 5})
    c = r.certificate
    inside = c.lower_bound <= c.delta <= c.upper_bound
    assert np.isnan(r.delta) != inside
    if not inside:
        assert any("bracket its own point and dual certify" in str(w.message) for w in caught)
