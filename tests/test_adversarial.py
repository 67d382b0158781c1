"""The adversarial catalogue of experiments.studies.adversarial: its signals have the stated properties, its
judge catches a false certificate, and ``robust-adversarial --quick`` runs end to end."""
from __future__ import annotations

import json
import math
from types import SimpleNamespace

import control
import numpy as np
import pytest
from scipy.signal import welch

import unfalsify as uf
from experiments.studies import adversarial as adv
from experiments.studies.adversarial import Case, Excitation, Noise
from experiments.lab.plants import third_order
from synthesis._validation import DataError

N = 1200


def _band_fraction(x, lo, hi, nperseg=256):
    f, p = welch(x, fs=1.0, nperseg=nperseg)
    bin_ = 1.0 / nperseg  # Welch's Hann window spreads a line over about ±2 bins
    inside = (f >= lo - 2 * bin_) & (f <= hi + 2 * bin_)
    return p[inside].sum() / p.sum()


@pytest.mark.parametrize("band, lines", [((0.002, 0.05), 0), ((0.1, 0.2), 0), ((0.005, 0.1), 3)])
def test_multisine_power_is_inside_its_band(band, lines):
    x = Excitation("multisine", band=band, lines=lines).signal(N, seed=0)
    assert np.isclose(np.sqrt(np.mean(x ** 2)), 1.0)
    assert _band_fraction(x, *band) > 0.97
    spectrum = np.abs(np.fft.rfft(x)) ** 2
    k = np.flatnonzero(spectrum > 1e-9 * spectrum.max())
    assert np.all(k / N >= band[0]) and np.all(k / N <= band[1])  # exactly on the grid, inside the band
    if lines:
        assert k.size == lines


@pytest.mark.parametrize("cutoff", [0.02, 0.05, 0.15])
def test_lowpass_noise_has_little_power_above_twice_its_cutoff(cutoff):
    x = Excitation("lowpass", cutoff=cutoff).signal(4000, seed=1)
    assert _band_fraction(x, 0.0, 2 * cutoff, nperseg=512) > 0.97
    # and it is not white: half the band holds far less than half the power
    assert _band_fraction(x, 0.25, 0.5, nperseg=512) < 0.05 or cutoff > 0.2


@pytest.mark.parametrize("hold", [3, 10])
def test_held_prbs_is_piecewise_constant_on_blocks(hold):
    x = Excitation("held_prbs", hold=hold).signal(N, seed=2)
    assert set(np.unique(x)) <= {-1.0, 1.0}
    changes = np.flatnonzero(np.diff(x)) + 1
    assert changes.size > 0 and np.all(changes % hold == 0)


def test_steps_are_sparse():
    x = Excitation("steps", hold=100).signal(N, seed=3)
    assert np.count_nonzero(np.diff(x)) <= N // 100


def test_ar_sensor_noise_is_coloured_with_the_stated_rms():
    v = Noise(ar=0.95, sensor=0.1).sensor_noise(20000, np.random.default_rng(0))
    assert abs(np.std(v) - 0.1) < 0.02
    rho = np.corrcoef(v[1:], v[:-1])[0, 1]
    assert abs(rho - 0.95) < 0.02
    w = Noise(drift=0.01, offset=0.2, sensor=0.0).sensor_noise(2000, np.random.default_rng(0))
    assert abs(w[0] - 0.2) < 0.05 and np.std(np.diff(w)) == pytest.approx(0.01, rel=0.1)


def test_closed_loop_record_satisfies_the_loop_equation():
    case = next(c for c in adv.catalogue() if c.group == "closed_loop" and c.plant == "open_loop_unstable")
    rec = adv.make_record(case)
    assert rec.r is not None
    np.testing.assert_allclose(rec.u, case.feedback * (rec.r - rec.y), atol=1e-12)
    # the plant is open-loop unstable, the record is not: the loop held it
    assert np.max(np.abs(np.linalg.eigvals(rec.plant.A))) > 1.0
    assert np.max(np.abs(rec.y)) < 50


