"""Subspace predictor (thesis §2.1–2.3): methods vs numpy lstsq, noise-free LTI limits (2.10)/(2.12),
Hankel Gram recursion (2.8)–(2.9) vs the explicit product, rank deficiency, bad input, benchmark smoke test.

Reference quantities (Hankel matrices, Markov Toeplitz H_p, observability Γ_p) are built here with
plain loops, independently of the package.  Seeds are fixed per test.
"""
import tracemalloc
import warnings

import numpy as np
import pytest

import synthesis
from synthesis import DataError, PersistenceWarning, fit_predictor, hankel_gram

METHODS = ("cholesky", "qr", "lstsq")


# ----------------------------------------------------------------------------- independent references
def hankel_loops(x, rows, cols, start):
    """Block Hankel (2.1)–(2.4) with explicit loops: block (r, c) = x[start + r + c] (a column)."""
    x = np.asarray(x, float).reshape(len(x), -1)
    k = x.shape[1]
    H = np.zeros((rows * k, cols))
    for r in range(rows):
        for c in range(cols):
            H[r * k : (r + 1) * k, c] = x[start + r + c]
    return H


def data_matrices(u, y, i):
    j = len(u) - 2 * i + 1
    return (hankel_loops(u, i, j, 0), hankel_loops(y, i, j, 0), hankel_loops(u, i, j, i), hankel_loops(y, i, j, i))


def random_plant(rng, nx, m, l, rho=0.8):
    A = rng.standard_normal((nx, nx))
    A *= rho / max(abs(np.linalg.eigvals(A)))
    return A, rng.standard_normal((nx, m)), rng.standard_normal((l, nx)), rng.standard_normal((l, m))


def simulate(plant, u, x0, w=None):
    """x_{k+1} = A x_k + B (u_k + w_k), y_k = C x_k + D u_k; returns y (n, l) and states x (n, nx)."""
    A, B, C, D = plant
    w = np.zeros_like(u) if w is None else w
    x = np.array(x0, float)
    X, Y = [], []
    for uk, wk in zip(u, w):
        X.append(x)
        Y.append(C @ x + D @ uk)
        x = A @ x + B @ (uk + wk)
    return np.array(Y), np.array(X)


def markov_toeplitz_ref(plant, i):
    """H_p of (2.10) from (A, B, C, D)."""
    A, B, C, D = plant
    l, m = D.shape
    h = [D] + [C @ np.linalg.matrix_power(A, k) @ B for k in range(i - 1)]
    H = np.zeros((i * l, i * m))
    for r in range(i):
        for c in range(r + 1):
            H[r * l : (r + 1) * l, c * m : (c + 1) * m] = h[r - c]
    return H


def gamma_ref(plant, i):
    """Extended observability matrix Γ_p of (2.12)."""
    A, _, C, _ = plant
    return np.vstack([C @ np.linalg.matrix_power(A, k) for k in range(i)])


def w_past(u, y, k, i):
    """w_p = [u_{k-i}; …; u_{k-1}; y_{k-i}; …; y_{k-1}] (3.13), stacked by hand."""
    return np.concatenate([np.concatenate([u[t] for t in range(k - i, k)]), np.concatenate([y[t] for t in range(k - i, k)])])


def rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


def noisy_mimo(seed=0, n=900, m=2, l=2, nx=4, sigma=0.1):
    rng = np.random.default_rng(seed)
    plant = random_plant(rng, nx, m, l)
    u = rng.standard_normal((n, m))
    y, _ = simulate(plant, u, rng.standard_normal(nx), w=0.2 * rng.standard_normal((n, m)))
    return u, y + sigma * rng.standard_normal((n, l))


