"""The report's interactive figures (plotly): the map over the tests, and per test the measured
angle and torque with their decay fits (Rapp et al. 2022, Fig. 9) and the fit window.

Figures are plotly figure dicts; the page embeds plotly.js once and draws them.
"""
from __future__ import annotations

import base64
import functools
import json
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
import plotly.graph_objects as go
from plotly.subplots import make_subplots

from droptower.damped_cosine import DecayFit, TorqueFit
from droptower.extract.result import DEG, ExtractionResult
from droptower.io.signals import DropSignals
from droptower.maps import MapFit
from droptower.maps.plots import _frequency_along, path_grid

#: Most samples per drawn trace: a 0.25 s log at 38.4 kHz has 9600; every k-th is kept (the
#: fit is drawn from its own smooth curve, so only the measured trace is thinned). The drawn
#: span is two fit windows (about two periods): 200 points are 100 per period, and keep a
#: report of 4 500 tests within 40 MB (about 6.5 kB per test's figure).
MAX_POINTS = 200
COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f")
TEMPLATE = "plotly_white"


def _groups(tests: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
    if "inertia_kgm2" not in tests.columns or tests["inertia_kgm2"].isna().all():
        return [("tests", tests)]
    key = tests["inertia_kgm2"].astype(float).round(6)
    return [(f"J = {j:.4g} kg·m²", rows) for j, rows in tests.groupby(key, sort=True)]


def map_figure(tests: pd.DataFrame, names: list[str], fit: MapFit) -> go.Figure:
    """Stiffness and damping ratio over amplitude: the usable tests (hover: test, values) and
    the map along each inertia group's realised (amplitude, frequency) path (log amplitude axis)."""
    fig = make_subplots(rows=1, cols=2, horizontal_spacing=0.1,
                        subplot_titles=("stiffness [N·m/deg]", "d = E_diss/E_el (Rapp et al. 2022) [-]"))
    tests = tests.assign(_name=names)
    for (label, rows), color in zip(_groups(tests), _cycle()):
        a = rows["amplitude_deg"].to_numpy(float)
        grid = path_grid(a) if a.size else a
        f_grid = _frequency_along(rows, grid) if a.size else a
        for col, (q, model) in enumerate((("stiffness_nm_per_deg", fit.stiffness_nm_per_deg),
                                          ("damping_ratio", fit.damping_ratio)), start=1):
            fig.add_trace(go.Scatter(
                x=a, y=rows[q], mode="markers", name=label, legendgroup=label, showlegend=col == 1,
                marker={"color": color, "size": 7}, customdata=np.stack([rows["_name"], rows["frequency_hz"]], axis=-1),
                hovertemplate="%{customdata[0]}<br>amplitude %{x:.3f} deg<br>f %{customdata[1]:.1f} Hz<br>"
                              "%{y:.4g}<extra></extra>"), row=1, col=col)
            fig.add_trace(go.Scatter(x=grid, y=model(grid, f_grid), mode="lines", name=f"map, {label}",
                                     legendgroup=label, showlegend=False, line={"color": color},
                                     hovertemplate="map %{y:.4g} at %{x:.3f} deg<extra></extra>"), row=1, col=col)
    fig.update_xaxes(type="log", title_text="angular amplitude [deg]")
    fig.update_layout(template=TEMPLATE, height=420, margin={"l": 60, "r": 20, "t": 40, "b": 50},
                      legend={"orientation": "h", "y": -0.2})
    return fig


def _cycle():
    while True:
        yield from COLORS


#: Points of each drawn fit curve (smooth: a damped cosine over about one period).
FIT_POINTS = 40


@functools.lru_cache(maxsize=2)
def _decay_layout(panels: int) -> str:
    """The layout of a decay figure with ``panels`` stacked panels sharing the time axis, as
    plotly's make_subplots lays it out (JSON text; built once, it costs ~10 ms)."""
    fig = make_subplots(rows=panels, cols=1, shared_xaxes=True, vertical_spacing=0.08)
    fig.update_layout(height=240 * panels + 80, margin={"l": 60, "r": 20, "t": 50, "b": 50},
                      legend={"orientation": "h", "y": 1.08, "x": 1, "xanchor": "right"})
    layout = fig.to_plotly_json()["layout"]
    layout.pop("template", None)
    return json.dumps(layout)


@dataclass(frozen=True)
class StoredFit:
    """What a decay figure draws of an extraction (SI; times since the impact but
    ``impact_time_s``, on the log's clock), as :class:`~droptower.extract.result.ExtractionResult`
    names it: a result itself, or one rebuilt from a results-table row by
    :func:`droptower.report.decays.stored_fit`."""

    impact_time_s: float
    window_start_s: float
    window_end_s: float
    angle_offset_rad: float
    angle_fit: DecayFit
    torque_offset_nm: float
    torque_fit: TorqueFit | None


def decay_figure(signals: DropSignals, result: ExtractionResult | StoredFit, title: str) -> dict[str, Any]:
    """Angle (deg) and torque (N·m) minus their pre-trigger offsets over the time since the
    impact (ms), with the fits: solid inside the fit window (shaded), dashed beyond it. result:
    the extraction, or its fit as the results table stores it (:class:`StoredFit`).
    Returns the figure as a dict without its template (the page adds the shared one).

    Built as plain data on a cached layout (no plotly objects per test: a report of thousands
    of tests draws each in well under a millisecond); the measured trace, on its regular
    sample grid, is given by its first time and step (``x0``, ``dx``), not a time array."""
    t = signals.time_s - result.impact_time_s
    end = result.window_end_s
    show = np.flatnonzero((t >= -0.1 * end) & (t <= 2.0 * end))
    step = max(1, int(np.ceil(show.size / MAX_POINTS)))
    show = show[::step]
    inside = np.linspace(result.window_start_s, end, FIT_POINTS)
    beyond = np.linspace(end, 2.0 * end, FIT_POINTS)
    panels = [("angle [deg]", (signals.angle_rad - result.angle_offset_rad) / DEG, result.angle_fit, 1.0 / DEG)]
    if signals.torque_nm is not None and result.torque_fit is not None:
        panels.append(("torque [N·m]", signals.torque_nm - result.torque_offset_nm, result.torque_fit, 1.0))
    layout = json.loads(_decay_layout(len(panels)))
    regular = show.size > 1 and np.allclose(np.diff(t[show]), t[show[1]] - t[show[0]], rtol=1e-6, atol=1e-12)
    data, shapes = [], []
    for row, (label, measured, fit, scale) in enumerate(panels, start=1):
        first = row == 1
        axes = {"xaxis": "x" if first else f"x{row}", "yaxis": "y" if first else f"y{row}"}
        x = ({"x0": float(t[show[0]] * 1e3), "dx": float((t[show[1]] - t[show[0]]) * 1e3)} if regular
             else {"x": _f4(t[show] * 1e3)})
        data += [
            {"type": "scatter", **x, "y": _f4(measured[show]), "mode": "lines", "name": "measured",
             "line": {"color": "#888", "width": 1}, "showlegend": first, "legendgroup": "m", **axes},
            {"type": "scatter", "x": _f4(inside * 1e3), "y": _f4(fit(inside) * scale), "mode": "lines",
             "name": "fit (window)", "line": {"color": "#d62728", "width": 2}, "showlegend": first,
             "legendgroup": "f", **axes},
            {"type": "scatter", "x": _f4(beyond * 1e3), "y": _f4(fit(beyond) * scale), "mode": "lines",
             "name": "fit, extrapolated", "line": {"color": "#d62728", "width": 1, "dash": "dash"},
             "showlegend": first, "legendgroup": "e", **axes},
        ]
        shapes.append({"type": "rect", "x0": result.window_start_s * 1e3, "x1": end * 1e3, "y0": 0, "y1": 1,
                       "xref": axes["xaxis"], "yref": f"{axes['yaxis']} domain", "fillcolor": "#1f77b4",
                       "opacity": 0.08, "line": {"width": 0}})
        layout["yaxis" if first else f"yaxis{row}"]["title"] = {"text": label}
    layout[f"xaxis{len(panels)}" if len(panels) > 1 else "xaxis"]["title"] = {"text": "time since impact [ms]"}
    layout["title"] = {"text": title, "font": {"size": 13}}
    layout["shapes"] = shapes
    return {"data": data, "layout": layout}


def _f4(x: np.ndarray) -> dict[str, str]:
    """A plotly typed array of float32 (``{"dtype": "f4", "bdata": base64}``): float32 is plenty
    for drawing, and base64 takes 5.3 characters per number where JSON text of a float32 takes
    up to 20 (plain data is not converted by plotly as its figure objects are)."""
    return {"dtype": "f4", "bdata": base64.b64encode(np.ascontiguousarray(x, dtype=np.float32).data).decode("ascii")}
