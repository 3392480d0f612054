"""A lab's own folder through ``droptower extract``: per-file conditions (a German xlsx sheet,
or the file names), the lab's own rig (its geometry printed and stored with every row), and a
wrong rig flagged per drop. The folder is simulated (tests/labfolder.py), so the truth is known."""
from __future__ import annotations

import json
import shutil

import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings

from droptower.cli.main import main
from droptower.configs import preset_dir
from droptower.extract.geometry import FLAGS as GEOMETRY_FLAGS
from tests.labfolder import write_lab_folder
from tests.malformed_conditions import check_outcome, malformed_tables

PATTERN = "{fixture}_m{drop_mass_kg}_h{drop_height_mm}_rep{repeat}"


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    """Six drops: three fixtures x two masses at 40 mm (L1 and the 2 kg drops double-impact)."""
    return write_lab_folder(tmp_path_factory.mktemp("lab") / "lab", heights_mm=(40,), repeats=1)


def _extract(args, capsys, tmp_path, name="results.csv"):
    out = tmp_path / name
    code = main(["extract", *args, "--out", str(out)])
    err = capsys.readouterr().err
    table = pd.read_csv(out, keep_default_na=False, na_values=[""]) if out.exists() else None
    return code, err, table


def _geometry_flags(row) -> set[str]:
    return set(str(row["flags"]).split(";")) & set(GEOMETRY_FLAGS)


def test_conditions_sheet_and_rig(lab, capsys, tmp_path):
    """The xlsx sheet gives each file its fixture, inertia, mass, height and temperature; the rig
    its lever and laser radius; the geometry is printed once and stored; no geometry flag."""
    code, err, table = _extract([*map(str, lab.logs), "--rig", str(lab.rig), "--conditions", str(lab.sheet)],
                                capsys, tmp_path)
    assert code == 0, err
    geometry = [line for line in err.splitlines() if "geometry:" in line]
    assert geometry == [f"droptower: geometry: rig file {lab.rig}: lever length 0.25 m, laser radius 0.25 m, "
                        "fixtures 0.12, 0.25, 0.4 kg*m^2"]
    assert "shipped preset" not in err and "conditions table" not in err
    truth = lab.truth.set_index("file")
    assert len(table) == len(truth)
    for row in table.to_dict(orient="records"):
        want = truth.loc[row["file"].rsplit("/", 1)[-1]]
        assert row["fixture"] == want["fixture"]
        for key in ("inertia_kgm2", "drop_mass_kg", "drop_height_m"):
            assert row[key] == pytest.approx(want[key], rel=1e-12), key
        assert row["temperature_c"] == pytest.approx(want["temperature_c"], abs=0.005)  # the sheet's 0.01 degC
        assert (row["rig"], row["lever_length_m"], row["sensor_radius_m"]) == (str(lab.rig), 0.25, 0.25)
        assert row["double_impact"] == want["double_impact"]
        assert not _geometry_flags(row), row["flags"]


def test_conditions_from_names_and_named_fixtures(lab, capsys, tmp_path):
    """A rig written by `rig new` names the fixtures; the file names give fixture, mass, height
    and repeat; the stiffness is the sheet's run's to the last digit (same J, same signals)."""
    rig = tmp_path / "named.toml"
    assert main(["rig", "new", str(rig), "--lever-length-m", "0.25", "--laser-radius-m", "0.25", "--fixture", "L1=0.12",
                 "--fixture", "L2=0.25", "--fixture", "L3=0.40", "--drop-mass-kg", "1", "--drop-mass-kg", "2",
                 "--sample-rate-hz", "19200", "--drop-height-range-m", "0.005", "2"]) == 0
    code, err, by_name = _extract([*map(str, lab.logs), "--rig", str(rig), "--conditions-from-names", PATTERN],
                                  capsys, tmp_path, "names.csv")
    assert code == 0, err
    code, err, by_sheet = _extract([*map(str, lab.logs), "--rig", str(lab.rig), "--conditions", str(lab.sheet)],
                                   capsys, tmp_path, "sheet.csv")
    assert list(by_name["fixture"]) == list(by_sheet["fixture"]) == list(lab.truth["fixture"])
    assert list(by_name["repeat"]) == [1] * len(lab.logs)
    pd.testing.assert_series_equal(by_name["stiffness_nm_per_rad"], by_sheet["stiffness_nm_per_rad"])
    # without conditions the rig's named fixture follows from a given inertia
    code, err, table = _extract([str(lab.logs[2]), "--rig", str(rig), "--inertia-kgm2", "0.25"], capsys, tmp_path)
    assert code == 0 and table.loc[0, "fixture"] == "L2"


