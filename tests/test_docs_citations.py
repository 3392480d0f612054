"""Citations a reader can follow: every ``docs/theory.md#anchor`` cited in the tree exists, and
no comment, docstring, test or README cites a document outside the repository (the section
numbers of the former specification notes), a bare source-paper number ("seed" and its three
digits) or an issue number instead of the work itself (docs/references.md lists the papers)."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
THEORY = ROOT / "docs" / "theory.md"
#: where comments, docstrings, tests and user-facing texts live (generated results excluded)
SOURCES = [p for pattern in ("droptower/**/*.py", "tests/**/*.py", "benchmarks/**/*.py", "analysis/*.py", "README.md",
                             "docs/**/*.md", "droptower/**/*.md", "tests/**/*.md", "analysis/*.md", "benchmarks/*.md",
                             "rig_configs/**/*.md", "rig_configs/**/*.toml")
           for p in sorted(ROOT.glob(pattern))]
#: the sources page's table of the papers keeps the preset prefixes' numbers between these markers
KEEP = re.compile(r"<!-- cite_rewrite: off -->.*?<!-- cite_rewrite: on -->", re.S)
CITED = re.compile(r"docs/theory\.md((?:#[a-z0-9-]+)(?:, #[a-z0-9-]+)*)")
FORBIDDEN = {
    "a section of a document outside the repository": re.compile(r"\bNOTES\b"),
    "a bare source-paper number": re.compile(r"\b[Ss]eeds? 00[0-4]\b"),
    "an issue number": re.compile(r"\b[Ii]ssues? #?\d+\b"),
}


def _texts():
    for path in SOURCES:
        if path.resolve() == Path(__file__).resolve():
            continue
        yield path.relative_to(ROOT), KEEP.sub("", path.read_text(encoding="utf-8"))


def test_sources_are_found():
    names = {str(p.relative_to(ROOT)) for p in SOURCES}
    assert {"README.md", "docs/guide/map.md", "droptower/sdof.py", "tests/test_extract.py"} <= names
    assert THEORY.is_file() and (ROOT / "docs" / "references.md").is_file()


def test_every_cited_anchor_of_theory_exists():
    anchors = set(re.findall(r'<a id="([a-z0-9-]+)"></a>', THEORY.read_text(encoding="utf-8")))
    assert {"impact", "decay", "double-impact", "extraction", "map", "map-forms", "damping-measures"} <= anchors
    missing = []
    for rel, text in _texts():
        for group in CITED.findall(text):
            missing += [f"{rel}: #{a}" for a in re.findall(r"#([a-z0-9-]+)", group) if a not in anchors]
    assert not missing, "cited anchors that docs/theory.md does not define:\n" + "\n".join(missing)


@pytest.mark.parametrize("what", sorted(FORBIDDEN))
def test_no_citation_a_reader_cannot_follow(what):
    pattern = FORBIDDEN[what]
    found = [f"{rel}:{no}: {line.strip()}" for rel, text in _texts()
             for no, line in enumerate(text.splitlines(), 1) if pattern.search(line)]
    assert not found, f"{what} cited (rewrite it to docs/theory.md or docs/references.md):\n" + "\n".join(found)


def test_the_theory_and_references_cite_no_outside_notes():
    for path in (THEORY, ROOT / "docs" / "references.md"):
        text = path.read_text(encoding="utf-8")
        assert not re.search(r"\bNOTES\b|/work/|\.\./shared", text), path
