"""experiments.load_record: CSV / NPZ / MAT into a Record, with errors that name the fix."""
import pickle
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from experiments import Record, RecordError, load_record
from synthesis import DataError

CD_PLAYER = Path(__file__).resolve().parents[1] / "experiments" / "data" / "CD_player_arm_dat.mat"  # shipped


@pytest.fixture
def signals():
    rng = np.random.default_rng(1)
    n = 40
    t = 0.05 * np.arange(n)
    u = rng.standard_normal((n, 2))
    y = rng.standard_normal((n, 1))
    return t, u, y


def _write_csv(path, header, columns, fmt="%.17g", delimiter=","):
    table = np.column_stack(columns)
    np.savetxt(path, table, delimiter=delimiter, fmt=fmt, header=delimiter.join(header) if header else "",
               comments="")
    return path


def test_csv_by_name_and_by_index(tmp_path, signals):
    t, u, y = signals
    path = _write_csv(tmp_path / "r.csv", ["time", "u1", "u2", "y"], [t, u, y])
    rec = load_record(path, u=["u1", "u2"], y="y", t="time")
    assert isinstance(rec, Record)
    assert rec.u.shape == (40, 2) and rec.y.shape == (40, 1) and rec.n == 40 and rec.m == 2 and rec.l == 1
    assert np.array_equal(rec.u, u) and np.array_equal(rec.y, y)  # %.17g: exact round trip
    assert rec.dt == 0.05 and rec.u_columns == ("u1", "u2") and rec.y_columns == ("y",)
    assert np.array_equal(rec.t, t)
    by_index = load_record(path, u=[1, 2], y=-1, t=0)
    assert np.array_equal(by_index.u, rec.u) and by_index.dt == rec.dt and by_index.u_columns == ("u1", "u2")
    # no header: integer indices, semicolon separated, dt given
    path2 = _write_csv(tmp_path / "r2.csv", None, [u, y], delimiter=";")
    rec2 = load_record(path2, u=[0, 1], y=2, dt=0.05)
    assert np.array_equal(rec2.u, u) and rec2.u_columns == ("column 0", "column 1") and rec2.t is None
    assert not rec.u.flags.writeable
    assert pickle.loads(pickle.dumps(rec)) == rec


def test_rounded_time_column_gives_the_decimal_step(tmp_path):
    t = np.round(0.1 * np.arange(100), 6)
    path = _write_csv(tmp_path / "r.csv", ["t", "u", "y"], [t, np.ones(100), np.ones(100)], fmt="%.6f")
    assert load_record(path, u="u", y="y", t="t").dt == 0.1


def test_npz_by_key(tmp_path, signals):
    t, u, y = signals
    np.savez(tmp_path / "r.npz", time=t, u=u, y=y[:, 0], u_extra=u[:, 0])
    rec = load_record(tmp_path / "r.npz", u="u", y="y", t="time")
    assert np.array_equal(rec.u, u) and np.array_equal(rec.y, y) and rec.dt == 0.05
    assert rec.u_columns == ("u[:, 0]", "u[:, 1]")
    rec = load_record(tmp_path / "r.npz", u=["u_extra", "u"], y="y", dt=0.05)
    assert rec.u.shape == (40, 3)


def test_mat_by_variable_and_columns_and_by_name(tmp_path, signals):
    t, u, y = signals
    scipy.io.savemat(tmp_path / "r.mat", {"data": np.column_stack([t, u, y]), "u": u, "y": y[:, 0]})
    rec = load_record(tmp_path / "r.mat", variable="data", u=[1, 2], y=[3], t=0)
    assert np.array_equal(rec.u, u) and np.array_equal(rec.y, y) and rec.dt == 0.05
    rec = load_record(tmp_path / "r.mat", u="u", y="y", dt=0.05)  # MATLAB's (1, n) vector is one channel
    assert rec.y.shape == (40, 1) and np.array_equal(rec.y, y)


@pytest.mark.skipif(not CD_PLAYER.exists(), reason="the shipped data file is missing")
def test_cd_player_arm_file():
    rec = load_record(CD_PLAYER, variable="CD_player_arm_dat", u=[0, 1], y=[2, 3], dt=1)
    raw = scipy.io.loadmat(CD_PLAYER)["CD_player_arm_dat"]
    assert rec.u.shape == (2048, 2) and rec.y.shape == (2048, 2) and rec.dt == 1.0
    assert np.array_equal(rec.u, raw[:, :2]) and np.array_equal(rec.y, raw[:, 2:])
    with pytest.raises(RecordError, match="no sample time.*dt=1"):
        load_record(CD_PLAYER, variable="CD_player_arm_dat", u=[0, 1], y=[2, 3])