@pytest.mark.parametrize("d", [9, 10, 12])
def test_input_delay_is_exact(d):
    quiet = Noise(process=0.0, sensor=0.0)
    base = adv.make_record(Case("x", "delay", "third_order", noise=quiet))
    late = adv.make_record(Case("x", "delay", "third_order", noise=quiet, delay=d))
    np.testing.assert_array_equal(base.u, late.u)
    np.testing.assert_allclose(late.y[d:], base.y[:-d], atol=1e-12)
    assert np.all(late.y[:d] == 0.0)
    # the judge's plant carries the same delay
    imp = control.impulse_response(late.plant, T=np.arange(30) * late.plant.dt).y.ravel()
    assert np.all(imp[: d + 1] == 0.0) and imp[d + 1] != 0.0


def test_gain_drift_and_saturation_records():
    quiet = Noise(process=0.0, sensor=0.0)
    sat = adv.make_record(Case("x", "nonlinear", "third_order", noise=quiet, nonlinearity="saturation"))
    lin = adv.make_record(Case("x", "nonlinear", "third_order", noise=quiet))
    np.testing.assert_allclose(sat.y, 0.8 * lin.y, atol=1e-12)  # PRBS ±1 clipped at 0.8
    drift = adv.make_record(Case("x", "drift", "third_order", noise=quiet, gain_drift=(0.6, 1.4)))
    assert "midpoint" in drift.judge_note
    assert control.dcgain(drift.plant) == pytest.approx(1.0, rel=1e-3)  # midpoint gain of 0.6 → 1.4


def test_fit_and_held_out_parts_split_the_record():
    rec = adv.make_record(adv.catalogue()[0])
    assert rec.n_fit == 720 and len(rec.fit[0]) + len(rec.held_out[0]) == N


def test_catalogue_covers_every_condition_class_and_quick_is_small():
    cases = adv.catalogue()
    assert {c.group for c in cases} == {"excitation", "noise", "closed_loop", "delay", "resonance", "drift",
                                        "nonlinear", "rate_order"}
    kinds = {c.excitation.kind for c in cases}
    assert kinds == {"prbs", "multisine", "lowpass", "held_prbs", "steps"}
    assert {c.delay for c in cases if c.group == "delay"} == {9, 10, 12}
    assert any(c.dt == pytest.approx(0.02) for c in cases)
    assert 1 <= len(adv.quick_catalogue()) <= 6


def _static(kr, ky, dt=0.1):
    """u = kr·r − ky·y (inputs [r; y]); kr = 1 + ky tracks a unit-DC-gain plant exactly."""
    return control.ss(np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((1, 0)), [[kr, -ky]], dt)


def _fake(controller, delta=0.02, certified=True):
    return SimpleNamespace(certified=certified, controller=controller, delta=delta,
                           certificate=SimpleNamespace(tracking_floor=uf.certify.TRACKING_FLOOR))


def test_judge_flags_a_destabilising_controller_called_certified():
    P = third_order()
    wild = _static(61.0, 60.0)
    true, v = adv.judge_result(_fake(wild), P, warned=False)
    assert not true["stable"] and v == "false_certificate"
    true, v = adv.judge_result(_fake(_static(1.5, 0.5)), P, warned=False)
    assert true["ok"] and v == "certified"
    # the same loop with a δ too large for it fails the small gain
    true, v = adv.judge_result(_fake(_static(1.5, 0.5), delta=50.0), P, warned=False)
    assert v == "false_certificate" and any("δ‖M‖" in f for f in true["fails"])


def test_verdicts_of_refusals():
    assert adv.verdict(False, True, None) == "not_certified"
    assert adv.verdict(False, False, {"ok": True}) == "silent_failure"
    assert adv.verdict(False, False, None, DataError("too short: use a longer record")) == "refused_by_error"
    assert adv.verdict(False, False, None, DataError("bad")) == "refused_without_fix"
    assert adv.verdict(False, False, None, RuntimeError("boom")) == "silent_failure"


