"""Per-file conditions (droptower.io.conditions): a lab's sheet in any dialect or its file names,
read into SI by name and unit; bad rows fail their own file only; the rig's named fixtures."""
from __future__ import annotations

import math

import pandas as pd
import pytest

from droptower.errors import DroptowerError
from droptower.io.conditions import CONDITION_KEYS, Conditions, conditions_from_names, read_conditions
from droptower.io.logsettings import LogSettings
from droptower.rig.config import load_rig
from tests.labfolder import GERMAN, IMPERIAL, LAB_RIG_TOML, _write_sheet

TRUTH = pd.DataFrame({"file": ["L1_m1_h20_rep1.csv", "L2_m2_h40_rep2.csv", "L3_m2_h80_rep3.csv"],
                      "fixture": ["L1", "L2", "L3"], "inertia_kgm2": [0.12, 0.25, 0.40],
                      "drop_mass_kg": [1.0, 2.0, 2.0], "drop_height_m": [0.02, 0.04, 0.08],
                      "temperature_c": [22.6, 23.0, 23.4]})


def _check(conditions: Conditions, rel: float = 1e-12) -> None:
    for row in TRUTH.itertuples(index=False):
        got = conditions.for_path(f"some/folder/{row.file}")
        assert set(got) <= set(CONDITION_KEYS)
        assert got["fixture"] == row.fixture
        for key in ("inertia_kgm2", "drop_mass_kg", "drop_height_m", "temperature_c"):
            assert got[key] == pytest.approx(getattr(row, key), rel=rel), key


@pytest.mark.parametrize("suffix", [".xlsx", ".csv", ".parquet"])
@pytest.mark.parametrize("dialect", [GERMAN, IMPERIAL], ids=lambda d: d.name)
def test_sheet_in_a_labs_dialect(tmp_path, dialect, suffix):
    """German names (Datei, Hebel, Traegheit [kg m^2], Fallhoehe [mm], Temperatur [degC]) with ';' and
    decimal commas, or English ones in inches, pounds and degF: the same SI conditions (the sheet
    rounds temperatures to 0.01 of its unit, so 0.006 degC after a degF conversion)."""
    sheet = tmp_path / f"conditions{suffix}"
    _write_sheet(sheet, dialect, TRUTH)
    conditions = read_conditions(sheet)
    assert conditions.problems == () and conditions.source == str(sheet)
    _check(conditions, rel=3e-4 if dialect is IMPERIAL else 1e-12)


def test_mapping_overrides_names_and_units(tmp_path):
    """``ROLE=COLUMN[:UNIT]`` names columns no common name finds, with a unit the sheet lacks."""
    sheet = tmp_path / "c.csv"
    pd.DataFrame({"Messung": TRUTH["file"], "J": TRUTH["inertia_kgm2"] * 1e4, "Gewicht": TRUTH["drop_mass_kg"] * 1e3,
                  "Hub": TRUTH["drop_height_m"] * 100, "Hebel": TRUTH["fixture"], "T": TRUTH["temperature_c"]}
                 ).to_csv(sheet, index=False)
    conditions = read_conditions(sheet, columns={"inertia_kgm2": "J:kg*cm^2", "drop_mass_kg": "Gewicht:g",
                                                 "drop_height_m": "Hub:cm", "temperature_c": "T:degC"})
    _check(conditions, rel=1e-12)


def test_keyed_by_relative_path_and_stem(tmp_path):
    """Keys may be paths relative to the folder (the longest key that ends the path wins) or stems."""
    sheet = tmp_path / "c.csv"
    pd.DataFrame({"file": ["a/x.csv", "b/x.csv", "y"], "drop_height_m": [0.1, 0.2, 0.3]}).to_csv(sheet, index=False)
    conditions = read_conditions(sheet)
    assert conditions.for_path(tmp_path / "a" / "x.csv")["drop_height_m"] == 0.1
    assert conditions.for_path("b/x.csv")["drop_height_m"] == 0.2
    assert conditions.for_path("folder/y.csv")["drop_height_m"] == 0.3
    with pytest.raises(DroptowerError, match=r"z\.csv: not in the conditions table .*c\.csv"):
        conditions.for_path("folder/z.csv")
    assert conditions.unmatched(["a/x.csv", "q/y.csv"]) == ["b/x.csv"]


