"""``python -m experiments design DATA``: a CSV record to a report, a JSON summary and controller files.

The record: the stable third-order plant under a 1500-sample PRBS with process and sensor noise 0.05
(seed 100), written as ``t,u,y``.  The saved controller is checked bit for bit against the design
rebuilt here with the same call, and its step on P̂ against the rebuilt one's.
"""
from __future__ import annotations

import json
import re
import warnings

import numpy as np
import pytest

import unfalsify as uf
from experiments.cli import main
from experiments.studies.design_cli import default_weights, design_record, parse_tracking_floor
from experiments.lab.plants import third_order
from experiments.lab.signals import prbs
from experiments.lab.simulate import closed_loop, collect_data
from synthesis import DataError, load_controller

from _reports import assert_reports_complete

N = 1500


def _record():
    P = third_order()
    d = collect_data(P, prbs(N, seed=0), process_noise=0.05, sensor_noise=0.05, seed=100)
    return np.arange(N) * float(P.dt), d.u.reshape(-1), d.y.reshape(-1), float(P.dt)


def _write_csv(path, t, u, y):
    # repr precision: the CLI must read back exactly the floats the test designs with
    lines = ["t,u,y"] + [f"{float(a)!r},{float(b)!r},{float(c)!r}" for a, b, c in zip(t, u, y)]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def design_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("design")
    t, u, y, dt = _record()
    csv = _write_csv(tmp / "record.csv", t, u, y)
    return tmp, csv, (u, y, dt)


def test_design_json_files_and_controller_bit_for_bit(design_run, capsys):
    tmp, csv, (u, y, dt) = design_run
    assert main(["design", "--quick", str(csv), "--horizon", "10", "--window", "0:49", "--json",
                 "--out", str(tmp)]) == 0
    summary = json.loads(capsys.readouterr().out)
    for key in ("certified", "delta", "reason", "seconds", "controller_npz", "controller_mat", "report"):
        assert key in summary, key
    out = tmp / "design"
    for name in ("design.md", "design.json", "controller.npz", "controller.mat", "data.png", "output_error.png",
                 "step.png", "bode.png"):
        assert (out / name).is_file(), name
    assert summary["dt"] == pytest.approx(dt, rel=1e-12)  # from the time column: no --dt needed
    assert summary["window"] == [0, 49]
    assert_reports_complete(out, "design")
    md = (out / "design.md").read_text()
    assert "certificate bracket" in md and "decided by" in md and "Design search" in md
    # where dt came from, and in which unit (a bare 'time' column in ms cannot be told from one in seconds)
    assert f"dt = {dt:g} (the time column's step, in seconds" in md and "'time [ms]'" in md

    # the same design, rebuilt here: the saved matrices are bit for bit its controller's
    W1, W2, _ = default_weights(dt)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", uf.NotCertifiedWarning)  # a refusal is a result, not a failure
        res = uf.robust_design_from_data(u, y, 10, W1, W2, "auto", dt=dt, window=(0, 49))
    assert summary["certified"] == res.certified and summary["delta"] == res.delta
    assert summary["reason"] == res.reason
    assert summary["assumed"] == list(res.assumed) and len(res.assumed) == 1  # a ±1 PRBS: linearity untestable
    assert summary["premise_note"] == res.premise_note  # the ball the data do not confirm, if any
    # the ball the verdict states is the certificate's (1.25 δ), as in the premise note, not the W3 rule's 1.1 δ
    assert summary["certificate_margin"] == res.certificate.margin == 0.25 and summary["margin"] == res.margin
    assert "(1 + 0.25)·δ of P̂" in md
    assert (f"Not confirmed by the data: {res.premise_note}." in md) == bool(res.premise_note)
    assert all(f"Assumed, not testable on these data: {a}." in md for a in res.assumed)
    # time invariance tested on the whole record (record mode), as the pipeline's own result says
    assert summary["invariance_p_value"] == res.invariance.p_value and res.invariance.samples == len(u)
    assert "Chow's test" in md
    # the returned loop against the data: the excitation check's numbers, the δ-margin evidence among them
    ex = res.excitation
    assert res.certified and res.uncertainty == "additive" and ex.ok and 0 < ex.margin < 1  # tested, and passed
    for key, value in (("excitation_worst", ex.worst if ex else None), ("margin_evidence", ex.margin if ex else None)):
        assert summary[key] == (value if value is not None and not np.isnan(value) else None), key
    assert "evidence that the plant lacks the δ margin" in md
    K_npz, K_mat = load_controller(summary["controller_npz"]), load_controller(summary["controller_mat"])
    K = res.controller
    for mat in "ABCD":
        ref = np.asarray(getattr(K, mat), float)
        assert np.array_equal(np.asarray(getattr(K_npz, mat)), ref), mat
        assert np.array_equal(np.asarray(getattr(K_mat, mat)), ref), mat
    r = np.ones(100)
    a, b = closed_loop(res.model, K, r), closed_loop(res.model, K_npz, r)
    assert np.array_equal(a.y, b.y) and np.array_equal(a.u, b.u)


