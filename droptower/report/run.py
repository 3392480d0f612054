"""What a report is about: a campaign folder or an extraction's results table, read into
one :class:`Run` (facts for the summary, the results table, where each test's log is, and how
its log was extracted so the decay fit can be drawn again).

Names shown in the report are relative (to the campaign folder, or as the results table lists
them): a report never shows the machine's absolute paths.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from droptower.errors import DroptowerError, missing_file
from droptower.maps.results import read_results

#: Why a flag is raised (droptower.extract.extractor), shown next to every flagged test.
FLAG_REASONS = {
    "double_impact": "a second impact within the first period or the fit window restarts the decay (docs/theory.md#double-impact)",
    "clipping": "a channel sits at its extreme: the peaks are cut",
    "too_few_samples_per_period": "fewer than 20 samples per period",
    "short_window": "the fit window is shorter than the requested one (three quarters of a period at least)",
    "poor_fit": "the decay fit's RMS residual exceeds 5 % of the amplitude",
    "double_impact_unchecked": "no impact-force channel: a second impact could not be checked (warning)",
    "decay_cut_by_next_drop": "the next drop of the recording came before this drop's oscillation died out",
    # the geometry cross-checks (droptower.extract.geometry; docs/guide/extraction.md#the-geometry-used)
    "stiffness_m2_m1_deviation": "the torque's stiffness (M2) and the angle's (M1) differ by more than 20 %: "
                                 "the inertia, the lever length or the laser radius used is not the rig's",
    "laser_torque_amplitude_mismatch": "the laser's amplitude disagrees with the torque's amplitude over the "
                                       "fitted stiffness by more than 20 %: the laser radius used is not the rig's",
    "impact_energy_mismatch": "the lever's speed after the impact from the decay disagrees with the impulse's or "
                              "the impact law's (drop mass, height, inertia, lever length) by more than 25 %",
}


@dataclass
class Run:
    """One campaign or results table.

    kind: ``campaign`` or ``results table``; name: shown in the title; facts: (label, text)
    pairs for the summary; table: one row per test (the extractor's columns); test: a short
    name per row (``test_00042`` or the log's file name); logs: the log per row (None: not
    found); extract: keyword arguments of :class:`droptower.extract.files.Settings` that
    extract the logs as the run did; rig: the lab's rig (RigConfig) given for real logs, None
    otherwise.
    """

    kind: str
    name: str
    facts: list[tuple[str, str]]
    table: pd.DataFrame
    test: list[str]
    logs: list[Path | None]
    extract: dict[str, Any] = field(default_factory=dict)
    rig: Any = None


def load_run(source: str | Path, *, rig: Any = None, roles: dict[str, str] | None = None,
             sensor_radius_m: float | None = None, conditions: Any = None, inertia_kgm2: float | None = None,
             lever_length_m: float | None = None) -> Run:
    """A campaign folder (``manifest.json``, ``results.parquet``, ``logs/``), a results table
    (any format ``droptower map`` reads) whose ``file`` column names the logs, or a lab's folder
    of logs (extracted here, :func:`droptower.maps.fromlogs.results_from_logs`); one-line errors
    otherwise.

    rig (RigConfig), sensor_radius_m (m), conditions (:class:`~droptower.io.conditions.Conditions`),
    roles (channel mapping), inertia_kgm2 (kg*m^2, every log's) and lever_length_m (m): how a lab's logs are read, for the folder's extraction and for
    drawing the decays of a results table again (where its rows do not store the geometry)."""
    from droptower.io.logsettings import rig_defaults
    from droptower.maps.fromlogs import is_log_folder

    source = Path(source)
    if source.is_dir():
        if (source / "manifest.json").is_file():
            return _campaign(source)
        if is_log_folder(source):
            return _log_folder(source, rig, roles, sensor_radius_m, conditions, inertia_kgm2, lever_length_m)
        raise DroptowerError("a folder without manifest.json (not a campaign folder) and without logs; give a results table of the "
                             "extraction (its results file), a campaign folder or a folder of logs", file=source)
    if not source.is_file():
        raise missing_file(source)
    run = _results_table(source)
    defaults = {**_table_geometry(run.table), **rig_defaults(rig)}
    if lever_length_m is not None:
        defaults["lever_length_m"] = lever_length_m
    run.extract = {"defaults": defaults, "sensor_radius_m": sensor_radius_m,
                   **({"conditions": conditions} if conditions is not None else {})}
    if rig is not None:
        run.facts.insert(1, ("geometry", rig.geometry_text() if hasattr(rig, "geometry_text") else str(rig.name)))
    run.rig = rig
    return run


def _table_geometry(table: pd.DataFrame) -> dict[str, float]:
    """The lever length and laser radius (m) a results table's rows store, where all agree."""
    out = {}
    for column in ("lever_length_m", "sensor_radius_m"):
        if column in table.columns:
            values = pd.to_numeric(table[column], errors="coerce").dropna().unique()
            if len(values) == 1:
                out[column] = float(values[0])
    return out


def _log_folder(folder: Path, rig: Any, roles: dict[str, str] | None, sensor_radius_m: float | None,
                conditions: Any, inertia_kgm2: float | None = None, lever_length_m: float | None = None) -> Run:
    from droptower.io.logsettings import rig_defaults
    from droptower.maps.fromlogs import log_files, results_from_logs

    skip = [conditions.source] if conditions is not None and Path(str(conditions.source)).is_file() else []
    logs = log_files(folder, exclude=skip)
    table = results_from_logs(logs, rig=rig, roles=roles, sensor_radius_m=sensor_radius_m, conditions=conditions,
                              inertia_kgm2=inertia_kgm2, lever_length_m=lever_length_m)
    drops = table["drop_index"] if "drop_index" in table.columns else [None] * len(table)
    names = [Path(str(f)).name + (f" drop {int(k)}" if k is not None and pd.notna(k) and k > 1 else "")
             for f, k in zip(table["file"], drops)]
    paths = [Path(str(f)) for f in table["file"]]
    failed = int((table.get("status") == "failed").sum()) if "status" in table.columns else 0
    facts = [("folder", folder.resolve().name), ("logs", f"{len(logs)} real log(s), {failed} failed extraction")]
    if rig is not None:
        facts.append(("geometry", rig.geometry_text() if hasattr(rig, "geometry_text") else str(rig.name)))
    if conditions is not None:
        facts.append(("conditions", Path(str(conditions.source)).name))
    extract = {"defaults": {**rig_defaults(rig), **({"lever_length_m": lever_length_m} if lever_length_m else {})},
               "sensor_radius_m": sensor_radius_m,
               **({"conditions": conditions} if conditions is not None else {})}
    return Run("log folder", folder.resolve().name, facts, table, names, paths, extract, rig)


def _campaign(root: Path) -> Run:
    from droptower.campaign.folder import read_manifest

    manifest = read_manifest(root / "manifest.json")
    table_path = root / "results.parquet"
    if not table_path.is_file():
        raise DroptowerError("campaign folder without results.parquet (no test finished yet?)", file=root)
    table = pd.read_parquet(table_path)
    inputs = manifest.get("inputs", {})
    content = {k: (inputs.get(k) or {}).get("content") or {} for k in ("rig", "coupling", "doe")}
    summary = manifest.get("summary", {})
    settings = manifest.get("settings", {})
    facts = [
        ("rig", _described(content["rig"])),
        ("coupling", _described(content["coupling"]) + " (simulated)"),
        ("plan", f"{_described(content['doe'])}: {summary.get('n_tests', len(table))} tests"),
        ("tests", f"{summary.get('done', 0)} extracted, {summary.get('failed', 0)} failed, "
                  f"{summary.get('pending', 0)} pending"),
        ("settings", ", ".join(f"{k} = {v}" for k, v in settings.items())),
        ("run", f"created {manifest.get('created', '?')}, updated {manifest.get('updated', '?')}, droptower "
                f"{manifest.get('versions', {}).get('droptower', '?')}"),
    ]
    rig = content["rig"]
    extract: dict[str, Any] = {"window": settings.get("window", "first-cycle")}
    if "lever_length_m" in rig:
        extract["defaults"] = {"lever_length_m": float(rig["lever_length_m"])}
    laser = (rig.get("sensors") or {}).get("laser") or {}
    if "radius_m" in laser:
        extract["sensor_radius_m"] = float(laser["radius_m"])
    names = [Path(str(f)).stem if isinstance(f, str) and f else f"test_{t}" for f, t in
             zip(table.get("log_file", [None] * len(table)), table.get("test_id", range(len(table))))]
    logs = [root / f if isinstance(f, str) and f and (root / f).is_file() else None
            for f in table.get("log_file", [None] * len(table))]
    return Run("campaign", root.resolve().name, facts, table, names, logs, extract)


def _described(content: dict[str, Any]) -> str:
    name = content.get("name", "?")
    description = content.get("description")
    return f"{name} ({description})" if description else str(name)


def _results_table(path: Path) -> Run:
    table = read_results(path)
    files = [str(f) if isinstance(f, str) and f else None for f in table.get("file", [None] * len(table))]
    logs = [_find_log(f, path.parent) for f in files]
    names = [_shown(f, path.parent) if f else f"row {i + 1}" for i, f in enumerate(files)]
    if "drop_index" in table.columns:  # a recording with several drops: one test per drop
        repeated = pd.Series(files).duplicated(keep=False).to_numpy()
        names = [f"{n} drop {int(k)}" if again and pd.notna(k) else n
                 for n, k, again in zip(names, table["drop_index"], repeated)]
    simulated = "coupling" in table.columns and table["coupling"].notna().any()
    source = (f"simulated logs (coupling {', '.join(map(str, table['coupling'].dropna().unique()))})"
              if simulated else "real logs")
    counts = f"{len(table)} tests, logs found for {sum(p is not None for p in logs)}"
    facts = [("results table", path.name), ("logs", source), ("tests", counts)]
    if "rig" in table.columns and table["rig"].notna().any():
        facts.insert(1, ("rig", ", ".join(map(str, table["rig"].dropna().unique()))))
    return Run("results table", path.stem, facts, table, names, logs, {})


def _find_log(name: str | None, base: Path) -> Path | None:
    """The log as listed (absolute, or relative to the working folder of the extraction, which
    may be the table's folder or the current one)."""
    if not name:
        return None
    for candidate in (Path(name), base / name):
        if candidate.is_file():
            return candidate
    return None


def _shown(name: str, base: Path) -> str:
    """A log's name without the machine's absolute path: relative to the table's folder where
    it lies below it, else the file name."""
    p = Path(name)
    if not p.is_absolute():
        return name
    try:
        return os.path.relpath(p, base.resolve()) if p.is_relative_to(base.resolve()) else p.name
    except ValueError:
        return p.name
