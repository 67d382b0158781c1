"""Smoke test of ``python -m experiments bench-unfalsify --quick``."""
import json

import pytest

from synthesis import DataError
from experiments.bench.bench_unfalsify import run
from experiments.cli import Options, main

pytestmark = pytest.mark.slow  # minutes of CLI/LMI work: deselect with -m 'not slow'


def test_bench_unfalsify_quick(tmp_path):
    summary = run(Options(quick=True, out=tmp_path))
    assert (tmp_path / "bench_unfalsify.md").exists()
    data = json.loads((tmp_path / "bench_unfalsify.json").read_text())
    assert data["quick"] is True
    forms = {(s["kind"], s["form"], s["eliminate_L"]) for s in summary["series"]}
    assert ("arx", "thesis", False) in forms and ("subspace", "conditioned", True) in forms
    assert any("2×2" in s["series"] for s in summary["series"])  # the MIMO row (issue 28)
    for s in summary["series"]:
        assert s["largest_within_budget"] == s["rows"][-1]["size"]
        for r in s["rows"]:
            assert r["status"] in ("optimal", "optimal_inaccurate")
            assert r["max_violation"] <= 1e-5 * max(r["delta"], 1e-3)  # certified (tiny sizes)
    # both ARX forms agree on the same data
    by = {s["series"]: s["rows"] for s in summary["series"]}
    for rc, rt in zip(by["ARX conditioned"], by["ARX thesis"]):
        assert abs(rc["delta"] - rt["delta"]) <= 1e-4 * rc["delta"]


