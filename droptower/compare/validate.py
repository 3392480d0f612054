"""``validate``: a characteristic map against servo sweeps (and a measured map), as one call.

The map (a :class:`~droptower.maps.MapFit` or its ``map.json``) against the docs/theory.md#servo
sweeps run on the virtual servo bench (or measured servo results), optionally against a
measured map such as Rapp et al. 2022, Table 4 (with the campaign interpolated at its rows), and
a model-based map beside the paper's (docs/routes.md). The result prints its summary, converts
to a table (the sweep points) or a dict, and writes its files. ``droptower validate`` is a thin
layer over it.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import pandas as pd

from droptower.compare.servo_points import ServoPoints
from droptower.compare.validation import Validation
from droptower.configs import DEFAULT_COUPLING
from droptower.errors import DroptowerError
from droptower.maps.mapfit import MapFit


@dataclass
class MapValidation:
    """The result of :func:`validate`.

    validation: the map vs the servo points (table and summary); fit: the map; points: the servo
    points; reference: (rows, summary) of the comparison with a measured map, or None;
    routes: route name -> its :class:`~droptower.compare.validation.Validation` (the paper's map
    and the model-based map against the same points), or None; model_route: the model-based
    map's route name; reference_name: the measured map's file name.
    """

    validation: Validation
    fit: MapFit
    points: ServoPoints
    reference: tuple[pd.DataFrame, dict[str, Any]] | None = None
    routes: dict[str, Validation] | None = None
    model_route: str | None = None
    reference_name: str = "Table 4"

    @property
    def summary_dict(self) -> dict[str, Any]:
        """Per region (inside, outside, all of the map's range): points, RMS and max deviations (%)."""
        return self.validation.summary

    def to_frame(self) -> pd.DataFrame:
        """One row per servo point: map and servo stiffness and damping, deviations (%), region."""
        return self.validation.table.copy()

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: the summary and points, the reference comparison and the routes where given."""
        from droptower.jsonsafe import json_safe

        doc: dict[str, Any] = {"summary": self.validation.summary,
                               "points": self.validation.table.to_dict(orient="records")}
        if self.reference is not None:
            doc["reference"] = {"summary": self.reference[1], "rows": self.reference[0].to_dict(orient="records")}
        if self.routes is not None:
            doc["routes"] = {name: {"summary": v.summary, "points": v.table.to_dict(orient="records")}
                             for name, v in self.routes.items()}
        return json_safe(doc)

    def summary(self) -> str:
        """The deviations as text (and the routes' and the reference comparison's)."""
        from droptower.compare.reference_map import format_comparison
        from droptower.compare.validation import format_routes, format_summary

        lines = [format_summary(self.validation)]
        if self.routes is not None:
            lines.append(format_routes(self.routes))
        if self.reference is not None:
            lines.append(format_comparison(self.reference[1], self.reference_name))
        return "\n".join(lines)

    def write(self, out: str | Path, table_format: str = "csv") -> list[Path]:
        """Write validation, validation_summary.json, servo_results, fig14_servo_validation.png (and
        the reference comparison, the routes) into the folder ``out``; tables as ``table_format``
        (csv, parquet, json or xlsx). Returns the files."""
        from droptower.compare.files import write_validation
        from droptower.io.tables import write_table

        files = write_validation(out, self.validation, self.fit, self.points, self.reference,
                                 table_suffix=f".{table_format}")
        if self.routes is not None:
            from droptower.compare.validation import route_table

            out = Path(out)
            files.append(write_table(route_table(self.routes), out / f"validation_routes.{table_format}", "out"))
            files.append(write_table(self.routes[self.model_route].table,
                                     out / f"validation_model_map.{table_format}", "out"))
        return files

    def __repr__(self) -> str:
        s = self.validation.summary.get("all", {})
        figures = ", ".join(f"{k} {v:.3g}" for k, v in s.items() if isinstance(v, float) and "rms" in k)
        return f"<MapValidation: {len(self.validation.table)} servo points{'; ' + figures if figures else ''}>"

    def _repr_html_(self) -> str:
        return f"<pre>{self.summary()}</pre>"


def validate(map_fit: MapFit | str | Path, coupling: str | Path = DEFAULT_COUPLING, *,
             servo_results: str | Path | None = None, servo_columns: Mapping[str, str] | None = None,
             reference: str | Path | None = None, results: str | Path | pd.DataFrame | None = None,
             model_map: Any = None, quick: bool = False, rig: Any = None,
             roles: Mapping[str, str] | None = None, sensor_radius_m: float | None = None,
             conditions: Any = None) -> MapValidation:
    """Validate a characteristic map against servo-hydraulic sweeps (Rapp et al. 2022, Fig. 14).

    Parameters
    ----------
    map_fit : MapFit or path
        The map (:class:`~droptower.maps.MapFit`) or its ``map.json``.
    coupling : str or path
        The coupling (TOML or preset) the sweeps are run with on the virtual servo bench.
    servo_results : path, optional
        Measured servo results (a table) instead of the virtual bench.
    servo_columns : dict, optional
        Name -> ``SOURCE[:UNIT]`` of ``servo_results``' columns (lab names are found without it).
    reference : path, optional
        A measured map table (e.g. Rapp et al. 2022, Table 4) to compare with as well.
    results : path or DataFrame, optional
        With ``reference``: the campaign (folder, results table, DataFrame, or a lab's folder of
        logs, extracted with ``rig``, ``roles``, ``sensor_radius_m`` and ``conditions``)
        interpolated at each reference row.
    model_map : ModelMap or path, optional
        A model-based map (:class:`~droptower.compare.model_map.ModelMap` or its
        ``model_map.json``): both routes against the same servo points.
    quick : bool
        Fewer sweep steps.
    rig : RigConfig, optional
        The rig of a lab's logs given as ``results``: lever length (m), laser radius (m), fixtures.
    roles : dict, optional
        Channel role -> ``NAME[:UNIT]`` for reading those logs.
    sensor_radius_m : float, optional
        Laser spot radius (m) for their distance channel.
    conditions : Conditions, optional
        Their per-file conditions (fixture or inertia, drop mass and height, temperature).

    Returns
    -------
    MapValidation
        Deviations (map / servo - 1, %) inside and outside the map's measured range.

    Examples
    --------
    >>> v = validate("map.json", "rapp2022_nr60", quick=True)  # doctest: +SKIP
    >>> v.to_frame().head()  # doctest: +SKIP
    """
    from droptower.compare.reference_map import compare_reference, read_reference
    from droptower.compare.servo_points import read_servo_results, run_sweeps
    from droptower.compare.validation import validate_map
    from droptower.maps import read_results

    if results is not None and reference is None:
        raise DroptowerError("`results` needs `reference` (the measured map to compare the campaign with)")
    if servo_columns and servo_results is None:
        raise DroptowerError("`servo_columns` needs `servo_results` (the table whose columns it names)")
    fit = map_fit if isinstance(map_fit, MapFit) else MapFit.from_json(map_fit)
    reference_table = read_reference(reference) if reference is not None else None
    if isinstance(results, pd.DataFrame) or results is None:
        campaign = results
    else:
        from droptower.maps.fromlogs import is_log_folder, results_from_logs

        skip = [conditions.source] if conditions is not None and Path(str(conditions.source)).is_file() else []
        campaign = (results_from_logs(results, rig=rig, roles=roles, sensor_radius_m=sensor_radius_m,
                                      conditions=conditions, exclude=skip)
                    if is_log_folder(results) else read_results(results))
    points = (read_servo_results(servo_results, dict(servo_columns or {})) if servo_results is not None
              else run_sweeps(coupling, reduced=quick))
    validation = validate_map(fit, points)
    comparison = compare_reference(reference_table, fit, campaign) if reference_table is not None else None
    routes = route = None
    if model_map is not None:
        from droptower.compare.model_map import PAPER_ROUTE, ModelMap
        from droptower.compare.validation import validate_routes

        mm = model_map if isinstance(model_map, ModelMap) else ModelMap.from_json(model_map)
        route = mm.route
        routes = validate_routes({PAPER_ROUTE: fit, mm.route: mm}, points, hull=fit)
    return MapValidation(validation, fit, points, comparison, routes, route,
                         Path(reference).name if reference is not None else "Table 4")
