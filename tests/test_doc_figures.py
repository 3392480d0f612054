"""Every speed or accuracy figure of README.md and docs/ is rendered from a stored result
(analysis/readme_figures.py, ``<!-- figures:NAME -->`` blocks checked by tests/test_readme_figures.py),
or is one of the figures listed here with why it is not a measurement of this version: a quoted
literature value, an input or a target, or a dated account of a past measurement that explains a
design decision (it names its date or its before/after and is not offered as today's figure).

A sentence outside the blocks and code fences that holds a number with a unit of time or speed
(ms, s, min, h, x, ×) or a percentage *and* a word that makes it a measured claim (measured, wall,
CPU, takes, faster, RMS, per test, real time, ...) must be listed in :data:`ALLOWED`; a new such
sentence fails until it is rendered from a stored result or listed with its reason."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NUMBER = r"(?<![\w.])\d+(?:[.,]\d+)?(?:\s?[–-]\s?\d+(?:[.,]\d+)?)?"
FIGURE = re.compile(NUMBER + r"\s?(?:ms|s|min|h|×|x|%)(?!\w)")
CLAIM = re.compile(r"\b(measured|wall|CPU|takes?|took|faster|slower|real[ -]time|per (?:test|refit|fit|log|file)|"
                   r"RMS|runs? in|ran in)\b", re.IGNORECASE)
BLOCK = re.compile(r"<!-- figures:\w+ -->.*?<!-- /figures -->", re.DOTALL)
FENCE = re.compile(r"```.*?```", re.DOTALL)
SENTENCE = re.compile(r"(?<=[.;:])\s+|\n\s*\n|\n[-|]")

HISTORY = "a dated account of a past measurement behind a design decision (names its before/after)"
THEORY = "the theory's derivation or a physical quantity of the rig or model, not a speed or accuracy of this version"
TOLERANCE = "a tolerance, target or acceptance limit, not a measurement"
LITERATURE = "a value quoted from the cited paper"
#: not yet rendered: a measured figure of the study, a benchmark or a test whose stored result has
#: no block yet (e.g. benchmarks/results/identify_random.txt, tests/test_nr60_calibration.py's
#: figures); listed so that a new unrendered figure fails, to be rendered one by one
PENDING = "measured, not yet rendered from its stored result"
#: page -> (a distinctive piece of the sentence, why it is not rendered from a stored result)
ALLOWED: dict[str, list[tuple[str, str]]] = {
    "docs/benchmarks.md": [
        ("What remains is the coupling kernel itself in fl", PENDING),
    ],
    "docs/campaigns_at_scale.md": [
        ("- The torque sensor's resonance filter (a matrix", PENDING),
        ("On the `rapp2022` rig the rounding step at the l", THEORY),
        ("their Jacobians are thin (tests x a few coeffici", HISTORY),
        ("Unloaded, extracting a log takes about 5.5 ms, w", PENDING),
        ("the manifest, which lists every test, is rewritt", HISTORY),
        ("every test extracted, 60.4 kB per test, wall tim", HISTORY),
    ],
    "CONTRIBUTING.md": [
        ("Tests marked `slow` take more than 5 s each (the", TOLERANCE),
        ("**3 min 04 s and 3 min 02 s** (183.5 and 181.8 s", HISTORY),
        ("pytest itself reports 3 min 02 s and 3 min 00 s,", HISTORY),
        ("The machine's speed drifts by up to ~10 % from h", HISTORY),
        ("A fresh clone paid about 8 s more than `bench_su", HISTORY),
        ("Of each worker's collection about 2.5 s of CPU i", HISTORY),
        ("256 s idle, 468 s of user CPU) the heaviest test", HISTORY),
        ("The help of the 11 commands that run for real as", HISTORY),
        ("The longest single test is now ~17 s of CPU inst", HISTORY),
        ("1875 passed in 9 min 02 s, 412 s of user CPU in ", HISTORY),
        ("Fed the per-test times of the idle warm run (321", HISTORY),
        ("`load` 327 s wall, 1.36× the balanced test time,", HISTORY),
        ("8 s of CPU per worker (both workers import every", HISTORY),
        ("collection 7.6 s → 6.3 s of CPU per process, and", HISTORY),
        ("~80 s of CPU compiling, in seven kernels of 7–13", HISTORY),
        ("`_run_history_parallel` twice, 11 s of CPU.", HISTORY),
        ("its IR simplification makes them ~23 % faster pe", HISTORY),
    ],
    "docs/index.md": [
        ("2022 (stiffness 1.36 %, damping ratio 12.3 % RMS", PENDING),
    ],
    "docs/getting-started.md": [
        ("The core and the rig are numba kernels, compiled", PENDING),
    ],
    "docs/guide/design.md": [
        ("In `benchmarks/bench_design.py` a designed 12-dr", PENDING),
    ],
    "docs/guide/extraction.md": [
        ("without a force channel the angular velocity (a ", THEORY),
    ],
    "docs/guide/identification.md": [
        ("the RMS torque error is at most 2× the noise flo", TOLERANCE),
        ("with n discrete Prandtl elements the cost along ", THEORY),
        ("The verdict compares the RMS angle error with th", TOLERANCE),
        ("K' ≤ 3 % and loss factor ≤ 10 % RMS against the ", TOLERANCE),
        ("pfeffer-type couplings up to K' 1.5 % and loss f", PENDING),
    ],
    "docs/guide/uncertainty.md": [
        ("a drop whose budget has the same make-up as a r", TOLERANCE),
    ],
    "docs/guide/map.md": [
        ("On the paper's own Table 4 the map reproduces th", PENDING),
        ("the measured c/d differs between cases by about ", LITERATURE),
        ("On Table 4 every one of the 30 folds chooses `ve", PENDING),
    ],
    "docs/study.md": [
        ("on a band-limited random angle (1-50 Hz, RMS 0.5", PENDING),
        ("stiffness RMS 8.6 / 4.6 / 6.8 %, damping 14.1 / ", PENDING),
    ],
    "docs/theory.md": [
        ("6.78 % nRMSE for the four-part family, 4.0–4.3", HISTORY),
        ("with them 2.05 % (1.51 % fitted, measured on 2026", HISTORY),
        ("with its published parameters (servo records in ", HISTORY),
        ("In a simulated or measured log, a second force p", THEORY),
        ("Measured on a model tuned to Table 4 alone (a me", HISTORY),
        ("`droptower.compare.first_cycle.loop_span_damping", PENDING),
        ("The network alone (spring and filler network) re", PENDING),
        ("loops taken on a network broken down at the firs", PENDING),
        ("With both, the reference coupling reads 53 % RMS", PENDING),
        ("its reading over its bench, 1.16–1.20) gives eve", PENDING),
        ("either mechanism alone misses by 20 % or 30 % RM", PENDING),
        ("the family's coupling whose steady K*(A, f) is t", PENDING),
        ("the fit ended at 24.8× the noise and missed the ", PENDING),
        ("Two remedies were measured on the 24.8× fit and ", PENDING),
        ("13–16) reads a larger decay rate than the steady", PENDING),
        ("good fit, K' 0.19 %, loss factor 0.21 % RMS, 105", PENDING),
        ("on the Table-2 campaign of `rapp2022_nr60` (450 ", PENDING),
        ("2.2 % and 25 %), a good fit, in 38 s wall / 38 s", PENDING),
        ("41 s wall before the batch kernels ran on thread", PENDING),
        ("On 12-drop campaigns of other structures (three ", PENDING),
        ("with it K' 0.07 %, loss factor 0.35 % RMS, a goo", PENDING),
        ("the family's closed form fitted to that coupling", PENDING),
    ],
}


def claims(page: Path) -> list[str]:
    """The sentences of ``page`` outside figure blocks and code fences that state a measured figure."""
    text = FENCE.sub(lambda m: " " * len(m.group()), BLOCK.sub(lambda m: " " * len(m.group()), page.read_text()))
    return [" ".join(part.split()) for part in SENTENCE.split(text) if FIGURE.search(part) and CLAIM.search(part)]


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
