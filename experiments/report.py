"""Helpers for writing tables, CSV/JSON data, figures and markdown reports under ``--out``."""
from __future__ import annotations

import csv
import json
import time
from pathlib import Path
from typing import Iterable, Sequence

__all__ = ["format_table", "write_csv", "write_json", "save_figure", "Report", "median_time", "finish_report"]


def format_table(headers: Sequence[str], rows: Iterable[Sequence], floatfmt: str = ".4g") -> str:
    """Markdown (GitHub) table; floats formatted with ``floatfmt``."""

    def cell(v):
        if isinstance(v, float):
            return format(v, floatfmt)
        return str(v)

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


def write_json(path: Path, data) -> Path:
    from .cli import _jsonable

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=2, default=_jsonable))
    return path


def save_figure(fig, path: Path) -> Path:
    """Save a matplotlib figure as PNG and close it."""
    import matplotlib.pyplot as plt

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
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
    """Close a run: list the warnings, record run time and figures, write ``<name>.md`` and ``<name>.json``.

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
    write_json(Path(out) / f"{name}.json", summary)
    return summary
