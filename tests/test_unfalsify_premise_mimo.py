"""The frequency-domain premise tests for several inputs and outputs (issue 28, item 3).

H1 Welch estimate ``D̂ = S_eu S_uu⁻¹`` with a spectral-norm confidence radius, the local polynomial method with m
input columns, and ``check_excitation`` by ``σ̄(D̂M̂) ± σ̄(QM̂)`` (``Q`` the region's factor; ``r·σ̄(M̂)`` for one
input); m = l = 1 must give the SISO numbers.
"""
import re

import control
import numpy as np
import pytest

import unfalsify as uf
from synthesis._validation import DataError
from unfalsify.frequency_response import _local_fit, _local_fit_mimo, _mimo_welch, _record_pair
from unfalsify.premise import _frf_inconsistency, _low_band_inconsistency

SHAPES = [(2, 2), (2, 1), (1, 2)]  # (l, m): outputs × inputs


def _taps(l, m):
    """A fixed FIR operator of 3 taps, l × m each (‖D‖∞ of a few units)."""
    return np.random.default_rng(123).standard_normal((3, l, m))


def _filter(h, u):
    y = np.zeros((u.shape[0], h.shape[1]))
    for t in range(h.shape[0]):
        y[t:] += u[:u.shape[0] - t] @ h[t].T
    return y


def _response(h, omega):
    """The true (F, l, m) response, second route: the DTFT of the taps."""
    z = np.exp(-1j * np.outer(omega, np.arange(h.shape[0])))
    return np.einsum("ft,tlm->flm", z, h)


def _data(l, m, n, noise, seed):
    rng = np.random.default_rng(seed)
    h = _taps(l, m)
    u = rng.standard_normal((n, m))
    return h, u, _filter(h, u) + noise * rng.standard_normal((n, l))


def _err(est, h):
    return np.linalg.norm(est.response - _response(h, est.frequency), ord=2, axis=(1, 2))


# ---- the Welch (H1) estimate and its radius ----------------------------------------------------------------

@pytest.mark.parametrize("l,m", SHAPES)
def test_region_covers_the_true_response_over_seeds(l, m):
    misses = 0
    for seed in range(6):
        h, u, y = _data(l, m, 2048, 0.3, seed)
        est = uf.frequency_response_estimate(u, y)
        assert est.response.shape == (est.frequency.size, l, m) and est.radius.shape == est.frequency.shape
        assert (est.inputs, est.outputs) == (m, l) and est.input_psd.shape[1:] == (m, m)
        assert est.noise_psd.shape[1:] == (l, l) and est.coherence.shape[1:] == (l,)
        misses += bool(np.any(_err(est, h) > est.radius))
        assert np.all(est.excited) and np.median(est.radius) < 1.5  # ‖D‖ is 1–5 here; measured median ≤ 1.3
    assert misses <= 1  # simultaneous 99 % per record (measured: 0 of 20 records each shape)


@pytest.mark.parametrize("l,m", SHAPES)
def test_estimate_converges_to_the_true_response(l, m):
    h, u, y = _data(l, m, 2048, 0.0, 4)
    est = uf.frequency_response_estimate(u, y)
    assert np.max(_err(est, h)[1:]) < 0.05  # noise free: Hann leakage of a 3-tap response only
    errs, radii = [], []
    for n in (2048, 16384):
        h, u, y = _data(l, m, n, 0.3, 5)
        est = uf.frequency_response_estimate(u, y, nperseg=128)
        errs.append(np.median(_err(est, h)))
        radii.append(np.median(est.radius))
    assert errs[1] < 0.5 * errs[0] and radii[1] < 0.5 * radii[0]  # 8× the averages: ≈ 1/√8 (measured 0.35)


def test_siso_data_through_the_mimo_estimator_give_the_siso_numbers():
    rng = np.random.default_rng(2)
    u = rng.standard_normal(3000)
    y = np.convolve(u, [0.0, 1.0, 0.5, -0.25])[:3000] + 0.2 * rng.standard_normal(3000)
    siso = uf.frequency_response_estimate(u, y, nperseg=128, segments=[(u[:1000], y[:1000])])
    mimo = _mimo_welch([_record_pair(u, y), _record_pair(u[:1000], y[:1000])], 128, 1.0, 0.99)
    assert siso.response.shape == (65,) and mimo.response.shape == (65, 1, 1)
    np.testing.assert_allclose(mimo.response[:, 0, 0], siso.response, rtol=1e-12, atol=0)
    np.testing.assert_allclose(mimo.radius, siso.radius, rtol=1e-12)  # measured 9e-14 (S_vv by a matrix product)
    np.testing.assert_allclose(mimo.input_psd[:, 0, 0], siso.input_psd, rtol=1e-12)
    np.testing.assert_allclose(mimo.noise_psd[:, 0, 0].real, siso.noise_psd, rtol=1e-10, atol=1e-15)
    np.testing.assert_allclose(mimo.coherence[:, 0], siso.coherence, rtol=1e-12, atol=1e-15)
    assert mimo.averages == siso.averages and np.array_equal(mimo.excited, siso.excited)
    np.testing.assert_array_equal(mimo.gain, np.abs(mimo.response[:, 0, 0]))
    # a column vector is SISO too, and the public function keeps the 1-D fields
    col = uf.frequency_response_estimate(u[:, None], y[:, None], nperseg=128, segments=[(u[:1000], y[:1000])])
    np.testing.assert_array_equal(col.response, siso.response)
    np.testing.assert_array_equal(col.radius, siso.radius)


