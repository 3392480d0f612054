"""Figures read at a glance: in the rendered figure no two label boxes (suptitle, axes titles,
axis labels, tick labels, legends, notes) overlap and all lie inside the canvas; every visible line
has one legend entry (coinciding curves are drawn once and named together); a rig limit far off
the data's scale is a note, not an axis limit that squashes the data."""
from __future__ import annotations

import itertools

import numpy as np
import pandas as pd
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

from droptower.identify.dropreport import COINCIDE, servo_prediction_figure
from droptower.rig.config import load_rig
from droptower.rig.plots import plan_figure


def label_boxes(fig) -> list[tuple[str, object]]:
    """(name, window extent) of every text block of the rendered figure; an axis's tick labels
    count as one block."""
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    boxes = []
    if fig._suptitle is not None:
        boxes.append(("suptitle", fig._suptitle.get_window_extent(renderer)))
    for legend in fig.legends:
        boxes.append(("figure legend", legend.get_window_extent(renderer)))
    for i, ax in enumerate(fig.axes):
        for name, text in (("title", ax.title), ("xlabel", ax.xaxis.label), ("ylabel", ax.yaxis.label)):
            if text.get_text() and text.get_visible():
                boxes.append((f"axes {i} {name}", text.get_window_extent(renderer)))
        for axis in (ax.xaxis, ax.yaxis):
            lo, hi = sorted(axis.get_view_interval())
            ticks = [t.get_window_extent(renderer) for t, at in zip(axis.get_majorticklabels(), axis.get_majorticklocs())
                     if t.get_text() and lo - 1e-9 * abs(hi - lo) <= at <= hi + 1e-9 * abs(hi - lo)]  # drawn ones
            if ticks:
                boxes.append((f"axes {i} {axis.axis_name} tick labels", ticks[0].union(ticks)))
        if ax.get_legend() is not None:
            boxes.append((f"axes {i} legend", ax.get_legend().get_window_extent(renderer)))
        for text in ax.texts:
            boxes.append((f"axes {i} note", text.get_window_extent(renderer)))
    return boxes


def assert_readable(fig) -> None:
    boxes = label_boxes(fig)
    canvas = fig.bbox
    outside = [name for name, box in boxes if not (box.x0 >= canvas.x0 - 0.5 and box.y0 >= canvas.y0 - 0.5
                                                   and box.x1 <= canvas.x1 + 0.5 and box.y1 <= canvas.y1 + 0.5)]
    assert outside == [], f"outside the canvas: {outside}"
    overlapping = [(a, b) for (a, box_a), (b, box_b) in itertools.combinations(boxes, 2) if box_a.overlaps(box_b)]
    assert overlapping == [], f"overlapping labels: {overlapping}"


def servo_table(coinciding: bool) -> pd.DataFrame:
    """A servo prediction as identify --from-drop-tests writes it: 5 amplitudes x 4 frequencies.
    The model's K' and the map's damping ratio do not depend on the frequency (eq. 20 of Rapp et
    al. 2022 makes c/d a function of the amplitude), so their four curves coincide."""
    a, f = np.meshgrid(np.geomspace(0.3, 4.0, 5), [18.0, 24.0, 31.0, 40.0], indexing="ij")
    a, f = a.ravel(), f.ravel()
    spread = 0.0 if coinciding else 1.0
    return pd.DataFrame({
        "amplitude_deg": a, "frequency_hz": f,
        "model_storage_stiffness_nm_per_deg": 2000.0 * (1 - 0.2 * np.log10(a)) + spread * 8.0 * f,
        "model_loss_factor": 0.3 + 0.002 * f,
        "model_drop_tower_equivalent_damping_ratio": 0.1 + 0.002 * f,
        "map_stiffness_nm_per_deg": 1950.0 * (1 - 0.2 * np.log10(a)) + 15.0 * np.sqrt(f),
        "map_damping_ratio": 0.12 - 0.02 * np.log10(a) + spread * 0.003 * f,
    })


@pytest.mark.parametrize("coinciding", [True, False])
def test_servo_prediction_figure_has_one_entry_per_visible_line(coinciding: bool) -> None:
    fig = servo_prediction_figure(servo_table(coinciding))
    assert_readable(fig)
    for ax in fig.axes:
        lines = ax.get_lines()
        handles, labels = ax.get_legend_handles_labels()
        assert len(labels) == len(lines) == len(set(labels))  # every drawn line named once
        lo, hi = ax.dataLim.y0, ax.dataLim.y1
        for a, b in itertools.combinations(lines, 2):  # and no drawn line hides another
            if a.get_linestyle() == b.get_linestyle():
                assert np.max(np.abs(a.get_ydata() - b.get_ydata())) > COINCIDE * (hi - lo), (a.get_label(), b.get_label())
    k_labels = fig.axes[0].get_legend_handles_labels()[1]
    d_labels = fig.axes[1].get_legend_handles_labels()[1]
    if coinciding:  # the four frequencies of the model's K' and of the map's d are one line each
        assert "model, 18, 24, 31 and 40 Hz" in k_labels and len(k_labels) == 5
        assert "map, 18, 24, 31 and 40 Hz" in d_labels and len(d_labels) == 5
    else:
        assert len(k_labels) == len(d_labels) == 8


def plan_table(peak_torque_scale: float) -> pd.DataFrame:
    rows = []
    for case, j, m in (("case 1", 0.1557, 1.0), ("case 2", 0.359, 2.0)):
        for preload in (0.0, 500.0):
            for h in (0.05, 0.2, 1.0, 3.0):
                rows.append({"case": case, "inertia_kgm2": j, "drop_mass_kg": m, "preload_nm": preload,
                             "drop_height_m": h, "max_twist_deg": 2 + 3 * h + preload / 200,
                             "first_period_frequency_hz": 40 - 5 * h - 10 * j, "peak_torque_nm": peak_torque_scale * (0.2 + h / 3),
                             "min_clearance_mm": 2 + 10 * h, "double_impact": False})
    return pd.DataFrame(rows)


def test_plan_figure_keeps_the_data_scale_and_notes_the_sensor_range() -> None:
    rig = load_rig("rapp2022")
    sensor = rig.sensors.torque.range_nm
    fig = plan_figure(plan_table(1500.0), rig, "rapp2022_nr60")
    assert_readable(fig)
    torque_ax = fig.axes[2]
    assert torque_ax.get_ylim()[1] < 0.5 * sensor  # the data fill the panel
    assert [t.get_text() for t in torque_ax.texts] == [f"sensor range {sensor:g} N*m (above the scale)"]
    # near the range, the range is a line in the panel
    fig = plan_figure(plan_table(0.9 * sensor), rig, "rapp2022_nr60")
    assert_readable(fig)
    torque_ax = fig.axes[2]
    assert len(torque_ax.texts) == 0 and any(np.allclose(line.get_ydata(), sensor) for line in torque_ax.get_lines())