def test_errors_name_the_problem_and_the_fix(tmp_path, signals):
    t, u, y = signals
    path = _write_csv(tmp_path / "r.csv", ["time", "u1", "u2", "y"], [t, u, y])
    with pytest.raises(RecordError, match=r"no column 'y2' \(columns: time, u1, u2, y\)"):
        load_record(path, u="u1", y="y2", t="time")
    with pytest.raises(RecordError, match="index 7 is out of range"):
        load_record(path, u=7, y="y", t="time")
    with pytest.raises(RecordError, match="no sample time.*pass dt="):
        load_record(path, u="u1", y="y")
    with pytest.raises(RecordError, match="disagrees"):
        load_record(path, u="u1", y="y", t="time", dt=0.1)
    with pytest.raises(RecordError, match="dt must be"):
        load_record(path, u="u1", y="y", dt=-1.0)
    # non-uniform time
    t_bad = t.copy()
    t_bad[10:] += 0.01
    bad = _write_csv(tmp_path / "jitter.csv", ["time", "u1", "u2", "y"], [t_bad, u, y])
    with pytest.raises(RecordError, match=r"not uniformly sampled: the step from row 9 to 10.*numpy.interp"):
        load_record(bad, u="u1", y="y", t="time")
    assert load_record(bad, u="u1", y="y", t="time", rtol=0.5).n == 40  # a loose tolerance accepts it
    # NaN: which column, first row
    y_nan = y.copy()
    y_nan[[7, 12]] = np.nan
    nan = _write_csv(tmp_path / "nan.csv", ["time", "u1", "u2", "y"], [t, u, y_nan])
    with pytest.raises(RecordError, match=r"output y has NaN.*\(2\), the first at data row 7"):
        load_record(nan, u=["u1", "u2"], y="y", t="time")
    (tmp_path / "empty_cell.csv").write_text("t,u,y\n0,1,2\n1,,3\n2,1,2\n")
    with pytest.raises(RecordError, match="input u has NaN.*data row 1"):
        load_record(tmp_path / "empty_cell.csv", u="u", y="y", t="t")
    (tmp_path / "text.csv").write_text("t,u,y\n0,1,2\n1,abc,3\n2,1,2\n")  # two rows: "too few samples" first
    with pytest.raises(RecordError, match=r"'u', data row 1: 'abc' is not a number"):
        load_record(tmp_path / "text.csv", u="u", y="y", t="t")
    # NPZ: mismatched lengths, missing key, time along axis 1
    np.savez(tmp_path / "r.npz", u=u, y=y[:-1], wide=u.T)
    with pytest.raises(RecordError, match=r"different lengths \(u: 40, y: 39\)"):
        load_record(tmp_path / "r.npz", u="u", y="y", dt=1)
    with pytest.raises(RecordError, match=r"no array 'out' \(keys: u, wide, y\)"):
        load_record(tmp_path / "r.npz", u="u", y="out", dt=1)
    with pytest.raises(RecordError, match=r"time runs along axis 0: store wide.T"):
        load_record(tmp_path / "r.npz", u="wide", y="u", dt=1)
    # MAT: missing variable, names where indices are needed
    scipy.io.savemat(tmp_path / "r.mat", {"data": np.column_stack([u, y])})
    with pytest.raises(RecordError, match=r"no variable 'dat' \(it has: data\)"):
        load_record(tmp_path / "r.mat", variable="dat", u=0, y=2, dt=1)
    with pytest.raises(RecordError, match="integer index"):
        load_record(tmp_path / "r.mat", variable="data", u="u", y=2, dt=1)
    with pytest.raises(RecordError, match=r"\.csv, \.txt, \.npz, \.mat"):
        load_record(tmp_path / "r.xlsx", u=0, y=1, dt=1)
    with pytest.raises(FileNotFoundError):
        load_record(tmp_path / "absent.csv", u=0, y=1, dt=1)
    assert issubclass(RecordError, DataError) and issubclass(RecordError, ValueError)