def test_a_silent_input_channel_has_an_infinite_radius_and_is_refused_by_name():
    rng = np.random.default_rng(0)
    u = np.column_stack([rng.standard_normal(4096), np.zeros(4096)])
    e = 0.05 * rng.standard_normal((4096, 2))
    est = uf.frequency_response_estimate(u, e)
    assert np.all(np.isinf(est.radius)) and not np.any(est.excited) and np.all(np.isnan(est.response))
    assert np.isnan(_frf_inconsistency(est, 0.1)[0])
    P = control.ss([], [], [], np.eye(2), 1.0)
    K = control.ss([], [], [], np.hstack([0.5 * np.eye(2), -0.5 * np.eye(2)]), 1.0)
    ex = uf.check_excitation(P, K, est)
    assert not ex.ok and "u[:, 1]" in ex.reason and "excite" in ex.reason and "on input u[:, 1]" in ex.reason
    # the low band of the same record: the local fit is rank deficient, nothing is known
    low = uf.low_band_estimate(u, e, bins=4)
    assert np.all(np.isinf(low.radius))
    assert uf.check_excitation(P, K, est, low).reason == ex.reason  # the low band adds no evidence


def test_a_channel_silent_in_a_band_is_named_with_the_band():
    import scipy.signal

    rng = np.random.default_rng(1)
    b, a = scipy.signal.butter(6, 0.2)
    u = np.column_stack([rng.standard_normal(4096), scipy.signal.lfilter(b, a, rng.standard_normal(4096))])
    e = 0.05 * rng.standard_normal((4096, 2))
    est = uf.frequency_response_estimate(u, e)
    high = est.frequency > 0.6 * np.pi
    assert not np.any(est.excited[high]) and np.all(est.excited[(est.frequency > 0) & (est.frequency < 0.1 * np.pi)])
    assert np.min(est.radius[high]) > 10 * np.max(est.radius[(est.frequency > 0) & (est.frequency < 0.1 * np.pi)])
    P = control.ss([], [], [], np.eye(2), 1.0)
    K = control.ss([], [], [], np.hstack([0.5 * np.eye(2), -0.5 * np.eye(2)]), 1.0)
    ex = uf.check_excitation(P, K, est)
    assert not ex.ok and ex.frequency > 0.2 * np.pi
    assert "input u[:, 1] has the least power there" in ex.reason and "rad/sample" in ex.reason
    import re

    below = re.search(r"least power there, ([0-9-]+) dB below its own peak", ex.reason)
    assert below and int(below.group(1)) > 20  # a positive number of dB below (it had read "down to -95 dB below")
    ex1 = uf.check_excitation(control.ss([], [], [], 1.0, 1.0), control.ss([], [], [], [[0.5, -0.5]], 1.0),
                              uf.frequency_response_estimate(u[:, 1], e[:, 0]))
    below = re.search(r"the input's power there falls to ([0-9-]+) dB below its peak", ex1.reason)
    assert not ex1.ok and below and int(below.group(1)) > 20


def test_collinear_inputs_are_not_excited_although_every_channel_has_power():
    rng = np.random.default_rng(3)
    w = rng.standard_normal(4096)
    u = np.column_stack([w, 2.0 * w])  # both channels loud, one direction only
    est = uf.frequency_response_estimate(u, 0.05 * rng.standard_normal((4096, 1)))
    assert not np.any(est.excited) and np.all(np.isinf(est.radius))
    u[:, 1] += 1e-4 * rng.standard_normal(4096)  # nearly collinear: finite but useless radius, named as such
    est = uf.frequency_response_estimate(u, 0.05 * rng.standard_normal((4096, 1)))
    assert not np.any(est.excited) and np.min(est.radius) > 100
    P = control.ss([], [], [], np.ones((1, 2)), 1.0)
    K = control.ss([], [], [], [[0.3, -0.3], [0.3, -0.3]], 1.0)
    ex = uf.check_excitation(P, K, est)
    assert not ex.ok and "move together" in ex.reason and "in every input direction" in ex.reason


def test_bad_shapes_name_the_fix():
    rng = np.random.default_rng(0)
    u, y = rng.standard_normal((500, 2)), rng.standard_normal((500, 2))
    with pytest.raises(DataError, match="time along axis 0"):
        uf.frequency_response_estimate(u, y[:499])
    with pytest.raises(DataError, match="channels of the first record"):
        uf.frequency_response_estimate(u, y, segments=[(u[:, :1], y)])
    with pytest.raises(DataError, match="x.T|axis 0"):
        uf.frequency_response_estimate(u.T, y.T)
    with pytest.raises(DataError, match="window ≥ 18"):
        uf.low_band_estimate(u, y, bins=2, window=16)
    with pytest.raises(DataError, match="longer record"):
        uf.low_band_estimate(u[:39], y[:39], bins=2)  # two inputs: window 18, needs 2·(2 + 18) = 40 samples
    assert uf.low_band_estimate(u[:40], y[:40], bins=2).window == 18
    from unfalsify.premise import _low_bins  # the pipeline's bin count knows the wider window of two inputs

    assert (_low_bins(40, 16, 2), _low_bins(39, 16, 2), _low_bins(36, 16), _low_bins(35, 16)) == (2, 0, 2, 0)


