"""The files a validation writes into its output folder (:func:`write_validation`; the ``validate`` command's) (also used by ``analysis/run_study.py``).

- ``validation.csv`` (or the table format asked for): one row per servo point (:data:`droptower.compare.map_vs_servo.COLUMNS`);
- ``validation_summary.json``: RMS / max deviations inside and outside the range, definitions;
- ``servo_results.csv``: the servo points as measured or simulated (read back by
  :func:`droptower.compare.servo_points.read_servo_results`);
- ``fig14_servo_validation.png``: Rapp et al. 2022, Fig. 14;
- with a reference map: ``reference_comparison.csv`` and ``reference_summary.json``.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd

from droptower.campaign.folder import write_json
from droptower.compare.fig14 import FIG14, plot_fig14
from droptower.compare.servo_points import ServoPoints
from droptower.compare.map_vs_servo import ServoComparison
from droptower.errors import DroptowerError, make_folder
from droptower.io.tables import write_table
from droptower.maps import MapFit


def write_csv(path: Path, table: pd.DataFrame) -> Path:
    """``table`` as CSV at ``path`` (:func:`droptower.io.tables.write_table`)."""
    return write_table(table, path)


def output_folder(out: str | Path, create: bool = True) -> Path:
    """``out``, created if needed (``create``); a file in its place or an unwritable parent is a
    one-line error."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise DroptowerError("exists and is not a folder", file=out)
    if not create:
        return out
    make_folder(out)
    return out


def write_validation(out: str | Path, validation: ServoComparison, fit: MapFit, points: ServoPoints,
                     reference: tuple[pd.DataFrame, dict[str, Any]] | None = None,
                     table_suffix: str = ".csv") -> list[Path]:
    """Write the files of the module docstring into ``out`` (the tables as ``table_suffix``:
    .csv, .parquet, .json or .xlsx); returns them."""
    out = output_folder(out)
    files = [write_table(validation.table, out / f"validation{table_suffix}"),
             write_json(out / "validation_summary.json", validation.summary),
             write_table(points.raw, out / f"servo_results{table_suffix}"),
             plot_fig14(validation, fit, out / FIG14)]
    if reference is not None:
        files += [write_table(reference[0], out / f"reference_comparison{table_suffix}"),
                  write_json(out / "reference_summary.json", reference[1])]
    return files
