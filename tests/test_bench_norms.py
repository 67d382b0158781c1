import pytest
"""Smoke test of ``python -m experiments bench-norms --quick``."""
import json

from experiments.bench.bench_norms import run
from experiments.cli import Options, main

pytestmark = pytest.mark.slow  # minutes of CLI/LMI work: deselect with -m 'not slow'


def test_bench_norms_quick(tmp_path):
    summary = run(Options(quick=True, out=tmp_path))
    assert (tmp_path / "bench_norms.md").exists() and (tmp_path / "bench_norms.csv").exists()
    assert (tmp_path / "bench_norms_speedup.png").stat().st_size > 1000
    data = json.loads((tmp_path / "bench_norms.json").read_text())
    assert data["quick"] is True
    rows = {r["case"]: r for r in summary["rows"]}
    assert set(rows) == {"additive_robustness", "discrete_mixsyn", "collect_data"}
    assert rows["discrete_mixsyn"]["agreement"] == "same gamma_opt: True"
    assert rows["additive_robustness"]["agreement"].endswith("True")  # grid peak inside the bracket
    assert "0.00e+00" in rows["collect_data"]["agreement"] or "e-1" in rows["collect_data"]["agreement"]


def test_cli_registers_bench_norms(tmp_path):
    assert main(["bench-norms", "--quick", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "bench_norms" / "bench_norms.json").exists()
