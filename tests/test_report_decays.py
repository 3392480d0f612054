"""The report's decay figures without a second extraction: a campaign's results table stores
every test's fit (Rapp et al. 2022, eq. 13 and 17), and the figure drawn from the stored fit
and the log's trace is the figure of the extraction itself, to float32 drawing precision; rows
without a stored fit (a failed test) are extracted again; worker processes draw the same
figures as this process, in the run's order."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, seed, settings
from hypothesis import strategies as st

from droptower.damped_cosine import DecayFit, TorqueFit
from droptower.extract.files import Settings, extract_file
from droptower.extract.result import DEG
from droptower.extract.window import Window
from droptower.report.decays import ANGLE_COLUMNS, TORQUE_COLUMNS, decay_figures, jobs, stored_fit, title
from droptower.report.figures import decay_figure
from droptower.report.run import load_run
from test_report import _array, campaign  # noqa: F401  (the 12-test campaign fixture)


def _traces(fig: dict) -> dict[tuple[str, str], np.ndarray]:
    """(trace name, y axis) -> its (x, y) points as float64 (x from x0, dx on a regular grid)."""
    out = {}
    for t in fig["data"]:
        y = _array(t["y"]).astype(float)
        x = _array(t["x"]).astype(float) if "x" in t else t["x0"] + t["dx"] * np.arange(y.size)
        out[t["name"], t.get("yaxis", "y")] = np.stack([x, y])
    return out


def test_stored_fit_draws_the_extracted_figure(campaign) -> None:  # noqa: F811
    """For every extracted test of the campaign: the same traces, the same window, the same
    title as the figure of a fresh extraction of its log."""
    run = load_run(campaign)
    table = pd.read_parquet(campaign / "results.parquet")
    settings_ = Settings(window=Window.parse(run.extract.get("window", "first-cycle")),
                         defaults=run.extract.get("defaults", {}))
    compared = 0
    for i, log in enumerate(run.logs):
        row = table.iloc[i].to_dict()
        fit = stored_fit(row)
        if row["status"] != "done":
            assert fit is None  # the failed test's row has no amplitude: extracted again
            continue
        signals, result = extract_file(log, settings_)
        fresh = decay_figure(signals, result, "t")
        stored = decay_figure(signals, fit, "t")
        a, b = _traces(fresh), _traces(stored)
        assert a.keys() == b.keys() and len(a) == 6  # angle and torque: measured, fit, extrapolated
        for key in a:
            scale = np.abs(a[key][1]).max()
            np.testing.assert_allclose(b[key][0], a[key][0], rtol=1e-6, err_msg=str(key))
            np.testing.assert_allclose(b[key][1], a[key][1], rtol=0, atol=1e-6 * scale, err_msg=str(key))
        assert stored["layout"]["shapes"] == fresh["layout"]["shapes"]
        assert title(row["frequency_hz"], row["amplitude_deg"], row["stiffness_nm_per_deg"], row["damping_ratio"],
                     list(result.flags)) == title(result.frequency_hz, result.amplitude_ref_rad / DEG,
                                                   result.stiffness_nm_per_rad * DEG, result.damping_ratio,
                                                   result.flags)
        compared += 1
    assert compared == 11


@seed(28)
@settings(max_examples=60, deadline=None)
@given(amp=st.floats(1e-4, 0.2), delta=st.floats(0.0, 200.0), omega=st.floats(50.0, 2000.0),
       phase=st.floats(-math.pi, math.pi), a=st.floats(-500.0, 500.0), b=st.floats(-500.0, 500.0),
       offset=st.floats(-50.0, 50.0))
def test_stored_fit_inverts_the_tables_amplitudes_and_phases(amp, delta, omega, phase, a, b, offset) -> None:
    """A fit written as the extraction writes it (φ̂ in deg, T̂ = hypot(a, b), Φ_T = atan2(b, a))
    and read back gives the same curves (docs/theory.md#extraction, eq. 13 and 17)."""
    angle = DecayFit(np.array([amp, delta, omega, phase]), np.eye(4), 0.0)
    torque = TorqueFit(np.array([a, b, offset]), np.eye(3), 0.0, delta, omega)
    row = dict.fromkeys(ANGLE_COLUMNS, 1.0) | {
        "initial_amplitude_deg": amp / DEG, "decay_coefficient_per_s": delta, "angular_frequency_rad_per_s": omega,
        "phase_rad": phase, "angle_offset_deg": 0.3, "torque_offset_nm": 2.0, "torque_amplitude_nm": math.hypot(a, b),
        "torque_phase_rad": math.atan2(b, a), "torque_fit_offset_nm": offset}
    fit = stored_fit(row)
    t = np.linspace(0.0, 3 * 2 * np.pi / omega, 50)
    np.testing.assert_allclose(fit.angle_fit(t), angle(t), rtol=0, atol=1e-12 * amp)
    np.testing.assert_allclose(fit.torque_fit(t), torque(t), rtol=0, atol=1e-12 * (math.hypot(a, b) + abs(offset)))
    assert fit.angle_offset_rad == pytest.approx(0.3 * DEG) and fit.torque_offset_nm == 2.0
    assert stored_fit(row | {"phase_rad": float("nan")}) is None
    assert stored_fit({k: v for k, v in row.items() if k != "window_end_s"}) is None
    no_torque = stored_fit(row | dict.fromkeys(TORQUE_COLUMNS, float("nan")))
    assert no_torque.torque_fit is None and math.isnan(no_torque.torque_offset_nm)


@pytest.mark.slow
def test_workers_draw_what_this_process_draws_in_order(campaign, tmp_path) -> None:  # noqa: F811
    run = load_run(campaign)
    todo = jobs(run)
    assert [j.stored is None for j in todo] == [i == 2 for i in range(12)]  # the failed test: extracted again
    run.logs[4] = None
    one = decay_figures(run, {}, workers=1)
    two = decay_figures(run, {}, workers=2)
    assert list(one) == list(two) == run.test and one == two
    assert one["test_00004"] == "log not found"
    assert isinstance(one["test_00002"], dict)  # failed in the table, but its log extracts
    # a log that cannot be read: its reason, with the log's name and not its path
    bad = tmp_path / "broken.parquet"
    bad.write_bytes(b"not parquet")
    run.logs[7] = bad
    text = decay_figures(run, {}, workers=1)["test_00007"]
    assert text.startswith("the log cannot be read: ") and str(tmp_path) not in text and "broken" in text


def test_an_internal_error_of_a_worker_reaches_the_caller(campaign, monkeypatch) -> None:  # noqa: F811
    """Not a one-line reason of a test: a bug in drawing is raised by the report, not swallowed."""
    import droptower.report.decays as decays

    def broken(task):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(decays, "draw", broken)
    with pytest.raises(ZeroDivisionError, match="a bug"):
        decays.decay_figures(load_run(campaign), {}, workers=1)


def test_workers_below_one_are_a_one_line_error(campaign) -> None:  # noqa: F811
    from droptower.errors import DroptowerError

    with pytest.raises(DroptowerError, match="workers.*at least 1, got 0"):
        decay_figures(load_run(campaign), {}, workers=0)
