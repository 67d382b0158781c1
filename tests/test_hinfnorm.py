"""Certified discrete H∞ norm: synthesis.hinf_norm (bracket) and synthesis.norm_below (proof)."""
import control as ct
import numpy as np
import pytest

from synthesis import DataError, NormBracket, NormTest, hinf_norm, norm_below


def _resonance(zeta, w0, d=0.1):
    """Second-order discrete resonance, poles r·e^{±j w0 sqrt(1-ζ²)}, r = e^{-ζ w0}."""
    r, wd = np.exp(-zeta * w0), w0 * np.sqrt(1 - zeta ** 2)
    A = np.array([[2 * r * np.cos(wd), -r * r], [1.0, 0.0]])
    return ct.ss(A, [[1.0], [0.0]], [[0.3, 0.2]], [[d]], 1.0)


def _dense_gains(G, w):
    A, B, C, D = (np.asarray(M, float) for M in (G.A, G.B, G.C, G.D))
    z = np.exp(1j * np.asarray(w))
    M = z[:, None, None] * np.eye(A.shape[0])[None] - A[None]
    H = C[None] @ np.linalg.solve(M, np.broadcast_to(B, (z.size,) + B.shape)) + D[None]
    return np.linalg.svd(H, compute_uv=False)[:, 0]


def _reference(G, n=200_000):
    """2·10⁵-point uniform grid (a lower bound) and, separately, a fine local search at the pole angles."""
    w = np.linspace(0, np.pi, n)
    grid = float(_dense_gains(G, w).max())
    ang = np.abs(np.angle(np.linalg.eigvals(np.asarray(G.A, float))))
    fine = max(float(_dense_gains(G, a + np.linspace(-2e-4, 2e-4, 40001)).max()) for a in ang)
    return grid, max(grid, fine)


@pytest.mark.parametrize("zeta", [1e-2, 1e-3, 1e-4])
@pytest.mark.parametrize("w0", [0.3, 1.7, 3.0])
def test_lightly_damped_peak_between_grid_points(zeta, w0):
    G = _resonance(zeta, w0)
    b = hinf_norm(G)
    grid, fine = _reference(G)
    assert b.stable and b.reason == ""
    assert b.lower <= b.upper and b.gap < 1e-7
    assert fine <= b.upper  # the proven side bounds the best reference
    assert b.lower >= fine * (1 - 1e-9)  # and the attained side is at the peak
    assert _dense_gains(G, [b.frequency])[0] == pytest.approx(b.lower, rel=1e-9)  # attained where reported
    if zeta <= 1e-3:
        assert grid < b.lower * (1 - 1e-8)  # the 2·10⁵-point grid misses the peak: it is no upper bound


@pytest.mark.parametrize("dist", [1e-6, 1e-7])
def test_pole_within_1e6_of_unit_circle(dist):
    # stable (1 − |p| = dist) with a huge norm: reported, and the bracket is still proven
    p = 1 - dist
    G = ct.ss([[p, 0.0], [0.0, 0.5]], [[1.0], [1.0]], [[1.0, 1.0]], [[0.0]], 0.1)
    b = hinf_norm(G)
    exact = 1 / dist + 2.0  # peak at w = 0: 1/(1 − p) + 1/(1 − 0.5)
    assert b.stable and b.lower <= exact * (1 + 1e-9) and exact <= b.upper
    assert b.gap < 1e-6
    assert len(b.near_poles) == 1 and abs(b.near_poles[0] - p) < 1e-12
    assert norm_below(G, b.upper * (1 + 1e-9))
    assert not norm_below(G, b.lower * (1 - 1e-9))
    # control.norm's failure mode is not ours
    assert np.isfinite(b.upper)


def test_lightly_damped_near_circle_complex_pair():
    G = _resonance(3e-7, 0.8, d=0.0)  # 1 − |p| ≈ 2.4e-7
    b = hinf_norm(G)
    _, fine = _reference(G)
    assert b.near_poles and fine <= b.upper and b.lower >= fine * (1 - 1e-7)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(6))
def test_mimo_bracket_contains_reference(seed):
    rng = np.random.default_rng(seed)
    n, p, m = 6, 2 + seed % 2, 3 - seed % 2
    A = rng.standard_normal((n, n))
    A *= (1 - 10.0 ** -(2 + seed % 3)) / np.max(np.abs(np.linalg.eigvals(A)))
    G = ct.ss(A, rng.standard_normal((n, m)), rng.standard_normal((p, n)), rng.standard_normal((p, m)), 1.0)
    b = hinf_norm(G)
    _, fine = _reference(G)
    assert fine <= b.upper and b.lower >= fine * (1 - 1e-8)
    assert b.gap < 1e-6


def test_pencil_test_agrees_with_bisection_on_the_bracket():
    G = _resonance(1e-3, 1.1)
    b = hinf_norm(G)
    lo, hi = 0.5 * b.lower, 2.0 * b.upper
    assert not norm_below(G, lo) and norm_below(G, hi)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if norm_below(G, mid):
            hi = mid
        else:
            lo = mid
    # bisection on the proof converges into the bracket (up to its rounding allowance)
    assert b.lower * (1 - 1e-12) <= hi <= b.upper * (1 + 1e-9)
    t = norm_below(G, b.lower * (1 - 1e-6))
    assert not t and t.lower >= t.gamma and "attained" in t.reason


