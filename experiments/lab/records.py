"""Read a measured input/output record from a CSV, NPZ or MATLAB file.

:func:`load_record` is the first step from a data file to a designed controller: it picks the
input and output columns, finds the sample time and checks the samples, and returns a frozen
:class:`Record` with time along axis 0 (``u``: ``(n, m)``, ``y``: ``(n, l)``), ready for
:func:`synthesis.fit_predictor`, :func:`unfalsify.subspace_unfalsify` and the designs.
"""
from __future__ import annotations

import csv
import hashlib
import numbers
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from synthesis.export import read_variables
from synthesis.results import result
from synthesis.validation import DataError, as_signal, check_sample_time

__all__ = ["Record", "RecordError", "load_record", "record_columns", "text_columns", "time_unit", "RECORD_FORMATS"]

#: File endings :func:`load_record` reads.
RECORD_FORMATS = (".csv", ".txt", ".npz", ".mat")
#: Seconds per unit of the units a time column's name may carry in brackets (``time [ms]``), by lower-case name.
_SECONDS = {**dict.fromkeys(("s", "sec", "secs", "second", "seconds"), 1.0),
            **dict.fromkeys(("ms", "msec", "millisecond", "milliseconds"), 1e-3),
            **dict.fromkeys(("us", "µs", "μs", "usec", "microsecond", "microseconds"), 1e-6),
            **dict.fromkeys(("ns", "nanosecond", "nanoseconds"), 1e-9),
            **dict.fromkeys(("min", "minute", "minutes"), 60.0),
            **dict.fromkeys(("h", "hr", "hour", "hours"), 3600.0)}
_UNIT_SUFFIX = re.compile(r"\s*(\[([^\]]*)\]|\(([^)]*)\))\s*$")


def time_unit(name) -> tuple[str, str | None, float | None]:
    """A column name split into its bare name and the unit a logger writes after it in brackets, with the unit's
    length in seconds where it is a unit of time: ``"time [ms]"`` → ``("time", "ms", 0.001)``.

    :func:`load_record` converts a time column named with its unit to seconds, so that the sample time is in
    seconds whatever the logger's clock counted (a column ``time [ms]`` had given ``dt = 100`` for a 0.1 s record,
    and a controller and weights at that sample time).

    Returns
    -------
    (bare, unit, seconds)
        ``unit`` None when the name carries none; ``seconds`` None when the unit is not one of time
        (s, ms, µs/us, ns, min, h and their spelled-out names).

    Examples
    --------
    >>> time_unit("time [ms]"), time_unit("Time (s)"), time_unit("position [m]"), time_unit("t")
    (('time', 'ms', 0.001), ('Time', 's', 1.0), ('position', 'm', None), ('t', None, None))
    """
    text = str(name).strip()
    found = _UNIT_SUFFIX.search(text)
    if found is None:
        return text, None, None
    unit = (found.group(2) if found.group(2) is not None else found.group(3)).strip()
    return text[:found.start()].strip(), unit, _SECONDS.get(unit.lower())


class RecordError(DataError):
    """A data file cannot be turned into a record (missing column, NaN, non-uniform time, no dt, ...)."""


@result
@dataclass(frozen=True, eq=False)
class Record:
    """A sampled input/output record, time along axis 0.

    Attributes
    ----------
    u : ndarray, shape (n, m)
        Inputs, one column per channel.
    y : ndarray, shape (n, l)
        Outputs.
    dt : float
        Sample time (seconds, or 1 when the file has none and ``dt=1`` was passed).
    source : str
        The file read.
    u_columns, y_columns : tuple of str
        Where each channel came from (column name, ``"column 2"``, ``"key u"``, ...).
    t : ndarray, shape (n,), or None
        The time column, when there was one: in seconds where its name gave a unit (``time [ms]``), else as read.
    """

    u: np.ndarray
    y: np.ndarray
    dt: float
    source: str
    u_columns: tuple = ()
    y_columns: tuple = ()
    t: np.ndarray | None = None

    def __post_init__(self):
        # a Record built by hand names its channels (u0, u1, …) as the reports need a name for each
        for what in ("u", "y"):
            width = int(np.shape(getattr(self, what))[1]) if np.ndim(getattr(self, what)) == 2 else 1
            if not getattr(self, f"{what}_columns"):
                object.__setattr__(self, f"{what}_columns", tuple(f"{what}{k}" for k in range(width)))

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.u.shape[0])

    @property
    def m(self) -> int:
        """Number of inputs."""
        return int(self.u.shape[1])

    @property
    def l(self) -> int:  # noqa: E743 - the thesis's name for the number of outputs
        """Number of outputs."""
        return int(self.y.shape[1])


def _as_list(sel, what: str):
    if sel is None:
        return None
    if isinstance(sel, (str, numbers.Integral)) and not isinstance(sel, bool):
        return [sel]
    try:
        items = list(sel)
    except TypeError:
        raise RecordError(f"{what} must be a column name, an integer index or a list of them, got {sel!r}") from None
    if not items:
        raise RecordError(f"{what} selects no column; name at least one")
    for s in items:
        if isinstance(s, bool) or not isinstance(s, (str, numbers.Integral)):
            raise RecordError(f"{what}: {s!r} is neither a column name nor an integer index")
    return items


