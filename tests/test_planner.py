"""`droptower planner`: one offline HTML page whose predictions are the planner's (a grid,
interpolated in log height) and whose design is `droptower design`'s, checked in headless
Chromium: no console errors, the controls change the prediction, a target dragged on the plot
designs a campaign, and the downloaded plan equals `design --out` and runs with `campaign --doe`."""
from __future__ import annotations

import re
import time
import tomllib
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from droptower.cli.main import main
from droptower.design import Target, design_campaign, predict_candidates
from droptower.design.choose import CONDITION_KEYS, LEVEL_STEP_DECADES, RECORD_S, _choose, contiguous_feasible, _unreachable
from droptower.design.coverage import plane
from droptower.design.outputs import coverage_description, doe_document
from droptower.errors import DroptowerError
from droptower.planner.grid import GRID_HEIGHTS, REFINE_TOLERANCE, _grid
from droptower.rheology import load_coupling
from droptower.rig.config import load_rig
from droptower.rig.predictions import plan
from test_report import shared_chrome  # Debian's chromium via selenium, or a skip naming what is missing
from droptower.cli.flags import cli_text

PRELOADS = (0.0, 500.0)
#: A small target (one lever's band): a campaign of a few drops.
SMALL = {"amplitude_deg": [0.5, 0.7], "frequency_hz": [44.0, 47.0]}


@pytest.fixture(scope="session")  # kept when worksteal splits this file: a second block reuses it
def shipped():
    rig, coupling = load_rig("rapp2022"), load_coupling("rapp2022_nr60")
    return rig, coupling, predict_candidates(rig, coupling, PRELOADS)


@contextmanager
def shipped_candidates(shipped):
    """``choose.predict_candidates`` answering the call ``shipped`` made (the rig, coupling and
    preloads compared) with its candidates, any other call computed anew: the page and design
    commands below predict the same candidates once per module. Yields the calls answered."""
    from droptower.design import choose
    from droptower.rheology import coupling_to_toml

    rig, coupling, cands = shipped
    computed = choose.predict_candidates
    answered = []

    def predict_candidates(r, c, preloads_nm, *args, **kwargs):
        if (not args and not kwargs and r == rig and coupling_to_toml(c) == coupling_to_toml(coupling)
                and tuple(map(float, preloads_nm)) == PRELOADS):
            answered.append(True)
            return cands.copy()
        return computed(r, c, preloads_nm, *args, **kwargs)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(choose, "predict_candidates", predict_candidates)
        yield answered


@pytest.fixture(scope="session")  # kept when worksteal splits this file: a second block reuses it
def page(tmp_path_factory, shipped) -> Path:
    """The page `droptower planner` writes for the shipped rig and coupling."""
    out = tmp_path_factory.mktemp("planner") / "planner.html"
    with shipped_candidates(shipped) as answered:
        assert main(["planner", "--out", str(out), "--preloads-nm", "0,500", "--quiet"]) == 0
    assert answered == [True]  # the page's rig, coupling and preloads are those of `shipped`
    return out


def test_page_is_self_contained(page: Path) -> None:
    text = page.read_text()
    assert not re.search(r"<script[^>]*\ssrc=", text) and not re.search(r"<link[^>]*href=['\"]?https?:", text)
    assert text.count("<script type='text/javascript'>") == 1  # plotly.js embedded once
    assert "function chooseDrops" in text and str(page.parent) not in text


