"""Benchmark: the report of a large campaign (``droptower report``), written and opened in Chromium.

Targets for 4 500 tests (unloaded 2-core machine): the page and its side files <= 40 MB,
written in <= 60 s, open in headless Chromium (the table drawn and the first test's decay fit
drawn) in <= 10 s. Prints those figures and the ratio of the writing time to a baseline
measured in the same run: reading back and extracting the same logs (every 10th, scaled), the
least a report that draws every test's fit again from its log must do. Also opens a test of
the last side file (its figure loaded on demand) and times it.

    python benchmarks/bench_report.py --campaign DIR      # a finished campaign folder
    python benchmarks/bench_report.py --n 4500            # first runs a campaign of 4 500 tests (Table 2
                                                          # x 50 repeats) in a temporary folder
    python benchmarks/bench_report.py --n 4500 --json benchmarks/results/report.json

The report draws every test's decay figure from the fit its results table stores and the
log's trace, in worker processes, while its own process fits the map; the baseline extracts
every log again, as the report did before.
"""
from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from pathlib import Path

from timing import json_option, write_figures

TARGET_MB = 40.0
TARGET_WRITE_S = 60.0
TARGET_OPEN_S = 10.0
BASELINE_EVERY = 10


def baseline_s(campaign: Path) -> float:
    """Seconds to read back and extract every log of the campaign (timed on every 10th)."""
    from droptower.extract.files import Settings, extract_file
    from droptower.report.run import load_run

    run = load_run(campaign)
    logs = [log for log in run.logs if log is not None]
    settings = Settings(defaults=run.extract.get("defaults", {}), sensor_radius_m=run.extract.get("sensor_radius_m"))
    sample = logs[::BASELINE_EVERY]
    extract_file(sample[0], settings)
    t0 = time.perf_counter()
    for log in sample:
        try:
            extract_file(log, settings)
        except Exception:
            pass  # a failing test costs its time all the same
    return (time.perf_counter() - t0) / len(sample) * len(logs)


def open_in_chromium(page: Path) -> tuple[float, float, int]:
    """(seconds until the table and the first decay fit are drawn, seconds to draw a test of the
    last side file, table rows in the DOM)."""
    import shutil as sh

    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.support.ui import WebDriverWait

    options = webdriver.ChromeOptions()
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1280,1000"):
        options.add_argument(arg)
    chrome = webdriver.Chrome(service=Service(sh.which("chromedriver")), options=options)
    try:
        wait = WebDriverWait(chrome, 120)
        title = "return (document.querySelector('#decay .gtitle') || {}).textContent || ''"
        t0 = time.perf_counter()
        chrome.get(page.as_uri())
        wait.until(lambda d: d.execute_script("return document.querySelectorAll('#tests-table tbody tr').length") > 0)
        wait.until(lambda d: d.execute_script(title).startswith("f = "))
        opened = time.perf_counter() - t0
        rows = chrome.execute_script("return document.querySelectorAll('#tests-table tbody tr').length")
        last = chrome.execute_script("const f = JSON.parse(document.getElementById('decay-files').textContent);"
                                     "const k = Object.keys(f); return k[k.length - 1] || null")
        t1 = time.perf_counter()
        if last:
            chrome.execute_script(f"location.hash = '#fit-' + encodeURIComponent({last!r})")
            wait.until(lambda d: d.find_element("id", "decay-title").text == last
                       and d.execute_script("return document.getElementById('decay-message').textContent") == ""
                       and d.execute_script(title).startswith("f = "))
        return opened, time.perf_counter() - t1, rows
    finally:
        chrome.quit()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    what = ap.add_mutually_exclusive_group(required=True)
    what.add_argument("--campaign", type=Path, help="a finished campaign folder")
    what.add_argument("--n", type=int, help="run a campaign of N tests first (the Table-2 plan, N / 90 repeats)")
    ap.add_argument("--no-browser", action="store_true", help="skip the Chromium measurement")
    json_option(ap)
    args = ap.parse_args()

    from droptower.report import write_report

    tmp = Path(tempfile.mkdtemp(prefix="bench_report_"))
    try:
        if args.campaign is None:
            from bench_campaign import plan_of

            from droptower.campaign import run_campaign
            from droptower.configs import DEFAULT_COUPLING, DEFAULT_RIG

            args.campaign = tmp / "campaign"
            t0 = time.perf_counter()
            run_campaign(args.campaign, DEFAULT_RIG, DEFAULT_COUPLING, plan_of(args.n, tmp), progress=False)
            print(f"campaign of {args.n} tests run in {time.perf_counter() - t0:.0f} s")
        out = tmp / "report.html"
        t0 = time.perf_counter()
        write_report(args.campaign, out)
        wall = time.perf_counter() - t0
        files = [out, *sorted((tmp / "report_files").glob("*"))] if (tmp / "report_files").is_dir() else [out]
        size_mb = sum(p.stat().st_size for p in files) / 1e6
        n = sum(1 for _ in (args.campaign / "logs").iterdir())
        print(f"report of {args.campaign.name}: {n} tests, load average {os.getloadavg()[0]:.2f}")
        print(f"  written in             {wall:7.1f} s   {1e3 * wall / n:.1f} ms per test "
              f"(target <= {TARGET_WRITE_S:g} s for 4 500: {'ok' if wall * 4500 / n <= TARGET_WRITE_S else 'MISSED'})")
        print(f"  size                   {size_mb:7.1f} MB  page {out.stat().st_size / 1e6:.1f} MB + "
              f"{len(files) - 1} side files (target <= {TARGET_MB:g} MB for 4 500: "
              f"{'ok' if size_mb * 4500 / n <= TARGET_MB else 'MISSED'})")
        figures = {"tests": n, "write_s": wall, "size_mb": size_mb, "load_average_after_write": round(os.getloadavg()[0], 2)}
        if not args.no_browser:
            opened, on_demand, rows = open_in_chromium(out)
            print(f"  opens in Chromium      {opened:7.1f} s   (table drawn, {rows} rows on its first page, and the "
                  f"first fit; target <= {TARGET_OPEN_S:g} s: {'ok' if opened <= TARGET_OPEN_S else 'MISSED'})")
            print(f"  a test of the last side file drawn in {on_demand:.2f} s")
            figures |= {"open_s": opened, "on_demand_s": on_demand}
        base = baseline_s(args.campaign)
        print(f"baseline (reading back and extracting the {n} logs, timed on every {BASELINE_EVERY}th): {base:.1f} s")
        print(f"report writing / baseline: {wall / base:.2f}")
        write_figures(args.json, "bench_report", figures | {"baseline_s": base})
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
