"""``python -m experiments cd-player --quick``: the design workflow on the shipped real record (i = 10).

Real data, no true plant: the test checks the run's form (verdict, δ, reason, files) and that a refusal
comes with its reason, not which verdict the pipeline reaches.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

from experiments.studies import cd_player
from experiments.cli import main


def test_shipped_data_and_licence_are_in_the_package():
    data = Path(cd_player.DATA_FILE)
    assert data.is_file() and data.stat().st_size < 100_000
    for name in ("LICENSE-SLICOT-SystemIdentification", "README.md"):
        assert (data.parent / name).is_file(), name
    assert "BSD 3-Clause" in (data.parent / "LICENSE-SLICOT-SystemIdentification").read_text()


def test_cd_player_quick(tmp_path, capsys):
    assert main(["cd-player", "--quick", "--json", "--out", str(tmp_path)]) == 0
    summary = json.loads(capsys.readouterr().out)
    for key in ("certified", "delta", "reason", "seconds", "runs", "controller_npz", "controller_mat"):
        assert key in summary, key
    assert isinstance(summary["certified"], bool)
    assert math.isfinite(summary["delta"]) and summary["delta"] > 0
    assert summary["horizon"] == cd_player.HORIZONS[0] and len(summary["runs"]) == 1
    if not summary["certified"]:
        assert summary["reason"].strip()
    else:
        assert summary["reason"] == ""
    out = tmp_path / "cd_player"
    assert (out / "cd_player.md").is_file() and Path(summary["controller_npz"]).is_file()
    from _reports import assert_reports_complete

    assert_reports_complete(out, "cd-player")
