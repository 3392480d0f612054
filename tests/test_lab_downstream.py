"""A lab's own folder through map, the model route, validate and report (tests/labfolder.py: logs
simulated on the lab's rig, so each file's conditions and double impacts are known).

Folders are built once per module and kept small: 3 fixtures x 1 kg x 3 heights x 2 repeats
(every drop of the lightest fixture L1 strikes twice, as the impact law says: its equivalent mass
J/L^2 = 1.92 kg is not enough above the 1 kg drop mass), and for the round trips one fixture
x 12 drops in each of two dialects. The model route runs on the session's 54-file folder
(tests/conftest.py: its map FOLDER --family step, which test_lab_folder_e2e.py reads too).
"""
from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from labfolder import GERMAN, IMPERIAL, write_lab_folder  # noqa: E402
from shared_map_fits import share_map_fits  # noqa: E402

from droptower.cli.main import main  # noqa: E402
from droptower.maps import read_results, select_tests  # noqa: E402
from droptower.maps.coverage import TEMPERATURE_SPAN_K, coverage_notes, double_impact_advice  # noqa: E402

DURATION_S = 0.12
CHANNEL = {GERMAN.name: "distance=Weg", IMPERIAL.name: "distance=Disp"}


@pytest.fixture(scope="module", autouse=True)
def map_fits():
    """One map fit per distinct set of tests (tests/shared_map_fits.py): the tables of every
    format extract writes read back into the same tests, and map, report and validate of one
    folder fit the same map; each command still reads, selects, writes and prints."""
    with share_map_fits() as cache:
        yield cache


@pytest.fixture(scope="session")  # kept when worksteal splits this file: a second block reuses it
def lab(tmp_path_factory: pytest.TempPathFactory):
    """Three fixtures, the lightest of which strikes twice on every drop."""
    folder = tmp_path_factory.mktemp("lab")
    return write_lab_folder(folder, masses={"m1": 1.0}, heights_mm=(20, 40, 80), repeats=2, duration_s=DURATION_S)


@pytest.fixture(scope="module", params=[GERMAN, IMPERIAL], ids=lambda d: d.name)
def one_fixture(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory):
    """One fixture, 12 usable drops, in each of two dialects (German ';' and decimal commas,
    imperial tab-separated in ms, inches, kN*m and lbf)."""
    folder = tmp_path_factory.mktemp(f"one_{request.param.name}")
    return request.param, write_lab_folder(folder, dialect=request.param, fixtures={"L3": 0.40}, masses={"m1": 1.0},
                                           heights_mm=(20, 40, 80), repeats=4, duration_s=DURATION_S)


def _run(capsys: pytest.CaptureFixture[str], argv: list[str]) -> tuple[int, str, str]:
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def _lab_flags(lab, dialect=GERMAN) -> list[str]:
    return ["--rig", str(lab.rig), "--conditions", str(lab.sheet), "--channel", CHANNEL[dialect.name]]


