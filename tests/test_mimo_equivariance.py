"""Several inputs and outputs: every computation moves with the channels.

Permuting or sign-flipping the input and output channels of a record (``u → u Tuᵀ``, ``y → y Tyᵀ``, ``Tu``, ``Ty``
signed permutations) is a change of coordinates.  The predictor's block rows and columns move with them (time-major
blocks of ``m`` and ``l``), a design on weights carried along (``W1 Ty⁻¹``, ``W2 Tu⁻¹``, …) has the same levels and
the controller ``Tu K diag(Ty⁻¹, Ty⁻¹)``, and δ, γ_min and the verdicts do not change.  A wrong channel order, a
transposed block or a mixed-up shape gives wrong numbers that no single-channel test sees; these tests see them.
Measured on 2–3 inputs and 1–3 outputs (2026-11-29): every deviation at rounding level.
"""
import warnings

import control
import numpy as np
import pytest
from scipy.linalg import block_diag

import synthesis as sy
import unfalsify as uf

SHAPES = [(3, 2), (2, 3)]  # (m, l): inputs × outputs, both non-square


def _plant(m, l, seed, dt=1.0):
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.standard_normal((4, 4)))
    A = Q @ np.diag(rng.uniform(0.3, 0.85, 4)) @ Q.T
    return control.ss(A, rng.standard_normal((4, m)), rng.standard_normal((l, 4)), np.zeros((l, m)), dt)


def _record(m, l, n, seed, noise=0.02):
    P = _plant(m, l, seed)
    rng = np.random.default_rng(seed + 1)
    u = rng.standard_normal((n, m))
    y = control.forced_response(P, T=np.arange(n), U=u.T).outputs.reshape(l, n).T
    return P, u, y + noise * rng.standard_normal((n, l))


def _signed_permutation(k, shift, flip):
    """``T`` with ``(T x)[a] = ±x[(a + shift) mod k]``, the sign of row ``flip`` negative."""
    T = np.eye(k)[np.roll(np.arange(k), -shift)]
    T[flip % k] *= -1
    return T


def _changes(m, l):
    """(name, Tu, Ty): inputs permuted, outputs permuted, both with a sign flipped."""
    return [("inputs", np.abs(_signed_permutation(m, 1, 0)), np.eye(l)),
            ("outputs", np.eye(m), np.abs(_signed_permutation(l, 1, 0))),
            ("both and signs", _signed_permutation(m, 1, m - 1), _signed_permutation(l, 2, 0))]


def _blocks(T, i):
    """``T`` on every time step of a time-major stack of ``i`` samples."""
    return np.kron(np.eye(i), T)


def _times(W, T):
    """The weight ``W T`` (its input in the new coordinates)."""
    W = control.ss(W)
    return control.ss(W.A, W.B @ T, W.C, W.D @ T, W.dt)


def _markov(K, k=10):
    """``D, CB, CAB, …``: the controller's input/output map, whatever its state coordinates."""
    out, X = [np.asarray(K.D)], np.asarray(K.B)
    for _ in range(k):
        out.append(np.asarray(K.C) @ X)
        X = np.asarray(K.A) @ X
    return np.stack(out)


def _close(a, b, rtol):
    return np.linalg.norm(np.asarray(a) - np.asarray(b)) <= rtol * np.linalg.norm(b)


@pytest.mark.parametrize("m, l", SHAPES)
@pytest.mark.parametrize("method", ["cholesky", "qr", "lstsq", "recursive"])
def test_the_predictor_blocks_move_with_the_channels(m, l, method):
    """``Lu' = (I⊗Ty) Lu (I⊗Tu⁻¹)``; ``Lw`` likewise on its ``u`` and ``y`` column blocks (3.13)."""
    i = 4
    _, u, y = _record(m, l, 300, seed=10 * m + l)

    def fit(a, b):
        if method != "recursive":
            return sy.fit_predictor(a, b, i, method=method)
        rp = sy.RecursivePredictor.from_data(a[:150], b[:150], i, window=120)
        for t in range(150, 300, 40):
            rp.push(a[t:t + 40], b[t:t + 40])
        return rp.predictor()

    p0 = fit(u, y)
    for name, Tu, Ty in _changes(m, l):
        p1 = fit(u @ Tu.T, y @ Ty.T)
        Tui, Tyi = Tu.T, Ty.T  # signed permutations are orthogonal
        assert _close(p1.Lu, _blocks(Ty, i) @ p0.Lu @ _blocks(Tui, i), 1e-9), name
        assert _close(p1.Lw, _blocks(Ty, i) @ p0.Lw @ block_diag(_blocks(Tui, i), _blocks(Tyi, i)), 1e-9), name
        assert (p1.rank, p1.input_rank) == (p0.rank, p0.input_rank)