# ----------------------------------------------------------------------------- Hankel Gram (2.8)–(2.9)
@pytest.mark.parametrize(
    "m, l, i, j",
    [(1, 1, 1, 1), (1, 1, 1, 30), (1, 1, 4, 3), (2, 2, 5, 40), (1, 2, 3, 17), (2, 1, 6, 2), (3, 2, 2, 11)],
)
def test_hankel_gram_equals_explicit_product(m, l, i, j):
    rng = np.random.default_rng(10 * i + j)
    n = j + 2 * i - 1
    u, y = rng.standard_normal((n, m)), rng.standard_normal((n, l))
    Up, Yp, Uf, Yf = data_matrices(u, y, i)
    A = np.vstack([Up, Yp, Uf, Yf])  # row order of (2.7)
    G = hankel_gram(u, y, i)
    assert G.shape == (2 * i * (m + l),) * 2
    np.testing.assert_allclose(G, A @ A.T, rtol=0, atol=1e-12 * np.abs(A @ A.T).max())
    np.testing.assert_array_equal(G, G.T)


def test_hankel_gram_accepts_1d_signals():
    rng = np.random.default_rng(1)
    u, y = rng.standard_normal(50), rng.standard_normal(50)
    np.testing.assert_allclose(hankel_gram(u, y, 3), hankel_gram(u[:, None], y[:, None], 3))


def test_hankel_gram_memory_is_not_ij():
    """O(i² + j) memory: far below the 2i(m+l)·j doubles of the Hankel matrices (12.8 MB here)."""
    rng = np.random.default_rng(2)
    i, j = 20, 20000
    u, y = rng.standard_normal(j + 2 * i - 1), rng.standard_normal(j + 2 * i - 1)
    tracemalloc.start()
    hankel_gram(u, y, i)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    hankel_bytes = 2 * i * 2 * j * 8
    assert peak < hankel_bytes / 8, (peak, hankel_bytes)


# ----------------------------------------------------------------------------- methods vs numpy lstsq
@pytest.mark.parametrize("method", METHODS)
def test_methods_agree_with_numpy_lstsq_noisy_mimo(method):
    u, y = noisy_mimo(seed=3)
    i = 5
    Up, Yp, Uf, Yf = data_matrices(u, y, i)
    Phi = np.vstack([Up, Yp, Uf])
    ref = np.linalg.lstsq(Phi.T, Yf.T, rcond=None)[0].T
    with warnings.catch_warnings():
        warnings.simplefilter("error", PersistenceWarning)  # noisy, PE data: no rank warning
        p = fit_predictor(u, y, i, method=method)
    assert p.Lw.shape == (i * 2, i * 4) and p.Lu.shape == (i * 2, i * 2)
    assert rel(np.hstack([p.Lw, p.Lu]), ref) < 1e-9
    assert p.rank == p.n_regressors == i * (2 * 2 + 2) and p.full_rank
    assert p.input_rank == 2 * 2 * i and p.persistently_exciting
    assert p.n_columns == len(u) - 2 * i + 1 and p.method == method
    s_ref = np.linalg.svd(Phi, compute_uv=False)
    np.testing.assert_allclose(p.singular_values, s_ref, rtol=1e-8)


def test_default_method_is_cholesky_and_siso_shapes():
    rng = np.random.default_rng(4)
    u = rng.standard_normal(300)
    y = np.convolve(u, [0.0, 1.0, 0.5])[:300] + 0.05 * rng.standard_normal(300)
    p = fit_predictor(u, y, 7)
    assert p.method == "cholesky"
    assert (p.horizon, p.m, p.l) == (7, 1, 1)
    assert p.Lw.shape == (7, 14) and p.Lu.shape == (7, 7)