def test_the_page_speaks_python_unless_the_command_line_writes_it(page: Path, shipped, tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """The library's page tells its reader the Python call that runs a saved plan; the page the
    command writes tells the shell command, and differs in nothing else (the hint is text around
    the grid: the library's page is written here from the grid the command predicted)."""
    import html
    import json

    from droptower.cli.planner_cmd import RUN_HINT as SHELL_HINT
    from droptower.planner import page as planner_page
    from droptower.planner import write_planner

    shell_page = page.read_text(encoding="utf-8")
    found = re.search(r"<script type='application/json' id='planner-data'>(.*?)</script>", shell_page, re.S)
    data = json.loads(found.group(1))
    monkeypatch.setattr(planner_page, "planner_data", lambda *args: data)
    python_page = write_planner(*shipped[:2], PRELOADS, tmp_path / "python.html").read_text(encoding="utf-8")
    assert "run_campaign(" in python_page and "--doe" not in python_page
    assert "droptower campaign --doe plan.toml" in shell_page and "run_campaign(" not in shell_page
    assert python_page == shell_page.replace(html.escape(SHELL_HINT), html.escape(planner_page.RUN_HINT))


def test_bad_input_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["planner", "--out", str(tmp_path / "p.txt")]) == 2
    err = capsys.readouterr().err
    assert "p.txt: --out: the planner is an HTML page" in err and err.count("\n") == 1
    assert main(["planner", "--out", str(tmp_path / "p.html"), "--preloads-nm", "0,2000"]) == 2
    err = capsys.readouterr().err
    assert "preload 2000 N*m is outside the range 0-1000 N*m of rig rapp2022" in err and err.count("\n") == 1
    assert not (tmp_path / "p.html").exists()


def test_grid_is_refined_where_interpolation_misses(shipped) -> None:
    """Where a coupling's response jumps (the previous reference coupling, rapp2022_nr60_payne, on
    the heaviest lever at 1000 N*m preload between 0.074 and 0.085 m after the rig's 60 s preload
    hold: its rest logic; between 0.195 and 0.219 m after the former 30 s hold) the grid's
    heights close in; elsewhere interpolation in log height stays within the refinement
    tolerance of a direct prediction at random heights (seeded)."""
    rig = shipped[0]
    coupling = load_coupling("rapp2022_nr60_payne")
    heights, pred = _grid(rig, coupling, [(0.5233, 1.0, 1000.0)], GRID_HEIGHTS)
    assert len(heights) > GRID_HEIGHTS and len(pred) == len(heights)
    jump = (heights > 0.07) & (heights < 0.09)
    assert np.min(np.diff(np.log(heights[jump]))) < np.log(1.02)
    h = np.exp(np.random.default_rng(3).uniform(np.log(0.3), np.log(rig.drop_height_range_m[1]), 8))
    direct = plan(rig, coupling, pd.DataFrame([("x", 0.5233, 1.0, x, 1000.0) for x in h], columns=CONDITION_KEYS),
                  RECORD_S)
    for q in ("amplitude_deg", "frequency_hz"):
        np.testing.assert_allclose(np.interp(np.log(h), np.log(heights), pred[q]), direct[q], rtol=REFINE_TOLERANCE)


# ---- in the browser ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def chrome(page: Path, tmp_path_factory):
    """The process's Chromium (test_report.py's, started once per process) on the planner page,
    its downloads going to a folder of this module's."""
    downloads = tmp_path_factory.mktemp("downloads")
    browser = shared_chrome()
    browser.downloads = downloads
    browser.execute_cdp_cmd("Browser.setDownloadBehavior", {"behavior": "allow", "downloadPath": str(downloads)})
    browser.get(page.as_uri())
    browser.set_script_timeout(60)
    assert browser.execute_async_script(
        "const done = arguments[0]; window.planner.ready.then(() => done('ready'), e => done(String(e)))") == "ready"
    yield browser
    browser.get("about:blank")  # the next module's page starts from a blank one


def wait_for(condition, seconds: float = 10.0) -> bool:
    """Poll ``condition`` until it holds (True) or ``seconds`` pass (False)."""
    end = time.monotonic() + seconds
    while not condition():
        if time.monotonic() > end:
            return False
        time.sleep(0.1)
    return True


def _severe(chrome) -> list:
    return [e for e in chrome.get_log("browser") if e["level"] in ("SEVERE", "ERROR")]


