"""docs/troubleshooting.md cannot rot: every message it quotes is still one the code prints.

A quoted message is a line of a ``text`` block of the page (``droptower: error:`` and the like
are the command line's prefix, left out of the comparison); its
variable parts are written in capitals (``FILE``, ``NAME``, ``N``) or as ``…``, the example
values the page fills in (a channel's name, a file's) are in quotes or numbers, and flags
(``--rig``) and bracketed forms (``NAME[:UNIT]``) are taken as variable, since the command line
composes them. The fixed text
between them must occur in one string of the package (adjacent literals joined, an f-string's
replacement fields as gaps), as the library writes it or as the command line reports it (its
Python names turned into flags by ``droptower.cli.flags.cli_text``)."""
from __future__ import annotations

import io
import re
import tokenize
from functools import lru_cache
from pathlib import Path

import pytest

from droptower.cli.flags import cli_text

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "troubleshooting.md"
#: a message's variable parts: capitals (FILE, NAME, ROLE, N), "…", quoted example values, numbers, and
#: the flags and bracketed forms the command line composes (``give {flags}``, ``NAME[:UNIT]``)
VARIABLE = re.compile(r"\b[A-Z][A-Z_]*\b|…|'[^']*'|\b\d+(?:\.\d+)?\b|--[a-z][a-z0-9-]*|\[[^\]]*\]")
#: the line's prefix the command line adds to every message
PREFIX = re.compile(r"^droptower: (?:error|warning|note): (?:FILE: )?")
GAP = "\x00"


def quoted_messages() -> list[str]:
    text = PAGE.read_text(encoding="utf-8")
    blocks = re.findall(r"```text\n(.*?)```", text, re.S)
    return [line.strip() for block in blocks for line in block.splitlines() if line.strip()]


def _literal_text(token: str) -> str:
    """A string token's text, an f-string's replacement fields as gaps."""
    prefix = re.match(r"[A-Za-z]*", token).group(0).lower()
    body = token[len(prefix):]
    quote = body[:3] if body[:3] in ('"""', "'''") else body[0]
    body = body[len(quote):-len(quote)]
    if "f" in prefix:
        body = re.sub(r"\{\{|\}\}|\{(?:[^{}]|\{[^{}]*\})*\}",
                      lambda m: m.group(0)[0] if m.group(0) in ("{{", "}}") else GAP, body)
    if "r" not in prefix:
        body = body.replace("\\'", "'").replace('\\"', '"').replace("\\n", "\n")
    return body


@lru_cache(maxsize=1)
def package_strings() -> tuple[str, ...]:
    """Every string of the package's sources (adjacent literals joined), as written and as the
    command line words it."""
    strings = []
    for path in sorted((ROOT / "droptower").rglob("*.py")):
        tokens = tokenize.generate_tokens(io.StringIO(path.read_text(encoding="utf-8")).readline)
        run: list[str] = []
        for tok in tokens:
            if tok.type == tokenize.STRING:
                run.append(_literal_text(tok.string))
            elif tok.type in (tokenize.NL, tokenize.NEWLINE, tokenize.COMMENT) and run:
                continue
            elif run:
                strings.append("".join(run))
                run = []
    return tuple(strings) + tuple(cli_text(s) for s in strings)


def fixed_parts(message: str) -> list[str]:
    """The fixed text of a quoted message: the parts between its variable ones (≥ 3 characters)."""
    body = PREFIX.sub("", message)
    parts = (p.strip(" ;:,()") for p in VARIABLE.split(body))  # the punctuation around a part may be composed
    return [p for p in parts if len(p) >= 3]


def test_the_page_quotes_messages():
    messages = quoted_messages()
    assert len(messages) >= 12
    assert all(fixed_parts(m) for m in messages)


@pytest.mark.parametrize("message", quoted_messages())
def test_every_quoted_message_is_still_printed(message):
    strings = package_strings()
    missing = [part for part in fixed_parts(message) if not any(part in s for s in strings)]
    assert not missing, f"docs/troubleshooting.md quotes {message!r}; no string of droptower/ holds {missing}"


def test_a_reworded_message_is_caught():
    strings = package_strings()
    assert any("no rotating inertia" in s for s in strings)
    assert not any("no rotational inertia" in s for s in strings)
