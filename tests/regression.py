"""Figures a test measured once and compares with: ``tests/data/regression/<test module>.json``.

A limit that no closed form, conservation law or published number gives (how far a
first-order update moves when the step halves on a calibrated preset, say) is not written into
the test as "the measured value plus some room". The test stores the figure in the module's
file and compares a fresh computation with it within that computation's own reproducibility,
which the test states with the figure. When a change of the physics is meant to move a figure,

    python tests/regenerate.py

reruns every test that stores figures (the ``regression`` fixture marks them) with
``--regenerate``, rewrites the files and the campaign reference values
(``tests/data/campaign_reference``); the JSON diff is reviewed with the change that moved it.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

DIRECTORY = Path(__file__).resolve().parent / "data" / "regression"


class Regression:
    """The stored figures of one test (``request.node``): :meth:`check` compares with them, or
    stores the value given when the run was started with ``--regenerate``."""

    def __init__(self, node: pytest.Item, regenerate: bool) -> None:
        self.path = DIRECTORY / f"{Path(str(node.path)).stem}.json"
        self.test = node.name
        self.regenerate = regenerate

    def _load(self) -> dict:
        return json.loads(self.path.read_text()) if self.path.is_file() else {}

    def check(self, key: str, value: float, rel: float, atol: float = 0.0) -> float:
        """Compare ``value`` with the stored figure ``key`` of this test: it must lie within
        ``rel`` of it (plus ``atol``), the computation's reproducibility. Returns the stored
        figure (``value`` itself when regenerating)."""
        value = float(value)
        if not math.isfinite(value):
            raise AssertionError(f"{self.test}: {key} = {value} is not a figure to store")
        if self.regenerate:
            stored = self._load()
            stored.setdefault(self.test, {})[key] = value
            DIRECTORY.mkdir(parents=True, exist_ok=True)
            self.path.write_text(json.dumps(stored, indent=1, sort_keys=True) + "\n")
            return value
        figures = self._load().get(self.test, {})
        if key not in figures:
            raise AssertionError(f"{self.path.name}: no stored figure '{key}' for {self.test}; "
                                 "run python tests/regenerate.py")
        expected = float(figures[key])
        assert math.fabs(value - expected) <= rel * math.fabs(expected) + atol, (
            f"{self.test}: {key} = {value:.6g}, stored {expected:.6g} (tolerance {rel:g} relative"
            f"{f' + {atol:g}' if atol else ''}); if the change is meant, run python tests/regenerate.py")
        return expected
