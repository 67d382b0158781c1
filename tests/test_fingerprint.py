"""synthesis.record_fingerprint: which samples of a record another record holds (the held-out check's basis)."""
import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import synthesis
from synthesis.fingerprint import BLOCK, _block_hashes, _row_hashes


def _record(n, seed, m=1, l=1):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n, m))
    return u, np.cumsum(u, axis=0)[:, :l] * 0.1 + 0.01 * rng.standard_normal((n, l))


@settings(max_examples=30, deadline=None)
@given(n=st.integers(300, 3000), start=st.integers(0, 2999), length=st.integers(2 * BLOCK - 1, 3000),
       seed=st.integers(0, 2**31), m=st.integers(1, 2), l=st.integers(1, 2))
def test_a_copied_stretch_is_found_up_to_its_ends(n, start, length, seed, m, l):
    """Any stretch of 2·block − 1 samples or more of the record is found; of each, at most block − 1 samples at
    either end are missed (the bound the docstring states), and never a sample outside it."""
    u, y = _record(n, seed, m, l)
    start = min(start, n - (2 * BLOCK - 1))
    stop = min(start + length, n)
    fp = synthesis.record_fingerprint(u, y)
    other_u, other_y = _record(500, seed + 1, m, l)
    query_u = np.concatenate([other_u[:200], u[start:stop], other_u[200:]])
    query_y = np.concatenate([other_y[:200], y[start:stop], other_y[200:]])
    mask = fp.shared(query_u, query_y)
    inside = np.zeros(mask.size, bool)
    inside[200:200 + stop - start] = True
    assert not np.any(mask & ~inside)
    # the found part: from the first aligned block start at or after `start` to the last aligned block end
    first = -(-start // BLOCK) * BLOCK
    last = min(stop, n // BLOCK * BLOCK) // BLOCK * BLOCK
    assert np.count_nonzero(mask) == max(last - first, 0) >= stop - start - 2 * (BLOCK - 1)


def test_other_noise_a_sign_flip_and_rounding_are_different_records():
    u, y = _record(4000, 0)
    fp = synthesis.record_fingerprint(u, y)
    assert fp.shared_fraction(u, y) == 1 - (4000 % BLOCK) / 4000
    assert fp.shared_fraction(u, y + 1e-12) == 0.0                  # one bit of difference anywhere in a block
    assert fp.shared_fraction(-u, -y) == 0.0                          # a linear plant's other record, not this one
    assert fp.shared_fraction(np.float32(u).astype(float), y) == 0.0  # rounded: not the fitted numbers
    assert fp.shared_fraction(u[:, 0].tolist(), y[:, 0]) == fp.shared_fraction(u, y)  # lists and 1-D arrays alike
    u2, y2 = _record(100_000, 1)
    assert synthesis.record_fingerprint(u2, y2).shared_fraction(*_record(100_000, 2)) == 0.0


def test_idle_stretches_are_not_fingerprinted():
    """Equal idle stretches of two experiments (input and output constant) do not make them one record."""
    u, y = _record(1000, 3)
    idle = np.zeros((640, 1))
    fp = synthesis.record_fingerprint(np.vstack([idle, u]), np.vstack([idle + 2.0, y]))
    assert fp.digests.size == 1640 // BLOCK - 640 // BLOCK
    assert fp.shared_fraction(np.vstack([idle, u[:10]]), np.vstack([idle + 2.0, y[:10]])) == 0.0


def test_the_aligned_hashes_equal_the_sliding_ones():
    """Two routes to one number: the fingerprint's aligned blocks (a product with the powers, summed) and the
    query's Horner recursion over every offset."""
    u, y = _record(1000, 4, m=2, l=1)
    rows = np.hstack([u, y])
    fp = synthesis.record_fingerprint(u, y)
    assert np.array_equal(np.unique(_block_hashes(rows, BLOCK)[::BLOCK][:1000 // BLOCK]), fp.digests)
    assert np.unique(_row_hashes((rows,))).size == 1000


def test_bad_input_and_channel_mismatch_raise_data_error():
    u, y = _record(300, 5)
    fp = synthesis.record_fingerprint(u, y)
    with pytest.raises(synthesis.DataError, match="block must be an integer"):
        synthesis.record_fingerprint(u, y, block=0)
    with pytest.raises(synthesis.DataError):
        fp.shared(np.hstack([u, u]), y)
    with pytest.raises(synthesis.DataError):
        synthesis.record_fingerprint(u, y[:-1])
    assert fp.shared_fraction(u[:BLOCK - 1], y[:BLOCK - 1]) == 0.0  # shorter than a block: nothing can be found
    short = synthesis.record_fingerprint(u[:BLOCK - 1], y[:BLOCK - 1])  # a record shorter than a block: no digest
    assert short.samples == BLOCK - 1 and short.digests.size == 0 and short.shared_fraction(u, y) == 0.0


def test_a_fitted_predictor_keeps_its_record_and_pickles_with_it():
    u, y = _record(600, 6)
    for method in ("cholesky", "qr", "lstsq"):
        pred = synthesis.fit_predictor(u, y, 5, method=method)
        assert pred.fingerprint == synthesis.record_fingerprint(u, y)
        assert pred.fingerprint.shared_fraction(u[100:300], y[100:300]) > 0.3
        again = pickle.loads(pickle.dumps(pred))
        assert again.fingerprint == pred.fingerprint
    other = synthesis.fit_predictor(u, y, 5)
    object.__setattr__(other, "fingerprint", None)
    assert other == synthesis.fit_predictor(u, y, 5)  # equality is about the predictor, not its record