def test_summary_counts_certificates_on_an_untested_premise():
    def run(verdict, certified, assumed):
        return {"case": verdict, "group": "g", "excitation_kind": "prbs", "verdict": verdict, "certified": certified,
                "premise_ratio": 1.0, "assumed": assumed}

    results = [run("certified", True, ["input 0 takes the values {-1, 1} only"]), run("certified", True, []),
               run("false_certificate", True, ["input 0 takes the values {-1, 1} only"]),
               run("not_certified", False, ["input 0 takes the values {-1, 1} only"])]
    summary = adv.summarise(results)
    assert summary["certified_assuming"] == 2 and summary["false_certificates_assuming"] == 1
    assert any("cannot test" in line and ": 2, of them false: 1" in line
               for line in adv.summary_lines({**summary, "mode": "validation"}))


def test_summary_counts_certificates_on_a_ball_the_data_do_not_confirm():
    """``certified_unconfirmed``: certified runs whose result carries a premise note (runs from revisions without
    the field count as confirmed)."""
    note = "the data do not confirm the premise ‖P − P̂‖∞ ≤ (1 + margin)·δ = 0.1"
    results = [{"case": str(k), "group": "g", "excitation_kind": "prbs", "verdict": v, "certified": c,
                "premise_ratio": 1.0, "assumed": [], **({"unconfirmed": n} if n is not None else {})}
               for k, (v, c, n) in enumerate([("certified", True, note), ("certified", True, ""),
                                              ("certified", True, None), ("not_certified", False, note)])]
    assert adv.summarise(results)["certified_unconfirmed"] == 1


def test_untested_refuse_reaches_the_pipeline():
    """``--untested refuse``: the white-PRBS control case (certified by default) is refused, naming the fix."""
    from experiments.cli import main

    case = next(c for c in adv.catalogue() if c.name == "excitation/third_order/prbs")
    strict = adv.run_case(case, "refuse")
    assert not strict["certified"] and strict["verdict"] == "not_certified" and strict["assumed"]
    assert "cannot test the premise" in strict["reason"]
    with pytest.raises(SystemExit):
        main(["robust-adversarial", "--untested", "ignore"])


def test_premise_ratio():
    P = third_order()
    assert adv.premise_ratio(P, P, 0.1)[0] == pytest.approx(0.0, abs=1e-9)
    half = control.ss(P.A, 0.5 * P.B, P.C, P.D, P.dt)
    r, _ = adv.premise_ratio(P, half, 0.1)
    assert r == pytest.approx(0.5 * 1.0 / 0.1, rel=1e-3)  # ‖0.5 P‖∞ = 0.5 (peak at DC for this plant)
    r, why = adv.premise_ratio(adv.open_loop_unstable(), P, 0.1)
    assert r == float("inf") and "not stable" in why


@pytest.mark.parametrize("plant", ["servo", "wide", "delayed"])
def test_true_factors_for_the_coprime_judge(plant):
    """The judge's factors of the true plant reproduce it (second route: its frequency response), also when
    aligned to a model's factors; the aligned perturbation's norm bounds the pointwise distance from above, and
    meets it (the premise ratio measured, not bracketed).
    "delayed": a plant of order 9 above the model's horizon 4 (an input delay of 6 samples on a third-order plant; it
    crashed the alignment, measured on the adversarial catalogue's seed 6)."""
    from experiments.lab.plants import servo
    from experiments.studies import mimo_pipeline, robust_pipeline as rp

    if plant == "delayed":
        P = control.ss(third_order() * control.tf([1.0], [1.0] + [0.0] * 6, third_order().dt))
    else:
        P = servo() if plant == "servo" else mimo_pipeline.wide()
    m = P.ninputs
    w = np.array([0.05, 0.7, 2.0]) / P.dt
    G = np.moveaxis(np.asarray(P.horner(np.exp(1j * w * P.dt)), complex).reshape(1, m, -1), -1, 0)
    rng = np.random.default_rng(0)
    u = rng.standard_normal((600, m))
    y = np.asarray(control.forced_response(P, T=np.arange(600) * P.dt, U=u.T).outputs).reshape(-1, 1)
    y += 0.01 * rng.standard_normal(y.shape)
    import synthesis as sy

    Fh = uf.coprime_factors(sy.fit_predictor(u, y, 4), P.dt)
    for F in (rp.true_factors(P), rp.true_factors(P, like=Fh)):
        N, M = F.response(w)
        assert np.allclose(N / M, G, rtol=1e-8, atol=1e-10)
    aligned = rp.true_factors(P, like=Fh)
    lower = uf.coprime_distance(Fh, P)[0]
    assert rp._fir_gap(aligned, Fh) >= lower * (1 - 1e-6)
    # ... and meets it: the bracket of the premise ratio closes (a least-squares Q of degree 4, the former rule, left
    # the upper end 1.5-10 times the lower one on these plants)
    assert rp._fir_gap(aligned, Fh) <= 1.05 * lower
    for Pd in rp._coprime_perturbations(aligned, 0.01):  # size-ε perturbations are ε away in that factorisation
        assert uf.coprime_distance(aligned, Pd)[0] <= 0.01 * (1 + 1e-6)


