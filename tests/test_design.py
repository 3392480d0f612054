"""`droptower design`: a target region to a plan that the campaign realises as predicted."""
from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from droptower.campaign import run_campaign
from droptower.cli.main import main
from droptower.design import Target, design_campaign, in_hull
from droptower.design.coverage import plane
from droptower.design.identification import _log_det, d_optimal
from droptower.design.outputs import coverage_description, run_sheet, write_doe
from droptower.design.repeats import repeats_for
from droptower.errors import DroptowerError
from droptower.rheology import load_coupling
from droptower.rig.config import load_doe, load_rig
from pictures import assert_drawn

TARGET = Target((0.3, 3.0), (22.0, 50.0))


# ------------------------------------------------------------------ the hull
@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.lists(st.tuples(st.floats(-3, 3), st.floats(-3, 3)), min_size=1, max_size=40))
def test_in_hull_equals_the_triangle_test(queries):
    """A triangle's hull holds exactly the points with non-negative barycentric coordinates."""
    tri = np.array([[0.0, 0.0], [2.0, 0.5], [0.5, 2.0]])
    q = np.array(queries)
    t = np.column_stack([tri[1] - tri[0], tri[2] - tri[0]])
    lam = np.linalg.solve(t, (q - tri[0]).T).T
    bary = np.column_stack([1 - lam.sum(axis=1), lam])
    clear = np.all(np.abs(bary) > 1e-6, axis=1)  # away from the edges, where rounding decides
    inside = np.all(bary >= 0, axis=1)
    assert np.array_equal(in_hull(tri, q)[clear], inside[clear])


def test_in_hull_of_a_line_holds_only_its_points():
    line = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]])
    assert in_hull(line, np.array([[1.0, 1.0], [0.5, 0.6]])).tolist() == [True, False]


def test_target_refuses_empty_or_reversed_ranges():
    with pytest.raises(DroptowerError, match="^amplitude_deg: "):
        Target((3.0, 0.3), (22.0, 50.0))
    with pytest.raises(DroptowerError, match="^frequency_hz: "):
        Target((0.3, 3.0), (0.0, 50.0))


def test_repeats_reach_the_target_uncertainty_and_no_fewer_do():
    """The mean of n tests has 1/sqrt(n) of one test's uncertainty: n is the least n with
    u1/sqrt(n) <= target."""
    rel = pd.DataFrame({"stiffness_relative_std": [0.004, 0.01], "damping_ratio_relative_std": [0.03, 0.02]})
    n = repeats_for(rel, 1.0)
    assert 0.03 / math.sqrt(n) <= 0.01 < 0.03 / math.sqrt(n - 1)


# ------------------------------------------------------------------ on the shipped rig and coupling
@pytest.fixture(scope="session")  # kept when worksteal splits this file: a second block reuses it
def designed():
    rig, coupling = load_rig("rapp2022"), load_coupling("rapp2022_nr60")
    return rig, coupling, design_campaign(rig, coupling, TARGET, repeats=1)


@pytest.mark.slow
def test_designed_campaign_realises_the_prediction_and_covers_the_target(designed, tmp_path):
    """Run the written plan through `campaign` (rig -> logs -> extraction): every condition's
    amplitude and frequency within 3 % of the design's prediction, no double impact, and
    every point of the target that the design claims lies in the hull of the realised tests."""
    rig, coupling, d = designed
    doe = write_doe(d.conditions, tmp_path / "designed.toml", coverage_description(d))
    res = run_campaign(tmp_path / "run", "rapp2022", "rapp2022_nr60", doe, workers=1, progress=False).results
    keys = ["inertia_kgm2", "drop_mass_kg", "drop_height_m", "preload_nm"]
    m = d.conditions.merge(res, on=keys, suffixes=("_predicted", ""))
    assert len(m) == len(res) == d.n_tests
    assert not res["double_impact"].any()
    assert np.max(np.abs(m["amplitude_deg"] / m["amplitude_deg_predicted"] - 1)) <= 0.03
    assert np.max(np.abs(m["frequency_hz"] / m["frequency_hz_predicted"] - 1)) <= 0.03
    grid = TARGET.grid()
    claimed = in_hull(plane(d.conditions["amplitude_deg"], d.conditions["frequency_hz"]), grid)
    realised = in_hull(plane(res["amplitude_deg"], res["frequency_hz"]), grid)
    assert claimed.mean() == pytest.approx(d.covered_fraction)
    assert np.all(realised[claimed])
    # the design covers all the rig can reach of the target
    assert d.covered_fraction == pytest.approx(d.reachable_fraction, abs=1e-9)
    assert d.covered_fraction > 0.6


