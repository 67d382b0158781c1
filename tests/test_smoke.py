import numpy as np

import synthesis


def test_package_imports_and_fits():
    rng = np.random.default_rng(0)
    u = rng.standard_normal(200)
    y = np.convolve(u, [0.0, 1.0, 0.5])[:200]
    pred = synthesis.fit_predictor(u, y, 5)
    assert pred.Lw.shape == (5, 10)
    assert pred.Lu.shape == (5, 5)