def test_the_judge_names_the_coprime_small_gain_for_a_coprime_result():
    """A coprime result is judged by ε‖[K; I](M + NK)⁻¹‖ and size-ε perturbations; the failure text said "δ‖M‖"
    and "size-δ" for both families."""
    import synthesis as sy
    from experiments.lab.plants import servo
    from experiments.studies.adversarial import judge

    P = servo()
    rng = np.random.default_rng(1)
    u = rng.standard_normal((600, 1))
    y = np.asarray(control.forced_response(P, T=np.arange(600) * P.dt, U=u.T).outputs).reshape(-1, 1)
    y += 0.01 * rng.standard_normal(y.shape)
    F = uf.coprime_factors(sy.fit_predictor(u, y, 4), P.dt)
    K = control.ss([], [], [], [[0.5, -0.5]], P.dt)  # u = 0.5 (r − y)
    t = judge(P, K, 50.0, 1.0, "coprime", F)  # an ε no loop tolerates
    assert t["stable"] and not t["ok"]
    assert any(f.startswith("true ε‖[K; I](M + NK)⁻¹‖ = ") for f in t["fails"]), t["fails"]
    assert not any("δ" in f for f in t["fails"]), t["fails"]
    additive = judge(P, K, 50.0, 1.0)
    assert any(f.startswith("true δ‖M‖ = ") for f in additive["fails"]), additive["fails"]


def test_the_judge_factors_a_plant_once_and_reads_perturbed_loops_by_their_eigenvalues(monkeypatch):
    """The judge and the premise ratio factor the same plant like the same P̂: the search for Q runs once (60 s at
    i = 32); a perturbed loop's spectral radius from its state matrix equals additive_robustness's, which also
    proves an H∞ norm the judge does not use (63-70 s a perturbation at i = 32)."""
    import synthesis as sy
    from experiments.lab.plants import servo
    from experiments.studies import robust_pipeline as rp

    P = servo()
    rng = np.random.default_rng(1)
    u = rng.standard_normal((600, 1))
    y = np.asarray(control.forced_response(P, T=np.arange(600) * P.dt, U=u.T).outputs).reshape(-1, 1)
    y += 0.01 * rng.standard_normal(y.shape)
    like4, like5 = (uf.coprime_factors(sy.fit_predictor(u, y, i), P.dt) for i in (4, 5))
    calls = []
    search = rp._closest_multiplier
    monkeypatch.setattr(rp, "_closest_multiplier", lambda *a: calls.append(1) or search(*a))
    monkeypatch.setattr(rp, "_FACTORS_CACHE", {})
    F = rp.true_factors(P, like=like4)
    assert rp.true_factors(P, like=like4) is F and len(calls) == 1
    assert rp.true_factors(P, like=like5) is not F and len(calls) == 2  # another P̂: factored anew
    K = control.ss([], [], [], [[0.5, -0.5]], P.dt)  # u = 0.5 (r − y)
    for Pd in rp._coprime_perturbations(F, 0.05):
        assert rp._loop_radius(Pd, K) == pytest.approx(uf.additive_robustness(Pd, K).spectral_radius, rel=1e-10)