def _weights(m, l):
    """Per-channel weights that differ (a permutation must move them) and a coupled W1."""
    W1 = sy.diagonal_weight(*[sy.makeweight(10.0 * (k + 1), (0.2 + 0.1 * k, 1.0), 0.3, 1.0) for k in range(l)])
    M = np.eye(l) + 0.3 * np.triu(np.ones((l, l)), 1)
    W1 = control.ss(W1.A, W1.B, M @ W1.C, M @ W1.D, 1.0)
    W2 = sy.diagonal_weight(*[sy.makeweight(0.05 * (k + 1), (1.0, 0.3), 1.0, 1.0) for k in range(m)])
    return W1, W2


def _uncertainty(kind, m, l, Tu=None, Ty=None):
    """The law's uncertainty weights, carried into new coordinates when ``Tu``, ``Ty`` are given."""
    Tu = np.eye(m) if Tu is None else Tu
    Ty = np.eye(l) if Ty is None else Ty
    if kind == "additive":   # W3 on u (m inputs), W4 onto y: W3 Tu⁻¹, Ty W4 Ty⁻¹ (s moves with y)
        W3 = sy.diagonal_weight(*[sy.makeweight(0.2 * (k + 1), (0.5, 1.0), 2.0, 1.0) for k in range(m)])
        W4 = control.ss([], [], [], np.diag(np.linspace(0.3, 0.6, l)), 1.0)
        return sy.Additive(_times(W3, Tu.T), control.ss([], [], [], Ty @ W4.D @ Ty.T, 1.0))
    if kind == "multiplicative":   # W3 on y (l inputs)
        W3 = sy.diagonal_weight(*[sy.makeweight(0.2 * (k + 1), (0.5, 1.0), 2.0, 1.0) for k in range(l)])
        W4 = control.ss([], [], [], np.diag(np.linspace(0.2, 0.4, l)), 1.0)
        return sy.Multiplicative(_times(W3, Ty.T), control.ss([], [], [], Ty @ W4.D @ Ty.T, 1.0))
    return None