# ---------------------------------------------------------------------------------------------- CSV
#: The samples the design asks for at the least: one input and one output at horizon 1 (unfalsify's record check,
#: 3·i(2m + l) + 2i − 1 fitting samples with the last third held out).  A table with fewer rows and fewer columns
#: than this is too short read either way, by rows or (signals stored in rows) by columns.
_FEWEST_SAMPLES = 15


def _check_orientation(table: np.ndarray, path: Path, text=None) -> None:
    """A CSV table with more columns than rows holds its signals in rows (a record saved transposed), unless it is
    too short read either way: then the problem is the few samples (``text``: the text cells, named first in a wide
    table, as :func:`load_record` passes them)."""
    rows, cols = table.shape
    if cols <= rows:
        return
    if cols < _FEWEST_SAMPLES:
        # two rows under four columns had been called "signals stored in rows: save the transposed table", which
        # gives four samples: no design either
        raise RecordError(f"{str(path)!r} has {rows} data row{'s' if rows != 1 else ''} and {cols} columns: "
                          f"{rows} sample{'s are' if rows != 1 else ' is'} far too few for a design (a record has one "
                          f"row per sample; one input and one output at horizon 1 ask for {_FEWEST_SAMPLES}); record "
                          "a longer one")
    if text:  # a wide table with text: name its first text cell
        raise RecordError(min(text.values())[2])
    raise RecordError(f"{str(path)!r} has {rows} data row{'s' if rows != 1 else ''} and {cols} columns: more "
                      "columns than samples, so the signals look stored in rows; a record has one row per sample "
                      "and one column per signal: save the transposed table")


#: The last CSV parse of :func:`_read_csv`, ``(key, (header, table, text))``: key the path as given, the reading
#: options and a digest of the file's bytes; None before the first.
_last_parse = None


def _read_csv(path: Path, delimiter: str | None, decimal: str | None = None):
    """``(header, table, text)`` of a CSV file (:func:`_parse_csv`), parsed once while its bytes stay the same.

    The design command calls :func:`record_columns`, :func:`text_columns` and :func:`load_record` on one file: each had
    parsed it, three parses of the same text (a 100 000-row record: 2.8–3.5 s, 1.2 s parsed once; hashing its 5.1 MB
    takes 6–14 ms, measured on 2 shared cores).  The bytes are read and hashed on every call, so a file changed in
    between, even to the same size within the same second, is parsed again: the answer is the parse's, kept or not.
    The table is kept read-only (its readers never write it); the header and the text cells are handed out as copies
    (:func:`record_columns` returns the header to the user)."""
    global _last_parse
    raw = path.read_bytes()
    key = (str(path), delimiter, decimal, hashlib.blake2b(raw, digest_size=16).digest())
    last = _last_parse  # one read: another thread may replace it
    if last is None or last[0] != key:
        _last_parse = None  # the previous file's memory goes before the next parse
        header, table, text = _parse_csv(path, raw, delimiter, decimal)
        table.flags.writeable = False
        last = _last_parse = (key, (header, table, text))
    header, table, text = last[1]
    return (None if header is None else list(header)), table, dict(text)


