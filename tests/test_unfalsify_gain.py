"""Theorem 7.1 (unfalsified gain) and the Toeplitz numerics behind it."""
import warnings

import numpy as np
import pytest
import scipy.linalg
import scipy.signal

import unfalsify as uf
from synthesis import DataError
from unfalsify.solvers.toeplitz import DENSE_LIMIT


def _well_conditioned_input(rng, n):
    """Dominant first sample => u(q) minimum phase => T(u) well conditioned."""
    u = 0.3 * rng.standard_normal(n)
    u[0] = 2.0
    return u


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_gain_equals_generalised_eigenvalue(seed):
    # γ² = λ_max of the pencil (T(y)ᵀT(y), T(u)ᵀT(u)) (7.1), an independent route (seed-fixed data)
    rng = np.random.default_rng(seed)
    n = 10
    u = _well_conditioned_input(rng, n)
    y = rng.standard_normal(n)
    Tu, Ty = uf.toeplitz_matrix(u), uf.toeplitz_matrix(y)
    lam = scipy.linalg.eigh(Ty.T @ Ty, Tu.T @ Tu, eigvals_only=True)
    res = uf.unfalsified_gain_result(u, y)
    assert res.gamma == pytest.approx(np.sqrt(lam[-1]), rel=1e-9)
    assert uf.unfalsified_gain(u, y) == res.gamma
    # (7.1) holds at γ and fails just below it
    g = res.gamma
    assert np.linalg.eigvalsh((g * (1 + 1e-9)) ** 2 * Tu.T @ Tu - Ty.T @ Ty).min() >= -1e-9
    assert np.linalg.eigvalsh((0.99 * g) ** 2 * Tu.T @ Tu - Ty.T @ Ty).min() < 0
    assert uf.is_unfalsified(u, y, 1.0001 * g)
    assert not uf.is_unfalsified(u, y, 0.99 * g)


def test_noise_free_lti_data_recovers_markov_parameters_and_hinf_bound():
    # y = G u with G stable: h = Markov parameters of G and, by Carathéodory–Fejér, γ ≤ ‖G‖∞
    rng = np.random.default_rng(3)
    n = 60
    b, a = [0.0, 0.5, 0.2], [1.0, -0.6, 0.2]
    u = np.sign(rng.standard_normal(n))
    y = scipy.signal.lfilter(b, a, u)
    res = uf.unfalsified_gain_result(u, y, warn=False)
    imp = scipy.signal.lfilter(b, a, np.r_[1.0, np.zeros(n - 1)])
    # rounding of y (1e-16) is amplified by T(u)⁻¹ (cond ≫ 1e8 here): the exact deconvolution of the
    # rounded data drifts from the true Markov parameters late in the window, by ~1e-7 at n = 60
    np.testing.assert_allclose(res.impulse[:30], imp[:30], atol=1e-12)
    np.testing.assert_allclose(res.impulse, imp, atol=1e-5)
    w = np.linspace(0, np.pi, 4001)
    _, H = scipy.signal.freqz(b, a, worN=w)
    hinf = np.abs(H).max()
    assert res.gamma <= hinf * (1 + 1e-5)
    assert res.gamma >= np.linalg.norm(y) / np.linalg.norm(u)  # γ ≥ ‖T(h)u‖/‖u‖
    assert res.gamma > 0.9 * hinf  # long window: close to the H∞ norm


def test_dense_and_lanczos_norm_agree():
    rng = np.random.default_rng(4)
    for n in (50, DENSE_LIMIT + 100):
        h = rng.standard_normal(n) * 0.9 ** np.arange(n)
        d = uf.toeplitz_norm(h, method="dense")
        lz = uf.toeplitz_norm(h, method="lanczos")
        assert lz == pytest.approx(d, rel=1e-10)
    # a huge dynamic range (growing h, as from an unstable T(u)⁻¹) is fine too
    h = 1.3 ** np.arange(120) * rng.standard_normal(120)
    assert uf.toeplitz_norm(h, method="lanczos") == pytest.approx(uf.toeplitz_norm(h, method="dense"), rel=1e-10)


def test_toeplitz_norm_of_zero_and_scalar():
    assert uf.toeplitz_norm(np.zeros(5)) == 0.0
    assert uf.toeplitz_norm([-3.0]) == 3.0
    # T(δ e₂) is δ times a shift: norm |δ|
    assert uf.toeplitz_norm([0.0, 0.25, 0.0, 0.0]) == pytest.approx(0.25)


