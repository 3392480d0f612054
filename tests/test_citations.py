"""Every citation of a work in the package, its benchmarks and analysis scripts resolves to an entry
of docs/references.md.

A work is cited by the short form its entry in docs/references.md gives (bold, under its
anchor): author-year ("Rapp et al. 2022", "Heine & Plagemann's (2014)" in a sentence), or for the
two source papers whose authors are not known, their entry's name ("the elastoslide paper").
Nicknames ("the pfeffer paper", "seed002" as a paper, an author without the year) are not
resolvable and are refused.
"""
from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
REFERENCES = REPO / "docs" / "references.md"
SOURCES = sorted([*(REPO / "droptower").rglob("*.py"), *(REPO / "benchmarks").glob("*.py"), *(REPO / "analysis").glob("*.py")])

_SURNAME = r"[A-Z\u00c0-\u00de][^\W\d_]+(?:-[A-Z][^\W\d_]+)?"
_AUTHORS = rf"{_SURNAME}(?: {_SURNAME})?(?: et al\.|(?:, {_SURNAME})* & {_SURNAME})?"
#: an author-year citation: authors, a possessive, the year bare or in parentheses
CITATION = re.compile(rf"(?P<authors>{_AUTHORS})(?:'s)? \(?(?P<year>(?:1[6-9]|20)\d\d)\b\)?")
#: "X paper": X must name an entry (the two papers without known authors) or be a determiner
PAPER = re.compile(r"([\w-]+(?: model)?) papers?\b")
GENERIC = {"the", "a", "this", "that", "its", "each", "source", "five", "one", "technical", "same", "other",
           "if", "is", "not", "and", "or", "else", "in", "import", "return"}  # and the code's variable ``paper``
#: an author named without the year ("Rapp et al.'s map")
NO_YEAR = re.compile(r"\bet al\.(?!(?:'s)? \(?(?:1[6-9]|20)\d\d)")


def _entries() -> dict[str, str]:
    """Short form -> anchor of every entry of docs/references.md."""
    text = REFERENCES.read_text(encoding="utf-8")
    return dict((form, anchor) for anchor, form in re.findall(r'<a id="([\w-]+)"></a>\n\*\*(.+?)\*\*', text))


def _author_year(entries: dict[str, str]) -> set[str]:
    return {form for form in entries if re.search(r"\b(?:1[6-9]|20)\d\d$", form)}


def _named_papers(entries: dict[str, str]) -> set[str]:
    return {m.group(1).lower() for form in entries for m in [re.fullmatch(r"The (.+) paper", form)] if m}


def _citations(text: str) -> list[str]:
    """The author-year citations in ``text``, normalised to 'Authors Year'."""
    return [f"{m.group('authors')} {m.group('year')}" for m in CITATION.finditer(text)]


def _resolves(citation: str, known: set[str]) -> bool:
    # a capitalised word before the authors ("See Rapp et al. 2022") is not part of them
    return citation in known or citation.split(" ", 1)[-1] in known


def test_the_references_are_read():
    entries = _entries()
    assert {"Rapp et al. 2022", "Heine & Plagemann 2014", "García Tárrago et al. 2007"} <= _author_year(entries)
    assert _named_papers(entries) == {"zero-dimensional model", "elastoslide"}
    assert entries["Rapp et al. 2022"] == "rapp2022"


def test_the_scans_see_every_form():
    known = _author_year(_entries())
    found = _citations("(Rapp et al. 2022, eq. 16), Heine & Plagemann's (2014) model, Kraus's (1984) shapes, "
                       "García Tárrago et al. 2007; McKay, Beckman & Conover 1979; See Iwan 1966")
    assert found == ["Rapp et al. 2022", "Heine & Plagemann 2014", "Kraus 1984", "García Tárrago et al. 2007",
                     "McKay, Beckman & Conover 1979", "See Iwan 1966"]
    assert all(_resolves(c, known) for c in found)
    assert not any(_resolves(c, known) for c in _citations("Rapp 2022, Heine and Plagemann 2014, Kraus 1985"))
    assert [m.group(1) for m in PAPER.finditer("the pfeffer paper, the elastoslide paper")] == ["pfeffer", "elastoslide"]
    assert NO_YEAR.search("Rapp et al.'s map") and not NO_YEAR.search("Rapp et al.'s (2022) map")


def test_every_author_year_citation_has_an_entry():
    known = _author_year(_entries())
    cited = {path: _citations(path.read_text(encoding="utf-8")) for path in SOURCES}
    assert {"Rapp et al. 2022", "Heine & Plagemann 2014"} <= {c for found in cited.values() for c in found}
    unresolved = [f"{path.relative_to(REPO)}: {c}" for path, found in cited.items() for c in found
                  if not _resolves(c, known)]
    assert not unresolved, "citations without an entry in docs/references.md:\n" + "\n".join(unresolved)


def test_no_nickname_is_left():
    named = _named_papers(_entries())
    found = []
    for path in SOURCES:
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            bad = [m.group(0) for m in PAPER.finditer(line)
                   if m.group(1).lower() not in named and m.group(1).lower().split()[-1] not in GENERIC]
            bad += [m.group(0) for m in NO_YEAR.finditer(line)]
            bad += re.findall(r"\bseed ?00\d\b(?!_)", line)
            found += [f"{path.relative_to(REPO)}:{n}: {b!r} in {line.strip()}" for b in bad]
    assert not found, "nicknames (cite the short form of docs/references.md):\n" + "\n".join(found)
