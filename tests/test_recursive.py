"""Recursive predictor (§2.3.1): update / downdate sequences equal a refit on the same data window."""
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from synthesis import DataError, PersistenceWarning, RecursivePredictor, RefactorWarning, fit_predictor, hankel_gram

TRACKS = ("gram", "factor")


def _data(seed, n, m, l):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n, m))
    # an FIR plant plus noise keeps the regressor well conditioned
    y = np.zeros((n, l))
    taps = rng.standard_normal((3, l, m))
    for d in range(3):
        y[d:] += u[: n - d] @ taps[d].T
    return u, y + 0.3 * rng.standard_normal((n, l))


def _refit(u, y, i, t, rp):
    """fit_predictor on the samples the recursive predictor should currently summarise."""
    start = t - (rp.n_columns + 2 * i - 1)
    assert start >= 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PersistenceWarning)
        return fit_predictor(u[start:t], y[start:t], i, method="cholesky"), (start, t)


def _assert_same(p, ref, tol=1e-8):
    L, Lref = np.hstack([p.Lw, p.Lu]), np.hstack([ref.Lw, ref.Lu])
    assert np.linalg.norm(L - Lref) <= tol * max(np.linalg.norm(Lref), 1.0)
    assert p.rank == ref.rank and p.input_rank == ref.input_rank and p.n_columns == ref.n_columns


@pytest.mark.parametrize("track", TRACKS)
def test_growing_window_sample_by_sample_equals_refit(track):
    u, y = _data(0, 160, 2, 2)
    i = 3
    rp = RecursivePredictor.from_data(u[:60], y[:60], i, track=track)
    for t in range(61, 161):
        rp.push(u[t - 1], y[t - 1])  # one MIMO sample as 1-D arrays
    ref, _ = _refit(u, y, i, 160, rp)
    assert rp.n_columns == 160 - 2 * i + 1
    p = rp.predictor()
    assert p.method == "recursive"
    _assert_same(p, ref)
    np.testing.assert_allclose(rp.gram, hankel_gram(u, y, i), rtol=1e-12, atol=1e-10)
    assert rp.n_samples_kept == 2 * i - 1  # growing window keeps only the last 2i-1 samples


@pytest.mark.parametrize("track", TRACKS)
def test_sliding_window_equals_refit_on_window(track):
    u, y = _data(1, 400, 1, 1)
    i, window = 4, 60
    rp = RecursivePredictor.from_data(u[:100], y[:100], i, window=window, track=track)
    assert rp.n_columns == window  # longer record: only the last `window` columns are used
    t = 100
    for k in (1, 1, 5, 17, 1, 30, 2, 59, 60, 1, 100, 3):
        rp.push(u[t : t + k], y[t : t + k])
        t += k
        ref, (start, _) = _refit(u, y, i, t, rp)
        assert rp.n_columns == window and start == t - window - 2 * i + 1
        _assert_same(rp.predictor(), ref)
        assert rp.n_samples_kept == window + 2 * i - 1


def test_window_grows_then_slides_from_rank_deficient_start():
    """§6.3-like start: fewer columns than regressors (singular Gram); predictor still returned."""
    u, y = _data(2, 600, 1, 1)
    i, window = 16, 120  # n_reg = 48, N = 64
    n0 = 2 * i - 1 + 20  # j = 20 < n_reg
    rp = RecursivePredictor.from_data(u[:n0], y[:n0], i, window=window)
    with pytest.warns(PersistenceWarning):
        p0 = rp.predictor()
    assert p0.rank == 20 and not p0.full_rank
    ref0, _ = _refit(u, y, i, n0, rp)
    _assert_same(p0, ref0)
    t = n0
    while t < 600:
        k = min(50, 600 - t)
        rp.push(u[t : t + k], y[t : t + k])
        t += k
        ref, _ = _refit(u, y, i, t, rp)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", PersistenceWarning)
            _assert_same(rp.predictor(), ref)
    assert rp.n_columns == window and rp.predictor().full_rank


def test_thesis_adaptive_start_i64():
    """§6.3: R initialised from n = 384 samples at i = 64, then 50 new samples at a time."""
    u, y = _data(6, 384 + 200, 1, 1)
    i = 64
    rp = RecursivePredictor.from_data(u[:384], y[:384], i)
    assert rp.n_columns == 257
    t = 384
    for _ in range(4):
        rp.push(u[t : t + 50], y[t : t + 50])
        t += 50
    ref, _ = _refit(u, y, i, t, rp)
    _assert_same(rp.predictor(), ref)
    assert rp.n_samples_kept == 2 * i - 1


def test_factor_track_refactors_with_warning_when_downdate_loses_definiteness():
    u, y = _data(3, 200, 1, 1)
    i, window = 5, 8  # window < N = 20: the Gram is singular, downdates must fail
    rp = RecursivePredictor.from_data(u[:40], y[:40], i, window=window, track="factor")
    with pytest.warns(RefactorWarning, match="downdate failed"):
        rp.push(u[40:41], y[40:41])
    ref, _ = _refit(u, y, i, 41, rp)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PersistenceWarning)
        _assert_same(rp.predictor(), ref)


