"""The minimax engine against independent routes: normal-equation Schur complement, full KKT solve,
Hessian inertia and the saddle inequalities themselves."""
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from synthesis import (DataError, InfeasibleGammaError, NearGammaMinWarning, feasibility_threshold,
                       minimax_gamma_min, solve_minimax)


def _maps(seed, nz=30, nd=8, nu=6, nx=5):
    rng = np.random.default_rng(seed)
    return rng.standard_normal((nz, nd)), rng.standard_normal((nz, nu)), rng.standard_normal((nz, nx))


def _hessian(Md, Mu, gamma):
    M = np.hstack([Md, Mu])
    Hs = M.T @ M
    nd = Md.shape[1]
    Hs[:nd, :nd] -= gamma**2 * np.eye(nd)
    return Hs


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_gamma_min_equals_schur_complement_eigenvalue(seed):
    Md, Mu, _ = _maps(seed)
    # (3.29)-(3.30): largest eigenvalue of Md'Md - Md'Mu (Mu'Mu)^-1 Mu'Md
    S = Md.T @ Md - Md.T @ Mu @ np.linalg.solve(Mu.T @ Mu, Mu.T @ Md)
    ref = np.sqrt(np.linalg.eigvalsh(S).max())
    assert np.isclose(minimax_gamma_min(Md, Mu), ref, rtol=1e-10)


@pytest.mark.parametrize("seed", [0, 3])
def test_gains_equal_full_kkt_solve(seed):
    Md, Mu, Mx = _maps(seed)
    g = 1.3 * minimax_gamma_min(Md, Mu)
    sol = solve_minimax(Md, Mu, Mx, g)
    # (3.31): [d; u] = -Hess^-1 [Md Mu]' Mx
    ref = -np.linalg.solve(_hessian(Md, Mu, g), np.hstack([Md, Mu]).T @ Mx)
    assert np.allclose(sol.d_gain, ref[: Md.shape[1]], rtol=1e-9, atol=1e-11)
    assert np.allclose(sol.u_gain, ref[Md.shape[1]:], rtol=1e-9, atol=1e-11)
    assert sol.gamma == g and np.isclose(sol.gamma_min, minimax_gamma_min(Md, Mu))


def test_saddle_inertia_switches_at_gamma_min():
    Md, Mu, _ = _maps(7)
    gm = minimax_gamma_min(Md, Mu)
    for ratio, ok in [(1.001, True), (0.999, False)]:
        ev = np.linalg.eigvalsh(_hessian(Md, Mu, ratio * gm))
        n_pos, n_neg = int(np.sum(ev > 0)), int(np.sum(ev < 0))
        assert ((n_pos, n_neg) == (Mu.shape[1], Md.shape[1])) is ok


def test_saddle_point_inequalities():
    Md, Mu, Mx = _maps(11)
    g = 1.2 * minimax_gamma_min(Md, Mu)
    sol = solve_minimax(Md, Mu, Mx, g)
    rng = np.random.default_rng(0)
    x = rng.standard_normal(Mx.shape[1])
    d0, u0 = sol.d_gain @ x, sol.u_gain @ x

    def J(d, u):
        z = Md @ d + Mu @ u + Mx @ x
        return z @ z - g**2 * d @ d

    J0 = J(d0, u0)
    for _ in range(20):
        assert J(d0, u0 + rng.standard_normal(u0.size)) > J0  # u is a minimiser
        assert J(d0 + rng.standard_normal(d0.size), u0) < J0  # d is a maximiser


def test_infeasible_gamma_and_near_warning():
    Md, Mu, Mx = _maps(4)
    gm = minimax_gamma_min(Md, Mu)
    with pytest.raises(InfeasibleGammaError, match=f"{gm:.6g}") as err:
        solve_minimax(Md, Mu, Mx, gm)
    assert err.value.gamma_min == gm  # the same computation, not an approximation of it
    assert gm < err.value.threshold < gm * (1 + 1e-10)
    assert isinstance(err.value, ValueError)
    with pytest.raises(InfeasibleGammaError):
        solve_minimax(Md, Mu, Mx, 0.5 * gm)
    with pytest.warns(NearGammaMinWarning):
        solve_minimax(Md, Mu, Mx, 1.02 * gm)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        solve_minimax(Md, Mu, Mx, 1.04 * gm)


def test_infinite_gamma_is_least_squares():
    Md, Mu, Mx = _maps(5)
    sol = solve_minimax(Md, Mu, Mx, np.inf)
    assert np.all(sol.d_gain == 0)
    assert np.allclose(sol.u_gain, -np.linalg.lstsq(Mu, Mx, rcond=None)[0])


def test_no_disturbance_channel():
    _, Mu, Mx = _maps(6)
    Md = np.zeros((Mu.shape[0], 0))
    assert minimax_gamma_min(Md, Mu) == 0.0
    sol = solve_minimax(Md, Mu, Mx, 1.0)
    assert np.allclose(sol.u_gain, -np.linalg.lstsq(Mu, Mx, rcond=None)[0])


