"""Helpers for writing tables, CSV/JSON data, figures and markdown reports under ``--out``."""
from __future__ import annotations

import csv
import json
import re
import time
from pathlib import Path
from typing import Iterable, Sequence

_PIPE = re.compile(r"(?<!\\)\|")

__all__ = ["format_table", "write_csv", "write_json", "save_figure", "Report", "median_time", "finish_report",
           "markdown_tables", "LiveTable",
           "check_figure", "FIGURE_PROBLEMS", "json_default", "dumps_json", "strict_json"]


def format_table(headers: Sequence[str], rows: Iterable[Sequence], floatfmt: str = ".4g") -> str:
    """Markdown (GitHub) table; floats formatted with ``floatfmt``."""

    def cell(v):
        if isinstance(v, float):
            v = format(v, floatfmt)
        # a bare '|' (e.g. "max |pole|") would split the cell: escape it (already escaped ones are kept)
        return _PIPE.sub(r"\\|", str(v).replace("\n", " "))

    headers = [cell(h) for h in headers]
    rows = [[cell(v) for v in r] for r in rows]
    widths = [max(len(str(h)), *(len(r[k]) for r in rows)) if rows else len(str(h)) for k, h in enumerate(headers)]
    line = lambda vals: "| " + " | ".join(str(v).ljust(w) for v, w in zip(vals, widths)) + " |"  # noqa: E731
    sep = "|" + "|".join("-" * (w + 2) for w in widths) + "|"
    return "\n".join([line(headers), sep, *(line(r) for r in rows)])


def write_csv(path: Path, headers: Sequence[str], rows: Iterable[Sequence]) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(headers)
        w.writerows(rows)
    return path


def write_json(path: Path, data, *, strict: bool = False) -> Path:
    """``data`` as indented JSON at ``path``; ``strict``: numbers that are not finite as strings
    (:func:`strict_json`)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(dumps_json(data, strict=strict))
    return path


def dumps_json(data, *, strict: bool = False) -> str:
    """``json.dumps`` with the summaries' types; ``strict``: valid JSON for any reader (:func:`strict_json`)."""
    if strict:
        return json.dumps(strict_json(data), indent=2, default=json_default, allow_nan=False)
    return json.dumps(data, indent=2, default=json_default)