def test_sliding_window_survives_large_level_drop():
    """Adding and subtracting huge old columns must not swamp a window of small new data."""
    rng = np.random.default_rng(4)
    i, window = 3, 50
    u = rng.standard_normal(400)
    y = np.convolve(u, [0.0, 1.0, 0.4])[:400] + 0.2 * rng.standard_normal(400)
    u[:150] *= 1e6
    y[:150] *= 1e6
    for track in TRACKS:
        rp = RecursivePredictor.from_data(u[:60], y[:60], i, window=window, track=track)
        for t in range(60, 400):
            rp.push(u[t], y[t])
        ref, _ = _refit(u, y, i, 400, rp)
        _assert_same(rp.predictor(), ref, tol=1e-7)


@pytest.mark.parametrize("track", TRACKS)
def test_a_window_of_small_data_is_exact_right_after_a_level_drop(track):
    """The error of adding and subtracting is relative to the largest energy since the last recomputation: a
    1e5 drop of the signal level had left Lu off by 1.3e-5 (relative) for a whole window (until the periodic
    recomputation), the batch fit on the same window being exact to 1e-13."""
    rng = np.random.default_rng(137)
    i, window, big = 5, 400, 600
    u = rng.standard_normal((2100, 1))
    u[:big] *= 10 ** 2.5
    u[big:] /= 10 ** 2.5
    y = np.zeros((2100, 1))
    x = np.zeros(2)
    for k in range(2100):
        y[k] = x.sum()
        x = np.array([0.8, 0.5]) * x + u[k]
    y += 1e-3 / 10 ** 2.5 * rng.standard_normal((2100, 1))
    rp = RecursivePredictor.from_data(u[:big], y[:big], i, window=window, track=track)
    for t in range(big, 2100, 50):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RefactorWarning)  # the factor track refactors while the big data leave
            rp.push(u[t:t + 50], y[t:t + 50])
        if t + 50 - (rp.n_columns + 2 * i - 1) >= big:  # the window holds only the small data
            ref, _ = _refit(u, y, i, t + 50, rp)
            _assert_same(rp.predictor(), ref, tol=1e-8)  # (the batch Gram fit itself is off by ~1e-10 here)


def test_bad_arguments():
    u, y = _data(5, 50, 2, 1)
    with pytest.raises(DataError, match="window"):
        RecursivePredictor.from_data(u, y, 3, window=0)
    with pytest.raises(DataError, match="track"):
        RecursivePredictor.from_data(u, y, 3, track="qr")
    with pytest.raises(DataError, match="numeric"):  # a string is no sample (it had raised numpy's ValueError)
        RecursivePredictor.from_data(u, y, 3).push("a", np.zeros(1))
    with pytest.raises(DataError, match="too few samples"):
        RecursivePredictor.from_data(u[:5], y[:5], 3)
    rp = RecursivePredictor.from_data(u, y, 3)
    with pytest.raises(DataError, match="channel"):
        rp.push(np.ones((2, 3)), np.ones((2, 1)))
    with pytest.raises(DataError, match="NaN"):
        rp.push(np.ones((1, 2)), [np.nan])
    with pytest.raises(DataError, match="same number"):
        rp.push(np.ones((3, 2)), np.ones((2, 1)))
    assert rp.n_columns == 50 - 5  # failed pushes changed nothing
    assert "RecursivePredictor(horizon=3" in repr(rp)


@settings(max_examples=25, deadline=None)
@given(
    m=st.integers(1, 2),
    l=st.integers(1, 2),
    i=st.integers(1, 5),
    window=st.one_of(st.none(), st.integers(1, 40)),
    extra0=st.integers(1, 30),
    chunks=st.lists(st.integers(1, 12), min_size=1, max_size=8),
    track=st.sampled_from(TRACKS),
    seed=st.integers(0, 10_000),
)
def test_push_sequences_equal_refit_property(m, l, i, window, extra0, chunks, track, seed):
    n = 2 * i - 1 + extra0 + sum(chunks)
    u, y = _data(seed, n, m, l)
    t = 2 * i - 1 + extra0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RefactorWarning)
        warnings.simplefilter("ignore", PersistenceWarning)
        rp = RecursivePredictor.from_data(u[:t], y[:t], i, window=window, track=track)
        for k in chunks:
            rp.push(u[t : t + k], y[t : t + k])
            t += k
        p = rp.predictor()
    expected_j = t - 2 * i + 1 if window is None else min(window, t - 2 * i + 1)
    assert rp.n_columns == expected_j
    ref, (start, _) = _refit(u, y, i, t, rp)
    np.testing.assert_allclose(rp.gram, hankel_gram(u[start:t], y[start:t], i), rtol=1e-10, atol=1e-9)
    _assert_same(p, ref, tol=1e-7)