def test_bad_rows_fail_their_own_files(tmp_path):
    """No file name, a file twice, a word for a number, a negative mass: one problem line each;
    those files raise, the others are read."""
    sheet = tmp_path / "c.xlsx"
    pd.DataFrame({"Datei": ["a.csv", None, "b.csv", "b.csv", "c.csv", "d.csv", "e.csv"],
                  "Fallmasse [kg]": [1.0, 2.0, 1.0, 1.0, "heavy", -1.0, 2.0]}).to_excel(sheet, index=False)
    conditions = read_conditions(sheet)
    assert len(conditions.problems) == 4
    assert "row 2: no file name" in conditions.problems[0]
    assert "'b.csv' listed twice (rows 3 and 4)" in conditions.problems[1]
    assert "drop_mass_kg 'heavy' is not a number" in conditions.problems[2]
    assert "drop_mass_kg -1 must be > 0" in conditions.problems[3]
    for name in ("b.csv", "c.csv", "d.csv"):
        with pytest.raises(DroptowerError, match=rf"{name}: conditions table .*c\.xlsx"):
            conditions.for_path(name)
    assert conditions.for_path("a.csv") == {"drop_mass_kg": 1.0}
    assert conditions.for_path("e.csv") == {"drop_mass_kg": 2.0}


@pytest.mark.parametrize(("frame", "message"), [
    (pd.DataFrame({"file": [], "drop_mass_kg": []}), "empty conditions table"),
    (pd.DataFrame({"name": ["a.csv"], "drop_mass_kg": [1.0]}), r"no file column .*`columns=\{'file': 'COLUMN'\}`"),
    (pd.DataFrame({"file": ["a.csv"], "comment": ["ok"]}), "no condition column"),
    (pd.DataFrame({"file": ["a.csv"], "Fallhoehe [blorps]": [1.0]}), "unknown unit"),
    (pd.DataFrame({"file": ["a.csv"], "Fallhoehe [kg]": [1.0]}), "not a unit of drop_height_m"),
])
@pytest.mark.parametrize("suffix", [".csv", ".xlsx"])
def test_table_problems_are_one_line(tmp_path, frame, message, suffix):
    sheet = tmp_path / f"c{suffix}"
    frame.to_csv(sheet, index=False) if suffix == ".csv" else frame.to_excel(sheet, index=False)
    with pytest.raises(DroptowerError, match=message) as info:
        read_conditions(sheet)
    assert str(sheet) in str(info.value) and "\n" not in str(info.value)


def test_xlsx_is_read_by_its_suffix(tmp_path):
    """The issue's failure: an xlsx read as text gave a UTF-8 decode error."""
    sheet = tmp_path / "conditions.xlsx"
    _write_sheet(sheet, GERMAN, TRUTH)
    assert read_conditions(sheet).for_path("L2_m2_h40_rep2.csv")["drop_mass_kg"] == 2.0


def test_names_pattern():
    conditions = conditions_from_names("{fixture}_m{drop_mass_kg}_h{drop_height_mm}_rep{repeat}")
    assert conditions.for_path("lab/L2_m1_h40_rep3.csv") == {"fixture": "L2", "drop_mass_kg": 1.0,
                                                              "drop_height_m": pytest.approx(0.04), "repeat": 3}
    assert conditions_from_names("T{temperature_c:degF}_h{drop_height_m:in}").for_path("T77_h1p5.csv") == {
        "temperature_c": pytest.approx(25.0), "drop_height_m": pytest.approx(0.0381)}
    with pytest.raises(DroptowerError, match="does not match the conditions pattern"):
        conditions.for_path("other.csv")
    with pytest.raises(DroptowerError, match="unknown field"):
        conditions_from_names("{lever}_{drop_height_mm}")


