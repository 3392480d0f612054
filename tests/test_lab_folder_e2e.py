"""A lab's own folder, end to end, through the command line alone.

The folder is what a lab exports (``tests/labfolder.py``, the German dialect: five header lines,
``;`` separators, decimal commas, ``Zeit [s];Weg [mm];Moment [Nm];Kraft [kN]`` with the laser's
displacement at 0.25 m, 19.2 kHz, cp1252), 54 single-drop CSV files named by their conditions, a
conditions sheet ``conditions.xlsx`` keyed by file name and the lab's own rig file (0.25 m lever,
three fixtures 0.12 / 0.25 / 0.40 kg*m^2). The drops are simulated on the virtual rig with
``rapp2022_nr60``, so the truth is known:

- each usable drop's stiffness, amplitude, frequency and damping ratio equal those of the same
  simulated drop evaluated from droptower's own log (which carries J, L, the laser radius and
  the conditions as metadata): the lab's dialect, its units, the laser's displacement, the sheet
  and the rig file must together give the same numbers, to the 7 significant digits the lab's
  files are written with;
- the lightest fixture (J/L^2 = 1.92 kg, about the drop mass: docs/theory.md#double-impact) and
  the 2 kg drops are double impacts, so the map covers the 1 kg drops of L2 and L3 and names L1
  as dropped out;
- the bench CSV is the virtual servo bench on the same coupling, written with the lab's own
  German column names, so the model-based route must agree with it as it does on the package's
  own campaigns (docs/routes.md) and the paper's route within its first-cycle bias.

The same folder with the preset rig ``rapp2022`` (0.2 m lever, 0.15 m laser radius) is
flagged on every drop, and the preset's source is printed.

Every step runs ``droptower`` in-process (``droptower.cli.main.main``), one as a subprocess.
The folder and every step's outputs are built once per process (session-scoped fixtures: when
worksteal splits this file into two blocks of one worker, the second reuses them); the folder,
its extraction with either rig and its model route are tests/conftest.py's, which
test_extract_lab.py and test_lab_downstream.py read too.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from labfolder import LabFolder, Step, droptower
from shared_bench import share_bench
from shared_map_fits import share_map_fits

pytestmark = pytest.mark.slow

COUPLING = "rapp2022_nr60"
#: the flags extract raised before the lab's geometry was checked: any other flag on a drop is a
#: geometry flag (the M2/M1 deviation, the laser amplitude against the torque, the impact energy)
BASE_FLAGS = {"double_impact", "clipping", "too_few_samples_per_period", "short_window", "poor_fit",
              "double_impact_unchecked", "decay_cut_by_next_drop"}
#: the bench's points (deg, Hz): inside the usable drops' hull (0.13-0.35 deg at 34-46 Hz) and around it
BENCH_AMPLITUDES_DEG, BENCH_FREQUENCIES_HZ = (0.15, 0.2, 0.25, 0.3), (36.0, 40.0, 44.0)
#: the lab's bench software's column names (German; validate recognises them without a mapping)
BENCH_COLUMNS = {"amplitude_deg": "Amplitude [°]", "frequency_hz": "Frequenz [Hz]",
                 "storage_stiffness_nm_per_deg": "Speichersteifigkeit [Nm/°]", "loss_factor": "Verlustfaktor"}


def _flags(value: object) -> set[str]:
    if not isinstance(value, str) or not value.strip():
        return set()
    return {f.strip() for f in re.split(r"[;,|]", value) if f.strip()}


@pytest.fixture(scope="session")
def lab(lab_folder) -> LabFolder:
    """The 54-file folder (tests/conftest.py, shared with test_extract_lab.py: only read here)."""
    return lab_folder  # write_lab_folder's defaults: GERMAN, COUPLING


@pytest.fixture(scope="session")
def work(lab_work) -> Path:
    return lab_work  # where tests/conftest.py's steps on the folder write


@pytest.fixture(scope="session")
def usable(lab) -> pd.DataFrame:
    """The truth of the drops without a double impact (the 1 kg drops of L2 and L3)."""
    truth = lab.truth[~lab.truth["double_impact"]]
    assert sorted(set(truth["fixture"])) == ["L2", "L3"] and len(truth) == 18
    return truth.set_index("file")


@pytest.fixture(scope="session")
def native(lab, lab_folder_and_drops, usable, work) -> pd.DataFrame:
    """The usable drops, the very simulations the lab's files were written from
    (tests/conftest.py), evaluated from droptower's own logs, whose metadata carry J, L and the
    laser radius: the numbers the lab's folder must give."""
    from droptower.extract.files import Settings, extract_file

    by_file = dict(zip(lab.truth["file"], lab_folder_and_drops[1]))
    rows = []
    for name in usable.index:
        drop = by_file[name]
        _, result = extract_file(drop.write_log(work / f"native_{Path(name).stem}.parquet"), Settings())
        rows.append({"file": name, "stiffness_nm_per_rad": result.stiffness_nm_per_rad,
                     "amplitude_ref_rad": result.amplitude_ref_rad, "frequency_hz": result.frequency_hz,
                     "damping_ratio": result.damping_ratio})
    return pd.DataFrame(rows).set_index("file")


