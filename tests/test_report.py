"""``droptower report``: one self-contained offline HTML file of a campaign or an
``extract --out`` results table; failures and flags first with their reasons, the map with
fit and cross-validated errors, a sortable per-test table, per-test decay-fit plots that show
the fit the table reports; and in headless Chromium: no console errors, the table sorts, a
test's link draws its decay fit, and a screenshot at 1280 px."""
from __future__ import annotations

import atexit
import base64
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from droptower.campaign import run_campaign
from droptower.cli.main import main
from droptower.maps import fit_map
from droptower.report import write_report

# 3 cases of Rapp et al. 2022, Table 2 x 4 heights, no preload: 12 tests, enough for a map
PLAN = """name = "report_test"
base_seed = 7
repeats = 1
heights_m = [0.1, 0.5, 1.5, 4.0]
preloads_nm = [0.0]
[[group]]
name = "case 1"
inertia_kgm2 = 0.1557
drop_mass_kg = 1.0
[[group]]
name = "case 2"
inertia_kgm2 = 0.359
drop_mass_kg = 2.0
[[group]]
name = "case 3"
inertia_kgm2 = 0.5233
drop_mass_kg = 2.0
"""


#: the campaign below, built once per process: test_report_decays and test_report_scale import the
#: fixture and only read the folder (each writes its pages elsewhere)
_CAMPAIGN: list[Path] = []


@pytest.fixture(scope="session")  # kept when worksteal splits this file: a second block reuses it
def campaign(tmp_path_factory) -> Path:
    """A campaign on the calibrated coupling, then one test marked failed and one flagged in its
    results (as an extraction error and a second impact would leave them)."""
    if not _CAMPAIGN:
        _CAMPAIGN.append(_report_campaign(tmp_path_factory))
    return _CAMPAIGN[0]