def test_text_output_names_verdict_and_paths(design_run, capsys):
    tmp, csv, _ = design_run
    out = tmp / "text"
    assert main(["design", str(csv), "--horizon", "10", "--window", "0:49", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "certified" in text.lower() and "controller.npz" in text and "design.md" in text
    assert "assumed, not testable on these data: input 0 takes the values {-1, 1}" in text  # a ±1 PRBS record
    # --untested refuse: the same record refused, the fix named
    assert main(["design", str(csv), "--horizon", "10", "--window", "0:49", "--untested", "refuse", "--json",
                 "--out", str(tmp / "strict")]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert not summary["certified"] and "several amplitudes" in summary["reason"]
    # --feedthrough: the plant declared to respond within the sample, which the record cannot confirm
    assert main(["design", str(csv), "--horizon", "10", "--window", "0:49", "--feedthrough", "--json",
                 "--out", str(tmp / "feedthrough")]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert uf.FEEDTHROUGH_STATEMENT in summary["assumed"]


def _bad(tmp_path, capsys, argv):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code not in (0, None)
    return capsys.readouterr().err


def test_nan_in_record_is_an_input_error(tmp_path, capsys):
    t, u, y, _ = _record()
    y = y.copy()
    y[7] = np.nan
    csv = _write_csv(tmp_path / "nan.csv", t, u, y)
    err = _bad(tmp_path, capsys, ["design", str(csv), "--horizon", "10", "--out", str(tmp_path)])
    assert "design: error:" in err and "NaN" in err and "row 7" in err


def test_non_uniform_time_is_an_input_error(tmp_path, capsys):
    t, u, y, _ = _record()
    t = t.copy()
    t[300:] += 0.05
    csv = _write_csv(tmp_path / "jitter.csv", t, u, y)
    err = _bad(tmp_path, capsys, ["design", str(csv), "--horizon", "10", "--out", str(tmp_path)])
    assert "not uniformly sampled" in err


def test_missing_file_and_bad_window_are_input_errors(design_run, tmp_path, capsys):
    _, csv, _ = design_run
    err = _bad(tmp_path, capsys, ["design", str(tmp_path / "none.csv"), "--horizon", "10", "--out", str(tmp_path)])
    assert "no data file" in err
    err = _bad(tmp_path, capsys, ["design", str(csv), "--horizon", "10", "--window", "1400:49",
                                  "--out", str(tmp_path)])
    assert "held out" in err
    err = _bad(tmp_path, capsys, ["design", str(csv), "--horizon", "10", "--window", "zero", "--out", str(tmp_path)])
    assert "START:LEN" in err


def test_a_record_with_too_few_columns_names_the_option(tmp_path, capsys):
    t, u, _, _ = _record()
    path = tmp_path / "one_signal.csv"
    path.write_text("t,u\n" + "\n".join(f"{float(a)!r},{float(b)!r}" for a, b in zip(t, u)) + "\n")
    err = _bad(tmp_path, capsys, ["design", str(path), "--horizon", "10", "--out", str(tmp_path)])
    assert "leaves no column for --u and --y" in err  # it had raised IndexError
    err = _bad(tmp_path, capsys, ["design", str(path), "--horizon", "10", "--u", "u", "--out", str(tmp_path)])
    assert "leaves no column for --y" in err and "pass --y" in err


def test_mimo_record_names_the_options(tmp_path, capsys):
    t, u, y, _ = _record()
    path = tmp_path / "mimo.csv"
    rows = (f"{float(a)!r},{float(b)!r},{float(b)!r},{float(c)!r},{float(c)!r}" for a, b, c in zip(t, u, y))
    path.write_text("t,u1,u2,y1,y2\n" + "\n".join(rows) + "\n")
    err = _bad(tmp_path, capsys, ["design", str(path), "--horizon", "10", "--out", str(tmp_path)])
    assert "--u" in err and "--y" in err and "comma-separated" in err


def test_weights_from_files_equal_the_defaults(design_run, tmp_path, capsys):
    """``--weights W1FILE W2FILE`` (saved with save_controller) gives the default design bit for bit."""
    from synthesis import save_controller

    _, csv, (_, _, dt) = design_run
    W1, W2, _ = default_weights(dt)
    f1, f2 = save_controller(tmp_path / "w1.npz", W1), save_controller(tmp_path / "w2.mat", W2)
    assert main(["design", str(csv), "--horizon", "10", "--window", "0:49", "--weights", str(f1), str(f2),
                 "--json", "--out", str(tmp_path / "files")]) == 0
    files = json.loads(capsys.readouterr().out)
    assert main(["design", str(csv), "--horizon", "10", "--window", "0:49", "--json",
                 "--out", str(tmp_path / "defaults")]) == 0
    defaults = json.loads(capsys.readouterr().out)
    assert files["delta"] == defaults["delta"] and files["certified"] == defaults["certified"]
    a, b = load_controller(files["controller_npz"]), load_controller(defaults["controller_npz"])
    assert all(np.array_equal(getattr(a, m), getattr(b, m)) for m in "ABCD")
    assert "w1.npz" in files["weights"]
    err = _bad(tmp_path, capsys, ["design", str(csv), "--horizon", "10", "--w1", "100,1,1", "--w2", "1,2,3,4",
                                  "--out", str(tmp_path)])
    assert "DC,FREQ,MAG,HF" in err


def test_design_of_a_two_by_two_record(tmp_path, capsys):
    """Several channels: --u and --y take comma lists; W1, W2 diagonal; a controller with inputs [r; y] (4)."""
    import control

    from experiments.studies.mimo_pipeline import coupled_lags

    P = coupled_lags()
    n = 600
    rng = np.random.default_rng(3)
    u = np.sign(rng.standard_normal((n, 2)))
    y = control.forced_response(P, T=np.arange(n), U=u.T).outputs.T + 0.02 * rng.standard_normal((n, 2))
    rows = (",".join(repr(float(v)) for v in (k, *u[k], *y[k])) for k in range(n))
    path = tmp_path / "mimo.csv"
    path.write_text("t,u1,u2,y1,y2\n" + "\n".join(rows) + "\n")
    assert main(["design", str(path), "--u", "u1,u2", "--y", "y1,y2", "--horizon", "3", "--json",
                 "--out", str(tmp_path)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["u"] == ["u1", "u2"] and summary["y"] == ["y1", "y2"]
    assert np.isfinite(summary["delta"]) and (summary["certified"] or summary["reason"])
    K = load_controller(summary["controller_npz"])
    assert (K.ninputs, K.noutputs) == (4, 2)
    assert len(summary["step_final"]) == 2
    assert_reports_complete(tmp_path / "design", "design")


def _one_input_two_outputs(tmp_path):
    """A lag and a resonance driven by one input, both measured (a plant with fewer inputs than outputs)."""
    import control

    dt, n = 0.1, 900
    lag, mode = (control.ss(control.c2d(control.tf(b, a), dt)) for b, a in (([1.0], [1, 1]), ([0.5], [1, 0.8, 1])))
    P = control.ss(control.append(lag, mode) * control.ss([], [], [], [[1.0], [1.0]], dt))
    rng = np.random.default_rng(5)
    u = rng.uniform(-1.0, 1.0, n)
    y = control.forced_response(P, T=np.arange(n) * dt, U=u).outputs.T + 0.02 * rng.standard_normal((n, 2))
    rows = (",".join(repr(float(v)) for v in (u[k], *y[k])) for k in range(n))
    path = tmp_path / "simo.csv"
    path.write_text("u,y1,y2\n" + "\n".join(rows) + "\n")
    return path, u, y, dt


def test_a_floor_per_output_reaches_the_certificate(tmp_path, capsys, monkeypatch):
    """One input, two outputs: no loop tracks independent steps on both, and the refusal names --tracking-floor;
    ``--tracking-floor 0.2,inf`` is the certificate's floor per output (the library's verdict and δ with it)."""
    from experiments.studies import design_cli

    path, u, y, dt = _one_input_two_outputs(tmp_path)
    args = ["design", str(path), "--u", "u", "--y", "y1,y2", "--dt", str(dt), "--horizon", "8", "--json"]
    assert main([*args, "--out", str(tmp_path / "default")]) == 0
    default = json.loads(capsys.readouterr().out)
    assert not default["certified"] and "--tracking-floor 0.1,inf" in default["reason"]
    assert default["tracking_floor"] == 0.1
    calls = []  # the library call the command makes, and its result (a second solve of the same design had
    # doubled this test's time for the same comparison)

    def spy(*a, **kw):
        calls.append((a, kw, design_record(*a, **kw)))
        return calls[-1][2]

    monkeypatch.setattr(design_cli, "design_record", spy)
    assert main([*args, "--tracking-floor", "0.2,inf", "--out", str(tmp_path / "floors")]) == 0
    floors = json.loads(capsys.readouterr().out)
    assert floors["tracking_floor"] == [0.2, None] and "fewer inputs" not in (floors["reason"] or "")
    (a, kw, (res, _)), = calls
    np.testing.assert_allclose(a[0], u[:, None], rtol=1e-15)  # the CSV holds repr(float): the same numbers
    np.testing.assert_allclose(a[1], y, rtol=1e-15)
    assert a[2:4] == (dt, 8) and kw["tracking_floor"] == (0.2, np.inf)
    W1, W2, _ = default_weights(dt, 1, 2, untracked=(1,))  # the untracked output weighed by UNTRACKED_WEIGHT
    for got, want in ((a[4], W1), (a[5], W2)):
        assert got.dt == want.dt and all(np.array_equal(getattr(got, x), getattr(want, x)) for x in "ABCD")
    assert res.certificate.tracking_floor == (0.2, np.inf)
    assert (floors["certified"], floors["delta"]) == (res.certified, res.delta)
    md = (tmp_path / "floors" / "design" / "design.md").read_text()
    assert f"dt = {dt:g} (given)" in md
    # the floors reach the certificate (above); the verdict is the library's, a refusal since the whole record's low
    # band refutes the premise (premise ratio 4.1 on the true plant), and a refused report states no floor
    assert floors["certified"] == ("at most (0.2, inf) per output" in md)
    assert "W1 = 0.01 (static) on output 1 (not tracked)" in md
    for bad, words in (("0.1,x", "must be a number"), ("-1", "must be a number"), ("0.1,0.1,0.1", "3 floors for 2")):
        err = _bad(tmp_path, capsys, [*args, "--tracking-floor", bad, "--out", str(tmp_path)])
        assert words in err, err


def test_an_operating_point_is_named_and_removed_with_detrend(tmp_path, capsys):
    """A record around an operating point (the input switching between 0 and 2, the output at 3 + deviations): the
    models have no constant term, so the report names the means and ``--detrend mean``; with it the design runs on
    the deviations, the same as a design of the centred record made here, and the report says how to apply the
    controller."""
    t, u, y, dt = _record()
    csv = _write_csv(tmp_path / "operating.csv", t, u + 1.0, y + 3.0)
    assert main(["design", str(csv), "--horizon", "10", "--window", "0:49", "--json", "--out", str(tmp_path)]) == 0
    as_read = json.loads(capsys.readouterr().out)
    assert not as_read["operating_point"]["removed"]
    assert "the mean of y" in as_read["operating_point_note"] and "--detrend mean" in as_read["operating_point_note"]
    assert main(["design", str(csv), "--horizon", "10", "--window", "0:49", "--detrend", "mean", "--json",
                 "--out", str(tmp_path)]) == 0
    summary = json.loads(capsys.readouterr().out)
    point = summary["operating_point"]
    assert point["removed"] and point["u"] == [pytest.approx(float(np.mean(u + 1.0)), abs=1e-12)]
    assert point["y"] == [pytest.approx(float(np.mean(y + 3.0)), abs=1e-12)]
    assert "feed the controller r − ȳ and y − ȳ and add ū" in summary["operating_point_note"]
    W1, W2, _ = default_weights(dt)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = uf.robust_design_from_data(u + 1.0 - np.mean(u + 1.0), y + 3.0 - np.mean(y + 3.0), 10, W1, W2, "auto",
                                         dt=dt, window=(0, 49))
    assert summary["delta"] == pytest.approx(float(ref.delta), rel=1e-9)
    assert summary["certified"] == bool(ref.certified)


def test_a_large_mean_is_named_in_the_report_without_detrend():
    from experiments.lab.records import Record
    from experiments.studies.design_cli import operating_point

    rng = np.random.default_rng(0)
    u = np.sign(rng.standard_normal((400, 1)))
    rec = Record(u=u, y=0.5 * u + 2.0, dt=1.0, source="x")
    same, point, text = operating_point(rec)
    assert same is rec and not point["removed"] and "The mean of y (1.97" in text and "--detrend mean" in text
    assert "mean of u" not in text  # a ±1 PRBS: its mean is below a tenth of its standard deviation
    with pytest.raises(DataError, match="--detrend"):
        operating_point(rec, "linear")


def _signals_csv(path, header, columns):
    path.write_text(",".join(header) + "\n" + "\n".join(",".join(f"{float(v)!r}" for v in row)
                                                        for row in zip(*columns)) + "\n")
    return path


def test_one_of_u_and_y_on_a_wide_record_is_refused(tmp_path):
    from experiments.lab.records import RecordError
    from experiments.studies.design_cli import _select

    t, u, y, _ = _record()
    path = _signals_csv(tmp_path / "wide.csv", ["t", "u1", "u2", "y1", "y2"], [t, u, u, y, y])
    with pytest.raises(RecordError, match="--y is missing"):  # it had taken u2 for the output
        _select(path, {"u": "u1"})
    with pytest.raises(RecordError, match="--u is missing"):
        _select(path, {"y": "y1,y2"})
    assert _select(path, {"u": "u1,u2", "y": "y1"})[:2] == (["u1", "u2"], "y1")
    three = _signals_csv(tmp_path / "three.csv", ["t", "u", "y"], [t, u, y])
    assert _select(three, {"u": "u"})[:3] == ("u", "y", "t")  # one column left: unambiguous


def _with_status(path, header, columns, at):
    """A record with a logger's status column ("ok" in every row) inserted at position ``at``."""
    rows = [[f"{float(v)!r}" for v in row] for row in zip(*columns)]
    lines = [header[:at] + ["status"] + header[at:]] + [r[:at] + ["ok"] + r[at:] for r in rows]
    path.write_text("\n".join(",".join(line) for line in lines) + "\n")
    return path


@pytest.mark.parametrize("at", [1, 3])
def test_a_text_column_is_not_counted_as_a_signal(tmp_path, at):
    # "t,u,y,status" without --u/--y had been refused as "3 signal columns (u, y, status)": the status, text in every
    # row, counted as a signal; the selection is now the one of the file without it
    from experiments.lab.records import RecordError, load_record
    from experiments.studies.design_cli import _select

    t, u, y, _ = _record()
    path = _with_status(tmp_path / "status.csv", ["t", "u", "y"], [t, u, y], at)
    assert _select(path, {})[:3] == ("u", "y", "t")
    assert _select(path, {"u": "u"})[:3] == ("u", "y", "t")
    wide = _with_status(tmp_path / "wide.csv", ["t", "u1", "u2", "y"], [t, u, u, y], at)
    with pytest.raises(RecordError, match=r"has 3 signal columns \(u1, u2, y; status holds text, not a "
                                          r"signal\): say which are inputs with --u"):
        _select(wide, {})
    lone = _with_status(tmp_path / "lone.csv", ["t", "u"], [t, u], at)
    with pytest.raises(RecordError, match=r"status holds text, not a signal\) leaves no column for --u and --y"):
        _select(lone, {})
    for role, sel in (("y", dict(u="u", y="status")), ("u", dict(u="status", y="y"))):  # selected: refused, named
        with pytest.raises(RecordError, match=rf"'status', data row 0: 'ok' is not a number: the column holds text in "
                                              rf"every row, not a signal; select a column of numbers as {role}="):
            load_record(path, t="t", **sel)


@pytest.mark.parametrize("dt", [None, "0.01"])
def test_a_text_column_chosen_as_the_time_column_is_refused_as_text_not_as_stamps(tmp_path, capsys, dt):
    # "--t status" (text in every row) had been told "the time column must hold numbers ... convert the stamps to
    # numbers": stamps it does not hold; a column of date-time stamps keeps that message
    t, u, y, _ = _record()
    path = _with_status(tmp_path / "status.csv", ["t", "u", "y"], [t, u, y], 3)
    argv = ["design", str(path), "--horizon", "10", "--u", "u", "--y", "y", "--out", str(tmp_path)]
    argv += ["--dt", dt] if dt else []
    err = _bad(tmp_path, capsys, argv + ["--t", "status"])
    fix = ("; dt= is given: omit t=" if dt else r", or pass dt=<sample time> instead of t= \(--dt instead of --t\)")
    assert re.search(r"'status', data row 0: 'ok' is not a number: the column holds text in every row, not times; "
                     r"select a column of numbers as t= \(--t of python -m experiments design\)" + fix, err), err
    assert "stamps" not in err
    stamps = path.with_name("stamps.csv")
    stamps.write_text(path.read_text().replace(",ok", ",2026-11-29 10:00:00"))
    err = _bad(tmp_path, capsys, [a if a != str(path) else str(stamps) for a in argv] + ["--t", "status"])
    assert "the time column must hold numbers" in err and "convert the stamps to numbers" in err


def test_the_design_command_parses_a_csv_record_once(tmp_path, monkeypatch):
    # record_columns, then text_columns (no --u/--y: the status column is left out), then load_record had each parsed
    # the file: three parses of the same text
    import os

    import experiments.lab.records as records
    from experiments.lab.records import load_record, record_columns, text_columns
    from experiments.studies import design_cli

    t, u, y, _ = _record()
    path = _with_status(tmp_path / "status.csv", ["t", "u", "y"], [t, u, y], 3)
    parsed = []
    parse = records._parse_csv
    monkeypatch.setattr(records, "_parse_csv", lambda *a, **k: parsed.append(a[0]) or parse(*a, **k))

    class Read(Exception):
        """Raised with the record the command read, before its design."""

    def stop(rec, detrend):
        raise Read(rec)

    monkeypatch.setattr(design_cli, "operating_point", stop)
    with pytest.raises(Read) as read:
        main(["design", str(path), "--horizon", "10", "--out", str(tmp_path)])
    assert len(parsed) == 1
    rec = read.value.args[0]  # the record the file holds, as a parse of its own reads it
    parsed.clear()
    monkeypatch.setattr(records, "_last_parse", None)
    alone = load_record(path, u="u", y="y", t="t")
    assert len(parsed) == 1 and np.array_equal(rec.u, alone.u) and np.array_equal(rec.y, alone.y)
    assert rec.dt == alone.dt and (rec.u_columns, rec.y_columns) == (("u",), ("y",))
    # the public functions answer as before: the header is the caller's copy
    names = record_columns(path)[0]
    names.append("mine")
    assert record_columns(path) == (["t", "u", "y", "status"], 4) and text_columns(path) == [3] and len(parsed) == 1
    # a file rewritten to the same size with the same modification time is read anew (its bytes are compared)
    stat = path.stat()
    path.write_text(path.read_text().replace(",ok", ",no"))
    os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    assert path.stat().st_size == stat.st_size and path.stat().st_mtime_ns == stat.st_mtime_ns
    assert record_columns(path) == (["t", "u", "y", "status"], 4) and len(parsed) == 2
    path.write_text(path.read_text().replace(",no", ",1.0"))
    assert text_columns(path) == [] and len(parsed) == 3


def test_a_time_column_is_never_a_signal_also_with_dt(tmp_path):
    from experiments.lab.records import RecordError, load_record
    from experiments.studies.design_cli import _select

    t, u, y, dt = _record()
    path = _signals_csv(tmp_path / "timed.csv", ["time", "u1", "y1"], [t, u, y])
    u_sel, y_sel, t_sel, _ = _select(path, {"dt": dt})  # --dt given: the time column had become the input
    assert (u_sel, y_sel, t_sel) == ("u1", "y1", "time")
    rec = load_record(path, u=u_sel, y=y_sel, t=t_sel, dt=dt)
    assert np.array_equal(rec.u[:, 0], u) and rec.dt == pytest.approx(dt)
    with pytest.raises(RecordError, match="disagrees with the time column"):  # a --dt the time column refutes
        load_record(path, u=u_sel, y=y_sel, t=t_sel, dt=2 * dt)


def test_a_bad_time_column_and_a_transposed_csv_name_the_fix(tmp_path):
    from experiments.lab.records import RecordError, load_record
    from experiments.studies.design_cli import _select

    t, u, y, _ = _record()
    path = _signals_csv(tmp_path / "r.csv", ["time", "u1", "u2", "y1"], [t, u, u, y])
    with pytest.raises(RecordError, match=r"--t 'Time' is not a column.*time, u1, u2, y1"):  # had raised ValueError
        _select(path, {"t": "Time"})
    with pytest.raises(RecordError, match="--t 7 is not a column"):
        _select(path, {"t": "7"})
    flipped = tmp_path / "flipped.csv"
    flipped.write_text("\n".join(",".join(f"{float(v)!r}" for v in row) for row in (u[:300], y[:300])) + "\n")
    with pytest.raises(RecordError, match="save the transposed table"):
        _select(flipped, {"dt": 1.0})
    with pytest.raises(RecordError, match="save the transposed table"):
        load_record(flipped, u=0, y=1, dt=1.0)


def test_a_coprime_certificate_is_reported_as_such():
    from types import SimpleNamespace

    from experiments.studies.design_cli import _family, summary_lines

    # margin is the W3 rule's (0.1); the ball the certificate proves has the certificate's margin (0.25)
    cert = SimpleNamespace(margin=0.25)
    res = SimpleNamespace(uncertainty="coprime", epsilon=0.0277, delta=0.128, margin=0.1, certificate=cert)
    assert _family(res).startswith("ε = 0.0277 in coprime-factor form") and "sized by δ = 0.128" in _family(res)
    assert "(1 + 0.25)·ε" in _family(res)
    additive = SimpleNamespace(uncertainty="additive", epsilon=float("nan"), delta=0.128, margin=0.1, certificate=cert)
    assert _family(additive) == "δ = 0.128 (every plant within (1 + 0.25)·δ of P̂ in ‖Δ‖∞)"
    summary = dict(certified=True, uncertainty="coprime", epsilon=0.0277, delta=0.128, decided_by="subspace (7.5)",
                   controller_npz="K.npz", controller_mat="K.mat")
    assert "certified in coprime-factor form for ε = 0.0277, not for δ" in summary_lines(summary)[0]


def test_summaries_are_strict_json(tmp_path):
    from experiments.lab.report import Report, finish_report

    summary = finish_report(Report("t"), {"a": float("nan"), "b": np.array([np.inf, 1.0]), "c": -np.inf}, tmp_path,
                            "strict")
    text = (tmp_path / "strict.json").read_text()

    def refuse(name):
        raise ValueError(name)

    data = json.loads(text, parse_constant=refuse)  # NaN / Infinity would be refused, as jq and JavaScript do
    assert (data["a"], data["b"], data["c"]) == ("nan", ["inf", 1.0], "-inf")
    assert np.isnan(summary["a"])  # the returned summary keeps its numbers


def test_an_untracked_output_gets_a_small_static_weight():
    """``--tracking-floor 0.1,inf``: W1 (default or ``--w1``) weighs output 1 by UNTRACKED_WEIGHT, not like output 0
    (the same W1 on both had left every one-input two-output record of the hunt uncertified)."""
    from experiments.studies.design_cli import UNTRACKED_WEIGHT, _weights, untracked_outputs

    floor = parse_tracking_floor("0.1,inf")
    assert untracked_outputs(floor) == (1,)
    for extra in ({}, {"w1": "100,1,1,0.2", "w2": "0.05,3,0.3,1"}):
        W1, W2, text = _weights(extra, 0.1, 1, 2, untracked_outputs(floor))
        tracked = _weights(extra, 0.1, 1, 1)[0]
        assert W1.noutputs == 2 and W2.noutputs == 1
        assert float(np.asarray(W1.D)[1, 1]) == UNTRACKED_WEIGHT and np.asarray(W1.D)[0, 1] == 0.0
        assert float(np.asarray(W1.D)[0, 0]) == float(np.asarray(tracked.D)[0, 0])  # output 0 as before
        assert W1.nstates == tracked.nstates  # the untracked output's weight has no dynamics
        assert "(not tracked)" in text
    assert "not tracked" not in _weights({}, 0.1, 1, 2, untracked_outputs(parse_tracking_floor("0.1")))[2]


def test_a_jittered_time_column_is_read_with_dt(tmp_path):
    """The design command takes a column named time as the time column whatever --dt says, so the refusal's fix for
    jittered stamps ("pass the sample time as dt= too") must work with the column still read."""
    from experiments.lab.records import RecordError, load_record
    from experiments.studies.design_cli import _select

    t, u, y, dt = _record()
    jittered = t + np.random.default_rng(0).uniform(-0.2, 0.2, t.size) * dt
    path = _signals_csv(tmp_path / "jitter.csv", ["time", "u", "y"], [jittered, u, y])
    with pytest.raises(RecordError, match="not uniformly sampled"):
        load_record(path, **dict(zip(("u", "y", "t"), _select(path, {})[:3])))
    u_sel, y_sel, t_sel, _ = _select(path, {"dt": dt})
    assert t_sel == "time"
    rec = load_record(path, u=u_sel, y=y_sel, t=t_sel, dt=dt)
    assert rec.dt == dt and np.array_equal(rec.y[:, 0], y)


@pytest.mark.slow
def test_a_record_in_small_units_names_the_weights_that_certify(tmp_path, capsys):
    """u in mV-like units (×1e3) and y in km-like units (×1e-3): the gain 1e-6 left the default W2 (0.05 at DC)
    forbidding the effort the loop needs, and the refusal named W1 (integral action), which does not help.  The
    report names the units and the --w1/--w2 of the default design in them; with those the record certifies."""
    t, u, y, dt = _record()
    path = _signals_csv(tmp_path / "units.csv", ["t", "u", "y"], [t, 1e3 * u, 1e-3 * y])
    args = ["design", str(path), "--horizon", "8", "--json"]
    assert main([*args, "--out", str(tmp_path / "default")]) == 0
    default = json.loads(capsys.readouterr().out)
    assert not default["certified"] and "rms(y)/rms(u) is 1." in default["scale_note"]
    options = default["scale_note"].split("pass W2 times ")[1].split(": ", 1)[1].rstrip(".").split()
    assert options[0] == "--w1" and options[2] == "--w2"
    assert main([*args, *options, "--out", str(tmp_path / "scaled")]) == 0
    scaled = json.loads(capsys.readouterr().out)
    assert not scaled["scale_note"]  # weights given: nothing more to propose
    W1, W2, _ = default_weights(dt)  # the proposed weights are the defaults in the record's units: the same verdict
    natural, _ = design_record(u, y, dt, 8, W1, W2)
    assert scaled["certified"] == natural.certified
    assert scaled["delta"] == default["delta"]  # δ is the record's, whatever the weights


def test_a_time_array_in_an_npz_or_mat_file_is_read_like_a_time_column(tmp_path):
    """``numpy.savez(f, u=u, y=y, t=t)``: a CSV's time column was found by its name, the same record's ``t`` array
    was not, and the command refused it for want of a sample time."""
    import scipy.io

    from experiments.lab.records import load_record
    from experiments.studies.design_cli import _select

    t, u, y, dt = _record()
    np.savez(tmp_path / "r.npz", u=u, y=y, t=t)
    scipy.io.savemat(tmp_path / "r.mat", {"u": u[None, :], "y": y[None, :], "time": t[None, :]})
    for path, name in ((tmp_path / "r.npz", "t"), (tmp_path / "r.mat", "time")):
        u_sel, y_sel, t_sel, variable = _select(path, {})
        assert (u_sel, y_sel, t_sel) == ("u", "y", name)
        rec = load_record(path, u=u_sel, y=y_sel, t=t_sel, variable=variable)
        assert rec.dt == pytest.approx(dt) and np.array_equal(rec.u[:, 0], u)
    np.savez(tmp_path / "two.npz", u=u, y=y, t=t, time=t)  # two candidates: none is guessed
    assert _select(tmp_path / "two.npz", {})[2] is None


@pytest.mark.parametrize("name", ["time [s]", "Time (s)", "t (sec)", "TIME"])
def test_a_time_column_with_its_unit_in_the_name_is_found(tmp_path, name):
    # loggers write the unit into the header; "time [s]" had not been found, the record had then been refused for
    # "no time column" (with --u/--y given) or its time column offered as a third signal (without)
    from experiments.lab.records import load_record
    from experiments.studies.design_cli import _select

    t, u, y, dt = _record()
    path = _signals_csv(tmp_path / "units.csv", [name, "force [N]", "position [m]"], [t, u, y])
    assert _select(path, {})[:3] == ("force [N]", "position [m]", name)
    assert _select(path, {"u": "force [N]", "y": "position [m]"})[2] == name
    assert load_record(path, u="force [N]", y="position [m]", t=name).dt == pytest.approx(dt)


@pytest.mark.parametrize("name, per_second", [("time [ms]", 1e3), ("Time (us)", 1e6), ("t [min]", 1 / 60)])
def test_a_time_column_in_other_units_gives_the_sample_time_in_seconds(tmp_path, name, per_second):
    """A logger's clock in ms: the column's step (100) had been taken as the sample time in seconds, and the design
    saved a controller and weights at dt = 100 with no note.  The unit in the name converts it; --dt in seconds is
    checked against the converted stamps; a unit that is not one of time is refused, naming the fix."""
    from experiments.lab.records import RecordError, load_record

    t, u, y, dt = _record()
    path = _signals_csv(tmp_path / "clock.csv", [name, "u", "y"], [t * per_second, u, y])
    rec = load_record(path, u="u", y="y", t=name)
    assert rec.dt == pytest.approx(dt, rel=1e-9) and rec.t == pytest.approx(t, rel=1e-9, abs=1e-12)
    assert load_record(path, u="u", y="y", t=name, dt=dt).dt == pytest.approx(dt)
    from experiments.studies.design_cli import _select

    assert _select(path, {})[:3] == ("u", "y", name)  # the command finds it and reads it with load_record
    bad = _signals_csv(tmp_path / "odd.csv", ["time [m]", "u", "y"], [t, u, y])
    with pytest.raises(RecordError, match=r"'time \[m\]' is in 'm', not a unit of time .* pass dt="):
        load_record(bad, u="u", y="y", t="time [m]")


def _date_time_csv(path, time_name, u, y):
    """A logger's CSV whose time column holds date-time stamps at 0.1 s (text, not numbers)."""
    path.write_text(f"{time_name},u,y\n" + "".join(f"2026-11-29 10:{k // 600:02d}:{k % 600 / 10:04.1f},{a!r},{b!r}\n"
                                                    for k, (a, b) in enumerate(zip(u.tolist(), y.tolist()))))
    return path


def test_a_time_column_named_with_a_unit_not_of_time_is_not_taken_for_the_sample_time(tmp_path):
    # "Time (UTC)" holding date-time stamps: since 'time [...]' names are found, it had been taken as the time column
    # and the record refused even with --dt (and a message naming "--dt instead of --t", neither of which helped)
    from experiments.lab.records import load_record
    from experiments.studies.design_cli import _select

    t, u, y, dt = _record()
    path = _date_time_csv(tmp_path / "utc.csv", "Time (UTC)", u, y)
    u_sel, y_sel, t_sel, _ = _select(path, {"u": "u", "y": "y", "dt": dt})
    assert t_sel is None
    rec = load_record(path, u=u_sel, y=y_sel, t=t_sel, dt=dt)
    assert rec.dt == dt and np.array_equal(rec.y[:, 0], y)
    assert _select(_signals_csv(tmp_path / "ms.csv", ["Time (ms)", "u", "y"], [1e3 * t, u, y]), {})[2] == "Time (ms)"


def test_a_time_column_of_date_time_stamps_found_by_its_name_names_a_fix_that_works_with_dt(tmp_path):
    # the command takes a column named 'time' for the time column; holding date-time stamps, it was refused with
    # "pass --dt instead of --t" to a user who had passed --dt and no --t
    from experiments.lab.records import RecordError, load_record
    from experiments.studies.design_cli import _select

    _, u, y, dt = _record()
    path = _date_time_csv(tmp_path / "stamps.csv", "time", u, y)
    u_sel, y_sel, t_sel, _ = _select(path, {"u": "u", "y": "y", "dt": dt})
    with pytest.raises(RecordError, match=r"the time column must hold numbers .*; dt= is given: omit t=, or rename "
                                          r"the column .* --t is not given") as info:
        load_record(path, u=u_sel, y=y_sel, t=t_sel, dt=dt)
    assert "instead of --t" not in str(info.value)
    path.write_text(path.read_text().replace("time,", "stamp,", 1))  # the fix it names
    assert load_record(path, **dict(zip(("u", "y", "t"), _select(path, {"u": "u", "y": "y"})[:3])), dt=dt).dt == dt
