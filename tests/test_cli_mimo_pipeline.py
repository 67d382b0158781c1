"""``python -m experiments mimo-pipeline --quick``: the §7.4 pipeline on a 2 × 2 plant, judged on the true plant."""
from __future__ import annotations

import json

import control
import numpy as np
import pytest

from experiments.cli import main
from experiments.studies import mimo_pipeline as mp


def test_judge_fails_an_unstable_and_passes_a_good_loop():
    P = mp.coupled_lags()
    good = control.ss([], [], [], np.hstack([0.5 * np.eye(2), -0.5 * np.eye(2)]), 1.0)
    bad = control.ss([], [], [], np.hstack([50 * np.eye(2), -50 * np.eye(2)]), 1.0)
    assert not mp.judge(P, bad, 0.01)["ok"] and "unstable" in mp.judge(P, bad, 0.01)["fails"][0]
    j = mp.judge(P, good, 0.01, floor=1.0)
    assert j["stable"] and j["small_gain"] < 1


def test_tall_plant_tracks_its_first_output_only():
    assert mp.tracking_floor(mp.tall()) == (0.1, float("inf"))
    assert mp.tracking_floor(mp.coupled_lags()) == (0.1, 0.1)


@pytest.mark.slow
def test_mimo_pipeline_quick(tmp_path, capsys):
    assert main(["mimo-pipeline", "--quick", "--json", "--out", str(tmp_path)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["runs"] == 2 and summary["false_certificates"] == 0 and summary["silent_failures"] == 0
    by_case = {r["excitation"]: r for r in summary["cases"]}
    assert by_case["silent_channel"]["verdict"] in ("not_certified", "refused_by_error")
    assert "u[:, 1]" in by_case["silent_channel"]["reason"]          # the silent input is named
    prbs = by_case["prbs"]
    if prbs["verdict"] == "certified":                                 # then the premise held on the true plant
        assert prbs["premise_ratio"] < 1.25 and prbs["true_small_gain"] < 1
    assert (tmp_path / "mimo_pipeline" / "mimo_pipeline.md").is_file()
