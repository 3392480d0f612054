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
from droptower.compare.map_vs_servo import ServoComparison
from droptower.configs import DEFAULT_COUPLING
from droptower.errors import DroptowerError
from droptower.maps.mapfit import MapFit


@dataclass
class MapValidation:
    """The result of :func:`validate`.

    validation: the map vs the servo points (table and summary); fit: the map; points: the servo
    points; reference: (rows, summary) of the comparison with a measured map, or None;
    routes: route name -> its :class:`~droptower.compare.map_vs_servo.ServoComparison` (the paper's map
    and the model-based map against the same points), or None; model_route: the model-based
    map's route name; reference_name: the measured map's file name; agreement: route name -> its
    E_n per servo point (:func:`droptower.uncertainty.route_agreement`), where the routes'
    expanded uncertainties are known, or None.
    """

    validation: ServoComparison
    fit: MapFit
    points: ServoPoints
    reference: tuple[pd.DataFrame, dict[str, Any]] | None = None
    routes: dict[str, ServoComparison] | None = None
    model_route: str | None = None
    reference_name: str = "Table 4"
    agreement: dict[str, pd.DataFrame] | None = None

    @property
    def summary_dict(self) -> dict[str, Any]:
        """Deprecated (removed in the next release): ``to_dict()["summary"]``, the same dict."""
        import warnings

        warnings.warn("MapValidation.summary_dict is deprecated: use MapValidation.to_dict()['summary']",
                      DeprecationWarning, stacklevel=2)
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
        if self.agreement is not None:
            doc["agreement"] = {name: t.to_dict(orient="records") for name, t in self.agreement.items()}
        return json_safe(doc)

    def summary(self) -> str:
        """The deviations as text (and the routes' and the reference comparison's)."""
        from droptower.compare.reference_map import format_comparison
        from droptower.compare.map_vs_servo import format_routes, format_summary

        lines = [format_summary(self.validation)]
        if self.routes is not None:
            lines.append(format_routes(self.routes))
        if self.reference is not None:
            lines.append(format_comparison(self.reference[1], self.reference_name))
        if self.agreement is not None:
            from droptower.uncertainty.agreement import format_agreement

            lines.append(format_agreement(self.agreement))
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
            from droptower.compare.map_vs_servo import route_table

            out = Path(out)
            files.append(write_table(route_table(self.routes), out / f"validation_routes.{table_format}", "out"))
            files.append(write_table(self.routes[self.model_route].table,
                                     out / f"validation_model_map.{table_format}", "out"))
        if self.agreement is not None:
            from droptower.io.tables import write_table

            table = pd.concat([t.assign(route=name) for name, t in self.agreement.items()], ignore_index=True)
            files.append(write_table(table, Path(out) / f"validation_en.{table_format}", "out"))
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
             conditions: Any = None, uncertainty: Any = None, servo_u95_rel: float | None = None) -> MapValidation:
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
    uncertainty : RigUncertainty, optional
        The rig's input uncertainties (:class:`droptower.uncertainty.RigUncertainty`): with it
        (or with ``servo_u95_rel``) each route gets E_n numbers per servo point
        (``agreement``). The paper's map's U95 (:func:`droptower.uncertainty.map_uncertainty`)
        needs ``results``, the tests it was fitted to; the model-based map's is its own U95 where
        it was built with the inputs (its bands and each input's shift), else 2·std of its bands
        with the inertia's share on K' (see :func:`model_route_u95`). Not given: the inputs the
        map (``map.json``'s ``input_uncertainty``) or the model map was computed with, if any.
    servo_u95_rel : float, optional
        The bench's own relative expanded uncertainty (0.02: 2 %) for every point where the servo
        table gives none (columns ``servo_stiffness_nm_per_deg_U95``, ``servo_damping_ratio_U95``).

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
    from droptower.compare.map_vs_servo import compare_with_servo
    from droptower.maps import read_results

    judged = uncertainty is not None or servo_u95_rel is not None
    if results is not None and reference is None and not judged:
        raise DroptowerError("`results` needs `reference` (the measured map to compare the campaign with) or "
                             "`uncertainty` (the paper map's expanded uncertainty is computed from its tests)")
    if servo_columns and servo_results is None:
        raise DroptowerError("`servo_columns` needs `servo_results` (the table whose columns it names)")
    fit = map_fit if isinstance(map_fit, MapFit) else MapFit.from_json(map_fit)
    mm = None
    if model_map is not None:
        from droptower.compare.model_map import ModelMap

        mm = model_map if isinstance(model_map, ModelMap) else ModelMap.from_json(model_map)
    if uncertainty is None and judged:  # the inputs the maps were computed with (map.json, model_map.json)
        stored = fit.input_uncertainty or (mm.input_uncertainty if mm is not None else None)
        if stored:
            from droptower.rig.uncertainty import RigUncertainty

            uncertainty = RigUncertainty.model_validate(stored)
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
    validation = compare_with_servo(fit, points)
    comparison = compare_reference(reference_table, fit, campaign) if reference_table is not None else None
    routes = route = None
    if mm is not None:
        from droptower.compare.model_map import PAPER_ROUTE
        from droptower.compare.map_vs_servo import validate_routes

        route = mm.route
        routes = validate_routes({PAPER_ROUTE: fit, mm.route: mm}, points, hull=fit)
    agreement = _agreement(fit, validation, routes, mm, campaign, uncertainty, servo_u95_rel, points) \
        if judged else None
    return MapValidation(validation, fit, points, comparison, routes, route,
                         Path(reference).name if reference is not None else "Table 4", agreement)


def model_route_u95(model_map: Any, table: pd.DataFrame, inertia_u_rel: float = 0.0) -> dict[str, Any]:
    """The model-based map's expanded uncertainties (k = 2) at the validation table's points.

    A map built with the rig's input uncertainties (``model_map.input_sets``: each input's shift
    of the identification, :mod:`droptower.uncertainty.route`) gives its own ``<q>_U95``: the
    bands' standard uncertainty (the fit's, cluster-robust) and every input's share in quadrature.
    Without them: the bands and, for the storage stiffness K', the inertia's share K'·u_J/J (a J
    error scales the stiffness the identification finds from the decays, c = J(ω² + δ²); an upper
    figure where the flange's torque is fitted too), the loss factor and d without inputs.
    Quantity -> U95 per point; empty without bands."""
    import numpy as np

    if not model_map.has_bands:
        return {}
    grid = model_map.evaluate(table["amplitude_deg"].to_numpy(float), table["frequency_hz"].to_numpy(float))
    k, d = "storage_stiffness_nm_per_deg", "drop_tower_equivalent_damping_ratio"
    if f"{k}_U95" in grid.columns:
        return {"stiffness_nm_per_deg": grid[f"{k}_U95"].to_numpy(), "damping_ratio": grid[f"{d}_U95"].to_numpy()}
    u_k = np.hypot(grid[f"{k}_std"].to_numpy(), grid[k].to_numpy() * inertia_u_rel)
    return {"stiffness_nm_per_deg": 2.0 * u_k, "damping_ratio": 2.0 * grid[f"{d}_std"].to_numpy()}


def model_map_with_inputs(model_map: Any, inertia_u_rel: float) -> Any:
    """A copy of a model-based map whose grid's bands (95 %) hold the inputs' share too: each
    quantity's ``<q>_U95`` where the map carries its inputs' shifted sets, else K' ±
    1.96·√(std² + (K'·u_J/J)²), the fit's band and J's in quadrature (:func:`model_route_u95`).
    For the figures (``plot_model_map``); a map without bands or grid is returned as it is."""
    from dataclasses import replace

    import numpy as np

    from droptower.compare.model_map import QUANTITIES, Z95

    grid = model_map.grid
    q = "storage_stiffness_nm_per_deg"
    if grid is None or f"{q}_std" not in grid.columns:
        return model_map
    grid = grid.copy()
    if f"{q}_U95" in grid.columns:
        for name in QUANTITIES:
            u = grid[f"{name}_U95"] / 2.0
            grid[f"{name}_band_lo"], grid[f"{name}_band_hi"] = grid[name] - Z95 * u, grid[name] + Z95 * u
        return replace(model_map, grid=grid, band_method=f"{model_map.band_method}; with the rig's inputs "
                       f"({', '.join(model_map.input_sets)}; GUM)", _cache={})
    if not inertia_u_rel > 0:
        return model_map
    u = np.hypot(grid[f"{q}_std"], grid[q] * inertia_u_rel)
    grid[f"{q}_band_lo"], grid[f"{q}_band_hi"] = grid[q] - Z95 * u, grid[q] + Z95 * u
    return replace(model_map, grid=grid, band_method=f"{model_map.band_method}; with J's {100 * inertia_u_rel:.3g} % "
                                                    "on K' (the inputs, GUM)", _cache={})


def inertia_u_rel(uncertainty: Any, campaign: pd.DataFrame | None) -> float:
    """The relative standard uncertainty J carries into an identification over every fixture:
    each fixture's u_J/J weighted by its share of the tests (independent fixtures; GUM 5.1.2),
    or the largest given without the tests; 0 where none is given."""
    import numpy as np

    entries = list(getattr(uncertainty, "inertias_kgm2", None) or [])
    if not entries:
        return 0.0
    if campaign is None or "inertia_kgm2" not in campaign.columns:
        return max(e.standard / e.nominal for e in entries)
    inertias = pd.to_numeric(campaign["inertia_kgm2"], errors="coerce").to_numpy(float)
    weights = np.array([np.isclose(inertias, e.nominal, rtol=1e-6).sum() for e in entries], float) / inertias.size
    return float(np.sqrt(sum((w * e.standard / e.nominal) ** 2 for w, e in zip(weights, entries))))


def _agreement(fit: MapFit, validation: ServoComparison, routes: dict[str, ServoComparison] | None, mm: Any,
               campaign: pd.DataFrame | None, uncertainty: Any, servo_u95_rel: float | None,
               points: ServoPoints) -> dict[str, pd.DataFrame]:
    """E_n per servo point of each route whose expanded uncertainty is known."""
    from droptower.compare.model_map import PAPER_ROUTE
    from droptower.uncertainty import map_uncertainty, route_agreement

    paper_table = routes[PAPER_ROUTE].table if routes is not None else validation.table
    out: dict[str, pd.DataFrame] = {}
    if campaign is not None:
        bands = map_uncertainty(campaign, uncertainty, map_fit=fit).predict(paper_table["amplitude_deg"],
                                                                             paper_table["frequency_hz"])
        u95 = {q: bands[f"{q}_U95"].to_numpy() for q in ("stiffness_nm_per_deg", "damping_ratio")}
        out[PAPER_ROUTE] = route_agreement(paper_table, u95, servo_u95=servo_u95_columns(points, paper_table),
                                           u95_ref_rel=servo_u95_rel)
    if routes is not None and mm is not None:
        table = routes[mm.route].table
        u95 = model_route_u95(mm, table, inertia_u_rel(uncertainty, campaign))
        if u95:
            out[mm.route] = route_agreement(table, u95, servo_u95=servo_u95_columns(points, table),
                                            u95_ref_rel=servo_u95_rel)
    return out


#: the servo table's columns of its own expanded uncertainty (95 %), per judged quantity, first found wins
SERVO_U95_COLUMNS: dict[str, tuple[str, ...]] = {
    "stiffness_nm_per_deg": ("servo_stiffness_nm_per_deg_U95", "storage_stiffness_nm_per_deg_U95"),
    "damping_ratio": ("servo_damping_ratio_U95", "drop_tower_equivalent_damping_ratio_U95"),
}


def servo_u95_columns(points: ServoPoints, table: pd.DataFrame) -> dict[str, Any]:
    """The bench's own U95 per row of a validation ``table``, from its file's columns
    (:data:`SERVO_U95_COLUMNS`, in the quantity's unit), matched by amplitude and frequency; a
    quantity without such a column is left out (NaN rows: not given there)."""
    import numpy as np

    raw = points.raw
    out: dict[str, Any] = {}
    if raw is None or "amplitude_deg" not in raw.columns:
        return out
    key = lambda a, f: list(zip(np.round(np.asarray(a, float), 9), np.round(np.asarray(f, float), 9)))  # noqa: E731
    rows = key(table["amplitude_deg"], table["frequency_hz"])
    for q, names in SERVO_U95_COLUMNS.items():
        column = next((c for c in names if c in raw.columns), None)
        if column is None:
            continue
        lookup = dict(zip(key(raw["amplitude_deg"], raw["frequency_hz"]), pd.to_numeric(raw[column], errors="coerce")))
        out[q] = np.array([lookup.get(r, np.nan) for r in rows], float)
    return out
