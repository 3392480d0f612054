"""Hysteresis loops of a servo-bench grid: torque over angle (degrees), one panel per amplitude."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from droptower.io.droptower_log import save_figure
from droptower.servo.bench import BenchResult


def plot_loops(result: BenchResult, path: str | Path, title: str = "", units: str = "torsional") -> Path:
    """Draw the last evaluated cycle of every grid point into ``path`` (PNG, PDF, SVG...).

    One panel per amplitude, one curve per frequency; torque in N*m over angle in degrees, or
    for a translational coupling (``units``) force in N over displacement in mm.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    table = result.table
    amps = sorted(table["amplitude_deg"].unique())
    ncol = min(3, len(amps))
    nrow = math.ceil(len(amps) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.6 * nrow), squeeze=False)
    # the same numbers read as m and N: displacement shown in mm
    to_display, motion, load, unit = ((1e3, "displacement [mm]", "force [N]", "mm") if units == "translational"
                                      else (180.0 / math.pi, "angle [deg]", "torque [N*m]", "deg"))
    for ax, amp in zip(axes.flat, amps):
        for i in np.flatnonzero(table["amplitude_deg"].to_numpy() == amp):
            ev, row = result.evaluations[i], table.iloc[i]
            ax.plot(to_display * ev.loop_angle_rad, ev.loop_torque_nm, lw=1.2,
                    label=f"{row['frequency_hz']:g} Hz, psi {row['relative_damping_psi']:.2f}")
        ax.set_title(f"amplitude {to_display * math.radians(amp):.4g} {unit}")
        ax.set_xlabel(motion)
        ax.set_ylabel(load)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    for ax in list(axes.flat)[len(amps):]:
        ax.set_visible(False)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    try:
        path = save_figure(fig, path, 120)
    finally:
        plt.close(fig)
    return path
