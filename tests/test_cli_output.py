"""What a CLI user sees (issue #13, item 1): a closing summary, JSON only with --json, partial reports kept."""
from __future__ import annotations

import json
import os
import sys
import types

import pytest

from experiments import cli
from experiments.lab.report import LiveTable, check_figure, format_table, markdown_tables


@pytest.fixture
def fake_command(monkeypatch):
    mod = types.ModuleType("fake_experiment")

    def run(opts):
        print("chatter from the experiment")
        md = opts.out / "fake.md"
        md.write_text("# fake\n")
        return {"report": str(md), "seconds": 1.25, "value": 3}

    mod.run = run
    mod.summary_lines = lambda s: [f"value = {s['value']}"]
    monkeypatch.setitem(sys.modules, "fake_experiment", mod)
    monkeypatch.setitem(cli.COMMANDS, "fake", ("fake_experiment", "run", "a test double"))


def test_every_run_ends_with_a_summary_naming_its_report(fake_command, tmp_path, capsys):
    assert cli.main(["fake", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[-2:] == [f"fake: report: {tmp_path / 'fake' / 'fake.md'} (1.2 s)", "  value = 3"]


def test_json_flag_prints_only_json(fake_command, tmp_path, capsys):
    assert cli.main(["fake", "--json", "--out", str(tmp_path)]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out) == {"report": str(tmp_path / "fake" / "fake.md"), "seconds": 1.25, "value": 3}
    assert "chatter" in captured.err


def test_summary_without_report_names_the_folder(tmp_path):
    assert cli.summary_text("x", {}, out=tmp_path) == f"x: output in {tmp_path}"


def test_every_subcommand_returns_a_report_key():
    import inspect
    import importlib

    for name, (module, *_) in cli.COMMANDS.items():
        src = inspect.getsource(importlib.import_module(module))
        assert '"report"' in src or "finish_report(" in src, name


def test_live_table_keeps_rows_of_an_interrupted_run(tmp_path):
    live = LiveTable(tmp_path, "bench", "Bench", ["size", "time [s]"], intro="intro")
    live.add([10, 0.5])
    live.add([20, 1.5], record={"size": 20, "wall_s": 1.5})
    md = (tmp_path / "bench.md").read_text()
    assert "Partial results: 2 row(s)" in md and markdown_tables(md) == [
        [["size", "time [s]"], ["------", "----------"], ["10", "0.5"], ["20", "1.5"]]]
    data = json.loads((tmp_path / "bench.json").read_text())
    assert data["partial"] and data["rows"] == [[10, 0.5], {"size": 20, "wall_s": 1.5}]
    with pytest.raises(ValueError, match="2 headers"):
        live.add([1, 2, 3])


def test_bench_unfalsify_interrupted_after_one_solve_keeps_it(tmp_path, monkeypatch):
    from experiments.bench import bench_unfalsify

    calls = []

    def fake_solve(spec, size, seed, budget):
        if calls:
            raise KeyboardInterrupt
        calls.append(size)
        return {"size": size, "label": str(size), "status": "optimal", "delta": 0.1, "wall_s": 0.2}

    monkeypatch.setattr(bench_unfalsify, "_run_with_budget", fake_solve)
    with pytest.raises(KeyboardInterrupt):
        bench_unfalsify.run(cli.Options(quick=True, out=tmp_path))
    table = markdown_tables((tmp_path / "bench_unfalsify.md").read_text())[0]
    assert len(table) == 3 and table[2][2] == "optimal"
    assert json.loads((tmp_path / "bench_unfalsify.json").read_text())["rows"][0]["delta"] == 0.1


def test_table_cells_with_pipes_are_escaped():
    text = format_table(["max |pole|", "x"], [["‖K|S‖", 1.0], ["a \\| b", 2.0]])
    assert all(len(row) == 2 for row in markdown_tables(text)[0])


def test_check_figure_finds_missing_labels_legend_and_hidden_curves():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    ax.plot([0, 1, 2], [1, 2, 3], label="nominal")
    ax.plot([0, 1, 2], [1, 2, 3], label="robust")
    problems = check_figure(fig)
    assert "axes 0: no x label" in problems and "axes 0: no y label" in problems and "no legend" in problems
    assert any("hidden under" in p for p in problems)
    ax.lines[1].set_linestyle("--")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("y (rad)")
    ax.legend()
    assert check_figure(fig) == []
    plt.close(fig)


def test_an_output_folder_that_cannot_be_made_is_a_usage_error(fake_command, tmp_path, capsys):
    """``--out`` below a file (or anywhere not writable) had ended every command in a FileNotFoundError traceback."""
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    with pytest.raises(SystemExit) as caught:
        cli.main(["fake", "--out", str(blocker / "results")])
    assert caught.value.code == 2
    assert "cannot create the output folder" in capsys.readouterr().err


@pytest.mark.parametrize("command, option", [("sweep", "--workers"), ("bench-split", "--workers"),
                                             ("bench-unfalsify", "--repeats")])
@pytest.mark.parametrize("value", ["-5", "0", "two"])
def test_counts_are_refused_at_parsing(command, option, value, tmp_path, capsys):
    """``--workers -5`` had reached the run and ended in a DataError traceback (sweep, bench-split)."""
    with pytest.raises(SystemExit) as caught:
        cli.main([command, option, value, "--quick", "--out", str(tmp_path)])
    assert caught.value.code == 2
    assert "give an integer ≥ 1" in capsys.readouterr().err



_BLAS_SCRIPT = """
import json, os, sys, types
from threadpoolctl import threadpool_info
from experiments import cli

def threads():
    return sorted({p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"})

seen = {}
for module in ("fake_study", "experiments.bench.fake_bench", "fake_study_with_variable"):
    if module == "fake_study_with_variable":
        os.environ["OPENBLAS_NUM_THREADS"] = "2"   # the user's own count
    mod = types.ModuleType(module)
    mod.run = lambda opts, module=module: (seen.__setitem__(module, threads()), {"report": "", "seconds": 0.0})[1]
    sys.modules[module] = mod
    cli.COMMANDS["fake"] = (module, "run", "a test double")
    cli.main(["fake", "--json", "--out", sys.argv[1]])
print(json.dumps({"seen": seen, "after": threads()}), file=sys.stderr)
"""


def test_studies_run_blas_on_one_thread_unless_the_environment_says_otherwise(tmp_path):
    """The study commands on 2 cores ran twice as long with OpenBLAS's two threads (chapter7 --quick 19 s against
    9 s): they hold BLAS to one thread for the run and restore it after; benchmarks and a user's own thread count
    are left alone.  In a child process: this suite's conftest holds its own process to one thread."""
    import subprocess

    env = {k: v for k, v in os.environ.items() if k not in cli.BLAS_VARIABLES}
    child = subprocess.run([sys.executable, "-c", _BLAS_SCRIPT, str(tmp_path)], env=env, capture_output=True,
                           text=True, timeout=120)
    assert child.returncode == 0, child.stderr
    report = json.loads(child.stderr.strip().splitlines()[-1])
    configured = report["after"]
    if configured == [1]:
        pytest.skip("BLAS runs one thread on this machine: nothing to hold")
    assert report["seen"] == {"fake_study": [1], "experiments.bench.fake_bench": configured,
                              "fake_study_with_variable": configured}
