"""Raw servo time records to K', K'' and loss factor (droptower.servo.records, `droptower
evaluate-servo`, `validate --servo-records`), against closed forms and the virtual bench's own
evaluation:

- a linear Kelvin-Voigt record T = k phi + c dphi/dt: K' = k and K'' = c omega exactly, in every
  block of a record that ramps up from rest, with or without a time vector, in mm/kN;
- white noise on the torque: the scatter over the cycles is the closed form sigma sqrt(2/N)/A;
- records the virtual bench writes of a nonlinear coupling (the package's log writer): the
  route's K' and loss factor are the bench's own (``run_grid``, ``evaluate_history``);
- malformed records (missing channel, one cycle, NaN, time running back): one line, exit 2.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings, strategies as st

from droptower.cli.main import main
from droptower.errors import DroptowerError
from droptower.io import write_log
from droptower.rheology import load_coupling
from droptower.servo import evaluate_history, evaluate_record, evaluate_records, find_blocks, run_grid, run_records
from droptower.servo import histories as H

K = 14000.0  # N*m/rad
C = 8.0      # N*m*s/rad
FS = 2048.0


def _kelvin_voigt(t: np.ndarray, x: np.ndarray, k: float = K, c: float = C) -> np.ndarray:
    """T = k x + c dx/dt, the rate from the cubic spline through the samples (central
    differences would be off by (omega h)^2 / 6 of c omega; the spline's error is of 4th order)."""
    from scipy.interpolate import CubicSpline

    return k * x + c * CubicSpline(t, x)(t, 1)


def _write_csv(path, columns: dict[str, np.ndarray]) -> str:
    pd.DataFrame(columns).to_csv(path, index=False)
    return str(path)


def _run(capsys, argv: list[str]) -> tuple[int, str, str]:
    code = main(argv)
    out, err = capsys.readouterr()
    assert "Traceback" not in err and "internal error" not in err, err
    return code, out, err


def test_kelvin_voigt_record_gives_k_and_c_omega(tmp_path, capsys):
    """One sine test (amplitude rising over 2 cycles from rest, as a bench drives it): K' = k and
    K'' = c omega to the evaluation's interpolation error, from the command line's JSON."""
    f, a = 10.0, math.radians(1.0)
    history = H.sine(f, a, FS, run_in_cycles=5, cycles=5)
    t, x = history.time_s, history.angle_rad
    # during the ramp from rest the rate by central differences; once steady the exact one
    w = 2 * math.pi * f
    y = K * x + C * np.gradient(x, t, edge_order=2)
    steady = t >= 2.0 / f
    y[steady] = K * x[steady] + C * a * w * np.cos(w * t[steady])
    record = _write_csv(tmp_path / "kv.csv", {"time_s": t, "angle_rad": x, "torque_nm": y})
    code, out, _ = _run(capsys, ["evaluate-servo", record, "--json"])
    assert code == 0
    rows = json.loads(out)
    assert len(rows) == 1
    row = rows[0]
    assert row["storage_stiffness_nm_per_rad"] == pytest.approx(K, rel=1e-9)
    assert row["loss_stiffness_nm_per_rad"] == pytest.approx(C * w, rel=1e-7)
    assert row["loss_factor"] == pytest.approx(C * w / K, rel=1e-7)
    assert row["frequency_hz"] == pytest.approx(f, rel=1e-7)  # linear interpolation of the crossings
    # the one-eighth-cycle smoothing scales the amplitude by its gain at f (1 - 1e-4)
    assert row["amplitude_deg"] == pytest.approx(1.0, rel=2e-4)
    assert row["evaluated_cycles"] == 5
    # the last 5 whole cycles: the record's evaluation segment
    assert row["first_cycle_start_s"] == pytest.approx(history.evaluation_segments[0].start_s, abs=1e-3 / f)
    assert row["storage_stiffness_std_nm_per_deg"] == pytest.approx(0.0, abs=1e-9 * math.radians(K))


def test_noise_scatter_is_the_closed_form(tmp_path):
    """White noise sigma on the torque: a single cycle's first-harmonic K' scatters by
    sigma sqrt(2/N) / A (N samples per cycle; the smoothing passes the fundamental), and the
    mean over n cycles lies within its standard error of k."""
    f, a, sigma, n_cycles = 8.0, math.radians(1.0), 2.0, 41
    t = np.arange(int((n_cycles + 2) / f * FS)) / FS
    w = 2 * math.pi * f
    x = a * np.sin(w * t)
    y = K * x + C * a * w * np.cos(w * t) + np.random.default_rng(7).normal(0.0, sigma, t.size)
    record = _write_csv(tmp_path / "noisy.csv", {"time_s": t, "angle_rad": x, "torque_nm": y})
    row = evaluate_records([record], cycles=40).iloc[0]
    assert row["evaluated_cycles"] == 40
    expected = sigma * math.sqrt(2.0 / (FS / f)) / a  # N*m/rad
    # the sample standard deviation of 40 cycles is within 3 of its standard errors (1/sqrt(2*39) = 11 %)
    assert row["storage_stiffness_std_nm_per_rad"] == pytest.approx(expected, rel=0.34)
    assert row["loss_stiffness_std_nm_per_rad"] == pytest.approx(expected, rel=0.34)
    assert abs(row["storage_stiffness_nm_per_rad"] - K) < 4 * expected / math.sqrt(40)
    assert abs(row["loss_stiffness_nm_per_rad"] - C * w) < 4 * expected / math.sqrt(40)
    assert row["loss_factor_std"] == pytest.approx(expected / K, rel=0.34)


def test_several_blocks_ramping_from_rest_in_one_file(tmp_path):
    """An amplitude sweep from rest (each step blended in over 2 cycles) in one file: every
    block found, its last five cycles are the sweep's evaluation segment, and in each K' = k and
    K'' = c omega. A frequency sweep in one file: the blocks and figures of the bench's own
    evaluation (evaluate_history; at a switch of frequency the velocity jumps and the smoothing
    spreads the dashpot's step into the last cycle: both K'' 0.4 % above c omega at 2 Hz)."""
    amplitudes = np.radians([0.5, 1.0, 2.0, 4.0])
    sweeps = {"amplitude": H.amplitude_sweep(amplitudes, 5.0, FS, run_in_cycles=4, cycles=5),
              "frequency": H.frequency_sweep([2.0, 5.0, 10.0], math.radians(1.0), FS, run_in_cycles=4, cycles=5)}
    for name, history in sweeps.items():
        y = _kelvin_voigt(history.time_s, history.angle_rad)
        record = _write_csv(tmp_path / f"{name}.csv", {"time_s": history.time_s, "angle_rad": history.angle_rad,
                                                       "torque_nm": y})
        table = evaluate_records([record])
        segments = history.evaluation_segments
        bench = evaluate_history(history, y)
        assert len(table) == len(segments), table
        for row, seg, ev in zip(table.itertuples(), segments, bench):
            assert row.frequency_hz == pytest.approx(seg.frequency_hz, rel=1e-6)
            assert row.evaluated_cycles == 5
            # the last five cycles of the block are the history's evaluation segment
            assert row.first_cycle_start_s == pytest.approx(seg.start_s, abs=1e-3 / seg.frequency_hz)
            assert row.storage_stiffness_nm_per_rad == pytest.approx(ev.storage_stiffness_nm_per_rad, rel=1e-6)
            assert row.loss_stiffness_nm_per_rad == pytest.approx(ev.loss_stiffness_nm_per_rad, rel=1e-5)
            if name == "amplitude":
                assert row.storage_stiffness_nm_per_rad == pytest.approx(K, rel=1e-6)
                assert row.loss_stiffness_nm_per_rad == pytest.approx(C * 2 * math.pi * seg.frequency_hz, rel=1e-5)
        if name == "amplitude":
            np.testing.assert_allclose(table["amplitude_rad"], amplitudes, rtol=2e-4)


def test_a_record_without_time_vector(tmp_path, capsys):
    """No time channel: refused without a sample rate (naming the flags); with
    --sample-interval-s or --sample-rate-hz the same results as with the time channel."""
    history = H.amplitude_sweep(np.radians([1.0, 2.0]), 4.0, FS, run_in_cycles=3, cycles=4)
    y = _kelvin_voigt(history.time_s, history.angle_rad)
    timed = _write_csv(tmp_path / "timed.csv", {"time_s": history.time_s, "angle_rad": history.angle_rad, "torque_nm": y})
    bare = _write_csv(tmp_path / "bare.csv", {"angle_rad": history.angle_rad, "torque_nm": y})
    code, _, err = _run(capsys, ["evaluate-servo", bare])
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "bare.csv" in err and "--sample-rate-hz or --sample-interval-s" in err
    with pytest.raises(DroptowerError, match="`sample_rate_hz` or `sample_interval_s`"):
        evaluate_records([bare])
    reference = evaluate_records([timed])
    for flag, value in (("--sample-interval-s", 1 / FS), ("--sample-rate-hz", FS)):
        out = tmp_path / f"bench{flag}.csv"
        code, _, _ = _run(capsys, ["evaluate-servo", bare, flag, repr(value), "--out", str(out)])
        assert code == 0
        got = pd.read_csv(out)
        for column in ("storage_stiffness_nm_per_deg", "loss_factor", "amplitude_deg", "frequency_hz"):
            np.testing.assert_allclose(got[column], reference[column], rtol=1e-9)


def test_translational_record_in_mm_and_kn(tmp_path, capsys):
    """A bearing's displacement (mm) and force (kN), quasi-static blocks from rest, no time
    vector: K' = k (N/m) and K'' = c omega in the translational fields; through a lever arm r
    the torsional K' = k r^2 (rad, N*m) and the same loss factor."""
    k, c, r = 2.0e6, 5.0e4, 0.25  # N/m, N*s/m, m
    fs = 200.0
    history = H.amplitude_sweep([0.038, 0.076, 0.152], 0.5, fs, run_in_cycles=3, cycles=4)  # m (3.8-15.2 cm)
    y = _kelvin_voigt(history.time_s, history.angle_rad, k, c)
    record = _write_csv(tmp_path / "bearing.csv", {"Weg [mm]": 1e3 * history.angle_rad, "Kraft [kN]": 1e-3 * y})
    code, out, _ = _run(capsys, ["evaluate-servo", record, "--sample-interval-s", "0.005", "--json"])
    assert code == 0, out
    rows = json.loads(out)
    assert len(rows) == 3
    w = 2 * math.pi * 0.5
    for row, amplitude in zip(rows, (38.0, 76.0, 152.0)):
        assert row["storage_stiffness_n_per_m"] == pytest.approx(k, rel=1e-6)
        assert row["loss_stiffness_n_per_m"] == pytest.approx(c * w, rel=1e-5)
        assert row["amplitude_mm"] == pytest.approx(amplitude, rel=2e-4)
        assert "storage_stiffness_nm_per_rad" not in row
    code, out, _ = _run(capsys, ["evaluate-servo", record, "--sample-interval-s", "0.005", "--lever-arm-m", str(r),
                                 "--json"])
    assert code == 0
    rows_t = json.loads(out)
    for row, row_x in zip(rows_t, rows):
        assert row["storage_stiffness_nm_per_rad"] == pytest.approx(k * r * r, rel=1e-6)
        assert row["loss_factor"] == pytest.approx(row_x["loss_factor"], rel=1e-9)
        assert row["amplitude_rad"] == pytest.approx(row_x["amplitude_mm"] * 1e-3 / r, rel=1e-9)
    # a torsional record has no lever to read it by
    torsional = _write_csv(tmp_path / "t.csv", {"time_s": history.time_s, "angle_rad": history.angle_rad, "torque_nm": y})
    code, _, err = _run(capsys, ["evaluate-servo", torsional, "--lever-arm-m", "0.25"])
    assert code == 2 and "--lever-arm-m" in err and "torsional already" in err


def _good_record(n_cycles: int = 8, f: float = 10.0) -> dict[str, np.ndarray]:
    t = np.arange(int(n_cycles / f * FS)) / FS
    x = math.radians(1.0) * np.sin(2 * math.pi * f * t)
    return {"time_s": t, "angle_rad": x, "torque_nm": _kelvin_voigt(t, x)}


@pytest.mark.parametrize("case", ["missing channel", "one cycle", "nan", "time runs back", "constant angle"])
def test_malformed_records_are_one_line_exit_2(tmp_path, capsys, case):
    columns = _good_record()
    if case == "missing channel":
        del columns["torque_nm"]
    elif case == "one cycle":
        columns = _good_record(n_cycles=1)
    elif case == "nan":
        columns["torque_nm"][500] = np.nan
    elif case == "time runs back":
        columns["time_s"][700], columns["time_s"][701] = columns["time_s"][701], columns["time_s"][700]
    elif case == "constant angle":
        columns["angle_rad"][:] = 0.01
    record = _write_csv(tmp_path / "bad.csv", columns)
    code, out, err = _run(capsys, ["evaluate-servo", record])
    assert code == 2 and out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("droptower: error: ") and "bad.csv" in lines[0], err
    expected = {"missing channel": "no torque channel", "one cycle": "no block of at least two whole cycles",
                "nan": "NaN", "time runs back": "time", "constant angle": "constant"}[case]
    assert expected in lines[0]


def test_a_batch_goes_on_and_lists_its_failures(tmp_path, capsys):
    good = _write_csv(tmp_path / "good.csv", _good_record())
    bad = _write_csv(tmp_path / "bad.csv", {k: v for k, v in _good_record().items() if k != "torque_nm"})
    out = tmp_path / "bench.csv"
    code, _, err = _run(capsys, ["evaluate-servo", good, bad, str(tmp_path / "missing.csv"), "--out", str(out)])
    assert code == 2
    assert len(pd.read_csv(out)) == 1  # the good record's block is written
    assert "2 of 3 record(s) failed" in err and "missing.csv: no such file" in err and "bad.csv" in err


@settings(max_examples=25, deadline=None, derandomize=True)
@given(kind=st.sampled_from(["nan", "inf", "back", "cut", "flat"]), where=st.floats(0.0, 1.0))
def test_random_corruption_is_one_line(kind, where, tmp_path_factory):
    """Wherever a record is corrupted, the library raises one DroptowerError naming the file
    (never another exception) or, if the damage leaves whole blocks, evaluates them."""
    folder = tmp_path_factory.mktemp("corrupt")
    columns = _good_record(n_cycles=6)
    n = columns["time_s"].size
    i = min(n - 2, int(where * (n - 1)))
    if kind in ("nan", "inf"):
        columns["torque_nm"][i] = np.nan if kind == "nan" else np.inf
    elif kind == "back":
        columns["time_s"][i + 1] = columns["time_s"][i] - 1e-4
    elif kind == "cut":
        columns = {k: v[: max(3, i // 4)] for k, v in columns.items()}
    else:
        columns["angle_rad"][i:] = columns["angle_rad"][i]
    record = _write_csv(folder / "r.csv", columns)
    try:
        table = evaluate_records([record])
    except DroptowerError as exc:
        assert "r.csv" in str(exc) and "\n" not in str(exc)
    else:
        assert kind in ("cut", "flat")
        np.testing.assert_allclose(table["storage_stiffness_nm_per_rad"], K, rtol=1e-6)


def test_blocks_of_a_record_from_rest():
    """find_blocks: plateaus of amplitude, their whole cycles from upward crossing to upward crossing."""
    history = H.amplitude_sweep(np.radians([1.0, 3.0]), 5.0, FS, run_in_cycles=4, cycles=5)
    blocks = find_blocks(history.time_s, history.angle_rad)
    assert [b.index for b in blocks] == [1, 2]
    np.testing.assert_allclose([b.amplitude_rad for b in blocks], np.radians([1.0, 3.0]), rtol=1e-3)
    np.testing.assert_allclose([b.frequency_hz for b in blocks], 5.0, rtol=1e-7)
    # the steady cycles (run-in after its 2 ramp cycles, and the evaluated ones) are whole cycles of the block
    assert all(b.n_cycles >= 7 for b in blocks)


def test_the_bench_records_of_a_nonlinear_coupling_give_the_bench_s_own_figures(tmp_path, capsys):
    """rapp2022_nr60 (filler network, Payne, Maxwell branches) on the virtual bench: its raw
    records written by the package's log writer and evaluated through the command line give
    the K' and loss factor the bench's own evaluation reports (run_grid), to round-off."""
    amplitudes, frequencies = np.radians([0.5, 1.5]), [10.0, 30.0]
    records = run_records("rapp2022_nr60", amplitudes, frequencies)
    grid = run_grid("rapp2022_nr60", amplitudes, frequencies)
    paths = []
    for i, rec in enumerate(records):
        paths.append(str(write_log(tmp_path / f"servo_{i}.csv", rec.time_s, {"angle_rad": rec.angle_rad,
                                                                              "torque_nm": rec.torque_nm}, {})))
    out = tmp_path / "bench.csv"
    code, _, _ = _run(capsys, ["evaluate-servo", *paths, "--out", str(out)])
    assert code == 0
    got = pd.read_csv(out)
    assert len(got) == len(grid)
    np.testing.assert_allclose(got["frequency_hz"], grid["frequency_hz"], rtol=1e-6)
    # half peak-to-peak of the resampled cycles: the peaks fall between the 1024 points of a cycle differently
    np.testing.assert_allclose(got["amplitude_deg"], grid["angle_amplitude_deg"], rtol=1e-6)
    np.testing.assert_allclose(got["storage_stiffness_nm_per_deg"], grid["storage_stiffness_nm_per_deg"], rtol=1e-6)
    np.testing.assert_allclose(got["loss_factor"], grid["loss_factor"], rtol=1e-6)
    np.testing.assert_allclose(got["relative_damping_psi"], grid["relative_damping_psi"], rtol=1e-6)


def test_a_nonlinear_sweep_in_one_file_gives_the_bench_s_evaluation(tmp_path):
    """One file holding an amplitude sweep of rapp2022_nr60 (blocks blended from one amplitude
    to the next): the blocks found in it and their last cycles are the sweep's evaluation
    segments, and K', K'', loss factor are the bench's evaluate_history of the same record."""
    coupling = load_coupling("rapp2022_nr60")
    history = H.amplitude_sweep(np.radians([0.5, 1.0, 2.0]), 10.0, FS, run_in_cycles=5, cycles=5)
    # the coupling driven on a fine step (16 x), recorded at the bench's rate
    fine = 16
    t_fine = np.arange(history.time_s.size * fine) / (FS * fine)
    angle_fine = np.interp(t_fine, history.time_s, history.angle_rad)
    torque = coupling.simulate(angle_fine[None, :], 1.0 / (FS * fine)).torque_nm[0, ::fine]
    angle = angle_fine[::fine]
    path = write_log(tmp_path / "sweep.csv", history.time_s, {"angle_rad": angle, "torque_nm": torque}, {})
    reference = evaluate_history(history, torque)
    table = evaluate_records([path])
    assert len(table) == len(reference)
    for row, ev in zip(table.itertuples(), reference):
        assert row.storage_stiffness_nm_per_rad == pytest.approx(ev.storage_stiffness_nm_per_rad, rel=1e-6)
        assert row.loss_factor == pytest.approx(ev.loss_factor, rel=1e-6)


@pytest.fixture(scope="module")
def map_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("map") / "map.json"
    assert main(["map", "rapp2022_table4", "--out", str(path), "--quiet"]) == 0
    return path


def test_validate_servo_records_in_one_go(tmp_path, capsys, map_file):
    """validate --servo-records = evaluate-servo --out bench.csv, then validate --servo-results
    bench.csv: the same deviations; the evaluated table is kept in --out."""
    amplitudes, frequencies = np.radians([0.5, 1.5]), [10.0, 30.0]
    paths = [str(write_log(tmp_path / f"s{i}.csv", r.time_s, {"angle_rad": r.angle_rad, "torque_nm": r.torque_nm}, {}))
             for i, r in enumerate(run_records("rapp2022_nr60", amplitudes, frequencies))]
    bench = tmp_path / "bench.csv"
    assert main(["evaluate-servo", *paths, "--out", str(bench), "--quiet"]) == 0
    code, out, _ = _run(capsys, ["validate", "--map", str(map_file), "--servo-results", str(bench), "--json"])
    assert code == 0
    two_steps = json.loads(out)
    records = [a for p in paths for a in ("--servo-records", p)]
    code, out, err = _run(capsys, ["validate", "--map", str(map_file), *records, "--json", "--out", str(tmp_path / "v")])
    assert code == 0, err
    one_go = json.loads(out)
    assert len(one_go["points"]) == 4
    assert one_go["points"] == two_steps["points"]
    assert one_go["summary"]["servo_source"].startswith("servo records s0.csv, s1.csv, s2.csv and 1 more")
    assert (tmp_path / "v" / "servo_records.csv").is_file()
    # without --out: a temporary table, nothing left behind, the same points
    code, out, _ = _run(capsys, ["validate", "--map", str(map_file), *records, "--json"])
    assert code == 0 and json.loads(out)["points"] == two_steps["points"]
    # the records' flags without records, records and results together, a translational record without lever
    code, _, err = _run(capsys, ["validate", "--map", str(map_file), "--servo-sample-rate-hz", "100"])
    assert code == 2 and "--servo-sample-rate-hz needs --servo-records" in err
    code, _, err = _run(capsys, ["validate", "--map", str(map_file), *records, "--servo-results", str(bench)])
    assert code == 2 and "not both" in err
    history = H.sine(1.0, 0.01, 200.0, run_in_cycles=3, cycles=3)
    mm = _write_csv(tmp_path / "mm.csv", {"Weg [mm]": 1e3 * history.angle_rad,
                                          "Kraft [kN]": 1e-3 * _kelvin_voigt(history.time_s, history.angle_rad, 1e6, 1e3)})
    code, _, err = _run(capsys, ["validate", "--map", str(map_file), "--servo-records", mm])
    assert code == 2 and "--servo-sample-rate-hz or --servo-sample-interval-s" in err
    code, _, err = _run(capsys, ["validate", "--map", str(map_file), "--servo-records", mm,
                                 "--servo-sample-interval-s", "0.005"])
    assert code == 2 and "--servo-lever-arm-m" in err
    code, out, err = _run(capsys, ["validate", "--map", str(map_file), "--servo-records", mm,
                                   "--servo-sample-interval-s", "0.005", "--servo-lever-arm-m", "0.25", "--json"])
    assert code == 0, err
    assert len(json.loads(out)["points"]) == 1


def test_every_flag_of_servo_and_evaluate_servo_is_documented():
    """docs/guide/servo.md names every flag of `servo` and `evaluate-servo` and validate's
    servo-record flags (each in its table, in backticks), and no flag those commands lack."""
    import re
    from pathlib import Path

    from droptower.cli.servo_cmd import servo
    import click

    from droptower.cli.servo_records_cmd import evaluate_servo, servo_record_options
    from droptower.cli.validate_cmd import validate

    page = (Path(__file__).resolve().parents[1] / "docs" / "guide" / "servo.md").read_text(encoding="utf-8")
    documented = set(re.findall(r"`(--[a-z][a-z0-9-]*)", page))
    flags = set()
    for command in (servo, evaluate_servo):
        flags |= {opt for p in command.params for opt in p.opts if opt.startswith("--") and opt != "--help"}
    servo_records_flags = {opt for p in click.command()(servo_record_options(lambda **kw: None)).params for opt in p.opts}
    assert servo_records_flags <= {opt for p in validate.params for opt in p.opts}
    missing = (flags | servo_records_flags) - documented
    assert not missing, f"undocumented in docs/guide/servo.md: {sorted(missing)}"
    known = flags | {opt for p in validate.params for opt in p.opts}
    assert documented <= known, f"documented but no such flag: {sorted(documented - known)}"


def test_a_sample_rate_that_contradicts_the_time_channel_is_refused(tmp_path, capsys):
    record = _write_csv(tmp_path / "timed.csv", _good_record())
    code, _, err = _run(capsys, ["evaluate-servo", record, "--sample-rate-hz", "1000"])
    assert code == 2 and "runs at 2048 Hz" in err and "--sample-rate-hz" in err
    assert _run(capsys, ["evaluate-servo", record, "--sample-interval-s", repr(1 / FS), "--json"])[0] == 0
    code, _, err = _run(capsys, ["evaluate-servo", record, "--sample-rate-hz", "1000", "--sample-interval-s", "0.001"])
    assert code == 2 and "not both" in err
    folder = tmp_path / "folder.csv"
    folder.mkdir()
    code, _, err = _run(capsys, ["evaluate-servo", str(folder)])
    assert code == 2 and err.strip().endswith("folder.csv: not a file")


def test_a_nonlinear_translational_record_from_rest_in_mm_and_kn(tmp_path):
    """seed001_specimen (the elastoslide paper's specimen: friction and rate dependence, a
    translational coupling) driven through blocks ramping up from rest at 0.5 Hz, written in mm
    and kN without a time vector: the blocks found and K', loss factor of the bench's own
    evaluation of the SI record (evaluate_history)."""
    coupling = load_coupling("seed001_specimen")
    fs = 256.0
    history = H.amplitude_sweep([0.5e-3, 1.5e-3, 3e-3], 0.5, fs, run_in_cycles=3, cycles=4)
    fine = 16
    t_fine = np.arange(history.time_s.size * fine) / (fs * fine)
    motion = np.interp(t_fine, history.time_s, history.angle_rad)
    force = coupling.simulate(motion[None, :], 1.0 / (fs * fine)).torque_nm[0, ::fine]
    reference = evaluate_history(history, force)
    record = _write_csv(tmp_path / "specimen.csv", {"Weg [mm]": 1e3 * motion[::fine], "Kraft [kN]": 1e-3 * force})
    table = evaluate_records([record], sample_interval_s=1 / fs, cycles=4)
    assert len(table) == len(reference) == 3
    for row, ev in zip(table.itertuples(), reference):
        assert row.storage_stiffness_n_per_m == pytest.approx(ev.storage_stiffness_nm_per_rad, rel=1e-5)
        assert row.loss_factor == pytest.approx(ev.loss_factor, rel=1e-5)
    assert table["loss_factor"].iloc[-1] > 0.05  # friction: a loop, not a line


def test_a_record_of_whole_cycles_from_its_first_sample():
    """Stamps 0 to T - dt of exactly 8 sine cycles: the crossings at 0 and T (just outside the
    samples) bound whole cycles too: 8 whole cycles; the first is settling, the last has no
    samples after it for the smoothing: cycles 3 to 7 evaluated, K' = k."""
    f = 4.0
    t = np.arange(int(8 / f * FS)) / FS
    x = math.radians(1.0) * np.sin(2 * math.pi * f * t)
    row = evaluate_record(t, x, _kelvin_voigt(t, x)).iloc[0]
    assert row["block_cycles"] == 8 and row["evaluated_cycles"] == 5
    assert row["first_cycle_start_s"] == pytest.approx(2 / f, abs=1e-6)
    assert row["storage_stiffness_nm_per_rad"] == pytest.approx(K, rel=1e-6)