def test_cli_registers_bench(tmp_path):
    assert main(["bench-unfalsify", "--quick", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "bench_unfalsify" / "bench_unfalsify.json").exists()


def test_json_flag_prints_only_json(tmp_path, capsys):
    # the benchmark prints its markdown table; with --json stdout must still parse as the summary
    assert main(["bench-unfalsify", "--quick", "--json", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr()
    data = json.loads(out.out)
    assert data == json.loads((tmp_path / "bench_unfalsify" / "bench_unfalsify.json").read_text())
    assert "Chapter 7 unfalsification LMIs" in out.err  # the report text went to stderr instead


@pytest.mark.slow
def test_bench_unfalsify_structured_quick(tmp_path):
    # ``--backend structured --quick``: every row certified and verified, the ARX comparison agrees,
    # CSV and the scaling PNG are written
    assert main(["bench-unfalsify", "--quick", "--backend", "structured", "--out", str(tmp_path)]) == 0
    out = tmp_path / "bench_unfalsify"
    data = json.loads((out / "bench_unfalsify.json").read_text())
    assert data["backend"] == "structured" and "series" not in data  # the cvxpy series did not run
    st = data["structured"]
    for s in st["series"]:
        for r in s["rows"]:
            assert r["verify"] is True and r["lower"] <= r["upper"] and r["peak_rss_mb"] > 0
            if "bracket" in s["series"]:  # FFT-only bracket: certified both sides, gap reported, not small
                assert r["status"] == "bracket" and 0 < r["lower"] and r["relative_gap"] < 1
            else:
                assert r["status"] == "optimal" and r["relative_gap"] <= s["tol"]
    assert st["comparison"]["delta_difference"] <= 1e-5 * st["comparison"]["cvxpy"]["delta"]
    assert (out / "bench_unfalsify_structured.csv").read_text().count("\n") == 1 + sum(
        len(s["rows"]) for s in st["series"])
    assert (out / "bench_unfalsify_scaling.png").stat().st_size > 1000
    assert "Fitted exponents" in (out / "bench_unfalsify.md").read_text()


@pytest.mark.slow
def test_bench_unfalsify_structured_subspace_series_only(tmp_path):
    # ``--series subspace``: the subspace rows alone, no ARX rows and no Clarabel comparison
    assert main(["bench-unfalsify", "--quick", "--backend", "structured", "--series", "subspace",
                 "--out", str(tmp_path)]) == 0
    st = json.loads((tmp_path / "bench_unfalsify" / "bench_unfalsify.json").read_text())["structured"]
    assert {s["series"] for s in st["series"]} == {"subspace structured, L fixed", "subspace structured, L optimised",
                                                   "subspace structured 2×2, L optimised"}  # the MIMO row (issue 28)
    assert st["comparison"] is None
    for s in st["series"]:
        assert all(r["status"] == "optimal" and r["verify"] is True for r in s["rows"])


def test_cli_extra_arguments_are_per_command(tmp_path):
    with pytest.raises(SystemExit):  # --backend belongs to bench-unfalsify only
        main(["bench-norms", "--quick", "--backend", "structured", "--out", str(tmp_path)])
    with pytest.raises(SystemExit):
        main(["bench-unfalsify", "--backend", "nope", "--out", str(tmp_path)])


@pytest.mark.slow
def test_bench_unfalsify_primal_dual_table(tmp_path):
    # ``--series arx-pd``: arx_pd against arx_barrier on the same problems, both certified, brackets overlapping
    # (--repeats 2: two timed solves of each, against the --quick default of one)
    assert main(["bench-unfalsify", "--quick", "--backend", "structured", "--series", "arx-pd", "--sizes", "30",
                 "--repeats", "2", "--out", str(tmp_path)]) == 0
    st = json.loads((tmp_path / "bench_unfalsify" / "bench_unfalsify.json").read_text())["structured"]
    assert st["series"] == [] and st["comparison"] is None and st["warm"] is None
    (row,) = st["primal_dual"]["rows"]
    assert row["n"] == 30 and row["overlap"] is True and row["ratio"] > 0
    assert row["repeats"] == 2 and len(row["arx_barrier"]["walls"]) == len(row["arx_pd"]["walls"]) == 2
    for name in ("arx_barrier", "arx_pd"):
        assert row[name]["status"] == "optimal" and row[name]["gap"] <= 1e-4


@pytest.mark.slow
def test_bench_unfalsify_subspace_primal_dual_table(tmp_path):
    # ``--series subspace-pd``: column_pd against column_barrier on (7.5), L fixed and optimised, both certified
    assert main(["bench-unfalsify", "--quick", "--backend", "structured", "--series", "subspace-pd", "--sizes",
                 "3x20", "--out", str(tmp_path)]) == 0
    st = json.loads((tmp_path / "bench_unfalsify" / "bench_unfalsify.json").read_text())["structured"]
    assert st["series"] == [] and st["primal_dual"] is None
    rows = st["subspace_primal_dual"]["rows"]
    assert [(r["size"], r["L_fixed"]) for r in rows] == [([3, 20], True), ([3, 20], False)]
    for row in rows:
        assert row["overlap"] is True and row["ratio"] > 0
        for name in ("column_barrier", "column_pd"):
            assert row[name]["status"] == "optimal" and row[name]["gap"] <= 1e-4
    with pytest.raises(DataError, match="i×j pairs"):
        main(["bench-unfalsify", "--quick", "--backend", "structured", "--series", "subspace-pd", "--sizes", "30",
              "--out", str(tmp_path)])


@pytest.mark.slow
def test_bench_unfalsify_baseline_revision_is_timed_in_the_same_run(tmp_path):
    # --baseline-rev HEAD: the committed code exported by git archive and run in a subprocess on each row's data;
    # against itself the δ agree to the tolerance and every row has its time
    assert main(["bench-unfalsify", "--quick", "--backend", "structured", "--series", "subspace", "--baseline-rev",
                 "HEAD", "--out", str(tmp_path)]) == 0
    st = json.loads((tmp_path / "bench_unfalsify" / "bench_unfalsify.json").read_text())["structured"]
    assert st["baseline_rev"] == "HEAD"
    one_channel = [r for s in st["series"] for r in s["rows"] if s["kind"] == "subspace" and "2×2" not in s["series"]]
    assert one_channel and all(r["revision_s"] > 0 and r["revision_delta_rel"] <= 2e-6 for r in one_channel)
    assert "× rev" in (tmp_path / "bench_unfalsify" / "bench_unfalsify.md").read_text()
    with pytest.raises(DataError, match="--baseline-rev 'no-such-revision'"):
        main(["bench-unfalsify", "--quick", "--backend", "structured", "--series", "subspace", "--baseline-rev",
              "no-such-revision", "--out", str(tmp_path)])


def test_repeats_option_is_checked(tmp_path, capsys):
    # refused at parsing, a usage error (it had reached the run and ended in a DataError traceback)
    with pytest.raises(SystemExit) as caught:
        main(["bench-unfalsify", "--quick", "--backend", "structured", "--series", "arx", "--repeats", "0",
              "--out", str(tmp_path)])
    assert caught.value.code == 2 and "invalid count 0: give an integer ≥ 1" in capsys.readouterr().err


def test_arx_arithmetic_limit_counts_the_structured_step_from_its_threshold():
    """From n = ARX_STRUCTURED_FROM a Newton step's only n³ work is the Newton system's Cholesky (n³/3) and a
    trial factorisation is O(n²); below it the dense step's 3n³ and LAPACK's n³/3 per trial."""
    from experiments.bench.bench_unfalsify import ARX_STRUCTURED_FROM, _needed_flops
    from unfalsify.solvers import arx_barrier

    assert ARX_STRUCTURED_FROM == arx_barrier._STRUCTURED_FROM  # the bench's copy of the solver's threshold
    n = ARX_STRUCTURED_FROM
    step, trial = _needed_flops("arx", n, 1, 1, 0), _needed_flops("arx", n, 1, 0, 1)
    assert n**3 / 3 < step < n**3 / 3 + 200 * n * n and 0 < trial < 10 * n * n
    m = n - 1
    assert _needed_flops("arx", m, 1, 1, 0) >= 3 * m**3 and _needed_flops("arx", m, 1, 0, 1) >= m**3 / 3
