"""§7.4 pipeline: subspace δ → Theorem 3.7 additive-uncertainty design, checked on the servo.

Servo 1/(s(s+1)) ZOH at 10 Hz (experiments.lab.plants), §5.4 data (PRBS ±1, process and sensor
noise σ = 0.05, seed 0), Design 1 weights.  The predictor is the least-squares fit on 1000
samples (i = 20, the §5.4 horizon); δ is unfalsified for that predictor on the first
2i + j − 1 samples with j = 20 (a few seconds).
"""
import warnings

import control
import numpy as np
import pytest

import synthesis
import unfalsify as uf
from experiments.lab.servo_setup import design_weights, servo_data, step_response
from experiments.lab.plants import servo
from synthesis.validation import DataError

pytestmark = pytest.mark.slow  # minutes of CLI/LMI work: deselect with -m 'not slow'

I, J = 20, 20


@pytest.fixture(scope="module")
def setup():
    W = design_weights()
    W1, W2 = W["W11"], W["W21"]
    data = servo_data(1000, seed=0)
    pred = synthesis.fit_predictor(data.u, data.y, I)
    n = 2 * I + J - 1
    u, y = data.u[:n], data.y[:n]
    A, Uf, Yf = uf.subspace_data(u, y, I)
    rms = np.linalg.norm(Yf - np.hstack([pred.Lw, pred.Lu]) @ A) / np.sqrt(Yf.size)
    pfor = lambda h: synthesis.fit_predictor(data.u, data.y, h)  # noqa: E731 - reference models at other horizons
    # a second experiment on the same plant, not used to fit anything: held out for the premise test
    held = servo_data(500, seed=1)
    val = (held.u, held.y)
    res = uf.robust_design_from_data(u, y, I, W1, W2, 0.5 * rms, predictor=pred, predictor_for=pfor, validation=val)
    return dict(W1=W1, W2=W2, pred=pred, u=u, y=y, res=res, plant=servo(), pfor=pfor, val=val)


def test_unfalsification_is_certified_and_positive(setup):
    res = setup["res"]
    unf = res.unfalsification
    assert unf.status in ("optimal", "optimal_inaccurate")
    assert unf.certificate.ok(1e-5)
    assert res.delta > 0.01  # σ below the residual rms leaves a real uncertainty (measured 0.053)
    # δ is for the given (fixed) predictor
    np.testing.assert_array_equal(unf.Lu, setup["pred"].Lu)


def test_fixed_point_weight_and_gamma(setup):
    res, pred = setup["res"], setup["pred"]
    c = res.w3_gain
    # independent recomputation of γ_min_a at W3 = c through hinf_design
    d = synthesis.hinf_design(pred, setup["W1"], setup["W2"], gamma_ratio=1.1,
                              uncertainty=synthesis.Additive(c, 1.0))
    assert d.gamma == pytest.approx(res.gamma, rel=1e-10)
    assert c == pytest.approx((1 + res.margin) * res.delta * d.gamma, rel=1e-8)
    assert res.covered_delta == pytest.approx((1 + res.margin) * res.delta, rel=1e-8)
    assert res.certified and res.covers_delta and res.reason == ""
    assert len(res.search) == 1  # the requested design certified: no search
    # Thm 3.7: γ_min_a > γ_min of the nominal design (3.8)
    assert res.gamma_min_a > res.gamma_min_nominal
    assert res.gamma_min_nominal == pytest.approx(synthesis.gamma_min(pred, setup["W1"], setup["W2"]), rel=1e-12)


def test_small_gain_certificate_on_true_plant(setup):
    res, plant = setup["res"], setup["plant"]
    rob = uf.additive_robustness(plant, res.controller)
    assert rob.stable
    assert res.delta * rob.peak < 1.0  # δ‖K(I+PK)⁻¹‖∞ < 1 (measured ≈ 0.6)
    assert rob.certifies(res.delta)


