"""Every subcommand of ``python -m experiments`` runs with ``--quick`` (issue "From a data file to a saved,
certified controller", item 5c: ``demo --quick`` crashed with an IndexError in chapter7).

Subcommands that already have a ``--quick`` CLI test elsewhere are not run again here; the coverage
test checks that every entry of ``experiments.cli.COMMANDS`` is run by one or the other.
"""
import json
import re
from pathlib import Path

import pytest

from experiments import cli

TESTS = Path(__file__).resolve().parent

#: measured with --quick on a loaded 2-core machine: demo 33 s, bench-split 32 s, sweep 16 s, robust-pipeline 14 s,
#: bench-predictor 3.5 s
HERE = {
    "demo": (pytest.mark.slow, ()),
    "robust-pipeline": (pytest.mark.slow, ()),
    "bench-predictor": (None, ()),
    "bench-split": (pytest.mark.slow, ()),
    "sweep": (pytest.mark.slow, ("--workers", "1")),
}


def _tested_elsewhere() -> set[str]:
    """Subcommands run through the CLI with --quick by another test file."""
    found = set()
    for path in TESTS.glob("test_*.py"):
        if path.name == Path(__file__).name:
            continue
        found.update(re.findall(r'main\(\[\s*"([a-z0-9-]+)",\s*"--quick"', path.read_text(encoding="utf-8")))
    return found


def test_every_subcommand_has_a_quick_run():
    elsewhere = _tested_elsewhere()
    missing = set(cli.COMMANDS) - elsewhere - set(HERE)
    assert not missing, f"subcommands without a --quick CLI test: {sorted(missing)}; add them to HERE"
    assert not (set(HERE) - set(cli.COMMANDS)), "HERE names a subcommand that no longer exists"


@pytest.mark.parametrize("name", [pytest.param(n, marks=[m] if m else []) for n, (m, _) in HERE.items()])
def test_quick_run(name, tmp_path, capsys):
    extra = list(HERE[name][1])
    assert cli.main([name, "--quick", "--json", "--out", str(tmp_path), *extra]) == 0
    summary = json.loads(capsys.readouterr().out)
    folder = cli.output_dir(tmp_path, name)
    assert folder.is_dir() and any(folder.iterdir())
    if "report" in summary:
        assert Path(summary["report"]).is_file()