def _parse_csv(path: Path, raw: bytes, delimiter: str | None, decimal: str | None = None):
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:  # a binary file, or text in another encoding, had raised it bare
        raise RecordError(f"{str(path)!r} is not UTF-8 text (byte {exc.start}: {exc.reason}): a CSV record must be "
                          "UTF-8 (or ASCII) text; re-save it as UTF-8 CSV, or export .npz/.mat for binary "
                          "data") from None
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise RecordError(f"{str(path)!r} has no data rows")
    if delimiter is None:
        try:
            delimiter = csv.Sniffer().sniff(lines[0], delimiters=",;\t ").delimiter
        except csv.Error:
            delimiter = ","
    rows = [[c.strip() for c in r] for r in csv.reader(lines, delimiter=delimiter, skipinitialspace=True)]
    if delimiter == " ":
        rows = [[c for c in r if c] for r in rows]
    if decimal is None:
        decimal = _guess_decimal(rows, delimiter)
    elif decimal not in (".", ","):
        raise RecordError(f"decimal must be '.' or ',', got {decimal!r}")
    if decimal == "," and delimiter == ",":
        raise RecordError("decimal=',' needs another field separator than ','; pass delimiter=';' (or the file's)")

    def number(cell):
        return float(cell.replace(",", ".") if decimal == "," else cell)

    def numeric(cell):
        try:
            number(cell)
            return True
        except ValueError:
            return False

    rows = _without_trailing_empty_column(rows)
    header = None
    if not all(numeric(c) for c in rows[0]) and not _data_row_with_text(rows, numeric):
        header, rows = rows[0], rows[1:]
    if not rows:
        raise RecordError(f"{str(path)!r} has a header but no data rows")
    if header is not None and delimiter == " ":
        header = _units_with_names(header)
    if header is not None and not any(numeric(c) for c in rows[0]):
        # a logger's units row ("s,N,m") under the names had been read as data: "'s' is not a number; drop that
        # column", which sends the user to the wrong fix
        raise RecordError(f"{str(path)!r}: the row after the header ({', '.join(rows[0])}) holds no number: a second "
                          "header row (units?); delete it, or start it with '#' to mark it as a comment")
    if header is not None and _labels_in_first_column(header, rows, numeric):
        names = ", ".join([header[0]] + [r[0] for r in rows])
        raise RecordError(f"{str(path)!r}: its first column holds names ({names}) and the rest of each row "
                          "numbers: the signals look stored in rows; a record has one row per sample and one column "
                          "per signal: save the transposed table (names in the first row)")
    width = len(header) if header is not None else len(rows[0])
    data = np.empty((len(rows), width))
    text = {}  # column -> why it is not numbers; an error only once the column is selected (load_record)
    fails = dict.fromkeys(range(width), 0)
    for r, row in enumerate(rows):
        if len(row) != width:
            raise RecordError(_field_count_message(path, header, rows, r))
        for c, cell in enumerate(row):
            try:
                data[r, c] = number(cell) if cell != "" else np.nan
            except ValueError:
                data[r, c] = np.nan
                fails[c] += 1
                if c not in text:  # (row, column) orders the messages as the cells were read
                    col = repr(header[c]) if header is not None else f"column {c}"
                    hint = ("; decimal commas? pass decimal=','" if decimal == "." and _DECIMAL_COMMA.fullmatch(cell)
                            else "")
                    text[c] = (r, c, f"{str(path)!r}: {col}, data row {r}: {cell!r} is not a number", hint, cell)
    for c, (r, _, where, hint, cell) in text.items():
        if header is not None and r == 0 and fails[c] == 1 and len(rows) > 1:
            # text on the first row alone: a units row with a number in it ("s,N,1"), which the check above lets
            # through; "drop that column" (or, for the time column, "pass dt=") had named the wrong fix
            text[c] = (r, c, f"{where} and the column's other rows are: the row after the header "
                             f"({', '.join(rows[0])}) looks like a second header row (units?); delete it, or start it "
                             "with '#' to mark it as a comment", "units", where, cell)
        else:
            text[c] = (r, c, f"{where}{hint}; fix the file or drop that column", "cell", f"{where}{hint}", cell)
    return header, data, text


def _field_count_message(path: Path, header, rows, r: int) -> str:
    """Data row ``r`` has another number of fields than the header (or the first row): which line has how many, and
    which of them ends with a delimiter, the likely slip where the two differ by that empty last field alone."""
    first, what = (header, "the header") if header is not None else (rows[0], "data row 0")
    ends = [name for name, line in ((what, first), (f"data row {r}", rows[r])) if line and line[-1] == ""]
    hint = (f"; {' and '.join(ends)} end{'s' if len(ends) == 1 else ''} with a delimiter, which counts as an empty "
            "last field: delete the delimiter where no value follows it" if ends else "")
    return (f"{str(path)!r}: data row {r} has {len(rows[r])} fields but {what} has {len(first)}{hint}; every row "
            "needs one value per column")


def _data_row_with_text(rows, numeric) -> bool:
    """Is the first row, partly numbers, a data row of a file without a header whose text columns (a status) hold
    text on the next row too?  Such a row is not a header: it would lose the record's first sample."""
    if len(rows) < 2 or not any(numeric(c) for c in rows[0]) or len(rows[1]) != len(rows[0]):
        return False
    # a wide table with a name first and numbers after it is a record saved transposed (_labels_in_first_column),
    # not this; any other text (a status column of a two-row file) had made a wide table's first row its header
    if len(rows) < len(rows[0]) and not numeric(rows[0][0]) and all(numeric(c) for c in rows[0][1:]):
        return False
    return all(numeric(a) == numeric(b) for a, b in zip(rows[0], rows[1]))


def _units_with_names(header):
    """A space-separated header's names with their units put back (``time [ms]`` had split into ``time``,
    ``[ms]``): a field that is a unit in brackets alone belongs to the name before it (:func:`time_unit`)."""
    merged = []
    for cell in header:
        if merged and _UNIT_SUFFIX.fullmatch(cell) and not _UNIT_SUFFIX.search(merged[-1]):
            merged[-1] = f"{merged[-1]} {cell}"
        else:
            merged.append(cell)
    return merged


def _without_trailing_empty_column(rows):
    """Drop the empty last field that a delimiter at the end of a line makes (``t,u,y,``, as some spreadsheets
    export): it had been read as a signal column of NaN named '', or, without a header, had made the first data row
    look like one.

    The field goes also when only some lines end with the delimiter (the header and not the rows, or every row but
    the last): every line is then the one field longer or shorter, and that field is empty wherever it is.  Dropping
    a last field that holds nothing moves no other field, so no column is misaligned; any other difference in the
    number of fields is left to the reader's field-count error.
    """
    while rows:
        width = max(len(r) for r in rows)
        long = [r for r in rows if len(r) == width]
        if width < 2 or any(r[-1] != "" for r in long) or any(len(r) not in (width, width - 1) for r in rows):
            return rows
        rows = [r[:-1] if len(r) == width else r for r in rows]
    return rows


