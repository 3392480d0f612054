"""The report's two-routes section: the paper's map (eq. 19/20) and the model-based map side by
side, each named, over amplitude per frequency (95 % bands shaded where the map has them), and both validated against
the servo bench inside and outside the drop tests' hull (docs/routes.md).

Kept in its own module and handed to :func:`droptower.report.write_report` as an extra section,
so the report's own layout is untouched.
"""
from __future__ import annotations

import html
from pathlib import Path
from typing import Any

import numpy as np
import plotly.graph_objects as go
import plotly.io as pio
from plotly.subplots import make_subplots

from droptower.compare.model_map import PAPER_ROUTE, ModelMap
from droptower.report.figures import COLORS, TEMPLATE
from droptower.report.page import plain_table

HEADING = "Two routes: paper map and model-based map"


def routes_figure(model_map: ModelMap, paper: Any | None) -> go.Figure:
    """K' (c) and d over amplitude per grid frequency: the model-based map solid with its band,
    the paper's map dashed."""
    grid = model_map.grid if model_map.grid is not None else model_map.evaluate_grid()
    fig = make_subplots(rows=1, cols=2, horizontal_spacing=0.1,
                        subplot_titles=("stiffness: K' (model), c (paper) [N·m/deg]", "damping ratio d [-]"))
    panels = (("storage_stiffness_nm_per_deg", "stiffness_nm_per_deg"), ("drop_tower_equivalent_damping_ratio",
                                                                         "damping_ratio"))
    for i, (f, rows) in enumerate(grid.sort_values("amplitude_deg").groupby("frequency_hz")):
        color, a = COLORS[i % len(COLORS)], rows["amplitude_deg"].to_numpy(float)
        for col, (q, paper_q) in enumerate(panels, start=1):
            label = f"{f:.3g} Hz"
            if f"{q}_band_lo" in rows:
                fig.add_trace(go.Scatter(x=np.concatenate([a, a[::-1]]),
                                         y=np.concatenate([rows[f"{q}_band_hi"], rows[f"{q}_band_lo"][::-1]]),
                                         fill="toself", line={"width": 0}, fillcolor=color, opacity=0.2,
                                         hoverinfo="skip", showlegend=False, legendgroup=label), row=1, col=col)
            fig.add_trace(go.Scatter(x=a, y=rows[q], mode="lines", line={"color": color}, legendgroup=label,
                                     name=f"{model_map.route}, {label}", showlegend=col == 1,
                                     hovertemplate="model %{y:.4g} at %{x:.3f} deg<extra></extra>"), row=1, col=col)
            if paper is not None:
                fig.add_trace(go.Scatter(x=a, y=getattr(paper, paper_q)(a, np.full_like(a, f)), mode="lines",
                                         line={"color": color, "dash": "dash"}, legendgroup=label,
                                         name=f"{PAPER_ROUTE}, {label}", showlegend=col == 1,
                                         hovertemplate="paper map %{y:.4g} at %{x:.3f} deg<extra></extra>"),
                              row=1, col=col)
    fig.update_xaxes(type="log", title_text="angular amplitude [deg]")
    fig.update_layout(template=TEMPLATE, height=460, margin={"l": 60, "r": 20, "t": 40, "b": 50},
                      legend={"orientation": "h", "y": -0.25, "font": {"size": 10}})
    return fig


def routes_section(model_map: ModelMap, paper: Any | None, validations: dict[str, Any] | None = None
                   ) -> tuple[str, str]:
    """(heading, HTML) of the section: what each route is, the figure, and the route table."""
    from droptower.compare.map_vs_servo import route_table

    ident = model_map.identification
    verdict = ident.get("verdict")
    parts = [f"<p id='routes-names'><b>{html.escape(PAPER_ROUTE)}</b>: Rapp et al. 2022, eq. 19/20 fitted to the "
             "first-cycle readings of the decays (biased where relaxation is slower than the oscillation, "
             f"docs/theory.md#first-cycle). <b>{html.escape(model_map.route)}</b>: the coupling model "
             "identified from the same decays, evaluated as the servo bench does (first harmonic K', loss factor, "
             "the drop-tower-equivalent d of that loss factor)"
             + (f"; identification verdict <span class='{'bad' if verdict == 'poor fit' else 'ok'}'>"
                f"{html.escape(str(verdict))}</span>" if verdict else "") + ".</p>",
             f"<p>Bands: {html.escape(model_map.band_method or 'none (the coupling was given without a covariance)')}"
             ".</p>",
             pio.to_html(routes_figure(model_map, paper), include_plotlyjs=False, full_html=False,
                         default_height="460px", config={"responsive": True, "displaylogo": False})]
    if validations:
        table = route_table(validations).rename(columns=lambda c: c.replace("_deviation_pct", " dev. [%]"))
        parts.append("<p>Both routes against the servo bench at the same points; regions by the paper map's hull "
                     "of the drop tests (RMS and max |deviation|, %; stiffness: c or K' vs the servo's K').</p>")
        parts.append(f"<div id='routes-table'>{plain_table(table)}</div>")
    return HEADING, "".join(parts)


def routes_report_section(source: str | Path, model_map: ModelMap, form: str = "paper",
                          coupling: Any | None = None, reduced: bool = True, *,
                          servo_results: str | Path | None = None, servo_columns: dict[str, str] | None = None,
                          table: Any = None) -> tuple[str, str]:
    """The section for a campaign folder, results table or lab's folder: the paper's map fitted
    to its tests (``table``: the run's results, else read from ``source``), and both routes
    validated against the servo points: the lab's measured ``servo_results`` (a table, with
    ``servo_columns`` as :func:`~droptower.compare.servo_points.read_servo_results` takes them),
    else the sweeps run on ``coupling`` (a campaign's own), else not validated."""
    from droptower.compare import read_servo_results, run_sweeps
    from droptower.compare.map_vs_servo import validate_routes
    from droptower.errors import DroptowerError
    from droptower.maps import fit_map, read_results
    from droptower.report.run import load_run

    paper = None
    try:
        if table is None:
            table = load_run(source).table if Path(source).is_dir() else read_results(source)
        paper = fit_map(table, source=str(source), form=form)
    except DroptowerError:
        paper = None  # the report's map section says why
    validations = None
    points = None
    if servo_results is not None:
        points = read_servo_results(servo_results, dict(servo_columns or {}))
    elif coupling is not None:
        points = run_sweeps(coupling, reduced=reduced)
    if points is not None:
        routes = {PAPER_ROUTE: paper, model_map.route: model_map} if paper is not None else {model_map.route: model_map}
        validations = validate_routes(routes, points, hull=paper)
    return routes_section(model_map, paper, validations)
