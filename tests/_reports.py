"""Checks shared by the CLI tests: every markdown table is well formed, every figure complete (issue #13)."""
from __future__ import annotations

from pathlib import Path

from experiments.lab.report import FIGURE_PROBLEMS, markdown_tables


def table_problems(md: Path) -> list[str]:
    """Rows whose number of cells differs from the header's, in every table of ``md``."""
    problems = []
    for k, table in enumerate(markdown_tables(md.read_text())):
        width = len(table[0])
        for r, row in enumerate(table[1:], start=1):
            if len(row) != width:
                problems.append(f"{md.name} table {k} row {r}: {len(row)} cells, header has {width}: {row}")
    return problems


def assert_reports_complete(run_dir: Path, command: str | None = None) -> None:
    """Every ``*.md`` under ``run_dir`` has well-formed tables; every PNG saved there passed ``check_figure``.

    With ``command``, also: the run's JSON summary names its report, and the CLI's closing summary
    (``experiments.cli.summary_text`` with the module's ``summary_lines``) names it too.
    """
    if command is not None:
        import importlib
        import json

        from experiments.cli import COMMANDS, summary_text

        summary = json.loads((Path(run_dir) / f"{command.replace('-', '_')}.json").read_text())
        assert Path(summary["report"]).exists()
        mod = importlib.import_module(COMMANDS[command][0])
        text = summary_text(command, summary, getattr(mod, "summary_lines", None))
        assert text.startswith(f"{command}: report: {summary['report']}")
    mds = sorted(Path(run_dir).rglob("*.md"))
    assert mds, f"no markdown report under {run_dir}"
    problems = [p for md in mds for p in table_problems(md)]
    pngs = sorted(Path(run_dir).rglob("*.png"))
    for png in pngs:
        assert str(png) in FIGURE_PROBLEMS, f"{png.name} was not written by experiments.lab.report.save_figure"
        problems += [f"{png.name}: {p}" for p in FIGURE_PROBLEMS[str(png)]]
    assert not problems, "\n".join(problems)