@pytest.fixture(scope="session")
def bench(work) -> Path:
    """The lab's bench results: the virtual servo bench on the same coupling (``droptower servo``),
    written as the lab's software writes them (German names, ';', decimal commas)."""
    step = droptower("servo", COUPLING, "--amplitude-deg", ",".join(map(str, BENCH_AMPLITUDES_DEG)),
                     "--frequency-hz", ",".join(map(str, BENCH_FREQUENCIES_HZ)), "--json", "-q")
    assert step.code == 0, step.err
    table = pd.DataFrame(json.loads(step.out))[list(BENCH_COLUMNS)].rename(columns=BENCH_COLUMNS)
    path = work / "Pruefstand_Ergebnisse.csv"
    table.to_csv(path, sep=";", decimal=",", index=False, encoding="cp1252")
    return path


@pytest.fixture(scope="session")
def extracted(lab_extracted) -> tuple[Step, pd.DataFrame]:
    step, out = lab_extracted
    return step, pd.read_csv(out) if out.is_file() else pd.DataFrame()


@pytest.fixture(scope="session")
def mapped(extracted, work) -> Step:
    with share_map_fits():  # the tests' map, fitted once per process for map, map FOLDER and report
        return droptower("map", work / "results.csv", "--out", work / "map.json")


@pytest.fixture(scope="session")
def model_mapped(lab_model_mapped) -> Step:
    return lab_model_mapped  # map FOLDER --family template --template rapp2022_nr60 --model-out model_map.json


@pytest.fixture(scope="session")
def validated(mapped, model_mapped, bench, work) -> Step:
    with share_bench(keep=__name__):  # the model map at the bench's points: evaluated once for validate and report
        return droptower("validate", "--map", work / "map.json", "--model-map", work / "model_map.json",
                         "--servo-results", bench, "--out", work / "validation", "--json")


@pytest.fixture(scope="session")
def reported(lab, model_mapped, bench, work) -> Step:
    with share_map_fits(), share_bench(keep=__name__):
        return droptower("report", lab.folder, "--conditions", lab.sheet, "--rig", lab.rig, "--servo-results", bench,
                         "--model-map", work / "model_map.json", "--out", work / "report.html")


def _drawn_decays(page: Path) -> set[str]:
    """The tests whose decay figure a report holds: in the page (``decay-data``, a figure as an
    object, a reason as a string) or in its side files (``decay-files`` names them)."""
    text = page.read_text(encoding="utf-8")

    def block(name: str) -> dict:
        return json.loads(re.search(rf"<script type='application/json' id='{name}'>(.*?)</script>", text, re.S).group(1))

    return {name for name, fig in block("decay-data").items() if isinstance(fig, dict)} | set(block("decay-files"))


def _row_by_file(table: pd.DataFrame) -> pd.DataFrame:
    return table.assign(file=[Path(f).name for f in table["file"]]).set_index("file")


def test_extract_gives_every_drop_with_its_conditions_and_the_truths_numbers(lab, usable, native, extracted):
    step, table = extracted
    assert step.code == 0, step.err
    assert "Traceback" not in step.err
    rows = _row_by_file(table)
    assert sorted(rows.index) == sorted(lab.truth["file"])  # 54 drops, none lost
    truth = lab.truth.set_index("file").loc[rows.index]
    # the conditions from the sheet, per file
    assert list(rows["fixture"]) == list(truth["fixture"])
    np.testing.assert_allclose(rows["inertia_kgm2"], truth["inertia_kgm2"], rtol=1e-12)
    np.testing.assert_allclose(rows["drop_mass_kg"], truth["drop_mass_kg"], rtol=1e-12)
    np.testing.assert_allclose(rows["drop_height_m"], truth["drop_height_m"], rtol=1e-9)
    np.testing.assert_allclose(rows["temperature_c"], truth["temperature_c"], atol=0.005 + 1e-9)  # the sheet's 2 decimals
    # the geometry used, stored with every row and printed once
    np.testing.assert_allclose(rows["lever_length_m"], 0.25)
    np.testing.assert_allclose(rows["sensor_radius_m"], 0.25)
    assert step.err.count("geometry") == 1 and "0.25" in step.err
    # the double impacts are flagged, nothing else: the lab's geometry raises no geometry flag
    flags = {name: _flags(v) for name, v in rows["flags"].items()}
    assert {name for name, f in flags.items() if "double_impact" in f} == set(truth.index[truth["double_impact"]])
    assert set().union(*flags.values()) <= {"double_impact", "poor_fit"}
    # the usable drops' numbers are the truth's (the lab's files hold 7 significant digits)
    got = rows.loc[usable.index]
    for column in ("stiffness_nm_per_rad", "frequency_hz", "damping_ratio"):
        np.testing.assert_allclose(got[column], native[column], rtol=1e-4, err_msg=column)
    np.testing.assert_allclose(np.radians(got["amplitude_deg"]), native["amplitude_ref_rad"], rtol=1e-4)