def _labels_in_first_column(header, rows, numeric) -> bool:
    """A table whose first cell of every row is a name and whose other cells are numbers: a record saved transposed
    with its signals' names in the first column (read as it is, the second row's name fails as 'not a number')."""
    return (len(header) > 2 and not numeric(header[0]) and all(numeric(c) for c in header[1:])
            and all(r and not numeric(r[0]) and all(numeric(c) for c in r[1:]) for r in rows))


#: A number written with a decimal comma (``-1,25``, ``3,0e-4``), as spreadsheets in many locales export it.
_DECIMAL_COMMA = re.compile(r"[+-]?\d*,\d+([eE][+-]?\d+)?")


def _guess_decimal(rows, delimiter: str) -> str:
    """``","`` when the separator is not a comma and every field of the last row is a number with a decimal comma
    or an integer (a spreadsheet's export in a comma-decimal locale), else ``"."``."""
    if delimiter == "," or not rows:
        return "."
    last = [c for c in rows[-1] if c]
    commas = [bool(_DECIMAL_COMMA.fullmatch(c)) for c in last]
    plain = [bool(re.fullmatch(r"[+-]?\d+", c)) for c in last]
    return "," if any(commas) and all(a or b for a, b in zip(commas, plain)) else "."


def _pick_columns(table: np.ndarray, header, sel, what: str, path: Path):
    names = []
    cols = []
    picked = []
    for s in sel:
        if isinstance(s, str):
            if header is None:
                raise RecordError(f"{what}={s!r} names a column but {str(path)!r} has no header row; select "
                                  "columns by integer index instead")
            if s not in header:
                raise RecordError(f"{str(path)!r} has no column {s!r} (columns: {', '.join(header)}); "
                                  f"pass {what}= one of them or an integer index")
            if header.count(s) > 1:
                where = [c for c, name in enumerate(header) if name == s]
                raise RecordError(f"{str(path)!r} has {len(where)} columns named {s!r} (columns {where}); select "
                                  f"{what}= by integer index or rename them")
            k = header.index(s)
        else:
            k = int(s)
            if not -table.shape[1] <= k < table.shape[1]:
                raise RecordError(f"{what}: column index {k} is out of range; {str(path)!r} has "
                                  f"{table.shape[1]} columns (0 … {table.shape[1] - 1})")
            k %= table.shape[1]
        cols.append(table[:, k])
        names.append(header[k] if header is not None else f"column {k}")
        picked.append(k)
    return np.column_stack(cols), names, picked


def _check_distinct(selected: dict, path: Path) -> None:
    """Each column (or array) serves one role: ``selected`` maps a role (``"u"``, ``"y"``, ``"t"``) to the columns it
    picked.  The same column as input and output (or twice in one role) is a slip that would fit a plant ``y = u``."""
    seen = {}
    for role, picked in selected.items():
        for k in picked:
            if k in seen:
                name = f"column {k}" if isinstance(k, int) else repr(k)
                other = seen[k]
                twice = f"twice in {role}=" if other == role else f"both as {other}= and as {role}="
                raise RecordError(f"{str(path)!r}: {name} is selected {twice}; each signal needs its own column")
            seen[k] = role


# ---------------------------------------------------------------------------------------------- arrays
def _key(arrays: dict, key, what: str, path: Path):
    if not isinstance(key, str):
        raise RecordError(f"{what}={key!r}: without variable= the entries of {str(path)!r} are selected by name "
                          f"(keys: {', '.join(sorted(arrays))}); or pass variable=<matrix name> and column indices")
    if key not in arrays:
        raise RecordError(f"{str(path)!r} has no array {key!r} (keys: {', '.join(sorted(arrays)) or 'none'}); "
                          f"pass {what}= one of them")
    arr = np.asarray(arrays[key])
    if arr.dtype.kind not in "biuf":
        raise RecordError(f"{str(path)!r}: array {key!r} is not numeric (dtype {arr.dtype})")
    arr = np.asarray(arr, dtype=float)
    if arr.ndim == 2 and 1 in arr.shape:  # MATLAB stores vectors as (1, n) or (n, 1)
        arr = arr.reshape(-1)
    return arr


def _check_finite(arr: np.ndarray, names, path: Path, what: str):
    bad = ~np.isfinite(arr)
    if bad.any():
        rows, cols = np.nonzero(bad)
        first = int(np.argmin(rows))
        r, c = int(rows[first]), int(cols[first])
        count = int(np.count_nonzero(bad[:, c]))
        raise RecordError(
            f"{str(path)!r}: {what} {names[c]} has NaN, empty or infinite values ({count}), the first at data row {r} "
            f"(0-based); clean or interpolate them, or cut the record to the rows before {r} (or after the last bad "
            "one)")