# ----------------------------------------------------------------------------- noise-free LTI limits
@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("seed, m, l, nx, i", [(0, 2, 2, 3, 6), (1, 1, 1, 4, 8), (2, 2, 1, 2, 5)])
def test_noise_free_lti_recovers_markov_toeplitz_and_state(method, seed, m, l, nx, i):
    """(2.10) Lu = H_p and (2.12) Lw w_p = Γ_p x_k hold exactly for noise-free data of order < i."""
    rng = np.random.default_rng(seed)
    plant = random_plant(rng, nx, m, l)
    n = 700
    u = rng.standard_normal((n, m))
    y, X = simulate(plant, u, rng.standard_normal(nx))
    with pytest.warns(PersistenceWarning, match="noise free"):
        p = fit_predictor(u, y, i, method=method)
    # regressor rank: 2mi input rows plus nx state directions; the input part is full rank
    assert p.rank == 2 * m * i + nx
    assert p.input_rank == 2 * m * i
    H = markov_toeplitz_ref(plant, i)
    assert rel(p.Lu, H) < 1e-8
    Gam = gamma_ref(plant, i)
    for k in (i, n // 2, n - i):
        wp = w_past(u, y, k, i)
        np.testing.assert_allclose(p.past_vector(u[:k], y[:k]), wp)
        assert rel(p.Lw @ wp, Gam @ X[k]) < 1e-8
        # (2.6): the prediction equals the true future outputs
        np.testing.assert_allclose(p.predict(wp, u[k : k + i]), y[k : k + i], atol=1e-8 * np.abs(y).max())


# ----------------------------------------------------------------------------- rank deficiency
@pytest.mark.parametrize("method", METHODS)
def test_input_not_persistently_exciting_warns_and_returns_min_norm(method):
    rng = np.random.default_rng(6)
    n, i = 400, 4
    t = np.arange(n)
    u = np.sin(0.3 * t)  # persistently exciting of order 2 only
    y = np.convolve(u, [0.0, 0.8, 0.3])[:n] + 0.1 * rng.standard_normal(n)
    with pytest.warns(PersistenceWarning, match=r"rank 2 < 2mi = 8"):
        p = fit_predictor(u, y, i, method=method)
    assert p.input_rank == 2 and not p.persistently_exciting
    assert p.rank == 2 + i  # two input directions plus i noisy output rows
    Up, Yp, Uf, Yf = data_matrices(u, y, i)
    ref = np.linalg.pinv(np.vstack([Up, Yp, Uf]).T, rcond=1e-6) @ Yf.T
    assert rel(np.hstack([p.Lw, p.Lu]), ref.T) < 1e-6


@pytest.mark.parametrize("method", METHODS)
def test_too_few_columns_gives_min_norm_predictor(method):
    rng = np.random.default_rng(7)
    i, m, l = 5, 2, 1
    n = 2 * i - 1 + 12  # j = 12 < i(2m+l) = 25
    u, y = rng.standard_normal((n, m)), rng.standard_normal((n, l))
    with pytest.warns(PersistenceWarning):
        p = fit_predictor(u, y, i, method=method)
    assert p.rank == 12 and p.singular_values.shape == (25,)
    Up, Yp, Uf, Yf = data_matrices(u, y, i)
    ref = np.linalg.pinv(np.vstack([Up, Yp, Uf]).T) @ Yf.T  # minimum-norm least squares
    assert rel(np.hstack([p.Lw, p.Lu]), ref.T) < 1e-8


def test_regressor_rank_warning_mentions_sample_count():
    """2mi <= j < i(2m+l): the input is PE but the regressor cannot be full rank; say how much data is needed."""
    rng = np.random.default_rng(8)
    i = 12
    n = 30 + 2 * i - 1  # j = 30: 24 = 2mi <= j < 36 = i(2m+l)
    with pytest.warns(PersistenceWarning, match=r"rank 30 < 36 .*collect at least 59 samples") as rec:
        p = fit_predictor(rng.standard_normal(n), rng.standard_normal(n), i)
    assert rec[0].filename == __file__  # points at the caller
    assert p.input_rank == 24 and p.rank == 30


def test_default_rcond_gram_methods_are_looser():
    assert synthesis.default_rcond("cholesky", 100, 1000) > 1e3 * synthesis.default_rcond("qr", 100, 1000)
    assert synthesis.default_rcond("recursive", 100, 1000) == synthesis.default_rcond("cholesky", 100, 1000)


@pytest.mark.parametrize("args, match", [(("bogus", 30, 100), "unknown method 'bogus'"),
                                         (("qr", -1, 100), "n_regressors must be an integer ≥ 1"),
                                         (("qr", 30, 0), "n_columns must be an integer ≥ 1"),
                                         (("cholesky", 30.0, 100), "n_regressors must be an integer ≥ 1")])
def test_default_rcond_checks_its_arguments(args, match):
    """default_rcond("bogus", -1, 0) had returned 0.0: no tolerance at all."""
    with pytest.raises(DataError, match=match):
        synthesis.default_rcond(*args)


def test_rcond_as_text_is_refused_not_parsed():
    u = np.random.default_rng(0).standard_normal(100)
    with pytest.raises(DataError, match="rcond must be a finite number >= 0, got '0.5'"):
        fit_predictor(u, u, 3, rcond="0.5")
    with pytest.raises(DataError, match="rcond must be a finite number >= 0, got True"):
        synthesis.RecursivePredictor(3, 1, 1, rcond=True)


@pytest.mark.parametrize("scale", [1e-7, 1e-4, 1e5])
def test_badly_scaled_output_gives_the_same_predictor_in_its_units(scale):
    # y in another unit (metres for a micro-positioner, encoder counts): the least-squares predictor only
    # changes units.  The Gram route's √eps-relative rank tolerance had dropped the y rows (with a
    # PersistenceWarning): at 1e-4 or 1e5 the cholesky Lu was off by 100 % or 14 %, and γ_min of the §5.4
    # example by 61 % at 1e5.  The channels are now scaled to unit rms (by powers of two) before the decision.
    u, y = noisy_mimo(seed=4, n=600)
    ref = fit_predictor(u, y, 4)
    with warnings.catch_warnings():
        warnings.simplefilter("error", PersistenceWarning)
        p = fit_predictor(u, scale * y, 4)
        q = fit_predictor(u, scale * y, 4, method="qr")
        rp = synthesis.RecursivePredictor.from_data(u[:400], scale * y[:400], 4, window=300)
        rp.push(u[400:], scale * y[400:])
        r = rp.predictor()
        rf = synthesis.RecursivePredictor.from_data(u, scale * y, 4, track="factor").predictor()
    assert p.rank == p.n_regressors == ref.rank
    for pred in (p, q, rf):
        assert rel(pred.Lu / scale, ref.Lu) < 1e-6
        assert rel(pred.Lw[:, : 4 * 2] / scale, ref.Lw[:, : 4 * 2]) < 1e-6  # the u_p columns
        assert rel(pred.Lw[:, 4 * 2:], ref.Lw[:, 4 * 2:]) < 1e-6  # the y_p columns: unitless
    window = fit_predictor(u[600 - 300 - 7:], scale * y[600 - 300 - 7:], 4)
    assert rel(r.Lu, window.Lu) < 1e-9
    np.testing.assert_allclose(p.singular_values, q.singular_values, rtol=1e-6)  # those of the regressor itself


def test_badly_scaled_rank_deficient_data_keep_the_minimum_norm_predictor():
    # noise-free outputs in a tiny unit: the rank is decided on the channels scaled to unit rms, and the
    # predictor is still the minimum-norm one of the data themselves (pinv with that rank, not of the scaled data)
    rng = np.random.default_rng(5)
    A = np.array([[0.5, 0.2, 0.0], [0.0, 0.3, 0.1], [0.1, 0.0, -0.4]])
    B, C = rng.standard_normal((3, 2)), 1e-4 * rng.standard_normal((2, 3))
    u = rng.standard_normal((800, 2))
    x, y = np.zeros(3), np.empty((800, 2))
    for k in range(800):
        y[k] = C @ x
        x = A @ x + B @ u[k]
    i = 5
    with pytest.warns(PersistenceWarning, match="numerical rank"):
        p = fit_predictor(u, y, i)
    j = 800 - 2 * i + 1
    H = lambda s, k: synthesis.block_hankel(s, i, j, k)  # noqa: E731
    Phi = np.vstack([H(u, 0), H(y, 0), H(u, i)])
    U, s, Vt = np.linalg.svd(Phi, full_matrices=False)
    q = p.rank
    assert q == 2 * 2 * i + 3  # the input rows and the plant's three states
    ref = H(y, i) @ (Vt[:q].T / s[:q]) @ U[:, :q].T
    assert rel(np.hstack([p.Lw, p.Lu]), ref) < 1e-6


def test_explicit_rcond_truncates():
    u, y = noisy_mimo(seed=9, n=300)
    with pytest.warns(PersistenceWarning, match="rcond = 0.5 is too large"):
        p = fit_predictor(u, y, 3, rcond=0.5)
    assert p.rank < p.n_regressors and p.rcond == 0.5
    # the Gram route decides on the regressor with each channel scaled to unit rms (over its 2i lags) by a power
    # of two
    Up, Yp, Uf, Yf = data_matrices(u, y, 3)
    u_ch, y_ch = np.tile([0, 1], 3), np.tile([2, 3], 3)  # rows: lag-major, 2 channels per lag
    ch = np.r_[u_ch, y_ch, u_ch, y_ch]
    A = np.vstack([Up, Yp, Uf, Yf])
    rms = np.array([np.sqrt(np.mean(A[ch == c] ** 2)) for c in range(4)])
    Phi = (A / 2.0 ** np.round(np.log2(rms))[ch][:, None])[:18]
    sv = np.linalg.svd(Phi, compute_uv=False)
    assert p.rank == np.count_nonzero(sv > 0.5 * sv[0])
    with pytest.warns(PersistenceWarning, match="rcond = 0.5 is too large"):
        q = fit_predictor(u, y, 3, method="qr", rcond=0.5)  # the QR route decides on the regressor itself
    assert np.all(q.singular_values[: q.rank] > 0.5 * q.singular_values[0])


# ----------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    "u, y, horizon, match",
    [
        (np.ones(50), np.ones(49), 3, "samples but 50 were expected"),
        (np.r_[np.ones(49), np.nan], np.ones(50), 3, "NaN or infinite"),
        (np.ones(50), np.r_[np.ones(49), np.inf], 3, "NaN or infinite"),
        (np.ones(10), np.ones(10), 6, "too few samples"),
        (np.ones(50), np.ones(50), 0, "horizon must be an integer ≥ 1"),
        (np.ones(50), np.ones(50), -2, "horizon must be an integer ≥ 1"),
        (np.ones(50), np.ones(50), 2.5, "horizon must be an integer"),
        (np.ones(50), np.ones(50), True, "horizon must be an integer"),
        (np.ones((50, 2, 2)), np.ones(50), 3, "dimensions"),
        (np.ones(0), np.ones(0), 1, "empty"),
        ("abc", np.ones(3), 1, "numeric"),
    ],
)
@pytest.mark.parametrize("method", METHODS)
def test_bad_input_raises_value_error(u, y, horizon, match, method):
    with pytest.raises(DataError, match=match) as exc:
        fit_predictor(u, y, horizon, method=method)
    assert isinstance(exc.value, ValueError)


