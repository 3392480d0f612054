"""compare_models as a library call: every family within its time budget, the table always
complete, a family out of time listed "not converged" and ranked last, the exit code."""
from __future__ import annotations

import numpy as np
import pytest

from droptower.cli.main import main
from droptower.errors import DroptowerError
from droptower.identify import compare_models
from droptower.identify.budget import BudgetExceeded, check, remaining_s, time_budget
from droptower.identify.ranking import EXIT_NONE_FITS, NOT_CONVERGED
from droptower.identify.verdict import EXIT_POOR_FIT
from droptower.rheology import parse_coupling
from random_couplings import random_truth, servo_records


class FakeClock:
    """The budgets' clock, injected (droptower.identify.budget.clock): time moves only when a
    test moves it, so budgets are tested on exact times, not on a loaded machine's wall clock."""

    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t

    def advance(self, seconds: float) -> None:
        self.t += seconds


@pytest.fixture
def clock(monkeypatch):
    import droptower.identify.budget as budget

    fake = FakeClock()
    monkeypatch.setattr(budget, "clock", fake)
    return fake


def test_budget_runs_out_nests_and_is_absent_outside(clock):
    check()  # no budget: never raises
    assert remaining_s() == float("inf")
    with time_budget(0.05):
        check()
        with time_budget(10.0):  # an inner budget never outlasts the outer one
            assert remaining_s() == pytest.approx(0.05, abs=1e-9)
        clock.advance(0.049)
        check()  # within its budget
        assert remaining_s() == pytest.approx(0.001)
        clock.advance(0.002)
        with pytest.raises(BudgetExceeded, match="0.05 s"):
            check()
    check()
    with time_budget(None):
        check()
    with pytest.raises(ValueError):
        with time_budget(0.0):
            pass


@pytest.fixture(scope="module")
def records():
    """Short servo records (0.5 % noise, seeded) of a random pfeffer coupling."""
    return servo_records(parse_coupling(random_truth("pfeffer", np.random.default_rng(27))), 27)


def test_a_family_out_of_its_budget_is_listed_not_converged_and_ranked_last(records):
    """zerodim6 gets a budget it cannot meet, pfeffer none: the table holds both, zerodim6
    "not converged" with the reason and last, pfeffer first; the exit code is that of the
    best converged family (0: its truth is a good fit)."""
    result = compare_models(records, ["zerodim6", "pfeffer"], budget_s={"zerodim6": 1e-3, "pfeffer": None})
    table = result.ranking
    assert table["family"].tolist() == ["pfeffer", "zerodim6"] and table.index.tolist() == [1, 2]
    row = table.iloc[-1]
    assert row["status"] == NOT_CONVERGED and row["verdict"] == NOT_CONVERGED and np.isnan(row["bic"])
    assert "time budget of 0.001 s" in row["note"] and row["n_parameters"] == 6
    assert table.iloc[0]["status"] == "converged" and table.iloc[0]["verdict"] == "good fit"
    assert result.best == "pfeffer" and result.exit_code() == 0
    assert set(result.not_converged) == {"zerodim6"} and set(result.results) == {"pfeffer"}
    doc = result.to_dict()
    assert [r["family"] for r in doc["ranking"]] == ["pfeffer", "zerodim6"] and "records" in doc


def test_no_family_within_its_budget_exits_2_with_a_full_table(records, tmp_path, capsys):
    from droptower.io import write_log

    paths = []
    for seg in records:
        paths.append(tmp_path / f"{seg.name}.csv")
        write_log(paths[-1], np.arange(seg.n) * seg.dt_s, {"angle_rad": seg.angle_rad, "torque_nm": seg.torque_nm}, {})
    result = compare_models(records, ["pfeffer", "zerodim6"], budget_s=1e-3)
    assert result.ranking["status"].tolist() == [NOT_CONVERGED] * 2 and result.best is None
    assert result.exit_code() == EXIT_NONE_FITS
    code = main(["compare-models", *map(str, paths), "--families", "pfeffer,zerodim6", "--budget-s", "0.001"])
    captured = capsys.readouterr()
    assert code == EXIT_NONE_FITS
    assert "pfeffer" in captured.out and "zerodim6" in captured.out and "not converged" in captured.out
    assert "no family converged" in captured.err
    code = main(["compare-models", *map(str, paths), "--families", "pfeffer", "--budget-s", "-1"])
    assert code == 2 and "--budget-s" in capsys.readouterr().err
    code = main(["compare-models", *map(str, paths), "--families", "pfeffer", "--total-budget-s", "0"])
    assert code == 2 and "--total-budget-s" in capsys.readouterr().err


def test_the_exit_code_follows_the_best_converged_family(records):
    result = compare_models(records, ["pfeffer"], budget_s=None)
    result.ranking.loc[1, "verdict"] = "poor fit"
    assert result.exit_code() == EXIT_POOR_FIT and result.exit_code(accept_poor=True) == 0


def test_the_total_budget_is_shared_the_cheaper_families_first(records, monkeypatch, clock):
    """Every family stalls (it checks its budget until that runs out): they are fitted in the
    order of their parameter counts, each gets an equal share of what is left of the total
    budget (its own budget larger), and the whole table is done within the total (each fit
    stops within one check of its share) with every family "not converged"."""
    import droptower.identify.ranking as ranking
    from droptower.identify.data import DataScale
    from droptower.identify.families import family_class

    got = []

    def stall(kind, *args):
        got.append((kind, remaining_s(), clock()))
        while True:
            clock.advance(0.005)  # a core call's time
            check()

    monkeypatch.setattr(ranking, "_fit", stall)
    kinds = ["zerodim20", "pfeffer", "zerodim6"]
    total = 0.6
    t0 = clock()
    result = compare_models(records, kinds, budget_s=60.0, total_budget_s=total)
    elapsed = clock() - t0
    sizes = {k: len(family_class(k)(DataScale.of(records)).parameters) for k in kinds}
    assert [k for k, _, _ in got] == sorted(kinds, key=sizes.get)
    # each family gets an equal share of what is left of the total when it starts (its own
    # budget, 60 s, larger), never more
    for i, (_, share, started) in enumerate(got):
        assert share == pytest.approx((t0 + total - started) / (len(kinds) - i), abs=1e-9)
    assert got[0][1] == pytest.approx(total / 3, abs=1e-9)
    assert elapsed <= total + 0.005 + 1e-9  # the whole table within the total and one call
    assert result.ranking["status"].tolist() == [NOT_CONVERGED] * 3 and set(result.not_converged) == set(kinds)
    with pytest.raises(DroptowerError, match="total_budget_s"):
        compare_models(records, kinds, total_budget_s=0.0)