def test_preset_rig_on_lab_logs_is_flagged(lab, capsys, tmp_path):
    """The issue's case: the shipped preset (0.2 m lever, laser at 0.15 m) on logs of a 0.25 m lever
    and a laser at 0.25 m. A warning names the preset and its geometry; every drop whose decay
    can judge the geometry (no double impact) carries all three geometry flags."""
    code, err, table = _extract([*map(str, lab.logs), "--rig", "rapp2022", "--conditions", str(lab.sheet)],
                                capsys, tmp_path)
    assert code == 0
    (warning,) = [line for line in err.splitlines() if "warning:" in line and "preset" in line]
    assert "--rig rapp2022 is a shipped preset" in warning and "lever length 0.2 m, laser radius 0.15 m" in warning
    judged = table[~table["double_impact"]]
    assert len(judged) == 2  # L2 and L3 with the 1 kg mass
    for row in judged.to_dict(orient="records"):
        assert _geometry_flags(row) == set(GEOMETRY_FLAGS), row["flags"]
        assert row["stiffness_m2_m1_deviation_pct"] == pytest.approx(-40, abs=2)  # the laser's 0.15/0.25
        assert row["amplitude_laser_torque_deviation_pct"] == pytest.approx(66.7, abs=3)
    # the docs' old example, --inertia-kgm2 0.25 for every log: still flagged (the L3 drop by its energy)
    code, err, table = _extract([*map(str, lab.logs), "--rig", "rapp2022", "--inertia-kgm2", "0.25"], capsys, tmp_path)
    assert all(_geometry_flags(row) for row in table[~table["double_impact"]].to_dict(orient="records"))


def test_several_fixtures_and_no_inertia_says_what_is_missing(lab, capsys):
    """--rig was given: the message says the rig has three fixtures and what would say which,
    never to give --rig."""
    assert main(["extract", str(lab.logs[0]), "--rig", str(lab.rig)]) == 2
    err = capsys.readouterr().err
    assert "rig " + str(lab.rig) + " has 3 fixtures (0.12, 0.25, 0.4 kg*m^2)" in err
    assert "--conditions" in err and "--inertia-kgm2" in err and "give --rig" not in err and "or --rig" not in err
    assert "`" not in err  # flags, not Python names


def test_drop_conditions_read_by_suffix(lab, capsys, tmp_path):
    """The issue's failure: the xlsx sheet given to --drop-conditions was a UTF-8 decode error;
    now it is read, and a table keyed by file is pointed at --conditions. An xlsx keyed by
    drop_index works."""
    assert main(["extract", str(lab.logs[0]), "--rig", str(lab.rig), "--drop-conditions", str(lab.sheet)]) == 2
    err = capsys.readouterr().err
    assert "codec" not in err and "per-file conditions table, give it as --conditions" in err
    drops = tmp_path / "drops.xlsx"
    pd.DataFrame({"drop_index": [1], "inertia_kgm2": [0.12], "Fallhoehe [mm]": [40.0]}).to_excel(drops, index=False)
    assert main(["extract", str(lab.logs[0]), "--rig", str(lab.rig), "--drop-conditions", str(drops), "--json"]) == 0
    (row,) = json.loads(capsys.readouterr().out)
    assert row["inertia_kgm2"] == 0.12


@pytest.fixture(scope="module")
def small(lab, tmp_path_factory):
    """Three logs (one per fixture, the 1 kg mass) for the malformed tables."""
    folder = tmp_path_factory.mktemp("small")
    chosen = [p for p in lab.logs if "_m1_" in p.name]
    logs = [shutil.copy(p, folder / p.name) for p in chosen]
    truth = lab.truth[lab.truth["file"].isin([p.name for p in chosen])].reset_index(drop=True)
    return folder, [str(p) for p in logs], truth


@settings(max_examples=30, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=__import__("hypothesis").strategies.data())
def test_malformed_conditions_tables(small, lab, data, capsys, tmp_path):
    """Missing files, extra rows, duplicates, rows without a file, words for numbers, unknown
    units, empty tables, as CSV or xlsx: one line per problem, exit 2 or a per-file failure,
    never a traceback, every other file written."""
    folder, logs, truth = small
    case = data.draw(malformed_tables(folder, truth))
    out = tmp_path / "results.csv"
    out.unlink(missing_ok=True)  # one tmp_path for every example
    code = main(["extract", *logs, "--rig", str(lab.rig), "--conditions", str(case.table), "--out", str(out)])
    err = capsys.readouterr().err
    evaluated = {p.rsplit("/", 1)[-1] for p in pd.read_csv(out)["file"]} if out.exists() else set()
    check_outcome(case, code, err, evaluated)


