"""Test helper: a lab's own folder of drop-test logs, as a lab exports it (not as droptower writes
logs): one CSV per drop named by its conditions, the lab's dialect (header lines, separators,
decimal commas, its own channel names and units, the laser's displacement instead of an angle),
a conditions sheet keyed by file name and the lab's own rig file.

The drops are simulated on the virtual rig, so the truth is known: ``LabFolder.truth`` holds each
file's conditions in SI.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

#: the lab's rig: a 0.25 m lever, three fixtures, a laser at 0.25 m from the pivot, 19.2 kHz
LAB_RIG_TOML = """\
# The lab's own drop tower (a test rig, not a shipped preset)
name = "lab_tower"
description = "the lab's tower: 250 mm lever, three lever fixtures, 1 kg and 2 kg drop masses"
source = "the lab's own measurements"

lever_length_m = 0.25
inertias_kgm2 = [0.12, 0.25, 0.40]
drop_masses_kg = [1.0, 2.0]
drop_height_range_m = [0.005, 2.0]
preload_range_nm = [0.0, 500.0]
coupling_limit_deg = 28.0
restitution = 0.5

[sensors]
sample_rate_hz = 19200.0
pre_trigger_s = 0.005

[sensors.laser]
radius_m = 0.25
noise_m = 1.0e-6

[sensors.torque]
noise_nm = 2.0
range_nm = 10000.0

[sensors.impact_force]
contact_duration_s = 3.0e-4
noise_n = 5.0
range_n = 222000.0
"""

#: fixture name -> inertia (kg*m^2), drop-mass name -> mass (kg), heights in mm (the file names' units)
FIXTURES = {"L1": 0.12, "L2": 0.25, "L3": 0.40}
MASSES = {"m1": 1.0, "m2": 2.0}
HEIGHTS_MM = (20, 40, 80)
REPEATS = 3


@dataclass(frozen=True)
class Dialect:
    """How a lab's software writes a CSV: header lines above the names, separators, the names
    and units of its channels (time, laser displacement, torque, impact force), the conditions
    sheet's columns and the file names' pattern."""

    name: str
    delimiter: str
    decimal: str
    header: tuple[str, ...]
    columns: tuple[str, str, str, str]          # time, displacement, torque, force
    scale: tuple[float, float, float, float]    # SI value * scale = written value
    sheet_columns: dict[str, str] = field(default_factory=dict)   # role -> the sheet's column name
    height_scale: float = 1.0                   # drop height in m * height_scale = the sheet's value


#: the dialect of the lab in the issue that asked for this: German names, ';' and decimal commas
GERMAN = Dialect(
    "german", ";", ",",
    ("Messprogramm: Fallturm", "Datum: 28.11.2026", "Kanaele: 4", "Abtastrate: 19200 Hz", "Pruefer: -"),
    ("Zeit [s]", "Weg [mm]", "Moment [Nm]", "Kraft [kN]"), (1.0, 1e3, 1.0, 1e-3),
    {"file": "Datei", "fixture": "Hebel", "inertia": "Traegheit [kg m^2]", "mass": "Fallmasse [kg]",
     "height": "Fallhoehe [mm]", "temperature": "Temperatur [degC]"}, 1e3)

#: another lab: tab-separated, time in ms, displacement in inches, torque in kN*m, force in lbf
IMPERIAL = Dialect(
    "imperial", "\t", ".", ("Test rig export", "Operator: -"),
    ("Time (ms)", "Disp (in)", "Torque (kN*m)", "Force (lbf)"), (1e3, 1 / 0.0254, 1e-3, 1 / 4.4482216152605),
    {"file": "File name", "fixture": "Lever", "inertia": "Inertia (kg*m^2)", "mass": "Drop mass (lb)",
     "height": "Drop height (in)", "temperature": "Temp (degF)"}, 1 / 0.0254)


@dataclass
class LabFolder:
    """What :func:`write_lab_folder` wrote: the folder, its logs, the sheet, the rig file and
    each file's true conditions (SI)."""

    folder: Path
    logs: list[Path]
    sheet: Path
    rig: Path
    truth: pd.DataFrame


