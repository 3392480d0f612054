"""One name per quantity: what ``simulate`` reports of a test and what ``extract`` reads from
that test's log agree on every key the two share, and the impact (lever rate, energy) does not
depend on the fit window; the window-dependent start rate of the fitted decay has its own name."""
from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from droptower.cli.main import main

#: keys whose values are not physical quantities of the test (bookkeeping)
BOOKKEEPING = {"warnings", "contact_times_s", "flags", "file", "source", "rig", "coupling", "log"}


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]):
    assert main(argv) == 0, capsys.readouterr().err
    return json.loads(capsys.readouterr().out)


@pytest.fixture(scope="module")
def simulated(tmp_path_factory) -> tuple[dict, Path]:
    """One drop test with a later contact (so a second-impact time exists on both sides)."""
    from droptower.cli.simulate_cmd import json_safe
    from droptower.rig.config import load_rig
    from droptower.rheology import load_coupling
    from droptower.rig.simulate import DropTest, simulate

    log = tmp_path_factory.mktemp("one_name") / "test.parquet"
    result = simulate(load_rig("rapp2022"), load_coupling("rapp2022_nr60"), [DropTest(0.359, 2.0, 1.0, 500.0, 0, 0)],
                      0.25)[0]
    result.write_log(log)
    return json_safe(result.to_dict()), log


def _agree(key: str, a, b, sample_s: float) -> bool:
    if isinstance(a, bool) or not isinstance(a, (int, float)):
        return a == b
    if key.endswith("_after_s"):  # times between contacts: the pulses' onsets, within samples
        return abs(a - b) <= 3 * sample_s
    return math.isclose(a, b, rel_tol=2e-3, abs_tol=1e-12)


@pytest.mark.parametrize("window", ["first-cycle", "2-cycles"])
def test_simulate_and_extract_agree_on_every_shared_key(simulated, window: str, capsys) -> None:
    summary, log = simulated
    row = _run(["extract", str(log), "--window", window, "--json"], capsys)[0]
    shared = (set(summary) & set(row)) - BOOKKEEPING
    # the quantities both report, under one name each
    assert {"impact_energy_j", "lever_rate_after_rad_per_s", "impact_impulse_n_s", "impact_time_s",
            "second_impact_after_s", "double_impact", "inertia_kgm2"} <= shared
    sample_s = 1.0 / row["sample_rate_hz"]
    differ = {k: (summary[k], row[k]) for k in sorted(shared) if not _agree(k, summary[k], row[k], sample_s)}
    assert differ == {}
    assert row["lever_rate_after_from"] == "impact_force"
    assert not any(k.startswith("log_") for k in row), "extract contradicts the log's metadata"


def test_impact_energy_does_not_depend_on_the_window_and_the_fit_rate_has_its_own_name(simulated, capsys) -> None:
    _, log = simulated
    rows = [_run(["extract", str(log), "--window", w, "--json"], capsys)[0] for w in ("first-cycle", "2-cycles", "0.1")]
    assert len({r["impact_energy_j"] for r in rows}) == 1
    assert len({r["lever_rate_after_rad_per_s"] for r in rows}) == 1
    # the fitted decay's start rate moves with the window (a nonlinear coupling): its own name
    fit_rates = [r["decay_fit_initial_rate_rad_per_s"] for r in rows]
    assert max(fit_rates) / min(fit_rates) - 1 > 1e-3


def test_without_a_force_channel_the_impact_law_gives_the_impact(simulated, capsys) -> None:
    summary, log = simulated
    row = _run(["extract", str(log), "--channel", "impact_force=-", "--json"], capsys)[0]
    assert row["lever_rate_after_from"] == "impact_law"
    # the impact law on the log's m1, h, k, L, J: the simulated rate within the rig's restitution tolerance
    assert row["lever_rate_after_rad_per_s"] == pytest.approx(summary["lever_rate_after_rad_per_s"], rel=2e-3)
    assert row["impact_energy_j"] == pytest.approx(summary["predicted_impact_energy_j"], rel=1e-9)
