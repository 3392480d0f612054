"""The stored figures (tests/regression.py): a value within the stated reproducibility passes,
one outside it fails naming the figure and the command, a missing figure fails, and
``--regenerate`` stores what the test measured."""
from __future__ import annotations

import json
from types import SimpleNamespace

import pytest

import regression as store


@pytest.fixture
def node(tmp_path, monkeypatch):
    monkeypatch.setattr(store, "DIRECTORY", tmp_path)
    return SimpleNamespace(path=tmp_path / "test_example.py", name="test_figure[a]")


def test_regenerate_stores_and_a_fresh_run_compares(node, tmp_path):
    assert store.Regression(node, regenerate=True).check("error", 0.0123, rel=1e-6) == 0.0123
    assert json.loads((tmp_path / "test_example.json").read_text()) == {"test_figure[a]": {"error": 0.0123}}
    check = store.Regression(node, regenerate=False).check
    assert check("error", 0.0123 * (1 + 5e-7), rel=1e-6) == 0.0123
    with pytest.raises(AssertionError, match=r"error = 0.01231, stored 0.0123 .*python tests/regenerate.py"):
        check("error", 0.01231, rel=1e-6)
    assert check("error", 0.01231, rel=1e-6, atol=1e-5) == 0.0123  # the absolute part widens it


def test_a_missing_figure_or_a_non_finite_value_fails(node):
    with pytest.raises(AssertionError, match="no stored figure 'error' for test_figure\\[a\\]"):
        store.Regression(node, regenerate=False).check("error", 0.1, rel=1e-6)
    with pytest.raises(AssertionError, match="not a figure to store"):
        store.Regression(node, regenerate=True).check("error", float("nan"), rel=1e-6)
