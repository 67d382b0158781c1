"""experiments/ shows its three kinds: lab/ (the library the runs use), studies/ (the thesis experiments),
bench/ (the benchmarks); the library modules' former paths stay importable, every package ships."""
import ast
import importlib
import pathlib
import pytest

import experiments
from experiments.cli import COMMANDS, _entry

ROOT = pathlib.Path(__file__).resolve().parents[1]
KINDS = ("lab", "studies", "bench")


@pytest.mark.parametrize("name", ["plants", "signals", "simulate", "records", "report"])
def test_former_library_paths_are_the_lab_modules(name):
    new = importlib.import_module(f"experiments.lab.{name}")
    assert importlib.import_module(f"experiments.{name}") is new
    assert getattr(experiments, name) is new
    ns = {}
    exec(f"import experiments.{name} as old; from experiments.{name} import __all__ as names", ns)
    assert ns["old"] is new and all(hasattr(new, n) for n in ns["names"])


def test_every_subcommand_lives_in_studies_or_bench():
    for name in COMMANDS:
        module, func, _, _ = _entry(name)
        kind = "bench" if name.startswith("bench-") else "studies"
        assert module.startswith(f"experiments.{kind}."), (name, module)
        assert callable(getattr(importlib.import_module(module), func))


def test_every_package_is_listed_for_setuptools():
    tomllib = pytest.importorskip("tomllib")  # Python 3.11+
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    on_disk = {".".join(p.parent.relative_to(ROOT).parts) for pkg in ("synthesis", "unfalsify", "experiments")
               for p in (ROOT / pkg).rglob("__init__.py")}
    assert on_disk == set(cfg["packages"])
    assert cfg["package-data"]["experiments"] == ["data/*"]
    from experiments.studies.cd_player import DATA_FILE

    assert DATA_FILE.is_file() and DATA_FILE.parent == ROOT / "experiments" / "data"


def test_lab_does_not_import_the_studies_or_benchmarks():
    for path in (ROOT / "experiments" / "lab").glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ImportFrom):
                target = (node.module or "").split(".")
                up = target[0] if node.level == 2 else target[1] if target[0] == "experiments" and len(target) > 1 \
                    else None
                assert up not in ("studies", "bench", "cli"), (path.name, node.module)
