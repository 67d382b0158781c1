"""`python -m experiments bench-adaptive --quick`: files, percentiles, breakdown, and the agreement of
the adaptive designs with a batch design (timings themselves are only reported, never asserted)."""
import csv
import json

import numpy as np
import pytest

from experiments import cli


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench_ad")
    assert cli.main(["bench-adaptive", "--quick", "--out", str(out)]) == 0
    return out / "bench_adaptive"


def test_files_and_summary(run_dir):
    names = {p.name for p in run_dir.iterdir()}
    s = json.loads((run_dir / "bench_adaptive.json").read_text())
    assert set(s["files"]) <= names
    assert s["quick"] and s["n_updates"] >= 30
    for phase in ("total", "push", "predictor", "design"):
        st = s["stats_s"][phase]
        assert 0 <= st["p50"] <= st["p99"] <= st["max"]
    assert s["stats_s"]["total"]["max"] > 0
    assert "route before (spectral + hinf_design + StateSpace)" in s["breakdown_s"]
    # the same closed loop redesigned by the route before: same γ_min history to rounding
    assert s["stats_before_s"]["total"]["p50"] > 0
    assert s["gamma_min_max_rel_diff_vs_before"] < 1e-6
    md = (run_dir / "bench_adaptive.md").read_text()
    assert "p99" in md and "Breakdown" in md and "bench_adaptive.png" in md


def test_csv_has_one_row_per_update(run_dir):
    with open(run_dir / "bench_adaptive.csv") as f:
        rows = list(csv.reader(f))
    s = json.loads((run_dir / "bench_adaptive.json").read_text())
    assert rows[0][:3] == ["step", "n_columns", "seconds"]
    data = np.array(rows[1:], dtype=float)
    assert data.shape[0] == s["n_updates"]
    assert np.all(np.diff(data[:, 0]) == s["period"])
    # the phases never exceed the recorded total
    assert np.all(data[:, 3:6].sum(axis=1) <= data[:, 2] * (1 + 1e-9) + 1e-9)
    assert rows[0][6] == "cpu_seconds" and np.all(data[:, 6] > 0)


def test_adaptive_design_equals_batch_design(run_dir):
    a = json.loads((run_dir / "bench_adaptive.json").read_text())["agreement"]
    assert a["gamma_min_rel"] <= 1e-9 and a["gain_rel"] <= 1e-9
    # second route: the engine on the full map, γ_min by an SVD of the explicit projection, SVD gains
    assert a["gamma_min_rel_projection_svd"] <= 1e-9 and a["gain_rel_full_map_svd_route"] <= 1e-9


def test_bench_adaptive_is_registered():
    assert "bench-adaptive" in cli.COMMANDS
