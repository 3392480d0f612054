"""The drop-test fit's first guesses (:func:`droptower.identify.dropfit.identify_drops`): the
closed form fitted to the first-cycle readings (``Family.guess_from_readings``) gives the first
search its start, for the family without its deferred part; the whole family's guess is read only
where that search ends poor, and the wider search starts from it, the same start as when it was
read before the first search. On a large campaign each reading costs seconds (one reading per test)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import droptower.identify.dropfit as dropfit
from test_identify_engine import _decays as engine_decays
import droptower.identify.engine.search as engine_search
import droptower.identify.families.filled_rubber as filled_rubber_module
from droptower.identify.engine.problem import DropProblem
from droptower.identify.droplogs import DropDecay, first_cycle_readings
from droptower.identify.families import family_class
from droptower.identify.families.filled_rubber import FilledRubberFamily
from droptower.identify.families.stages import setup_family
from droptower.identify.verdict import GOOD, POOR

DT = 1 / 4800
#: a network of 8 elements (the drop tests' family in tests/test_identify_filled_rubber.py)
OPTIONS = {"n": 8}
#: few evaluations per local fit: every stage runs, cheaply
QUICK = dropfit.DropFitSettings(holdout_fraction=0.0, conditioning=None, max_nfev=3)


def _decays() -> list[DropDecay]:
    """Three free decays of the family's first-guess coupling (tests/test_identify_engine.py's maker)."""
    return engine_decays("filled_rubber")


@pytest.mark.parametrize("poor", [False, True], ids=["good first search", "poor first search"])
def test_the_whole_familys_first_guess_is_read_only_for_the_wider_search(monkeypatch, poor: bool) -> None:
    """A good first search (the verdict forced good) reads one first guess (the family without its
    stiffening branch) and searches once from it; a poor one (forced poor) reads the whole family's
    guess too, and the wider search starts exactly where the closed form of the whole family puts it
    (computed here independently from the same readings). The guesses run one start of their
    closed-form fit instead of 12 (:data:`~droptower.identify.families.filled_rubber.GUESS_STARTS`):
    which guess each search starts from is the claim, not how close it is, and one start still
    gives the two families' guesses apart (asserted below)."""
    monkeypatch.setattr(filled_rubber_module, "GUESS_STARTS", 1)
    decays = _decays()
    guesses: list[tuple[bool, np.ndarray]] = []
    starts: list[tuple[bool, np.ndarray]] = []
    original_guess, original_search = FilledRubberFamily.guess_from_readings, engine_search._Search.global_fit

    def guess(self, *args, **kw):
        out = original_guess(self, *args, **kw)
        guesses.append((bool(self.options["stiffening_branch"]), np.array(out, float)))
        return out

    def search(self, problem, x0, free, *, escalate=False, **kw):
        starts.append((escalate, np.array(x0, float)))
        return original_search(self, problem, x0, free, escalate=escalate, **kw)

    def verdict(problem, *args, **kw):
        v, rss, n = original_verdict(problem, *args, **kw)
        return dataclasses.replace(v, verdict=POOR if poor else GOOD, reasons=["forced"] if poor else []), rss, n

    original_verdict = DropProblem.verdict
    monkeypatch.setattr(FilledRubberFamily, "guess_from_readings", guess)
    monkeypatch.setattr(engine_search._Search, "global_fit", search)
    monkeypatch.setattr(DropProblem, "verdict", verdict)
    dropfit.identify_drops("filled_rubber", decays, settings=QUICK, options=OPTIONS)

    assert guesses[0][0] is False and not starts[0][0]
    np.testing.assert_array_equal(starts[0][1], guesses[0][1])
    if not poor:
        assert len(guesses) == 1 and len(starts) == 1
        return
    assert [g[0] for g in guesses] == [False, True] and [s[0] for s in starts] == [False, True]
    fam = family_class("filled_rubber")(dropfit.drop_scale(decays), OPTIONS)
    s = setup_family(fam, {}, {})
    whole = original_guess(fam, *first_cycle_readings(decays), s.x0, s.given)
    np.testing.assert_array_equal(starts[1][1], whole)
    assert not np.array_equal(whole, guesses[0][1])  # the two starts differ: the test tells them apart