# ---- the local polynomial method -----------------------------------------------------------------------

@pytest.mark.parametrize("l,m", SHAPES)
def test_low_band_region_covers_the_true_response(l, m):
    misses = 0
    for seed in range(6):
        h, u, y = _data(l, m, 2048, 0.3, 10 + seed)
        est = uf.low_band_estimate(u, y, bins=8)
        assert est.response.shape == (8, l, m) and est.window == max(16, 6 * (m + 1))
        misses += bool(np.any(_err(est, h) > est.radius))
        # not vacuous: measured median 0.4–1.7 (‖D(1)‖₂ ≈ 1.2); widest at bin 1, where the fit extrapolates
        assert np.median(est.radius) < 2.0 and est.radius[0] >= est.radius[-1]
    assert misses <= 1
    h, u, y = _data(l, m, 2048, 0.0, 3)
    np.testing.assert_allclose(uf.low_band_estimate(u, y, bins=6).response, _response(h, 2 * np.pi * np.arange(1, 7)
                                                                                   / 2048), atol=1e-3)


def test_low_band_siso_fit_through_the_mimo_fit_is_the_same():
    rng = np.random.default_rng(4)
    U = np.fft.rfft(rng.standard_normal(600))[1:17]
    Y = (0.7 + 0.2j) * U + 0.1 * (rng.standard_normal(16) + 1j * rng.standard_normal(16))
    for at in (0, 3, 8):
        g, r = _local_fit(U, Y, at, 1e-3)
        G, R, _ = _local_fit_mimo(U[:, None], Y[:, None], at, 1e-3)
        assert G.shape == (1, 1) and abs(G[0, 0] - g) <= 1e-12 * abs(g) and R == pytest.approx(r, rel=1e-12)


# ---- inconsistency with δ and the excitation check ---------------------------------------------------------

def _fake(response, radius, low=False):
    """A MIMO estimate with the given (F, l, m) response and (F,) radius on 0…π."""
    response = np.asarray(response, complex)
    F, l, m = response.shape
    f = np.linspace(0.01 if low else 0.0, 0.05 if low else np.pi, F)
    if low:
        return uf.LowBandEstimate(frequency=f, response=response, radius=np.asarray(radius, float), confidence=0.99,
                                  window=18, degree=2, samples=1000, dt=1.0)
    return uf.FrequencyResponseEstimate(frequency=f, response=response, radius=np.asarray(radius, float),
                                        coherence=np.ones((F, l)), input_psd=np.tile(np.eye(m), (F, 1, 1)),
                                        noise_psd=np.zeros((F, l, l)), averages=30.0, confidence=0.99,
                                        nperseg=2 * (F - 1), dt=1.0)


def test_mimo_inconsistency_uses_the_largest_singular_value_and_names_the_entry():
    D = np.zeros((5, 2, 2), complex)
    D[2] = [[0.0, 0.0], [0.5, 0.0]]  # u[:, 0] → y[:, 1]
    worst, why = _frf_inconsistency(_fake(D, np.full(5, 0.1)), 0.2)
    assert worst == pytest.approx(2.0) and "from input u[:, 0] to output y[:, 1]" in why and "1.57 rad/sample" in why
    assert _frf_inconsistency(_fake(D, np.full(5, 0.1)), 0.5)[1] == ""
    worst, why = _low_band_inconsistency(_fake(D, np.full(5, 0.1), low=True), 0.2)
    assert worst == pytest.approx(2.0) and "at low frequency" in why and "u[:, 0] to output y[:, 1]" in why


def test_low_band_evidence_looks_in_the_direction_the_loop_sees():
    """‖D̂‖₂ − r large in a direction M̂ does not reach is no evidence against the loop; in its direction it is."""
    P = control.ss([], [], [], np.zeros((2, 2)), 1.0)  # P̂ = 0: M̂ = C_y
    K = control.ss([], [], [], np.hstack([np.zeros((2, 2)), np.diag([0.0, 0.5])]), 1.0)  # C_y = diag(0, 0.5)
    welch = _fake(np.zeros((9, 2, 2)), np.full(9, 0.01))
    blind = np.tile(np.diag([5.0, 0.0]), (3, 1, 1))  # D̂ M̂ = 0: (‖D̂‖ − r)‖M̂‖ = 2.45 but σ̄(D̂M̂) − r‖M̂‖ < 0
    ok = uf.check_excitation(P, K, welch, _fake(blind, np.full(3, 0.1), low=True))
    assert ok.ok and ok.worst == pytest.approx(0.005)  # from the Welch frequencies: (0 + 0.01)·0.5
    seen = np.tile(np.diag([0.0, 5.0]), (3, 1, 1))  # σ̄(D̂M̂) = 2.5, minus r·0.5
    bad = uf.check_excitation(P, K, welch, _fake(seen, np.full(3, 0.1), low=True))
    assert not bad.ok and bad.worst == pytest.approx(2.45) and "differs from P̂" in bad.reason
    assert "σ̄(D̂M̂) − r·σ̄(M̂)" in bad.reason  # the low band's lower bound (it had read +); no region: the radius
    # the Welch test is directional too: a large D̂ the loop does not see passes, the one it sees does not
    assert uf.check_excitation(P, K, _fake(np.tile(np.diag([5.0, 0.0]), (9, 1, 1)), np.full(9, 0.01))).ok
    assert not uf.check_excitation(P, K, _fake(np.tile(np.diag([0.0, 5.0]), (9, 1, 1)), np.full(9, 0.01))).ok
    with pytest.raises(DataError, match="same"):
        uf.check_excitation(P, K, _fake(np.zeros((9, 1, 2)), np.full(9, 0.01)))