def test_bad_method_and_rcond():
    u = np.random.default_rng(0).standard_normal(40)
    with pytest.raises(ValueError, match="unknown method"):
        fit_predictor(u, u, 2, method="svd")
    with pytest.raises(DataError, match="rcond"):
        fit_predictor(u, u, 2, rcond=-1.0)
    with pytest.raises(DataError, match="hankel|too few"):
        hankel_gram(u[:3], u[:3], 2)


def test_predict_and_past_vector_check_sizes():
    u, y = noisy_mimo(seed=10, n=200)
    p = fit_predictor(u, y, 3)
    with pytest.raises(DataError, match="w_p must have 12"):
        p.predict(np.zeros(11), np.zeros((3, 2)))
    with pytest.raises(DataError, match="u_f must have 6"):
        p.predict(np.zeros(12), np.zeros(5))
    with pytest.raises(DataError, match="at least i=3"):
        p.past_vector(u[:2], y[:2])
    with pytest.raises(DataError, match="channel"):
        p.past_vector(u[:5, :1], y[:5])
    assert p.predict(p.past_vector(u, y), np.zeros((3, 2))).shape == (3, 2)


def test_past_vector_refuses_records_of_different_lengths():
    # the last i rows of u[:10] and y[:9] are samples 7..9 and 6..8: inputs and outputs of different times
    u, y = noisy_mimo(seed=10, n=200)
    p = fit_predictor(u, y, 3)
    with pytest.raises(DataError, match=r"u_past has 10 samples but y_past has 9.*same samples"):
        p.past_vector(u[:10], y[:9])


