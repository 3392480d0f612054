"""Every speed or accuracy figure of README.md and docs/ is rendered from a stored result
(analysis/readme_figures.py, ``<!-- figures:NAME -->`` blocks checked by tests/test_readme_figures.py),
or is one of the figures listed here with why it is not a measurement of this version: a quoted
literature value, an input or a target, or a dated account of a past measurement that explains a
design decision (it names its date or its before/after and is not offered as today's figure).

A sentence outside the blocks and code fences that holds a number with a unit of time or speed
(ms, s, min, h, x, ×) or a percentage *and* a word that makes it a measured claim (measured, wall,
CPU, takes, costs, faster, RMS, per test, real time, ...) must be listed in :data:`ALLOWED`; a new such
sentence fails until it is rendered from a stored result or listed with its reason."""
from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NUMBER = r"(?<![\w.])\d+(?:[.,]\d+)?(?:\s?[–-]\s?\d+(?:[.,]\d+)?)?"
FIGURE = re.compile(NUMBER + r"\s?(?:ms|s|min|h|×|x|%)(?!\w)")
CLAIM = re.compile(r"\b(measured|wall|CPU|takes?|took|faster|slower|real[ -]time|per (?:test|refit|fit|log|file)|"
                   r"RMS|runs? in|ran in|costs?)\b", re.IGNORECASE)
BLOCK = re.compile(r"<!-- figures:\w+ -->.*?<!-- /figures -->", re.DOTALL)
FENCE = re.compile(r"```.*?```", re.DOTALL)
SENTENCE = re.compile(r"(?<=[.;:])\s+|\n\s*\n|\n[-|]")