def test_a_failing_fit_or_pipeline_is_recorded_not_raised(monkeypatch):
    case = adv.catalogue()[0]

    def broken_fit(*a, **k):
        raise np.linalg.LinAlgError("singular")

    monkeypatch.setattr(adv.synthesis, "fit_predictor", broken_fit)
    out = adv.run_case(case)
    assert out["verdict"] == "fit_failed" and "singular" in out["error"]
    monkeypatch.undo()

    def broken_pipeline(*a, **k):
        raise RuntimeError("unexpected")

    monkeypatch.setattr(adv.uf, "robust_design_from_data", broken_pipeline)
    out = adv.run_case(case)
    assert out["verdict"] == "silent_failure" and "unexpected" in out["error"]
    monkeypatch.undo()

    def broken_ratio(*a, **k):
        raise ValueError("matmul")

    monkeypatch.setattr(adv, "result_premise_ratio", broken_ratio)  # the catalogue goes on (it crashed at seed 6)
    out = adv.run_case(case)
    assert out["verdict"] in adv.VERDICTS and math.isnan(out["premise_ratio"])
    assert "not measured: ValueError: matmul" in out["premise_note"]


@pytest.mark.slow
def test_bad_only_and_seed_end_the_run_as_input_errors(tmp_path, capsys):
    from experiments.cli import main

    for argv, message in ((["--only", "no-such-case"], "matches no case"), (["--seed", "-1", "--quick"], "invalid seed")):
        with pytest.raises(SystemExit) as stop:
            main(["robust-adversarial", *argv, "--out", str(tmp_path)])
        assert stop.value.code == 2 and message in capsys.readouterr().err  # it had run 0 cases / raised ValueError


def test_quick_runs_end_to_end(tmp_path, capsys):
    from experiments.cli import main

    assert main(["robust-adversarial", "--quick", "--json", "--out", str(tmp_path)]) == 0
    summary = json.loads(capsys.readouterr().out)
    for key in ("mode", "runs", "certified", "certified_fraction", "verdicts", "by_excitation", "by_group",
                "false_certificates", "silent_failures", "false_certificate_cases", "silent_failure_cases", "cases"):
        assert key in summary
    assert summary["runs"] == len(adv.quick_catalogue())
    assert all(c["verdict"] in adv.VERDICTS for c in summary["cases"])
    # every certified loop had its δ (ε) margin tested against the data, and the data did not refute it
    assert all(0.0 <= c["margin_evidence"] < 1.0 for c in summary["cases"] if c.get("certified"))
    folder = tmp_path / "robust_adversarial"
    for ext in ("md", "json", "csv"):
        assert (folder / f"robust_adversarial.{ext}").exists()
    assert summary["silent_failures"] == 0, summary["silent_failure_cases"]
    if summary["false_certificates"] and summary["mode"].startswith("baseline"):
        # the pipeline without its premise test (validation=) is known to certify these; with it, strict
        pytest.xfail(f"baseline pipeline: false certificates {summary['false_certificate_cases']}")
    assert summary["false_certificates"] == 0, summary["false_certificate_cases"]


def test_held_out_data_reach_the_pipeline_when_it_takes_validation(monkeypatch):
    case = adv.catalogue()[0]
    seen = {}

    def with_validation(u, y, horizon, W1, W2, sigma, *, validation=None, **kwargs):
        seen["validation"], seen["n"] = validation, len(u)
        raise DataError("stop here: use a fake")

    monkeypatch.setattr(adv.uf, "robust_design_from_data", with_validation)
    out = adv.run_case(case)
    assert out["mode"] == "validation" and out["verdict"] == "refused_by_error"
    rec = adv.make_record(case)
    u_hold, y_hold = seen["validation"]
    np.testing.assert_array_equal(u_hold, rec.held_out[0])
    np.testing.assert_array_equal(y_hold, rec.held_out[1])
    assert seen["n"] == 2 * case.i + case.j - 1

    def without(u, y, horizon, W1, W2, sigma, **kwargs):
        seen["kwargs"] = kwargs
        raise DataError("stop here: use a fake")

    monkeypatch.setattr(adv.uf, "robust_design_from_data", without)
    out = adv.run_case(case)
    assert out["mode"].startswith("baseline") and "validation" not in seen["kwargs"]


