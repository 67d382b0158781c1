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


_DOCS = ["README.md", "experiments/README.md", "experiments/studies/README.md", "experiments/studies/RESULTS.md",
         "experiments/bench/README.md", "experiments/data/README.md", "docs/UNFALSIFICATION.md", "docs/ERRATA.md",
         "docs/ERRORS.md", "experiments/bench/BENCHMARKS.md", "CHANGELOG.md"]


@pytest.mark.parametrize("doc", _DOCS)
def test_relative_links_point_to_files(doc):
    path = ROOT / doc
    for target in re.findall(r"\]\(([^)#:]+)(?:#[^)]*)?\)", path.read_text()):
        assert (path.parent / target).exists(), f"{doc} links to missing {target}"


def _slug(heading: str) -> str:
    """The anchor GitHub gives a markdown heading: lower case, punctuation dropped, spaces as hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


@pytest.mark.parametrize("doc", _DOCS)
def test_link_anchors_name_a_heading(doc):
    # ERRATA's link to UNFALSIFICATION.md#robust-design-74-two-corrections-to-the-thesis led nowhere: the heading had
    # been overwritten when the several-channels section was added above it
    path = ROOT / doc
    for target, anchor in re.findall(r"\]\(([^)#:]*)#([^)]*)\)", path.read_text()):
        linked = path.parent / target if target else path
        heads = [_slug(h) for h in re.findall(r"^#+ (.*)$", linked.read_text(), re.M)]
        assert anchor in heads, f"{doc} links to {target or doc}#{anchor}, which has no such heading"


@pytest.mark.parametrize("doc", _DOCS[:-2])  # the measurement log and the CHANGELOG record history, issues included
def test_user_docs_cite_no_internal_issue_numbers(doc):
    # a user has the repository, not its issue tracker: "(issue 29)" in a heading names nothing they can open
    assert not re.search(r"\bissue[ -]\d+", (ROOT / doc).read_text(), re.I), f"{doc} cites an internal issue number"


@pytest.mark.parametrize("pkg", [synthesis, unfalsify, experiments, experiments.lab, baselines],
                         ids=lambda p: p.__name__)
def test_every_public_function_has_a_runnable_examples_section(pkg):
    # the Examples run as doctests (the README's test command collects the packages with --doctest-modules)
    import inspect

    missing = [name for name in pkg.__all__ if inspect.isfunction(getattr(pkg, name))
               and not re.search(r"^Examples\n-+\n", inspect.getdoc(getattr(pkg, name)) or "", re.M)]
    assert not missing, f"public functions without a numpydoc Examples section: {missing}"


def _readme_rows(text: str) -> list[tuple[str, str]]:
    """(first cell, second cell) of every markdown table row of ``experiments/README.md``."""
    rows = []
    for line in text.splitlines():
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", line.strip())[1:-1]]
        if len(cells) >= 2:
            rows.append((cells[0], cells[1]))
    return rows


def test_experiments_readme_lists_every_subcommand_and_its_options():
    # the README promises "every python -m experiments subcommand, its options and the files it writes":
    # robust-adversarial (and four bench-unfalsify options) had been left out of its tables
    from experiments.cli import COMMANDS, _entry

    rows = _readme_rows((ROOT / "experiments" / "README.md").read_text())
    firsts = [first for first, _ in rows]
    missing = [name for name in COMMANDS if not any(re.match(rf"`{re.escape(name)}[ `]", f) for f in firsts)]
    assert not missing, f"subcommands without a row in experiments/README.md: {missing}"
    undocumented = []
    for name in COMMANDS:
        for flags, _ in _entry(name)[3]:
            flag = flags[0] if flags[0].startswith("-") else flags[0].upper()
            if not any(first == f"`{name}`" and flag in second for first, second in rows):
                undocumented.append(f"{name} {flag}")
    assert not undocumented, f"options without a row in experiments/README.md's options table: {undocumented}"


def test_results_say_that_the_scripts_they_name_are_not_in_the_repository():
    # RESULTS.md labels studies by their scratch folders ("slowH scripts", "s18/hunt_m3"), which a user does not have
    text = (ROOT / "experiments" / "studies" / "RESULTS.md").read_text()
    intro = text[:text.index("\n## ")]
    labels = set(re.findall(r"\b(\w+) scripts\b", text)) - {"the", "one-off"}
    assert "not part of the\nrepository" in intro or "not part of the repository" in intro
    assert all(label in intro for label in labels), sorted(label for label in labels if label not in intro)


def test_studies_readme_has_a_section_for_every_study_subcommand():
    # "one module per subcommand: what each runs": robust-adversarial, design and cd-player had no section
    from experiments.cli import COMMANDS

    heads = re.findall(r"^## (.*)$", (ROOT / "experiments" / "studies" / "README.md").read_text(), re.M)
    studies = [name for name, entry in COMMANDS.items() if entry[0].startswith("experiments.studies.")]
    missing = [name for name in studies if not any(f"`{name}`" in h for h in heads)]
    assert not missing, f"study subcommands without a section in experiments/studies/README.md: {missing}"
