"""Chow's test of time invariance on ARX fits of a record's segments (unfalsify.invariance)."""
import pickle

import numpy as np
import pytest
import scipy.signal
import scipy.stats

import unfalsify as uf
from synthesis import DataError


def _arx_record(n, seed, gain=(1.0, 1.0), noise=0.1):
    """y(t) = 0.7 y(t−1) + g(t)·0.5 u(t−1) + e(t), e white: an exact ARX(1) record, its gain ramping g0 → g1."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    g = np.linspace(gain[0], gain[1], n)
    y = scipy.signal.lfilter([0.0, 0.5], [1.0, -0.7], g * u + noise / 0.5 * np.roll(rng.standard_normal(n), -1))
    return u, y


def test_the_statistic_equals_the_interaction_regression_of_the_textbook_chow_test():
    # second route: the unrestricted model as one regression with every regressor interacted with the segment
    u, y = _arx_record(600, 0, gain=(0.8, 1.2))
    t = uf.check_time_invariance(u, y, order=3)
    n = len(u)  # the lagged regressors written out: y(t−1..t−3), u(t−1..t−3) for t = 3 … n−1
    Phi = np.column_stack([y[3 - d : n - d] for d in (1, 2, 3)] + [u[3 - d : n - d] for d in (1, 2, 3)])
    target = y[3:]
    half = np.arange(Phi.shape[0]) >= (Phi.shape[0] + 1) // 2
    full = np.hstack([Phi * ~half[:, None], Phi * half[:, None]])
    rss = lambda X: float(np.sum((target - X @ np.linalg.lstsq(X, target, rcond=None)[0]) ** 2))  # noqa: E731
    r0, r1 = rss(Phi), rss(full)
    d1, d2 = Phi.shape[1], Phi.shape[0] - full.shape[1]
    F = (r0 - r1) / d1 / (r1 / d2)
    assert t.dof == (d1, d2)
    assert t.statistic == pytest.approx(F, rel=1e-9)
    assert t.p_value == pytest.approx(scipy.stats.f.sf(F, d1, d2), rel=1e-9)


def test_p_values_of_time_invariant_records_are_uniform():
    # exact ARX(1) data with white errors: under the null hypothesis F has the F distribution, so about 5 % of
    # p-values fall below 0.05 and the p-values are uniform (Kolmogorov–Smirnov)
    p = np.array([uf.check_time_invariance(*_arx_record(400, s), order=2).p_value for s in range(200)])
    assert 2 <= np.sum(p < 0.05) <= 20
    assert scipy.stats.kstest(p, "uniform").pvalue > 1e-3


def test_a_drifting_gain_is_detected_and_the_reason_names_the_fix():
    u, y = _arx_record(1500, 1, gain=(0.6, 1.4))
    t = uf.check_time_invariance(u, y)
    assert t.rejected and t.p_value < 1e-6 and t.order == 16 and t.segments == 2 and t.samples == 1500
    assert "not that of one time-invariant plant" in t.reason and "Use a record over which" in t.reason
    same = uf.check_time_invariance(*_arx_record(1500, 1))
    assert not same.rejected and same.reason == ""


def test_an_output_error_plant_with_the_default_order_is_not_flagged():
    # coloured equation error (sensor noise on an output-error plant): a long ARX model whitens it
    flagged = 0
    for seed in range(20):
        rng = np.random.default_rng(seed)
        u = rng.standard_normal(1500)
        y = scipy.signal.lfilter([0.0, 0.2, 0.1], [1.0, -1.5, 0.7], u) + 0.1 * rng.standard_normal(1500)
        flagged += uf.check_time_invariance(u, y).rejected
    assert flagged <= 1


def test_several_channels_bonferroni_and_the_output_named():
    rng = np.random.default_rng(3)
    n = 2000
    U = rng.standard_normal((n, 2))
    g = np.linspace(0.5, 1.5, n)
    Y = np.column_stack([scipy.signal.lfilter([0.0, 0.5], [1.0, -0.6], U[:, 0] + 0.3 * U[:, 1]),
                         scipy.signal.lfilter([0.0, 0.5], [1.0, -0.6], g * U[:, 1])]) + 0.05 * rng.standard_normal((n, 2))
    t = uf.check_time_invariance(U, Y)
    assert t.rejected and "(output 1)" in t.reason
    Y[:, 1] = scipy.signal.lfilter([0.0, 0.5], [1.0, -0.6], U[:, 1]) + 0.05 * rng.standard_normal(n)
    assert not uf.check_time_invariance(U, Y).rejected


def test_bad_input_raises_data_error_naming_the_fix():
    u, y = _arx_record(30, 0)
    with pytest.raises(DataError, match="too short to test time invariance"):
        uf.check_time_invariance(u, y)
    u, y = _arx_record(400, 0)
    with pytest.raises(DataError, match="segments"):
        uf.check_time_invariance(u, y, segments=1)
    with pytest.raises(DataError, match="level"):
        uf.check_time_invariance(u, y, level=0.0)
    with pytest.raises(DataError, match="order"):
        uf.check_time_invariance(u, y, order=0)
    with pytest.raises(DataError, match="smaller order"):
        uf.check_time_invariance(u, y, order=150)


def test_min_record_length_is_the_shortest_record_tested_by_default():
    for outputs, inputs in ((1, 1), (1, 2), (2, 2)):
        need = uf.min_record_length(outputs, inputs)
        rng = np.random.default_rng(outputs + inputs)
        u, y = rng.standard_normal((need, inputs)), rng.standard_normal((need, outputs))
        assert uf.check_time_invariance(u, y).order == 8
        with pytest.raises(DataError, match=f"need {need} samples"):
            uf.check_time_invariance(u[:-1], y[:-1])
    assert uf.min_record_length(1, 1, segments=3) == 3 * uf.min_record_length(1, 1) // 2
    assert uf.min_record_length(np.int64(2), np.int64(2)) == uf.min_record_length(2, 2)
    for bad in (dict(outputs=0, inputs=1), dict(outputs=1.5, inputs=1), dict(outputs=True, inputs=1),
                dict(outputs=1, inputs=-1), dict(outputs="1", inputs=1), dict(outputs=1, inputs=1, segments=1)):
        with pytest.raises(DataError, match="must be an integer ≥"):
            uf.min_record_length(**bad)


def test_the_result_is_frozen_and_pickles():
    t = uf.check_time_invariance(*_arx_record(400, 0))
    back = pickle.loads(pickle.dumps(t))
    assert back.p_value == t.p_value and back.reason == t.reason
    with pytest.raises(AttributeError):
        t.p_value = 0.0


@pytest.mark.parametrize("noise", [0.0, 1e-12, 1e-9])
def test_noise_free_records_are_tested_not_rejected_by_rounding(noise):
    """A simulated record without noise (or nearly) leaves residuals at the rounding level: Chow's F is then no
    statistic (measured before: p = 6e-38 for a noise-free LTI record of 3000 samples, 6e-21 with noise 1e-12).  An
    LTI record is accepted; a record whose ARX model switches between the two halves is rejected."""
    rng = np.random.default_rng(7)
    n, p = 3000, 16
    u = rng.standard_normal(n)
    lti = scipy.signal.lfilter([0.0, 0.5, 0.2], [1.0, -1.2, 0.5], u) + noise * rng.standard_normal(n)
    test = uf.check_time_invariance(u, lti, order=p)
    assert not test.rejected and test.p_value > 0.01
    # the same recursion with its coefficients switched where the second segment's regression rows begin
    switch = p + len(np.array_split(np.arange(n - p), 2)[0])
    y = np.zeros(n)
    for k in range(2, n):
        a1, b1 = (1.2, 0.5) if k < switch else (1.0, 0.7)
        y[k] = a1 * y[k - 1] - 0.5 * y[k - 2] + b1 * u[k - 1] + 0.2 * u[k - 2]
    y += noise * rng.standard_normal(n)
    changed = uf.check_time_invariance(u, y, order=p)
    assert changed.rejected and "time-invariant" in changed.reason


# ---- against=: two records of one plant? ------------------------------------------------------------------------

def test_against_sees_a_plant_that_changed_between_two_records_which_neither_record_shows():
    """A fitting record and a validation record, each of one LTI plant, but the input gain is 1.5 times larger in the
    second: each record alone passes the test, the comparison of the two rejects one model for both."""
    first = _arx_record(700, 11)
    second = _arx_record(500, 12, gain=(1.5, 1.5))
    assert not uf.check_time_invariance(*first).rejected and not uf.check_time_invariance(*second).rejected
    t = uf.check_time_invariance(*first, against=second)
    assert t.rejected and t.p_value < 1e-6 and t.order == 16 and t.segments == 2
    assert t.samples == 1200 and t.split == 700
    assert "between the experiments" in t.reason and "Use records of the plant as it is now" in t.reason
    same = uf.check_time_invariance(*first, against=_arx_record(500, 13))
    assert not same.rejected and same.reason == ""


def test_against_is_chows_test_on_the_stacked_rows_of_the_two_records():
    # second route: the textbook interaction regression, every row regressed on its own record's past only
    (u1, y1), (u2, y2) = _arx_record(400, 21), _arx_record(300, 22, gain=(1.1, 1.1))
    t = uf.check_time_invariance(u1, y1, order=3, against=(u2, y2))

    def rows(u, y):
        n = len(u)
        return np.column_stack([y[3 - d : n - d] for d in (1, 2, 3)] + [u[3 - d : n - d] for d in (1, 2, 3)]), y[3:]

    (P1, t1), (P2, t2) = rows(u1, y1), rows(u2, y2)
    Phi, target = np.vstack([P1, P2]), np.r_[t1, t2]
    second = np.arange(len(target)) >= len(t1)
    full = np.hstack([Phi * ~second[:, None], Phi * second[:, None]])
    rss = lambda X: float(np.sum((target - X @ np.linalg.lstsq(X, target, rcond=None)[0]) ** 2))  # noqa: E731
    d1, d2 = Phi.shape[1], len(target) - full.shape[1]
    F = (rss(Phi) - rss(full)) / d1 / (rss(full) / d2)
    assert t.dof == (d1, d2) and t.statistic == pytest.approx(F, rel=1e-9)
    assert t.p_value == pytest.approx(scipy.stats.f.sf(F, d1, d2), rel=1e-9)


def test_against_p_values_of_one_plant_are_uniform():
    p = np.array([uf.check_time_invariance(*_arx_record(300, s), order=2, against=_arx_record(200, 1000 + s)).p_value
                  for s in range(200)])
    assert 2 <= np.sum(p < 0.05) <= 20
    assert scipy.stats.kstest(p, "uniform").pvalue > 1e-3


def test_against_bad_input_raises_data_error_naming_the_fix():
    u, y = _arx_record(400, 0)
    with pytest.raises(DataError, match="not both"):
        uf.check_time_invariance(u, y, split=200, against=(u, y))
    with pytest.raises(DataError, match="a pair"):
        uf.check_time_invariance(u, y, against=u)
    with pytest.raises(DataError, match="same channels"):
        uf.check_time_invariance(u, y, against=(np.ones((400, 2)), y))
    need = uf.min_record_length(1, 1) // 2
    assert uf.check_time_invariance(u, y, against=(u[:need], y[:need])).order == 8
    with pytest.raises(DataError, match=f"need {need} samples in each"):
        uf.check_time_invariance(u, y, against=(u[: need - 1], y[: need - 1]))
    with pytest.raises(DataError, match="smaller order"):
        uf.check_time_invariance(u, y, order=40, against=(u[:100], y[:100]))
