"""The coverage figure of a designed campaign: what the rig reaches, the target, the design."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from droptower.design.choose import Design
from droptower.design.coverage import in_hull, plane


def plot_coverage(design: Design, path: str | Path, title: str = "") -> Path:
    """Amplitude (log axis) vs frequency: every candidate drop per lever and mass (feasible
    dots on a line, drops that hit a limit as crosses), the target rectangle, the designed
    conditions and their hull, and the target points the hull misses."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = design.target
    fig, ax = plt.subplots(figsize=(8.5, 6), layout="constrained")
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    cands = design.candidates
    for i, ((case, mass), g) in enumerate(cands.groupby(["case", "drop_mass_kg"], sort=True)):
        c = colours[i % len(colours)]
        ok = g[g["feasible"]].sort_values("amplitude_deg")
        if len(ok):
            ax.plot(ok["amplitude_deg"], ok["frequency_hz"], ".-", color=c, lw=0.8, alpha=0.6,
                    label=f"{case}, {mass:g} kg: possible drops")
        bad = g[~g["feasible"]]
        if len(bad):
            ax.plot(bad["amplitude_deg"], bad["frequency_hz"], "x", color=c, alpha=0.5, ms=5,
                    label=f"{case}, {mass:g} kg: a limit hit")
    (a0, a1), (f0, f1) = t.amplitude_deg, t.frequency_hz
    ax.add_patch(matplotlib.patches.Rectangle((a0, f0), a1 - a0, f1 - f0, fill=False, ls="--", lw=1.5,
                                              color="k", label="target"))
    cond = design.conditions
    pts = plane(cond["amplitude_deg"], cond["frequency_hz"])
    try:
        hull = ConvexHull(pts)
        ring = np.append(hull.vertices, hull.vertices[0])
        ax.fill(10 ** pts[ring, 0], pts[ring, 1], color="tab:green", alpha=0.12, label="hull of the design")
    except QhullError:
        pass
    ax.plot(cond["amplitude_deg"], cond["frequency_hz"], "o", mfc="none", mec="k", ms=9,
            label=f"designed: {design.n_conditions} conditions, {design.n_tests} drops")
    grid = t.grid()
    miss = grid[~in_hull(pts, grid)]
    if len(miss):
        ax.plot(10 ** miss[:, 0], miss[:, 1], ".", color="tab:red", ms=3, label="target not covered")
    ax.set_xscale("log")
    ax.set_xlabel("amplitude [deg]")
    ax.set_ylabel("frequency [Hz]")
    ax.set_title(title or f"{100 * design.covered_fraction:.0f} % of the target covered")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