# ----------------------------------------------------------------------------------------------- round trips
@pytest.mark.slow
def test_extract_output_reads_back_into_map_validate_and_report(one_fixture, tmp_path, capsys):
    """Every table extract --out writes (CSV, Parquet, Excel, JSON; logs of two dialects whose
    copied header/delimiter metadata hold ';' or tabs) reads back with the same numbers (CSV to
    its printed precision, 1e-12) and maps, validate reads the map, and report draws every
    decay of the CSV (the format that broke)."""
    dialect, lab = one_fixture
    tables = {}
    for suffix in (".csv", ".parquet", ".xlsx", ".json"):
        out = tmp_path / f"results{suffix}"
        code, _, err = _run(capsys, ["extract", *map(str, lab.logs), *_lab_flags(lab, dialect), "--out", str(out),
                                     "-q"])
        assert code == 0, err
        tables[suffix] = table = read_results(out)
        assert len(table) == len(lab.logs) == 12
        assert set(table["delimiter"].astype(str)) == {dialect.delimiter}
        usable, excluded = select_tests(table)
        assert len(usable) == 12 and not excluded, excluded
        code, text, err = _run(capsys, ["map", str(out), "--out", str(tmp_path / f"map{suffix}.json")])
        assert code == 0, err
        assert "12 tests used, 0 excluded" in text
    ref = tables[".parquet"]
    for suffix, t in tables.items():
        for column in ("amplitude_deg", "frequency_hz", "stiffness_nm_per_deg", "damping_ratio", "inertia_kgm2"):
            np.testing.assert_allclose(t[column].astype(float), ref[column].astype(float), rtol=1e-12, err_msg=suffix)
    if dialect is GERMAN:  # the map read back from the CSV validates (once: the sweeps cost seconds)
        code, text, err = _run(capsys, ["validate", "--map", str(tmp_path / "map.csv.json"), "--quick"])
        assert code == 0, err
    page = tmp_path / "report.html"
    code, _, err = _run(capsys, ["report", str(tmp_path / "results.csv"), "--rig", str(lab.rig), "--channel",
                                 CHANNEL[dialect.name], "--out", str(page), "-q"])
    assert code == 0, err
    assert "no decay plot" not in page.read_text(encoding="utf-8")


def test_a_misread_separator_is_said(one_fixture, tmp_path, capsys):
    """A results CSV whose rows do not split under its names row (a note line above the names)
    says the separator was misread, not 'lacks column(s) ... (has: <a data row>)'."""
    dialect, lab = one_fixture
    out = tmp_path / "results.csv"
    assert main(["extract", *map(str, lab.logs), *_lab_flags(lab, dialect), "--out", str(out), "-q"]) == 0
    bad = tmp_path / "noted.csv"
    bad.write_text("exported by the lab\n" + out.read_text(encoding="utf-8"), encoding="utf-8")
    code, _, err = _run(capsys, ["map", str(bad)])
    assert code == 2 and err.count("\n") == 1
    assert "separator was misread" in err and "line 2 holds the names" in err and "has:" not in err


# ------------------------------------------------------------------------------------- several fixtures, map
def test_map_of_a_lab_folder_names_the_fixture_that_dropped_out(lab, capsys):
    """One call over a folder of three fixtures: the map covers L2 and L3, names L1 (every drop a
    double impact, as the simulation's truth says) with why and a drop mass that would avoid
    it, below the 1 kg that struck twice; rows carry the fixture and the temperature."""
    truth = lab.truth.set_index("fixture")["double_impact"].groupby(level=0).all()
    assert truth.to_dict() == {"L1": True, "L2": False, "L3": False}
    code, out, err = _run(capsys, ["map", str(lab.folder), *_lab_flags(lab), "--json"])
    assert code == 0, err
    doc = json.loads(out)
    (line,) = doc["coverage"]
    assert line.startswith("fixture L1 (J = 0.12 kg*m^2): all 6 test(s) left out of the map (flag double_impact x6)")
    advised = float(re.search(r"a drop mass of at most ([\d.]+) kg would avoid it", line).group(1))
    assert 0.1 < advised < 1.0  # the 1 kg struck twice
    assert "none of the rig's drop masses would" in line
    assert len(doc["excluded"]) == 6 and all(e["test"].startswith("L1_") for e in doc["excluded"])
    assert doc["fixtures"] == ["L2", "L3"]  # the map carries the fixtures it covers, and their temperatures
    used = lab.truth[lab.truth["fixture"] != "L1"]["temperature_c"]
    np.testing.assert_allclose(doc["temperature_range_c"], [used.min(), used.max()], atol=0.006)  # the sheet's 2 decimals


