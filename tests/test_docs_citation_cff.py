"""CITATION.cff is a valid Citation File Format 1.2.0 file whose version is the package's.

The required keys and their types are those of the format's schema (1.2.0: ``cff-version``,
``message``, ``title``, ``authors``; an author is a person with ``family-names`` or an entity with
``name``); the version is the package's (``droptower.__version__``, which pyproject.toml reads), so a release that forgets the file fails here."""
from __future__ import annotations

import re
import tomllib
from pathlib import Path

import yaml  # PyYAML: a dependency of dask[distributed], which the test extra installs

ROOT = Path(__file__).resolve().parents[1]
#: the schema's keys of a 1.2.0 file (a key outside them makes the file invalid)
CFF_KEYS = {"abstract", "authors", "cff-version", "commit", "contact", "date-released", "doi", "identifiers",
            "keywords", "license", "license-url", "message", "preferred-citation", "references", "repository",
            "repository-artifact", "repository-code", "title", "type", "url", "version"}


def _cff() -> dict:
    return yaml.safe_load((ROOT / "CITATION.cff").read_text(encoding="utf-8"))


def test_citation_cff_is_valid_cff_1_2_0():
    cff = _cff()
    assert cff["cff-version"] == "1.2.0"
    assert set(cff) <= CFF_KEYS, f"keys outside CFF 1.2.0: {sorted(set(cff) - CFF_KEYS)}"
    for key in ("message", "title"):
        assert isinstance(cff[key], str) and cff[key].strip()
    assert cff.get("type", "software") in {"software", "dataset"}
    assert isinstance(cff["authors"], list) and cff["authors"]
    for author in cff["authors"]:
        assert isinstance(author, dict) and (author.get("name") or author.get("family-names"))
    assert cff["authors"] == [{"name": "the droptower developers"}]
    assert cff["license"] == "MIT"
    assert all(isinstance(k, str) and k for k in cff.get("keywords", []))


def test_citation_cff_version_is_the_packages():
    # pyproject.toml reads the version from droptower.__version__ (its one place)
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    assert project["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "droptower.__version__"}
    import droptower

    assert str(_cff()["version"]) == droptower.__version__


def test_citation_cff_has_no_placeholder():
    text = (ROOT / "CITATION.cff").read_text(encoding="utf-8")
    assert not re.search(r"TODO|FIXME|XXX|example\.(com|org)|<[A-Za-z ]+>|\bYOUR[-_ ]", text)
    urls = {k: v for k, v in _cff().items() if k in {"url", "repository", "repository-code", "repository-artifact",
                                                      "license-url", "doi"}}
    assert all(isinstance(v, str) and v.startswith(("https://", "10.")) for v in urls.values()), urls
