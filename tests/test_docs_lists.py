"""Every list in the docs that the code also holds is complete and names nothing the code does
not have: the identification families (``droptower.identify.families.FAMILIES``, those fitted
from drop tests ``droptower.identify.dropfit.DROP_FAMILIES``), the coupling element kinds
(``droptower.rheology.elements.ELEMENT_KINDS``), the flags ``extract`` raises (the report's
``FLAG_REASONS``) and the options of ``extract`` and ``servo``.

A list is read as the backticked names between two fixed phrases of its page, so a family added
to the code and not to the page (or a name left on the page after the code dropped it) fails
here, naming the page and the name."""
from __future__ import annotations

import re
from pathlib import Path

import click
import pytest

from droptower.cli.identify_cmd import DROP_FAMILY_NAMES, FAMILY_NAMES
from droptower.identify.dropfit import DROP_FAMILIES
from droptower.identify.families import FAMILIES
from droptower.report.run import FLAG_REASONS
from droptower.rheology.elements import ELEMENT_KINDS

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
NAME = re.compile(r"`([a-z][a-z0-9_]*)`")


def _between(page: str, start: str, end: str) -> str:
    """The text of ``page`` from the phrase ``start`` to the next ``end`` (whitespace folded)."""
    text = " ".join((DOCS / page).read_text(encoding="utf-8").split())
    assert start in text, f"docs/{page}: the list's opening phrase {start!r} is gone"
    tail = text[text.index(start):]
    assert end in tail, f"docs/{page}: the list's closing phrase {end!r} is gone"
    return tail[:tail.index(end)]


def _names(page: str, start: str, end: str) -> set[str]:
    return set(NAME.findall(_between(page, start, end)))


#: (page, opening phrase, closing phrase, the registry the list must equal, names in the span that are not list items)
LISTS = {
    "identify's families": ("guide/identification.md", "The family (`--family`, `family=` in Python): `zerodim6`", "Every fit is bounded",
                            set(FAMILIES), {"rapp2022_nr60"}),
    "identify --from-drop-tests' families": ("guide/identification.md", "The family: `elastoslide`",
                                             "(e.g. the composition", set(DROP_FAMILIES), set()),
    "the families fitted from servo records only": ("guide/identification.md", "or `template` (e.g.",
                                                    "fit servo records only", set(FAMILIES) - set(DROP_FAMILIES),
                                                    {"template", "rapp2022_nr60"}),
    "compare-models --from-drop-tests' families": ("guide/identification.md",
                                                   "`droptower compare-models --from-drop-tests", "to the same",
                                                   set(DROP_FAMILIES), {"droptower"}),
    "design --for-identification's families": ("guide/design.md", "`--for-identification MODEL`",
                                               "first fitted to the coupling's", set(DROP_FAMILIES), set()),
    "the coupling element kinds": ("guide/couplings.md", "Element kinds:", "`droptower.servo.steady",
                                   set(ELEMENT_KINDS), {"constriction"}),
}


@pytest.mark.parametrize("what", LISTS)
def test_docs_list_matches_the_code(what):
    page, start, end, registry, other = LISTS[what]
    listed = _names(page, start, end) - other
    assert not registry - listed, f"docs/{page}: {what} lacks {sorted(registry - listed)}"
    assert not listed - registry, f"docs/{page}: {what} names {sorted(listed - registry)}, which the code lacks"


def test_the_command_lines_family_choices_are_the_registries():
    assert set(FAMILY_NAMES) | {"template"} == set(FAMILIES)
    assert set(DROP_FAMILY_NAMES) | {"template"} == set(DROP_FAMILIES)


def test_every_element_kind_has_its_theory():
    theory = (DOCS / "theory.md").read_text(encoding="utf-8")
    assert not [k for k in ELEMENT_KINDS if f"`{k}`" not in theory]


def _raised_flags() -> set[str]:
    """The flags the extractor raises: the literals it appends to a result's ``flags``, the
    named flag constants of droptower/extract (``NAME = "flag"`` under a ``#:`` comment naming a
    flag) and a module's ``FLAGS`` tuple."""
    flags = set()
    for path in (ROOT / "droptower" / "extract").glob("*.py"):
        text = path.read_text(encoding="utf-8")
        flags |= set(re.findall(r"flags\.append\(\"([a-z_]+)\"\)", text))
        flags |= set(re.findall(r"#:[^\n]*\bflag\b[^\n]*\n[A-Z_]+ = \"([a-z_]+)\"", text))
        for listed in re.findall(r"^FLAGS = \(([^)]*)\)", text, re.M):  # a module's tuple of the flags it raises
            flags |= set(re.findall(r"\"([a-z_0-9]+)\"", listed))
    return flags


def test_every_extract_flag_has_its_reason_and_its_docs():
    raised = _raised_flags()
    assert {"double_impact", "poor_fit", "decay_cut_by_next_drop"} <= raised  # the scan finds them
    assert not raised - set(FLAG_REASONS), f"flags the report cannot explain: {sorted(raised - set(FLAG_REASONS))}"
    guide = (DOCS / "guide" / "extraction.md").read_text(encoding="utf-8")
    undocumented = [flag for flag in FLAG_REASONS if f"`{flag}`" not in guide]
    assert not undocumented, f"docs/guide/extraction.md does not name the flag(s) {undocumented}"


def _options(command: str) -> list[list[str]]:
    from droptower.cli.main import cli

    cmd = cli.get_command(click.Context(cli), command)
    return [[o for o in p.opts + p.secondary_opts if o.startswith("--")]
            for p in cmd.params if isinstance(p, click.Option) and not p.hidden]


@pytest.mark.parametrize("command, page", [("extract", "guide/extraction.md"), ("servo", "guide/servo.md"),
                                           ("evaluate-servo", "guide/servo.md")])
def test_every_option_is_documented_in_its_guide(command, page):
    """Each visible option of the command is named on its guide page (``--quiet``, common to all
    commands, on the conventions page)."""
    text = (DOCS / page).read_text(encoding="utf-8") + (DOCS / "conventions.md").read_text(encoding="utf-8")
    missing = [names[0] for names in _options(command) if not any(re.search(re.escape(n) + r"(?![\w-])", text)
                                                                    for n in names)]
    assert not missing, f"docs/{page} does not document {command}'s {missing}"