def write_lab_folder(folder: str | Path, dialect: Dialect = GERMAN, coupling: str = "rapp2022_nr60",
                     fixtures: dict[str, float] | None = None, masses: dict[str, float] | None = None,
                     heights_mm: tuple[float, ...] = HEIGHTS_MM, repeats: int = REPEATS,
                     sheet_suffix: str = ".xlsx", duration_s: float = 0.2, seed: int = 0) -> LabFolder:
    """Simulate every fixture x mass x height x repeat on the lab's rig and write the folder.

    Files are named ``{fixture}_{mass}_h{height_mm}_rep{repeat}.csv`` (repeats from 1); the sheet
    has one row per file with the dialect's column names and units (the temperature varies a
    little around 23 degC).
    """
    from droptower.rheology import load_coupling
    from droptower.rig.config import load_rig
    from droptower.rig.simulate import DropTest, simulate

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    rig_path = folder / "lab_rig.toml"
    rig_path.write_text(LAB_RIG_TOML, encoding="utf-8")
    rig = load_rig(rig_path)
    fixtures = FIXTURES if fixtures is None else fixtures
    masses = MASSES if masses is None else masses
    cases = list(itertools.product(fixtures.items(), masses.items(), heights_mm, range(1, repeats + 1)))
    tests = [DropTest(inertia_kgm2=j, drop_mass_kg=m, drop_height_m=h / 1e3, repeat=r, seed=seed + k)
             for k, ((_, j), (_, m), h, r) in enumerate(cases)]
    results = simulate(rig, load_coupling(coupling), tests, duration_s=duration_s)
    rng = np.random.default_rng(seed)
    logs, rows = [], []
    radius = rig.sensors.laser.radius_m
    for ((fixture, j), (mass, m), h, r), result in zip(cases, results):
        ch = result.channels()
        # the laser reads the lever's displacement at its radius (the rig's own sensor model)
        values = (ch.time_s - ch.time_s[0], ch.laser_distance_m, ch.torque_nm, ch.impact_force_n)
        name = f"{fixture}_{mass}_h{h:g}_rep{r}.csv"
        path = folder / name
        _write_csv(path, dialect, [v * s for v, s in zip(values, dialect.scale)])
        logs.append(path)
        temperature_c = 23.0 + float(rng.normal(0.0, 0.4))
        rows.append({"file": name, "fixture": fixture, "inertia_kgm2": j, "drop_mass_kg": m,
                     "drop_height_m": h / 1e3, "repeat": r, "temperature_c": temperature_c,
                     "double_impact": result.double_impact, "laser_radius_m": radius})
    truth = pd.DataFrame(rows)
    sheet = folder / f"conditions{sheet_suffix}"
    _write_sheet(sheet, dialect, truth)
    return LabFolder(folder, logs, sheet, rig_path, truth)


def _number(value: float, dialect: Dialect) -> str:
    text = f"{value:.7g}"
    return text.replace(".", ",") if dialect.decimal == "," else text


def _write_csv(path: Path, dialect: Dialect, columns: list[np.ndarray]) -> None:
    lines = list(dialect.header)
    lines.append(dialect.delimiter.join(dialect.columns))
    table = np.column_stack(columns)
    lines += [dialect.delimiter.join(_number(v, dialect) for v in row) for row in table]
    path.write_text("\n".join(lines) + "\n", encoding="cp1252" if dialect is GERMAN else "utf-8")


def _write_sheet(path: Path, dialect: Dialect, truth: pd.DataFrame) -> None:
    c = dialect.sheet_columns
    if dialect is IMPERIAL:
        temperature = truth["temperature_c"] * 9 / 5 + 32
        mass = truth["drop_mass_kg"] / 0.45359237
    else:
        temperature, mass = truth["temperature_c"], truth["drop_mass_kg"]
    sheet = pd.DataFrame({c["file"]: truth["file"], c["fixture"]: truth["fixture"],
                          c["inertia"]: truth["inertia_kgm2"], c["mass"]: mass,
                          c["height"]: truth["drop_height_m"] * dialect.height_scale,
                          c["temperature"]: temperature.round(2)})
    if path.suffix == ".xlsx":
        sheet.to_excel(path, index=False)
    elif path.suffix == ".parquet":
        sheet.to_parquet(path, index=False)
    else:
        sheet.to_csv(path, index=False, sep=dialect.delimiter, decimal=dialect.decimal)