def test_exact_and_float_deconvolution_agree_and_reproduce_y():
    rng = np.random.default_rng(5)
    n = 80
    u = np.sign(rng.standard_normal(n))
    y = rng.standard_normal(n)
    he = uf.deconvolve(u, y, exact=True)
    hf = uf.deconvolve(u, y)
    np.testing.assert_allclose(hf, he, rtol=1e-8, atol=1e-12 * np.abs(he).max())
    # T(u) h = y, checked as a convolution (h * u)[:n] = y, relative to the size of the terms
    conv = np.convolve(he, u)[:n]
    assert np.abs(conv - y).max() <= 1e-12 * np.abs(he).max() * n


def test_toeplitz_cond_matches_numpy_for_small_n():
    rng = np.random.default_rng(6)
    for n in (5, 20, 30):
        u = np.sign(rng.standard_normal(n))
        assert uf.toeplitz_cond(u) == pytest.approx(np.linalg.cond(uf.toeplitz_matrix(u)), rel=1e-6)
    assert uf.toeplitz_cond([0.0, 1.0]) == np.inf


def test_ill_conditioned_input_warns_and_well_conditioned_does_not():
    rng = np.random.default_rng(7)
    n = 120
    u = np.sign(rng.standard_normal(n))
    y = rng.standard_normal(n)
    assert uf.toeplitz_cond(u) > uf.COND_WARN  # measured ≫ 1e8 for a ±1 PRBS this long
    with pytest.warns(uf.IllConditionedWarning):
        res = uf.unfalsified_gain_result(u, y)
    assert not res.well_conditioned
    u2 = _well_conditioned_input(rng, n)
    with warnings.catch_warnings():
        warnings.simplefilter("error", uf.IllConditionedWarning)
        res2 = uf.unfalsified_gain_result(u2, y)
    assert res2.well_conditioned and np.isfinite(res2.gamma)


def test_noisy_gain_grows_with_n():
    # for noisy data the minimal gain grows with n (noise is not a bounded causal Δ)
    rng = np.random.default_rng(8)
    u = np.sign(rng.standard_normal(60))
    y = scipy.signal.lfilter([0, 0.00484, 0.00468], [1, -1.905, 0.905], u) + 0.03 * rng.standard_normal(60)
    g = [uf.unfalsified_gain(u[:n], y[:n], warn=False) for n in (10, 30, 60)]
    assert g[0] <= g[1] <= g[2]  # a prefix's constraint is a principal block: monotone exactly
    assert g[2] > 10 * g[0]


@pytest.mark.parametrize(
    "u, y",
    [
        ([1.0, np.nan, 1.0], [0.0, 1.0, 2.0]),  # NaN
        ([1.0, 1.0, 1.0], [0.0, 1.0]),  # lengths
        (np.ones((2, 4)), np.ones(4)),  # time along axis 1 (several channels are accepted since issue 28)
    ],
)
def test_bad_input_raises(u, y):
    with pytest.raises(DataError):
        uf.unfalsified_gain(u, y)


def test_is_unfalsified_rejects_bad_gamma():
    with pytest.raises(DataError):
        uf.is_unfalsified([1.0, 0.0], [0.5, 0.0], -1.0)
    with pytest.raises(DataError):
        uf.is_unfalsified([1.0, 0.0], [0.5, 0.0], np.nan)



@pytest.mark.parametrize("kw, fragment", [
    (dict(gamma="1e9"), r"gamma \(the gain bound\) must be a finite number >= 0, got '1e9'"),
    (dict(gamma=True), r"gamma \(the gain bound\) must be"),
    (dict(gamma=1.0, rtol="1e-9"), r"rtol \(the relative tolerance of the comparison\) must be a finite number >= 0"),
    (dict(gamma=1.0, rtol=-1e-9), r"rtol .* must be a finite number >= 0, got -1e-09"),
])
def test_is_unfalsified_refuses_strings_for_its_numbers(kw, fragment):
    # gamma="1e9" had been parsed by float() silently, rtol="1e-9" reached numpy's sum (a bare TypeError)
    gamma = kw.pop("gamma")
    with pytest.raises(DataError, match=fragment):
        uf.is_unfalsified([1.0, 0.0], [0.5, 0.0], gamma, **kw)
    assert uf.is_unfalsified([1.0, 0.0], [0.5, 0.0], 0.5) and not uf.is_unfalsified([1.0, 0.0], [0.5, 0.0], 0.49)


def test_deconvolve_and_norm_reject_bad_input_with_value_errors():
    # a public helper must not leak ZeroDivisionError/IndexError: DataError names the problem and the fix
    with pytest.raises(DataError, match="u\\[0\\] == 0.*first non-zero"):
        uf.deconvolve([0.0, 1.0, 1.0], [0.0, 1.0, 2.0])
    with pytest.raises(DataError, match="same length"):
        uf.deconvolve([1.0, 1.0, 1.0], [0.0, 1.0], exact=True)
    with pytest.raises(DataError, match="same length"):
        uf.deconvolve([], [])
    # NaN, complex, object arrays and several channels had been read silently (NaN out, imaginary parts dropped)
    for u, match in (([1.0, np.nan, 1.0], "NaN"), (np.array([1.0, 2.0, 3.0]) + 1j, "complex"),
                     (np.array([None, None, None]), "NaN"), (np.ones((3, 2)), "one channel"), ("abc", "numeric")):
        with pytest.raises(DataError, match=match):
            uf.deconvolve(u, [1.0, 2.0, 3.0])
    assert uf.deconvolve([2.0, 1.0], [[2.0], [3.0]]).tolist() == [1.0, 1.0]  # a column (n, 1) is one channel



