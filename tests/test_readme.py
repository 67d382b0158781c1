"""The README's code blocks run as written (they are the API tour users copy)."""
import re
import runpy
import warnings
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
BLOCKS = re.findall(r"```python\n(.*?)```", README.read_text(), re.S)


def test_readme_has_code_blocks():
    assert len(BLOCKS) >= 3


# the Chapter 7 block solves LMIs (several seconds): slow
_PARAMS = [pytest.param(k, marks=pytest.mark.slow) if "import unfalsify" in b else k for k, b in enumerate(BLOCKS)]


@pytest.mark.parametrize("k", _PARAMS)
def test_readme_block_runs(k, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    script = tmp_path / f"readme_block{k}.py"
    script.write_text(BLOCKS[k])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        runpy.run_path(str(script), run_name="__main__")
    assert capsys.readouterr().out.strip(), "each README block prints its results"


# ---- the numbers the README prints in its comments -------------------------------------------------
# A line ``print(...)  # 0.102 0.159 …`` states what the call prints. The stated values are the comment's
# leading tokens (up to ": " or " (word"); they are checked against the printed tokens, in order:
#   - plain numbers within the rounding they are shown with (±1 unit of the last digit shown, e.g. 0.873
#     accepts 0.872–0.874, 104 accepts 103–105), numbers below 1e-6 only as "tiny" (|x| ≤ 10 × the stated);
#   - "≈ v" within 3 % relative; "~v" within a factor 10;
#   - words (True, optimal, …) exactly.
# Comments whose leading part is prose (e.g. "≈ noise level") are not checks.
_TOKEN = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:e[-+]?\d+)?|[A-Za-z_]+")
_STATUS_WORDS = {"True", "False", "optimal", "optimal_inaccurate"}
_PRINT = re.compile(r"^(\s*)print\((.*)\)\s+#\s*(.+)$")


def _expected(comment: str):
    """(kind, tokens) of a print comment, or None when it states no values."""
    head = re.split(r":\s|\s\((?=[A-Za-z§])", comment, maxsplit=1)[0].strip()
    kind = "exact"
    if head.startswith("≈"):
        kind, head = "approx", head[1:].strip()
    elif head.startswith("~"):
        kind, head = "order", head[1:].strip()
    tokens = _TOKEN.findall(head)
    if not tokens or any(t[0].isalpha() and t not in _STATUS_WORDS for t in tokens):
        return None
    return kind, tokens


def _close(kind: str, stated: str, actual: str) -> bool:
    if stated[0].isalpha() or actual[:1].isalpha():
        return stated == actual
    s, a = float(stated), float(actual)
    if kind == "approx":
        return abs(a - s) <= 0.03 * abs(s)
    if kind == "order" or abs(s) < 1e-6:
        return abs(a) <= 10 * abs(s)
    mant = stated.lower().split("e")[0]
    exp = int(stated.lower().split("e")[1]) if "e" in stated.lower() else 0
    decimals = len(mant.split(".")[1]) if "." in mant else 0
    return abs(a - s) <= 10.0 ** (exp - decimals) * 1.000001


def _checked_block(src: str):
    lines, checks = src.split("\n"), {}
    for k, line in enumerate(lines):
        m = _PRINT.match(line)
        if m and _expected(m.group(3)):
            checks[k] = (line.strip(), _expected(m.group(3)))
            lines[k] = f"{m.group(1)}__record({k}, {m.group(2)})"
    return "\n".join(lines), checks


_VALUE_BLOCKS = [k for k, b in enumerate(BLOCKS) if _checked_block(b)[1]]


def _heading(k: int) -> str:
    text = README.read_text()
    pos = text.index("```python\n" + BLOCKS[k])
    return re.findall(r"^#+ (.*)$", text[:pos], re.M)[-1]


# the Chapter 7 block solves LMIs (several seconds): slow
_VALUE_PARAMS = [pytest.param(k, marks=pytest.mark.slow) if "import unfalsify" in BLOCKS[k] else k
                 for k in _VALUE_BLOCKS]


@pytest.mark.parametrize("k", _VALUE_PARAMS)
def test_readme_printed_values_match_the_comments(k, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    src, checks = _checked_block(BLOCKS[k])
    printed = {}

    def record(line, *args):
        printed[line] = " ".join(str(a) for a in args)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        exec(compile(src, f"README block {k}", "exec"), {"__name__": "__main__", "__record": record})
    wrong = []
    for line, (code, (kind, stated)) in checks.items():
        actual = _TOKEN.findall(printed[line])
        if len(actual) < len(stated) or not all(_close(kind, s, a) for s, a in zip(stated, actual)):
            wrong.append(f"{code}\n    README says {' '.join(stated)} ({kind}), code prints {printed[line]}")
    assert not wrong, "\n".join(wrong)


def test_value_parser():
    assert _expected("(10, 20) (10, 10) 30 20") == ("exact", ["10", "20", "10", "10", "30", "20"])
    assert _expected("≈ 0.88 (Table 5.1, Design 1)") == ("approx", ["0.88"])
    assert _expected("≈ noise level") is None and _expected("≈ Markov parameters 0, 0.5") is None
    assert _expected("True 1.19: NOT certified (see below)") == ("exact", ["True", "1.19"])
    assert _close("exact", "0.873", "0.8734") and not _close("exact", "0.873", "0.8751")
    assert _close("order", "1e-15", "3e-15") and not _close("order", "1e-15", "1e-13")
