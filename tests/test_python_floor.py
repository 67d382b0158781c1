"""pyproject's ``requires-python`` floor holds for the code: no language feature or standard-library name newer than
the floor (vermin's static analysis, annotations evaluated).  CI runs one Python only, so this is the check that the
older releases the floor admits are not broken by syntax or a newer module."""
import pathlib
import re
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGES = ("synthesis", "unfalsify", "experiments", "tests")


def _floor() -> str:
    text = (ROOT / "pyproject.toml").read_text()
    return re.search(r'^requires-python\s*=\s*">=\s*(\d+\.\d+)"', text, re.M).group(1)


def _vermin(target: str, *paths) -> subprocess.CompletedProcess:
    code = "import sys, vermin; sys.exit(vermin.main())"
    args = ["-t=%s-" % target, "--no-tips", "--violations", "--eval-annotations", *map(str, paths)]
    return subprocess.run([sys.executable, "-c", code, "vermin", *args], capture_output=True, text=True, cwd=ROOT)


def test_code_runs_on_the_floor_python():
    run = _vermin(_floor(), *PACKAGES)
    assert run.returncode == 0, run.stdout + run.stderr


def test_the_check_can_fail(tmp_path):
    newer = tmp_path / "newer.py"
    newer.write_text("import tomllib\n")  # Python 3.11
    run = _vermin("3.10", newer)
    assert run.returncode != 0 and "tomllib" in run.stdout