def test_decimal_commas_are_read_when_the_separator_is_not_a_comma(tmp_path, signals):
    t, u, y = signals
    plain = load_record(_write_csv(tmp_path / "dot.csv", ["t", "u1", "u2", "y"], [t, u, y]), u=["u1", "u2"],
                        y="y", t="t")
    text = (tmp_path / "dot.csv").read_text().replace(",", ";").replace(".", ",")  # a comma-decimal locale's export
    (tmp_path / "comma.csv").write_text(text)
    rec = load_record(tmp_path / "comma.csv", u=["u1", "u2"], y="y", t="t")
    np.testing.assert_array_equal(rec.u, plain.u)
    np.testing.assert_array_equal(rec.y, plain.y)
    assert rec.dt == plain.dt
    assert load_record(tmp_path / "comma.csv", u=["u1", "u2"], y="y", t="t", decimal=",").n == plain.n
    hint = r"'u1', data row 0: '0,3455\d*' is not a number; decimal commas\? pass decimal=','"
    with pytest.raises(RecordError, match=hint):
        load_record(tmp_path / "comma.csv", u=["u1", "u2"], y="y", t="t", decimal=".")
    with pytest.raises(RecordError, match="decimal must be"):
        load_record(tmp_path / "comma.csv", u="u1", y="y", t="t", decimal="dot")
    with pytest.raises(RecordError, match="needs another field separator"):
        load_record(tmp_path / "dot.csv", u="u1", y="y", t="t", decimal=",")


def test_one_column_cannot_serve_two_signals(tmp_path, signals):
    t, u, y = signals
    path = _write_csv(tmp_path / "r.csv", ["t", "u1", "u2", "y"], [t, u, y])
    with pytest.raises(RecordError, match="column 1 is selected both as u= and as y="):
        load_record(path, u="u1", y="u1", t="t")
    with pytest.raises(RecordError, match="column 3 is selected both as u= and as y="):
        load_record(path, u=[1, -1], y=3, t="t")  # -1 is column 3
    with pytest.raises(RecordError, match="column 0 is selected both as u= and as t="):
        load_record(path, u="t", y="y", t="t")
    with pytest.raises(RecordError, match="twice in u="):
        load_record(path, u=["u1", "u1"], y="y", t="t")
    np.savez(tmp_path / "r.npz", u=u, y=y)
    with pytest.raises(RecordError, match="'u' is selected both as u= and as y="):
        load_record(tmp_path / "r.npz", u="u", y="u", dt=0.05)
    dup = _write_csv(tmp_path / "dup.csv", ["t", "u", "u", "y"], [t, u, y])
    with pytest.raises(RecordError, match=r"2 columns named 'u' \(columns \[1, 2\]\); select u= by integer index"):
        load_record(dup, u="u", y="y", t="t")
    assert load_record(dup, u=[1, 2], y="y", t="t").m == 2  # by index it is unambiguous


def test_files_the_readers_cannot_parse_raise_record_errors(tmp_path):
    # MATLAB's v7.3 files are HDF5 behind a 128-byte header whose version field is 0x0200
    header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, HDF5 schema 1.00 .".ljust(116) + bytes(8) + b"\x00\x02IM"
    (tmp_path / "v73.mat").write_bytes(header + b"\x89HDF\r\n\x1a\n" + bytes(256))
    with pytest.raises(RecordError, match=r"v7\.3 \(HDF5\).*'-v7'"):
        load_record(tmp_path / "v73.mat", u="u", y="y", dt=1)
    (tmp_path / "junk.mat").write_bytes(bytes(300))
    with pytest.raises(RecordError, match="cannot read .* as a MATLAB file"):
        load_record(tmp_path / "junk.mat", u="u", y="y", dt=1)
    np.savez(tmp_path / "objects.npz", u=np.array([object()] * 3), y=np.ones(3))
    with pytest.raises(RecordError, match=r"as NPZ .*numpy\.savez"):
        load_record(tmp_path / "objects.npz", u="u", y="y", dt=1)
    (tmp_path / "junk.npz").write_bytes(b"not a zip archive")
    with pytest.raises(RecordError, match="as NPZ"):
        load_record(tmp_path / "junk.npz", u="u", y="y", dt=1)