def test_double_impact_advice_agrees_with_the_simulated_rig(lab):
    """The advice's closed form against the virtual rig's own double impacts: at the lab's
    fixtures with their measured decay, 1 kg strikes L1 twice and clears L2 and L3."""
    from droptower.maps.fromlogs import results_from_logs
    from droptower.io.conditions import read_conditions
    from droptower.rig.config import load_rig

    rig = load_rig(lab.rig)
    table = results_from_logs(lab.logs, rig=rig, roles={"distance": "Weg"},
                              conditions=read_conditions(lab.sheet, rig=rig))
    for fixture, j in (("L1", 0.12), ("L2", 0.25), ("L3", 0.40)):
        rows = table[table["fixture"] == fixture]  # the fixture's own frequency and decay (L1's: flagged drops')
        f, delta = rows["frequency_hz"].median(), rows["decay_coefficient_per_s"].median()
        text = double_impact_advice(j, f, delta, 0.25, 0.5, [1.0], [0.02, 0.04, 0.08], (1.0,))
        clears = "of the rig's drop masses, 1 kg would" in text
        assert clears == (not lab.truth[lab.truth["fixture"] == fixture]["double_impact"].all()), (fixture, text)
    # without the rig: the lever length the rows store, the restitution measured from the impulse
    # (J phi'(0+) = L * impulse, docs/theory.md#impact; the rig's is 0.5)
    from droptower.maps.coverage import _restitution

    assert _restitution(table[table["fixture"] == "L1"], 0.25) == pytest.approx(0.5, abs=0.02)
    (line,) = coverage_notes(table, *select_tests(table))
    assert line.startswith("fixture L1") and "restitution 0.5" in line


def test_temperature_span_is_said():
    """A map over tests more than TEMPERATURE_SPAN_K apart says so; within it, nothing."""
    n = 12
    table = pd.DataFrame({"amplitude_deg": np.linspace(0.1, 0.3, n), "frequency_hz": 40.0,
                          "stiffness_nm_per_deg": 350.0, "damping_ratio": 0.5, "file": [f"f{i}" for i in range(n)]})
    for span, said in ((TEMPERATURE_SPAN_K + 1.0, True), (TEMPERATURE_SPAN_K - 1.0, False)):
        t = table.assign(temperature_c=np.linspace(20.0, 20.0 + span, n))
        notes = coverage_notes(t, *select_tests(t))
        assert bool([s for s in notes if "K of temperature" in s]) == said, notes


# ------------------------------------------------------------------------------------------ the model route
@pytest.mark.slow  # the first of this process's tests to read the folder's model route waits for it
def test_model_route_on_a_lab_folder(lab_model_mapped, lab_work, tmp_path, capsys):
    """map FOLDER --family on a plain folder of logs with --conditions and --rig (the lab's
    54-file folder: tests/conftest.py runs it once per process, test_lab_folder_e2e.py checks the
    identified coupling against the truth and its report page): the model-based map with bands and
    a verdict; its figure says the band is shaded; validate takes a bench CSV with the lab's German
    column names and compares both routes. The bench: the reduced sweeps' amplitudes at 10, 30 and
    60 Hz (12 points, most outside the drops' hull; the sweeps' 1 Hz points would cost the model
    route's bench simulation ten times all the others, and a misread column, unit or route shows
    at any point)."""
    from droptower.rheology import load_coupling
    from droptower.servo import run_grid

    step = lab_model_mapped  # map FOLDER --rig --conditions --family template --template rapp2022_nr60 --model-out
    assert step.code == 0, step.err
    assert "model-based map, template" in step.out and "good fit" in step.out and "bands: 95 %" in step.out
    from droptower.compare.model_map import ModelMap
    from droptower.compare.model_map_plots import _stiffness

    mm = lab_work / "model_map.json"
    banded = ModelMap.from_json(mm)
    grid = banded.grid if banded.grid is not None else banded.evaluate_grid()
    assert banded.has_bands and any(c.endswith("_band_lo") for c in grid.columns)
    assert "95 % band shaded" in _stiffness(banded, grid, None, None).axes[1].get_title()
    points = run_grid(load_coupling("rapp2022_nr60"), np.radians([0.2, 0.5, 1.5, 2.5]), [10.0, 30.0, 60.0])
    bench = tmp_path / "bench.csv"
    pd.DataFrame({"Amplitude [°]": points["amplitude_deg"], "Frequenz [Hz]": points["frequency_hz"],
                  "Speichersteifigkeit [Nm/°]": points["storage_stiffness_nm_per_deg"],
                  "Verlustfaktor": points["loss_factor"]}).to_csv(bench, sep=";", decimal=",", index=False)
    code, out, err = _run(capsys, ["validate", "--map", str(lab_work / "map_folder.json"), "--servo-results", str(bench),
                                   "--model-map", str(mm)])
    assert code == 0, err
    row = next(line for line in out.splitlines() if line.startswith("model-based map, template") and " all " in line)
    k_rms, eta_rms = (float(x) for x in row.split()[-3:-1])
    assert k_rms < 1.0 and eta_rms < 1.0  # the model route predicts the bench (the coupling simulated is the bench's)