# ----------------------------------------------------------------------------- benchmark smoke test
def test_bench_predictor_quick(tmp_path):
    from experiments.bench.bench_predictor import run
    from experiments.cli import Options

    summary = run(Options(quick=True, out=tmp_path))
    for name in ("bench_predictor.md", "bench_predictor.json", "bench_predictor.csv", "bench_predictor.png"):
        assert (tmp_path / name).exists(), name
    assert summary["batch"] and summary["recursive"] and summary["scaling"]
    assert summary["peak_gflops"] > 0 and set(summary["scaling_exponents"]) >= {"cholesky vs j", "cholesky vs i"}
    for row in summary["batch"]:
        assert row["qr_s"] is None or row["qr_s"] > 0
        assert row["cholesky_s"] > 0 and row["before_s"] > 0 and row["max_rel_diff"] < 1e-6
        assert row["solver"] in ("triangular", "spectral") and 0 < row["peak_fraction_minimal"]
        # the same fixed count for both routes: the fractions are in the ratio of the times
        ratio = row["peak_fraction_dense_equivalent"] / row["peak_fraction_dense_equivalent_before"]
        assert ratio == pytest.approx(row["speedup_vs_before"], rel=1e-12)
        if row["qr_s"] is not None:  # the dense SYRK route runs wherever QR does, on the same count
            assert row["dense_s"] > 0 and row["max_rel_diff_dense"] < 1e-6
            ratio = row["peak_fraction_performed_dense"] / row["peak_fraction_dense_equivalent"]
            assert ratio == pytest.approx(row["cholesky_s"] / row["dense_s"], rel=1e-12)
    assert any(row["m"] == 2 for row in summary["batch"])  # a MIMO case
    header = (tmp_path / "bench_predictor.csv").read_text().splitlines()[0]
    assert "cholesky_s" in header and "peak_fraction_dense_equivalent" in header


