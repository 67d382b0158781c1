"""`python -m experiments noncollocated --quick` (§6.2): files, and its numbers by second routes.

The plant is rebuilt here from the §6.1 transfer function (python-control ``tf`` + ZOH), not
from ``experiments.lab.plants``; closed loops are formed with python-control's ``feedback``, not
with the experiment's own interconnection; γ_min is recomputed with the QR predictor.
"""
import csv
import json

import control as ct
import numpy as np
import pytest

from experiments import cli
from experiments.studies import noncollocated
from experiments.lab.plants import THREE_DISK_DT as DT
from experiments.lab.torsional_setup import NONCOLLOCATED

import synthesis


def _thesis_y3_plant():
    k, a = 24.26, 0.35
    wz1, wz2 = 10.65, 42.00  # (the y3 transfer function has no zeros: ζz1, ζz2 do not enter)
    zp1, wp1, zp2, wp2 = 0.024, 15.85, 0.010, 43.50
    den = np.polymul(np.polymul([1, a, 0], [1, 2 * zp1 * wp1, wp1**2]), [1, 2 * zp2 * wp2, wp2**2])
    # state space before sampling: a tf of this order in polynomial form loses ~1e-4 in a closed loop
    return ct.c2d(ct.ss(ct.tf([k * wz1**2 * wz2**2], den)), DT, method="zoh")


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("nc")
    assert cli.main(["noncollocated", "--quick", "--out", str(out)]) == 0
    return out / "noncollocated"


@pytest.fixture(scope="module")
def summary(run_dir):
    return json.loads((run_dir / "noncollocated.json").read_text())


@pytest.fixture(scope="module")
def controllers(run_dir):
    z = np.load(run_dir / "controllers.npz")
    mk = lambda p: ct.ss(z[p + "_A"], z[p + "_B"], z[p + "_C"], z[p + "_D"], float(z["dt"]))  # noqa: E731
    return mk("K_sub"), mk("K_model"), float(z["gamma_sub"]), float(z["gamma_model"])