def test_delta_margin_evidence_mimo_is_the_largest_singular_value_on_the_plant():
    """P̂ = 4I, D̂ = diag(−3, 0) (the plant is diag(1, 4)), C_y = −2I: δ·σ̄(M_P) = δ·2/3 on the first channel,
    where σ̄(M̂) is only 2/9; the low-band estimate alone carries the evidence here (the Welch D̂ is 0)."""
    P_hat = control.ss([], [], [], 4.0 * np.eye(2), 1.0)
    K = control.ss([], [], [], np.hstack([2.0 * np.eye(2), -2.0 * np.eye(2)]), 1.0)
    M_P = uf.additive_channel(control.ss([], [], [], np.diag([1.0, 4.0]), 1.0), K)
    sigma = float(np.linalg.norm(np.real(control.dcgain(M_P)), 2))  # second route: the plant's own map
    welch = _fake(np.zeros((9, 2, 2)), np.full(9, 0.01))
    low = _fake(np.tile(np.diag([-3.0, 0.0]), (3, 1, 1)), np.zeros(3), low=True)
    ex = uf.check_excitation(P_hat, K, welch, low, delta=2.0)
    assert sigma == pytest.approx(2.0 / 3.0, rel=1e-12)
    assert ex.margin == pytest.approx(2.0 * sigma, rel=1e-9) and not ex.ok and "δ margin" in ex.reason
    assert uf.check_excitation(P_hat, K, welch, low, delta=1.0).ok
    with pytest.raises(DataError, match="delta must be a number ≥ 0"):
        uf.check_excitation(P_hat, K, welch, low, delta=float("nan"))


def test_epsilon_margin_evidence_mimo_is_the_plants_own_coprime_channel():
    """2 × 2 coprime form: P̂ = 4I as factors (M̂, N̂) = (I, 4I), R̂ = diag(−3, 0) (the plant diag(1, 4)), C_y = −2I.
    With a zero radius the evidence is ε·σ̄ of the coprime channel of the plant's factors (I, diag(1, 4)), computed
    by coprime_channel (the second route); with radius r it is ε·σ̄(Ẑ)/(1 + r·σ̄(Ẑ_u))."""
    def factors(N0):
        return uf.CoprimeFactors(N=np.stack([N0, np.zeros((2, 2))]), M=np.stack([np.eye(2), np.zeros((2, 2))]), dt=1.0)

    F = factors(4.0 * np.eye(2))
    K = control.ss([], [], [], np.hstack([2.0 * np.eye(2), -2.0 * np.eye(2)]), 1.0)
    H_P = np.real(control.dcgain(uf.coprime_channel(factors(np.diag([1.0, 4.0])), K)))  # (4, 2): u rows, y rows
    sigma, sigma_u = np.linalg.norm(H_P, 2), np.linalg.norm(H_P[:2], 2)
    R = np.tile(np.diag([-3.0, 0.0]), (9, 1, 1))
    exact = uf.check_excitation(F.model(), K, _fake(R, np.zeros(9)), factors=F, delta=1.0)
    assert exact.margin == pytest.approx(sigma, rel=1e-9)
    ex = uf.check_excitation(F.model(), K, _fake(R, np.full(9, 0.05)), factors=F, delta=2.0)
    assert ex.margin == pytest.approx(2.0 * sigma / (1.0 + 0.05 * sigma_u), rel=1e-9)
    assert not ex.ok and "ε margin" in ex.reason


def test_check_excitation_mimo_path_on_siso_data_gives_the_siso_numbers():
    rng = np.random.default_rng(6)
    u = rng.standard_normal(2048)
    e = np.convolve(u, [0.0, 0.05, 0.02])[:2048] + 0.05 * rng.standard_normal(2048)
    frf, low = uf.frequency_response_estimate(u, e), uf.low_band_estimate(u, e, bins=8)
    P = control.ss(control.tf([0.5], [1, -0.5], 1.0))
    for gain in (0.4, 3.0):  # passes, and refused
        K = control.ss([], [], [], [[gain, -gain]], 1.0)
        siso = uf.check_excitation(P, K, frf, low)
        as3 = lambda x: x.reshape(-1, 1, 1)  # noqa: E731
        frf3 = type(frf)(**{**{k: getattr(frf, k) for k in frf.__dataclass_fields__}, "response": as3(frf.response),
                            "input_psd": as3(frf.input_psd), "noise_psd": as3(frf.noise_psd),
                            "coherence": frf.coherence[:, None]})
        low3 = type(low)(**{**{k: getattr(low, k) for k in low.__dataclass_fields__}, "response": as3(low.response)})
        mimo = uf.check_excitation(P, K, frf3, low3)
        assert mimo.ok == siso.ok and mimo.worst == pytest.approx(siso.worst, rel=1e-12)
        assert mimo.frequency == siso.frequency