def test_record_protocol_gives_the_pipeline_the_whole_record_and_the_window(monkeypatch):
    """``--protocol record``: the record, fitting part then held-out part, with ``window=`` the (7.5) window; no
    predictor, predictor_for or validation from the catalogue (the pipeline fits and holds out itself)."""
    case = adv.catalogue()[0]
    seen = {}

    def record_mode(u, y, horizon, W1, W2, sigma, **kwargs):
        seen.update(u=u, y=y, sigma=sigma, kwargs=kwargs)
        raise DataError("stop here: use a fake")

    monkeypatch.setattr(adv.uf, "robust_design_from_data", record_mode)
    out = adv.run_case(case, protocol="record")
    assert out["mode"] == "record (window=)" and out["verdict"] == "refused_by_error"
    rec = adv.make_record(case)
    np.testing.assert_array_equal(seen["u"], np.concatenate([rec.fit[0], rec.held_out[0]]))
    np.testing.assert_array_equal(seen["y"], np.concatenate([rec.fit[1], rec.held_out[1]]))
    assert seen["sigma"] == "auto" and seen["kwargs"]["window"] == (0, 2 * case.i + case.j - 1)
    assert not {"predictor", "predictor_for", "validation"} & set(seen["kwargs"])
    with pytest.raises(DataError, match="unknown protocol"):
        adv.run_case(case, protocol="window")


def test_record_protocol_refuses_the_drift_the_held_out_part_cannot_show():
    """The catalogue's false certificate at ``drift/third_order`` seed 4 (validation protocol: its 600 held-out
    samples do not show the drift) is refused in record mode by the time-invariance test on the whole record."""
    case = next(c for c in adv.catalogue(4) if c.name.startswith("drift/third_order"))
    out = adv.run_case(case, protocol="record")
    assert not out["certified"] and out["verdict"] == "not_certified"
    assert "not that of one time-invariant plant" in out["reason"]


def test_a_quantised_multisine_is_not_certified_on_its_window_leakage():
    """A low-band multisine played through a quantiser (a DAC at 1 % of its range: the plant receives the
    quantised signal) once certified a coprime-factor loop whose margin was false on the plant: the Welch bins
    above the band, which gather the band's lines, gave small disks around the in-band response (measured: the
    third-order and resonant plants, seed 0, both protocols).  Those bins are leaked now (their radius inf), and
    no loop certifies on them."""
    case = next(c for c in adv.catalogue(0) if c.name == "excitation/third_order/multisine[0.002-0.05]/DAC 1%")
    x = case.excitation.signal(1200, 0)
    step = 0.01 * (x.max() - x.min())
    assert np.allclose(x / step, np.round(x / step)) and np.unique(x).size > 20  # on the DAC's grid, many levels
    out = adv.run_case(case, protocol="validation")
    assert out["verdict"] != "false_certificate", out["true"]
    assert not out["certified"]


def test_the_judge_takes_a_plant_with_several_channels():
    """The true-plant judge on a two-input plant whose ``K(I+PK)⁻¹`` peaks on the second input had raised IndexError
    (the scalar worst-phase perturbation indexed the frequency grid by a flattened channel index), and a floor per
    output raised TypeError: a study re-run on a multi-channel record could not judge its certificates."""
    judge = adv.judge
    P = control.ss(np.diag([0.8, 0.5]), [[0.1, 1.0], [0.05, 0.8]], [[0.5, 0.4]], [[0.0, 0.0]], 0.1)
    K = control.ss([[1.0]], [[0.2, -0.2]], [[0.1], [1.0]], [[0.03, -0.03], [0.3, -0.3]], 0.1)  # PI on r − y
    t = judge(P, K, 0.05, 0.1)
    assert t["ok"] and t["stable"] and 0 < t["small_gain"] < 0.1 and t["tracks"]
    tall = control.ss(np.diag([0.8, 0.5]), [[1.0], [0.4]], [[0.5, 0.4], [0.3, -0.2]], [[0.0], [0.0]], 0.1)
    K2 = control.ss([[1.0]], [[0.2, 0.0, -0.2, 0.0]], [[1.0]], [[0.3, 0.0, -0.3, 0.0]], 0.1)  # tracks output 0
    t2 = judge(tall, K2, 0.05, (0.1, float("inf")))
    assert t2["ok"] and t2["tracks"] and t2["step_error"] == pytest.approx(1.0)  # output 1 not tracked, not judged
    assert not judge(tall, K2, 0.05, (0.1, 0.1))["tracks"]