def test_dense_route_of_the_benchmark_equals_fit_predictor():
    """The explicit-Hankel SYRK Gram is a second route to the recursion (2.8)-(2.9): same predictor."""
    from experiments.bench.bench_predictor import _dense_fit

    u, y = noisy_mimo(seed=17, n=500)
    Lw, Lu = _dense_fit(u, y, 4)
    p = fit_predictor(u, y, 4)
    assert rel(np.hstack([Lw, Lu]), np.hstack([p.Lw, p.Lu])) < 1e-10


def test_legacy_route_of_the_benchmark_equals_fit_predictor():
    from synthesis.baselines import former_cholesky_fit  # bench-predictor's baseline

    u, y = noisy_mimo(seed=16, n=500)
    Lw, Lu = former_cholesky_fit(u, y, 4)
    p = fit_predictor(u, y, 4)
    assert rel(np.hstack([Lw, Lu]), np.hstack([p.Lw, p.Lu])) < 1e-10


@pytest.mark.parametrize("method", METHODS)
def test_complex_data_is_refused_not_truncated(method):
    """Casting complex samples to float would silently drop their imaginary part."""
    u = np.random.default_rng(11).standard_normal(50)
    with pytest.raises(DataError, match="complex"):
        fit_predictor(u + 1j * u, u, 3, method=method)
    with pytest.raises(DataError, match="complex"):
        fit_predictor(u, (u + 0j).astype(complex), 3, method=method)


def test_block_hankel_and_predict_validate_input():
    x = np.arange(10.0)
    np.testing.assert_array_equal(synthesis.block_hankel(x, 3, 4, start=2), hankel_loops(x, 3, 4, 2))
    with pytest.raises(DataError, match="rows"):
        synthesis.block_hankel(x, 0, 5)
    with pytest.raises(DataError, match="start"):
        synthesis.block_hankel(x, 2, 3, start=-1)
    with pytest.raises(DataError, match="NaN"):
        synthesis.block_hankel(np.r_[x, np.nan], 2, 10)
    p = fit_predictor(*noisy_mimo(seed=12, n=200), 3)
    with pytest.raises(DataError, match="finite"):
        p.predict(np.full(12, np.nan), np.zeros(6))