def test_a_record_built_by_hand_names_its_channels():
    from experiments.lab.records import Record

    rec = Record(u=np.zeros((5, 2)), y=np.zeros((5, 1)), dt=1.0, source="by hand")
    assert rec.u_columns == ("u0", "u1") and rec.y_columns == ("y0",)  # the design report had raised IndexError
    named = Record(u=np.zeros((5, 1)), y=np.zeros((5, 1)), dt=1.0, source="x", u_columns=("volts",))
    assert named.u_columns == ("volts",) and named.y_columns == ("y0",)


def test_unix_time_stamps_are_uniform_to_their_rounding(tmp_path, signals):
    """Time stamps near 1.7e9 s (a Unix time) are stored to ~2.4e-7 s: their steps of 0.05 s differ by that much
    (relative 5e-6 > rtol), and the record had been refused as not uniformly sampled."""
    t, u, y = signals
    stamps = 1.7e9 + t
    assert np.ptp(np.diff(stamps)) > 1e-6 * 0.05  # the rounding alone exceeds the relative tolerance
    path = _write_csv(tmp_path / "unix.csv", ["time", "u1", "u2", "y"], [stamps, u, y])
    rec = load_record(path, u=["u1", "u2"], y="y", t="time")
    assert rec.dt == 0.05  # rounded to the digits the stamps carry, not 0.05000000006
    bad = stamps.copy()
    bad[20:] += 0.01  # a real step change is still found
    with pytest.raises(RecordError, match="not uniformly sampled: the step from row 19 to 20"):
        load_record(_write_csv(tmp_path / "bad.csv", ["time", "u1", "u2", "y"], [bad, u, y]), u="u1", y="y", t="time")


def test_a_jittered_time_column_with_dt_is_accepted_and_a_gap_is_not(tmp_path, signals):
    """The fix the non-uniform refusal names (the sample time as dt= too) must work with the time column still read:
    the design command picks a column named t/time whatever --dt says.  Stamps within half a sample of the dt grid
    are accepted; a missing row, or a column in other units, is not, and the message names the dt that fits."""
    t, u, y = signals
    jittered = t + np.random.default_rng(3).uniform(-0.01, 0.01, t.size)  # ±0.2 samples
    path = _write_csv(tmp_path / "jitter.csv", ["time", "u1", "u2", "y"], [jittered, u, y])
    with pytest.raises(RecordError, match=r"not uniformly sampled.*pass the sample time as dt= too"):
        load_record(path, u="u1", y="y", t="time")
    rec = load_record(path, u="u1", y="y", t="time", dt=0.05)
    assert rec.dt == 0.05 and np.array_equal(rec.t, jittered)
    gap = np.r_[t[:20], t[21:] + 0.0][: t.size - 1]  # row 20 missing: the stamps skip a sample
    gapped = _write_csv(tmp_path / "gap.csv", ["time", "u1", "u2", "y"], [gap, u[:-1], y[:-1]])
    off_grid = r"disagrees with the time column 'time': row 20 .*\+1 samples off.*rows are missing"
    with pytest.raises(RecordError, match=off_grid):
        load_record(gapped, u="u1", y="y", t="time", dt=0.05)
    ms = _write_csv(tmp_path / "ms.csv", ["time", "u1", "u2", "y"], [1000 * t, u, y])
    with pytest.raises(RecordError, match=r"mean step is 50\); if the column is in other units, pass dt=50 or omit"):
        load_record(ms, u="u1", y="y", t="time", dt=0.05)


def test_a_transposed_csv_with_names_in_its_first_column_is_named(tmp_path, signals):
    """``time,0,0.05,…`` / ``u1,…`` / ``y,…``: the signals in rows, names first.  It had been refused as "'time',
    data row 0: 'u1' is not a number; fix the file or drop that column", a fix that does not apply."""
    t, u, y = signals
    rows = [["time", *t], ["u1", *u[:, 0]], ["y", *y[:, 0]]]
    path = tmp_path / "rows.csv"
    path.write_text("\n".join(",".join(str(c) for c in r) for r in rows) + "\n")
    with pytest.raises(RecordError, match=r"first column holds names \(time, u1, y\).*save the transposed table"):
        load_record(path, u="u1", y="y", t="time")
    # a header with a text cell in a data row is still the cell's own error
    bad = _write_csv(tmp_path / "r.csv", ["time", "u1", "u2", "y"], [t, u, y])
    lines = bad.read_text().splitlines()
    lines[2] = "x" + lines[2][lines[2].index(","):]
    bad.write_text("\n".join(lines) + "\n")
    with pytest.raises(RecordError, match="data row 1: 'x' is not a number"):
        load_record(bad, u="u1", y="y", t="time")


