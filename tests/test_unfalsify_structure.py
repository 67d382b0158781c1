"""Package layout rules for unfalsify (and the experiments building blocks it is used with).

* dependencies flow one way: experiments → unfalsify → synthesis (checked on the import
  statements of every module, so a stray import fails here before it becomes a cycle);
* what a public module declares in ``__all__`` is re-exported by its package;
* results are frozen dataclasses.
"""
import ast
import dataclasses
import importlib
import pathlib
import pkgutil

import pytest

import experiments
import unfalsify

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _imported_packages(pkg: str) -> set[str]:
    found = set()
    for path in (ROOT / pkg).glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                found |= {(a.name.split(".")[0], path.name) for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                found.add((node.module.split(".")[0], path.name))
    return found


@pytest.mark.parametrize("pkg, forbidden", [("synthesis", {"unfalsify", "experiments"}),
                                            ("unfalsify", {"experiments"})])
def test_dependencies_flow_one_way(pkg, forbidden):
    bad = sorted((mod, f) for mod, f in _imported_packages(pkg) if mod in forbidden)
    assert not bad, f"{pkg} must not import {forbidden}: {bad}"


@pytest.mark.parametrize("pkg, modules", [(unfalsify, None),
                                          (experiments, ("lab.plants", "lab.signals", "lab.simulate", "lab.records"))])
def test_public_module_names_are_reexported(pkg, modules):
    names = modules or [m.name for m in pkgutil.iter_modules(pkg.__path__) if not m.name.startswith("_")]
    for name in names:
        mod = importlib.import_module(f"{pkg.__name__}.{name}")
        missing = sorted(set(getattr(mod, "__all__", ())) - set(pkg.__all__))
        assert not missing, f"{pkg.__name__}.{name}: {missing}"


def test_results_are_frozen_dataclasses():
    for cls in (unfalsify.ArxResult, unfalsify.SubspaceResult, unfalsify.GainResult, unfalsify.RobustDesignResult,
                unfalsify.AdditiveRobustness, unfalsify.Certificate, experiments.ClosedLoopResult,
                experiments.OpenLoopData):
        assert dataclasses.is_dataclass(cls) and cls.__dataclass_params__.frozen, cls.__name__