def load_record(path, *, u, y, t=None, dt=None, variable: str | None = None, delimiter: str | None = None,
                decimal: str | None = None, rtol: float = 1e-6) -> Record:
    """Read an input/output record from a ``.csv`` (or ``.txt``), ``.npz`` or ``.mat`` file.

    Parameters
    ----------
    path : str or pathlib.Path
        The file; its ending chooses the reader.
    u, y : str, int or list of them
        The input and output channels.  CSV: column names (the header row) or integer column
        indices (0-based; negative counts from the end).  NPZ/MAT without ``variable``: array
        names; a 1-D array is one channel, a 2-D array ``(n, k)`` is ``k`` channels (a list of
        names is stacked column by column).  With ``variable``: column indices of that matrix.
    t : str or int, optional
        The time column (selected like ``u``).  The sample time is then its mean step (rounded to
        12 significant digits, fewer for stamps whose float rounding is coarser, e.g. a Unix time), and every
        step must equal it to the relative tolerance ``rtol`` (plus the stamps' rounding).  A column whose name
        (or NPZ/MAT key) carries its unit in brackets (``time [ms]``, ``Time (us)``; :func:`time_unit`) is converted
        to seconds, whether selected by name or by index; without one the stamps are taken as seconds.
    dt : float, optional
        The sample time, when the file has no time column (e.g. ``dt=1`` for a record in samples).
        Given together with ``t``, the two must agree: every stamp within half a sample of the grid
        ``t[0] + k·dt`` (a jittered clock is accepted, a missing row or a column in other units is not).
    variable : str, optional
        NPZ/MAT: the name of one matrix (samples along the rows) that holds all channels; ``u``,
        ``y``, ``t`` are then its column indices.
    delimiter : str, optional
        CSV field separator (default: guessed from the first line among ``, ; tab space``).
    decimal : {'.', ','}, optional
        CSV decimal mark.  Default: ``','`` when the separator is not a comma and the last row's
        numbers are written with decimal commas (``0,25;1,5``, a spreadsheet's export in many
        locales), else ``'.'``.
    rtol : float
        Relative tolerance of the uniformity check of the time column.

    Returns
    -------
    Record
        ``u`` ``(n, m)``, ``y`` ``(n, l)``, ``dt``, the source and where each channel came from.

    Raises
    ------
    RecordError
        Unknown file ending; a file its reader cannot parse (a MATLAB v7.3 file, a damaged NPZ);
        a missing column, key or variable (the message lists what there is); a column name the
        header holds twice; one column selected for two signals (e.g. as ``u`` and ``y``); NaN,
        empty or infinite values (which column, first row); channels of different lengths; a
        non-uniform (without ``dt``) or decreasing time column; ``t`` and ``dt`` that disagree; no sample time at
        all; a matrix with time along axis 1.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> from experiments import load_record
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "step.csv"
    >>> _ = path.write_text("time,force,position\\n0.0,1,0.0\\n0.1,1,0.2\\n0.2,1,0.5\\n0.3,1,0.7\\n")
    >>> rec = load_record(path, u="force", y="position", t="time")
    >>> rec.u.shape, rec.y.shape, rec.dt
    ((4, 1), (4, 1), 0.1)
    >>> load_record(path, u="force", y="speed", t="time")
    Traceback (most recent call last):
    ...
    experiments.lab.records.RecordError: '...step.csv' has no column 'speed' (columns: time, force, position); pass y= one of them or an integer index

    A MATLAB matrix with the channels in its columns and no time (``dt=1``: one unit per sample):

    >>> import scipy.io
    >>> mat = path.with_name("arm.mat")
    >>> scipy.io.savemat(mat, {"data": np.random.default_rng(0).standard_normal((50, 4))})
    >>> rec = load_record(mat, variable="data", u=[0, 1], y=[2, 3], dt=1)
    >>> rec.m, rec.l, rec.n, rec.dt
    (2, 2, 50, 1.0)
    """
    path = Path(path)
    fmt = _record_format(path)
    u_sel, y_sel = _as_list(u, "u"), _as_list(y, "y")
    if u_sel is None or y_sel is None:
        raise RecordError("pass both u= and y= (the input and output columns)")
    t_sel = None if t is None else _as_list(t, "t")
    if t_sel is not None and len(t_sel) != 1:
        raise RecordError(f"t must be one column, got {t!r}")

    if fmt in (".csv", ".txt") or variable is not None:
        if fmt in (".csv", ".txt"):
            if variable is not None:
                raise RecordError("variable= is for NPZ/MAT files; a CSV file's columns are selected by u=, y=, t=")
            header, table, text = _read_csv(path, delimiter, decimal)
            _check_orientation(table, path, text)
        else:
            text = {}
            arrays = read_variables(path, error=RecordError)
            if variable not in arrays:
                raise RecordError(f"{str(path)!r} has no variable {variable!r} (it has: "
                                  f"{', '.join(sorted(arrays)) or 'nothing'}); pass variable= one of them")
            table = np.asarray(arrays[variable])
            if table.dtype.kind not in "biuf" or table.ndim not in (1, 2):
                raise RecordError(f"{str(path)!r}: {variable!r} must be a numeric matrix (samples × channels), "
                                  f"got dtype {table.dtype}, shape {table.shape}")
            table = np.asarray(table, dtype=float).reshape(table.shape[0], -1)
            if table.shape[1] > table.shape[0]:
                raise RecordError(f"{str(path)!r}: {variable!r} has shape {table.shape}: more channels than "
                                  f"samples; time runs along axis 0: transpose it ({variable}.T) before saving")
            header = None
            bad = [s for s in u_sel + y_sel + (t_sel or []) if isinstance(s, str)]
            if bad:
                raise RecordError(f"with variable={variable!r} select columns by integer index, not by name {bad[0]!r}")
        U, u_names, u_cols = _pick_columns(table, header, u_sel, "u", path)
        Y, y_names, y_cols = _pick_columns(table, header, y_sel, "y", path)
        T, _, t_cols = _pick_columns(table, header, t_sel, "t", path) if t_sel else (None, None, [])
        T = None if T is None else T[:, 0]
        # the unit is the column's, however it was selected: by index (t=0, --t 0) it had been ignored (dt = 100 for
        # a 0.1 s record in ms)
        t_name = header[t_cols[0]] if t_cols and header is not None else None
        _check_distinct({"u": u_cols, "y": y_cols, "t": t_cols}, path)
        # a column of text (a logger's status, a date-time stamp) is refused only when it is selected: unselected,
        # it had refused the whole file ("'status', data row 0: 'OK' is not a number; drop that column")
        selected = [text[k] for k in t_cols + u_cols + y_cols if k in text]
        if t_cols and t_cols[0] in text and min(selected) == text[t_cols[0]] and text[t_cols[0]][3] == "cell":
            # with dt= given, "--dt instead of --t" named what the user of the design command had done: it takes a
            # column named t/time for the time column by itself
            fix = ("dt= is given: omit t=, or rename the column (python -m experiments design takes a column named t "
                   "or time for the time column when --t is not given)" if dt is not None else
                   "pass dt=<sample time> instead of t= (--dt instead of --t)")
            where, cell = text[t_cols[0]][4:]
            if np.isnan(table[:, t_cols[0]]).all() and _STAMP.search(cell) is None:
                # text in every row and no date or clock time in it (a logger's status): "convert the stamps to
                # numbers" had named stamps the column does not hold
                join = "; " if dt is not None else ", or "
                raise RecordError(f"{where}: the column holds text in every row, not times; select a column of "
                                  f"numbers as t= (--t of python -m experiments design){join}{fix}")
            # a date-time stamp ("2026-11-29 10:00:00.1"): the reader takes numbers only, and "drop that column" had
            # been the fix named for the column that gives the sample time
            raise RecordError(f"{where}: the time column must hold numbers (seconds, or a unit in its name, e.g. "
                              f"'time [ms]'); {fix}, or convert the stamps to numbers")
        if selected:
            raise RecordError(_selected_text_message(min(selected), table, {"u": u_cols, "y": y_cols, "t": t_cols}))
        if variable is not None:
            u_names = [f"{variable}[:, {c.split()[-1]}]" for c in u_names]
            y_names = [f"{variable}[:, {c.split()[-1]}]" for c in y_names]
    else:
        arrays = read_variables(path, error=RecordError)

        def gather(sel, what):
            parts, names = [], []
            for key in sel:
                arr = _key(arrays, key, what, path)
                if arr.ndim == 2 and arr.shape[1] > arr.shape[0]:
                    raise RecordError(f"{str(path)!r}: {key!r} has shape {arr.shape}: more channels than samples; "
                                      f"time runs along axis 0: store {key}.T (shape {arr.shape[::-1]})")
                if arr.ndim not in (1, 2):
                    raise RecordError(f"{str(path)!r}: {key!r} must be 1-D or 2-D, got shape {arr.shape}")
                if arr.size == 0:  # reshape(0, -1) had raised numpy's bare ValueError
                    raise RecordError(f"{str(path)!r}: {key!r} is empty (shape {arr.shape}): the file holds no samples "
                                      "of it; save the record's arrays with their data")
                arr = arr.reshape(arr.shape[0], -1)
                parts.append(arr)
                names += [key] if arr.shape[1] == 1 else [f"{key}[:, {k}]" for k in range(arr.shape[1])]
            lengths = {p.shape[0] for p in parts}
            if len(lengths) > 1:
                raise RecordError(f"{str(path)!r}: the {what} arrays {sel} have different lengths "
                                  f"{[p.shape[0] for p in parts]}; cut them to a common length")
            return np.hstack(parts), names

        _check_distinct({"u": u_sel, "y": y_sel, "t": t_sel or []}, path)
        U, u_names = gather(u_sel, "u")
        Y, y_names = gather(y_sel, "y")
        T, t_name = None, (t_sel[0] if t_sel else None)
        if t_sel:
            T = _key(arrays, t_sel[0], "t", path)
            if T.ndim != 1:
                raise RecordError(f"{str(path)!r}: the time array {t_sel[0]!r} must be one column, got shape {T.shape}")
        lens = {"u": U.shape[0], "y": Y.shape[0], **({"t": T.shape[0]} if T is not None else {})}
        if len(set(lens.values())) > 1:
            listed = ", ".join(f"{k}: {v}" for k, v in lens.items())
            raise RecordError(f"{str(path)!r}: the signals have different lengths ({listed}); "
                              "every signal needs one value per sample: cut them to a common length")

    _check_finite(U, u_names, path, "input")
    _check_finite(Y, y_names, path, "output")
    if T is not None and t_name is not None:
        T = _in_seconds(T, t_name, path)
    dt_value = _sample_time(T, dt, rtol, path, t_sel[0] if t_sel else None)
    U = as_signal(U, "u")
    Y = as_signal(Y, "y", n=U.shape[0])
    return Record(u=U, y=Y, dt=dt_value, source=str(path), u_columns=tuple(u_names), y_columns=tuple(y_names),
                  t=T)


