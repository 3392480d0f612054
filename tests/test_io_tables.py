"""``droptower.io.tables``: one table writer, the format chosen by the file's suffix, unknown
suffixes refused on one line; and the commands that write tables use it."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import tomli_w

from droptower.cli.main import main
from droptower.errors import DroptowerError
from droptower.io.tables import TABLE_SUFFIXES, check_table_path, write_table
from droptower.maps import MapFit
from tests.test_maps import synthetic_table

#: the same tests' map fitted once per process by this module's commands and calls (tests/conftest.py)
pytestmark = pytest.mark.usefixtures("shared_map_fits")

TABLE = pd.DataFrame({
    "case": [1, 2, 3],
    "stiffness_nm_per_deg": [812.5, 1e-5, math.nan],      # 1e-5: pandas' to_json would print 0.0
    "double_impact": pd.array([True, False, None], dtype="boolean"),
    "flags": [["poor_fit", "clipping"], [], ["double_impact"]],
    "file": ["a.bin", "b.bin", None],
})


def read_back(path: Path) -> pd.DataFrame:
    suffix = path.suffix
    if suffix == ".csv":
        return pd.read_csv(path)
    if suffix == ".parquet":
        return pd.read_parquet(path)
    if suffix == ".json":
        return pd.DataFrame(json.loads(path.read_text()))
    return pd.read_excel(path, engine="openpyxl")


@pytest.mark.parametrize("suffix", TABLE_SUFFIXES)
def test_every_format_round_trips_values_missing_values_and_lists(tmp_path: Path, suffix: str) -> None:
    path = write_table(TABLE, tmp_path / "sub" / f"t{suffix}")  # the folder is created
    back = read_back(path)
    assert list(back.columns) == list(TABLE.columns)
    assert back["case"].tolist() == [1, 2, 3]
    assert back["stiffness_nm_per_deg"].iloc[0] == 812.5 and back["stiffness_nm_per_deg"].iloc[1] == 1e-5
    assert pd.isna(back["stiffness_nm_per_deg"].iloc[2]) and pd.isna(back["file"].iloc[2])
    assert bool(back["double_impact"].iloc[0]) is True and pd.isna(back["double_impact"].iloc[2])
    assert back["flags"].iloc[0] == "poor_fit;clipping"
    assert not list(tmp_path.glob("sub/.*"))  # no temporary file left


def test_format_is_the_suffix_not_a_default(tmp_path: Path) -> None:
    write_table(TABLE, tmp_path / "t.xlsx")
    write_table(TABLE, tmp_path / "t.JSON")  # case-insensitive
    assert (tmp_path / "t.xlsx").read_bytes()[:2] == b"PK"  # a zip (Office Open XML), not CSV text
    assert json.loads((tmp_path / "t.JSON").read_text())[2]["stiffness_nm_per_deg"] is None


def test_mixed_text_and_numbers_become_text(tmp_path: Path) -> None:
    table = pd.DataFrame({"meta_operator": ["anna", 7, None]})
    back = pd.read_parquet(write_table(table, tmp_path / "t.parquet"))
    assert back["meta_operator"].tolist()[:2] == ["anna", "7"] and pd.isna(back["meta_operator"].iloc[2])


@pytest.mark.parametrize("name", ["plan.txt", "plan", "plan.xls"])
def test_unknown_suffix_is_refused_naming_file_and_formats(tmp_path: Path, name: str) -> None:
    with pytest.raises(DroptowerError) as err:
        write_table(TABLE, tmp_path / name, "--out")
    message = err.value.message
    assert name in message and "--out" in message and ".csv, .parquet, .json, .xlsx" in message
    assert not (tmp_path / name).exists()
    assert check_table_path(tmp_path / "a.Parquet") == tmp_path / "a.Parquet"


def test_unwritable_target_is_one_line(tmp_path: Path) -> None:
    (tmp_path / "t.csv").mkdir()  # a folder where the file should go
    with pytest.raises(DroptowerError) as err:
        write_table(TABLE, tmp_path / "t.csv")
    assert "t.csv: cannot write" in err.value.message and "\n" not in err.value.message


# ---- the commands ------------------------------------------------------------------------------
LINEAR = {"name": "linear14k", "element": [{"kind": "spring", "stiffness": 14000.0},
                                           {"kind": "dashpot", "damping": 15.55}]}
DOE = {"name": "tiny", "group": [{"inertias_kgm2": [0.359], "drop_masses_kg": [2.0], "drop_heights_m": [0.5],
                                  "preloads_nm": [0.0], "repeats": 1}]}


def test_plan_out_xlsx_is_excel_and_unknown_suffix_exit_2(tmp_path: Path, capsys) -> None:
    coupling = tmp_path / "linear.toml"
    coupling.write_text(tomli_w.dumps(LINEAR))
    out = tmp_path / "plan.xlsx"
    assert main(["plan", "--coupling", str(coupling), "--out", str(out)]) == 0, capsys.readouterr().err
    sheet = pd.read_excel(out, engine="openpyxl")
    assert len(sheet) > 1 and {"case", "amplitude_deg", "first_period_frequency_hz"} <= set(sheet.columns)
    capsys.readouterr()
    assert main(["plan", "--coupling", str(coupling), "--out", str(tmp_path / "plan.txt")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "plan.txt" in err and "unknown table format" in err


def test_map_out_csv_is_the_coefficient_table_and_json_the_map(tmp_path: Path, capsys) -> None:
    results = tmp_path / "results.csv"
    synthetic_table(0.0).to_csv(results, index=False)
    assert main(["map", str(results), "--out", str(tmp_path / "map.csv")]) == 0
    assert main(["map", str(results), "--out", str(tmp_path / "map.json")]) == 0
    table = pd.read_csv(tmp_path / "map.csv")
    fit = MapFit.from_json(tmp_path / "map.json")
    assert table["coefficient"].tolist() == [f"k{i}" for i in range(1, 14)]
    np.testing.assert_allclose(table["value"], [fit.coefficients[f"k{i}"] for i in range(1, 14)], rtol=1e-12)
    assert table.loc[0, "unit"] == "N*m/deg" and table.loc[0, "equation"] == "Rapp et al. 2022, eq. 19"
    capsys.readouterr()
    assert main(["map", str(results), "--out", str(tmp_path / "map.yaml")]) == 2
    assert "unknown table format" in capsys.readouterr().err
