"""Continuous recordings: every drop of a recording is found and evaluated on its own samples,
and gives what its single-drop log gives. The recordings are the virtual rig's logs of a
Kelvin–Voigt coupling one after the other, with pauses, drift and noise between them
(tests/recordings.py), written in every format the readers take."""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from droptower import sdof
from droptower.cli.main import main
from droptower.extract import Settings, SyntheticDrop, extract_file
from droptower.extract.drop_spans import find_drops, parse_drop_selection
from droptower.extract.files import DECAY_CUT, extract_drops
from droptower.errors import DroptowerError
from droptower.io import write_log
from droptower.io.signals import DropSignals
from droptower.rheology.loader import parse_coupling
from droptower.rig.config import load_rig
from droptower.rig.simulate import DropTest, simulate

sys.path.insert(0, str(Path(__file__).resolve().parent))
from recordings import concatenate, write_catman, write_mdf, write_mts_dat, write_tdms  # noqa: E402

INERTIA, LEVER = 0.359, 0.2
PAUSES_S = [0.4, 0.9, 0.6]
#: results compared with the single-drop log's
COMPARED = ("stiffness_nm_per_rad", "damping_ratio", "frequency_hz", "amplitude_deg", "initial_amplitude_deg",
            "stiffness_torque_nm_per_rad", "loss_factor", "decay_fit_initial_rate_rad_per_s")
UNITS = {"angle_rad": "rad", "torque_nm": "N*m", "impact_force_n": "N", "laser_distance_m": "m"}


@pytest.fixture(scope="module")
def rig_drops(tmp_path_factory):
    """Three rig drops (heights 0.2, 1.4, 0.6 m; the second with a 1000 N·m preload), their
    single-drop logs with and without the force channel, and the recording's samples."""
    stiffness, d_ratio = 14_000.0, 1.5
    r = float(sdof.decay_ratio(d_ratio))
    omega = np.sqrt(stiffness / (INERTIA * (1 + r * r)))
    coupling = parse_coupling({"name": "kelvin-voigt", "element": [
        {"kind": "spring", "stiffness": stiffness}, {"kind": "dashpot", "damping": 2 * INERTIA * r * omega}]})
    rig = load_rig("rapp2022")
    tests = [DropTest(INERTIA, 2.0, h, p, seed=s) for s, (h, p) in enumerate([(0.2, 0.0), (1.4, 1000.0), (0.6, 0.0)])]
    folder = tmp_path_factory.mktemp("drops")
    drops = simulate(rig, coupling, tests, duration_s=0.2)
    logs = [(d.channels().time_s, d.channels().columns()) for d in drops]
    singles = [d.write_log(folder / f"single{i}.csv") for i, d in enumerate(drops)]
    no_force = [write_log(folder / f"single{i}_no_force.csv", t, {k: v for k, v in c.items() if k != "impact_force_n"},
                          d.metadata()) for i, (d, (t, c)) in enumerate(zip(drops, logs))]
    time, columns, starts = concatenate(logs, PAUSES_S, seed=3)
    return {"folder": folder, "singles": singles, "no_force": no_force, "time": time, "columns": columns,
            "starts": starts, "radius": rig.sensors.laser.radius_m, "single_start_s": float(logs[0][0][0])}


def _write(kind: str, folder: Path, time: np.ndarray, columns: dict[str, np.ndarray]) -> tuple[Path, dict[str, str]]:
    """The recording in one format, and the channel roles it needs."""
    fs = 1.0 / float(np.diff(time).mean())
    metadata = {"inertia_kgm2": INERTIA, "lever_length_m": LEVER}
    if kind in ("csv", "parquet"):
        return write_log(folder / f"recording.{kind}", time, columns, metadata), {}
    if kind == "plain.csv":  # a lab's CSV export: units in brackets, decimal comma, no metadata
        path = folder / "recording_plain.csv"
        names = ["Zeit [s]", *(f"{k} [{UNITS[k]}]" for k in columns)]
        rows = np.column_stack([time, *columns.values()])
        path.write_text(";".join(names) + "\n" + "\n".join(";".join(repr(float(v)).replace(".", ",") for v in row)
                                                             for row in rows) + "\n")
        return path, {"time": "Zeit", **{r: n for r, n in (("angle", "angle_rad"), ("torque", "torque_nm"),
                                                            ("impact_force", "impact_force_n")) if n in columns}}
    if kind == "bin":
        return write_catman(folder / "recording.bin", fs, columns, UNITS), {}
    if kind == "mf4":
        return write_mdf(folder / "recording.mf4", time, columns, UNITS), {}
    if kind == "tdms":
        roles = {"angle": "drops/angle_rad", "torque": "drops/torque_nm", "impact_force": "drops/impact_force_n"}
        return write_tdms(folder / "recording.tdms", fs, columns, UNITS), {k: v for k, v in roles.items()
                                                                             if v.split("/")[1] in columns}
    if kind == "dat":
        return write_mts_dat(folder / "recording.dat", time, columns, UNITS), {"time": "Running Time"}
    raise ValueError(kind)