def _selected_text_message(entry, table: np.ndarray, roles: dict) -> str:
    """The refusal of a selected column with text (``entry`` from the CSV reader's ``text``): a column with text in
    every row (a status) is no signal, and "fix the file or drop that column" had not said that another column is
    to be selected."""
    r, c, message, kind, where, _ = entry
    if kind != "cell" or not np.isnan(table[:, c]).all():
        return message
    role = next(name for name, cols in roles.items() if c in cols)
    return (f"{where}: the column holds text in every row, not a signal; select a column of numbers as {role}= "
            f"(--{role} of python -m experiments design)")


#: A cell that looks like a date or a clock time (``2026-11-29``, ``29.11.2026``, ``10:00:00.1``): in the time
#: column, a logger's stamps, which :func:`load_record` asks to be converted to numbers (or replaced by ``dt=``).
_STAMP = re.compile(r"\d{1,4}[-/.]\d{1,2}[-/.]\d{1,4}|\d{1,2}:\d{2}")


def _in_seconds(T: np.ndarray, name: str, path: Path) -> np.ndarray:
    """The time column ``name`` in seconds, by the unit its name carries (:func:`time_unit`); as read without one."""
    _, unit, seconds = time_unit(name)
    if unit is None:
        return T
    if seconds is None:
        raise RecordError(f"{str(path)!r}: the time column {name!r} is in {unit!r}, not a unit of time this reader "
                          "converts (s, ms, us, ns, min, h); rename it with its unit of time, or pass dt=<sample time "
                          "in seconds> without t=")
    return T * seconds


