"""Subspace LQG (Thm 4.1) against its normal-equation closed form (4.2), and Thm 4.2 (γ → ∞ limit of H∞)."""
import numpy as np
import pytest
from scipy import signal

from synthesis import DataError, fit_predictor, hinf_design
from synthesis.lqg import lqg_design

DT = 0.1


def _predictor(m, l, i=5, n=400, seed=2):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((3, 3))
    A *= 0.85 / max(abs(np.linalg.eigvals(A)))
    B, C = rng.standard_normal((3, m)), rng.standard_normal((l, 3))
    u = rng.choice([-1.0, 1.0], (n, m))
    _, y, _ = signal.dlsim((A, B, C, np.zeros((l, m)), DT), u)
    return fit_predictor(u, y + 0.02 * rng.standard_normal(y.shape), i)


@pytest.mark.parametrize("m,l", [(1, 1), (2, 2), (1, 2)])
def test_lqg_closed_form(m, l):
    pred = _predictor(m, l)
    rng = np.random.default_rng(0)
    Fq, Fr = rng.standard_normal((l, l)), rng.standard_normal((m, m))
    Q, R = Fq @ Fq.T + 0.5 * np.eye(l), Fr @ Fr.T + 0.1 * np.eye(m)
    d = lqg_design(pred, Q, R, dt=DT)
    i = pred.horizon
    Qd, Rd = np.kron(np.eye(i), Q), np.kron(np.eye(i), R)
    G = -np.linalg.solve(pred.Lu.T @ Qd @ pred.Lu + Rd, pred.Lu.T @ Qd @ pred.Lw)  # (4.2)
    assert np.allclose(d.gain, G, rtol=1e-9, atol=1e-12)
    assert d.gain.shape == (i * m, i * (m + l))
    K = d.controller
    assert K.nstates == i * (m + l) and K.dt == DT and K.ninputs == 2 * l and K.noutputs == m
    assert np.all(np.asarray(K.B)[:, :l] == 0) and np.all(np.asarray(K.D) == 0)  # the regulator ignores r


@pytest.mark.parametrize("m,l", [(1, 1), (2, 2)])
def test_theorem_4_2_hinf_tends_to_lqg(m, l):
    pred = _predictor(m, l, seed=4)
    rng = np.random.default_rng(1)
    Fq, Fr = rng.standard_normal((l, l)), rng.standard_normal((m, m))
    Q, R = Fq @ Fq.T + 0.5 * np.eye(l), Fr @ Fr.T + 0.1 * np.eye(m)
    W1 = np.linalg.cholesky(Q).T  # D1ᵀD1 = Q
    W2 = np.linalg.cholesky(R).T  # D2ᵀD2 = R
    lqg = lqg_design(pred, Q, R).gain
    errs = []
    for ratio in [1e1, 1e3, 1e6]:
        d = hinf_design(pred, W1, W2, gamma_ratio=ratio)
        assert [c for c, _ in d.columns] == ["w_p", "x_w1", "x_w2"]
        assert d.gain.shape[1] == pred.Lw.shape[1]  # constant weights: no weight states
        errs.append(np.linalg.norm(d.gain - lqg) / np.linalg.norm(lqg))
    assert errs[0] > errs[1] > errs[2]
    assert errs[2] < 1e-8
    assert np.allclose(hinf_design(pred, W1, W2, gamma=np.inf).gain, lqg, rtol=1e-10, atol=1e-12)


def test_bad_q_r():
    pred = _predictor(1, 1)
    with pytest.raises(DataError, match="positive definite"):
        lqg_design(pred, -1.0, 1.0)
    with pytest.raises(DataError, match="positive definite"):
        lqg_design(pred, 1.0, 0.0)
    with pytest.raises(DataError, match="matrix"):
        lqg_design(pred, np.eye(2), 1.0)
    with pytest.raises(DataError, match="symmetric"):
        lqg_design(_predictor(2, 2), np.array([[1.0, 0.5], [0.0, 1.0]]), np.eye(2))
    with pytest.raises(DataError, match="NaN"):
        lqg_design(pred, np.nan, 1.0)


def test_bad_sample_time():
    pred = _predictor(1, 1)
    assert lqg_design(pred, 1.0, 1.0, dt=0.1).controller.dt == 0.1
    assert lqg_design(pred, 1.0, 1.0).controller.dt is True
    for bad in (0, 0.0, -0.1, float("nan"), float("inf"), "0.1", False):
        with pytest.raises(DataError, match="dt"):
            lqg_design(pred, 1.0, 1.0, dt=bad)


def test_non_numeric_weights_are_named():
    pred = _predictor(1, 1)
    with pytest.raises(DataError, match="Q must be"):
        lqg_design(pred, "a", 1.0)


def test_weights_as_text_or_complex_are_refused_not_parsed():
    """lqg_design(pred, "1", 0.01) had parsed the string and designed with Q = 1."""
    pred = _predictor(1, 1)
    with pytest.raises(DataError, match=r"Q must be real numbers, not text \('1'\)"):
        lqg_design(pred, "1", 0.01)
    with pytest.raises(DataError, match=r"R must be real numbers, not text"):
        lqg_design(pred, 1.0, ["0.01"])
    with pytest.raises(DataError, match="R is complex"):
        lqg_design(pred, 1.0, 0.01 + 0j)
