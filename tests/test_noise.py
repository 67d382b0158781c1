"""synthesis.estimate_noise: σ from the residual of the least-squares subspace predictor."""
import numpy as np
import pytest

import synthesis
from synthesis import DataError
from synthesis.predictor import block_hankel

FIR = [0.0, 1.0, 0.5, 0.25]


def _fir_data(n, sigma, seed, m=1):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n, m))
    y = np.column_stack([np.convolve(u[:, c], FIR)[:n] for c in range(m)]).sum(axis=1, keepdims=True)
    return u, y + sigma * rng.standard_normal((n, 1))


def test_against_lstsq_on_explicit_hankel_matrices():
    # second route: numpy.linalg.lstsq on [U_p; Y_p; U_f] → Y_f, residual and dof correction by hand
    u, y = _fir_data(400, 0.2, 0)
    i = 4
    est = synthesis.estimate_noise(u, y, i)
    j = 400 - 2 * i + 1
    Up, Uf = block_hankel(u, i, j, 0), block_hankel(u, i, j, i)
    Yp, Yf = block_hankel(y, i, j, 0), block_hankel(y, i, j, i)
    Phi = np.vstack([Up, Yp, Uf])
    X, *_ = np.linalg.lstsq(Phi.T, Yf.T, rcond=None)
    E = Yf - X.T @ Phi
    rms = np.sqrt(np.mean(E ** 2))
    assert est.residual_rms == pytest.approx(rms, rel=1e-8)
    assert est.n_regressors == Phi.shape[0] == 12 and est.n_columns == j
    assert est.sigma == pytest.approx(rms * np.sqrt(j / (j - 12)), rel=1e-8)
    assert est.first_step[0] == pytest.approx(np.sqrt(np.mean(E[0] ** 2) * j / (j - 12)), rel=1e-8)
    assert est.suggested_sigma == pytest.approx(0.5 * rms, rel=1e-8)
    assert "sqrt(j/(j − 12))" in est.how


def test_near_the_known_noise_level():
    u, y = _fir_data(4000, 0.05, 1)
    est = synthesis.estimate_noise(u, y, 5)
    assert est.sigma == pytest.approx(0.05, rel=0.05)
    assert est.first_step[0] == pytest.approx(0.05, rel=0.08)
    assert est.per_output.shape == (1,)
    assert est.suggested_sigma < est.residual_rms < est.sigma


def test_dof_correction_makes_the_variance_unbiased():
    # the FIR plant is inside the regression model with independent white noise: E[RSS] = (j − p)σ²
    # exactly, so the mean corrected σ² over many short records is σ², the uncorrected one (j − p)/j σ²
    i, n = 3, 40  # p = 9 regressors, j = 35
    s2, r2 = [], []
    for seed in range(300):
        est = synthesis.estimate_noise(*_fir_data(n, 1.0, seed), i)
        s2.append(est.sigma ** 2)
        r2.append(est.residual_rms ** 2)
    se = np.std(s2) / np.sqrt(len(s2))
    assert abs(np.mean(s2) - 1.0) < 3.5 * se
    assert np.mean(r2) == pytest.approx((35 - 9) / 35, abs=3.5 * se)


def test_mimo_per_output_and_errors():
    rng = np.random.default_rng(2)
    u = rng.standard_normal((1500, 2))
    y = np.column_stack([np.convolve(u[:, 0], FIR)[:1500], np.convolve(u[:, 1], FIR)[:1500]])
    y = y + np.array([0.02, 0.2]) * rng.standard_normal((1500, 2))
    est = synthesis.estimate_noise(u, y, 4)
    assert est.per_output == pytest.approx([0.02, 0.2], rel=0.1)
    with pytest.raises(DataError, match="interpolates"):
        synthesis.estimate_noise(u[:30], y[:30], 4)  # j = 23 <= 24 regressors
    with pytest.raises(DataError, match="fraction"):
        synthesis.estimate_noise(u, y, 4, fraction=1.5)
    with pytest.raises(DataError, match="time runs along axis 0"):
        synthesis.estimate_noise(u.T, y, 4)