def test_a_record_too_short_for_a_confidence_region_is_not_said_to_excite_nothing():
    """A 2 × 2 record of 40 samples under white ±1 inputs excites every frequency, but two Welch segments leave no
    finite confidence radius: the premise test had said "the record excites no frequency" (the held-out third of a
    150-sample record given to the design command)."""
    rng = np.random.default_rng(0)
    u = np.sign(rng.standard_normal((40, 2)))
    y = u @ np.array([[1.0, 0.5], [0.2, 1.0]]) + 0.05 * rng.standard_normal((40, 2))
    est = uf.frequency_response_estimate(u, y, 0.1)
    assert est.excited.any() and not np.isfinite(est.radius).any()
    worst, why = _frf_inconsistency(est, 0.1)
    assert np.isnan(worst) and "too short for a confidence region" in why and "record longer" in why
    assert "excites no frequency" not in why


def test_a_short_output_error_segment_names_a_fix_for_record_mode():
    """Record mode (``window=``, the design command) gives the output-error test the record's last third; its refusal
    had said only "pass a longer validation record", which the design command has no option for."""
    rng = np.random.default_rng(1)
    u = np.sign(rng.standard_normal(30))
    y = np.convolve(u, [0.0, 0.5, 0.25])[:30]
    model = control.ss([[0.0]], [[1.0]], [[0.5]], [[0.0]], 1.0)
    with pytest.raises(DataError, match=r"needs at least 48.*a record three times that long\), or lower the horizon"):
        uf.output_error_unfalsify(model, u, y, 8, held_out=True)


# ---- excitation does not depend on the inputs' units ------------------------------------------------------------

def _two_input_record(seed=0, n=1500):
    """A 2 × 2 record under independent white ±1 inputs (the FIR taps of ``_taps``, output noise 0.05)."""
    rng = np.random.default_rng(seed)
    u = np.sign(rng.standard_normal((n, 2)))
    return u, _filter(_taps(2, 2), u) + 0.05 * rng.standard_normal((n, 2))


@pytest.mark.parametrize("units", [(1e-3, 1e3), (1e3, 1e-3), (1.0, 1e-2)])
def test_excitation_is_the_same_in_other_input_units(units):
    """Both inputs excite every frequency whatever their units: in units 10⁻³ and 10³, ``λ_min/λ_max(S_uu) ≈ 10⁻¹²``
    had excited no frequency, and the §7.4 pipeline had refused with "the record excites no frequency"."""
    u, y = _two_input_record()
    base = uf.frequency_response_estimate(u, y, 0.1)
    est = uf.frequency_response_estimate(u * np.array(units), y, 0.1)
    assert np.all(base.excited)
    np.testing.assert_array_equal(est.excited, base.excited)
    np.testing.assert_array_equal(np.isfinite(est.radius), np.isfinite(base.radius))
    # the estimate is the same operator in the record's units: Ĝ diag(1/units)
    np.testing.assert_allclose(est.response, base.response / np.array(units), rtol=1e-8)
    assert "excites no frequency" not in _frf_inconsistency(est, 0.1)[1]


def test_the_low_band_fit_is_the_same_in_other_input_units():
    """The local polynomial fit decides its rank on unit-norm columns: in units 10⁻⁶ and 10⁶ it had dropped four of
    six bins as rank deficient."""
    u, y = _two_input_record()
    base = uf.low_band_estimate(u, y, 0.1, bins=6)
    est = uf.low_band_estimate(u * [1e-6, 1e6], y, 0.1, bins=6)
    assert np.all(np.isfinite(base.radius)) and np.all(np.isfinite(est.radius))
    np.testing.assert_allclose(est.response, base.response / np.array([1e-6, 1e6]), rtol=1e-8)


def test_persistence_is_the_same_in_other_input_units():
    """The window's rank test (a predictor that records no ranks) on unit-rms channels: in units 10⁻⁶ and 10⁶ the
    rank had been half of 2i·m and the record called not persistently exciting."""
    from unfalsify.robust import _persistence_reason

    u, _ = _two_input_record()
    assert _persistence_reason(object(), u, 5, "predictor") == ""
    assert _persistence_reason(object(), u * [1e-6, 1e6], 5, "predictor") == ""
    # a genuinely collinear pair is still refused, in any units
    assert "not persistently exciting" in _persistence_reason(object(), np.column_stack([u[:, 0], 2e6 * u[:, 0]]),
                                                              5, "predictor")