def test_additive_robustness_peak_matches_direct_formula(setup):
    # second route: evaluate K(I+PK)⁻¹ from P(z) and C_y(z) directly at a few frequencies
    res, plant = setup["res"], setup["plant"]
    C = control.ss(res.controller)
    Cy = C[:, 1:]
    w = np.logspace(-2, np.log10(np.pi / 0.1), 400)
    z = np.exp(1j * w * 0.1)
    p = np.array([complex(np.squeeze(plant(zz))) for zz in z])
    k = np.array([complex(np.squeeze(Cy(zz))) for zz in z])
    direct = np.abs(k / (1 - k * p)).max()
    rob = uf.additive_robustness(plant, res.controller, n_grid=8192)
    assert rob.peak >= direct * (1 - 1e-9)
    assert rob.peak == pytest.approx(direct, rel=0.02)
    # peak is the proven side of the bracket; the grid values lie below it
    assert rob.peak == rob.bracket.upper and rob.bracket.lower <= rob.peak
    assert direct <= rob.bracket.lower * (1 + 1e-9) and rob.bracket.gap < 1e-6


@pytest.mark.parametrize("kind", ["+static", "-static", "+delay", "-delay", "lowpass"])
def test_closed_loop_with_additive_perturbation_of_size_delta_is_stable(setup, kind):
    res, plant = setup["res"], setup["plant"]
    d, dt = res.delta, plant.dt
    num, den = {
        "+static": ([d], [1.0]),
        "-static": ([-d], [1.0]),
        "+delay": ([d], [1.0, 0.0]),  # δ z⁻¹
        "-delay": ([-d], [1.0, 0.0, 0.0]),  # −δ z⁻²
        "lowpass": ([0.5 * d, 0.5 * d], [1.0, 0.0]),  # δ(1 + z⁻¹)/2: ‖·‖∞ = δ at DC
    }[kind]
    pert = control.tf(num, den, dt)
    w = np.linspace(0.0, np.pi, 2001)
    peak = np.abs([complex(np.squeeze(pert(np.exp(1j * x)))) for x in w]).max()
    assert peak == pytest.approx(d, rel=1e-9)
    step = step_response(plant, res.controller, 400, perturbation=control.ss(pert))
    assert step.stable  # eigenvalues of the perturbed loop
    assert np.isfinite(step.max_abs_y) and step.max_abs_y < 3.0  # and the simulation stays bounded


def test_thesis_weight_rule_is_the_inverse(setup):
    # W3 = (1/δ) I covers only ‖P_Δ‖∞ < 1/(γδ): over-conservative here (γδ² ≪ 1), and the controller it
    # gives barely acts: trivially robust, but it fails the performance floor, so it is NOT certified
    res = setup["res"]
    with pytest.warns(uf.NotCertifiedWarning, match="performance floor"):
        th = uf.robust_design_from_data(setup["u"], setup["y"], I, setup["W1"], setup["W2"], res.unfalsification.sigma,
                                        predictor=setup["pred"], w3_rule="thesis",
                                        unfalsification=res.unfalsification, search=False)
    assert not th.certified and not th.covers_delta and "performance floor" in th.reason
    assert th.certificate.small_gain < 1  # robust it is ...
    assert th.certificate.step.final_error > 0.5  # ... because it does almost nothing
    assert th.w3_gain == pytest.approx(1 / res.delta)
    assert th.covered_delta == pytest.approx(1 / (th.gamma * res.delta))
    assert th.covered_delta > 10 * res.delta  # grossly over-covered
    assert th.gamma_min_a > res.gamma_min_a  # and it pays for it in performance
    assert len(th.search) == 1  # search=False: the requested design only


def test_thesis_rule_warns_when_it_does_not_cover_delta(setup):
    # an artificial large δ (γδ² > 1) through a crafted unfalsification result
    import dataclasses

    unf = dataclasses.replace(setup["res"].unfalsification, delta=3.0)
    with pytest.warns(uf.NotCertifiedWarning, match="NOT certified for δ = 3"):
        th = uf.robust_design_from_data(setup["u"], setup["y"], I, setup["W1"], setup["W2"], 0.01,
                                        predictor=setup["pred"], w3_rule="thesis", unfalsification=unf)
    assert th.covered_delta < 3.0  # the finite-horizon coverage 1/(γδ) misses δ
    assert not th.covers_delta and not th.certified and th.reason


def test_zero_delta_gives_the_nominal_design(setup):
    import dataclasses

    unf = dataclasses.replace(setup["res"].unfalsification, delta=0.0)
    r0 = uf.robust_design_from_data(setup["u"], setup["y"], I, setup["W1"], setup["W2"], 0.01,
                                    predictor=setup["pred"], unfalsification=unf, predictor_for=setup["pfor"])
    assert r0.w3_gain == 0.0
    # no uncertainty channel at all (W3 = 0 alone would keep W4's s → z_w1 path, Thm 3.7)
    assert r0.design.uncertainty is None
    assert r0.gamma_min_a == pytest.approx(r0.gamma_min_nominal, rel=1e-12)


