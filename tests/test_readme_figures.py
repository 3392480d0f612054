"""The documentation's measured figures come from one place: every block marked
``<!-- figures:NAME -->`` in the documentation pages and analysis/README.md is what analysis/readme_figures.py renders from the stored full
study (analysis/results/) and the stored benchmark figures (benchmarks/results/, committed).
Nothing is timed here: the benchmarks ran when the results were stored."""
from __future__ import annotations

import importlib.util
import json
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
REGENERATE = ("python analysis/readme_figures.py --render-only (rewrite the blocks from the stored results), or "
              "python analysis/readme_figures.py (re-run the study and the benchmarks first)")


def _module():
    spec = importlib.util.spec_from_file_location("readme_figures", ROOT / "analysis" / "readme_figures.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["readme_figures"] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


figures = _module()


@pytest.fixture(scope="module")
def stored() -> dict:
    return figures.load_stored()


@pytest.mark.parametrize("name", list(figures.BLOCKS))
def test_readme_block_is_the_stored_results(name, stored):
    path, render = figures.BLOCKS[name]
    problems = figures.disagreements(figures.written_block(name), render(stored))
    assert not problems, f"{path}, block {name}: " + "; ".join(problems) + f". Regenerate: {REGENERATE}"


def test_every_marked_block_is_known():
    pages = {str(p.relative_to(ROOT)) for p in [ROOT / "README.md", *(ROOT / "docs").rglob("*.md")]}
    assert not {p for p in pages if "<!-- figures:" in (ROOT / p).read_text()} - {p for p, _ in figures.BLOCKS.values()}
    for path in {p for p, _ in figures.BLOCKS.values()}:
        names = re.findall(r"<!-- figures:(\w+) -->", (ROOT / path).read_text())
        assert sorted(names) == sorted(n for n, (p, _) in figures.BLOCKS.items() if p == path), path
        assert (ROOT / path).read_text().count(figures.END) == len(names), path


def test_the_check_tells_noise_from_drift(stored):
    """A time within the stated machine noise passes, one beyond it fails; a computed figure must
    read exactly as stored; changed words fail."""
    block = figures.bench_table(stored)
    rendered = figures.text(block)
    assert figures.disagreements(rendered, block) == []
    first = next(p for p in block if isinstance(p, figures.Figure) and p.noise > 1 and float(p.text) > 1)
    value, noise = float(first.text), first.noise
    index = block.index(first)

    def with_value(new: str) -> str:
        return figures.text(block[:index]) + new + figures.text(block[index + 1:])
    assert figures.disagreements(with_value(f"{value * 0.9 * noise:.4g}"), block) == []
    assert figures.disagreements(with_value(f"{value * 1.1 * noise:.4g}"), block)
    assert figures.disagreements(with_value(f"{value / (1.1 * noise):.4g}"), block)

    study = figures.study_targets(stored)
    computed = next(p for p in study if isinstance(p, figures.Figure) and p.noise == 1.0)
    i = study.index(computed)
    nudged = figures.text(study[:i]) + f"{float(computed.text) + 0.01:.2f}" + figures.text(study[i + 1:])
    assert figures.disagreements(nudged, study)
    assert figures.disagreements(figures.text(study).replace("met", "reached", 1), study)


def test_stored_benchmark_figures_name_their_machine(stored):
    for name in figures.BENCHMARKS:
        record = stored[name]
        assert record["benchmark"] == f"bench_{name}"
        machine = record["machine"]
        assert machine["cores"] >= 1 and machine["processor"] and re.fullmatch(r"\d{4}-\d\d-\d\d", machine["date"])
        assert not re.search(r"/(tmp|work|home|root|Users)/|\.venv|site-packages", json.dumps(record)), name