def test_unstable_and_marginal_systems():
    b = hinf_norm(ct.tf([1], [1, -1.5], 0.1))
    assert not b.stable and b.upper == np.inf and b.lower == np.inf and "unstable" in b.reason
    assert b.gap == np.inf and "inf" in str(b)
    b = hinf_norm(ct.ss([[1.0]], [[1.0]], [[1.0]], [[0.0]], 0.1))
    assert not b.stable and b.upper == np.inf and "unit circle" in b.reason
    t = norm_below(ct.ss([[1.0]], [[1.0]], [[1.0]], [[0.0]], 0.1), 1e6)
    assert not t and "unit circle" in t.reason


def test_static_zero_and_simple_systems():
    b = hinf_norm(ct.ss([], [], [], [[3.0, 4.0]], 0.1))
    assert b.lower == pytest.approx(5.0) and b.upper >= 5.0 and b.gap < 1e-7
    z = hinf_norm(ct.ss([[0.5]], [[0.0]], [[1.0]], [[0.0]], 1.0))
    assert z.lower == z.upper == 0.0 and z.gap == 0.0
    b = hinf_norm(ct.tf([1], [1, -0.5], 1))  # TransferFunction accepted: peak 2 at w = 0
    assert b.lower <= 2.0 <= b.upper and b.frequency == pytest.approx(0.0, abs=1e-6)
    assert isinstance(b, NormBracket) and isinstance(norm_below(ct.tf([1], [1, -0.5], 1), 2.1), NormTest)
    assert norm_below(ct.tf([1], [1, -0.5], 1), 2.0 * (1 + 1e-6))
    assert not norm_below(ct.tf([1], [1, -0.5], 1), 2.0)


def test_bad_input_raises_data_error():
    with pytest.raises(DataError, match="continuous"):
        hinf_norm(ct.tf([1], [1, 1]))
    with pytest.raises(DataError, match="continuous"):
        norm_below(ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]]), 1.0)
    with pytest.raises(DataError, match="NaN"):
        hinf_norm(ct.ss([[np.nan]], [[1.0]], [[1.0]], [[0.0]], 1.0))
    with pytest.raises(DataError, match="not proper"):
        hinf_norm(ct.tf([1, 2, 3], [1, 0.5], 0.1))
    with pytest.raises(DataError):
        hinf_norm(np.eye(2))
    with pytest.raises(DataError, match="tol"):
        hinf_norm(ct.tf([1], [1, -0.5], 1), tol=0.0)
    with pytest.raises(DataError, match="gamma"):
        norm_below(ct.tf([1], [1, -0.5], 1), -1.0)


@pytest.mark.parametrize("n_grid", [0, -5, 1, 10.5, "10", True])
def test_n_grid_must_be_a_count_of_at_least_two(n_grid):
    """int() had parsed "10" and cut 10.5, 0 and -5 had silently become 2; peak_gain had raised numpy's
    ValueError/TypeError."""
    from synthesis import bounded_real_certificate, peak_gain

    G = ct.tf([1], [1, -0.5], 1)
    for call in (lambda: hinf_norm(G, n_grid=n_grid), lambda: norm_below(G, 3.0, n_grid=n_grid),
                 lambda: bounded_real_certificate(G, 3.0, n_grid=n_grid), lambda: peak_gain(G, n_grid=n_grid)):
        with pytest.raises(DataError, match="n_grid must be an integer ≥ 2"):
            call()
    assert hinf_norm(G, n_grid=2).lower == pytest.approx(2.0)


def test_a_system_without_outputs_has_norm_zero():
    """peak_gain had raised an IndexError; all four agree with hinf_norm's 0.  (python-control itself refuses to
    build a system with states and no inputs, so only the no-output case can reach the norms.)"""
    from synthesis import bounded_real_certificate, peak_gain

    E = ct.ss([[0.5]], [[1.0]], np.zeros((0, 1)), np.zeros((0, 1)), 1.0)
    assert E.noutputs == 0
    assert peak_gain(E) == 0.0
    assert hinf_norm(E).upper == 0.0
    assert norm_below(E, 1.0)
    cert = bounded_real_certificate(E, 1.0)
    assert cert and "empty system" in cert.reason


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_badly_scaled_realisation_gives_the_bracket_of_its_well_scaled_twin(seed):
    """State units over 8 decades: the same transfer function, so the same norm; computed in an exactly
    balanced realisation, the bracket stays tight and its attained side is not inflated by rounding."""
    rng = np.random.default_rng(seed)
    n = 20
    A = rng.standard_normal((n, n))
    A *= 0.95 / max(abs(np.linalg.eigvals(A)))
    B, C, D = rng.standard_normal((n, 2)), rng.standard_normal((2, n)), 0.3 * rng.standard_normal((2, 2))
    t = 10.0 ** rng.uniform(-4, 4, n)
    twin = hinf_norm(ct.ss(A, B, C, D, 1.0))
    scaled = hinf_norm(ct.ss(A * (t[:, None] / t[None, :]), B * t[:, None], C / t[None, :], D, 1.0))
    assert twin.gap < 1e-7 and scaled.gap < 1e-7
    assert scaled.lower == pytest.approx(twin.lower, rel=1e-9)
    assert scaled.lower <= twin.upper * (1 + 1e-12) and twin.lower <= scaled.upper * (1 + 1e-12)
