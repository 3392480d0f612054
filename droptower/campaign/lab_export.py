"""A virtual campaign written as a lab's own export, to rehearse the evaluation of a lab's folder.

A lab's drop tower does not write droptower's logs: it writes one CSV per drop in its own dialect
(header lines, separators, decimal commas, its own channel names and units, the laser's
displacement instead of an angle), a conditions sheet keyed by file name, and it has its own rig.
:func:`write_lab_folder` simulates every fixture x drop mass x drop height x repeat on such a rig
and writes the folder as that lab would, so the whole evaluation of a lab's folder (per-file
conditions from the sheet, the lab's rig, per-drop results, the map, the model-based map, the
validation against a bench, the report) can be rehearsed on data whose truth is known
(:attr:`LabFolder.truth`; docs/tutorials/lab-folder.md). Two dialects ship: :data:`GERMAN` (``;``, decimal commas, cp1252,
``Zeit [s];Weg [mm];Moment [Nm];Kraft [kN]``) and :data:`IMPERIAL` (tabs, ms, inches, kN*m, lbf).
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

if TYPE_CHECKING:
    from droptower.rheology import Coupling

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

#: the lab rig's lever fixtures: name -> rotating inertia (kg*m^2)
FIXTURES = {"L1": 0.12, "L2": 0.25, "L3": 0.40}
#: the drop masses: name (as in the file names) -> mass (kg)
MASSES = {"m1": 1.0, "m2": 2.0}
#: the drop heights (mm, the file names' unit)
HEIGHTS_MM = (20, 40, 80)
#: repeats per condition
REPEATS = 3


@dataclass(frozen=True)
class LabDialect:
    """How a lab's software writes its files.

    ``name``; ``delimiter`` and ``decimal`` (separators); ``header`` (the free-text lines above
    the names row); ``columns`` (the names, units included, of time, laser displacement, torque
    and impact force); ``scale`` (SI value x scale = written value, per column: s, m, N*m, N to
    the columns' units); ``sheet_columns`` (the conditions sheet's column per role: ``file``,
    ``fixture``, ``inertia``, ``mass``, ``height``, ``temperature``); ``height_scale`` and
    ``mass_scale`` (m and kg to the sheet's units); ``fahrenheit`` (the sheet's temperatures in
    degF, else degC); ``encoding`` (of the log files)."""

    name: str
    delimiter: str
    decimal: str
    header: tuple[str, ...]
    columns: tuple[str, str, str, str]          # time, displacement, torque, force
    scale: tuple[float, float, float, float]    # SI value * scale = written value
    sheet_columns: dict[str, str] = field(default_factory=dict)   # role -> the sheet's column name
    height_scale: float = 1.0                   # drop height in m * height_scale = the sheet's value
    mass_scale: float = 1.0                     # drop mass in kg * mass_scale = the sheet's value
    fahrenheit: bool = False                    # the sheet's temperatures in degF (else degC)
    encoding: str = "utf-8"                     # of the log files


#: a German lab's software: five header lines, German names, ';', decimal commas, cp1252, the sheet's heights in mm
GERMAN = LabDialect(
    "german", ";", ",",
    ("Messprogramm: Fallturm", "Datum: 28.11.2026", "Kanaele: 4", "Abtastrate: 19200 Hz", "Pruefer: -"),
    ("Zeit [s]", "Weg [mm]", "Moment [Nm]", "Kraft [kN]"), (1.0, 1e3, 1.0, 1e-3),
    {"file": "Datei", "fixture": "Hebel", "inertia": "Traegheit [kg m^2]", "mass": "Fallmasse [kg]",
     "height": "Fallhoehe [mm]", "temperature": "Temperatur [degC]"}, 1e3, encoding="cp1252")

#: another lab: tab-separated, time in ms, displacement in inches, torque in kN*m, force in lbf
IMPERIAL = LabDialect(
    "imperial", "\t", ".", ("Test rig export", "Operator: -"),
    ("Time (ms)", "Disp (in)", "Torque (kN*m)", "Force (lbf)"), (1e3, 1 / 0.0254, 1e-3, 1 / 4.4482216152605),
    {"file": "File name", "fixture": "Lever", "inertia": "Inertia (kg*m^2)", "mass": "Drop mass (lb)",
     "height": "Drop height (in)", "temperature": "Temp (degF)"}, 1 / 0.0254, mass_scale=1 / 0.45359237,
    fahrenheit=True)


@dataclass
class LabFolder:
    """What :func:`write_lab_folder` wrote: the folder, its logs, the sheet, the rig file and
    each file's true conditions (SI)."""

    folder: Path
    logs: list[Path]
    sheet: Path
    rig: Path
    truth: pd.DataFrame