def test_bad_arguments(setup):
    with pytest.raises(ValueError):
        uf.robust_design_from_data(setup["u"], setup["y"], I, setup["W1"], setup["W2"], 0.01, w3_rule="inverse")
    with pytest.raises(ValueError):
        uf.robust_design_from_data(setup["u"], setup["y"], I, setup["W1"], setup["W2"], 0.01, gamma_ratio=1.0)
    with pytest.raises(ValueError):
        uf.additive_weight_fixed_point(setup["pred"], setup["W1"], setup["W2"], -0.1)


def test_additive_channel_against_direct_formula_and_bad_controller(setup):
    # M = C_y/(1 − C_y P) point by point from the two frequency responses (second route)
    res, plant = setup["res"], setup["plant"]
    M = uf.additive_channel(plant, res.controller)
    Cy = control.ss(res.controller)[:, 1:]
    for w in (0.03, 0.7, 5.0, 25.0):
        z = np.exp(1j * w * plant.dt)
        k, p = complex(np.squeeze(Cy(z))), complex(np.squeeze(plant(z)))
        assert complex(np.squeeze(M(z))) == pytest.approx(k / (1 - k * p), rel=1e-8)
    with pytest.raises(ValueError, match=r"inputs \[r; y\]"):
        uf.additive_channel(plant, Cy)  # an error-feedback controller (one input) is refused


def test_uncertified_delta_is_raised_to_the_certified_value_and_warned(setup):
    # a (7.5) answer whose own impulses certify a larger δ than the solver reported (as from an
    # 'optimal_inaccurate' solve): the design must be sized by the certified value, with a warning
    import dataclasses

    unf = setup["res"].unfalsification
    low = dataclasses.replace(unf, delta=0.5 * unf.delta,
                              certificate=dataclasses.replace(unf.certificate, delta=0.5 * unf.delta))
    assert not low.certificate.ok()
    with pytest.warns(uf.SolverWarning, match="not certified"):
        r = uf.robust_design_from_data(setup["u"], setup["y"], I, setup["W1"], setup["W2"], unf.sigma,
                                       predictor=setup["pred"], unfalsification=low, predictor_for=setup["pfor"])
    assert r.delta == pytest.approx(unf.certificate.delta_certified, rel=1e-12)
    assert r.covered_delta == pytest.approx((1 + r.margin) * r.delta, rel=1e-8)
    with warnings.catch_warnings():  # a certified answer is used as is, silently
        warnings.simplefilter("error", uf.SolverWarning)
        r2 = uf.robust_design_from_data(setup["u"], setup["y"], I, setup["W1"], setup["W2"], unf.sigma,
                                        predictor=setup["pred"], unfalsification=unf, predictor_for=setup["pfor"])
    assert r2.delta == unf.delta


@pytest.mark.parametrize("kw", [dict(delta=np.nan), dict(delta=0.1, margin=-0.1), dict(delta=0.1, gamma_ratio=1.0),
                                dict(delta=0.1, gamma_ratio=0.5)])
def test_fixed_point_rejects_bad_arguments(setup, kw):
    with pytest.raises(ValueError, match="must be"):
        uf.additive_weight_fixed_point(setup["pred"], setup["W1"], setup["W2"], **kw)