def _read_csv(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    return rows[0], np.array(rows[1:], dtype=float)


def test_files_written(run_dir, summary):
    names = {p.name for p in run_dir.iterdir()}
    assert "noncollocated.md" in names and "noncollocated.json" in names
    assert len([n for n in names if n.endswith(".png")]) >= 4
    md = (run_dir / "noncollocated.md").read_text()
    assert "γ_min" in md and "fig6_5_step.png" in md
    assert set(summary["files"]) <= names


def test_subspace_controller_stabilises_true_plant(controllers):
    K_sub, _, _, _ = controllers
    P = _thesis_y3_plant()
    # u = K_r r + K_y y; the loop is P in positive feedback with K_y
    cl = ct.feedback(P, K_sub[0, 1], sign=+1)
    poles = ct.poles(cl)
    assert np.max(np.abs(poles)) < 1.0


def test_model_based_closed_loop_norm_below_gamma(controllers, summary):
    _, K_model, _, gamma_model = controllers
    P = _thesis_y3_plant()
    W1, W2 = (ct.c2d(W, DT, method="tustin") for W in NONCOLLOCATED.continuous())
    L = P * K_model
    assert np.max(np.abs(ct.poles(ct.feedback(L, 1)))) < 1.0
    w = np.logspace(-2, np.log10(np.pi / DT) - 1e-4, 3000)
    zz = np.exp(1j * w * DT)
    Lz = np.array([complex(ct.evalfr(L, z)) for z in zz])
    Kz = np.array([complex(ct.evalfr(K_model, z)) for z in zz])
    S = 1.0 / (1.0 + Lz)
    w1 = np.array([complex(ct.evalfr(W1, z)) for z in zz])
    w2 = np.array([complex(ct.evalfr(W2, z)) for z in zz])
    peak = np.max(np.sqrt(np.abs(w1 * S) ** 2 + np.abs(w2 * Kz * S) ** 2))
    assert peak <= gamma_model * (1 + 1e-6)
    assert gamma_model == pytest.approx(1.35 * summary["model_based"]["gamma_opt"], rel=1e-9)
    # the experiment's own grid value agrees with this independent evaluation
    assert summary["model_based"]["weighted_closed_loop_hinf_on_grid"] == pytest.approx(peak, rel=2e-2)
    # the report's bracket: its proven upper side is at least every grid value (a grid is a lower bound)
    for key in ("model_based", "subspace"):
        br = summary[key]["weighted_closed_loop_hinf_bracket"]
        if br.startswith("["):
            lo, up = (float(v) for v in br.strip("[]").split(","))
            assert lo <= up and summary[key]["weighted_closed_loop_hinf_on_grid"] <= up * (1 + 1e-9)
    # thesis §6.2: the ∞-horizon γ_opt is 2.24 with the thesis's (unknown) weights;
    # ours were chosen to land near it
    assert 2.0 < summary["model_based"]["gamma_opt"] < 2.5


def test_gamma_min_by_qr_predictor(run_dir, summary):
    _, data = _read_csv(run_dir / "data.csv")
    u, y = data[:, 1], data[:, 2]
    pred = synthesis.fit_predictor(u, y, summary["i"], method="qr")
    W1, W2 = NONCOLLOCATED.discrete(DT)
    g = synthesis.gamma_min(pred, W1, W2)
    assert summary["subspace"]["gamma_min"] == pytest.approx(g, rel=1e-6)
    assert summary["subspace"]["gamma"] == pytest.approx(1.35 * g, rel=1e-6)


def test_step_responses_by_python_control(run_dir, controllers):
    K_sub, K_model, _, _ = controllers
    head, step = _read_csv(run_dir / "step.csv")
    t = step[:, 0]
    P = _thesis_y3_plant()
    T_ideal = ct.feedback(P * K_model, 1)
    # y = P u, u = K_r r + K_y y  =>  y = (1 - P K_y)^-1 P K_r r
    T_sub = ct.feedback(P, K_sub[0, 1], sign=+1) * K_sub[0, 0]
    for T, col in ((T_ideal, "y_ideal"), (T_sub, "y_subspace")):
        y = ct.forced_response(T, T=t, U=np.ones_like(t)).outputs
        assert np.max(np.abs(y - step[:, head.index(col)])) < 1e-6 * max(1.0, np.max(np.abs(y)))


def test_step_metrics_on_closed_forms():
    t = np.arange(0, 20, 1e-3)
    tau = 0.5
    m = noncollocated.step_metrics(t, 1 - np.exp(-t / tau))
    assert m["rise_time_s"] == pytest.approx(tau * np.log(9), rel=1e-3)
    assert m["steady_state_error"] == pytest.approx(0.0, abs=1e-6)
    wd, sigma = 2 * np.pi * 3.5, 0.4
    y = 0.82 * (1 - np.exp(-sigma * t) * np.cos(wd * t))
    m = noncollocated.step_metrics(t, y)
    assert m["ringing_hz"] == pytest.approx(3.5, rel=1e-3)
    assert m["steady_state_error"] == pytest.approx(0.18, abs=1e-3)
    wrong_way = noncollocated.step_metrics(t, -(1 - np.exp(-t / tau)))
    assert np.isnan(wrong_way["rise_time_s"]) and wrong_way["steady_state_error"] == pytest.approx(2.0)


def test_chosen_weights_match_their_documentation():
    from experiments.lab import torsional_setup

    for spec, crossing in ((NONCOLLOCATED, 23.06), (torsional_setup.COLLOCATED, 64.59)):
        W1c, W2c = spec.continuous()
        W1d, W2d = spec.discrete(DT)
        assert 20 * np.log10(abs(complex(ct.evalfr(W1c, 0)))) == pytest.approx(26.02, abs=0.01)
        # Tustin maps s = 0 to z = 1 and s = ∞ to z = −1
        assert complex(ct.evalfr(W1d, 1.0)) == pytest.approx(complex(ct.evalfr(W1c, 0)))
        assert complex(ct.evalfr(W2d, -1.0)) == pytest.approx(spec.c, rel=1e-9)
        w = np.linspace(0.8 * crossing, 1.2 * crossing, 4001)
        mag = np.abs([complex(ct.evalfr(W1c, 1j * x)) for x in w])
        assert w[np.argmin(np.abs(mag - 1))] == pytest.approx(crossing, rel=1e-3)
        assert np.linalg.matrix_rank(np.atleast_2d(W1d.D)) == 1 and np.linalg.matrix_rank(np.atleast_2d(W2d.D)) == 1
    with pytest.raises(ValueError, match="unknown weight set"):
        torsional_setup.torsional_weights("colocated")


def test_bad_input_raises():
    with pytest.raises(ValueError, match="same length"):
        noncollocated.step_metrics(np.arange(10.0), np.arange(9.0))
    P = _thesis_y3_plant()
    with pytest.raises(ValueError, match="inputs"):
        noncollocated.closed_loop_system(P, ct.ss([[0.5]], [[1, 1, 1]], [[1]], [[0, 0, 0]], DT))
    with pytest.raises(ValueError, match="strictly proper"):
        noncollocated.closed_loop_system(ct.ss([[0.5]], [[1]], [[1]], [[1]], DT), ct.ss([[0.5]], [[1]], [[1]], [[0]], DT))


def test_report_tables_and_figures_are_complete(run_dir):
    from _reports import assert_reports_complete

    assert_reports_complete(run_dir, "noncollocated")