def _report_campaign(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("report")
    (root / "plan.toml").write_text(PLAN)
    out = root / "campaign"
    run_campaign(out, doe=root / "plan.toml", workers=1, duration_s=0.1, progress=False)
    table = pd.read_parquet(out / "results.parquet")
    table.loc[2, ["status", "error"]] = ["failed", "fit window shorter than 3/4 of the oscillation period"]
    table.loc[2, ["amplitude_deg", "stiffness_nm_per_deg", "damping_ratio"]] = np.nan
    table.loc[5, "flags"] = "double_impact"
    table.to_parquet(out / "results.parquet", index=False)
    return out


@pytest.fixture(scope="session")  # kept when worksteal splits this file: a second block reuses it
def report(campaign: Path) -> Path:
    return write_report(campaign)


def _fits(text: str) -> dict:
    match = re.search(r"<script type='application/json' id='decay-data'>(.*?)</script>", text, re.S)
    return json.loads(match.group(1).replace("<\\/", "</"))


def _array(value) -> np.ndarray:
    """A plotly array: a list, or {dtype, bdata} (base64 typed array)."""
    if isinstance(value, dict):
        return np.frombuffer(base64.b64decode(value["bdata"]), dtype=np.dtype(value["dtype"]))
    return np.asarray(value, float)


def test_report_is_self_contained_and_has_no_absolute_paths(campaign: Path, report: Path) -> None:
    text = report.read_text()
    assert report == campaign / "report.html"
    assert not re.search(r"<script[^>]*\ssrc=", text) and not re.search(r"<link[^>]*href=['\"]?https?:", text)
    assert str(campaign.parent) not in text and "/tmp/" not in text.split("</head>")[1]
    assert text.count("<script type='text/javascript'>") == 1  # plotly.js embedded once


def test_failures_and_flags_come_first_with_their_reasons(report: Path) -> None:
    body = report.read_text().split("</head>")[1]
    problems, rest = body.index("<h2>Failures and flags</h2>"), body.index("<h2>Characteristic map</h2>")
    assert problems < rest < body.index("<h2>Tests</h2>")
    section = body[problems:rest]
    assert "1 failed" in section and "test_00002" in section
    assert "extraction failed: fit window shorter than 3/4 of the oscillation period" in section
    assert "flag double_impact" in section and "restarts the decay" in section
    # the failed row goes first, then the exclusions (the flagged test is excluded from the map)
    assert section.index("test_00002") < section.index("test_00005")
    assert "excluded from the map" in section


def test_map_section_gives_coefficients_and_cross_validated_errors(campaign: Path, report: Path) -> None:
    text = report.read_text()
    section = text[text.index("<h2>Characteristic map</h2>"):text.index("<h2>Tests</h2>")]
    fit = fit_map(campaign)
    assert fit.stats.n_tests == 10  # 12 - the failed - the double impact
    assert f"fitted to {fit.stats.n_tests} tests (2 excluded" in section
    assert "leave-one-drop-height-out (4 folds)" in section
    for value in (fit.stats.stiffness_rms_error_pct, fit.stats.damping_ratio_cv_rms_error_pct):
        assert f">{value:.4g}<" in section
    assert ">k13<" in section and "Rapp et al. 2022, eq. 20" in section
    assert "class=\"plotly-graph-div\"" in section


def test_decay_plots_show_the_fit_the_table_reports(campaign: Path, report: Path) -> None:
    """Every test with a log has its figure; the drawn fit is φ̂·e^(−δt)·cos(ωt − Φ) with the
    table's values (Rapp et al. 2022, eq. 13), the window shading is the table's window."""
    fits = _fits(report.read_text())
    table = pd.read_parquet(campaign / "results.parquet")
    assert sorted(fits) == [f"test_{i:05d}" for i in range(12)]
    row = table.iloc[7]
    fig = fits["test_00007"]
    fit_trace = next(t for t in fig["data"] if t["name"] == "fit (window)" and t.get("yaxis", "y") == "y")
    t_ms, angle_deg = _array(fit_trace["x"]).astype(float), _array(fit_trace["y"]).astype(float)
    t = t_ms / 1e3
    expected = row["initial_amplitude_deg"] * np.exp(-row["decay_coefficient_per_s"] * t) * np.cos(
        row["angular_frequency_rad_per_s"] * t - row["phase_rad"])
    np.testing.assert_allclose(angle_deg, expected, atol=2e-6 * np.abs(expected).max())  # float32 drawing
    assert t[0] == pytest.approx(row["window_start_s"], rel=1e-6) and t[-1] == pytest.approx(row["window_end_s"], rel=1e-6)
    shapes = fig["layout"]["shapes"]
    assert len(shapes) == 2 and shapes[0]["x1"] == pytest.approx(row["window_end_s"] * 1e3)
    assert {t["name"] for t in fig["data"]} == {"measured", "fit (window)", "fit, extrapolated"}
    assert any(t.get("yaxis") == "y2" for t in fig["data"])  # the torque panel


def test_results_table_report_and_cli(campaign: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`extract --out` of the campaign's logs, then `droptower report TABLE`: the logs are found
    beside the table, named relative to it; the map is the same."""
    logs = tmp_path / "logs"
    shutil.copytree(campaign / "logs", logs)
    table = tmp_path / "results.csv"
    assert main(["extract", *map(str, sorted(logs.glob("*.parquet"))), "--out", str(table)]) == 0
    assert main(["report", str(table), "--out", str(tmp_path / "out" / "r.html"), "--form", "velocity"]) == 0
    err = capsys.readouterr().err  # a summary line for every file written
    assert f"droptower: wrote {table} (12 test(s) x " in err
    assert f"droptower: wrote {tmp_path / 'out' / 'r.html'} (HTML report, " in err
    text = (tmp_path / "out" / "r.html").read_text()
    assert str(tmp_path) not in text
    assert "simulated logs (coupling rapp2022_nr60)" in text and "logs found for 12" in text
    assert sorted(_fits(text)) == [f"logs/test_{i:05d}.parquet" for i in range(12)]
    assert "Form <b>velocity</b>" in text


def test_bad_input_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["report", str(tmp_path / "nothing")]) == 2
    assert capsys.readouterr().err.strip().endswith("nothing: no such file")
    (tmp_path / "folder").mkdir()
    assert main(["report", str(tmp_path / "folder")]) == 2
    err = capsys.readouterr().err
    assert "not a campaign folder" in err and err.count("\n") == 1
    (tmp_path / "r.txt").write_text("x")  # text tables are read (lab exports), this one has no results
    assert main(["report", str(tmp_path / "r.txt")]) == 2
    err = capsys.readouterr().err
    assert "r.txt: results table lacks column(s) amplitude_deg" in err and err.count("\n") == 1
    (tmp_path / "r.yaml").write_text("x: 1")
    assert main(["report", str(tmp_path / "r.yaml")]) == 2
    assert "unsupported table format '.yaml'" in capsys.readouterr().err


# ---- in the browser ---------------------------------------------------------------------------
def _chrome():
    """Debian's chromium driven by its chromedriver (selenium), or a skip naming what is missing."""
    webdriver = pytest.importorskip("selenium.webdriver", reason="selenium is not installed (pip install '.[test]')")
    from selenium.webdriver.chrome.service import Service

    browser, driver = shutil.which("chromium"), shutil.which("chromedriver")
    if browser is None or driver is None:
        pytest.skip("Debian's chromium and chromium-driver are not installed (apt-get install chromium chromium-driver)")
    options = webdriver.ChromeOptions()
    options.binary_location = browser
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--window-size=1280,1000"):
        options.add_argument(arg)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    return webdriver.Chrome(service=Service(driver), options=options)


#: one browser per process for the pages that are only loaded and read (the report, the split
#: report, the two routes): a start of Chromium costs more than most of these tests
_SHARED: list = []


def shared_chrome():
    """The process's Chromium (:func:`_chrome`, quit at exit), back at 1280 x 1000 px with the
    log of earlier pages read away, so a test sees its own page's messages only."""
    if not _SHARED:
        browser = _chrome()
        atexit.register(browser.quit)
        _SHARED.append(browser)
    browser = _SHARED[0]
    browser.set_window_size(1280, 1000)
    browser.get("about:blank")
    browser.get_log("browser")
    return browser


@pytest.mark.slow
def test_report_in_headless_chromium(report: Path, tmp_path: Path) -> None:
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    chrome = shared_chrome()
    try:
        chrome.get(report.as_uri())
        wait = WebDriverWait(chrome, 30)
        rows = "return document.querySelectorAll('#tests-table tbody tr').length"
        wait.until(lambda d: d.execute_script(rows) == 12)  # the table library has drawn the table
        wait.until(lambda d: d.execute_script("return document.querySelector('#decay .main-svg') !== null"))
        before = chrome.execute_script(
            "return [...document.querySelectorAll('#tests-table tbody tr')].map(tr => tr.children[0].textContent)")
        assert before == [f"test_{i:05d}" for i in range(12)]  # in test order until sorted

        # sort by amplitude: the header of the scrolled table is a copy of the table's own
        column = chrome.execute_script(
            "return [...document.querySelectorAll('#tests-table thead th')].findIndex(th => th.textContent.startsWith('amplitude'))")
        assert column > 0
        def sort_by_amplitude(state: str, on: str) -> list[float]:
            """Click the column's title text or its sort arrow (DataTables: ascending, descending,
            none) and wait until the header says ``state``; the column's numbers as shown."""
            th = next(th for th in chrome.find_elements(By.XPATH, "//th[starts-with(normalize-space(.), 'amplitude')]")
                      if th.is_displayed())
            th.find_element(By.CSS_SELECTOR, "span.dt-column-title" if on == "title" else "span.dt-column-order").click()
            wait.until(lambda d: th.get_attribute("aria-sort") == state)
            return chrome.execute_script(
                "return [...document.querySelectorAll('#tests-table tbody tr')].map("
                f"tr => parseFloat(tr.children[{column}].textContent)).filter(v => !isNaN(v))")

        ascending = sort_by_amplitude("ascending", on="title")  # a click on the title's text sorts
        descending = sort_by_amplitude("descending", on="arrow")
        assert len(ascending) == 11  # the failed test has no amplitude
        assert ascending == sorted(ascending) and ascending != sorted(ascending, reverse=True)
        assert descending == sorted(ascending, reverse=True)

        # a test's link draws its decay fit
        chrome.find_element(By.LINK_TEXT, "test_00009").click()
        wait.until(lambda d: d.find_element(By.ID, "decay-title").text == "test_00009")
        title = "return (document.querySelector('#decay .gtitle') || {}).textContent || ''"
        wait.until(lambda d: d.execute_script(title).startswith("f = "))

        severe = [e for e in chrome.get_log("browser") if e["level"] in ("SEVERE", "ERROR")]
        assert severe == [], severe
        assert chrome.execute_script("return document.documentElement.scrollWidth") <= 1280  # no sideways scroll

        chrome.set_window_size(1280, 1000)
        height = chrome.execute_script("return document.documentElement.scrollHeight")
        chrome.set_window_size(1280, min(height, 6000))
        chrome.execute_script("window.scrollTo(0, 0)")
        shot = tmp_path / "report_1280.png"
        assert chrome.save_screenshot(str(shot))
        png = shot.read_bytes()
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and int.from_bytes(png[16:20], "big") == 1280
        print(f"\nscreenshot: {shot}")
    finally:
        chrome.set_window_size(1280, 1000)
