"""Rapp et al. 2022, Fig. 9: the measured angle with its decay fit, and the torque with its fit (eq. 17).

Drawn with matplotlib's object API on the Agg canvas (no pyplot state, no display needed).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from droptower.errors import make_folder
from droptower.extract.result import DEG, ExtractionResult
from droptower.io.droptower_log import atomic_write
from droptower.io.signals import DropSignals


def plot_fit(signals: DropSignals, result: ExtractionResult, path: str | Path, title: str | None = None) -> Path:
    """Write a PNG of the angle (deg) and torque (N·m) around the impact with their fits and the
    angle fit's residual; returns the path.

    Signals are shown minus their pre-trigger offsets, over time since the impact (ms); the fits
    are solid inside the fit window and dashed beyond it. The title names the test (file, J, m,
    h, preload, as far as the log's metadata says) and the results ± their standard uncertainty.
    """
    path = Path(path)
    t = signals.time_s - result.impact_time_s
    end = result.window_end_s
    show = (t >= -0.1 * end) & (t <= 2.0 * end)
    inside = np.linspace(result.window_start_s, end, 400)
    beyond = np.linspace(end, 2.0 * end, 400)
    angle = (signals.angle_rad - result.angle_offset_rad) / DEG
    panels = [("angle [deg]", angle, result.angle_fit, 1.0 / DEG)]
    if signals.torque_nm is not None and result.torque_fit is not None:
        panels.append(("torque [N*m]", signals.torque_nm - result.torque_offset_nm, result.torque_fit, 1.0))

    fig = Figure(figsize=(8, 2.8 * len(panels) + 2.2), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(panels) + 1, 1, sharex=True, squeeze=False,
                        gridspec_kw={"height_ratios": [1.0] * len(panels) + [0.45]})[:, 0]
    for ax, (label, measured, fit, scale) in zip(axes, panels):
        ax.plot(t[show] * 1e3, measured[show], color="0.55", lw=0.8, label="measured")
        ax.plot(inside * 1e3, fit(inside) * scale, color="C3", lw=1.6, label="fit (in the window)")
        ax.plot(beyond * 1e3, fit(beyond) * scale, color="C3", lw=1.0, ls="--", label="fit, extrapolated")
        ax.axvspan(result.window_start_s * 1e3, end * 1e3, color="C0", alpha=0.07, label="fit window")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    # the residual of the angle fit: structure in it is what the model misses
    window = (t >= result.window_start_s) & (t <= end)
    residual = axes[-1]
    residual.plot(t[window] * 1e3, angle[window] - result.angle_fit(t[window]) / DEG, color="C0", lw=0.8,
                  label=f"angle - fit (RMS {100 * result.fit_error:.2f} % of the peak)")
    residual.axhline(0.0, color="0.3", lw=0.6)
    residual.set_ylabel("residual [deg]")
    residual.legend(loc="upper right", fontsize=8)
    residual.grid(alpha=0.3)
    axes[-1].set_xlabel("time since impact [ms]")
    axes[0].set_title(title or _title(signals, result), fontsize=9)
    make_folder(path.parent)
    atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"))
    return path


def _title(signals: DropSignals, result: ExtractionResult) -> str:
    """The test (file, J, m, h, preload as the metadata says) and its results ± standard uncertainty."""
    meta = signals.metadata
    test = [Path(str(signals.source)).name] if signals.source else []
    test += [f"{label} = {float(meta[key]):g} {unit}" for key, label, unit in (
        ("inertia_kgm2", "J", "kg*m^2"), ("drop_mass_kg", "m", "kg"), ("drop_height_m", "h", "m"),
        ("preload_nm", "preload", "N*m")) if isinstance(meta.get(key), (int, float))]
    if not any(s.startswith("J =") for s in test) and np.isfinite(result.inertia_kgm2):
        test.append(f"J = {result.inertia_kgm2:g} kg*m^2")

    def pm(value: float, key: str, scale: float = 1.0, digits: int = 3) -> str:
        std = result.std.get(key, np.nan) * scale
        return f"{value * scale:.{digits}g} ± {std:.2g}" if np.isfinite(std) else f"{value * scale:.{digits}g}"

    values = (f"f = {pm(result.frequency_hz, 'frequency_hz', digits=4)} Hz, "
              f"φ̂_ref = {pm(result.amplitude_ref_rad, 'amplitude_ref_rad', 1 / DEG)} deg, "
              f"c = {pm(result.stiffness_nm_per_rad, 'stiffness_nm_per_rad', DEG, 4)} N*m/deg, "
              f"d = E_diss/E_el (Rapp et al. 2022) = {pm(result.damping_ratio, 'damping_ratio')}, "
              f"D = {result.lehr_damping:.3g}")
    flags = f"  [{', '.join(result.flags)}]" if result.flags else ""
    return f"{', '.join(test)}\n{values}{flags}"