def test_a_binary_or_non_utf8_file_is_a_record_error(tmp_path):
    """A binary file named .csv, or text in Latin-1, had raised UnicodeDecodeError from the CSV reader."""
    binary = tmp_path / "scope.csv"
    binary.write_bytes(bytes(range(128, 256)) * 8)
    latin = tmp_path / "latin.csv"
    latin.write_bytes("t,u,y\n0,1,2\n0.1,1,2\n# température\n".encode("latin-1"))
    for path in (binary, latin):
        with pytest.raises(RecordError, match="is not UTF-8 text.*re-save it as UTF-8 CSV"):
            load_record(path, u="u", y="y")


def test_an_empty_array_is_a_record_error(tmp_path):
    """An NPZ with an empty channel had raised numpy's bare ValueError (reshape of size 0)."""
    path = tmp_path / "empty.npz"
    np.savez(path, u=np.zeros(0), y=np.zeros(0))
    with pytest.raises(RecordError, match="'u' is empty"):
        load_record(path, u="u", y="y", dt=0.1)


def test_a_spreadsheet_file_names_the_formats_to_save_it_in(tmp_path, capsys):
    # record_columns (the design CLI's first look at a file) had passed an .xlsx to the NPZ/MAT reader: "cannot read
    # ... as NPZ or MAT: its ending is '.xlsx'", which names no format to save the data in
    from experiments import record_columns
    from experiments.cli import main

    sheet = tmp_path / "run.xlsx"
    sheet.write_bytes(b"PK\x03\x04 a spreadsheet")
    fix = r"the ending '\.xlsx' is not one of \.csv, \.txt, \.npz, \.mat; save the data as CSV"
    with pytest.raises(RecordError, match=fix):
        record_columns(sheet)
    with pytest.raises(RecordError, match=fix):
        load_record(sheet, u=0, y=1, dt=1)
    with pytest.raises(SystemExit) as exc:
        main(["design", str(sheet), "--horizon", "5", "--out", str(tmp_path)])
    assert exc.value.code == 2 and "save the data as CSV" in capsys.readouterr().err
    with pytest.raises(FileNotFoundError):
        record_columns(tmp_path / "missing.csv")


def test_a_units_row_under_the_header_is_named(tmp_path, signals):
    # a logger's units row had been read as data: "'s' is not a number; fix the file or drop that column"
    t, u, y = signals
    path = tmp_path / "units.csv"
    rows = "\n".join(",".join(f"{x:.17g}" for x in row) for row in np.column_stack([t, u, y]))
    path.write_text("time,u1,u2,y\ns,N,N,m\n" + rows + "\n")
    with pytest.raises(RecordError, match=r"the row after the header \(s, N, N, m\) holds no number: a second header "
                                          r"row \(units\?\); delete it, or start it with '#'"):
        load_record(path, u="u1", y="y", t="time")
    path.write_text("time,u1,u2,y\n# s,N,N,m\n" + rows + "\n")  # the fix the message names
    assert load_record(path, u="u1", y="y", t="time").n == len(t)


@pytest.mark.parametrize("header", [True, False])
def test_a_delimiter_at_the_end_of_every_line_adds_no_column(tmp_path, signals, header):
    # "t,u1,u2,y," (a spreadsheet's export) had given a fourth column of NaN named '', offered as a signal
    from experiments import record_columns

    t, u, y = signals
    rows = "\n".join(",".join(f"{x:.17g}" for x in row) + "," for row in np.column_stack([t, u, y]))
    path = tmp_path / "trailing.csv"
    path.write_text(("time,u1,u2,y,\n" if header else "") + rows + "\n")
    names, width = record_columns(path)
    assert width == 4 and names == (["time", "u1", "u2", "y"] if header else None)
    rec = load_record(path, u=[1, 2], y=3, t=0)
    assert np.array_equal(rec.u, u) and np.array_equal(rec.y, y)
    with pytest.raises(RecordError, match="out of range"):  # the empty column is gone, not a NaN signal
        load_record(path, u=1, y=4, t=0)


