"""synthesis.makeweight: first-order discrete weight, Tustin prewarped at the crossover frequency."""
import control
import numpy as np
import pytest

import synthesis
from synthesis import WeightError


def _gain(W, w, dt):
    return abs(complex(np.squeeze(W(np.exp(1j * w * dt)))))


def _continuous(dc, freq, mag, hf):
    # second route: the continuous design written out, evaluated directly
    a = freq * np.sqrt((mag ** 2 - hf ** 2) / (dc ** 2 - mag ** 2))
    return lambda s: (hf * s + dc * a) / (s + a)


CASES = [  # (dc, (freq, mag), hf, dt): a W1-like low-pass, a W2-like high-pass, a slow sample time
    (100.0, (0.5, 1.0), 0.5, 0.1),
    (0.05, (2.0, 0.3), 10.0, 0.1),
    (1000.0, (3.0, 2.0), 0.01, 0.5),
]


@pytest.mark.parametrize("dc, cross, hf, dt", CASES)
def test_gains_at_dc_crossover_and_nyquist(dc, cross, hf, dt):
    freq, mag = cross
    W = synthesis.makeweight(dc, cross, hf, dt)
    assert isinstance(W, control.StateSpace) and W.dt == dt and W.nstates == 1
    assert _gain(W, 0.0, dt) == pytest.approx(dc, rel=1e-12)
    assert _gain(W, freq, dt) == pytest.approx(mag, rel=1e-12)  # exact by the prewarping
    assert _gain(W, np.pi / dt, dt) == pytest.approx(hf, rel=1e-12)
    # the discrete weight at ω equals the continuous one at the prewarped frequency (2/dt·tan(ω dt/2) scaled)
    Wc = _continuous(dc, freq, mag, hf)
    K = freq / np.tan(freq * dt / 2)
    for w in (0.3 * freq, freq, 2.0 * freq, 0.9 * np.pi / dt):
        if w >= np.pi / dt:
            continue
        s = 1j * K * np.tan(w * dt / 2)
        assert complex(np.squeeze(W(np.exp(1j * w * dt)))) == pytest.approx(Wc(s), rel=1e-10)
    assert abs(Wc(1j * freq)) == pytest.approx(mag, rel=1e-12)
    # high frequency: the continuous design's hf, approached by the discrete one near Nyquist
    assert abs(Wc(1j * 1e9)) == pytest.approx(hf, rel=1e-6)


@pytest.mark.parametrize("dc, cross, hf, dt", CASES)
def test_stable_minimum_phase_biproper(dc, cross, hf, dt):
    W = synthesis.makeweight(dc, cross, hf, dt)
    assert np.all(np.abs(control.poles(W)) < 1) and np.all(np.abs(control.zeros(W)) < 1)
    assert abs(float(np.squeeze(W.D))) > 0
    assert synthesis.as_weight(W, "W1", dt=dt) is W  # accepted as a weight


def test_continuous_design_and_agreement_with_python_control_prewarp():
    Wc = synthesis.makeweight(100.0, (0.5, 1.0), 0.5, 0)
    assert Wc.dt == 0
    Wd = control.sample_system(Wc, 0.1, method="tustin", prewarp_frequency=0.5)
    W = synthesis.makeweight(100.0, (0.5, 1.0), 0.5, 0.1)
    for w in (0.01, 0.5, 5.0, 30.0):
        z = np.exp(1j * w * 0.1)
        assert complex(np.squeeze(W(z))) == pytest.approx(complex(np.squeeze(Wd(z))), rel=1e-9)


@pytest.mark.parametrize("args, match", [
    ((100.0, (0.5, 200.0), 0.5, 0.1), "strictly between dc = 100 and hf = 0.5"),
    ((100.0, (0.5, 0.5), 0.5, 0.1), "strictly between"),
    ((1.0, (0.5, 1.0), 1.0, 0.1), "strictly between"),
    ((100.0, (40.0, 1.0), 0.5, 0.1), "not below the Nyquist frequency"),
    ((100.0, (np.pi / 0.1, 1.0), 0.5, 0.1), "Nyquist"),
    ((-1.0, (0.5, 1.0), 0.5, 0.1), "dc must be a positive"),
    ((100.0, (0.5, 1.0), 0.0, 0.1), "hf must be a positive"),
    ((100.0, (0.0, 1.0), 0.5, 0.1), "crossover frequency must be a positive"),
    ((100.0, (0.5, -1.0), 0.5, 0.1), "mag must be a positive"),
    ((100.0, 0.5, 0.5, 0.1), "pair"),
    ((100.0, (0.5, 1.0), 0.5, -0.1), "dt must be"),
    ((1e300, (0.5, 1.0), 0.5, 0.1), "unit circle"),  # had raised OverflowError (mag ** 2)
    ((0.5, (0.5, 1.0), 1e300, 0.1), "beyond floating point"),  # the same
    ((1e16, (0.5, 1.0), 0.5, 0.1), "unit circle"),  # had returned a weight with W(1) = inf
    ((1e11, (0.5, 1.0), 0.5, 0.1), "off by more than 1e-6"),  # had returned W(1) off by 2.4e-4
])
def test_errors_name_the_fix(args, match):
    with pytest.raises(WeightError, match=match):
        synthesis.makeweight(*args)
    assert issubclass(WeightError, ValueError)


def test_large_but_representable_gain_ratios_keep_their_values():
    """Gain ratios the refusal lets through keep their gains to 1e-6 (the second route is the continuous design of
    ``_continuous``)."""
    for dc, cross, hf in ((1e7, (0.5, 1.0), 0.5), (1e-3, (0.5, 1e-1), 1e5)):
        W = synthesis.makeweight(dc, cross, hf, 0.1)
        assert _gain(W, 0.0, 0.1) == pytest.approx(dc, rel=1e-6)
        assert _gain(W, cross[0], 0.1) == pytest.approx(cross[1], rel=1e-9)
        assert abs(_continuous(dc, *cross, hf)(1j * cross[0])) == pytest.approx(cross[1], rel=1e-9)