@pytest.mark.parametrize("exact", [False, True])
def test_deconvolve_refuses_a_solution_that_leaves_floating_point(exact):
    """u[0] = 1e-300 makes T(u)⁻¹y overflow: deconvolve had returned inf/nan without a word (exact=True as well:
    the data's own answer, not rounding).  unfalsified_gain keeps reading such data as γ = inf (method 'overflow'),
    and toeplitz_cond as inf."""
    rng = np.random.default_rng(0)
    u, y = rng.standard_normal(30), rng.standard_normal(30)
    u[0] = 1e-300
    with pytest.raises(DataError, match=r"leaves floating point at sample 1 .*too ill-conditioned.*\|u\[0\]\| = 1e-300"
                                        r".*start the window at a sample where u is large"):
        uf.deconvolve(u, y, exact=exact)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", uf.IllConditionedWarning)
        r = uf.unfalsified_gain_result(u, y, exact=exact)
    assert r.gamma == np.inf and r.method == "overflow" and uf.toeplitz_cond(u) == np.inf
    u[0] = 1e-3  # ill-conditioned but finite: still solved
    h = uf.deconvolve(u, y, exact=exact)
    assert np.all(np.isfinite(h)) and h[0] == pytest.approx(y[0] / 1e-3, rel=1e-12)
    for n in (2, 5):  # the method is checked for every size (n < 3 used to fall through to dense)
        with pytest.raises(ValueError, match="unknown method"):
            uf.toeplitz_norm(np.ones(n), method="svd")


@pytest.mark.parametrize("call, match", [
    (lambda: uf.toeplitz_norm(np.ones((5, 2))), r"h must be one sequence.*shape \(5, 2\).*block_toeplitz_norm"),
    (lambda: uf.toeplitz_matrix(None), "x must be a real numeric sequence.*got None"),  # had returned [[nan]]
    (lambda: uf.toeplitz_matrix([1.0, np.nan]), "x contains 1 NaN"),
    (lambda: uf.toeplitz_cond([]), "u is empty.*at least one sample"),  # had raised IndexError
    (lambda: uf.toeplitz_cond([1.0, np.inf]), "u contains 1 NaN or infinite"),
    (lambda: uf.toeplitz_norm("abc"), "h must be a real numeric sequence"),
    (lambda: uf.toeplitz_matrix("abc"), "x must be a real numeric sequence"),
    (lambda: uf.toeplitz_cond("abc"), "u must be a real numeric sequence"),
    (lambda: uf.toeplitz_matrix(np.ones(3) + 1j), "x must be a real numeric sequence"),
    (lambda: uf.toeplitz_norm(np.ones(5), tol=-1.0), r"tol .*must be a finite number >= 0"),
    (lambda: uf.toeplitz_norm(np.ones(5), tol=np.nan), r"tol .*must be a finite number >= 0"),
    (lambda: uf.toeplitz_norm(np.ones(5), tol="x"), r"tol .*must be a finite number >= 0"),
])
def test_toeplitz_helpers_refuse_what_is_not_one_finite_sequence(call, match):
    with pytest.raises(DataError, match=match):
        call()


@pytest.mark.parametrize("n", [0, 1, 2, 7, 60])
def test_toeplitz_matrix_is_scipys_and_a_column_is_one_sequence(n):
    x = np.random.default_rng(n).standard_normal(n)
    np.testing.assert_array_equal(uf.toeplitz_matrix(x), scipy.linalg.toeplitz(x, np.zeros(n)))
    if n:
        assert uf.toeplitz_norm(x[:, None]) == uf.toeplitz_norm(x) == uf.toeplitz_norm(x[None, :])


def test_deconvolve_returns_an_overflowing_solution_only_when_asked():
    u = np.r_[1e-300, np.ones(9)]
    y = np.ones(10)
    with pytest.raises(DataError, match="leaves floating point"):
        uf.deconvolve(u, y)
    h = uf.deconvolve(u, y, overflow="return")  # what unfalsified_gain reads as γ = inf
    assert not np.all(np.isfinite(h))
    assert uf.unfalsified_gain_result(u, y, warn=False).method == "overflow"
    with pytest.raises(DataError, match="overflow must be"):
        uf.deconvolve(u, y, overflow="ignore")