def test_identify_from_a_lab_folder(lab, capsys):
    """identify --from-drop-tests on a plain folder: with the three-fixture rig alone each log is
    told the conditions must say its fixture (not 'give --rig', which was given); with
    --conditions and --sensor-radius-m it fits."""
    code, _, err = _run(capsys, ["identify", "--from-drop-tests", str(lab.folder), "--family", "template",
                                 "--template", "rapp2022_nr60", "--rig", str(lab.rig), "--channel", "distance=Weg"])
    assert code == 2
    assert "several lever fixtures" in err and "give --conditions" in err
    assert "or --rig" not in err and "Traceback" not in err
    code, out, err = _run(capsys, ["identify", "--from-drop-tests", str(lab.folder), "--family", "template",
                                   "--template", "rapp2022_nr60", "--rig", str(lab.rig), "--conditions", str(lab.sheet),
                                   "--channel", "distance=Weg", "--sensor-radius-m", "0.25"])
    assert code == 0, err
    assert "verdict: good fit" in out
    assert "conditions.xlsx" not in err  # the sheet beside the logs is not taken for a log


def test_model_coupling_figures_claim_no_band(lab, tmp_path):
    """A map of a coupling given as it is has no bands: its figures say so, never 'band shaded'."""
    from droptower.compare.model_map import model_map_from_coupling
    from droptower.compare.model_map_plots import _damping, _stiffness
    from droptower.maps.mapfit import MapRange
    from droptower.rheology import load_coupling

    mm = model_map_from_coupling(load_coupling("rapp2022_nr60"), MapRange.of_points([0.1, 0.3, 0.2], [35, 46, 40]))
    grid = mm.evaluate_grid()
    assert not mm.has_bands
    texts = [t.get_text() for fig in (_stiffness(mm, grid, None, None), _damping(mm, grid, None, None))
             for ax in fig.axes for t in (ax.title, *ax.texts)]
    assert not any("shaded" in t for t in texts), texts
    assert any("no bands" in t for t in texts)


# ------------------------------------------------------------------------------------------------------ report
def test_report_on_a_lab_folder_fails_loudly_or_draws_every_decay(lab, tmp_path, capsys):
    """Without geometry: exit 2, one line naming the flag to give, no page; with the rig but no
    conditions: the conditions are asked for (not the rig); with both: every usable decay drawn."""
    page = tmp_path / "r.html"
    code, _, err = _run(capsys, ["report", str(lab.folder), "--out", str(page)])
    assert code == 2 and err.count("\n") == 1 and not page.exists()
    assert "none of the 18 logs can be evaluated" in err and "--sensor-radius-m or --rig" in err
    code, _, err = _run(capsys, ["report", str(lab.folder), "--rig", str(lab.rig), "--channel", "distance=Weg",
                                 "--out", str(page)])
    assert code == 2 and "give --conditions" in err and not page.exists()
    code, _, err = _run(capsys, ["report", str(lab.folder), *_lab_flags(lab), "--out", str(page)])
    assert code == 0, err
    html = page.read_text(encoding="utf-8")
    assert "no decay plot" not in html and "12 tests used, 6 excluded" in html
    assert re.search(r"id='not-covered'.*fixture L1 \(J = 0.12 kg\*m\^2\): all 6 test\(s\) left out", html, re.S)