def test_bad_maps():
    Md, Mu, Mx = _maps(8)
    Mu_def = Mu.copy()
    Mu_def[:, 1] = Mu_def[:, 0]
    with pytest.raises(DataError, match="full column rank"):
        minimax_gamma_min(Md, Mu_def)
    Mx_nan = Mx.copy()
    Mx_nan[0, 0] = np.nan
    with pytest.raises(DataError, match="NaN"):
        solve_minimax(Md, Mu, Mx_nan, 10.0)


def test_complex_and_text_maps_are_refused():
    """A complex map had lost its imaginary part with only a ComplexWarning; text had raised numpy's bare
    ValueError."""
    Md, Mu, Mx = _maps(8)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # refused before numpy's ComplexWarning
        with pytest.raises(DataError, match=r"M_d is complex.*take the real part"):
            minimax_gamma_min(Md + 1j, Mu)
        with pytest.raises(DataError, match="M_u is complex"):
            solve_minimax(Md, Mu.astype(complex), Mx, 10.0)
        with pytest.raises(DataError, match="M_x is complex"):
            solve_minimax(Md, Mu, 1j * Mx, 10.0)
    with pytest.raises(DataError, match=r"M_d must be real numbers, not text \('a'\)"):
        minimax_gamma_min("a", Mu)


def test_feasibility_threshold_checks_its_arguments():
    """A NaN gamma_min had given a NaN threshold, '2' a TypeError, maps of different heights a number."""
    Md, Mu = np.array([[1.0], [2.0]]), np.array([[1.0], [0.0]])
    for bad in (np.nan, "2", -1.0, np.inf):
        with pytest.raises(DataError, match="gamma_min must be a finite number >= 0"):
            feasibility_threshold(Md, Mu, bad)
    with pytest.raises(DataError, match="same number of rows"):
        feasibility_threshold(np.ones((3, 1)), Mu, 1.0)
    assert feasibility_threshold(Md, Mu, 2.0) == feasibility_threshold(Md, Mu, np.float64(2.0)) > 2.0


def test_non_numeric_gamma_is_named():
    Md, Mu, Mx = np.eye(3)[:, :1], np.eye(3)[:, 1:], np.ones((3, 2))
    for bad in ("2.0", None, True):
        with pytest.raises(DataError, match="gamma must be a real number"):
            solve_minimax(Md, Mu, Mx, bad)


def test_maps_with_different_row_counts_are_refused():
    """A (3, 2) M_d against a 2-row M_u used to be reshaped to (2, 3) and give a wrong γ_min."""
    with pytest.raises(DataError, match="same number of rows"):
        minimax_gamma_min(np.ones((3, 2)), np.eye(2))
    with pytest.raises(DataError, match="M_x"):
        solve_minimax(np.ones((2, 1)), np.eye(2), np.ones((3, 2)), 5.0)
    # a 1-D M_d of the right length is one disturbance column
    assert minimax_gamma_min(np.array([0.0, 0.0, 2.0]), np.eye(3)[:, :2]) == pytest.approx(2.0)


def _random_map(seed, nz, nd, nu, nx, scale):
    """A random performance map; ``scale`` spreads the column norms over many decades."""
    rng = np.random.default_rng(seed)
    Md, Mu, Mx = (rng.standard_normal((nz, k)) for k in (nd, nu, nx))
    Md = Md * np.logspace(0, scale, nd)[None, :]
    Mu = Mu * np.logspace(0, -scale, nu)[None, :]
    return Md, Mu, Mx


_maps_strategy = st.tuples(
    st.integers(0, 2**32 - 1),       # seed
    st.integers(1, 12),              # extra rows over nu (M_u must have full column rank)
    st.integers(1, 10),              # nd
    st.integers(1, 10),              # nu
    st.integers(1, 6),               # nx
    st.floats(0.0, 4.0),             # decades of column scaling
)


@settings(max_examples=150, deadline=None)
@given(_maps_strategy)
def test_gamma_min_and_next_float_are_refused(args):
    """γ = γ_min and γ = nextafter(γ_min, ∞) are infeasible, whatever the map (the bug: one ulp apart)."""
    seed, extra, nd, nu, nx, scale = args
    Md, Mu, Mx = _random_map(seed, nu + extra, nd, nu, nx, scale)
    gm = minimax_gamma_min(Md, Mu)
    for g in (gm, np.nextafter(gm, np.inf), 0.5 * gm):
        with pytest.raises(InfeasibleGammaError) as err:
            solve_minimax(Md, Mu, Mx, g)
        assert err.value.gamma_min == gm
    # the policy route decides with the same numbers: a policy returning γ_min is refused too
    with pytest.raises(InfeasibleGammaError):
        solve_minimax(Md, Mu, Mx, lambda g0: g0)