def test_an_unexcited_direction_stays_unexcited_in_any_units():
    """Normalising the channels does not excite what is not: two inputs moving together, a silent channel, a channel
    silent in a band (named, not the channel in small units), and a record whose inputs are all silent."""
    import scipy.signal

    rng = np.random.default_rng(3)
    w = rng.standard_normal(4096)
    e = 0.05 * rng.standard_normal((4096, 2))
    for units in [(1.0, 1.0), (1e-3, 1e3), (1e3, 1e-3)]:
        s = np.array(units)
        together = uf.frequency_response_estimate(np.column_stack([w, 2.0 * w]) * s, e)
        silent = uf.frequency_response_estimate(np.column_stack([w, np.zeros(4096)]) * s, e)
        assert not np.any(together.excited) and np.all(np.isinf(together.radius))
        assert not np.any(silent.excited) and np.all(np.isinf(silent.radius))
    b, a = scipy.signal.butter(6, 0.2)
    u = np.column_stack([1e-3 * rng.standard_normal(4096), 1e3 * scipy.signal.lfilter(b, a, rng.standard_normal(4096))])
    est = uf.frequency_response_estimate(u, e)
    high = est.frequency > 0.6 * np.pi
    assert not np.any(est.excited[high]) and np.all(est.excited[(est.frequency > 0) & (est.frequency < 0.1 * np.pi)])
    P = control.ss([], [], [], np.eye(2), 1.0)
    K = control.ss([], [], [], np.hstack([0.5 * np.eye(2), -0.5 * np.eye(2)]), 1.0)
    ex = uf.check_excitation(P, K, est)
    assert not ex.ok and "input u[:, 1] has the least power there" in ex.reason and "on input u[:, 1]" in ex.reason
    quiet = uf.frequency_response_estimate(np.zeros((4096, 2)), e)
    assert not np.any(quiet.excited)
    assert _frf_inconsistency(quiet, 0.1)[1] == "the record excites no frequency"


# ---- the confidence region's directions: σ̄(QM̂) in place of r·σ̄(M̂) ------------------------------------------------

def _in_units(sys_, rows=None, cols=None):
    """``diag(rows)·sys·diag(cols)`` (a system in other input units: P̂ → P̂D⁻¹, K's outputs → DK)."""
    out = sys_
    if cols is not None:
        out = out * control.ss([], [], [], np.diag(cols), sys_.dt)
    if rows is not None:
        out = control.ss([], [], [], np.diag(rows), sys_.dt) * out
    return out


def _loop_record(seed=0, n=3000):
    """A 2 × 2 plant, a model of it with a slower first pole, correlated ±1 inputs and the model's output error."""
    rng = np.random.default_rng(seed)
    u = np.sign(rng.standard_normal((n, 2))) @ np.array([[1.0, 0.6], [0.0, 0.8]])
    C = np.array([[1.0, 0.4], [0.3, 1.0]])
    P = control.ss(np.diag([0.8, 0.5]), np.eye(2), C, np.zeros((2, 2)), 1.0)
    P_hat = control.ss(np.diag([0.75, 0.5]), np.eye(2), C, np.zeros((2, 2)), 1.0)
    y = control.forced_response(P, U=u.T).outputs.T + 0.05 * rng.standard_normal((n, 2))
    return P_hat, u, y


def _check_in_units(P_hat, u, y, Ky, units, delta):
    """check_excitation of ``u = Ky(r − y)`` around P̂ with the inputs recorded in ``units`` (the same plant, loop and
    output error: P̂ and K rescaled with the record)."""
    s = np.asarray(units, float)
    model = _in_units(P_hat, cols=1.0 / s)
    e = y - control.forced_response(model, U=(u * s).T).outputs.T
    K = control.ss([], [], [], np.diag(s) @ np.hstack([Ky, -Ky]), 1.0)
    frf, low = uf.frequency_response_estimate(u * s, e), uf.low_band_estimate(u * s, e, bins=6)
    return uf.check_excitation(model, K, frf, low, delta=delta)


def test_check_excitation_is_the_same_in_other_input_units():
    """Inputs recorded in units 10⁻³ and 10³: the same plant, loop and data give the same verdict, worst loop gain,
    frequency and reason (but for the size of ``M̂`` it names, in the record's units).  ``r·σ̄(M̂)`` took r from
    ``λ_min(S_uu)``, the 10⁻³ channel's direction, and σ̄(M̂) from the 10³ one: measured before, the three loops that
    pass in units 1, 1 (worst 0.17–0.31) were refused with worst 1.0e5–1.5e5.

    The δ margin is a ball ``‖P − P̂‖₂ ≤ δ`` in the record's units, so it is the same statement only where the loop
    sees one input: with ``C_y`` acting on ``u[:, 1]`` alone, δ in units 1 is δ/10³ in units 10³.  Measured before,
    the evidence 0.23, 0.91 and 1.81 (δ = 0.5, 2, 4: the last refuses) fell to 6e-6–5e-5 in the other units, the
    radius having grown 10³-fold: the refusal was lost."""
    P_hat, u, y = _loop_record()
    loops = [0.3 * np.eye(2), np.array([[0.3, 0.1], [0.0, 0.2]]), np.array([[0.0, 0.0], [0.2, 0.3]]),
             np.array([[2.0, 0.5], [0.0, 1.5]])]  # the last is refused: the data show P̂ wrong where it is sensitive
    for Ky in loops:
        base = _check_in_units(P_hat, u, y, Ky, (1.0, 1.0), None)
        other = _check_in_units(P_hat, u, y, Ky, (1e-3, 1e3), None)
        assert other.ok == base.ok and other.frequency == base.frequency
        assert other.worst == pytest.approx(base.worst, rel=1e-6)
        # the same words and numbers, but for σ̄(M̂) itself, which is in the record's units
        assert re.sub(r"up to [^)]*", "", other.reason) == re.sub(r"up to [^)]*", "", base.reason)
    assert [_check_in_units(P_hat, u, y, Ky, (1.0, 1.0), None).ok for Ky in loops] == [True, True, True, False]
    assert "σ̄(QM̂), reaches" in other.reason  # the refusal names the region's part of the loop gain, not r
    Ky = loops[2]  # C_y drives u[:, 1] only: the δ ball of units 1, 1 is the ball of δ/10³ in units 10⁻³, 10³
    for delta in (0.5, 2.0, 4.0):
        base = _check_in_units(P_hat, u, y, Ky, (1.0, 1.0), delta)
        other = _check_in_units(P_hat, u, y, Ky, (1e-3, 1e3), delta / 1e3)
        assert other.ok == base.ok and other.margin == pytest.approx(base.margin, rel=1e-6)
    assert not _check_in_units(P_hat, u, y, Ky, (1.0, 1.0), 4.0).ok  # the margin refuses (evidence ≥ 1)