def test_bad_rcond_is_refused_at_construction():
    u, y = _data(5, 50, 2, 1)
    for bad in (-1.0, 1.5, float("nan"), "tight"):
        with pytest.raises(DataError, match="rcond"):
            RecursivePredictor.from_data(u, y, 3, rcond=bad)
    rp = RecursivePredictor.from_data(u, y, 3, rcond=1e-3)
    assert rp.predictor().rcond == 1e-3
    with pytest.raises(DataError, match="horizon"):
        RecursivePredictor(3.0, 1, 1)


@pytest.mark.parametrize("track", TRACKS)
@pytest.mark.parametrize("window", [None, 4])
def test_an_empty_predictor_names_the_samples_to_push_and_then_equals_refit(track, window):
    # it had returned an all-zero Predictor (n_columns 0) with a warning, and counted every pushed sample as a column
    u, y = _data(7, 40, 2, 1)
    rp = RecursivePredictor(3, 2, 1, window=window, track=track)
    with pytest.raises(DataError, match=r"holds 0 sample\(s\).*push at least 6 more"):
        rp.predictor()
    rp.push(u[:5], y[:5])
    assert rp.n_columns == 0
    with pytest.raises(DataError, match=r"holds 5 sample\(s\).*push at least 1 more"):
        rp.predictor()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PersistenceWarning)
        warnings.simplefilter("ignore", RefactorWarning)  # 4 columns of 18 rows: the downdated factor is singular
        for t in range(5, 20):  # one sample at a time: 2i = 6 samples give the first column
            rp.push(u[t], y[t])
            assert rp.n_columns == (t - 4 if window is None else min(window, t - 4))
            p = rp.predictor()
            ref, _ = _refit(u, y, 3, t + 1, rp)
            _assert_same(p, ref)


@pytest.mark.parametrize("window", [None, 80])
def test_factor_track_is_unit_free_on_noise_free_data(window):
    """The factor track had factored the unscaled Gram matrix: noise-free data (a singular Gram) with channels in
    units 1e±3 gave a regressor rank of 17 instead of 18 and an Lu off by 1.7e-3 (relative) against the batch fit on
    the same window, which factors the channels scaled to unit rms; the gram track was exact to 1e-10."""
    rng = np.random.default_rng(7)
    n, i = 300, 4
    u = rng.standard_normal((n, 2))
    B, C = rng.standard_normal((2, 2)), rng.standard_normal((2, 2))
    y, x = np.zeros((n, 2)), np.zeros(2)
    for k in range(n):  # a strictly proper 2-state plant, no noise
        y[k] = C @ x
        x = np.array([0.8, -0.5]) * x + B @ u[k]
    u, y = u * [1e-3, 1e3], y * [1e3, 1e-3]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RefactorWarning)  # a singular factor cannot be downdated
        warnings.simplefilter("ignore", PersistenceWarning)
        rp = RecursivePredictor.from_data(u[:120], y[:120], i, window=window, track="factor")
        for t in (120, 300):
            if t > 120:
                for s in range(120, t, 10):
                    rp.push(u[s:s + 10], y[s:s + 10])
            ref, _ = _refit(u, y, i, t, rp)
            p = rp.predictor()
            assert p.rank == ref.rank == 18
            assert np.linalg.norm(p.Lu - ref.Lu) <= 1e-8 * np.linalg.norm(ref.Lu)


@pytest.mark.parametrize("track", ["gram", "factor"])
@pytest.mark.parametrize("twin", [False, True])
def test_a_predictor_s_lazy_fields_describe_its_own_window_after_later_pushes(track, twin):
    """``singular_values`` and ``control_pvalue`` are computed when read.  The factor track had handed its live
    summary to those recipes (channels already near unit rms, so no scaled copy): read after a later push they
    described the later window (singular values 319 instead of 20, p 0.86 instead of 0.66, measured).  Twin input
    channels: the rank-deficient route holds the factor too."""
    rng = np.random.default_rng(0)
    n = 400
    u = rng.standard_normal(n)
    y = np.convolve(u, [0.0, 0.9, 0.4])[:n] + 0.01 * rng.standard_normal(n)  # about unit rms: no channel scaling
    if twin:
        u = np.column_stack([u, u])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PersistenceWarning)
        rp = RecursivePredictor.from_data(u, y, 1, track=track)
        pred = rp.predictor()
        ref = fit_predictor(u, y, 1)
        rp.push(rng.standard_normal((4000, u.ndim)).squeeze(), 5 * rng.standard_normal(4000))  # y no longer follows u
    np.testing.assert_allclose(pred.singular_values, ref.singular_values, rtol=1e-8)
    assert pred.control_pvalue == pytest.approx(ref.control_pvalue, rel=1e-6)