def test_interpolated_predictions_are_the_planners(chrome, shipped) -> None:
    """At random heights between the grid's (seeded), the page's prediction is within 1 % of a
    direct prediction (amplitude, frequency, peak torque, impact force; clearance within 0.1 mm)."""
    rig, coupling, _ = shipped
    rng = np.random.default_rng(17)
    levers, masses = sorted(rig.inertias_kgm2), sorted(rig.drop_masses_kg)
    picks = [(rng.integers(len(levers)), rng.integers(len(masses)), rng.integers(len(PRELOADS)),
              float(np.exp(rng.uniform(*np.log(rig.drop_height_range_m))))) for _ in range(12)]
    shown = pd.DataFrame([chrome.execute_script("return window.planner.predict(...arguments)", int(lv), int(m), int(p), h)
                          for lv, m, p, h in picks]).astype(float)
    direct = plan(rig, coupling, pd.DataFrame([("x", levers[lv], masses[m], h, PRELOADS[p]) for lv, m, p, h in picks],
                                              columns=CONDITION_KEYS), RECORD_S)
    ok = direct["first_period_s"].notna().to_numpy()
    assert ok.sum() >= 10
    for q in ("amplitude_deg", "frequency_hz", "peak_torque_nm", "impact_force_peak_n"):
        np.testing.assert_allclose(shown[q][ok], direct[q][ok], rtol=0.01, err_msg=q)
    np.testing.assert_allclose(shown["min_clearance_mm"][ok], direct["min_clearance_mm"][ok], atol=0.1)


def test_page_chooses_what_design_chooses(chrome, shipped) -> None:
    """Random targets (seeded; some of one frequency, some with wider level spacing): the page's
    drops equal choose.py's, bit for bit, and so do its sentences on what is unreachable; the
    plan (budget included) equals doe_document's but for the covered percentage in its
    description, which comes from the final predictions (direct in Python at the campaign's
    record length, interpolated here) and may differ by a point; errors are design's."""
    rig, coupling, cands = shipped
    feasible = contiguous_feasible(cands)
    all_pts = plane(feasible["amplitude_deg"], feasible["frequency_hz"])
    rng = np.random.default_rng(2026)
    said = 0
    for k in range(24):
        a0 = 10 ** rng.uniform(-1.3, 0.3)
        a1, f0 = a0 * 10 ** rng.uniform(0, 1.2), rng.uniform(18, 50)
        f1 = f0 if k % 6 == 0 else f0 + rng.uniform(0, 25)
        target, step = Target((a0, a1), (f0, f1), PRELOADS), LEVEL_STEP_DECADES * 1.25 ** (k % 3)
        js = chrome.execute_script("return window.planner.chooseDrops(arguments[0], arguments[1])",
                                   {"amplitude_deg": [a0, a1], "frequency_hz": [f0, f1]}, step)
        assert [(d["j"], d["m"], d["h"]) for d in js] == _choose(rig, feasible, target, step), (target, step)
        js = chrome.execute_script("return window.planner.unreachable(arguments[0])",
                                   {"amplitude_deg": [a0, a1], "frequency_hz": [f0, f1]})
        assert js == _unreachable(target, all_pts, feasible, rig), target
        said += len(js)
    assert said >= 10  # the targets reach beyond the rig: there was something to say
    targets = []
    for max_tests in (None, 14, 40, 6):
        a0, f0 = 10 ** rng.uniform(-1, 0), rng.uniform(22, 40)
        targets.append(({"amplitude_deg": [a0, a0 * 10 ** rng.uniform(0.2, 1)],
                         "frequency_hz": [f0, f0 + rng.uniform(3, 20)]}, max_tests))
    targets.append(({"amplitude_deg": [5.0, 8.0], "frequency_hz": [80.0, 90.0]}, None))  # beyond the rig
    errors = 0
    for t, max_tests in targets:
        doc = chrome.execute_script(
            "const d = window.planner.designCampaign(arguments[0], 3, arguments[1]);"
            "return d.error || window.planner.doeDocument(d, 'plan')", t, max_tests)
        try:
            designed = design_campaign(rig, coupling, Target(*t.values(), PRELOADS), max_tests=max_tests,
                                       candidates=cands)
            expected = doe_document(designed.conditions, "plan", coverage_description(designed))
        except DroptowerError as exc:  # a budget too small, a target beyond the rig: the page says so as design
            assert doc == cli_text(exc.problem)  # the page speaks the command's words
            errors += 1
            continue
        strip = re.compile(r"\d+ % of the target covered")
        assert strip.sub("", doc.pop("description")) == strip.sub("", expected.pop("description"))
        assert doc == expected, t
    assert errors == 2