def _assert_same(drop_result, single_result) -> None:
    """Equal within half a standard uncertainty and 1e-3 relative: the drop's pre-trigger holds a
    few samples of the pause the single log does not, which moves the baseline by about the
    noise over √N; everything else is the log's own samples."""
    got, want = drop_result.to_dict(), single_result.to_dict()
    for key in COMPARED:
        assert got[key] == pytest.approx(want[key], rel=1e-3), key
        if f"{key}_std" in want:
            assert abs(got[key] - want[key]) <= 0.5 * want[f"{key}_std"], key
    assert sorted(drop_result.flags) == sorted(single_result.flags)


@pytest.mark.parametrize("kind", ["csv", "parquet", "plain.csv", "bin", "mf4", "tdms", "dat"])
def test_every_drop_of_a_recording_equals_its_single_log(rig_drops, tmp_path, kind):
    if kind in ("mf4", "tdms"):
        pytest.importorskip("asammdf" if kind == "mf4" else "nptdms")
    path, roles = _write(kind, tmp_path, rig_drops["time"], rig_drops["columns"])
    settings = Settings(roles=roles, inertia_kgm2=INERTIA, lever_length_m=LEVER, sensor_radius_m=rig_drops["radius"])
    drops = extract_drops(path, settings)
    assert [d.span.index for d in drops] == [1, 2, 3] and all(d.error is None for d in drops)
    dt = float(np.diff(rig_drops["time"]).mean())
    for drop, single, start in zip(drops, rig_drops["singles"], rig_drops["starts"]):
        _, reference = extract_file(single, Settings(sensor_radius_m=rig_drops["radius"]))
        _assert_same(drop.result, reference)
        # the impact on the recording's clock: the log's own impact time shifted by where the log starts
        at = rig_drops["time"][start] + reference.impact_time_s - rig_drops["single_start_s"]
        assert drop.result.impact_time_s == pytest.approx(at, abs=1.5 * dt)


def test_drops_without_a_force_channel_are_found_by_the_angle(rig_drops, tmp_path):
    columns = {k: v for k, v in rig_drops["columns"].items() if k != "impact_force_n"}
    path, _ = _write("csv", tmp_path, rig_drops["time"], columns)
    drops = extract_drops(path, Settings(sensor_radius_m=rig_drops["radius"]))
    assert len(drops) == 3 and all(d.error is None for d in drops)
    for drop, single in zip(drops, rig_drops["no_force"]):
        _, reference = extract_file(single, Settings(sensor_radius_m=rig_drops["radius"]))
        _assert_same(drop.result, reference)
        assert "double_impact_unchecked" in drop.result.flags


def test_a_single_drop_log_is_one_drop_over_its_whole_record(rig_drops):
    signals = Settings(sensor_radius_m=rig_drops["radius"]).read_signals(rig_drops["singles"][0])
    (span,) = find_drops(signals)
    assert (span.index, span.start, span.stop, span.next_onset, span.cut) == (1, 0, signals.time_s.size, None, False)