@pytest.mark.parametrize("ends", ["header", "rows but the last", "one row", "rows, not the header"])
def test_a_delimiter_at_the_end_of_some_lines_only_adds_no_column(tmp_path, signals, ends):
    # "t,u1,u2,y," over rows without the trailing delimiter (or every row with it but the last) had been refused:
    # "data row 0 has 4 fields but 5 were expected", though the one extra field is empty wherever it is
    t, u, y = signals
    rows = [",".join(f"{x:.17g}" for x in row) for row in np.column_stack([t, u, y])]
    header = "time,u1,u2,y" + ("," if ends in ("header", "rows but the last") else "")
    if ends == "rows but the last":
        rows = [r + "," for r in rows[:-1]] + rows[-1:]
    elif ends == "one row":
        rows[7] += ","
    elif ends == "rows, not the header":
        rows = [r + "," for r in rows]
    path = tmp_path / "some_trailing.csv"
    path.write_text(header + "\n" + "\n".join(rows) + "\n")
    rec = load_record(path, u=["u1", "u2"], y="y", t="time")
    assert np.array_equal(rec.u, u) and np.array_equal(rec.y, y) and rec.u_columns == ("u1", "u2")


def test_a_field_count_error_names_the_line_that_ends_with_a_delimiter(tmp_path):
    # a difference in fields that is not the empty last one alone is refused, and the message says which line ends
    # with a delimiter (it had said "data row 1 has 3 fields but 4 were expected")
    path = tmp_path / "ragged.csv"
    path.write_text("t,u,y,\n0,1,2,3\n0.1,1,2\n")
    with pytest.raises(RecordError, match=r"data row 1 has 3 fields but the header has 4; the header ends with a "
                                          r"delimiter.*delete the delimiter where no value follows it"):
        load_record(path, u="u", y="y", t="t")
    path.write_text("t,u,y\n0,1,2\n0.1,1\n")  # a value missing: no delimiter to blame
    with pytest.raises(RecordError, match=r"data row 1 has 2 fields but the header has 3; every row needs one value"):
        load_record(path, u="u", y="y", t="t")
    rows = "".join(f"0.{k},1,2,\n" for k in range(2, 9))  # a value missing before the delimiter: a NaN, not a shift
    path.write_text("t,u,y,\n0,1,2,\n0.1,1,\n" + rows)
    with pytest.raises(RecordError, match=r"output y has NaN, empty or infinite values \(1\), the first at data row 1"):
        load_record(path, u="u", y="y", t="t")


def test_a_text_column_refuses_the_file_only_when_it_is_selected(tmp_path, signals):
    # a logger's status column or a date-time stamp beside the signals had refused the whole file
    t, u, y = signals
    rows = [f"2026-11-29T10:00:{s:06.3f},{a!r},{b!r},{c!r},OK"
            for s, a, b, c in zip(t.tolist(), u[:, 0].tolist(), u[:, 1].tolist(), y[:, 0].tolist())]
    path = tmp_path / "logger.csv"
    path.write_text("stamp,u1,u2,y,status\n" + "\n".join(rows) + "\n")
    rec = load_record(path, u=["u1", "u2"], y="y", dt=0.05)
    assert np.array_equal(rec.u, u) and np.array_equal(rec.y, y)
    for sel in (dict(u="status", y="y"), dict(u="u1", y="y", t="stamp")):  # selected: the cell's own message
        with pytest.raises(RecordError, match=r"data row 0: '(OK|2026-11-29T10:00:00.000)' is not a number"):
            load_record(path, dt=0.05, **sel)
    # without a header, a status column does not make the first data row a header (its sample would be lost)
    bare = tmp_path / "bare.csv"
    bare.write_text("\n".join(r[r.index(",") + 1:] for r in rows) + "\n")
    rec = load_record(bare, u=[0, 1], y=2, dt=0.05)
    assert np.array_equal(rec.u, u) and np.array_equal(rec.y, y)


@pytest.mark.parametrize("text", ["0.0,1.0,0.0,ok\n0.1,1.0,0.5,ok\n", "0.0,1.0,0.0\n0.1,1.0,0.5\n",
                                  "t,u,y,status\n0.0,1.0,0.0,ok\n0.1,1.0,0.5,ok\n"])
def test_a_two_row_file_is_refused_for_its_few_samples(tmp_path, text):
    # without a header, a status column had made the first of two data rows the header, and the two-row file was
    # then refused as "signals stored in rows: save the transposed table", which gives four samples: no record either
    from experiments import record_columns

    path = tmp_path / "two.csv"
    path.write_text(text)
    message = r"has 2 data rows and [34] columns: 2 samples are far too few for a design.*record a longer one"
    with pytest.raises(RecordError, match=message):
        record_columns(path)
    with pytest.raises(RecordError, match=message):
        load_record(path, u=1, y=2, dt=0.1)


