"""A campaign's results per test condition, and Rapp et al. 2022, Fig. 11 (the preload's effect).

``condition_summary(results)`` collapses the repeats: one row per (case, inertia, drop mass,
drop height, preload) with ``n_tests`` (extracted tests without an unusable flag) and the mean
and sample standard deviation (``*_std_over_repeats``, ddof = 1; NaN for a single test) of
amplitude, frequency, stiffness and the damping: Rapp's d = E_diss/E_el (``damping_ratio``) beside
Lehr's D (``lehr_damping``) and the loss factor η (``loss_factor``) of the same decay. ``plot_preload_effect`` draws Rapp et al. 2022,
Fig. 11: stiffness and damping ratio over amplitude, one series per case and preload with
± std bars, so a preload that does not change the coupling shows as coinciding series.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from droptower.io.droptower_log import save_figure
from droptower.sdof import DAMPING_LABEL, damping_measures
from droptower.maps.results import select_tests

CONDITION = ("case", "inertia_kgm2", "drop_mass_kg", "drop_height_m", "preload_nm")
QUANTITIES = ("amplitude_deg", "frequency_hz", "stiffness_nm_per_deg", "damping_ratio", "lehr_damping", "loss_factor")
FIG11 = "fig11_preload_effect.png"


def condition_summary(results: pd.DataFrame) -> pd.DataFrame:
    """One row per test condition (columns in the module docstring), in plan order."""
    usable, _ = select_tests(results)
    # D and eta beside Rapp's d, from d itself (docs/theory.md#damping-measures): older tables lack them
    lehr, eta = damping_measures(usable["damping_ratio"].to_numpy(float))
    usable = usable.assign(lehr_damping=lehr, loss_factor=eta)
    keys = [c for c in CONDITION if c in results.columns]
    groups = usable.groupby(keys, sort=False, dropna=False)[list(QUANTITIES)]
    mean, std = groups.mean(), groups.std(ddof=1)
    table = pd.concat([groups.size().rename("n_tests"), mean.add_suffix("_mean"),
                       std.add_suffix("_std_over_repeats")], axis=1)
    order = [f"{q}{s}" for q in QUANTITIES for s in ("_mean", "_std_over_repeats")]
    return table[["n_tests", *order]].reset_index()


def preload_effect_pct(summary: pd.DataFrame, quantity: str) -> float:
    """Largest |mean at a preload / mean at the lowest preload - 1| over the conditions, in %."""
    rest = [c for c in CONDITION if c in summary.columns and c != "preload_nm"]
    worst = 0.0
    for _, rows in summary.groupby(rest, sort=False):
        rows = rows.sort_values("preload_nm")
        base = rows[f"{quantity}_mean"].iloc[0]
        worst = max(worst, float(np.nanmax(np.abs(rows[f"{quantity}_mean"] / base - 1.0))))
    return 100.0 * worst


def plot_preload_effect(summary: pd.DataFrame, path: str | Path, title: str) -> Path:
    """Rapp et al. 2022, Fig. 11 from a :func:`condition_summary` (see the module docstring)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 5))
    cases = list(dict.fromkeys(summary["case"]))
    preloads = sorted(summary["preload_nm"].unique())
    markers = "osD^v<>p*h"
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, quantity, label in ((axes[0], "stiffness_nm_per_deg", "stiffness [N*m/deg]"),
                                (axes[1], "damping_ratio", DAMPING_LABEL)):
        for i, case in enumerate(cases):
            for j, preload in enumerate(preloads):
                rows = summary[(summary["case"] == case) & (summary["preload_nm"] == preload)]
                rows = rows.sort_values("amplitude_deg_mean")
                if rows.empty:
                    continue
                ax.errorbar(rows["amplitude_deg_mean"], rows[f"{quantity}_mean"],
                            xerr=rows["amplitude_deg_std_over_repeats"].fillna(0.0),
                            yerr=rows[f"{quantity}_std_over_repeats"].fillna(0.0),
                            color=colors[i % len(colors)], marker=markers[j % len(markers)],
                            ms=max(3.0, 10.0 - 3.0 * j), mfc="none", lw=1.0,  # hollow, shrinking: coinciding
                            # series (no preload effect) stay visible
                            ls=("-", "--", ":", "-.")[j % 4], capsize=2,
                            label=f"{case}, preload {preload:g} N*m")
        ax.set_xlabel("amplitude [deg]")
        ax.set_ylabel(label)
        ax.set_title(f"{label.split(' [')[0]}: largest preload effect {preload_effect_pct(summary, quantity):.1f} %",
                     fontsize=9)
        ax.grid(True, alpha=0.3)
    axes[1].legend(fontsize=7, ncol=1 + len(cases) * len(preloads) // 10)
    fig.suptitle(f"Fig. 11 (Rapp et al. 2022): preload effect, mean ± std over repeats; {title}", fontsize=10)
    fig.tight_layout()
    path = save_figure(fig, path, 120)
    plt.close(fig)
    return path