def _record_format(path: Path) -> str:
    """The file's ending, checked: one :data:`RECORD_FORMATS` reads, and a file that exists."""
    fmt = path.suffix.lower()
    if fmt not in RECORD_FORMATS:
        raise RecordError(f"cannot read {str(path)!r}: the ending {fmt or '(none)'!r} is not one of "
                          f"{', '.join(RECORD_FORMATS)}; save the data as CSV (a header row and one column per "
                          "signal), NPZ or MAT")
    if not path.exists():
        raise FileNotFoundError(f"no data file {str(path)!r}")
    return fmt


def record_columns(path, variable: str | None = None) -> tuple[list[str] | None, int | None]:
    """The column names and the number of columns of a record file, before choosing ``u`` and ``y``.

    Parameters
    ----------
    path : str or Path
        A CSV/TXT file, or an NPZ/MAT file.
    variable : str, optional
        For NPZ/MAT: the name of a 2-D matrix whose columns are the signals.

    Returns
    -------
    names : list of str or None
        The CSV header (None without one, and for NPZ/MAT).
    width : int or None
        The number of columns of the CSV or of ``variable``; None for files of named arrays.

    Raises
    ------
    FileNotFoundError
        No file at ``path``.
    RecordError
        A CSV without data rows; an ending :func:`load_record` does not read (``.xlsx``: the message names the
        formats to save the data in).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from experiments import record_columns
    >>> with tempfile.TemporaryDirectory() as d:
    ...     f = pathlib.Path(d) / "run.csv"
    ...     _ = f.write_text("t,u,y\\n0,1,0\\n0.1,1,0.5\\n0.2,1,0.8\\n")
    ...     record_columns(f)
    (['t', 'u', 'y'], 3)
    """
    # the ending first, as load_record checks it: an .xlsx had reached the NPZ/MAT reader and its bare
    # "cannot read as NPZ or MAT", which names no format to save the data in
    path = Path(path)
    fmt = _record_format(path)
    if fmt in (".csv", ".txt"):
        header, table, _ = _read_csv(path, None)
        _check_orientation(table, path)
        return header, table.shape[1]
    if variable is not None and fmt in (".npz", ".mat"):
        arrays = read_variables(path, error=RecordError)
        if variable in arrays and np.ndim(arrays[variable]) == 2:
            return None, int(np.shape(arrays[variable])[1])
    return None, None


