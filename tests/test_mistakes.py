"""Common mistakes fail with a message that names the fix (issue "From a data file to a saved,
certified controller", item 5)."""
import numpy as np
import pytest

import synthesis
import unfalsify as uf
from synthesis import DataError

TRANSPOSED = r"time runs along axis 0: pass {}\.T \(shape \(500, {}\)\)"


@pytest.mark.parametrize("m", [1, 2])
def test_time_along_axis_1_names_the_transpose(m):
    rng = np.random.default_rng(0)
    wide, good = rng.standard_normal((m, 500)), rng.standard_normal((500, m))
    with pytest.raises(DataError, match=TRANSPOSED.format("u", m)):
        synthesis.fit_predictor(wide, good, 10)
    with pytest.raises(DataError, match=TRANSPOSED.format("y", m)):
        synthesis.fit_predictor(good, wide, 10)
    with pytest.raises(DataError, match=TRANSPOSED.format("u", m)):
        synthesis.hankel_gram(wide, good, 10)
    with pytest.raises(DataError, match=TRANSPOSED.format("u", m)):
        synthesis.RecursivePredictor.from_data(wide, good, 10)
    if m == 1:
        with pytest.raises(DataError, match=TRANSPOSED.format("u", 1)):
            uf.subspace_data(wide, good, 10)
        with pytest.raises(DataError, match=TRANSPOSED.format("y", 1)):
            uf.arx_least_squares(good, wide, 2, 2)


def test_short_windows_and_single_samples_are_still_accepted():
    # the past window of a controller and one new MIMO sample may have more channels than rows
    rng = np.random.default_rng(0)
    u, y = rng.standard_normal((300, 3)), rng.standard_normal((300, 3))
    rp = synthesis.RecursivePredictor.from_data(u, y, 2)
    rp.push(rng.standard_normal((1, 3)), rng.standard_normal((1, 3)))
    assert rp.n_columns == 298
    pred = synthesis.fit_predictor(u, y, 2)
    assert pred.past_vector(u[-2:], y[-2:]).shape == (12,)  # (2, 3) windows: more channels than rows
    # a 1-D signal is one channel, never "transposed"
    assert synthesis.fit_predictor(u[:, 0], y[:, 0], 5).m == 1
