"""Theorem 7.1 on a record that starts at rest, and the least-norm extension of Markov parameters behind it.

An input that is zero for its first p samples makes T(u) singular.  The answers are checked against routes
that do not use the reduction to the samples after the zeros: the semidefinite program ``min ‖T(h)‖₂`` over all
n Markov parameters subject to the data relation (cvxpy), the generalised eigenvalues of (7.1) on the range of
T(u), and dense norms of the returned h.
"""
import pickle
import warnings

import cvxpy as cp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import unfalsify as uf
from synthesis import DataError
from unfalsify.solvers.extension import minimal_extension
from unfalsify.solvers.toeplitz import block_toeplitz_matrix

from test_unfalsify_mimo import _cvx_gain as _cvx_least_norm  # min ‖T(h)‖₂ s.t. the data relation, in cvxpy


def _dense_norm(h):
    return float(np.linalg.norm(block_toeplitz_matrix(h), 2))


def _record_at_rest(seed, n, p, m=1, l=1):
    """p zero input vectors, then a random input through a two-tap operator; y zero while u is."""
    rng = np.random.default_rng(seed)
    u = np.vstack([np.zeros((p, m)), rng.standard_normal((n - p, m))])
    G = [rng.standard_normal((l, m)), 0.5 * rng.standard_normal((l, m))]
    y = np.array([sum(G[d] @ u[t - d] for d in range(2) if t >= d) for t in range(n)])
    return u, y + np.vstack([np.zeros((p, l)), 0.1 * rng.standard_normal((n - p, l))])


# ---- the least-norm extension ------------------------------------------------------------------------

@settings(max_examples=60, deadline=None)
@given(k=st.integers(1, 12), extra=st.integers(0, 12), shape=st.sampled_from([(1, 1), (2, 1), (1, 2), (3, 1)]),
       seed=st.integers(0, 2**31 - 1), integer=st.booleans())
def test_extension_keeps_the_norm_and_the_given_parameters(k, extra, shape, seed, integer):
    rng = np.random.default_rng(seed)
    h = rng.standard_normal((k,) + shape)
    if integer:  # small integers: repeated singular values
        h = np.round(2 * h)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a failed check would warn
        f = minimal_extension(h, k + extra)
    assert f.shape == (k + extra,) + shape
    np.testing.assert_array_equal(f[:k], h)
    gamma = _dense_norm(h)
    assert _dense_norm(f) <= gamma * (1 + 1e-9) + 1e-300


@pytest.mark.parametrize("h", [[1.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0], [0.0, 0.0, 2.0], [3.0, -1.0, 0.5, 0.25]])
def test_extension_attains_the_cvxpy_minimum(h):
    # the same minimum by an SDP over the free parameters: Parrott's theorem, one entry at a time
    k, n = len(h), len(h) + 3
    free = cp.Variable(n - k)
    d = cp.Variable()
    full = cp.hstack([np.array(h), free])
    T = cp.bmat([[full[r - c] if c <= r else 0.0 for c in range(n)] for r in range(n)])
    cp.Problem(cp.Minimize(d), [cp.bmat([[d * np.eye(n), T.T], [T, d * np.eye(n)]]) >> 0]).solve(solver="CLARABEL")
    f = minimal_extension(np.array(h), n)
    assert _dense_norm(f) == pytest.approx(float(d.value), rel=1e-6, abs=1e-8)
    assert _dense_norm(f) == pytest.approx(_dense_norm(np.array(h)), rel=1e-12, abs=1e-300)


def test_extension_of_a_siso_sequence_is_one_dimensional_and_zeros_stay_zero():
    assert minimal_extension([0.0, 0.0], 4).tolist() == [0.0, 0.0, 0.0, 0.0]
    assert minimal_extension([2.0], 3).tolist() == [2.0, 0.0, 0.0]  # a static gain extends by zeros
    assert minimal_extension([1.0, 2.0], 2).tolist() == [1.0, 2.0]


@pytest.mark.parametrize("h, n, match", [
    ([1.0, 2.0], 1, "n must be"),
    ([1.0, np.nan], 3, "NaN"),
    (np.ones((2, 2, 2)), 3, "one input or one output"),
    (np.ones((2, 2)), 3, "shape"),
])
def test_extension_bad_input_names_the_problem(h, n, match):
    with pytest.raises(DataError, match=match):
        minimal_extension(h, n)


# ---- Theorem 7.1 on a record at rest -------------------------------------------------------------------