def test_the_usable_drops_stiffness_is_the_couplings(usable, extracted):
    """Against the coupling itself: the servo bench's K' at each drop's reference amplitude
    and frequency. The drop tower's first-cycle c agrees within the method's own error (the
    study's map-free check, decays vs bench at the same points: 2.1 % RMS, docs/study.md;
    measured here: 0.4-1.1 % below), far from what a wrong inertia would give (the fixtures'
    J differ by 60 % and more)."""
    from droptower.rheology import load_coupling
    from droptower.servo import run_grid

    rows = _row_by_file(extracted[1]).loc[usable.index]
    coupling = load_coupling(COUPLING)
    k_storage = np.array([run_grid(coupling, amplitudes_rad=[np.radians(a)], frequencies_hz=[f])
                          ["storage_stiffness_nm_per_deg"].iloc[0]
                          for a, f in zip(rows["amplitude_deg"], rows["frequency_hz"])])
    deviation = rows["stiffness_nm_per_deg"].to_numpy() / k_storage - 1
    assert np.all(np.abs(deviation) < 0.021), deviation


def test_map_covers_the_usable_fixtures_and_names_the_one_that_dropped_out(lab, usable, mapped, work):
    assert mapped.code == 0, mapped.err
    doc = json.loads((work / "map.json").read_text())
    # every usable drop of both fixtures and nothing else: 18 used, the 36 double impacts left out by name
    assert doc["fit"]["n_tests"] == len(usable) == 18
    assert {Path(e["test"]).name for e in doc["excluded"]} == set(lab.truth["file"]) - set(usable.index)
    # eq. 19 over two fixtures' drops of one coupling (the study's campaign: 0.24 %, docs/guide/map.md)
    assert doc["fit"]["stiffness_rms_error_pct"] < 1.0
    # the lightest fixture dropped out entirely, named with why (double impacts) and the plan's advice
    said = mapped.err + mapped.out
    assert re.search(r"\bL1\b", said), said
    assert "double impact" in said.replace("_", " ")


def test_the_model_route_runs_on_the_lab_folder_with_bands_and_a_verdict(usable, model_mapped, work):
    from droptower.compare.model_map import ModelMap
    from droptower.rheology import load_coupling
    from droptower.servo import run_grid

    assert model_mapped.code == 0, model_mapped.err
    mm = ModelMap.from_json(work / "model_map.json")
    assert mm.has_bands and mm.identification["verdict"] == "good fit"
    grid = mm.grid
    lo, hi = grid["storage_stiffness_nm_per_deg_band_lo"], grid["storage_stiffness_nm_per_deg_band_hi"]
    assert np.all(lo <= grid["storage_stiffness_nm_per_deg"]) and np.all(grid["storage_stiffness_nm_per_deg"] <= hi)
    # the identified coupling is the lab's coupling on the bench: K' and loss factor at the grid's points
    amplitudes, frequencies = np.unique(grid["amplitude_deg"]), np.unique(grid["frequency_hz"])
    truth = run_grid(load_coupling(COUPLING), amplitudes_rad=np.radians(amplitudes), frequencies_hz=frequencies)
    key = ["amplitude_key", "frequency_key"]
    keyed = [g.assign(amplitude_key=g["amplitude_deg"].round(6), frequency_key=g["frequency_hz"].round(6))
             for g in (grid, truth)]
    merged = keyed[0].merge(keyed[1].drop(columns=["amplitude_deg", "frequency_hz"]), on=key, suffixes=("", "_truth"))
    assert len(merged) == len(grid)
    np.testing.assert_allclose(merged["storage_stiffness_nm_per_deg"], merged["storage_stiffness_nm_per_deg_truth"],
                               rtol=0.01)
    np.testing.assert_allclose(merged["loss_factor"], merged["loss_factor_truth"], rtol=0.03)