HISTORY = "a dated account of a past measurement behind a design decision (names its before/after)"
THEORY = "the theory's derivation or a physical quantity of the rig or model, not a speed or accuracy of this version"
TOLERANCE = "a tolerance, target or acceptance limit, not a measurement"
LITERATURE = "a value quoted from the cited paper"
#: page -> (a distinctive piece of the sentence, why it is not rendered from a stored result)
ALLOWED: dict[str, list[tuple[str, str]]] = {
    "docs/campaigns_at_scale.md": [
        ("On the `rapp2022` rig the rounding step at the l", THEORY),
        ("their Jacobians are thin (tests x a few coeffici", HISTORY),
        ("the manifest, which lists every test, is rewritt", HISTORY),
        ("the manifest (which lists every test) at most ev", TOLERANCE),
        ("every test extracted, 60.4 kB per test, wall tim", HISTORY),
    ],
    "CONTRIBUTING.md": [
        ("Tests marked `slow` take more than 5 s each (the", TOLERANCE),
        ("**3 min 04 s and 3 min 02 s** (183.5 and 181.8 s", HISTORY),
        ("pytest itself reports 3 min 02 s and 3 min 00 s,", HISTORY),
        ("The machine's speed drifts by up to ~10 % from h", HISTORY),
        ("A fresh clone paid (2026-11-27) about 8 s more t", HISTORY),
        ("192 s with that copy's numba cache warm, 200 s c", HISTORY),
        ("**42.9 s → 17.4 s**", HISTORY),
        ("Of each worker's collection about 2.5 s of CPU w", HISTORY),
        ("Fed the per-test times of the idle warm run of 2", HISTORY),
        ("`load` (2026-11-27) 327 s wall, 1.36× the balanc", HISTORY),
        ("`test_lab_downstream.py`'s model route on a lab ", HISTORY),
        ("the help of the 11 commands that run for real as", HISTORY),
        ("the longest single test went from 52 s → ~17 s of", HISTORY),
        ("the whole suite after it, measured once on 2026-", HISTORY),
        ("the whole suite after it (`bench_suite.py`, load", HISTORY),
        ("1989 passed in 7 min 30 s (450.8 s wall, 471 s o", HISTORY),
        ("8 s of CPU per worker (both workers import every", HISTORY),
        ("collection 7.6 s → 6.3 s of CPU per process, and", HISTORY),
        ("~80 s of CPU compiling, in seven kernels of 7–13", HISTORY),
        ("`_run_history_parallel` twice, 11 s of CPU (befo", HISTORY),
        ("its IR simplification made them ~23 % faster per", HISTORY),
        ("not inlining it costs ~45 % of the batch speed", HISTORY),
    ],
    "docs/guide/design.md": [
        ("When the design for identification was added (m", HISTORY),
    ],
    "docs/guide/extraction.md": [
        ("without a force channel the angular velocity (a ", THEORY),
    ],
    "docs/guide/identification.md": [
        ("up to four rounds, each from the last one's fit,", TOLERANCE),
        ("the RMS torque error is at most 2× the noise flo", TOLERANCE),
        ("with n discrete Prandtl elements the cost along ", THEORY),
        ("The verdict compares the RMS angle error with th", TOLERANCE),
        ("K' ≤ 3 % and loss factor ≤ 10 % RMS against the ", TOLERANCE),
    ],
    "docs/guide/uncertainty.md": [
        ("a drop whose budget has the same make-up as a r", TOLERANCE),
    ],
    "docs/guide/map.md": [
        ("the measured c/d differs between cases by about ", LITERATURE),
    ],
    "docs/theory.md": [
        ("the rounds repeat from the better fit (four at m", TOLERANCE),
        ("6.78 % nRMSE for the four-part family, 4.0–4.3", HISTORY),
        ("with them 2.05 % (1.51 % fitted, measured on 2026", HISTORY),
        ("with its published parameters (servo records in ", HISTORY),
        ("In a simulated or measured log, a second force p", THEORY),
        ("Measured before the reference coupling was built", HISTORY),
        ("the energy per cycle in the decay and in steady ", HISTORY),
        ("on the 12-drop campaign 31× the noise allowance.", HISTORY),
        ("the decays with a recovery time of 0.01 s and of", THEORY),
        ("K' and the loss factor within 0.01 % of the unlo", HISTORY),
        ("before, fit 1.9 %, prediction 2.6 % (the unseen ", HISTORY),
        ("switching the law's own history terms off in the", HISTORY),
        ("draw #2 on 2026-11-27 (when the `payne` draws' m", HISTORY),
        ("the fit ended (before the change below, 2026-11-", HISTORY),
        ("Two remedies were measured on the 24.8× fit (20", HISTORY),
        ("the steady twin as a start of the search (its de", HISTORY),
        ("predicted its bench within 0.66 % / 0.65 % RMS o", HISTORY),
    ],
}


def claims(page: Path) -> list[str]:
    """The sentences of ``page`` outside figure blocks and code fences that state a measured figure
    (a clause after a colon is claimed by the clause that leads to it: "measured: 1.6 %")."""
    text = FENCE.sub(lambda m: " " * len(m.group()), BLOCK.sub(lambda m: " " * len(m.group()), page.read_text()))
    parts = SENTENCE.split(text)
    return [" ".join(part.split()) for i, part in enumerate(parts) if FIGURE.search(part) and (
        CLAIM.search(part) or (i and parts[i - 1].rstrip().endswith(":") and CLAIM.search(parts[i - 1])))]


PAGES = [ROOT / "README.md", ROOT / "CONTRIBUTING.md", *sorted((ROOT / "docs").rglob("*.md"))]


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_figure_is_rendered_or_listed_with_its_reason(page: Path) -> None:
    """A measured figure outside the blocks fails unless it is listed with its reason; a listed
    piece that no longer occurs fails too (the list stays the page's)."""
    found = claims(page)
    allowed = ALLOWED.get(str(page.relative_to(ROOT)), [])
    unlisted = [s for s in found if not any(piece in s for piece, _ in allowed)]
    assert not unlisted, (f"{page.relative_to(ROOT)}: figures not rendered from a stored result (render them with "
                          f"analysis/readme_figures.py, or list them in ALLOWED with why): {unlisted}")
    stale = [piece for piece, _ in allowed if not any(piece in s for s in found)]
    assert not stale, f"{page.relative_to(ROOT)}: listed but not found: {stale}"


