"""A map's results straight from a lab's folder of drop-test logs: every log extracted as
``droptower extract`` does (:func:`droptower.extract.files.extract_drops`), one row per drop, the
geometry used stored with each row, so a plain folder (not a campaign) maps in one call.

The lever length, the laser radius and each log's inertia come, in this order, from the
arguments, the log's metadata (with ``conditions``: the file's row of the conditions table), and
the rig (its inertia only where it has a single fixture). A log that cannot be evaluated is a
row with ``status`` ``failed`` and its ``error``: the batch goes on and the map lists it.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable, Mapping

import pandas as pd

from droptower.errors import DroptowerError, missing_file

#: Suffixes of the logs a folder is searched for (what the readers take from a lab's export).
LOG_SUFFIXES = (".csv", ".txt", ".dat", ".asc", ".tsv", ".parquet", ".mf4", ".mdf", ".bin", ".tdms", ".mat", ".h5")


def is_log_folder(path: str | Path) -> bool:
    """A folder holding logs and no campaign (no ``results.parquet``, no ``manifest.json``)."""
    p = Path(path)
    campaign = (p / "results.parquet").is_file() or (p / "manifest.json").is_file()
    return p.is_dir() and not campaign and any(log_files(p, strict=False))


def log_files(folder: str | Path, strict: bool = True, exclude: Iterable[str | Path] = ()) -> list[Path]:
    """The logs of a folder (:data:`LOG_SUFFIXES`, sorted by name), without the files in
    ``exclude`` (the conditions table lying beside them); ``strict``: none is an error naming it."""
    folder = Path(folder)
    if not folder.is_dir():
        raise missing_file(folder)
    skip = {Path(p).resolve() for p in exclude}
    found = sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in LOG_SUFFIXES
                   and p.resolve() not in skip)
    if strict and not found:
        raise DroptowerError(f"no logs ({', '.join(LOG_SUFFIXES)}) in the folder", file=folder)
    return found


def rig_defaults(rig: Any) -> dict[str, float]:
    """What a rig gives logs that do not say it: lever length (m), laser radius (m), and the
    inertia (kg*m^2) where the rig has one fixture."""
    if rig is None:
        return {}
    out = {"lever_length_m": float(rig.lever_length_m), "sensor_radius_m": float(rig.sensors.laser.radius_m)}
    if len(rig.inertias_kgm2) == 1:
        out["inertia_kgm2"] = float(rig.inertias_kgm2[0])
    return out


def results_from_logs(paths: str | Path | Iterable[str | Path], *, rig: Any = None,
                      inertia_kgm2: float | None = None, lever_length_m: float | None = None,
                      sensor_radius_m: float | None = None, roles: Mapping[str, str] | None = None,
                      conditions: Any = None, exclude: Iterable[str | Path] = ()) -> pd.DataFrame:
    """Extract every drop of the logs into a results table (the extractor's columns).

    Parameters
    ----------
    paths : path or paths
        Log files or folders of logs.
    rig : RigConfig, optional
        Lever length (m), laser radius (m) and a single fixture's inertia (kg*m^2) where the
        logs do not say them; its name is stored in the ``rig`` column.
    inertia_kgm2, lever_length_m, sensor_radius_m : float, optional
        Overrides of every log's inertia (kg*m^2), lever length (m), laser radius (m).
    roles : dict, optional
        Channel role -> ``NAME[:UNIT]``.
    conditions : Conditions, optional
        Per-file conditions (fixture or inertia, drop mass and height, preload, temperature).
    exclude : paths
        Files of the folders that are not logs (the conditions table beside them).

    Returns
    -------
    DataFrame
        One row per drop (``file`` as found, ``status`` done or failed, ``error``), with
        ``lever_length_m`` and ``sensor_radius_m`` used and the rig's name where known.
    """
    from droptower.extract.files import Settings, extract_drops, result_row

    files: list[Path] = []
    if conditions is not None and Path(str(conditions.source)).is_file():  # the table beside the logs is not a log
        exclude = [*exclude, conditions.source]
    for p in map(Path, [paths] if isinstance(paths, (str, Path)) else paths):
        files += log_files(p, exclude=exclude) if p.is_dir() else [p]
    extra = {"conditions": conditions} if conditions is not None else {}
    settings = Settings(roles=dict(roles or {}), inertia_kgm2=inertia_kgm2, lever_length_m=lever_length_m,
                        defaults=rig_defaults(rig), sensor_radius_m=sensor_radius_m, rig=rig, **extra)
    geometry = {"lever_length_m": lever_length_m or settings.defaults.get("lever_length_m"),
                "sensor_radius_m": sensor_radius_m or settings.defaults.get("sensor_radius_m"),
                "rig": (rig.name or "rig") if rig is not None else None}
    several = None
    if rig is not None and inertia_kgm2 is None and len(rig.inertias_kgm2) > 1:
        named = getattr(rig, "fixtures", None) or {}
        several = (", ".join(f"{n} {j:g}" for n, j in named.items()) if named
                   else ", ".join(f"{j:g}" for j in rig.inertias_kgm2)) + " kg*m^2"
    rows: list[dict[str, Any]] = []

    def failed(path: Path, exc: DroptowerError, **more: Any) -> dict[str, Any]:
        problem = exc.problem
        if several is not None and problem.startswith("no rotating inertia"):
            # `rig` was given: what is missing is which of its fixtures this log is
            problem = (f"no rotating inertia: the rig has several lever fixtures ({several}) and nothing says which "
                       "one this log is: give `conditions` (each file's fixture or inertia)")
        return {"file": str(path), **more, "status": "failed", "error": problem}

    for path in files:
        try:
            drops = extract_drops(path, settings)
        except DroptowerError as exc:
            rows.append(failed(path, exc))
            continue
        for drop in drops:
            if drop.error is not None:
                rows.append(failed(path, drop.error, drop_index=drop.span.index))
                continue
            row = result_row(path, drop.signals, drop.result, drop.span.index)
            row["status"] = "done"
            for key, value in geometry.items():  # the geometry used, stored with the result
                if value is not None and key not in row:
                    row[key] = value
            rows.append(row)
    return pd.DataFrame(rows)
