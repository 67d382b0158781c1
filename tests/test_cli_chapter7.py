"""``python -m experiments chapter7 --quick``: files, δ certificates, small-gain claims vs closed-loop poles.

Data seed 0 (CLI default), quick sizes: ARX n = 20 (both forms), subspace (i, j) = (12, 60), σ = 0.03.
"""
from __future__ import annotations

import json

import control
import numpy as np
import pytest

from experiments.studies import chapter7 as c7
from experiments.lab.servo_setup import closed_loop_matrix, design_weights, servo_data
from experiments.cli import main
from experiments.lab.plants import servo
from synthesis import fit_predictor, hinf_design

pytestmark = pytest.mark.slow  # minutes of CLI/LMI work: deselect with -m 'not slow'


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("chapter7")
    assert main(["chapter7", "--quick", "--out", str(out)]) == 0
    out = out / "chapter7"
    return out, json.loads((out / "chapter7.json").read_text())


def test_writes_report_figures_and_data(quick_run):
    out, summary = quick_run
    md = (out / "chapter7.md").read_text()
    for heading in ("ARX unfalsification", "subspace unfalsification", "Theorem 3.7", "Small-gain certificate",
                    "additive perturbations"):
        assert heading in md
    assert {"chapter7_small_gain.png", "chapter7_steps.png"} <= {p.name for p in out.glob("*.png")}
    assert (out / "chapter7_arx.csv").exists() and (out / "chapter7_steps.csv").exists()
    assert summary["quick"] is True


def test_delta_is_certified_and_both_arx_forms_agree(quick_run):
    _, s = quick_run
    sub = s["subspace"]
    assert sub["status"] in ("optimal", "optimal_inaccurate")
    assert sub["certificate_ok"] and sub["delta"] > 0
    assert sub["delta_certified"] == pytest.approx(sub["delta"], rel=1e-4)
    assert s["delta"] == pytest.approx(sub["delta"])
    forms = {a["form"]: a for a in s["arx"] if a["n"] == 20}
    # two formulations of (7.4): the literal LMI and the T(u)h substitution
    assert forms["thesis"]["delta"] == pytest.approx(forms["conditioned"]["delta"], rel=1e-3)
    for a in s["arx"]:
        assert a["cond_Tu"] > 1 and a["solve_time"] > 0


def test_w3_rules_and_gamma_ordering(quick_run):
    _, s = quick_run
    d = s["designs"]
    delta = s["delta"]
    assert d["gamma_min_a"] > d["gamma_min_nominal"]  # Theorem 3.7 remark: γ_min_a > γ_min
    assert d["covered_delta"] == pytest.approx(d["w3_gain"] / d["gamma_robust"])
    # the fixed point covers (1 + margin)δ; the design search may only widen W3 (factors ≥ 1)
    assert d["covered_delta"] >= (1 + d["margin"]) * delta * (1 - 1e-6)
    if d["designs_tried"] == 1:
        assert d["covered_delta"] == pytest.approx((1 + d["margin"]) * delta, rel=1e-6)
    # the loop that ships is certified on the data-based models, or refused with the reason. At the quick size
    # ((12, 60), σ = 0.03) δ of (7.5) is 0.009 and the held-out experiment shows P̂ off by more than that at
    # high frequency: the premise is falsified and the verdict says so (measured)
    assert d["delta_output_error"] >= 0 and delta == max(d["delta_subspace"], d["delta_output_error"])
    if d["certified"]:
        assert d["certificate_reason"] == "" and d["small_gain_on_model"] <= 1 / 1.25
    else:
        assert "premise not supported by the data" in d["certificate_reason"]
    assert d["thesis_rule_w3_gain"] == pytest.approx(1 / delta)
    for r in s["delta_sweep"]:
        assert r["covered"] >= r["delta"]


def test_small_gain_certificate_agrees_with_perturbed_poles(quick_run):
    """Where δ‖KS‖∞ < 1 every size-δ perturbation tried must leave the closed-loop poles inside the circle."""
    _, s = quick_run
    for cert in s["certificates"].values():
        assert cert["delta_times_peak"] == pytest.approx(s["delta"] * cert["peak_KS"])
        assert cert["radius"] == pytest.approx(1 / cert["peak_KS"])
    sm = s["step_metrics"]
    for name in ("nominal (Thm 3.1)", "robust, W3 = c (small-gain rule)"):
        assert s["certificates"][name]["certifies_delta"]
        size_delta = [k for k in sm if k.startswith(name + " / ") and "δ" in k.split(" / ")[1]
                      and "1.05" not in k]
        assert len(size_delta) == 2
        for k in size_delta:
            assert sm[k]["stable"] and sm[k]["max_abs_y"] < 2
        beyond = [k for k in sm if k.startswith(name + " / ") and "1.05" in k]
        assert len(beyond) == 1 and not sm[beyond[0]]["stable"]  # the radius is tight in the worst phase


@pytest.fixture(scope="module")
def small_loop():
    W = design_weights()
    d = servo_data(200, seed=1)
    pred = fit_predictor(d.u, d.y, 10)
    return servo(), hinf_design(pred, W["W11"], W["W21"]).controller


def test_additive_channel_response_second_route(small_loop):
    """M = C_y/(1 − C_y P) from the two frequency responses, point by point."""
    P, K = small_loop
    w = np.array([0.05, 0.5, 2.0, 10.0, 30.0])
    z = np.exp(1j * w * P.dt)
    Cy = np.array([complex(np.asarray(control.ss(K)[:, 1](zk)).item()) for zk in z])
    Pz = np.array([complex(np.asarray(P(zk)).item()) for zk in z])
    assert c7.additive_channel_response(P, K, w) == pytest.approx(Cy / (1 - Cy * Pz), rel=1e-8)


def test_worst_phase_allpass(small_loop):
    P, K = small_loop
    size = 0.02
    pd, info = c7.worst_phase_allpass(P, K, size)
    w = np.linspace(1e-3, np.pi / P.dt, 500)
    mag = np.abs(np.asarray(pd(np.exp(1j * w * P.dt))).reshape(-1))
    assert mag == pytest.approx(np.full_like(w, size), rel=1e-9)  # all-pass of size `size`
    assert np.all(np.abs(control.poles(pd)) < 1)
    M = c7.additive_channel_response(P, K, np.array([info["omega"]]))[0]
    loop = complex(np.asarray(pd(np.exp(1j * info["omega"] * P.dt))).item()) * M
    assert abs(np.angle(loop)) < 2e-3 and abs(loop) == pytest.approx(size * info["peak"])
    # growing the perturbation past 1/peak in that phase loses stability (poles, not simulation)
    big, _ = c7.worst_phase_allpass(P, K, 1.05 / info["peak"])
    small, _ = c7.worst_phase_allpass(P, K, 0.95 / info["peak"])
    rho = lambda pert: np.max(np.abs(np.linalg.eigvals(  # noqa: E731
        closed_loop_matrix(control.ss(control.parallel(control.ss(P), control.ss(pert))), K))))
    assert rho(small) < 1 < rho(big)


def test_report_tables_and_figures_are_complete(quick_run):
    from _reports import assert_reports_complete

    assert_reports_complete(quick_run[0], "chapter7")