def test_design_uses_the_rigs_fixtures_within_its_limits(designed):
    rig, _, d = designed
    c = d.conditions
    assert set(c["inertia_kgm2"]) <= set(rig.inertias_kgm2) and set(c["drop_mass_kg"]) <= set(rig.drop_masses_kg)
    lo, hi = rig.drop_height_range_m
    assert c["drop_height_m"].between(lo, hi).all()
    assert (c["warnings"].map(len) == 0).all() and (c["min_clearance_mm"] >= 1.0).all()
    # three levers, each spanning the target's amplitudes with levels at most 0.2 decades apart
    assert c["inertia_kgm2"].nunique() == 3
    lo, hi = np.log10(TARGET.amplitude_deg)
    for _, g in c.groupby("inertia_kgm2"):
        la = np.sort(np.log10(g["amplitude_deg"]))
        inside = la[(la >= lo - 0.05) & (la <= hi + 0.05)]
        assert inside[0] <= lo + 0.01 and np.max(np.diff(inside)) <= 0.2 + 1e-6


def test_unreachable_parts_are_named_with_the_lever_that_limits_them(designed):
    _, _, d = designed
    text = " | ".join(d.unreachable)
    assert "highest frequency reachable" in text and "lightest lever" in text
    assert "lowest frequency reachable" in text and "heaviest lever" in text


def test_written_plan_is_the_design(designed, tmp_path):
    rig, _, d = designed
    doe = load_doe(write_doe(d.conditions, tmp_path / "p.toml", "test", base_seed=7))
    doe.check(rig)
    cond = doe.conditions()
    keys = ["inertia_kgm2", "drop_mass_kg", "drop_height_m", "preload_nm"]
    assert sorted(map(tuple, cond[keys].to_numpy())) == sorted(map(tuple, d.conditions[keys].to_numpy()))
    assert doe.n_tests == d.n_tests and doe.base_seed == 7


def test_run_sheet_is_seeded_and_blocked_by_fixture(designed):
    _, _, d = designed
    d3 = design_campaign(*designed[:2], TARGET, repeats=3, candidates=d.candidates)
    a, b, other = run_sheet(d3.conditions, 1), run_sheet(d3.conditions, 1), run_sheet(d3.conditions, 2)
    assert a.equals(b) and not a.equals(other)
    assert len(a) == d3.n_tests and (a["operator_notes"] == "").all()
    fixture = list(zip(a["inertia_kgm2"], a["drop_mass_kg"]))
    changes = sum(x != y for x, y in zip(fixture, fixture[1:]))
    assert changes == len(set(fixture)) - 1  # each fixture mounted once
    # not simply sorted by height inside a block
    assert any(not g["drop_height_m"].is_monotonic_increasing for _, g in a.groupby("block"))


def test_budget_gives_way_repeats_first(designed):
    rig, coupling, d = designed
    small = design_campaign(rig, coupling, TARGET, repeats=5, max_tests=2 * d.n_conditions,
                            candidates=d.candidates)
    assert small.n_tests <= 2 * d.n_conditions and small.repeats == 2
    assert any("`max_tests=" in s for s in small.limits_hit)


# ------------------------------------------------------------------ the command
def test_cli_json_keys_and_files(tmp_path, capsys):
    out, sheet, png = tmp_path / "plan.toml", tmp_path / "order.xlsx", tmp_path / "coverage.png"
    code = main(["design", "--amplitude-deg", "0.5:2", "--frequency-hz", "25:45", "--preloads-nm", "0,500",
                 "--repeats", "2", "--out", str(out), "--sheet", str(sheet), "--plot", str(png), "--json"])
    assert code == 0
    doc = json.loads(capsys.readouterr().out)
    for key in ("tests", "conditions", "target_covered_fraction", "unreachable", "double_impacts_predicted",
                "limits_hit", "plan_file"):
        assert key in doc
    assert doc["tests"] == 2 * len(doc["conditions"]) and doc["double_impacts_predicted"] == 0
    assert out.exists()
    assert_drawn(png)
    assert len(pd.read_excel(sheet)) == doc["tests"]