@pytest.mark.slow
def test_full_lab_folder_and_table2_campaign_no_false_flags(lab_extracted, lab_extracted_preset, tmp_path, capsys):
    """Calibration of the geometry flags: the 54-file lab folder with its own rig and the logs of
    every Table-2 condition (3 cases x 10 heights x 3 preloads, the campaign's rapp2022 rig) raise
    none; the same folder with the preset rig flags every drop it can judge (the 18 without a
    double impact). The folder is ``write_lab_folder``'s default, extracted with either rig once
    per process (tests/conftest.py: ``extract LOGS --conditions SHEET --rig RIG --out TABLE``, read
    by test_lab_folder_e2e.py too). The flags judge a drop's geometry (its M2/M1 deviation, laser
    amplitude against torque, impact energy) against the rig's, which a condition's five repeats
    share: one drop per condition, 90 rather than the plan's 450, covers every condition."""
    (step, out), (wrong_step, wrong_out) = lab_extracted, lab_extracted_preset
    assert step.code == 0 and wrong_step.code == 0, step.err + wrong_step.err
    right = pd.read_csv(out, keep_default_na=False, na_values=[""])
    assert len(right) == 54
    assert not any(_geometry_flags(row) for row in right.to_dict(orient="records"))
    wrong = pd.read_csv(wrong_out, keep_default_na=False, na_values=[""])
    judged = wrong[~wrong["double_impact"]]
    assert len(judged) == 18 and all(_geometry_flags(row) == set(GEOMETRY_FLAGS)
                                     for row in judged.to_dict(orient="records"))
    table2 = (preset_dir("doe") / "rapp2022_table2.toml").read_text(encoding="utf-8")
    assert "\nrepeats = 5\n" in table2
    (tmp_path / "table2_once.toml").write_text(table2.replace("\nrepeats = 5\n", "\nrepeats = 1\n", 1), encoding="utf-8")
    assert main(["campaign", "--doe", str(tmp_path / "table2_once.toml"), "--out", str(tmp_path / "t2"), "--workers", "1",
                 "-q"]) == 0
    results = pd.read_csv(tmp_path / "t2" / "results.csv", keep_default_na=False)
    assert len(results) == 90 and len(results.groupby(["inertia_kgm2", "drop_height_m", "preload_nm"])) == 90
    assert not any(set(flags.split(";")) & set(GEOMETRY_FLAGS) for flags in results["flags"])


def test_one_row_for_two_logs_fails_both(lab, capsys, tmp_path):
    """Two days' logs of the same name under a sheet keyed by name: which row means which is
    not known, so both fail (and say how to key the sheet); the third log is written."""
    logs = []
    for day in ("day1", "day2"):
        (tmp_path / day).mkdir()
        logs.append(shutil.copy(lab.logs[2], tmp_path / day / lab.logs[2].name))
    code, err, table = _extract([*map(str, logs), str(lab.logs[4]), "--rig", str(lab.rig), "--conditions",
                                 str(lab.sheet)], capsys, tmp_path)
    assert code == 2 and list(table["file"]) == [str(lab.logs[4])]
    assert err.count("key the table by the path relative to the folder") == 4  # two error lines, two in the list


def test_a_fixture_that_drops_out_is_named(lab, capsys, tmp_path):
    """Every drop of L1 double-impacts (J/L^2 = 1.92 kg against the drop masses), and so does each
    2 kg drop of L2 and L3: one warning per group none of whose drops is usable (as map names
    them), with the equivalent mass and the drop mass that would avoid it; the usable groups get none."""
    code, err, table = _extract([*map(str, lab.logs), "--rig", str(lab.rig), "--conditions", str(lab.sheet)],
                                capsys, tmp_path)
    warned = [line for line in err.splitlines() if "warning:" in line]
    assert len(warned) == 3
    (l1,) = [line for line in warned if "fixture L1" in line]
    assert l1.startswith("droptower: warning: fixture L1 (J = 0.12 kg*m^2): all 2 test(s) left out") and \
        "J/L^2 = 1.92 kg" in l1 and "none of the rig's drop masses would" in l1
    for fixture in ("L2", "L3"):
        (line,) = [line for line in warned if f"fixture {fixture}" in line]
        assert "drop mass 2 kg: all 1 test(s)" in line and "of the rig's drop masses, 1 kg would" in line
