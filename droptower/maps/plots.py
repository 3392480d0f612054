"""The paper's map figures (Rapp et al. 2022, Fig. 10, 12, 13) as PNG files.

Uses matplotlib's object API (``Figure`` renders with the Agg canvas), so no global backend is
touched. Tests are grouped by rotating inertia when the table has ``inertia_kgm2`` (the paper's
cases 1-3), otherwise shown as one group.
"""
from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from droptower.errors import make_folder
from droptower.io.droptower_log import save_figure
from droptower.maps.mapfit import MapFit

FIG10 = "fig10_parameter_variation.png"
FIG12 = "fig12_stiffness_map.png"
FIG13 = "fig13_damping_map.png"


def plot_all(tests: pd.DataFrame, fit: MapFit, out_dir: str | Path, bands: Any = None) -> tuple[list[Path], list[str]]:
    """Write Fig. 10, 12 and 13 of the usable ``tests`` and the ``fit`` into ``out_dir``; with
    ``bands`` (a :class:`droptower.uncertainty.MapUncertainty` of ``fit``: anything whose
    ``predict(amplitude_deg, frequency_hz)`` gives ``stiffness_nm_per_deg_U95`` and
    ``damping_ratio_U95``) the map's expanded uncertainties (k = 2) as bars and bands.

    Returns the files written and notes on panels skipped for want of a column."""
    out_dir = make_folder(out_dir)
    notes = plot_parameter_variation(tests, out_dir / FIG10)
    plot_stiffness_map(tests, fit, out_dir / FIG12, bands)
    plot_damping_map(tests, fit, out_dir / FIG13, bands)
    return [out_dir / FIG10, out_dir / FIG12, out_dir / FIG13], notes