def write_lab_folder(folder: str | Path, dialect: LabDialect = GERMAN, coupling: "str | Path | Coupling" = "rapp2022_nr60",
                     fixtures: dict[str, float] | None = None, masses: dict[str, float] | None = None,
                     heights_mm: tuple[float, ...] = HEIGHTS_MM, repeats: int = REPEATS,
                     sheet_suffix: str = ".xlsx", duration_s: float = 0.2, seed: int = 0) -> LabFolder:
    """Write a virtual campaign as a lab's export, to rehearse the evaluation of a lab's folder.

    Every fixture x drop mass x drop height x repeat is simulated on the lab's rig
    (:data:`LAB_RIG_TOML`: a 0.25 m lever, a laser at 0.25 m, 19.2 kHz) and written as one CSV
    per drop in the lab's dialect, named ``{fixture}_{mass}_h{height_mm}_rep{repeat}.csv``
    (repeats from 1), beside a conditions sheet with one row per file (the dialect's column
    names and units; the temperature varies a little around 23 degC) and the rig file
    ``lab_rig.toml``.

    Parameters
    ----------
    folder : str or Path
        The folder to write (created if missing).
    dialect : LabDialect
        How the lab's software writes its files (:data:`GERMAN`, :data:`IMPERIAL` or your own).
    coupling : str, Path or Coupling
        The coupling the drops are simulated on: a preset name, a TOML file or a loaded coupling.
    fixtures : dict of str to float, optional
        Lever fixture name -> rotating inertia (kg*m^2); default :data:`FIXTURES`.
    masses : dict of str to float, optional
        Drop-mass name (as in the file names) -> drop mass (kg); default :data:`MASSES`.
    heights_mm : tuple of float
        Drop heights (mm, the file names' unit).
    repeats : int
        Repeats per condition.
    sheet_suffix : str
        The conditions sheet's format: ``.xlsx``, ``.csv`` (in the dialect) or ``.parquet``.
    duration_s : float
        Record length after the impact (s).
    seed : int
        Seed of the sensor noise (drop k gets ``seed + k``) and of the temperatures.

    Returns
    -------
    LabFolder
        The folder, its logs, the sheet, the rig file and each file's true conditions (SI).
    """
    from droptower.rheology import load_coupling
    from droptower.rig.config import load_rig
    from droptower.rig.simulate import DropTest, simulate

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    rig_path = folder / "lab_rig.toml"
    fixtures = FIXTURES if fixtures is None else fixtures
    masses = MASSES if masses is None else masses
    rig_path.write_text(_rig_toml(fixtures, masses), encoding="utf-8")
    rig = load_rig(rig_path)
    cases = list(itertools.product(fixtures.items(), masses.items(), heights_mm, range(1, repeats + 1)))
    tests = [DropTest(inertia_kgm2=j, drop_mass_kg=m, drop_height_m=h / 1e3, repeat=r, seed=seed + k)
             for k, ((_, j), (_, m), h, r) in enumerate(cases)]
    model = load_coupling(coupling) if isinstance(coupling, (str, Path)) else coupling
    results = simulate(rig, model, tests, duration_s=duration_s)
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


def _rig_toml(fixtures: dict[str, float], masses: dict[str, float]) -> str:
    """:data:`LAB_RIG_TOML` with the campaign's fixtures' inertias and drop masses."""
    def listed(values) -> str:
        return "[" + ", ".join(f"{float(v):.6g}" if float(v) != int(v) else f"{float(v):.1f}" for v in values) + "]"

    text = LAB_RIG_TOML
    if sorted(fixtures.values()) != sorted(FIXTURES.values()):
        text = text.replace("inertias_kgm2 = [0.12, 0.25, 0.40]", f"inertias_kgm2 = {listed(sorted(fixtures.values()))}")
    if sorted(set(masses.values())) != sorted(MASSES.values()):
        text = text.replace("drop_masses_kg = [1.0, 2.0]", f"drop_masses_kg = {listed(sorted(set(masses.values())))}")
    return text


def _number(value: float, dialect: LabDialect) -> str:
    text = f"{value:.7g}"
    return text.replace(".", ",") if dialect.decimal == "," else text


def _write_csv(path: Path, dialect: LabDialect, columns: list[np.ndarray]) -> None:
    lines = list(dialect.header)
    lines.append(dialect.delimiter.join(dialect.columns))
    table = np.column_stack(columns)
    lines += [dialect.delimiter.join(_number(v, dialect) for v in row) for row in table]
    path.write_text("\n".join(lines) + "\n", encoding=dialect.encoding)


def _write_sheet(path: Path, dialect: LabDialect, truth: pd.DataFrame) -> None:
    c = dialect.sheet_columns
    temperature = truth["temperature_c"] * 9 / 5 + 32 if dialect.fahrenheit else truth["temperature_c"]
    mass = truth["drop_mass_kg"] * dialect.mass_scale
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