def strict_json(obj):
    """``obj`` with every NaN and ±∞ (Python and numpy floats, in arrays too) as the strings ``"nan"``, ``"inf"``,
    ``"-inf"``: ``json.dumps`` writes them as ``NaN``/``Infinity``, which strict readers (``jq``, JavaScript) refuse,
    while ``float()`` reads the strings back.

    Examples
    --------
    >>> import numpy as np
    >>> strict_json({"a": float("nan"), "b": [1.0, np.inf], "c": np.array([-np.inf, 2.0]), "d": "x"})
    {'a': 'nan', 'b': [1.0, 'inf'], 'c': ['-inf', 2.0], 'd': 'x'}
    """
    obj = _from_numpy(obj)
    if isinstance(obj, float):
        return obj if obj == obj and abs(obj) != float("inf") else str(obj)
    if isinstance(obj, dict):
        return {k: strict_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [strict_json(v) for v in obj]
    return obj


def _from_numpy(obj):
    """A numpy scalar or array as the Python value (``.item()``, ``.tolist()``); anything else unchanged."""
    try:
        import numpy as np
    except ImportError:  # pragma: no cover
        return obj
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    return obj


def json_default(obj):
    """``default=`` of :func:`json.dumps` for the summaries: numpy scalars and arrays, paths."""
    value = _from_numpy(obj)
    if value is not obj:
        return value
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


#: ``str(path) -> list of problems`` of every figure saved by :func:`save_figure` in this process
#: (checked by the tests: labelled axes, a legend, no curve hidden under another).
FIGURE_PROBLEMS: dict[str, list[str]] = {}


def check_figure(fig) -> list[str]:
    """What a figure lacks: axis labels, a legend, or a curve drawn exactly over another in the same style.

    An axes may take its x (y) label from an axes it shares that axis with (stacked subplots); a figure
    needs at least one legend when some axes has two or more labelled curves.  Two lines with the same
    data (to 1e-6) must differ in line style or marker, or the first is invisible.
    """
    import numpy as np

    problems = []
    axes = [ax for ax in fig.get_axes() if ax.axison and (ax.lines or ax.collections or ax.images)]
    for k, ax in enumerate(axes):
        name = ax.get_title() or f"axes {k}"
        for axis, shared in (("x", ax.get_shared_x_axes()), ("y", ax.get_shared_y_axes())):
            get = "get_xlabel" if axis == "x" else "get_ylabel"
            if not any(getattr(a, get)() for a in shared.get_siblings(ax)):
                problems.append(f"{name}: no {axis} label")
        lines = [ln for ln in ax.lines if ln.get_visible() and len(np.atleast_1d(ln.get_xdata())) > 1]
        for a in range(len(lines)):
            for b in range(a + 1, len(lines)):
                la, lb = lines[a], lines[b]
                ya, yb = np.asarray(la.get_ydata(), float), np.asarray(lb.get_ydata(), float)
                xa, xb = np.asarray(la.get_xdata(), float), np.asarray(lb.get_xdata(), float)
                same = (ya.shape == yb.shape and np.allclose(xa, xb, equal_nan=True)
                        and np.allclose(ya, yb, rtol=1e-6, atol=0, equal_nan=True))
                if same and (la.get_linestyle(), la.get_marker()) == (lb.get_linestyle(), lb.get_marker()):
                    problems.append(f"{name}: curve {la.get_label()!r} is hidden under {lb.get_label()!r}")
    labelled = [ax for ax in axes
                if sum(not str(h.get_label()).startswith("_") for h in ax.lines + ax.collections) >= 2]
    if labelled and not (fig.legends or any(ax.get_legend() for ax in fig.get_axes())):
        problems.append("no legend")
    return problems


def save_figure(fig, path: Path) -> Path:
    """Save a matplotlib figure as PNG and close it; its :func:`check_figure` problems go to ``FIGURE_PROBLEMS``."""
    import matplotlib.pyplot as plt

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    FIGURE_PROBLEMS[str(path)] = check_figure(fig)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def median_time(fn, repeats: int = 5, warmup: int = 1) -> float:
    """Median wall time of ``fn()`` in seconds over ``repeats`` runs (after ``warmup`` runs)."""
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    times.sort()
    return times[len(times) // 2]


class Report:
    """Accumulates markdown sections and writes ``<out>/<name>.md``."""

    def __init__(self, title: str):
        self.parts: list[str] = [f"# {title}\n"]

    def section(self, heading: str, text: str = "") -> None:
        self.parts.append(f"\n## {heading}\n\n{text}\n")

    def text(self, text: str) -> None:
        self.parts.append(text + "\n")

    def table(self, headers, rows, floatfmt: str = ".4g") -> None:
        self.parts.append(format_table(headers, rows, floatfmt) + "\n")

    def figure(self, path: Path, caption: str, relative_to: Path | None = None) -> None:
        rel = Path(path).relative_to(relative_to) if relative_to else Path(path).name
        self.parts.append(f"\n![{caption}]({rel})\n\n*{caption}*\n")

    def write(self, path: Path) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("\n".join(self.parts))
        return path


def finish_report(rep: Report, summary: dict, out: Path, name: str, *, warn_log=(), figures=(),
                  t_start: float | None = None, warnings_heading: str = "Warnings raised (expected)") -> dict:
    """Close a run: list the warnings, record run time and figures, write ``<name>.md`` and ``<name>.json`` (strict
    JSON: a number that is not finite as the string ``"nan"``, ``"inf"`` or ``"-inf"``).

    Returns ``summary`` with ``warnings``, ``seconds`` (if ``t_start``), ``figures`` and ``report`` filled in.
    """
    warn_log = list(warn_log)
    if warn_log:
        rep.section(warnings_heading)
        rep.text("\n".join(f"- {w}" for w in warn_log))
    summary["warnings"] = warn_log
    if t_start is not None:
        summary["seconds"] = time.perf_counter() - t_start
        rep.text(f"\n_Run time {summary['seconds']:.1f} s._")
    summary["figures"] = [Path(f).name for f in figures]
    summary["report"] = str(rep.write(Path(out) / f"{name}.md"))
    write_json(Path(out) / f"{name}.json", summary, strict=True)
    return summary


def markdown_tables(text: str) -> list[list[list[str]]]:
    """The tables of a markdown document, each a list of rows of cells (split on unescaped ``|``).

    A table is a run of consecutive lines starting with ``|``; the separator row (``|---|``) is kept
    as a row, so a well-formed table has the same number of cells on every row.
    """
    tables, current = [], []
    for line in text.splitlines() + [""]:
        if line.lstrip().startswith("|"):
            body = line.strip()
            body = body[1:-1] if body.endswith("|") and not body.endswith("\\|") else body[1:]
            current.append([c.strip() for c in _PIPE.split(body)])
        elif current:
            tables.append(current)
            current = []
    return tables


class LiveTable:
    """A results table written to disk after every row, so an interrupted run keeps what it finished.

    Each :meth:`add` rewrites ``<out>/<name>.md`` (title, intro and the table so far, marked as
    partial) and ``<out>/<name>.json`` (``{"partial": true, "rows": [...]}``); the run's final report,
    written under the same names, replaces both when it completes.

    Parameters
    ----------
    out : pathlib.Path
        Output folder.
    name : str
        File stem (``"bench_unfalsify"``).
    title : str
        Markdown title.
    headers : sequence of str
        Table headers.
    intro : str, optional
        Text above the table.
    """

    def __init__(self, out: Path, name: str, title: str, headers: Sequence[str], intro: str = ""):
        self.md = Path(out) / f"{name}.md"
        self.json = Path(out) / f"{name}.json"
        self.title, self.headers, self.intro = title, list(headers), intro
        self.rows: list[list] = []
        self.records: list = []

    def add(self, row: Sequence, record=None) -> None:
        """Append a table row (and its JSON ``record``, default: the row) and rewrite both files."""
        if len(row) != len(self.headers):
            raise ValueError(f"row has {len(row)} cells but the table has {len(self.headers)} headers")
        self.rows.append(list(row))
        self.records.append(list(row) if record is None else record)
        self.flush()

    def flush(self) -> None:
        """Rewrite the markdown and JSON files with the rows so far."""
        rep = Report(self.title)
        if self.intro:
            rep.text(self.intro)
        rep.text(f"_Partial results: {len(self.rows)} row(s) so far; the run has not finished "
                 "(or was interrupted)._\n")
        rep.table(self.headers, self.rows)
        rep.write(self.md)
        write_json(self.json, {"partial": True, "headers": self.headers, "rows": self.records})
