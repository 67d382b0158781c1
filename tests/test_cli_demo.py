"""``python -m experiments demo``: the README's main job (defaults; seed 0)."""
from __future__ import annotations

import json

import pytest

from experiments.lab.servo_setup import THESIS_TABLE_5_1
from experiments.cli import main

pytestmark = pytest.mark.slow  # minutes of CLI/LMI work: deselect with -m 'not slow'

# ``demo --json`` (JSON alone on stdout, naming the report) is run by tests/test_cli_quick.py with ``--quick``.


def test_demo_writes_report_and_prints_summary(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path)]) == 0
    printed = capsys.readouterr().out
    tmp_path = tmp_path / "demo"  # the CLI writes into <out>/demo/
    assert "demo.md" in printed and "Design 1" in printed and "δ" in printed
    assert printed.startswith(f"demo: report: {tmp_path / 'demo.md'}")
    md = (tmp_path / "demo.md").read_text()
    assert "Table 5.1" in md and "§7.4" in md
    assert (tmp_path / "demo_table5_1_steps.png").exists()
    assert (tmp_path / "chapter7" / "chapter7.md").exists()
    for png in ("chapter7/chapter7_steps.png", "chapter7/chapter7_small_gain.png", "demo_table5_1_steps.png"):
        assert png in md and (tmp_path / png).exists()
    summary = json.loads((tmp_path / "demo.json").read_text())
    for name, (g, gam) in THESIS_TABLE_5_1.items():
        assert summary["table_5_1"][name]["gamma_min"] == pytest.approx(g, rel=0.03)
        assert summary["table_5_1"][name]["gamma"] == pytest.approx(gam, rel=0.03)
    assert summary["chapter7"]["delta"] > 0
    assert summary["seconds"] < 120
    from _reports import assert_reports_complete

    assert_reports_complete(tmp_path, "demo")  # demo.md and chapter7/chapter7.md