def test_a_drop_whose_decay_the_next_impact_cuts_is_flagged():
    # a lightly damped coupling rings for seconds; the next drop comes 0.6 s after the first
    synthetic = SyntheticDrop(damping_ratio=0.1, duration_s=1.2, second_impact_after_s=0.6,
                              second_impact_fraction=1.0, seed=4)
    time, columns = synthetic.channels()
    signals = DropSignals(time, columns["angle_rad"], columns["torque_nm"], columns["impact_force_n"],
                          synthetic.metadata())
    spans = find_drops(signals)
    assert [s.cut for s in spans] == [True, False]
    assert time[spans[1].onset] - time[spans[0].onset] == pytest.approx(0.6, abs=1e-3)
    # the same drops with the lever at rest before the second one are not flagged
    rested = SyntheticDrop(damping_ratio=1.5, duration_s=1.2, second_impact_after_s=0.6,
                           second_impact_fraction=1.0, seed=4)
    time, columns = rested.channels()
    spans = find_drops(DropSignals(time, columns["angle_rad"], columns["torque_nm"], columns["impact_force_n"]))
    assert [s.cut for s in spans] == [False, False]


def test_cut_flag_reaches_the_results(tmp_path):
    synthetic = SyntheticDrop(damping_ratio=0.1, duration_s=1.2, second_impact_after_s=0.6,
                              second_impact_fraction=1.0, seed=4)
    path = synthetic.write(tmp_path / "cut.csv")
    drops = extract_drops(path, Settings())
    assert DECAY_CUT in drops[0].result.flags and DECAY_CUT not in drops[1].result.flags


def test_drop_selection_and_conditions_on_the_command_line(rig_drops, tmp_path, capsys):
    path, _ = _write("csv", tmp_path, rig_drops["time"], rig_drops["columns"])
    conditions = tmp_path / "drops.csv"
    conditions.write_text("drop_index,drop_height_m,drop_mass_kg,preload_nm,inertia_kgm2\n1,0.2,2.0,0,\n"
                          "2,1.4,2.0,1000,\n3,0.6,2.0,0,0.5\n")
    args = ["extract", str(path), "--drops", "1,3", "--drop-conditions", str(conditions),
            "--sensor-radius-m", str(rig_drops["radius"]), "--json"]
    assert main(args) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["drop_index"] for r in rows] == [1, 3]
    assert [r["drop_height_m"] for r in rows] == [0.2, 0.6]
    # drop 3's inertia from the conditions (the recording's metadata says 0.359): ω alone is
    # measured, so the stiffness J(ω² + δ²) scales with the J used
    assert rows[0]["inertia_kgm2"] == INERTIA and rows[1]["inertia_kgm2"] == 0.5
    assert rows[1]["stiffness_nm_per_rad"] == pytest.approx(
        0.5 * (rows[1]["angular_frequency_rad_per_s"] ** 2 + rows[1]["decay_coefficient_per_s"] ** 2), rel=1e-9)
    assert all(r["file"] == str(path) and r["t_impact_s"] == r["impact_onset_time_s"] for r in rows)
    assert main(["extract", str(path), "--drops", "2-4", "--sensor-radius-m", "0.15"]) == 2
    assert "the record holds 3 drop(s)" in capsys.readouterr().err


def test_drop_selection_parsing():
    assert parse_drop_selection("1,3-5") == {1, 3, 4, 5}
    assert parse_drop_selection(" 2 ") == {2}
    for bad in ("0", "3-1", "a", "1,,2", ""):
        with pytest.raises(DroptowerError, match="`drops="):
            parse_drop_selection(bad)


def test_channels_and_report_see_every_drop(rig_drops, tmp_path, capsys):
    from droptower.report.run import load_run

    path, _ = _write("csv", tmp_path, rig_drops["time"], rig_drops["columns"])
    assert main(["channels", str(path)]) == 0
    (line,) = [x for x in capsys.readouterr().out.splitlines() if x.startswith("drops:")]
    assert line.startswith("drops: 3 (impacts at t = ")
    shown = [float(t) for t in line.split("t = ")[1].split(" s)")[0].split(", ")]
    # each log's impact comes its pre-trigger (5 ms) after the log's start
    starts = rig_drops["time"][rig_drops["starts"]] - rig_drops["single_start_s"]
    np.testing.assert_allclose(shown, starts, rtol=0, atol=1e-3)
    table = tmp_path / "results.csv"
    assert main(["extract", str(path), "--sensor-radius-m", str(rig_drops["radius"]), "--out", str(table)]) == 0
    run = load_run(table)
    assert run.test == [f"{path.name} drop {k}" for k in (1, 2, 3)]