# ------------------------------------------------------------------------------ malformed conditions tables
@pytest.fixture(scope="session")  # kept when worksteal splits this file: a second block reuses it
def small(lab, tmp_path_factory: pytest.TempPathFactory):
    """Three logs (one per fixture) for the malformed tables, with the rig beside them."""
    import shutil

    folder = tmp_path_factory.mktemp("small")
    chosen = [p for p in lab.logs if p.name.endswith("_h40_rep1.csv")]
    for p in chosen:
        shutil.copy(p, folder / p.name)
    tables = tmp_path_factory.mktemp("tables")  # the drawn tables lie outside the folder of logs
    truth = lab.truth[lab.truth["file"].isin([p.name for p in chosen])].reset_index(drop=True)
    return folder, tables, truth


def _commands(folder: Path, lab, table: Path, tmp_path: Path, map_json: Path) -> dict[str, list[str]]:
    flags = ["--rig", str(lab.rig), "--conditions", str(table), "--channel", "distance=Weg"]
    return {"map": ["map", str(folder), *flags],
            "report": ["report", str(folder), *flags, "--out", str(tmp_path / "r.html")],
            "validate": ["validate", "--map", str(map_json), "--servo-results", str(map_json.parent / "bench.csv"),
                         "--reference", str(table4_path()), "--results", str(folder), *flags]}