def test_the_region_bounds_the_true_loop_gain_over_seeds():
    """``‖(D − D̂)M̂‖₂ ≤ σ̄(QM̂)`` at every Welch and low-band frequency with the stated confidence, on simulated data
    with D known (a 3-tap 2 × 2 operator, correlated inputs in units 10⁻³ and 10³, M̂ a dynamic loop in those units):
    so the true perturbation loop gain σ̄(DM̂) lies within ``σ̄(D̂M̂) ± σ̄(QM̂)``.  At 90 % simultaneous confidence, 100
    records may miss in at most 19 (the binomial 99.8 % point; measured 0).  The test has power: a region 0.4 times
    as wide misses in 45 (Welch) and 48 (low band) of the 100, so the bound is within a factor 2.5 of tight, while
    ``r·σ̄(M̂)`` is about 10⁶ times ``σ̄(QM̂)`` here."""
    s = np.array([1e-3, 1e3])
    h = _taps(2, 2)
    P_hat = control.ss(np.diag([0.5, 0.3]), np.eye(2), [[1.0, 0.2], [0.0, 0.8]], np.zeros((2, 2)), 1.0)
    K = control.ss([[0.6]], [[1.0, 0.0, -1.0, 0.0]], [[0.3], [0.1]],
                   np.hstack([0.2 * np.eye(2), -np.array([[0.2, 0.05], [0.0, 0.3]])]), 1.0)
    M = uf.additive_channel(_in_units(P_hat, cols=1.0 / s), _in_units(K, rows=s))
    miss, narrow, outside, wider = np.zeros(2, int), np.zeros(2, int), np.zeros(2, int), []
    for seed in range(100):
        rng = np.random.default_rng(seed)
        w = rng.standard_normal((4096, 2)) @ np.array([[1.0, 0.7], [0.0, 0.5]])
        y = _filter(h, w) + 0.3 * rng.standard_normal((4096, 2))
        estimates = (uf.frequency_response_estimate(w * s, y, confidence=0.9),
                     uf.low_band_estimate(w * s, y, bins=8, confidence=0.9))
        for k, est in enumerate(estimates):
            ok = np.isfinite(est.radius)
            assert est.region.shape == (est.frequency.size, 2, 2) and ok.all()
            X = np.moveaxis(np.asarray(M(np.exp(1j * est.frequency), squeeze=False)), -1, 0)  # M̂, (F, 2, 2)
            D = _response(h, est.frequency) / s  # the true operator from the record's inputs
            QX = np.linalg.norm(est.region @ X, ord=2, axis=(1, 2))
            err = np.linalg.norm((D - est.response) @ X, ord=2, axis=(1, 2))
            true, centre = (np.linalg.norm(A @ X, ord=2, axis=(1, 2)) for A in (D, est.response))
            miss[k] += bool(np.any(err > QX))
            outside[k] += bool(np.any((true < centre - QX) | (true > centre + QX)))
            narrow[k] += bool(np.any(err > 0.4 * QX))
            wider.append(np.median(est.radius * np.linalg.norm(X, ord=2, axis=(1, 2)) / QX))
    assert np.all(miss <= 19) and np.all(outside <= miss)
    assert np.all(narrow >= 20)
    assert np.median(wider) > 1e4