def _rig(tmp_path, fixtures: str = "") -> object:
    text = LAB_RIG_TOML
    if fixtures:
        text = text.replace("inertias_kgm2 = [0.12, 0.25, 0.40]\n", "").replace("[sensors]\n", f"{fixtures}\n[sensors]\n")
    path = tmp_path / "rig.toml"
    path.write_text(text)
    return load_rig(path)


def test_rig_fixtures_name_inertias(tmp_path):
    """A rig file may give [fixtures] instead of inertias_kgm2; a sheet naming only the fixture
    gets its inertia, a sheet whose inertia disagrees with the named fixture fails that file."""
    rig = _rig(tmp_path, "[fixtures]\nL1 = 0.12\nL2 = 0.25\nL3 = 0.40\n")
    assert rig.inertias_kgm2 == [0.12, 0.25, 0.40]
    assert rig.fixture_inertia_kgm2("L2") == 0.25 and rig.fixture_name(0.2501) == "L2"
    assert rig.fixture_name(0.3) is None
    with pytest.raises(DroptowerError, match="no fixture 'L9'"):
        rig.fixture_inertia_kgm2("L9")
    sheet = tmp_path / "c.csv"
    pd.DataFrame({"file": ["a.csv", "b.csv", "c.csv"], "lever": ["L3", "L2", "L7"],
                  "inertia": [None, 0.3, None]}).to_csv(sheet, index=False)
    conditions = read_conditions(sheet, rig=rig)
    assert conditions.for_path("a.csv") == {"fixture": "L3", "inertia_kgm2": 0.40}
    assert len(conditions.problems) == 2
    with pytest.raises(DroptowerError, match="disagrees with fixture 'L2'"):
        conditions.for_path("b.csv")
    with pytest.raises(DroptowerError, match="not one of the fixtures"):
        conditions.for_path("c.csv")
    assert conditions_from_names("{fixture}_h{drop_height_mm}", rig=rig).for_path("L1_h20.csv")["inertia_kgm2"] == 0.12


def test_rig_fixture_must_be_listed(tmp_path):
    """Both given: every fixture must be one of the inertias (named in a one-line error)."""
    path = tmp_path / "both.toml"
    path.write_text(LAB_RIG_TOML.replace("[sensors]\n", "[fixtures]\nL9 = 0.9\n[sensors]\n"))
    with pytest.raises(DroptowerError, match="not one of inertias_kgm2"):
        load_rig(path)


def test_logsettings_merge_conditions_over_metadata(tmp_path):
    """read_signals merges a file's conditions over the log's metadata (the replaced value kept
    as log_<key>); a file the table lacks raises naming it."""
    from droptower.extract.synthetic import SyntheticDrop

    drop = SyntheticDrop(seed=1)
    log = drop.write(tmp_path / "drop.csv")
    sheet = tmp_path / "c.csv"
    pd.DataFrame({"file": ["drop.csv"], "inertia": [0.5], "temperature": [40.0]}).to_csv(sheet, index=False)
    signals = LogSettings(conditions=read_conditions(sheet)).read_signals(log)
    assert signals.metadata["inertia_kgm2"] == 0.5 and signals.metadata["temperature_c"] == 40.0
    assert math.isclose(signals.metadata["log_inertia_kgm2"], drop.inertia_kgm2)
    other = drop.write(tmp_path / "other.csv")
    with pytest.raises(DroptowerError, match="other.csv: not in the conditions table"):
        LogSettings(conditions=read_conditions(sheet)).read_signals(other)


def test_one_row_for_two_logs_is_refused_for_both(tmp_path):
    sheet = tmp_path / "c.csv"
    pd.DataFrame({"file": ["L2.csv", "day1/L3.csv", "day2/L3.csv"], "drop_height_m": [0.1, 0.2, 0.3]}).to_csv(
        sheet, index=False)
    conditions = read_conditions(sheet)
    shared = conditions.shared_rows(["day1/L2.csv", "day2/L2.csv", "day1/L3.csv", "day2/L3.csv"])
    assert set(shared) == {"day1/L2.csv", "day2/L2.csv"}
    assert "row 'L2.csv' of the conditions table" in shared["day1/L2.csv"]