def test_option_objects_and_the_earlier_keywords_give_the_same_pipeline(setup):
    s, res = setup, setup["res"]
    # step 1 alone: the same (7.5) solve as inside the pipeline (second route: the pipeline's own result)
    unf = uf.estimate_delta(s["u"], s["y"], I, res.unfalsification.sigma, predictor=s["pred"])
    assert unf.delta == res.unfalsification.delta and unf.certificate.verify()
    common = dict(predictor=s["pred"], predictor_for=s["pfor"], validation=s["val"], unfalsification=unf)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        grouped = uf.robust_design_from_data(
            s["u"], s["y"], I, s["W1"], s["W2"], unf.sigma, design=uf.DesignOptions(gamma_ratio=1.5, causal=True),
            certificate=uf.CertificateOptions(margin=0.3, tracking_floor=0.2), search=False, **common)
        legacy = uf.robust_design_from_data(s["u"], s["y"], I, s["W1"], s["W2"], unf.sigma, gamma_ratio=1.5,
                                            causal=True, certificate_margin=0.3, tracking_floor=0.2, search=False,
                                            **common)
    assert grouped.gamma == legacy.gamma and grouped.w3_gain == legacy.w3_gain and grouped.design.causal
    assert grouped.certificate.margin == legacy.certificate.margin == 0.3
    assert grouped.certificate.tracking_floor == 0.2 and grouped.reason == legacy.reason
    with pytest.raises(TypeError, match="gamma_ration"):
        uf.robust_design_from_data(s["u"], s["y"], I, s["W1"], s["W2"], unf.sigma, gamma_ration=1.5, **common)
    with pytest.raises(DataError, match="DesignOptions"):
        uf.robust_design_from_data(s["u"], s["y"], I, s["W1"], s["W2"], unf.sigma, design={"gamma_ratio": 1.5},
                                   **common)
    with pytest.raises(DataError, match="w3_rule"):
        uf.DesignOptions(w3_rule="inverse")


def test_noise_free_data_are_refused_with_one_reason():
    """A noise-free record fits the window to rounding: σ must lie below the residual rms and its budget above
    rounding, which cannot both hold.  Both σ='auto' and a given σ had refused with fixes that contradicted each
    other ("pass sigma > 2.3e-14", then "sigma must be below 5.7e-15"); one reason now says what is wrong."""
    rng = np.random.default_rng(0)
    n = 400
    u = np.sign(rng.standard_normal(n))
    y = np.convolve(u, [0.0, 0.5, 0.3, 0.1])[:n]  # an FIR plant, no noise
    W = control.tf([1.0, 0.2], [1.0, -0.5], 1.0)
    for sigma in ("auto", 1e-6):
        with pytest.raises(DataError, match="fits this window to rounding.*add sensor noise"):
            uf.robust_design_from_data(u, y, 5, W, W, sigma, window=(0, 49))
    # a little noise makes the same record usable: the refusal is about rounding, not about the plant
    noisy = y + 1e-3 * rng.standard_normal(n)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rd = uf.robust_design_from_data(u, noisy, 5, W, W, "auto", window=(0, 49))
    assert np.isfinite(rd.delta) and rd.delta >= 0


