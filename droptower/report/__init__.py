"""``droptower report``: one self-contained HTML report of a campaign folder or of an
extraction's results table with its logs.

:func:`write_report` reads the run (:mod:`droptower.report.run`), fits the map
(:func:`droptower.maps.fit_map`), draws the decay fit of every test over its log's trace
(:mod:`droptower.report.decays`, in worker processes) and writes the page
(:mod:`droptower.report.page`).
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any
from urllib.parse import quote

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from droptower.errors import DroptowerError, make_folder
from droptower.io.droptower_log import atomic_write
from droptower.maps import MapFit, fit_map, select_tests
from droptower.maps.coverage import coverage_notes
from droptower.maps.results import flag_list
from droptower.report import figures
from droptower.report.decays import Drawing
from droptower.report.page import fit_link, map_section, page, plain_table, tests_table
from droptower.report.run import FLAG_REASONS, Run, load_run

#: Columns of the per-test table, in order, where the results have them (name shown: unit in brackets).
TEST_COLUMNS = {
    "case": "case", "fixture": "fixture", "inertia_kgm2": "J [kg·m²]", "drop_mass_kg": "m [kg]", "drop_height_m": "h [m]",
    "preload_nm": "preload [N·m]", "temperature_c": "T [°C]", "amplitude_deg": "amplitude [deg]",
    "frequency_hz": "f [Hz]", "stiffness_nm_per_deg": "c [N·m/deg]", "damping_ratio": "d [-]",
    "fit_error": "fit error [-]",
}
#: Significant digits of the numbers in the per-test table (sorting uses the rounded numbers).
DIGITS = 4
#: Up to this many tests the decay figures are inside the page; beyond, in side files
#: (:data:`FITS_PER_FILE` tests each) loaded when a test is chosen: 4 500 tests inline made an
#: 88 MB page that took minutes to open.
INLINE_MAX_TESTS = 500
FITS_PER_FILE = 100


def default_out(source: str | Path) -> Path:
    """``DIR/report.html`` for a campaign folder, ``<table>.html`` beside a results table."""
    source = Path(source)
    return source / "report.html" if source.is_dir() else source.with_suffix(".html")


def write_report(source: str | Path, out: str | Path | None = None, form: str = "paper",
                 channels: dict[str, str] | None = None, extra_sections: list[tuple[str, str]] | None = None,
                 title: str | None = None, progress: bool = False, inline_max_tests: int = INLINE_MAX_TESTS,
                 workers: int | None = None, *, rig: Any = None, sensor_radius_m: float | None = None,
                 conditions: Any = None, run: Run | None = None, strict: bool = True,
                 inertia_kgm2: float | None = None, lever_length_m: float | None = None) -> Path:
    """Write the report of ``source`` (campaign folder, results table or a lab's folder of logs) to ``out``.

    form: the map form (``paper``, ``velocity``, ``auto``); channels: role -> ``NAME[:UNIT]``
    for reading real logs (as the extraction's channel roles); extra_sections: (heading, HTML) pairs
    appended (the study's); inline_max_tests: more tests than this put their decay figures in
    side files in ``<out stem>_files/`` beside the page; workers: processes drawing the decay
    figures (None: every local core, 1: this process); rig (RigConfig), sensor_radius_m (m),
    conditions (:class:`~droptower.io.conditions.Conditions`), inertia_kgm2 (kg*m^2), lever_length_m (m):
    how real logs are read
    (:func:`~droptower.report.run.load_run`); run: the run already loaded; strict: a usable test
    (one the map uses) whose decay cannot be drawn is a DroptowerError saying why, and no page is
    written (else the page lists it); returns the path of the page."""
    if run is None:
        run = load_run(source, rig=rig, roles=channels, sensor_radius_m=sensor_radius_m, conditions=conditions,
                       inertia_kgm2=inertia_kgm2, lever_length_m=lever_length_m)
    out = Path(out) if out is not None else default_out(source)
    with Drawing(run, channels or {}, progress, workers) as drawing:  # the decay figures, meanwhile the rest
        fit, map_error, usable_mask, excluded_reason, sections = _map_and_tests(run, source, form)
        fits = drawing.result()
    if strict:
        check_drawn(run, usable_mask, fits)
    problems = _problems(run, usable_mask, excluded_reason, fits)
    fit_files = None
    if len(fits) > inline_max_tests:
        fits, fit_files = _write_fit_files(fits, out)
    text = page(title or f"droptower report: {run.name}", run.facts + _counts(run, usable_mask, fit), problems,
                *sections, fits, extra_sections or [], fit_files)
    make_folder(out.parent)
    atomic_write(out, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))
    return out


def check_drawn(run: Run, usable: np.ndarray, fits: dict[str, object]) -> None:
    """Raise a one-line DroptowerError when a test the map uses has no decay figure: how many,
    and the first one's reason (its log missing, or the geometry to read it with)."""
    missing = [(name, fits.get(name)) for name, ok in zip(run.test, usable) if ok and isinstance(fits.get(name), str)]
    if not missing and fits and all(isinstance(f, str) for f in fits.values()):
        # not one decay drawn (no test usable either): the logs could not be read, say why
        name, why = next(iter(fits.items()))
        raise DroptowerError(f"none of the {len(fits)} decays can be drawn, e.g. {name}: {why}; no report written")
    if not missing:
        return
    name, why = missing[0]
    raise DroptowerError(f"{len(missing)} of {int(np.sum(usable))} usable decays cannot be drawn, e.g. {name}: {why}; "
                         "no report written")


def _map_and_tests(run: Run, source: str | Path, form: str) -> tuple[MapFit | None, str | None, np.ndarray,
                                                                      dict[int, str], tuple[str, str]]:
    """The map (its fit or why there is none), which tests it used and why others were left
    out, and the HTML of the map's section and of the per-test table."""
    table = run.table
    usable = None
    fit, map_error, usable_mask, excluded_reason = None, None, np.zeros(len(table), bool), {}
    try:
        usable, excluded = select_tests(table, source)
        usable_mask = table.index.isin(usable.index)
        excluded_reason = dict(zip(np.flatnonzero(~usable_mask), (e.reason for e in excluded)))
        # the map's least squares factor a (tests x a few) Jacobian hundreds of times: BLAS
        # threads cannot speed up so thin a matrix, and on a busy machine they made the map of
        # 4 500 tests ten times slower (54 s against 5 s, measured on 2 loaded cores)
        with threadpool_limits(limits=1, user_api="blas"):
            fit = fit_map(table, source=_shown_source(source), form=form)
        fit.coverage = tuple(coverage_notes(table, usable, excluded, rig=run.rig))
    except DroptowerError as exc:
        map_error = exc.message
    map_figure = figures.map_figure(usable, [n for n, ok in zip(run.test, usable_mask) if ok], fit) if fit else None
    sections = (map_section(fit, map_error, map_figure), tests_table(_tests(run, usable_mask, excluded_reason, fit)))
    return fit, map_error, usable_mask, excluded_reason, sections


def _write_fit_files(fits: dict[str, object], out: Path) -> tuple[dict[str, object], dict[str, str]]:
    """The decay figures in side files of :data:`FITS_PER_FILE` tests, ``<out stem>_files/fits_NNNN.js``
    (a script calling ``droptowerFits({...})``: a page opened from disk may load scripts, not
    read JSON files). Returns what stays in the page (the tests without a figure, with the
    reason) and, per test with a figure, the side file's URL relative to the page."""
    folder = out.parent / f"{out.stem}_files"
    make_folder(folder)
    for stale in folder.glob("fits_*.js"):  # of an earlier report with more tests
        stale.unlink()
    inline = {name: fig for name, fig in fits.items() if isinstance(fig, str)}
    drawn = [name for name, fig in fits.items() if not isinstance(fig, str)]
    files = {}
    for k in range(0, len(drawn), FITS_PER_FILE):
        names = drawn[k:k + FITS_PER_FILE]
        path = folder / f"fits_{k // FITS_PER_FILE:04d}.js"
        # plain json: the figures are plain data (plotly's encoder parses and writes each file
        # twice); a NaN is a number in a script, as it is not in JSON
        text = f"droptowerFits({json.dumps({n: fits[n] for n in names}, separators=(',', ':'))});\n"
        atomic_write(path, lambda tmp, text=text: Path(tmp).write_text(text, encoding="utf-8"))
        url = f"{quote(folder.name)}/{path.name}"
        files.update(dict.fromkeys(names, url))
    return inline, files


def _shown_source(source: str | Path) -> str:
    """The source as the user gave it if relative, else its name (no absolute paths in the page)."""
    p = Path(source)
    return p.name if p.is_absolute() else str(p)


def _counts(run: Run, usable: np.ndarray, fit: MapFit | None) -> list[tuple[str, str]]:
    flagged = sum(bool(flag_list(v)) for v in run.table.get("flags", []))
    return [("map", f"{int(usable.sum())} tests used, {len(run.table) - int(usable.sum())} excluded, "
                    f"{flagged} with flags" + (f"; form {fit.form.name}" if fit else ""))]


def _problems(run: Run, usable: np.ndarray, excluded_reason: dict[int, str], fits: dict[str, object]) -> str:
    """Failed tests, tests left out of the map and flagged tests, each with its reason."""
    t = run.table
    n = len(t)

    def column(name: str, default: object) -> list:  # plain lists: a 4 500-test loop of .iloc took seconds
        return t[name].tolist() if name in t.columns else [default] * n

    statuses, errors, flags, warnings_ = (column("status", "done"), column("error", None), column("flags", None),
                                          column("simulation_warnings", None))
    rows = []
    for i, name in enumerate(run.test):
        status = str(statuses[i])
        reasons = []
        if status == "failed":
            reasons.append(("failed", f"extraction failed: {errors[i]}" if "error" in t.columns else "failed"))
        if i in excluded_reason and status != "failed":
            reasons.append(("excluded from the map", excluded_reason[i]))
        for flag in flag_list(flags[i]) if "flags" in t.columns else []:
            reasons.append((f"flag {flag}", FLAG_REASONS.get(flag, "see the extractor's documentation")))
        warnings = warnings_[i]
        if isinstance(warnings, str) and warnings:
            reasons.append(("simulation warning", warnings))
        if isinstance(fits.get(name), str):
            reasons.append(("no decay plot", fits[name]))
        rows += [{"test": fit_link(name), "what": what, "reason": why} for what, why in reasons]
    if not rows:
        return "<p class='ok'>No failures, no flags: every test went into the map.</p>"
    table = pd.DataFrame(rows)
    order = {"failed": 0, "excluded from the map": 1}
    table = table.iloc[np.argsort(table["what"].map(order).fillna(2).to_numpy(), kind="stable")]
    n_failed = sum(table["what"] == "failed")
    n_excluded = sum(table["what"] == "excluded from the map")
    head = (f"<p><span class='{'bad' if n_failed else 'ok'}'>{n_failed} failed</span>, "
            f"<span class='{'warn' if n_excluded else 'ok'}'>{n_excluded} excluded from the map</span>, "
            f"{len(table) - n_failed - n_excluded} other notes.</p>")
    return head + plain_table(table, html_columns=("test",))


def _tests(run: Run, usable: np.ndarray, excluded_reason: dict[int, str], fit: MapFit | None) -> pd.DataFrame:
    """The per-test table: link, status, flags, map use, plan and extracted values, map deviations."""
    t = run.table
    out = pd.DataFrame({"test": [fit_link(n) for n in run.test]})
    out["status"] = t["status"].astype(str).to_numpy() if "status" in t.columns else "done"
    out["flags"] = [", ".join(flag_list(v)) for v in t["flags"]] if "flags" in t.columns else ""
    failed = out["status"].to_numpy() == "failed"
    out["in map"] = ["yes" if ok else "no: failed" if failed[i] else f"no: {excluded_reason.get(i, '')}"
                     for i, ok in enumerate(usable)]
    for column, label in TEST_COLUMNS.items():
        if column in t.columns:
            values = pd.to_numeric(t[column], errors="coerce")
            out[label] = _rounded(values.to_numpy(float)) if values.notna().any() or t[column].isna().all() else t[column]
    if fit is not None:
        a = pd.to_numeric(t["amplitude_deg"], errors="coerce").to_numpy(float)
        f = pd.to_numeric(t["frequency_hz"], errors="coerce").to_numpy(float)
        with np.errstate(invalid="ignore", divide="ignore"):
            out["map c dev. [%]"] = _rounded(100 * (fit.stiffness_nm_per_deg(a, f) / t["stiffness_nm_per_deg"].to_numpy(float) - 1))
            out["map d dev. [%]"] = _rounded(100 * (fit.damping_ratio(a, f) / t["damping_ratio"].to_numpy(float) - 1))
    return out


def _rounded(x: np.ndarray) -> np.ndarray:
    """To :data:`DIGITS` significant digits (NaN stays NaN)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = 10.0 ** (DIGITS - 1 - np.floor(np.log10(np.abs(x))))
        r = np.round(x * scale) / scale
    return np.where(np.isfinite(r), r, x)