def text_columns(path) -> list[int]:
    """The columns of a CSV record that hold text and no number (a logger's status, date-time stamps): not signals.

    :func:`load_record` reads such a column only when it is selected (and then refuses it, naming the cell); the
    design command leaves it out when it picks the signals itself, as if the file had no such column.

    Parameters
    ----------
    path : str or Path
        A CSV/TXT file; NPZ/MAT files hold numbers only and give ``[]``.

    Returns
    -------
    list of int
        0-based column indices, in order.  A column with a number in any data row is not listed: it is a signal
        with bad cells, which :func:`load_record` names when it is selected.

    Raises
    ------
    FileNotFoundError, RecordError
        As :func:`record_columns`.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from experiments import text_columns
    >>> with tempfile.TemporaryDirectory() as d:
    ...     f = pathlib.Path(d) / "run.csv"
    ...     _ = f.write_text("t,u,y,status\\n0,1,0,ok\\n0.1,1,0.5,ok\\n0.2,1,0.8,ok\\n0.3,1,0.9,ok\\n")
    ...     text_columns(f)
    [3]
    """
    path = Path(path)
    if _record_format(path) not in (".csv", ".txt"):
        return []
    _, table, text = _read_csv(path, None)
    return sorted(c for c in text if np.isnan(table[:, c]).all())


def _sample_time(T, dt, rtol: float, path: Path, t_name) -> float:
    if dt is not None:
        try:
            dt = check_sample_time(dt, "dt", allow_true=False)
        except DataError as exc:
            raise RecordError(str(exc)) from None
    if T is None:
        if dt is None:
            raise RecordError(f"{str(path)!r}: no sample time: the record has no time column; pass dt=<sample time> "
                              "(dt=1 for a record counted in samples) or t=<time column>")
        return dt
    if not np.all(np.isfinite(T)):
        r = int(np.flatnonzero(~np.isfinite(T))[0])
        raise RecordError(f"{str(path)!r}: time column {t_name!r} has a NaN or infinite value at row {r}; "
                          "fix it or pass dt= instead of t=")
    if T.shape[0] < 2:
        raise RecordError(f"{str(path)!r}: one sample gives no sample time; pass dt=")
    steps = np.diff(T)
    step = float(np.median(steps))
    if not step > 0:
        raise RecordError(f"{str(path)!r}: time column {t_name!r} does not increase; sort the rows by time or "
                          "pass the right column as t=")
    # the stamps' own rounding: time stamps far from 0 (a Unix time, 1.7e9 s) are stored to ~2.4e-7 s, and their
    # steps differ by that much however uniform the clock was
    resolution = 4.0 * float(np.spacing(np.max(np.abs(T[[0, -1]]))))
    if dt is not None:
        return _stamps_on_grid(T, dt, resolution, path, t_name)
    worst = int(np.argmax(np.abs(steps - step)))
    if abs(steps[worst] - step) > rtol * step + resolution:
        raise RecordError(
            f"{str(path)!r}: time column {t_name!r} is not uniformly sampled: the step from row {worst} to "
            f"{worst + 1} is {steps[worst]:.6g} against {step:.6g} (relative tolerance {rtol:g}); resample the "
            "record onto a uniform grid (e.g. numpy.interp) or, if the time stamps are only jittered, pass the "
            "sample time as dt= too (stamps within half a sample of its grid are then accepted), or loosen rtol=")
    # the mean step over the record, to 12 significant digits (fewer where the stamps' rounding leaves fewer): time
    # stamps written in decimal (0.0, 0.1, 0.2, 0.3) give 0.1, not 0.09999999999999999
    mean = (T[-1] - T[0]) / (T.shape[0] - 1)
    digits = 12 if resolution <= 0 else int(np.clip(np.floor(-np.log10(resolution / (T.shape[0] - 1) / mean)), 1, 12))
    return float(f"{mean:.{digits}g}")


def _stamps_on_grid(T, dt: float, resolution: float, path: Path, t_name) -> float:
    """``dt`` given with a time column: each stamp must lie within half a sample of ``T[0] + k·dt``.

    A logger's jitter (any size below half a sample) leaves every row the sample it claims to be; a missing or
    repeated row, a time column in other units (ms against s) or a wrong ``dt`` put some row a whole sample or more
    off the grid.
    """
    off = T - T[0] - dt * np.arange(T.shape[0])
    far = np.abs(off) >= 0.5 * dt + resolution
    if not far.any():
        return dt
    first = int(np.argmax(far))  # the first row off the grid: where a row is missing, or the units part
    step = float(f"{(T[-1] - T[0]) / (T.shape[0] - 1):.6g}")
    raise RecordError(
        f"{str(path)!r}: dt={dt:g} disagrees with the time column {t_name!r}: row {first} is stamped "
        f"{T[first] - T[0]:.6g} after row 0, {off[first] / dt:+.3g} samples off the grid of dt (the column's mean "
        f"step is {step:g}); if the column is in other units, pass dt={step:g} or omit dt= to take the sample time "
        "from it; if rows are missing or repeated there, resample the record onto a uniform grid (e.g. numpy.interp)")