def test_a_predictor_without_persistent_excitation_skips_the_coprime_form():
    """No form certifies a predictor whose input is not persistently exciting, so "auto" does not spend the coprime
    premise's solves on it (a constant input had taken 49 s, 33 of them there, before the same refusal)."""
    rng = np.random.default_rng(0)
    n = 300
    y = 0.02 * rng.standard_normal(n)
    W = control.tf([1.0, 0.2], [1.0, -0.5], 1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rd = uf.robust_design_from_data(np.ones(n), y, 5, W, W, 0.01)
        explicit = uf.robust_design_from_data(np.ones(n), y, 5, W, W, 0.01,
                                              certificate=uf.CertificateOptions(uncertainty="coprime"))
    assert not rd.certified and rd.uncertainty == "additive" and rd.coprime is None
    assert "not persistently exciting" in rd.reason
    assert not explicit.certified and explicit.coprime is not None  # asked for by name: still computed


@pytest.mark.parametrize("make, match", [
    (lambda: uf.CertificateOptions(margin=-1.0), "margin must be"),
    (lambda: uf.CertificateOptions(tracking_floor=-0.1), "tracking_floor must be"),
    (lambda: uf.CertificateOptions(tracking_floor=(0.1, float("nan"))), "tracking_floor.* must be"),
    # accepted before, refused only by the pipeline after δ had been solved:
    (lambda: uf.CertificateOptions(tracking_floor=float("inf")), "tracking_floor must be a finite"),
    (lambda: uf.CertificateOptions(tracking_floor=(np.inf, np.inf)), "at least one output must be tracked"),
    (lambda: uf.CertificateOptions(tracking_floor=[[0.1, 0.2]]), "tracking_floor.* must be"),
    (lambda: uf.CertificateOptions(tracking_floor=()), "tracking_floor is empty"),
    (lambda: uf.CertificateOptions(step_samples=4), "step_samples must be"),
    (lambda: uf.CertificateOptions(reference_horizon=0), r"reference_horizon \(CertificateOptions\) must be"),
    (lambda: uf.CertificateOptions(require_reference="yes"), "require_reference must be"),
    (lambda: uf.DesignSearch(gamma_ratios=(0.5,)), "gamma_ratios"),
    (lambda: uf.DesignSearch(w3_factors=(0.0,)), "w3_factors"),
    (lambda: uf.DesignSearch(causal=(0,)), "causal"),
    (lambda: uf.DesignSearch(horizons=5), "horizons must be a tuple"),
    (lambda: uf.DesignSearch(horizons=(5, 0)), r"each of horizons \(DesignSearch\) must be an integer ≥ 1, got 0"),
    (lambda: uf.DesignSearch(gamma_ratios=()), "gamma_ratios is empty"),
    (lambda: uf.EstimationOptions(form="bogus"), "unknown form"),
    (lambda: uf.EstimationOptions(backend="bogus"), "backend must be"),
    (lambda: uf.EstimationOptions(solver=3), "solver must be"),
    (lambda: uf.EstimationOptions(solver_options="x"), "solver_options must be a mapping"),
    (lambda: uf.DesignSearch(causal=[]), "causal is empty"),
    (lambda: uf.PremiseOptions(confidence=1.5), "confidence must lie in"),
    (lambda: uf.PremiseOptions(samples=0), "samples must be an integer"),
    (lambda: uf.PremiseOptions(nperseg=2.5), "nperseg must be an integer"),
    (lambda: uf.PremiseOptions(tol=0.0), "tol must be"),
    (lambda: uf.PremiseOptions(sigma=-1.0), "sigma must be None"),
])
def test_option_objects_check_their_fields_when_made(make, match):
    # they had been accepted and failed (or not) at the first solve that read them
    with pytest.raises(DataError, match=match):
        make()


def test_valid_option_objects_are_unchanged():
    assert uf.CertificateOptions(tracking_floor=(0.1, np.inf)).tracking_floor == (0.1, np.inf)
    assert uf.tracking_floors(np.array(0.2), 2).tolist() == [0.2, 0.2]  # a 0-d array is a number
    assert uf.DesignSearch(horizons=(5, np.int64(10))).horizons == (5, 10)
    assert uf.PremiseOptions(time_limit=None, nperseg=64).nperseg == 64


@pytest.mark.parametrize("n", [25, 35, 45])
def test_a_record_too_short_for_the_horizon_says_so(n):
    # it had been refused as noise-free data (35, 45 samples) or as an input at rest (25)
    rng = np.random.default_rng(0)
    u = np.sign(rng.standard_normal(n))
    y = np.convolve(u, [0.0, 0.5, 0.3])[:n] + 0.05 * rng.standard_normal(n)
    with pytest.raises(DataError, match=r"too short for horizon i = 10.*record at least 164 samples"):
        uf.robust_design_from_data(u, y, 10, 1.0, 0.1, "auto", dt=1.0, window="auto")


def _flip_design(pole: float, uncertainty: str, reference_horizon: int | None = None):
    """The record-mode design, in one uncertainty form, of a plant whose slow mode (``pole``, DC gain −1.1) flips the
    DC gain of its fast part (+1) to −0.1: 1500 samples of PRBS at 10 Hz, process and sensor noise 0.05, i = 5."""
    from experiments.lab.signals import prbs
    from experiments.lab.simulate import collect_data
    from experiments.studies.design_cli import default_weights

    dt = 0.1
    plant = control.ss(np.diag([pole, 0.7, 0.4]), [[-1.1 * (1 - pole)], [0.15], [0.3]], np.ones((1, 3)), 0.0, dt)
    d = collect_data(plant, prbs(1500, seed=1), process_noise=0.05, sensor_noise=0.05, seed=101)
    W1, W2, _ = default_weights(dt)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = uf.robust_design_from_data(d.u, d.y, 5, W1, W2, "auto", dt=dt, window="auto",
                                         certificate=uf.CertificateOptions(uncertainty=uncertainty,
                                                                           reference_horizon=reference_horizon))
    return res, plant


def test_a_slow_mode_that_flips_the_dc_gain_is_refused_on_the_whole_records_low_band():
    """A slow mode (pole 0.995) with DC gain −1.1 under fast modes of gain +1: P(1) = −0.1, but over i = 5 steps
    the plant looks like its fast part and P̂(1) ≈ +1.  The held-out third's low band starts at 0.128 rad/s, where
    the error is within the data's regions; the additive loop certified on it was unstable on the plant.  The
    output error over the whole 1500-sample record (lowest frequency 0.042 rad/s) places P̂ outside the ball."""
    res, _ = _flip_design(0.995, "additive")
    assert not res.certified
    assert "over the whole 1500-sample record" in res.premise.reason
    assert "raise the horizon, or fit on a longer record" in res.premise.reason
    low = res.premise.record_low_band
    assert low is not None and low.frequency[0] < res.premise.low_band.frequency[0] / 2


def test_a_dc_flip_is_refused_in_coprime_form_by_the_least_distance_over_the_disk():
    """The same flip with its slow pole at 0.99: the additive premise is refuted, and the coprime form had been
    certified (ε = 0.091) with a loop unstable on the plant, because the bound from the whole record's equation error
    took σ̄(P) ≤ (σ̄(N̂) + σ̄(R))/σ_min(M̂), which is loose where the slow mode cancels P's gain (0.088 at 0.042 rad/s,
    the true distance there 0.29).  The least distance over R's confidence disk refutes the family there, and
    stays below the plant's true distance from it (the second route, from the plant itself)."""
    res, plant = _flip_design(0.99, "coprime")
    assert not res.certified
    cop = res.coprime
    assert "over the whole 1500-sample record" in cop.reason and "coprime-factor family" in cop.reason
    low = cop.record_low_band
    bound = uf.error_gap(cop.factors, low)
    assert bound.max() > cop.epsilon
    z = np.exp(1j * low.frequency * plant.dt)
    G = np.array([complex(plant(zk)) for zk in z])
    assert np.all(bound <= uf.coprime_gap(cop.factors, low.frequency, G) + 1e-12)


def test_the_reference_model_at_the_records_longest_horizon_refuses_a_dc_flip_that_2i_cannot_see():
    """The flip with its slow pole at 0.995 (time constant 200 samples): in record mode the loop was certified in
    coprime-factor form and was unstable on the plant.  Over the reference's old horizon 2i = 10 the plant still looks
    like its fast part (P̂_ref(1) ≈ 0.95, P(1) = −0.1); the 1000-sample fitting part supports h = 31 with ten columns
    per regressor (1001 − 2h ≥ 30h), whose model sees the slow mode, and no design of the search certifies on it."""
    res, plant = _flip_design(0.995, "auto")
    assert res.reference_horizon == 31 == (1000 + 1) // (2 + uf.REFERENCE_COLUMNS * 3)
    assert res.reference_model is not None
    assert not res.certified
    assert "P̂_ref" in res.reason
    dc = lambda g: float(np.real(np.asarray(g(1.0))).ravel()[0])  # noqa: E731
    assert dc(res.reference_model) < dc(res.model) - 0.2  # the long model is pulled toward P(1) = −0.1


def test_an_explicit_reference_horizon_wins_over_the_one_chosen_from_the_record():
    """``CertificateOptions(reference_horizon=10)`` keeps the old reference (2i): the same record certifies again,
    the loop unstable on the plant, which is what the horizon chosen from the record prevents."""
    res, plant = _flip_design(0.995, "auto", reference_horizon=10)
    assert res.reference_horizon == 10
    assert res.certified
    assert not uf.certify_loop(plant, res.controller, res.delta).stable  # the true loop is unstable


def test_a_reference_horizon_the_input_does_not_excite_falls_back_to_2i():
    """Four sines excite a predictor of order 2h·m ≤ 8: the old reference's (2i = 4) but not the 300-sample record's
    longest well-determined horizon (h = 9, which needs order 18).  The reference falls back to 2i, so the longer
    horizon adds evidence without demanding more excitation than before (no persistence reason)."""
    t = np.arange(300)
    u = sum(np.sin(w * t) for w in (0.3, 0.9, 1.7, 2.5))
    y = np.convolve(u, [0.0, 1.0, 0.5])[:300] + 0.01 * np.random.default_rng(0).standard_normal(300)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pred = synthesis.fit_predictor(u, y, 2)
        assert synthesis.fit_predictor(u, y, 9).persistently_exciting is False
        res = uf.robust_design_from_data(u[:45], y[:45], 2, 10.0, 0.1, "auto", predictor=pred, dt=1.0,
                                         predictor_for=lambda h: synthesis.fit_predictor(u, y, h))
    assert (300 + 1) // (2 + uf.REFERENCE_COLUMNS * 3) == 9
    assert res.reference_horizon == 4 and res.reference_model is not None
    assert "reference predictor" not in res.premise_reason