def test_the_fewest_samples_are_those_the_design_asks_for():
    # the reader's "far too few for a design" names the design's own least record: one input, one output, horizon 1
    from experiments.lab.records import _FEWEST_SAMPLES
    from experiments.studies.design_cli import default_weights, design_record

    W1, W2 = default_weights(0.1)[:2]
    with pytest.raises(DataError, match=rf"record at least {_FEWEST_SAMPLES} samples"):
        design_record(np.ones(4), np.ones(4), 0.1, 1, W1, W2)


def test_a_time_column_of_date_time_stamps_names_dt_as_the_fix(tmp_path):
    # a logger's date-time stamps selected as the time column: the message had said "drop that column"
    path = tmp_path / "stamps.csv"
    path.write_text("timestamp,u,y\n" + "".join(f"2026-11-29 10:00:0{k},{k % 2},{0.1 * k}\n" for k in range(6)))
    with pytest.raises(RecordError, match=r"'timestamp', data row 0: .* is not a number: the time column must hold "
                                          r"numbers .* pass dt=<sample time> instead of t="):
        load_record(path, u="u", y="y", t="timestamp")
    assert load_record(path, u="u", y="y", dt=1.0).n == 6  # unselected, the text column is no obstacle


@pytest.mark.parametrize("t_sel", ["time [ms]", 0, -4])
def test_a_time_column_with_a_unit_is_converted_however_it_is_selected(tmp_path, signals, t_sel):
    # by index (t=0, or --t 0 of the design command) the name's unit had been ignored: dt = 50 for a 0.05 s record
    t, u, y = signals
    path = _write_csv(tmp_path / "clock.csv", ["time [ms]", "u1", "u2", "y"], [1e3 * t, u, y])
    rec = load_record(path, u=[1, 2], y=3, t=t_sel)
    assert rec.dt == pytest.approx(0.05, rel=1e-12) and rec.t == pytest.approx(t, rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("sel", [dict(t="time"), dict(t=0), dict(dt=0.05)])
def test_a_units_row_with_a_number_in_it_is_named(tmp_path, signals, sel):
    # "s,N,N,1" (a dimensionless output) has a number, so it was read as data: "'s' is not a number: the time column
    # must hold numbers ... pass dt= instead of t=", or with dt= "'N' is not a number; drop that column"
    t, u, y = signals
    rows = "\n".join(",".join(f"{x:.17g}" for x in row) for row in np.column_stack([t, u, y]))
    path = tmp_path / "units.csv"
    path.write_text("time,u1,u2,y\ns,N,N,1\n" + rows + "\n")
    with pytest.raises(RecordError, match=r"data row 0: '(s|N)' is not a number and the column's other rows are: the "
                                          r"row after the header \(s, N, N, 1\) looks like a second header row \(units"
                                          r"\?\); delete it, or start it with '#'"):
        load_record(path, u=["u1", "u2"], y="y", **sel)
    path.write_text("time,u1,u2,y,note\n" + "\n".join(f"{r},{'start' if k == 0 else k}"
                                                      for k, r in enumerate(rows.splitlines())) + "\n")
    assert load_record(path, u=["u1", "u2"], y="y", **sel).n == len(t)  # text on row 0 of a column not selected


def test_a_space_separated_header_with_units_in_brackets_keeps_each_unit_with_its_name(tmp_path, signals):
    # "time [ms] u1 [N] u2 [N] y [m]" split at every space had given 8 names for 4 columns: "data row 0 has 4 fields
    # but 8 were expected", and the unit of the time column was lost
    t, u, y = signals
    path = _write_csv(tmp_path / "log.txt", ["time [ms]", "u1 [N]", "u2 (N)", "y [m]"], [1e3 * t, u, y],
                      delimiter=" ")
    from experiments import record_columns

    assert record_columns(path) == (["time [ms]", "u1 [N]", "u2 (N)", "y [m]"], 4)
    rec = load_record(path, u=["u1 [N]", "u2 (N)"], y="y [m]", t="time [ms]")
    assert rec.dt == pytest.approx(0.05, rel=1e-12) and np.array_equal(rec.u, u) and np.array_equal(rec.y, y)