@pytest.mark.parametrize("args, words", [
    (["--amplitude-deg", "0.3:3", "--frequency-hz", "100:200"], "lies outside what rig rapp2022 reaches"),
    (["--amplitude-deg", "3:0.3", "--frequency-hz", "22:50"], "--amplitude-deg"),
    (["--amplitude-deg", "a:b", "--frequency-hz", "22:50"], "--amplitude-deg"),
    (["--amplitude-deg", "0.3:3", "--frequency-hz", "22:50", "--preloads-nm", "5000"], "--preloads-nm"),
    (["--amplitude-deg", "0.3:3", "--frequency-hz", "22:50", "--repeats", "2", "--uncertainty-pct", "1"],
     "not both"),
])
def test_impossible_or_malformed_targets_are_one_line_errors(tmp_path, capsys, args, words):
    code = main(["design", *args, "--out", str(tmp_path / "p.toml")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and words in err and "\n" not in err and "Traceback" not in err
    assert not (tmp_path / "p.toml").exists()


# ------------------------------------------------------------------ design for identification
def test_d_optimal_exchange_finds_the_best_multiset_of_small_problems():
    """Against brute force over every multiset of n drops: the optimum on almost every random
    problem (exchange can stop in a local optimum) and never far below it."""
    import itertools

    exact, worst = 0, 0.0
    for seed in range(120):
        rng = np.random.default_rng(seed)
        t, p = int(rng.integers(3, 7)), int(rng.integers(1, 4))
        n = int(rng.integers(p, p + 3))
        a = rng.normal(size=(t, p, 2))
        info = np.einsum("tik,tjk->tij", a, a)
        got = _log_det(info[d_optimal(info, n)].sum(axis=0))
        best = max(_log_det(info[list(c)].sum(axis=0)) for c in itertools.combinations_with_replacement(range(t), n))
        assert got <= best + 1e-9
        exact += got >= best - 1e-9
        worst = min(worst, got - best)
    assert exact >= 0.98 * 120 and worst > math.log(0.8)


def test_design_for_identification_writes_a_plan_with_predicted_errors(tmp_path, capsys):
    out = tmp_path / "ident.toml"
    code = main(["design", "--for-identification", "template", "--max-tests", "8", "--out", str(out), "--json"])
    assert code == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["tests"] == 8 and doc["family"] == "template"
    errs = doc["predicted_stderr"]
    assert errs and all(0 < v["relative_stderr"] < 1 for v in errs.values())
    doe = load_doe(out)
    doe.check(load_rig("rapp2022"))
    assert doe.n_tests == 8


@pytest.mark.slow
def test_uncertainty_target_sets_the_repeats_from_a_pilot(designed):
    """The pilot runs one virtual test per condition through the data path; a tighter target
    asks for more repeats, as the 1/sqrt(n) law says."""
    from droptower.design.repeats import pilot_uncertainty

    rig, coupling, d = designed
    small = design_campaign(rig, coupling, Target((0.5, 1.0), (28.0, 45.0)), repeats=1, candidates=d.candidates)
    rel = pilot_uncertainty(small, "rapp2022", "rapp2022_nr60")
    assert len(rel) == small.n_conditions
    assert rel[["stiffness_relative_std", "damping_ratio_relative_std"]].gt(0).all().all()
    loose, tight = repeats_for(rel, 2.0), repeats_for(rel, 0.2)
    assert 1 <= loose <= tight
    worst = rel[["stiffness_relative_std", "damping_ratio_relative_std"]].to_numpy().max()
    assert worst / math.sqrt(tight) <= 0.002 or tight == 50


def test_the_inputs_share_does_not_average_out_and_can_make_the_target_unreachable():
    """u_mean² = u_1²/n + (u_J/J)²: J's share stays with repeats (one J serves every repeat)."""
    from droptower.design.repeats import repeats_advice
    from droptower.rig.uncertainty import override_uncertainty

    rel = pd.DataFrame({"inertia_kgm2": [0.359, 0.5233], "stiffness_relative_std": [0.02, 0.01],
                        "damping_ratio_relative_std": [0.01, 0.01]})
    u_j = override_uncertainty(None, ["inertia_kgm2@0.359=0.001795"])  # 0.5 %
    plain, with_j = repeats_advice(rel, 1.0), repeats_advice(rel, 1.0, u_j)
    assert plain.repeats == 4 and plain.reachable
    n = with_j.repeats  # the least n with 0.02²/n + 0.005² <= 0.01²
    assert with_j.reachable and 0.02 ** 2 / n + 0.005 ** 2 <= 0.01 ** 2 < 0.02 ** 2 / (n - 1) + 0.005 ** 2
    blocked = repeats_advice(rel, 0.4, u_j)  # J alone is 0.5 % > 0.4 %
    assert not blocked.reachable and "inertia_kgm2@0.359" in blocked.limit and "no number of repeats" in blocked.limit
    assert blocked.repeats == 16  # where the fit's share 2 %/sqrt(n) falls below J's 0.5 %
