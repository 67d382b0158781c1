"""The barrier Hessian and the blocks of F⁻¹ from displacement generators against the definitions and the
dense routes."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import unfalsify as uf
from unfalsify.solvers import arx_barrier, baselines
from unfalsify.solvers.displacement import displacement_hessian, inverse_blocks, schur_cholesky
from unfalsify.solvers.toeplitz import corr_hessian, toeplitz_gram, toeplitz_matrix


def _blocks(h, margin):
    """The blocks of F⁻¹, F = [δI T(h)ᵀ; T(h) δI], δ = (1 + margin)‖T(h)‖₂ (+ a floor for h = 0)."""
    m = h.size
    T = toeplitz_matrix(h)
    d = (1.0 + margin) * np.linalg.norm(T, 2) + 1e-3
    S = np.linalg.inv(np.block([[d * np.eye(m), T.T], [T, d * np.eye(m)]]))
    return S[:m, :m], S[m:, :m], S[m:, m:]


def _trace_formula(S11, S21, S22):
    """``tr(F⁻¹E_aF⁻¹E_b)`` and ``T*(S21 S11)`` summed entry by entry (the definition)."""
    m = S11.shape[0]
    S = np.block([[S11, S21.T], [S21, S22]])
    E = [np.block([[np.zeros((m, m)), toeplitz_matrix(e).T], [toeplitz_matrix(e), np.zeros((m, m))]])
         for e in np.eye(m)]
    H = np.array([[np.trace(S @ Ea @ S @ Eb) for Eb in E] for Ea in E])
    P = S21 @ S11
    x = np.array([np.trace(P, offset=-a) for a in range(m)])
    return H, x


@pytest.mark.parametrize("m", [1, 2, 3, 5, 12, 30])
@pytest.mark.parametrize("margin", [1.0, 1e-2, 1e-5])
def test_equals_the_trace_formula(m, margin):
    h = np.random.default_rng(m).standard_normal(m) / np.sqrt(m)
    blocks = _blocks(h, margin)
    H, x = displacement_hessian(*blocks, cross=True)
    H_ref, x_ref = _trace_formula(*blocks)
    assert np.abs(H - H_ref).max() <= 1e-12 * np.abs(H_ref).max()
    assert np.abs(x - x_ref).max() <= 1e-12 * np.abs(x_ref).max()


def test_a_stack_equals_the_fft_route_entry_by_entry():
    rng = np.random.default_rng(7)
    m, j = 25, 6
    stacks = [_blocks(rng.standard_normal(m) * np.exp(-0.1 * np.arange(m)), 10.0 ** -k) for k in range(j)]
    S11, S21, S22 = (np.stack([s[i] for s in stacks]) for i in range(3))
    H, x = displacement_hessian(S11, S21, S22, cross=True)
    H_fft, x_fft = corr_hessian(S11, S21, S22, m, cross=True)
    assert H.shape == (j, m, m) and x.shape == (j, m)
    for k in range(j):
        assert np.abs(H[k] - H_fft[k]).max() <= 1e-11 * np.abs(H_fft[k]).max()
        assert np.abs(x[k] - x_fft[k]).max() <= 1e-11 * np.abs(x_fft[k]).max()


@settings(max_examples=30, deadline=None)
@given(m=st.integers(1, 40), seed=st.integers(0, 2**31 - 1), log_margin=st.floats(-6.0, 1.0),
       decay=st.floats(0.0, 0.5))
def test_random_blocks_agree_with_the_fft_route(m, seed, log_margin, decay):
    h = np.random.default_rng(seed).standard_normal(m) * np.exp(-decay * np.arange(m))
    blocks = _blocks(h, 10.0**log_margin)
    H, x = displacement_hessian(*blocks, cross=True)
    H_fft, x_fft = corr_hessian(*(b[None] for b in blocks), m, cross=True)
    # relative to the largest entry: the generators' cumulative sums lose digits to cancellation near the
    # boundary of the LMI (measured 2e-12 of the largest entry at m = 1000, margin 1e-4), the FFT's fewer
    assert np.abs(H - H_fft[0]).max() <= 1e-10 * np.abs(H_fft).max()
    assert np.abs(x - x_fft[0]).max() <= 1e-10 * max(np.abs(x_fft).max(), 1e-300)


def test_arx_barrier_gives_the_same_certified_delta_by_either_hessian():
    from experiments.bench.bench_unfalsify import _data

    u, y = _data(160, 3)
    _, rms = uf.arx_least_squares(u, y, 2, 2)

    def solve():
        return uf.arx_unfalsify(u, y, 2, 2, 0.5 * rms, backend="structured", tol=1e-6, progress=False)

    assert arx_barrier._STEP_ROUTE["hessian"] == "displacement"
    a = solve()
    with baselines.fft_barrier_hessian():
        assert arx_barrier._STEP_ROUTE["hessian"] == "fft"
        b = solve()
    assert arx_barrier._STEP_ROUTE["hessian"] == "displacement"  # restored
    _assert_both_certified_and_overlapping(a, b)


def _assert_both_certified_and_overlapping(a, b, tol=1e-6):
    """Both solves certified to ``tol`` (verified from the data) and their brackets overlap."""
    for r in (a, b):
        c = r.certificate
        assert r.status == "optimal" and c.verify() and c.upper_bound - c.lower_bound <= tol * c.upper_bound
    ca, cb = a.certificate, b.certificate
    assert max(ca.lower_bound, cb.lower_bound) <= min(ca.upper_bound, cb.upper_bound) * (1 + 1e-12)


def _random_factors(test):
    """Hypothesis over K = δ²I − T(h)ᵀT(h): order 1–80, δ from 1e-7 to 10 above ‖T(h)‖₂, impulses decaying or not."""
    cases = given(m=st.integers(1, 80), seed=st.integers(0, 2**31 - 1), log_margin=st.floats(-7.0, 1.0),
                  decay=st.floats(0.0, 0.5))
    return settings(max_examples=40, deadline=None)(cases(test))


def _random_factor(m, seed, log_margin, decay):
    """Random impulses h and :func:`_factor` at margin 10^log_margin."""
    h = np.random.default_rng(seed).standard_normal(m) * np.exp(-decay * np.arange(m))
    return (h,) + _factor(h, 10.0**log_margin)


def _factor(h, margin):
    """δ = (1 + margin)‖T(h)‖₂ (+ a floor), T(h) and the lower Cholesky factor of K = δ²I − TᵀT."""
    T = toeplitz_matrix(h)
    d = (1.0 + margin) * np.linalg.norm(T, 2) + 1e-3
    K = d * d * np.eye(h.size) - T.T @ T
    return d, T, np.linalg.cholesky(K), K


@_random_factors
def test_inverse_blocks_equal_the_dense_inverse(m, seed, log_margin, decay):
    h, d, T, L, K = _random_factor(m, seed, log_margin, decay)
    S = np.linalg.inv(np.block([[d * np.eye(m), T.T], [T, d * np.eye(m)]]))  # F⁻¹ by the generic route
    Kinv, A, S22, gens = inverse_blocks(L, h, d, generators=True)
    for got, want in ((d * Kinv, S[:m, :m]), (-A, S[m:, :m]), (S22, S[m:, m:])):
        assert np.abs(got - want).max() <= 1e-9 * np.abs(want).max()
    # the generators are those of the displacements ...
    for (X, G), block, shifted in ((gens.s11, S[:m, :m], lambda M: np.pad(M[:-1, :-1], ((1, 0), (1, 0)))),
                                   (gens.s22, S[m:, m:], lambda M: np.pad(M[1:, 1:], ((0, 1), (0, 1)))),
                                   (gens.s21, S[m:, :m], lambda M: np.pad(M[:-1, :-1], ((1, 0), (1, 0))))):
        assert np.abs(X @ G.T - (block - shifted(block))).max() <= 1e-9 * np.abs(block).max()
    # ... and the Hessian from them equals the 2-D FFT route on the dense blocks
    H, x = displacement_hessian(d * Kinv, -A, S22, cross=True, generators=gens)
    H_fft, x_fft = corr_hessian(S[None, :m, :m], S[None, m:, :m], S[None, m:, m:], m, cross=True)
    assert np.abs(H - H_fft[0]).max() <= 1e-9 * np.abs(H_fft).max()
    assert np.abs(x - x_fft[0]).max() <= 1e-9 * max(np.abs(x_fft).max(), 1e-300)


@_random_factors
def test_schur_factor_equals_lapack_and_serves_inverse_blocks(m, seed, log_margin, decay):
    h, d, T, L, K = _random_factor(m, seed, log_margin, decay)
    R = d * d * np.eye(m) - T @ T.T  # = J K J
    Ls = schur_cholesky(h, d)
    assert Ls is not None
    assert np.abs(np.triu(Ls, 1)).max(initial=0.0) == 0.0 and np.all(np.diag(Ls) > 0)
    # backward error, relative to the generators' size δ² + ‖h‖² (R's entries cancel near the boundary)
    assert np.abs(Ls @ Ls.T - R).max() <= 1e-14 * m * (d * d + h @ h)
    assert np.isclose(2 * np.sum(np.log(np.diag(Ls))), 2 * np.sum(np.log(np.diag(L))), rtol=1e-9, atol=1e-9)
    got = inverse_blocks(Ls, h, d, flipped=True)
    for a, b in zip(got, inverse_blocks(L, h, d)):
        assert np.abs(a - b).max() <= 1e-9 * np.abs(b).max()


@pytest.mark.parametrize("m", [1, 2, 7, 60])
@pytest.mark.parametrize("shrink", [0.999, 0.5])
def test_schur_factor_refuses_where_the_matrix_is_not_positive_definite(m, shrink):
    h = np.random.default_rng(m).standard_normal(m)
    d = shrink * np.linalg.norm(toeplitz_matrix(h), 2)
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.cholesky(d * d * np.eye(m) - toeplitz_matrix(h) @ toeplitz_matrix(h).T)
    assert schur_cholesky(h, d) is None
    assert schur_cholesky(np.array([np.nan] * m), 1.0) is None


def test_inverse_blocks_near_the_boundary_at_a_solver_size():
    """m = 600 (the solver uses the route from m = 300), K within 1e-7 of singular: the blocks agree with the
    dense route (solves against I) to 1e-11 of their largest entry; measured about 1e-13."""
    rng = np.random.default_rng(11)
    m = 600
    h = rng.standard_normal(m) / np.sqrt(m) * np.exp(-3.0 * np.arange(m) / m)
    d, T, L, K = _factor(h, 1e-7)
    assert np.allclose(toeplitz_gram(h), T.T @ T)
    Kinv_ref = np.linalg.solve(K, np.eye(m))
    refs = (Kinv_ref, T @ Kinv_ref, (np.eye(m) + T @ Kinv_ref @ T.T) / d)
    for got, want in zip(inverse_blocks(L, h, d), refs):
        assert np.abs(got - want).max() <= 1e-11 * np.abs(want).max()


def test_arx_barrier_gives_the_same_certified_delta_by_either_block_route(monkeypatch):
    from experiments.bench.bench_unfalsify import _data

    calls, factors = [], []
    monkeypatch.setattr(arx_barrier, "inverse_blocks", lambda *a, **k: calls.append(1) or inverse_blocks(*a, **k))
    monkeypatch.setattr(arx_barrier, "schur_cholesky", lambda *a: factors.append(1) or schur_cholesky(*a))

    n = arx_barrier._STRUCTURED_FROM + 20  # the structured routes apply
    u, y = _data(n, 5)
    _, rms = uf.arx_least_squares(u, y, 2, 2)

    def solve():
        return uf.arx_unfalsify(u, y, 2, 2, 0.5 * rms, backend="structured", tol=1e-6, progress=False)

    a = solve()
    used = len(calls)
    with baselines.dense_inverse_blocks():
        assert arx_barrier._STEP_ROUTE["blocks"] == "dense"
        b = solve()
    assert used == a.solver_stats["newton"] and len(calls) == used  # every step of a, none of b
    assert len(factors) == a.solver_stats["trials"] + b.solver_stats["trials"]  # every K of both solves
    assert arx_barrier._STEP_ROUTE["blocks"] == "generators"  # restored
    _assert_both_certified_and_overlapping(a, b)


def test_arx_barrier_weights_the_noise_barrier_by_the_root_of_the_lmi_order():
    """w = √(2n) for one channel, ν = 2n + w, and the solve certified (the weight also enters the dual point)."""
    from experiments.bench.bench_unfalsify import _data

    u, y = _data(60, 2)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    form = uf.ArxProblem.from_data(u, y, 2, 2, 0.5 * rms).column_form(scaled=True)
    solver = arx_barrier._ArxBarrier(form, tol=1e-6, time_limit=None, progress=False)
    assert solver.w == pytest.approx(np.sqrt(120)) and solver.nbar == pytest.approx(120 + np.sqrt(120))
    assert solver.mu == 3.0
    with baselines.former_routes():
        assert arx_barrier._ArxBarrier(form, tol=1e-6, time_limit=None, progress=False).w == 1.0
    r = uf.arx_unfalsify(u, y, 2, 2, 0.5 * rms, backend="structured", tol=1e-6, progress=False)
    assert r.status == "optimal" and r.certificate.verify()


def test_a_tight_tolerance_is_reached_through_the_structured_routes():
    """From n = _STRUCTURED_FROM the factor of K comes from the Schur algorithm at every step; near the end the
    blocks and the Hessian switch to the dense routes (their rounding would stall the path). Certified to 1e-9."""
    from experiments.bench.bench_unfalsify import _data

    u, y = _data(arx_barrier._STRUCTURED_FROM + 20, 1)
    _, rms = uf.arx_least_squares(u, y, 2, 2)
    r = uf.arx_unfalsify(u, y, 2, 2, 0.5 * rms, backend="structured", tol=1e-9, progress=False)
    c = r.certificate
    assert r.status == "optimal" and c.verify() and c.upper_bound - c.lower_bound <= 1e-9 * c.upper_bound