def test_the_scan_finds_a_stale_figure_and_skips_blocks(tmp_path: Path) -> None:
    """A time in prose is found; the same sentence inside a figure block or a code fence is not."""
    page = tmp_path / "page.md"
    sentence = "The 450 tests of Table 2 take 10–20 s on two cores."
    page.write_text(f"Intro.\n\n{sentence}\n\n<!-- figures:x -->\n{sentence}\n<!-- /figures -->\n\n```\n{sentence}\n```\n")
    assert claims(page) == [sentence]
    page.write_text("A spring of 10 N*m/rad; the record is 0.25 s long.\n")  # no measured claim
    assert claims(page) == []
    page.write_text("None is flagged (measured: M2/M1 within 1.6 %).\n")  # the claim before the colon
    assert claims(page) == ["M2/M1 within 1.6 %)."]


#: what dates a past measurement in its sentence: a date, or its before and after
DATED = re.compile(r"\d{4}-\d\d-\d\d|\bbefore\b|→", re.IGNORECASE)


def sentence_of(page: Path, piece: str) -> str:
    """The whole sentence (to its full stop, not to a colon or semicolon as :func:`claims` cuts) that
    holds ``piece``, outside the blocks and code fences."""
    text = FENCE.sub(lambda m: " " * len(m.group()), BLOCK.sub(lambda m: " " * len(m.group()), page.read_text()))
    flat = " ".join(text.split())
    at = flat.find(piece)
    assert at >= 0, f"{page.relative_to(ROOT)}: {piece!r} not found"
    start = max(flat.rfind(". ", 0, at), flat.rfind("\n", 0, at)) + 1
    end = flat.find(". ", at + len(piece))
    return flat[start:end + 1 if end >= 0 else len(flat)].strip()


@pytest.mark.parametrize("page", [p for p in PAGES if str(p.relative_to(ROOT)) in ALLOWED],
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_every_history_names_its_date_or_its_before_and_after(page: Path) -> None:
    """A figure kept as history is not offered as today's: its sentence names when it was measured
    (a date) or what it compares (before / after)."""
    undated = [piece for piece, why in ALLOWED[str(page.relative_to(ROOT))]
               if why == HISTORY and not DATED.search(sentence_of(page, piece))]
    assert not undated, f"{page.relative_to(ROOT)}: history without its date or before/after: {undated}"


def test_the_check_fails_on_a_new_unrendered_figure(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The page check itself, run on a fake page that states a time as a measurement outside any
    block, fails and names the sentence; the same sentence inside a figure block passes."""
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)  # the page's name relative to the fake root
    page = tmp_path / "docs" / "page.md"
    page.parent.mkdir()
    sentence = "The extraction of one log takes 3.2 s wall on two cores."
    page.write_text(f"# A page\n\n{sentence}\n")
    with pytest.raises(AssertionError, match="takes 3.2 s wall"):
        test_every_figure_is_rendered_or_listed_with_its_reason(page)
    page.write_text(f"# A page\n\n<!-- figures:x -->\n\n{sentence}\n\n<!-- /figures -->\n")
    test_every_figure_is_rendered_or_listed_with_its_reason(page)


def test_every_page_is_listed_once() -> None:
    """A page listed twice in ALLOWED loses the first list silently (a dict literal keeps the last)."""
    import ast

    tree = ast.parse(Path(__file__).read_text())
    literal = next(node.value for node in ast.walk(tree) if isinstance(node, ast.AnnAssign)
                   and getattr(node.target, "id", None) == "ALLOWED")
    pages = [key.value for key in literal.keys]
    assert len(pages) == len(set(pages)), sorted(p for p in pages if pages.count(p) > 1)
