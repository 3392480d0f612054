"""``droptower.io.table_reader``: servo results, results tables and measured maps read like logs
(delimiter, decimal comma, notes above the names, units in a row or in brackets, lab names,
a column mapping) and converted to the unit each column name carries."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from droptower.cli.main import main
from droptower.compare import read_servo_results
from droptower.compare.servo_points import SERVO_COLUMNS
from droptower.errors import DroptowerError
from droptower.io.table_reader import COMMON_ALIASES, parse_column_options, read_table
from droptower.io.tables import write_table
from droptower.maps import MapFit, read_results
from tests.test_maps import synthetic_table

#: the servo points every layout below holds (stiffness in N*m/deg)
SNAKE = pd.DataFrame({"amplitude_deg": [0.5, 1.5, 0.5], "frequency_hz": [10.0, 10.0, 30.0],
                      "storage_stiffness_nm_per_deg": [250.5, 200.25, 260.0], "loss_factor": [0.2, 0.25, 0.21]})
LAB = """Prüfstand: Servo 4
Datum: 2026-11-02
Amplitude [°];Frequenz [Hz];Speichersteifigkeit [Nm/°];Verlustfaktor [-]
0,5;10;250,5;0,2
1,5;10;200,25;0,25
0,5;30;260,0;0,21
"""


def test_lab_layout_reads_as_the_snake_case_table(tmp_path: Path) -> None:
    lab, snake = tmp_path / "lab.csv", tmp_path / "snake.csv"
    lab.write_text(LAB, encoding="cp1252")  # Windows lab software
    SNAKE.to_csv(snake, index=False)
    pd.testing.assert_frame_equal(read_servo_results(lab).table, read_servo_results(snake).table)


def test_units_row_and_conversion_to_the_named_unit(tmp_path: Path) -> None:
    path = tmp_path / "units.txt"
    rad = SNAKE["storage_stiffness_nm_per_deg"] * 180 / math.pi
    lines = ["Amplitude\tFrequency\tK'\teta", "rad\tHz\tN*m/rad\t-"] + [
        f"{math.radians(a)}\t{f}\t{k}\t{e}" for a, f, k, e in zip(SNAKE["amplitude_deg"], SNAKE["frequency_hz"], rad,
                                                                  SNAKE["loss_factor"])]
    path.write_text("\n".join(lines) + "\n")
    table = read_table(path, SERVO_COLUMNS)
    np.testing.assert_allclose(table["amplitude_deg"], SNAKE["amplitude_deg"], rtol=1e-12)
    np.testing.assert_allclose(table["storage_stiffness_nm_per_deg"], SNAKE["storage_stiffness_nm_per_deg"], rtol=1e-12)
    np.testing.assert_allclose(table["loss_factor"], SNAKE["loss_factor"], rtol=1e-12)


def test_column_mapping_with_unit_override_and_bracketed_parquet(tmp_path: Path) -> None:
    path = tmp_path / "odd.parquet"
    pd.DataFrame({"Amp": np.radians(SNAKE["amplitude_deg"]), "Freq [Hz]": SNAKE["frequency_hz"],
                  "Kprime [kN*m/deg]": SNAKE["storage_stiffness_nm_per_deg"] / 1e3,
                  "LF": SNAKE["loss_factor"]}).to_parquet(path)
    columns = parse_column_options(["amplitude_deg=Amp:rad", "loss_factor=LF",
                                    "storage_stiffness_nm_per_deg=Kprime"], "--servo-column")
    table = read_table(path, SERVO_COLUMNS, columns)
    for name in SNAKE.columns:
        np.testing.assert_allclose(table[name], SNAKE[name], rtol=1e-12)


def test_validate_cli_takes_the_lab_file_and_servo_column(tmp_path: Path, capsys) -> None:
    fit = MapFit.from_dict(json.loads(_map_json(tmp_path)))
    map_file = tmp_path / "map.json"
    fit.to_json(map_file)
    lab, snake = tmp_path / "lab.csv", tmp_path / "snake.csv"
    lab.write_text(LAB.replace("Verlustfaktor [-]", "LF"))
    SNAKE.to_csv(snake, index=False)
    assert main(["validate", "--map", str(map_file), "--servo-results", str(snake), "--json"]) == 0
    expected = json.loads(capsys.readouterr().out)
    assert main(["validate", "--map", str(map_file), "--servo-results", str(lab), "--servo-column",
                 "loss_factor=LF", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["points"] == expected["points"] and len(got["points"]) == 3
    out = tmp_path / "validation"
    assert main(["validate", "--map", str(map_file), "--servo-results", str(snake), "--out", str(out),
                 "--table-format", "xlsx", "--quiet"]) == 0
    sheet = pd.read_excel(out / "validation.xlsx", engine="openpyxl")
    assert len(sheet) == 3 and (out / "servo_results.xlsx").is_file() and not (out / "validation.csv").exists()
    assert main(["validate", "--map", str(map_file), "--servo-results", str(lab), "--servo-column", "eta=LF"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unknown column name(s) eta" in err


def _map_json(tmp_path: Path) -> str:
    results = tmp_path / "results.csv"
    synthetic_table(0.0).to_csv(results, index=False)
    from droptower.maps import fit_map

    return fit_map(read_results(results)).to_json()


@pytest.mark.parametrize("suffix", [".xlsx", ".json", ".csv"])
def test_results_tables_in_every_written_format_fit_the_same_map(tmp_path: Path, suffix: str) -> None:
    """What write_table writes, read_results reads: ';'-joined flags in a comma CSV included."""
    table = synthetic_table(0.0).assign(flags="short_window;poor_fit")
    table.loc[1:, "flags"] = ""
    path = write_table(table, tmp_path / f"results{suffix}")
    back = read_results(path)
    np.testing.assert_allclose(back["stiffness_nm_per_deg"], table["stiffness_nm_per_deg"], rtol=1e-12)
    assert back.loc[0, "flags"] == "short_window;poor_fit"


def test_bad_tables_are_one_line_errors(tmp_path: Path) -> None:
    path = tmp_path / "bad_unit.csv"
    path.write_text("Amplitude [furlong];Frequenz [Hz]\n1;2\n")
    with pytest.raises(DroptowerError) as err:
        read_table(path, COMMON_ALIASES)
    assert str(path) in err.value.message and "column 'Amplitude'" in err.value.message
    assert "furlong" in err.value.message
    path = tmp_path / "ragged.csv"
    path.write_text("a;b;c\n1;2\n3\n")
    with pytest.raises(DroptowerError, match="cannot find the columns"):
        read_table(path, COMMON_ALIASES)
    with pytest.raises(DroptowerError, match="expected NAME=SOURCE"):
        parse_column_options(["amplitude_deg"], "--servo-column")