@pytest.fixture(scope="session")  # kept when worksteal splits this file: a second block reuses it
def map_json(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A map (the paper's Table 4's) and a bench table for validate, made once."""
    folder = tmp_path_factory.mktemp("validate")
    assert main(["map", "rapp2022_table4", "--out", str(folder / "map.json"), "-q"]) == 0
    pd.DataFrame({"Amplitude [°]": [0.5, 1.0], "Frequenz [Hz]": [10.0, 20.0], "Speichersteifigkeit [Nm/°]": [300.0, 290.0],
                  "Verlustfaktor": [0.1, 0.11]}).to_csv(folder / "bench.csv", sep=";", decimal=",", index=False)
    return folder / "map.json"


from hypothesis import HealthCheck, given, settings, strategies as st  # noqa: E402

from droptower.data import table4_path  # noqa: E402
from tests.malformed_conditions import malformed_tables  # noqa: E402


@pytest.mark.slow
@settings(max_examples=8, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_malformed_conditions_through_map_report_validate(small, lab, map_json, data, capsys, tmp_path):
    """Missing files, extra rows, duplicates, rows without a file, words for numbers, unknown
    units, empty tables (tests/malformed_conditions.py) given to map, report and validate on a
    folder of logs: never a traceback; a table that is wrong as a whole is one error line naming
    it and exit 2 before any log is read; otherwise each file the table cannot give conditions
    for is named on its own error line (exit 2), the others are not, and rows naming no log are
    warned of (nothing dropped silently)."""
    folder, tables, truth = small
    case = data.draw(malformed_tables(tables, truth))
    for name, argv in _commands(folder, lab, case.table, tmp_path, map_json).items():
        code = main(argv)
        err = capsys.readouterr().err
        assert "Traceback" not in err, (name, err)
        errors = [line for line in err.splitlines() if "error:" in line]
        if case.whole_table:
            assert code == 2 and len(errors) == 1 and str(case.table) in errors[0], (name, err)
            continue
        assert code == (2 if case.failing else code) and code in (0, 2), (name, code, err)
        for failing in case.failing:
            assert any(failing in line for line in errors), (name, failing, err)
        for good in case.good:
            assert not any(good in line for line in errors), (name, good, err)
        if "extra" in case.problems:
            assert any("not_given_rep9.csv" in line and "names no log" in line for line in err.splitlines()), (name, err)


@pytest.mark.slow
@settings(max_examples=4, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_malformed_conditions_through_identify(small, lab, data, capsys):
    """The same tables given to identify --from-drop-tests: never a traceback; a table wrong as
    a whole is one error line naming it (exit 2); each file without conditions is excluded by
    name, the others are fitted."""
    folder, tables, truth = small
    case = data.draw(malformed_tables(tables, truth))
    code = main(["identify", "--from-drop-tests", str(folder), "--family", "template", "--template", "rapp2022_nr60",
                 "--rig", str(lab.rig), "--conditions", str(case.table), "--channel", "distance=Weg", "--verbose",
                 "--holdout-fraction", "0", "--accept-poor"])
    err = capsys.readouterr().err
    assert "Traceback" not in err, err
    if case.whole_table:
        errors = [line for line in err.splitlines() if "error:" in line]
        assert code == 2 and len(errors) == 1 and str(case.table) in errors[0], err
        return
    assert code in (0, 2), err
    excluded = [line for line in err.splitlines() if "excluded" in line]
    for failing in case.failing:
        assert any(failing in line for line in excluded), (failing, err)


def test_model_route_reads_a_results_table_with_its_logs(lab, tmp_path, capsys):
    """A results table from extract --out, with the logs it names: the model route reads each log
    with its own row's inertia (several fixtures, no conditions needed again), the double
    impacts excluded by name."""
    from droptower.compare.model_map import read_logs_for_model
    from droptower.rig.config import load_rig

    out = tmp_path / "results.xlsx"
    assert main(["extract", *map(str, lab.logs), *_lab_flags(lab), "--out", str(out), "-q"]) == 0
    capsys.readouterr()
    campaign = read_logs_for_model(out, "template", template="rapp2022_nr60", rig=load_rig(lab.rig),
                                   roles={"distance": "Weg"})
    truth = lab.truth.set_index("file")
    used = {d.name for d in campaign.decays}
    excluded = {Path(e["file"]).name: e["reason"] for e in campaign.excluded}
    assert used | set(excluded) == set(truth.index) and not used & set(excluded)  # nothing lost
    # the simulated double impacts are all excluded (the identification also wants 1.5 free periods)
    assert set(truth.index[truth["double_impact"]]) <= set(excluded)
    assert all(r.startswith("double impact") for r in excluded.values()), excluded
    assert {n[:2] for n in used} == {"L2", "L3"}
    for d in campaign.decays:
        assert d.inertia_kgm2 == pytest.approx(truth.loc[d.name, "inertia_kgm2"], rel=1e-12)


def test_messages_name_only_flags_the_command_has(lab, map_json, tmp_path, capsys):
    """On a lab's folder given too little, each command's messages name flags of that command
    only (never one it lacks), and never ask for what was given."""
    import click

    from droptower.cli.main import cli

    folder, rig = str(lab.folder), str(lab.rig)
    calls = [["map", folder], ["map", folder, "--rig", rig, "--channel", "distance=Weg"],
             ["report", folder, "--out", str(tmp_path / "r.html")],
             ["report", folder, "--rig", rig, "--out", str(tmp_path / "r.html")],
             ["identify", "--from-drop-tests", folder, "--family", "zerodim6"],
             ["identify", "--from-drop-tests", folder, "--family", "zerodim6", "--rig", rig],
             ["validate", "--map", str(map_json), "--servo-results", str(map_json.parent / "bench.csv"),
              "--reference", str(table4_path()), "--results", folder, "--channel", "distance=Weg"]]
    for argv in calls:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        command = cli.get_command(click.Context(cli), argv[0])
        known = {o for p in command.params if isinstance(p, click.Option) for o in p.opts}
        named = set(re.findall(r"(?<![\w-])--[a-z][a-z0-9-]+", err))
        assert named and named <= known, (argv, named - known, err)
        given = {a for a in argv if a.startswith("--")} - {"--from-drop-tests", "--family", "--out", "--channel"}
        assert not any(re.search(rf"give [^;]*{g}\b", err) for g in given), (argv, err)