@settings(max_examples=150, deadline=None)
@given(_maps_strategy)
def test_accepted_levels_have_a_true_saddle(args):
    """Any accepted γ just above the threshold gives gains whose Hessian has the saddle inertia (3.29):
    an independent eigenvalue check of γ²I − M̃_dᵀM̃_d on the explicit projection, no singular solve."""
    seed, extra, nd, nu, nx, scale = args
    Md, Mu, Mx = _random_map(seed, nu + extra, nd, nu, nx, scale)
    gm = minimax_gamma_min(Md, Mu)
    thr = feasibility_threshold(Md, Mu, gm)
    g = np.nextafter(thr, np.inf) * (1 + 1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NearGammaMinWarning)
        sol = solve_minimax(Md, Mu, Mx, g)
    assert np.all(np.isfinite(sol.u_gain)) and np.all(np.isfinite(sol.d_gain))
    # independent route: projector by lstsq, not QR; smallest eigenvalue of the Schur complement
    P = Mu @ np.linalg.lstsq(Mu, np.eye(Mu.shape[0]), rcond=None)[0]
    Mdt = Md - P @ Md
    sv = np.linalg.svd(Mdt, compute_uv=False)
    assert sv[0] < g  # γ² − σ_max² > 0: the maximisation over d is strictly concave
    # and the gains solve the stationarity condition (3.31) of the full Hessian to working accuracy
    H = _hessian(Md, Mu, g)
    rhs = -np.hstack([Md, Mu]).T @ Mx
    res = H @ np.vstack([sol.d_gain, sol.u_gain]) - rhs
    scale_ = np.linalg.norm(H, 2) * np.linalg.norm(np.vstack([sol.d_gain, sol.u_gain]), 2) + np.linalg.norm(rhs, 2)
    assert np.linalg.norm(res, 2) <= 1e-6 * scale_


def test_threshold_is_relative_to_the_accuracy_of_gamma_min():
    """τ grows with the map's size and norm and is a few hundred ulps of γ_min on a normal map."""
    Md, Mu, _ = _maps(4)
    gm = minimax_gamma_min(Md, Mu)
    thr = feasibility_threshold(Md, Mu, gm)
    k = (thr - gm) / (gm * np.finfo(float).eps)
    assert 1 < k < 1e4
    assert feasibility_threshold(10 * Md, Mu, 10 * gm) == pytest.approx(10 * thr, rel=1e-12)


# ------------------------------------------------------------------ routes of the fast engine (issue 12)
def test_gamma_min_equals_the_largest_singular_value_of_the_explicit_projection():
    """γ_min from λ_max(XᵀX) equals σ_max((I − P_u) M_d) from an SVD of the projection built by lstsq."""
    for seed in range(4):
        Md, Mu, _ = _random_map(seed, 128, 64, 64, 3, 2.0)
        P = Mu @ np.linalg.lstsq(Mu, np.eye(Mu.shape[0]), rcond=None)[0]
        ref = np.linalg.svd(Md - P @ Md, compute_uv=False)[0]
        assert minimax_gamma_min(Md, Mu) == pytest.approx(ref, rel=1e-12)


@pytest.mark.parametrize("ratio, route", [(1.3, "cholesky"), (1.03, "cholesky"), (1.02, "svd"), (np.inf, "none")])
def test_disturbance_gain_route_follows_the_level(ratio, route):
    Md, Mu, Mx = _maps(21)
    g = ratio * minimax_gamma_min(Md, Mu)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NearGammaMinWarning)
        sol = solve_minimax(Md, Mu, Mx, g)
    assert sol.route == route


@settings(max_examples=60, deadline=None)
@given(_maps_strategy, st.floats(1.03, 5.0))
def test_cholesky_and_svd_routes_give_the_same_gains(args, ratio):
    """The two routes of the disturbance gain, forced on the same factorisation, agree to 1e-10."""
    from synthesis.minimax import _gains, _saddle

    seed, extra, nd, nu, nx, scale = args
    Md, Mu, Mx = _random_map(seed, nu + extra, nd, nu, nx, scale)
    sd = _saddle(Md, Mu, Mx)
    g = ratio * sd.gamma_min
    if not g > sd.threshold:
        return  # γ_min = 0 (no disturbance reaches z beyond range(M_u))
    uc, dc, rc = _gains(sd, g, route="cholesky")
    us, ds, rs = _gains(sd, g, route="svd")
    assert (rc, rs) == ("cholesky", "svd")
    for a, b in ((uc, us), (dc, ds)):
        assert np.linalg.norm(a - b) <= 1e-10 * max(np.linalg.norm(b), 1e-300)


def test_unknown_route_is_refused():
    from synthesis.minimax import _gains, _saddle

    Md, Mu, Mx = _maps(22)
    sd = _saddle(Md, Mu, Mx)
    with pytest.raises(ValueError, match="route"):
        _gains(sd, 2 * sd.gamma_min, route="qr")
