"""The model-based map in the paper's figure types (Rapp et al. 2022, Fig. 12 and 13) as PNG files,
with the paper's map and the drop tests beside it and the 95 % bands shaded where the map has
them (a coupling taken as it is has no covariance: its figures say "no bands", never "shaded").

Fig. 12: the K' surface over amplitude x frequency with the tests' first-cycle stiffness on it,
and K' over amplitude per grid frequency. Fig. 13: the drop-tower-equivalent damping ratio over
amplitude per grid frequency. Matplotlib's object API (no global backend is touched).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from droptower.compare.model_map import PAPER_ROUTE, ModelMap
from droptower.errors import make_folder
from droptower.io.droptower_log import save_figure

FIG12 = "model_map_fig12_stiffness.png"
FIG13 = "model_map_fig13_damping.png"


def plot_model_map(model_map: ModelMap, out_dir: str | Path, tests: pd.DataFrame | None = None,
                   paper: object | None = None) -> list[Path]:
    """Write :data:`FIG12` and :data:`FIG13` of ``model_map``'s grid (evaluated if needed) into
    ``out_dir``; ``tests``: usable results (amplitude_deg, frequency_hz, stiffness_nm_per_deg,
    damping_ratio) drawn as points; ``paper``: the paper's map drawn dashed."""
    out = make_folder(out_dir)
    grid = model_map.grid if model_map.grid is not None else model_map.evaluate_grid()
    paths = [out / FIG12, out / FIG13]
    save_figure(_stiffness(model_map, grid, tests, paper), paths[0], 110)
    save_figure(_damping(model_map, grid, tests, paper), paths[1], 110)
    return paths


def _band_text(model_map: ModelMap) -> str:
    """What a figure says of the bands: shaded only where the grid carries them."""
    grid = model_map.grid
    drawn = model_map.has_bands and grid is not None and any(c.endswith("_band_lo") for c in grid.columns)
    return "95 % band shaded" if drawn else "no bands: no parameter covariance"


def _curves(ax, model_map: ModelMap, grid: pd.DataFrame, q: str, paper_q, paper: object | None) -> None:
    for i, (f, rows) in enumerate(grid.sort_values("amplitude_deg").groupby("frequency_hz")):
        a, color = rows["amplitude_deg"].to_numpy(float), f"C{i % 10}"
        ax.plot(a, rows[q], "-", color=color, label=f"{model_map.route}, {f:.3g} Hz")
        if f"{q}_band_lo" in rows:
            ax.fill_between(a, rows[f"{q}_band_lo"], rows[f"{q}_band_hi"], color=color, alpha=0.2, lw=0)
        if paper is not None:
            ax.plot(a, getattr(paper, paper_q)(a, np.full_like(a, f)), "--", color=color, lw=1,
                    label=f"{PAPER_ROUTE}, {f:.3g} Hz")
    ax.set_xscale("log")
    ax.grid(True, alpha=0.3)


def _stiffness(model_map: ModelMap, grid: pd.DataFrame, tests: pd.DataFrame | None, paper: object | None) -> Figure:
    fig = Figure(figsize=(12, 5), layout="constrained")
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    n_a = grid["amplitude_deg"].nunique()
    shape = (n_a, -1)
    ax3.plot_surface(grid["amplitude_deg"].to_numpy().reshape(shape), grid["frequency_hz"].to_numpy().reshape(shape),
                     grid["storage_stiffness_nm_per_deg"].to_numpy().reshape(shape), cmap="viridis", alpha=0.6, lw=0)
    ax = fig.add_subplot(1, 2, 2)
    _curves(ax, model_map, grid, "storage_stiffness_nm_per_deg", "stiffness_nm_per_deg", paper)
    if tests is not None and len(tests):
        ax3.scatter(tests["amplitude_deg"], tests["frequency_hz"], tests["stiffness_nm_per_deg"], s=8, color="k",
                    depthshade=False, label="drop tests (first cycle)")
        ax.plot(tests["amplitude_deg"], tests["stiffness_nm_per_deg"], "k.", ms=4, label="drop tests (first cycle)")
    ax3.set(xlabel="amplitude [deg]", ylabel="frequency [Hz]", zlabel="K' [N·m/deg]")
    ax.set(xlabel="amplitude [deg]", ylabel="stiffness [N·m/deg]", title=f"K' (model, {_band_text(model_map)}) and c (paper map)")
    ax.legend(fontsize=6, ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.15))
    fig.suptitle(f"Stiffness map (Fig. 12 type): {model_map.route}")
    return fig


def _damping(model_map: ModelMap, grid: pd.DataFrame, tests: pd.DataFrame | None, paper: object | None) -> Figure:
    fig = Figure(figsize=(12, 4.8), layout="constrained")
    ax_d, ax_eta = fig.subplots(1, 2)
    _curves(ax_d, model_map, grid, "drop_tower_equivalent_damping_ratio", "damping_ratio", paper)
    _curves(ax_eta, model_map, grid, "loss_factor", "damping_ratio", None)
    if tests is not None and len(tests):
        ax_d.plot(tests["amplitude_deg"], tests["damping_ratio"], "k.", ms=4, label="drop tests (first cycle)")
    ax_d.set(xlabel="amplitude [deg]", ylabel="damping ratio d [-]",
             title=f"d = E_diss/E_el: the model's (of its loss factor; {_band_text(model_map)}) and the paper map's")
    ax_eta.set(xlabel="amplitude [deg]", ylabel="loss factor [-]",
               title=f"the model's loss factor K''/K' ({_band_text(model_map)})")
    ax_d.legend(fontsize=6, ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.15))  # below: off the curves
    ax_eta.legend(fontsize=6)
    fig.suptitle(f"Damping map (Fig. 13 type): {model_map.route}")
    return fig