def test_validate_against_the_labs_bench_csv(validated, work):
    from droptower.compare.model_map import PAPER_ROUTE

    assert validated.code == 0, validated.err
    doc = json.loads(validated.out)
    routes = doc["routes"]
    model = next(v["summary"] for name, v in routes.items() if name != PAPER_ROUTE)
    paper = routes[PAPER_ROUTE]["summary"]
    assert model["inside"]["n_points"] >= 4 and paper["inside"]["n_points"] == model["inside"]["n_points"]
    # inside the tests' hull the model-based route is the bench (docs/routes.md: 0.2 % on Table 2)
    assert model["inside"]["stiffness_rms_deviation_pct"] < 1.0
    assert model["inside"]["loss_factor_rms_deviation_pct"] < 3.0
    # the paper's route: its stiffness within the first-cycle bias, its damping far off (docs/routes.md)
    assert paper["inside"]["stiffness_rms_deviation_pct"] < 6.5
    assert paper["inside"]["loss_factor_rms_deviation_pct"] > 5 * model["inside"]["loss_factor_rms_deviation_pct"]
    assert (work / "validation" / "validation_routes.csv").is_file()


def test_report_draws_every_usable_decay(lab, usable, reported, work):
    assert reported.code == 0, reported.err
    page = (work / "report.html").read_text(encoding="utf-8")
    names = {Path(name).name for name in _drawn_decays(work / "report.html")}
    assert set(usable.index) <= names, sorted(set(usable.index) - names)
    assert len(names) == len(lab.logs)  # every drop's decay is drawn, the double impacts' too
    assert "no decay plot" not in page and "id='routes-table'" in page
    # both routes validated against the lab's bench on the page: its 12 points, the model-based route on it
    text = re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", re.sub(r"<script.*?</script>", "", page, flags=re.S)))
    assert "Two routes: paper map and model-based map" in text
    rows = dict(re.findall(r"(paper map, eq\. 19/20|model-based map, template) all (\d+ [\d.]+)", text))
    n_points = len(BENCH_AMPLITUDES_DEG) * len(BENCH_FREQUENCIES_HZ)
    assert {route: int(v.split()[0]) for route, v in rows.items()} == {
        "paper map, eq. 19/20": n_points, "model-based map, template": n_points}
    assert float(rows["model-based map, template"].split()[1]) < 1.0  # K' RMS, % (as validate's)


def test_the_preset_rig_is_flagged_on_every_drop_and_its_source_printed(lab, extracted, lab_extracted_preset):
    step, out = lab_extracted_preset  # extract FOLDER's logs --conditions SHEET --rig rapp2022
    assert step.code == 0, step.err
    from droptower.rig.config import load_rig

    preset = load_rig("rapp2022")
    warning = [line for line in step.err.splitlines() if "warning" in line and "rapp2022" in line]
    assert len(warning) == 1, step.err
    # where the geometry came from (the shipped preset) and what it is
    assert "preset" in warning[0]
    assert f"{preset.lever_length_m:g} m" in warning[0] and f"{preset.sensors.laser.radius_m:g} m" in warning[0]
    rows, right = _row_by_file(pd.read_csv(out)), _row_by_file(extracted[1])
    np.testing.assert_allclose(rows["lever_length_m"], preset.lever_length_m)
    # the preset's 0.15 m laser radius reads the 0.25 m spot's displacement as 0.25/0.15 times the angle
    ratio = rows["amplitude_deg"] / right.loc[rows.index, "amplitude_deg"]
    np.testing.assert_allclose(ratio, 0.25 / preset.sensors.laser.radius_m, rtol=0.01)
    # every drop the map would use is flagged (a double impact, left out anyway, is not checked)
    flags = {name: _flags(v) for name, v in rows["flags"].items()}
    unflagged = [name for name, f in flags.items() if not f - BASE_FLAGS and "double_impact" not in f]
    assert not unflagged, unflagged
    assert sum(bool(f - BASE_FLAGS) for f in flags.values()) >= 18
    # and the map does not quietly use them: every test is left out, each with its flags named
    mapped = droptower("map", out)
    assert mapped.code == 2 and "stiffness_m2_m1_deviation" in mapped.err, mapped.err


def test_the_results_table_reads_back_in_a_fresh_process(extracted, work):
    """One step as a user types it: ``droptower map results.csv``, the installed console script in
    its own process (map's one run as installed, tests/test_cli_installed.py)."""
    from test_cli_installed import _run

    done = _run("map", str(work / "results.csv"), "--json", "-q")
    assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr
    assert json.loads(done.stdout)["fit"]["n_tests"] == 18