def _columns(columns, Tu, Ty, i):
    """The change of the stacked vector ``v`` (``HinfDesign.columns``/``disturbances``): ``v' = X v``."""
    blocks = []
    for name, size in columns:
        if name == "w_p":
            blocks += [_blocks(Tu, i), _blocks(Ty, i)]
        elif name == "r_k":
            blocks.append(Ty)
        elif name in ("r", "s"):
            blocks.append(_blocks(Ty, size // Ty.shape[0]))
        else:  # weight states: the same coordinates
            blocks.append(np.eye(size))
    return block_diag(*blocks)


@pytest.mark.parametrize("m, l", SHAPES)
@pytest.mark.parametrize("law", ["nominal", "causal", "additive", "multiplicative"])
def test_the_laws_and_controllers_move_with_the_channels(m, l, law):
    """γ_min and γ unchanged; ``gain' = (I⊗Tu) gain X⁻¹``; the controller ``Tu K diag(Ty⁻¹, Ty⁻¹)``; the
    receding-horizon loop gives ``Tu u`` on the changed measurements."""
    i = 4
    _, u, y = _record(m, l, 300, seed=3 * m + l)
    W1, W2 = _weights(m, l)
    causal = law == "causal"
    kind = law if law in ("additive", "multiplicative") else None
    pred = sy.fit_predictor(u, y, i, dt=1.0)
    d0 = sy.hinf_design(pred, W1, W2, causal=causal, uncertainty=_uncertainty(kind, m, l), dt=1.0)
    for name, Tu, Ty in _changes(m, l):
        pred1 = sy.fit_predictor(u @ Tu.T, y @ Ty.T, i, dt=1.0)
        d1 = sy.hinf_design(pred1, _times(W1, Ty.T), _times(W2, Tu.T), causal=causal,
                            uncertainty=_uncertainty(kind, m, l, Tu, Ty), dt=1.0)
        assert d1.gamma_min == pytest.approx(d0.gamma_min, rel=1e-12), name
        assert d1.gamma == pytest.approx(d0.gamma, rel=1e-12), name
        X = _columns(d0.columns, Tu, Ty, i)
        assert _close(d1.gain, _blocks(Tu, i) @ d0.gain @ X.T, 1e-9), name
        R = block_diag(Ty.T, Ty.T)
        assert _close(_markov(d1.controller), np.einsum("ab,kbc,cd->kad", Tu, _markov(d0.controller), R), 1e-9), name
        rng = np.random.default_rng(5)
        r, ym = rng.standard_normal((15, l)), rng.standard_normal((15, l))
        loops = [sy.RecedingHorizonController(d0), sy.RecedingHorizonController(d1)]
        for k in range(15):
            u0 = loops[0].control(r[k] if causal else None)
            u1 = loops[1].control(Ty @ r[k] if causal else None)
            assert _close(u1, Tu @ u0, 1e-9), name
            loops[0].observe(u0, ym[k], r[k])
            loops[1].observe(u1, Ty @ ym[k], Ty @ r[k])


@pytest.mark.parametrize("m, l", SHAPES)
def test_the_lqg_law_moves_with_the_channels(m, l):
    i = 4
    _, u, y = _record(m, l, 300, seed=7)
    rng = np.random.default_rng(3)
    A, B = rng.standard_normal((l, l)), rng.standard_normal((m, m))
    Q, R = A @ A.T + np.eye(l), 0.1 * (B @ B.T + np.eye(m))
    d0 = sy.lqg_design(sy.fit_predictor(u, y, i, dt=1.0), Q, R, dt=1.0)
    for name, Tu, Ty in _changes(m, l):
        d1 = sy.lqg_design(sy.fit_predictor(u @ Tu.T, y @ Ty.T, i, dt=1.0), Ty @ Q @ Ty.T, Tu @ R @ Tu.T, dt=1.0)
        assert _close(d1.gain, _blocks(Tu, i) @ d0.gain @ _columns(d0.columns, Tu, Ty, i).T, 1e-9), name


@pytest.mark.parametrize("m, l", [(2, 1), (2, 2), (1, 2)])
def test_delta_does_not_depend_on_the_channel_order(m, l):
    """Theorem 7.1, (7.4) and (7.5) (structured backends): δ unchanged, ``T(h)`` blocks ``Ty h Tu⁻¹``."""
    rng = np.random.default_rng(m + 4 * l)
    n = 40
    u = np.sign(rng.standard_normal((n, m)))
    y = np.stack([np.convolve(u[:, b], [0.0, 0.5, 0.3, 0.1])[:n] for b in range(m)], axis=1)
    y = y @ rng.standard_normal((l, m)).T + 0.1 * rng.standard_normal((n, l))
    g0 = uf.unfalsified_gain_result(u[:20], y[:20], warn=False)
    _, rms = uf.arx_least_squares(u[:16], y[:16], 1, 1)
    a0 = uf.arx_unfalsify(u[:16], y[:16], 1, 1, 0.5 * rms, backend="structured", progress=False)
    i = 2
    A, _, Yf = uf.subspace_data(u, y, i)
    sigma = 0.5 * float(np.sqrt(np.mean((Yf - np.linalg.lstsq(A.T, Yf.T, rcond=None)[0].T @ A) ** 2)))
    s0 = uf.subspace_unfalsify(u, y, i, sigma, backend="structured", progress=False)
    for name, Tu, Ty in _changes(m, l):
        u1, y1 = u @ Tu.T, y @ Ty.T
        g1 = uf.unfalsified_gain_result(u1[:20], y1[:20], warn=False)
        assert g1.gamma == pytest.approx(g0.gamma, rel=1e-10), name
        a1 = uf.arx_unfalsify(u1[:16], y1[:16], 1, 1, 0.5 * rms, backend="structured", progress=False)
        assert a1.delta == pytest.approx(a0.delta, rel=1e-9), name
        h0 = np.asarray(a0.impulse).reshape(16, l, m)
        assert _close(np.asarray(a1.impulse).reshape(16, l, m), np.einsum("ab,kbc,cd->kad", Ty, h0, Tu.T), 1e-6)
        s1 = uf.subspace_unfalsify(u1, y1, i, sigma, backend="structured", progress=False)
        assert s1.delta == pytest.approx(s0.delta, rel=1e-9), name
        assert _close(s1.Lu, _blocks(Ty, i) @ s0.Lu @ _blocks(Tu.T, i), 1e-6), name


def _mode_record(m, l, n=900):
    """FIR channels and a lightly damped mode (0.8 rad/sample, pole radius 0.999) from u[:, 0] to every output."""
    import scipy.signal
    rng = np.random.default_rng(11)
    u = rng.standard_normal((n, m))
    y = np.stack([np.convolve(u[:, min(o, m - 1)], [0.0, 1.0, 0.5])[:n] for o in range(l)], axis=1)
    mode = scipy.signal.lfilter([0.0, 0.02], [1.0, -2 * 0.999 * np.cos(0.8), 0.999 ** 2], u[:, 0])
    return u, y + 0.01 * rng.standard_normal((n, l)) + mode[:, None]


@pytest.mark.parametrize("m, l", [(2, 1), (2, 2), (1, 2)])
def test_loop_checks_do_not_depend_on_the_channel_order(m, l):
    """certify_loop (verdict, small-gain product), the narrow-line test, the excitation check."""
    u, y = _mode_record(m, l)
    K = control.ss([], [], [], np.hstack([0.2 * np.eye(m, l), -0.2 * np.eye(m, l)]), 1.0)
    pred = sy.fit_predictor(u[:600], y[:600], 3)
    model = uf.predictor_model(pred, 1.0)
    c0 = uf.certify_loop(model, K, 0.05, tracking_floor=10.0)
    line0 = uf.residual_line(model, K, u, y, 3, 1.0)
    assert line0[0] > 0  # the mode is seen: the test compares a line, not two zeros
    e = uf.output_error_residual(model, u[600:], y[600:], 3)
    ex0 = uf.check_excitation(model, K, uf.frequency_response_estimate(u[603:], e, 1.0), delta=0.05)
    for name, Tu, Ty in _changes(m, l):
        u1, y1 = u @ Tu.T, y @ Ty.T
        model1 = uf.predictor_model(sy.fit_predictor(u1[:600], y1[:600], 3), 1.0)
        Kd = Tu @ np.asarray(K.D) @ block_diag(Ty.T, Ty.T)
        K1 = control.ss([], [], [], Kd, 1.0)
        c1 = uf.certify_loop(model1, K1, 0.05, tracking_floor=10.0)
        assert c1.certified == c0.certified and c1.small_gain == pytest.approx(c0.small_gain, rel=1e-9), name
        line1 = uf.residual_line(model1, K1, u1, y1, 3, 1.0)
        assert line1[0] == pytest.approx(line0[0], rel=1e-9) and line1[1] == pytest.approx(line0[1]), name
        e1 = uf.output_error_residual(model1, u1[600:], y1[600:], 3)
        assert _close(e1, e @ Ty.T, 1e-9), name
        ex1 = uf.check_excitation(model1, K1, uf.frequency_response_estimate(u1[603:], e1, 1.0), delta=0.05)
        assert ex1.ok == ex0.ok and ex1.worst == pytest.approx(ex0.worst, rel=1e-9), name
        assert ex1.margin == pytest.approx(ex0.margin, rel=1e-9), name


def test_the_robust_design_verdict_does_not_depend_on_the_channel_order():
    """§7.4 on 2 × 2 data: the verdict, δ, γ and the shipped controller move with the channels."""
    rng = np.random.default_rng(0)
    n, G = 900, np.array([[1.0, 0.3], [0.2, 0.8]])
    P = control.ss(0.7 * np.eye(2), 0.3 * np.eye(2), G, np.zeros((2, 2)), 1.0)
    u = np.sign(rng.standard_normal((n, 2)))
    y = control.forced_response(P, T=np.arange(n), U=u.T).outputs.T + 0.01 * rng.standard_normal((n, 2))
    W1 = sy.diagonal_weight(sy.makeweight(100, (np.pi / 30, 1), 0.2, 1.0), sy.makeweight(50, (np.pi / 40, 1), 0.2, 1.0))
    W2 = sy.diagonal_weight(sy.makeweight(0.05, (np.pi / 10, 0.3), 1, 1.0), channels=2)
    Tu, Ty = _signed_permutation(2, 1, 1), _signed_permutation(2, 1, 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r0 = uf.robust_design_from_data(u, y, 2, W1, W2, "auto", window="auto", dt=1.0, search=False)
        r1 = uf.robust_design_from_data(u @ Tu.T, y @ Ty.T, 2, _times(W1, Ty.T), _times(W2, Tu.T), "auto",
                                        window="auto", dt=1.0, search=False)
    assert (r1.certified, r1.uncertainty, r1.window) == (r0.certified, r0.uncertainty, r0.window)
    assert r1.delta == pytest.approx(r0.delta, rel=1e-9) and r1.gamma == pytest.approx(r0.gamma, rel=1e-9)
    assert r1.w3_gain == pytest.approx(r0.w3_gain, rel=1e-9)
    R = block_diag(Ty.T, Ty.T)
    assert _close(_markov(r1.design.controller), np.einsum("ab,kbc,cd->kad", Tu, _markov(r0.design.controller), R),
                  1e-8)
