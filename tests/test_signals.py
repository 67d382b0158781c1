"""Signals: PRBS, white noise, steps."""
import numpy as np
import pytest

from experiments.lab.signals import prbs, step, step_sequence, white_noise


def test_prbs_is_binary_unit_power_and_periodic():
    u = prbs(3 * 1023 + 5, nbits=10, seed=3)
    assert set(np.unique(u)) == {-1.0, 1.0}
    np.testing.assert_allclose(np.mean(u**2), 1.0)
    np.testing.assert_array_equal(u[:1023], u[1023:2046])
    np.testing.assert_array_equal(u[:5], u[3069:3074])
    # maximum-length property: one period has 512 ones and 511 minus ones
    assert np.sum(u[:1023] > 0) == 512
    # circular autocorrelation is -1/N off the zero lag
    c = np.array([np.dot(u[:1023], np.roll(u[:1023], k)) for k in range(1, 20)]) / 1023
    np.testing.assert_allclose(c, -1 / 1023)


def test_prbs_seed_and_default_length():
    a, b = prbs(100, seed=1), prbs(100, seed=1)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(prbs(100, seed=1), prbs(100, seed=2))
    assert prbs(100).shape == (100,)  # nbits=7, one cycle covers 100
    np.testing.assert_allclose(np.abs(prbs(10, amplitude=0.5)), 0.5)
    with pytest.raises(ValueError):
        prbs(0)
    with pytest.raises(ValueError, match=r"n \(a number of samples\) must be an integer ≥ 1, got 2.5"):
        prbs(2.5)  # one count check for the toolkit (synthesis.validation.check_count)
    with pytest.raises(ValueError):
        prbs(10, nbits=1)


def test_white_noise():
    e = white_noise(20000, sigma=0.05, seed=0)
    assert e.shape == (20000,)
    assert abs(e.std() - 0.05) < 0.002 and abs(e.mean()) < 0.002
    np.testing.assert_array_equal(e, 0.05 * np.random.default_rng(0).standard_normal(20000))
    assert white_noise(5, channels=2, seed=1).shape == (5, 2)
    with pytest.raises(ValueError):
        white_noise(5, sigma=-1)


def test_steps():
    r = step_sequence(10, [1.0, -1.0, 0.5], hold=3)
    np.testing.assert_array_equal(r, [1, 1, 1, -1, -1, -1, 0.5, 0.5, 0.5, 1])
    np.testing.assert_array_equal(step(5, at=2, amplitude=2), [0, 0, 2, 2, 2])
    with pytest.raises(ValueError):
        step(5, at=5)
    with pytest.raises(ValueError):
        step_sequence(5, [], hold=2)
