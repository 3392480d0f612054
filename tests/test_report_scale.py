"""A report of many tests: past ``inline_max_tests`` the decay figures go to side files beside
the page, loaded when a test is chosen (forced here at 12 tests with a limit of 4 and 5 per
file); the page keeps every section, every test stays reachable, and in headless Chromium a
test's link loads its side file and draws its fit, with no console error and no network."""
from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from droptower.report import write_report
from test_report import _fits, campaign, shared_chrome  # noqa: F401  (the 12-test campaign fixture)


@pytest.fixture(scope="module")
def split(campaign: Path, tmp_path_factory, monkeypatch_module) -> Path:  # noqa: F811
    monkeypatch_module.setattr("droptower.report.FITS_PER_FILE", 5)
    return write_report(campaign, tmp_path_factory.mktemp("split") / "big report.html", inline_max_tests=4)


@pytest.fixture(scope="module")
def monkeypatch_module():
    with pytest.MonkeyPatch.context() as mp:
        yield mp


def _files(text: str) -> dict[str, str]:
    match = re.search(r"<script type='application/json' id='decay-files'>(.*?)</script>", text, re.S)
    return json.loads(match.group(1).replace("<\\/", "</"))


@pytest.mark.slow
def test_figures_go_to_side_files_and_every_test_stays_reachable(campaign: Path, split: Path) -> None:  # noqa: F811
    text = split.read_text()
    files = _files(text)
    assert _fits(text) == {}  # every test of the campaign has a figure: none inline
    assert sorted(files) == [f"test_{i:05d}" for i in range(12)]
    assert sorted(set(files.values())) == [f"big%20report_files/fits_{k:04d}.js" for k in range(3)]  # 5 + 5 + 2
    for k, (name, url) in enumerate(sorted(files.items())):
        assert url.endswith(f"fits_{k // 5:04d}.js") and f"href='#fit-{name}'" in text
    side = split.parent / "big report_files"
    figures = {}
    for path in sorted(side.glob("fits_*.js")):
        body = path.read_text()
        assert body.startswith("droptowerFits(") and body.rstrip().endswith(");")
        figures |= json.loads(body.strip()[len("droptowerFits("):-2])
    assert sorted(figures) == sorted(files)
    # typed arrays (base64 float32), thinned traces: ~6.5 kB per test keeps 4 500 tests within 40 MB
    per_test = sum(p.stat().st_size for p in side.glob("fits_*.js")) / len(files)
    assert per_test <= 7500, per_test
    assert figures["test_00007"]["data"][0]["y"]["dtype"] == "f4"
    assert {t["name"] for t in figures["test_00007"]["data"]} == {"measured", "fit (window)", "fit, extrapolated"}
    for heading in ("Summary", "Failures and flags", "Characteristic map", "Tests", "Decay fit"):
        assert f"<h2>{heading}</h2>" in text
    assert str(campaign.parent) not in text and "http" not in "".join(re.findall(r"src=['\"][^'\"]*", text))
    inline = write_report(campaign, split.parent / "inline.html")  # the default limit: one page as before
    assert _fits(inline.read_text()) == figures and not (split.parent / "inline_files").exists()  # the same figures


@pytest.mark.slow
def test_split_report_in_headless_chromium(split: Path) -> None:
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    chrome = shared_chrome()
    chrome.get(split.as_uri())
    wait = WebDriverWait(chrome, 30)
    rows = "return document.querySelectorAll('#tests-table tbody tr').length"
    wait.until(lambda d: d.execute_script(rows) == 12)
    title = "return (document.querySelector('#decay .gtitle') || {}).textContent || ''"
    wait.until(lambda d: d.execute_script(title).startswith("f = "))  # the first test, from the first file
    assert chrome.find_element(By.ID, "decay-title").text == "test_00000"
    chrome.find_element(By.LINK_TEXT, "test_00011").click()  # in the third side file
    wait.until(lambda d: d.find_element(By.ID, "decay-title").text == "test_00011")
    wait.until(lambda d: d.execute_script(title).startswith("f = ") and
               d.execute_script("return document.getElementById('decay-message').textContent") == "")
    loaded = chrome.execute_script("return [...document.querySelectorAll('head script[src]')].map(s => s.src)")
    assert [src.rsplit("/", 1)[1] for src in loaded] == ["fits_0000.js", "fits_0002.js"]  # on demand only
    severe = [e for e in chrome.get_log("browser") if e["level"] in ("SEVERE", "ERROR")]
    assert severe == [], severe
