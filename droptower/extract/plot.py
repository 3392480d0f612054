"""Seed 004 Fig. 9: the measured angle with its decay fit, and the torque with its fit (eq. 17).

Drawn with matplotlib's object API on the Agg canvas (no pyplot state, no display needed).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from droptower.extract.result import DEG, ExtractionResult
from droptower.io.droptower_log import atomic_write
from droptower.io.signals import DropSignals


def plot_fit(signals: DropSignals, result: ExtractionResult, path: str | Path, title: str | None = None) -> Path:
    """Write a PNG of the angle (deg) and torque (N·m) around the impact with their fits; returns the path.

    Signals are shown minus their pre-trigger offsets, over time since the impact (ms); the fits
    are solid inside the fit window and dashed beyond it.
    """
    path = Path(path)
    t = signals.time_s - result.impact_time_s
    end = result.window_end_s
    show = (t >= -0.1 * end) & (t <= 2.0 * end)
    inside = np.linspace(result.window_start_s, end, 400)
    beyond = np.linspace(end, 2.0 * end, 400)
    panels = [("angle / deg", (signals.angle_rad - result.angle_offset_rad) / DEG, result.angle_fit, 1.0 / DEG)]
    if signals.torque_nm is not None and result.torque_fit is not None:
        panels.append(("torque / N·m", signals.torque_nm - result.torque_offset_nm, result.torque_fit, 1.0))

    fig = Figure(figsize=(8, 2.8 * len(panels) + 0.6), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (label, measured, fit, scale) in zip(axes, panels):
        ax.plot(t[show] * 1e3, measured[show], color="0.55", lw=0.8, label="measured")
        ax.plot(inside * 1e3, fit(inside) * scale, color="C3", lw=1.6, label="fit (window)")
        ax.plot(beyond * 1e3, fit(beyond) * scale, color="C3", lw=1.0, ls="--", label="fit, extrapolated")
        ax.axvspan(result.window_start_s * 1e3, end * 1e3, color="C0", alpha=0.07)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time since impact / ms")
    axes[0].set_title(title or (
        f"f = {result.frequency_hz:.2f} Hz, φ̂_ref = {result.amplitude_ref_rad / DEG:.3f}°, "
        f"c = {result.stiffness_nm_per_rad * DEG:.1f} N·m/deg, d = {result.damping_ratio:.3f}"
        + (f"  [{', '.join(result.flags)}]" if result.flags else "")), fontsize=9)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"))
    return path
