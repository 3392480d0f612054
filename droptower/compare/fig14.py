"""Rapp et al. 2022, Fig. 14: the map against the servo-hydraulic sweeps, four panels.

(a) stiffness and (b) damping ratio over frequency for the frequency sweeps, (c) stiffness and
(d) damping ratio over amplitude for the amplitude sweeps. Servo points as markers, the map as
lines: solid inside the drop tower's measured range, dashed where it extrapolates; the range
is shaded. Matplotlib's object API (Agg canvas), no global backend is touched.
"""
from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from droptower.compare.map_vs_servo import ServoComparison
from droptower.errors import make_folder
from droptower.io.droptower_log import save_figure
from droptower.maps import MapFit

FIG14 = "fig14_servo_validation.png"


def plot_fig14(validation: ServoComparison, fit: MapFit, path: str | Path) -> Path:
    """Write the four panels to ``path`` (PNG); returns the path."""
    path = Path(path)
    make_folder(path.parent)
    table = validation.table
    r = fit.range
    fig = Figure(figsize=(11, 8.5), layout="constrained")
    axes = fig.subplots(2, 2)
    panels = (("frequency", "frequency_hz", "amplitude_deg", "frequency [Hz]", "{:g} deg", (r.frequency_hz_min, r.frequency_hz_max)),
              ("amplitude", "amplitude_deg", "frequency_hz", "angular amplitude [deg]", "{:g} Hz",
               (r.amplitude_deg_min, r.amplitude_deg_max)))
    for row, (sweep, x_name, const_name, x_label, label, span) in enumerate(panels):
        rows = table[table["sweep"] == sweep]
        ax_c, ax_d = axes[row]
        for ax in (ax_c, ax_d):
            ax.axvspan(*span, color="0.92", zorder=0, label="drop tower's range")
        for (const, group), color in zip(rows.groupby(const_name), itertools.cycle(f"C{i}" for i in range(10))):
            x = group[x_name].to_numpy(float)
            ax_c.plot(x, group["servo_stiffness_nm_per_deg"], "o", color=color, label=f"servo {label.format(const)}")
            ax_d.plot(x, group["servo_damping_ratio"], "o", color=color, label=f"servo {label.format(const)}")
            grid = np.linspace(x.min(), x.max(), 200)
            a, f = (np.full_like(grid, const), grid) if sweep == "frequency" else (grid, np.full_like(grid, const))
            inside = fit.in_range(a, f)
            for ax, values in ((ax_c, fit.stiffness_nm_per_deg(a, f)), (ax_d, fit.damping_ratio(a, f))):
                ax.plot(grid, np.where(inside, values, np.nan), "-", color=color)
                ax.plot(grid, np.where(inside, np.nan, values), "--", color=color)
        ax_c.set(xlabel=x_label, ylabel="stiffness [N·m/deg]")
        ax_d.set(xlabel=x_label, ylabel="d = E_diss/E_el (Rapp et al. 2022) [-]")
        ax_c.set_title(f"({'ac'[row]}) stiffness, {sweep} sweeps")
        ax_d.set_title(f"({'bd'[row]}) damping ratio, {sweep} sweeps")
        for ax in (ax_c, ax_d):
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize=7)
    s = validation.summary
    fig.suptitle("Map (lines; dashed: extrapolated) vs servo-hydraulic sweeps (markers), Rapp et al. 2022, Fig. 14\n"
                 f"inside the tested hull: stiffness rms {s['inside']['stiffness_rms_deviation_pct']:.1f} %, damping rms "
                 f"{s['inside']['damping_rms_deviation_pct']:.1f} %; outside it: {s['outside']['stiffness_rms_deviation_pct']:.1f} %, "
                 f"{s['outside']['damping_rms_deviation_pct']:.1f} %", fontsize=10)
    return save_figure(fig, path, 110)
