"""The documentation stays complete: every public name is in its package's index, every linked file exists.

(The package docstrings' examples themselves run as doctests: ``--doctest-modules`` in pyproject's addopts.)
"""
import re
from pathlib import Path

import pytest

import experiments
import synthesis
import unfalsify
from synthesis import baselines

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("pkg", [synthesis, unfalsify, experiments, baselines], ids=lambda p: p.__name__)
def test_every_public_name_is_in_the_package_index(pkg):
    indexed = set(re.findall(r"^   (\w+)\s+--", pkg.__doc__, re.M))
    assert not sorted(set(pkg.__all__) - indexed), "public names missing from the docstring index"
    assert not sorted(indexed - set(pkg.__all__)), "index entries that are not public names"


@pytest.mark.parametrize("doc", ["README.md", "experiments/README.md", "experiments/studies/README.md",
                                 "experiments/studies/RESULTS.md", "experiments/bench/README.md",
                                 "experiments/bench/BENCHMARKS.md", "experiments/data/README.md",
                                 "docs/UNFALSIFICATION.md", "docs/ERRATA.md", "docs/ERRORS.md", "CHANGELOG.md"])
def test_relative_links_point_to_files(doc):
    path = ROOT / doc
    for target in re.findall(r"\]\(([^)#:]+)(?:#[^)]*)?\)", path.read_text()):
        assert (path.parent / target).exists(), f"{doc} links to missing {target}"


@pytest.mark.parametrize("pkg", [synthesis, unfalsify, experiments, experiments.lab, baselines],
                         ids=lambda p: p.__name__)
def test_every_public_function_has_a_runnable_examples_section(pkg):
    # the Examples run as doctests (the README's test command collects the packages with --doctest-modules)
    import inspect

    missing = [name for name in pkg.__all__ if inspect.isfunction(getattr(pkg, name))
               and not re.search(r"^Examples\n-+\n", inspect.getdoc(getattr(pkg, name)) or "", re.M)]
    assert not missing, f"public functions without a numpydoc Examples section: {missing}"