def _groups(tests: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
    """(label, rows) per rotating inertia, or one group of all tests."""
    if "inertia_kgm2" not in tests.columns:
        return [("all tests", tests)]
    key = tests["inertia_kgm2"].astype(float).round(6)
    return [(f"J = {j:.4g} kg·m²", rows) for j, rows in tests.groupby(key, sort=True)]


def plot_parameter_variation(tests: pd.DataFrame, path: Path) -> list[str]:
    """Fig. 10: (a) amplitude vs drop height, (b) frequency vs inertia, (c) stiffness vs
    amplitude per inertia. Panels whose columns are absent are skipped; returns notes saying so."""
    panels, notes = [], []
    for label, column in (("(a) amplitude vs drop height", "drop_height_m"), ("(b) frequency vs inertia", "inertia_kgm2")):
        if column in tests.columns and tests[column].notna().any():
            panels.append(label)
        else:
            notes.append(f"Fig. 10{label[:3]} skipped: the results have no {column} column")
    panels.append("(c) stiffness vs amplitude")
    fig = Figure(figsize=(4.5 * len(panels), 4.0), layout="constrained")
    axes = fig.subplots(1, len(panels), squeeze=False)[0]
    groups = _groups(tests)
    for ax, title in zip(axes, panels):
        for label, rows in groups:
            if title.startswith("(a)"):
                ax.plot(rows["drop_height_m"], rows["amplitude_deg"], "o", label=label)
                ax.set(xlabel="drop height [m]", ylabel="angular amplitude [deg]")
            elif title.startswith("(b)"):
                ax.plot(rows["inertia_kgm2"], rows["frequency_hz"], "o", label=label)
                ax.set(xlabel="inertia [kg·m²]", ylabel="frequency [Hz]")
            else:
                ax.plot(rows["amplitude_deg"], rows["stiffness_nm_per_deg"], "o", label=label)
                ax.set(xlabel="angular amplitude [deg]", ylabel="stiffness [N·m/deg]")
        ax.set_title(title)
        ax.grid(True, alpha=0.3)
    axes[-1].legend()
    fig.suptitle("Effect of parameter variation (Rapp et al. 2022, Fig. 10)")
    save_figure(fig, path, 120)
    return notes


def plot_stiffness_map(tests: pd.DataFrame, fit: MapFit, path: Path, bands: Any = None) -> None:
    """Fig. 12: the eq. 19 surface over the measured amplitude × frequency range with the
    tests on it, and measured vs. model stiffness (with ``bands``: the model's U95 as bars)."""
    r = fit.range
    a, f = np.meshgrid(np.linspace(r.amplitude_deg_min, r.amplitude_deg_max, 40),
                       np.linspace(r.frequency_hz_min, r.frequency_hz_max, 40))
    fig = Figure(figsize=(11, 4.8), layout="constrained")
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    ax3.plot_surface(a, f, fit.stiffness_nm_per_deg(a, f), cmap="viridis", alpha=0.6, linewidth=0)
    ax = fig.add_subplot(1, 2, 2)
    for label, rows in _groups(tests):
        ax3.scatter(rows["amplitude_deg"], rows["frequency_hz"], rows["stiffness_nm_per_deg"], depthshade=False, label=label)
        model_c = fit.stiffness_nm_per_deg(rows["amplitude_deg"].to_numpy(float), rows["frequency_hz"].to_numpy(float))
        if bands is not None:
            u95 = bands.predict(rows["amplitude_deg"].to_numpy(float),
                                rows["frequency_hz"].to_numpy(float))["stiffness_nm_per_deg_U95"].to_numpy()
            ax.errorbar(rows["stiffness_nm_per_deg"], model_c, yerr=u95, fmt="o", capsize=2, label=f"{label} (map ± U95)")
        else:
            ax.plot(rows["stiffness_nm_per_deg"], model_c, "o", label=label)
    ax3.set(xlabel="amplitude [deg]", ylabel="frequency [Hz]", zlabel="stiffness [N·m/deg]")
    ax3.legend(loc="upper right")
    lo, hi = tests["stiffness_nm_per_deg"].min() * 0.95, tests["stiffness_nm_per_deg"].max() * 1.05
    ax.plot([lo, hi], [lo, hi], "k-", lw=1, label="model = test")
    ax.set(xlabel="test stiffness [N·m/deg]", ylabel=f"{_label(fit, 'eq. 19')} stiffness [N·m/deg]", xlim=(lo, hi), ylim=(lo, hi),
           title=f"rms {fit.stats.stiffness_rms_error_pct:.2f} %, max {fit.stats.stiffness_max_error_pct:.2f} %")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.suptitle(f"Stiffness map, {_label(fit, 'Rapp et al. 2022, eq. 19')} (Fig. 12)")
    save_figure(fig, path, 120)


def plot_damping_map(tests: pd.DataFrame, fit: MapFit, path: Path, bands: Any = None) -> None:
    """Fig. 13: damping ratio vs amplitude, tests and the map's curves (with ``bands``: the
    map's U95 band, k = 2, about each curve).

    Per inertia the curve follows the group's realised path: its tests' frequencies, which
    fall with amplitude (Payne effect, Fig. 10), joined in order of amplitude. Without inertias,
    curves at the lowest, middle and highest measured frequency."""
    fig = Figure(figsize=(6.5, 4.5), layout="constrained")
    ax = fig.add_subplot()
    for (label, rows), color in zip(_groups(tests), _colors()):
        a = rows["amplitude_deg"].to_numpy(float)
        ax.plot(a, rows["damping_ratio"], "o", color=color, label=label)
        if "inertia_kgm2" in tests.columns:
            grid = path_grid(a)
            along = _frequency_along(rows, grid)
            curve = fit.damping_ratio(grid, along)
            ax.plot(grid, curve, "-", color=color)
            if bands is not None:
                u95 = bands.predict(grid, along)["damping_ratio_U95"].to_numpy()
                ax.fill_between(grid, curve - u95, curve + u95, color=color, alpha=0.2, lw=0)
    if "inertia_kgm2" not in tests.columns:
        r = fit.range
        grid = np.geomspace(r.amplitude_deg_min, r.amplitude_deg_max, 60)
        for f, color in zip(np.linspace(r.frequency_hz_min, r.frequency_hz_max, 3), ["C1", "C2", "C3"]):
            ax.plot(grid, fit.damping_ratio(grid, f), "-", color=color, label=f"map at {f:.3g} Hz")
            if bands is not None:
                curve, u95 = fit.damping_ratio(grid, f), bands.predict(grid, f)["damping_ratio_U95"].to_numpy()
                ax.fill_between(grid, curve - u95, curve + u95, color=color, alpha=0.2, lw=0)
    ax.set(xlabel="angular amplitude [deg]", ylabel="d = E_diss/E_el (Rapp et al. 2022) [-]",
           title=f"{_label(fit, 'eq. 19 / eq. 20')}: rms {fit.stats.damping_ratio_rms_error_pct:.1f} %, "
                 f"max {fit.stats.damping_ratio_max_error_pct:.1f} %")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.suptitle(f"Damping ratio map, {_label(fit, 'Rapp et al. 2022, eq. 20')} (Fig. 13)")
    save_figure(fig, path, 120)


def _frequency_along(rows: pd.DataFrame, amplitude_deg: np.ndarray) -> np.ndarray:
    """The group's realised frequency (Hz) at the given amplitudes: its tests joined in order of
    amplitude, log f linear in log φ̂ between neighbouring amplitude levels (tests at one
    amplitude averaged in log), constant beyond the ends. The map drawn along it passes through
    its value at every test's own (amplitude, frequency)."""
    la, lf = np.log(rows["amplitude_deg"].to_numpy(float)), np.log(rows["frequency_hz"].to_numpy(float))
    levels, index = np.unique(la, return_inverse=True)
    mean_lf = np.bincount(index, lf) / np.bincount(index)
    return np.exp(np.interp(np.log(amplitude_deg), levels, mean_lf))


def path_grid(amplitude_deg: np.ndarray, n: int = 60) -> np.ndarray:
    """Amplitudes to draw a group's map curve at: a log grid over its range and its tests' own."""
    return np.union1d(np.geomspace(amplitude_deg.min(), amplitude_deg.max(), n), amplitude_deg)


def _label(fit: MapFit, paper: str) -> str:
    """The equation's name: the paper's for its form, else the form's name."""
    return paper if fit.form.name == "paper" else f"form {fit.form.name}"


def _colors() -> itertools.cycle:
    """Matplotlib's colour cycle, endless (more groups than colours reuse them)."""
    return itertools.cycle(f"C{i}" for i in range(10))