def test_the_controls_change_the_prediction(chrome) -> None:
    from selenium.webdriver.support.ui import Select

    def shown() -> tuple[str, ...]:
        return tuple(chrome.find_element("id", f"pred-{q}").text
                     for q in ("amplitude_deg", "frequency_hz", "peak_torque_nm", "min_clearance_mm"))

    first = shown()
    height = chrome.find_element("id", "height")
    height.clear()
    height.send_keys("2\n")
    higher = shown()
    assert float(higher[0]) > float(first[0]) and float(higher[1]) < float(first[1])  # the coupling softens
    Select(chrome.find_element("id", "mass")).select_by_index(1)
    assert float(shown()[0]) > float(higher[0])  # the heavier drop mass gives the lever more momentum
    Select(chrome.find_element("id", "lever")).select_by_index(2)
    heavier = shown()
    assert float(heavier[1]) < float(higher[1])  # a heavier lever swings slower
    Select(chrome.find_element("id", "preload")).select_by_index(1)
    chrome.execute_async_script("const done = arguments[0]; setTimeout(done, 300)")
    assert float(shown()[2]) > float(heavier[2]) + 400  # the screw's 500 N*m adds to the torque
    slider = chrome.find_element("id", "height-slider")
    chrome.execute_script("arguments[0].value = 0.2; arguments[0].dispatchEvent(new Event('input'))", slider)
    assert float(chrome.find_element("id", "height").get_attribute("value")) < 0.05
    assert _severe(chrome) == []


@pytest.mark.slow
def test_drag_a_target_and_download_the_plan_that_design_writes(chrome, shipped, tmp_path: Path) -> None:
    """A box dragged on the plot becomes the target; the small target typed then designs a plan
    whose download equals `droptower design --out` (text and parsed) and runs with `campaign --doe`."""
    from selenium.webdriver.common.action_chains import ActionChains

    before = chrome.find_element("id", "design-summary").text
    drag = chrome.find_element("css selector", "#plane .nsewdrag")
    ActionChains(chrome).move_to_element_with_offset(drag, -150, -100).click_and_hold().move_by_offset(
        200, 150).release().perform()
    assert wait_for(lambda: chrome.find_element("id", "design-summary").text != before)
    lo, hi = (float(chrome.find_element("id", i).get_attribute("value")) for i in ("a-lo", "a-hi"))
    assert 0.05 < lo < hi < 3 and chrome.execute_script("return document.getElementById('plane').layout.shapes.length") == 1

    for field, value in zip(("a-lo", "a-hi", "f-lo", "f-hi", "repeats"), (*SMALL["amplitude_deg"], *SMALL["frequency_hz"], 1)):
        box = chrome.find_element("id", field)
        box.clear()
        box.send_keys(f"{value:g}\n")
    chrome.find_element("id", "download").click()
    downloaded = chrome.downloads / "plan.toml"
    assert wait_for(downloaded.exists), "no download"
    text = downloaded.read_text()
    assert text == chrome.execute_script("return window.planner.toml()")
    assert _severe(chrome) == []

    expected = tmp_path / "plan.toml"
    with shipped_candidates(shipped) as answered:
        assert main(["design", "--amplitude-deg", "0.5:0.7", "--frequency-hz", "44:47", "--preloads-nm", "0,500",
                     "--repeats", "1", "--out", str(expected), "--quiet"]) == 0
    assert answered == [True]
    assert tomllib.loads(text) == tomllib.loads(expected.read_text())
    assert text == expected.read_text()
    plan_toml = tmp_path / "downloaded.toml"
    plan_toml.write_text(text)
    assert main(["campaign", "--doe", str(plan_toml), "--out", str(tmp_path / "run"), "--workers", "1", "--quiet"]) == 0
    results = pd.read_parquet(tmp_path / "run" / "results.parquet")
    doc = tomllib.loads(text)
    assert len(results) == sum(len(g["heights_m"]) for g in doc["group"]) * len(PRELOADS)
    assert (results["status"] == "done").all() and not results["double_impact"].any()


def test_screenshot(chrome, tmp_path: Path) -> None:
    """The page at 1280 px: no sideways scroll; the screenshot is a PNG of that width."""
    assert chrome.execute_script("return document.documentElement.scrollWidth") <= 1280
    shot = tmp_path / "planner_1280.png"
    assert chrome.save_screenshot(str(shot))
    png = shot.read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and int.from_bytes(png[16:20], "big") == 1280
    print(f"\nscreenshot: {shot}")