@pytest.mark.parametrize("m, l", [(1, 1), (1, 2), (2, 1), (2, 2)])
@pytest.mark.parametrize("seed", [0, 1])
def test_gain_of_a_record_at_rest_equals_the_full_length_program(m, l, seed):
    n, p = 7, 2
    u, y = _record_at_rest(seed, n, p, m, l)
    r = uf.unfalsified_gain_result(u, y, warn=False)
    assert r.leading_zeros == p and np.isfinite(r.gamma)
    assert r.gamma == pytest.approx(_cvx_least_norm(u, y), rel=1e-6)  # over all n parameters, zeros included
    assert r.gamma == uf.unfalsified_gain_result(u[p:], y[p:], warn=False).gamma  # the data after the zeros
    if m == 1:  # h at full length: it reproduces y and has norm γ
        h = r.impulse if l > 1 else r.impulse[:, None, None]
        assert h.shape == (n, l, 1)
        np.testing.assert_allclose(block_toeplitz_matrix(h) @ u[:, 0], y.reshape(-1), atol=1e-10)
        assert _dense_norm(h) == pytest.approx(r.gamma, rel=1e-9)
    else:
        assert r.impulse is None


def test_gain_at_rest_satisfies_71_on_the_range_of_Tu():
    # (7.1) T(y)ᵀT(y) ⪯ γ² T(u)ᵀT(u) with singular T(u): holds at γ, fails just below (SISO, 40 samples)
    u, y = _record_at_rest(3, 40, 6)
    r = uf.unfalsified_gain_result(u, y, warn=False)
    Tu, Ty = uf.toeplitz_matrix(u[:, 0]), uf.toeplitz_matrix(y[:, 0])
    scale = np.linalg.norm(Ty, 2) ** 2
    assert np.linalg.eigvalsh((r.gamma * (1 + 1e-8)) ** 2 * Tu.T @ Tu - Ty.T @ Ty).min() >= -1e-10 * scale
    assert np.linalg.eigvalsh((0.999 * r.gamma) ** 2 * Tu.T @ Tu - Ty.T @ Ty).min() < 0
    assert uf.is_unfalsified(u, y, 1.0001 * r.gamma) and not uf.is_unfalsified(u, y, 0.999 * r.gamma)


def test_output_before_input_is_explained_by_no_causal_operator():
    u, y = _record_at_rest(4, 20, 3)
    y[1] = 1e-6  # the output moves while the input is still zero
    r = uf.unfalsified_gain_result(u, y, warn=False)
    assert r.gamma == np.inf and r.method == "acausal" and r.impulse is None and r.leading_zeros == 3
    # the witness: x = e_{n−1} gives xᵀT(y)ᵀT(y)x = y_0² + … > 0 = γ² xᵀT(u)ᵀT(u)x for every γ
    x = np.zeros(20)
    x[-3] = 1.0
    assert np.linalg.norm(uf.toeplitz_matrix(u[:, 0]) @ x) == 0.0
    assert np.linalg.norm(uf.toeplitz_matrix(y[:, 0]) @ x) > 0.0
    assert not uf.is_unfalsified(u, y, 1e12)


def test_zero_input_and_zero_output_is_the_zero_operator():
    r = uf.unfalsified_gain_result(np.zeros(6), np.zeros(6))
    assert r.gamma == 0.0 and r.method == "zero input" and r.impulse.tolist() == [0.0] * 6
    assert uf.unfalsified_gain(np.zeros((6, 2)), np.zeros((6, 1))) == 0.0
    assert uf.unfalsified_gain(np.zeros(6), np.r_[np.zeros(5), 1.0]) == np.inf


def test_gain_at_rest_result_pickles_and_the_golden_example():
    r = uf.unfalsified_gain_result([0.0, 1.0, 1.0], [0.0, 1.0, 2.0])  # h = [1, 1] after the zero
    assert r.gamma == pytest.approx((1 + np.sqrt(5)) / 2, rel=1e-12)
    assert r.impulse[:2].tolist() == [1.0, 1.0] and r.leading_zeros == 1
    assert pickle.loads(pickle.dumps(r)) == r


def test_extension_above_the_dense_limit_is_proven_not_lanczos_checked():
    # the extension puts most singular values of T(h) at γ: the Lanczos check of its norm had raised
    # ArpackNoConvergence from n = 500 on (n > DENSE_LIMIT = 400), so records at rest of that length crashed
    rng = np.random.default_rng(0)
    h = rng.standard_normal(450) * 0.99 ** np.arange(450)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        f = minimal_extension(h, 500)
    assert np.all(np.isfinite(f)) and np.array_equal(f[:450], h)
    assert _dense_norm(f) == pytest.approx(_dense_norm(h), rel=1e-9)