# ----------------------------------------------------------------------------- fast path and its fallback (issue 12)
def test_well_conditioned_data_take_the_triangular_route_and_equal_lstsq():
    u, y = noisy_mimo(seed=12, n=800)
    i = 4
    with warnings.catch_warnings():
        warnings.simplefilter("error", PersistenceWarning)
        p = fit_predictor(u, y, i)
    assert p.solver == "triangular"
    Up, Yp, Uf, Yf = data_matrices(u, y, i)
    Phi = np.vstack([Up, Yp, Uf])
    ref = np.linalg.lstsq(Phi.T, Yf.T, rcond=None)[0].T
    assert rel(np.hstack([p.Lw, p.Lu]), ref) < 1e-9
    assert p.rank == p.n_regressors and p.input_rank == 2 * 2 * i
    # the singular values are computed on first access, and are those of the regressor
    np.testing.assert_allclose(p.singular_values, np.linalg.svd(Phi, compute_uv=False), rtol=1e-8)
    # ... and agree with the rank-revealing route on the same data
    from synthesis.hankel import hankel_gram as hg
    from synthesis.predictor import _predictor_from_gram

    q = _predictor_from_gram(hg(u, y, i), i, 2, 2, p.n_columns, p.rcond, "cholesky", route="spectral")
    assert q.solver == "spectral" and q.rank == p.rank and q.input_rank == p.input_rank
    assert rel(np.hstack([p.Lw, p.Lu]), np.hstack([q.Lw, q.Lu])) < 1e-10


@pytest.mark.parametrize("case", ["not_pe", "noise_free", "few_columns"])
def test_rank_deficient_data_fall_back_to_the_spectral_route_and_warn(case):
    rng = np.random.default_rng(13)
    if case == "not_pe":
        n, i = 400, 4
        u = np.sin(0.3 * np.arange(n))
        y = np.convolve(u, [0.0, 0.8, 0.3])[:n] + 0.1 * rng.standard_normal(n)
        ref_rcond = 1e-6
    elif case == "noise_free":
        n, i = 400, 6
        u = rng.standard_normal(n)
        y = np.convolve(u, [0.0, 1.0, 0.5])[:n]
        ref_rcond = 1e-6
    else:
        i = 5
        n = 2 * i - 1 + 10  # j = 10 < i(2m+l) = 15
        u, y = rng.standard_normal(n), rng.standard_normal(n)
        ref_rcond = None
    with pytest.warns(PersistenceWarning):
        p = fit_predictor(u, y, i)
    assert p.solver == "spectral" and p.rank < p.n_regressors
    Up, Yp, Uf, Yf = data_matrices(u, y, i)
    Phi = np.vstack([Up, Yp, Uf])
    ref = (np.linalg.pinv(Phi.T, rcond=ref_rcond) if ref_rcond else np.linalg.pinv(Phi.T)) @ Yf.T
    assert rel(np.hstack([p.Lw, p.Lu]), ref.T) < 1e-6
    lst = np.linalg.lstsq(Phi.T, Yf.T, rcond=p.rcond)[0].T
    assert rel(np.hstack([p.Lw, p.Lu]), lst) < 1e-6


def test_qr_and_lstsq_keep_their_routes():
    u, y = noisy_mimo(seed=14, n=300)
    assert fit_predictor(u, y, 3, method="qr").solver == "spectral"
    assert fit_predictor(u, y, 3, method="lstsq").solver is None


def test_deferred_singular_values_are_frozen_and_picklable():
    import dataclasses
    import pickle

    u, y = noisy_mimo(seed=15, n=300)
    p = fit_predictor(u, y, 3)
    assert p.solver == "triangular"
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.singular_values = np.zeros(3)
    q = pickle.loads(pickle.dumps(p))
    np.testing.assert_array_equal(q.singular_values, p.singular_values)
    np.testing.assert_array_equal(q.Lw, p.Lw)
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.singular_values = np.zeros(3)  # also after evaluation


@pytest.mark.parametrize("rows, c, j", [(1, 1, 1), (2, 1, 1), (3, 2, 2), (4, 3, 5), (5, 2, 9), (8, 1, 8),
                                        (8, 2, 17), (6, 4, 100), (16, 2, 33)])