@pytest.mark.parametrize("l", [1, 2])
def test_one_input_keeps_the_radius_numbers(l):
    """One input: the estimates carry no region factor (σ̄(QX) = r·σ̄(X) there), so every number of
    ``check_excitation`` is that of ``r·σ̄(M̂)``, written here as the module wrote it, bit for bit."""
    from unfalsify.excitation import _bin_response

    rng = np.random.default_rng(7)
    u = rng.standard_normal(2048)
    e = np.column_stack([np.convolve(u, [0.0, 0.05, 0.02])[:2048], 0.03 * u][:l]) + 0.05 * rng.standard_normal(
        (2048, l))
    frf, low = uf.frequency_response_estimate(u, e), uf.low_band_estimate(u, e, bins=8)
    assert getattr(frf, "region", None) is None and getattr(low, "region", None) is None  # (None before it existed)
    P = control.ss(control.tf([0.5], [1, -0.5], 1.0)) if l == 1 else control.ss([[0.5]], [[1.0]], [[1.0], [0.3]],
                                                                                 [[0.0], [0.0]], 1.0)
    K = control.ss([], [], [], np.hstack([0.4 * np.ones((1, l)), -0.4 * np.ones((1, l))]), 1.0)
    ex = uf.check_excitation(P, K, frf, low, delta=1.5)
    if l == 1:
        return  # the SISO path (|D̂|, r) has no region to read
    M = uf.additive_channel(P, K)
    parts = []
    for est, sign, spacing in ((frf, 1.0, frf.resolution), (low, -1.0, 2.0 * np.pi / (low.samples * low.dt))):
        Mz = _bin_response(M, est.frequency, spacing, est.dt, 9)
        gain_M = np.linalg.norm(Mz, ord=2, axis=(2, 3))
        gain_DM = np.linalg.norm(est.response[:, None] @ Mz, ord=2, axis=(2, 3))
        parts.append(np.max(gain_DM + sign * est.radius[:, None] * gain_M, axis=1))
    worst = max(float(np.max(parts[0])), float(np.max(np.maximum(parts[1], 0.0))))
    assert ex.worst == worst  # bit for bit


# ---- the premise's refutation reads the region's directions -------------------------------------------------

def _with_region(est, Q):
    """``est`` with the region factor ``Q`` (m × m) at every frequency and its radius ``σ̄(Q)``."""
    import dataclasses

    F = est.frequency.size
    return dataclasses.replace(est, radius=np.full(F, np.linalg.norm(Q, 2)), region=np.tile(Q, (F, 1, 1)))


def test_premise_refutation_reads_the_region_directions():
    """An error the record shows in its well-excited input direction is refuted although another direction is
    barely excited: ``‖D̂x‖ − ‖Qx‖`` at ``x = e₂`` is 0.45 > δ = 0.2, while ``‖D̂‖₂ − σ̄(Q)`` = −0.5 (the rule it
    replaced, which took the least-excited direction's confidence for every direction, and passed)."""
    D = np.tile(np.diag([0.0, 0.5]).astype(complex), (5, 1, 1))  # P − P̂ lives on input 1
    Q = np.diag([1.0, 0.05])  # input 0 barely excited, input 1 well
    for low in (False, True):
        est = _with_region(_fake(D, np.ones(5), low=low), Q)
        worst, why = (_low_band_inconsistency if low else _frf_inconsistency)(est, 0.2)
        assert worst == pytest.approx(0.45 / 0.2) and "by 0.45" in why
    # the same error where the record is blind is no evidence: 0.5 − 1 along e₁, 0 − 0.05 along e₂
    blind = _with_region(_fake(np.tile(np.diag([0.5, 0.0]).astype(complex), (5, 1, 1)), np.ones(5)), Q)
    worst, why = _frf_inconsistency(blind, 0.2)
    assert why == "" and worst == pytest.approx(-0.05 / 0.2)


def test_premise_gap_never_exceeds_the_true_error_where_the_region_holds():
    """Soundness on simulated data with D known (correlated inputs in units 10⁻³ and 10³, 30 records): wherever the
    region covers the truth, the directional gap is at most ``‖D‖₂`` (it is a lower bound over the region), and it
    is never below ``‖D̂‖₂ − r``; it is larger somewhere (the test has power)."""
    from unfalsify.premise import _model_gap

    s = np.array([1e-3, 1e3])
    h = _taps(2, 2)
    larger = 0
    for seed in range(30):
        rng = np.random.default_rng(seed)
        w = rng.standard_normal((2048, 2)) @ np.array([[1.0, 0.9], [0.0, 0.1]])
        y = _filter(h, w) + 0.3 * rng.standard_normal((2048, 2))
        for est in (uf.frequency_response_estimate(w * s, y, confidence=0.9),
                    uf.low_band_estimate(w * s, y, bins=8, confidence=0.9)):
            D = _response(h, est.frequency) / s
            gap = _model_gap(est)
            assert np.all(gap >= est.gain - est.radius - 1e-12)
            covered = np.linalg.norm((D - est.response) @ np.linalg.inv(est.region), ord=2, axis=(1, 2)) <= 1.0
            assert np.all(gap[covered] <= np.linalg.norm(D, ord=2, axis=(1, 2))[covered] * (1 + 1e-9))
            larger += int(np.any(gap > est.gain - est.radius + 1e-9))
    assert larger >= 30


def test_premise_gap_of_one_input_is_the_radius_rule():
    """One input (no region): ``|D̂| − r``, bit for bit."""
    from unfalsify.premise import _model_gap

    rng = np.random.default_rng(3)
    u = rng.standard_normal(2048)
    e = np.convolve(u, [0.0, 0.05, 0.02])[:2048] + 0.05 * rng.standard_normal(2048)
    for est in (uf.frequency_response_estimate(u, e), uf.low_band_estimate(u, e, bins=8)):
        assert est.region is None and np.array_equal(_model_gap(est), est.gain - est.radius, equal_nan=True)
