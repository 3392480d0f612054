"""Figures of the virtual drop tower: one test (Rapp et al. 2022, Fig. 4 and the traces) and a test plan.

matplotlib with the Agg backend (files only), imported when a figure is drawn.
"""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from droptower.io.droptower_log import save_figure
from droptower.rig.config import RigConfig

if TYPE_CHECKING:
    from droptower.rig.simulate import DropResult


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_test(result: "DropResult", path: str | Path) -> Path:
    """Rapp et al. 2022, Fig. 4 (drop mass and lever tip paths around the impact, contacts marked) over
    the recorded angle and torque channels (what the log holds) and the coupling's own torque."""
    plt = _pyplot()
    t_ms = 1e3 * result.time_s
    ch = result.channels()
    fig, axes = plt.subplots(3, 1, figsize=(9, 10), gridspec_kw={"height_ratios": [1.3, 1, 1]})
    axes[2].sharex(axes[1])
    # Fig. 4 window: from the start of the record to 1.5 periods (or past the second contact)
    period = result.period_s
    t_end = result.impact_time_s + (1.5 * period if np.isfinite(period) else 0.05)
    if result.double_impact:
        t_end = max(t_end, result.impact_time_s + result.second_impact_time_s + 0.005)
    win = result.time_s <= t_end
    later = "double impact (2nd contact in the 1st period)" if result.double_impact else \
        "later contact (after the 1st period: no double impact)"
    ax = axes[0]
    ax.plot(t_ms[win], -1e3 * result.drop_mass_m[win], label="drop mass")
    ax.plot(t_ms[win], -1e3 * result.lever_tip_m[win], label="lever tip")
    for n, c in enumerate(c for c in result.contacts if c.start_s <= t_end):
        ax.axvline(1e3 * c.start_s, color="r" if n else "k", lw=0.8, ls="--",
                   label="1st impact" if n == 0 else (later if n == 1 else None))
    if np.isfinite(period):
        ax.axvspan(1e3 * result.impact_time_s, 1e3 * (result.impact_time_s + period), color="0.92",
                   label="1st period of the lever")
    ax.set_ylabel("height above impact point [mm]")
    ax.set_xlabel("time [ms]")
    ax.legend(fontsize=8)
    t = result.test
    ax.set_title(f"J = {t.inertia_kgm2:g} kg*m^2, m1 = {t.drop_mass_kg:g} kg, h = {t.drop_height_m:g} m, "
                 f"preload {t.preload_nm:g} N*m ({result.coupling_name} on {result.rig.name})", fontsize=9)
    axes[1].plot(t_ms, np.degrees(ch.angle_rad), lw=0.8, label="angle (laser)")
    axes[1].set_ylabel("angle [deg]")
    axes[2].plot(t_ms, ch.torque_nm, lw=0.6, label="flange torque (sensor)")
    axes[2].plot(t_ms, result.coupling_torque_nm, lw=1.0, label="coupling torque")
    axes[2].set_ylabel("torque [N*m]")
    axes[2].set_xlabel("time [ms]")
    # every contact on the traces too: a later one (the drop mass falling back) kicks the decay
    for ax in axes[1:]:
        for n, c in enumerate(result.contacts):
            ax.axvline(1e3 * c.start_s, color="r" if n else "k", lw=0.8, ls="--",
                       label="1st impact" if n == 0 else (later if n == 1 else None))
        ax.legend(fontsize=8, loc="upper right")
    axes[1].set_title(f"recorded channels; {len(result.contacts)} contact(s)", fontsize=9)
    for a in axes:
        a.grid(True, alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path, 120)
    plt.close(fig)
    return Path(path)


def _limit(ax, limit: float, label: str, unit: str, values: np.ndarray) -> None:
    """A rig limit in a panel: a line where it lies within the data's scale, else a note in the
    corner (the sensor range of 10 kN*m drawn as a line would squash tests that reach 2 kN*m)."""
    finite = values[np.isfinite(values)]
    lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (limit, limit)
    margin = 0.25 * max(hi - lo, abs(hi), 1e-12)
    if lo - margin <= limit <= hi + margin:
        ax.axhline(limit, color="r", lw=1, ls="--", label=label)
        ax.legend(handles=ax.get_lines()[-1:], fontsize=7, loc="lower right")  # each panel's limit
        return
    where = "above" if limit > hi else "below"
    ax.annotate(f"{label} {limit:g} {unit} ({where} the scale)", xy=(0.02, 0.97 if where == "above" else 0.03),
                xycoords="axes fraction", va="top" if where == "above" else "bottom", fontsize=8, color="r")


def plan_figure(table: pd.DataFrame, rig: RigConfig, coupling_name: str | None = None):
    """Four panels over drop height, a line per (case, preload): twist against the coupling
    limit, frequency, peak torque against the sensor range, and the clearance of the drop mass
    to the lever tip in the first period (negative: double impact). A limit far off the data's
    scale is written in the panel's corner, not drawn (the axes keep the data's scale)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(13, 8), layout="constrained")
    axes = fig.subplots(2, 2, sharex=True)
    panels = [("max_twist_deg", "max. twist [deg]", rig.coupling_limit_deg, "coupling limit", "deg"),
              ("first_period_frequency_hz", "frequency of the first period [Hz]", None, None, "Hz"),
              ("peak_torque_nm", "peak torque [N*m]", rig.sensors.torque.range_nm, "sensor range", "N*m"),
              ("min_clearance_mm", "clearance mass-lever in 1st period [mm]", 0.0, "double impact below", "mm")]
    groups = table.groupby(["case", "inertia_kgm2", "drop_mass_kg"], sort=False) if "case" in table else \
        table.groupby(["inertia_kgm2", "drop_mass_kg"], sort=False)
    styles = ["-", "--", ":", "-."]
    for ax, (col, label, limit, limit_label, unit) in zip(axes.flat, panels):
        for ci, (key, grp) in enumerate(groups):
            name = key[0] if "case" in table else f"J={key[0]:g}"
            for pi, (preload, sub) in enumerate(grp.groupby("preload_nm")):
                sub = sub.sort_values("drop_height_m")
                ax.plot(sub["drop_height_m"], sub[col], styles[pi % len(styles)], color=f"C{ci}", marker="o", ms=3,
                        label=f"{name}, {key[-1]:g} kg, {preload:g} N*m")
                bad = sub["double_impact"].to_numpy(bool)
                ax.plot(sub["drop_height_m"][bad], sub[col][bad], "x", color="k", ms=7)
        if limit is not None:
            _limit(ax, limit, limit_label, unit, table[col].to_numpy(float))
        ax.set_ylabel(label)
        ax.set_xscale("log")
        ax.grid(True, which="both", alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("drop height [m]")
    axes[0, 1].plot([], [], "x", color="k", label="double impact")
    conditions = [h for h in axes[0, 1].get_lines() if not h.get_label().startswith("_")]
    fig.legend(handles=conditions, fontsize=8, loc="outside right center")  # beside, not on, the data
    coupling = f"coupling {coupling_name}, " if coupling_name else ""
    fig.suptitle(f"test plan: {coupling}rig '{rig.name}' (one line per case, drop mass and preload)")
    return fig


def plot_plan(table: pd.DataFrame, rig: RigConfig, path: str | Path, coupling_name: str | None = None) -> Path:
    """:func:`plan_figure` written to ``path`` (PNG)."""
    return save_figure(plan_figure(table, rig, coupling_name), path, 120)
