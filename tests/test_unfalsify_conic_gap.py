"""A conic solver's "optimal" that its own certificate does not pin down is warned.

Measured (1 × 2 record below, noise free, output nonlinearity 0.3 tanh): the cvxpy backend's (7.5) with L optimised
reported δ = 0.012424 "optimal" without a word, 1.3 % above the least δ the structured solver proves (its bracket
[0.0122610, 0.0122610]; ``eliminate_L=True`` gives the same); the cvxpy result's own certificate brackets it only to
[0.01133, 0.01242], a relative gap of 0.088.  The δ is attained (an upper bound) but not the minimum.
"""
import warnings

import numpy as np
import pytest
import scipy.signal

import unfalsify as uf

U_SIGNS = "+------+-+---++++-+++++--+--+++-+-"


def _record():
    u = np.array([1.0 if c == "+" else -1.0 for c in U_SIGNS])
    y = np.column_stack([scipy.signal.lfilter([0.0, 0.064, -0.344], np.poly([-0.738, 0.409]), u),
                         scipy.signal.lfilter([0.0, 0.073, 0.011], np.poly([-0.261, 0.079]), u)])
    return u, y + 0.3 * np.tanh(y)


def test_a_wide_bracket_behind_an_optimal_status_is_warned():
    u, y = _record()
    A, _, Yf = uf.subspace_data(u, y, 3)
    res = Yf - np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T @ A
    sigma = 0.1 * np.linalg.norm(res) / np.sqrt(res.size)
    with pytest.warns(uf.SolverWarning, match="relative gap"):
        r = uf.subspace_unfalsify(u, y, 3, sigma)
    exact = uf.subspace_unfalsify(u, y, 3, sigma, backend="structured", progress=False)
    assert r.status == "optimal" and r.certificate.verify()
    assert r.certificate.relative_gap > 0.02 and r.delta > exact.certificate.upper_bound * 1.005  # the case itself
    with warnings.catch_warnings():
        warnings.simplefilter("error", uf.SolverWarning)  # a tight bracket says nothing
        tight = uf.subspace_unfalsify(u, y, 3, sigma, eliminate_L=True)
    assert tight.delta == pytest.approx(exact.delta, rel=1e-5)