def test_vectorised_gram_equals_block_row_loop_and_explicit_product(rows, c, j):
    from synthesis.hankel import _interleaved_gram, _interleaved_gram_loop

    z = np.random.default_rng(rows * 100 + c * 10 + j).standard_normal((j + rows - 1, c))
    Z = np.vstack([z[r : r + j].T for r in range(rows)])  # interleaved block Hankel, explicit
    ref = Z @ Z.T
    G = _interleaved_gram(z, rows, j)
    assert np.array_equal(G, G.T)
    np.testing.assert_allclose(G, ref, rtol=0, atol=1e-13 * np.abs(ref).max())
    np.testing.assert_allclose(G, _interleaved_gram_loop(z, rows, j), rtol=0, atol=1e-13 * np.abs(ref).max())


def test_conditioning_estimate_is_a_close_lower_bound_for_either_factor_layout():
    """κ₂ of R1 estimated on R1R1ᵀ and its inverse: never above the SVD value, within 10 % of it, and the
    same decision from the lower factor R1 and from LAPACK's upper factor R1ᵀ of the Gram block."""
    from scipy.linalg import lapack

    from synthesis.predictor import _eig_max_estimate, _gram_inverse_apply, _start_block, _well_conditioned

    rng = np.random.default_rng(31)
    for decades in (1, 3, 5):
        n = 60
        Q1, _ = np.linalg.qr(rng.standard_normal((n, n)))
        Q2, _ = np.linalg.qr(rng.standard_normal((n, n)))
        A = Q1 @ np.diag(np.logspace(0, -decades, n)) @ Q2
        G = A @ A.T
        Rt, info = lapack.dpotrf(G, lower=0, clean=1)
        assert info == 0
        R1 = np.ascontiguousarray(Rt.T)
        s = np.linalg.svd(R1, compute_uv=False)
        V = _start_block(n)
        l1, _ = _eig_max_estimate(lambda X: R1 @ (R1.T @ X), 4, V)
        li, _ = _eig_max_estimate(_gram_inverse_apply(Rt, False), 6, V)
        kappa = np.sqrt(l1 * li)
        assert kappa <= s[0] / s[-1] * (1 + 1e-12)
        assert kappa >= 0.9 * s[0] / s[-1]
        for rc in (0.5 / kappa, 2.0 / kappa):  # clearly inside and clearly outside the margin
            assert _well_conditioned(R1, rc) == _well_conditioned(Rt, rc, lower=False) == (rc < 0.8 / kappa)


def test_bench_predictor_flop_counts_written_out():
    """The three counts of the rate table, for (i, j, m, l) = (2, 9, 1, 1) written out by hand:
    c = 2, N = 8, n = 6, P = 4, Q = 2."""
    from experiments.bench.bench_predictor import _flops

    fl = _flops(2, 9, 1, 1)
    gemm, tail, recursion, sym = 2 * (4 * 2) * (8 * 2) * 2, 2 * 4 * 4 * 1, 3 * 4 * 16, 64
    chol, solves, estimate = 6**3 / 3, 2 * (2 * 1) * 6**2, 112 * 6**2  # n³/3, 2·il·n², 112·n²
    assert fl["performed"] == gemm + tail + recursion + sym + chol + solves + estimate
    assert fl["minimal"] == 2 * 2 * 2 * 4 * 9 + chol + solves  # 2i lags x c² x j multiply-adds
    assert fl["dense_equivalent"] == 8 * 8 * 9 + chol + solves


@pytest.mark.parametrize("scale", [1e-170, 1e-160, 1e154])
def test_the_gram_route_refuses_data_whose_squares_leave_floating_point(scale):
    # 1e-170 had given rank 0 and a zero predictor, 1e-160 an Lu off by 1.5e-4 without a word, 1e154 LinAlgError
    rng = np.random.default_rng(0)
    u = rng.standard_normal(300)
    y = np.convolve(u, [0.0, 1.0, 0.5])[:300] + 0.01 * rng.standard_normal(300)
    with pytest.raises(DataError, match=r"u\[:, 0\] peaks at .*method='qr'"):
        fit_predictor(u * scale, y * scale, 4)
    qr = fit_predictor(u * scale, y * scale, 4, method="qr")  # the route it names: the predictor is scale-free
    np.testing.assert_allclose(qr.Lu, fit_predictor(u, y, 4).Lu, atol=1e-10)
