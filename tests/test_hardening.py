"""Absurd sizes, deep nesting, full disks, permissions, concurrent campaigns, exit codes.

Each kind of fault is tried with several cases; every one must end in one line naming the file
(or option) and the problem, exit code 2, no traceback, and nothing allocated or written that
the request could not finish.
"""
from __future__ import annotations

import builtins
import errno
import json
import os
import subprocess
import sys
import textwrap
import tracemalloc
import warnings
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from droptower.cli.main import main
from droptower.errors import DroptowerError

REPO = Path(__file__).resolve().parents[1]
SMALL_PLAN = """
name = "small"
heights_m = [0.2, 0.4]
repeats = 2
[[group]]
inertia_kgm2 = 0.359
drop_mass_kg = 2.0
"""
#: what a refused request may allocate at most: parsing its input and building the one-line error
#: stay far below it (measured: a few MiB), while each of these requests, had it been served,
#: needs more than the 2 GiB memory limit (or a coupling of 10^4+ elements per instance): a refusal
#: after allocating shows here, whatever the machine's load (no wall-clock bound)
REFUSED_PEAK_BYTES = 256 * 2**20


@contextmanager
def peak_allocation():
    """The peak of the Python and NumPy allocations traced inside the block (``.bytes``)."""
    class Peak:
        bytes = 0

    tracemalloc.start()
    try:
        yield Peak
    finally:
        Peak.bytes = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()


ELASTOSLIDE = """
[[element]]
kind = "elastoslide"
phi0 = 0.01
k = 1000.0
k0 = 100.0
v_r = 1.0
n = {n}
"""


def one_line_error(capsys: pytest.CaptureFixture[str], *needles: str) -> str:
    """The captured stderr is exactly one ``droptower: error:`` line holding every needle."""
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("droptower: error: "), err
    assert "Traceback" not in err and "np.float64" not in err, err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


def small_log(path: Path) -> Path:
    """A short simulated drop test (a log extract can evaluate)."""
    assert main(["simulate", "--inertia-kgm2", "0.359", "--drop-mass-kg", "2", "--height-m", "0.4",
                 "--duration-s", "0.06", "--out", str(path)]) == 0
    return path


@pytest.fixture(scope="module")
def good_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return small_log(tmp_path_factory.mktemp("logs") / "good.csv")


# ---- sizes that would exhaust the memory or run for days -----------------------------------------
@pytest.mark.parametrize("text, needle", [
    (ELASTOSLIDE.format(n="1e9"), "n = 1000000000 exceeds the limit of 10000"),
    (ELASTOSLIDE.format(n="20000"), "n = 20000 exceeds the limit of 10000"),
    ('[[element]]\nkind = "masing"\nn = 10000000\nstiffness = 1.0\nmax_yield_torque = 1.0\nalpha = 1.0\n',
     "n = 10000000 exceeds the limit of 10000"),
    ("[[element]]\nkind = \"spring\"\nstiffness = 1.0\n" * 1001, "1001 elements exceed the limit of 1000"),
    (ELASTOSLIDE.format(n=5000) * 20, "state variables per instance exceed the limit of 100000"),
    ('[[element]]\nkind = "elastoslide"\nk = 1.0\nk0 = 1.0\nv_r = 1.0\n[element.distribution]\n'
     f'yield_torque = [{", ".join(["1.0"] * 10001)}]\nweight = [{", ".join(["1.0"] * 10001)}]\n',
     "n = 10001 exceeds the limit of 10000"),
])
def test_huge_couplings_are_refused_before_allocating(tmp_path, capsys, text, needle):
    path = tmp_path / "huge.toml"
    path.write_text(text)
    with peak_allocation() as peak:
        assert main(["servo", str(path), "--amplitude-deg", "1", "--frequency-hz", "10"]) == 2
    assert peak.bytes < REFUSED_PEAK_BYTES
    one_line_error(capsys, str(path), needle)


@pytest.mark.parametrize("args, needle", [
    (["--duration-s", "1e9"], "more than the limit of 2 GiB"),
    (["--duration-s", "1e4"], "record at most 437 s after the impact"),
    (["--duration-s", "inf"], "--duration-s: must be > 0, got inf"),
])
def test_simulate_records_beyond_the_memory_limit_are_refused(capsys, args, needle):
    assert main(["simulate", "--inertia-kgm2", "0.359", "--drop-mass-kg", "2", "--height-m", "1", *args]) == 2
    one_line_error(capsys, "--duration-s", needle)


def test_memory_limit_follows_the_environment(monkeypatch, capsys):
    monkeypatch.setenv("DROPTOWER_MEMORY_LIMIT_GB", "0.001")  # 1 MiB: a 0.25 s record needs ~1.2 MiB
    assert main(["simulate", "--inertia-kgm2", "0.359", "--drop-mass-kg", "2", "--height-m", "1"]) == 2
    one_line_error(capsys, "more than the limit of 1.02 MiB (DROPTOWER_MEMORY_LIMIT_GB)")
    assert main(["simulate", "--inertia-kgm2", "0.359", "--drop-mass-kg", "2", "--height-m", "1",
                 "--duration-s", "0.1"]) == 0
    capsys.readouterr()
    monkeypatch.setenv("DROPTOWER_MEMORY_LIMIT_GB", "lots")
    assert main(["simulate", "--inertia-kgm2", "0.359", "--drop-mass-kg", "2", "--height-m", "1"]) == 2
    one_line_error(capsys, "DROPTOWER_MEMORY_LIMIT_GB: must be a number of GiB, got 'lots'")


@pytest.mark.parametrize("args, needle", [
    (["--frequency-hz", "1e-6"], "the servo run at 1e-06 Hz"),
    (["--frequency-hz", "1e-3,10"], "the servo run at 0.001 Hz"),
    (["--cycles", "1000000000"], "1e+09 cycles"),
    (["--sample-rate-hz", "1e308"], "needs an unbounded amount of memory"),
])
def test_servo_grids_beyond_the_limits_are_refused(capsys, args, needle):
    base = {"--frequency-hz": "10", "--amplitude-deg": "1"}
    base.update(dict(zip(args[::2], args[1::2])))
    with peak_allocation() as peak:
        assert main(["servo", "rapp2022_nr60", *[x for kv in base.items() for x in kv]]) == 2
    assert peak.bytes < REFUSED_PEAK_BYTES
    one_line_error(capsys, needle, "raise the lowest --frequency-hz")


def test_histories_refuse_before_allocating():
    from droptower.servo import histories

    with pytest.raises(DroptowerError, match=r"a history of 1.25e\+07 s at 38400 Hz needs about 6.98 TiB"):
        histories.sine(1e-6, 1.0, 38400.0)


def _plan(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "plan.toml"
    path.write_text(text)
    return path


def test_plan_with_ten_million_repeats_is_predicted_per_condition(tmp_path, capsys):
    """repeats = 1e7: ``plan`` predicts its 2 conditions (never the 2e7 rows); ``campaign`` refuses."""
    # the first plan of the process imports the planner and loads its kernels: done here, outside
    # the traced block (they are not the request's allocations; traced, they take ~10 s of CPU)
    assert main(["plan", "--doe", str(_plan(tmp_path, SMALL_PLAN))]) == 0
    capsys.readouterr()
    path = _plan(tmp_path, SMALL_PLAN.replace("repeats = 2", "repeats = 1e7"))
    with peak_allocation() as peak:
        assert main(["plan", "--doe", str(path)]) == 0
        assert "2 conditions, 20000000 tests" in capsys.readouterr().out
        assert main(["campaign", "--doe", str(path), "--out", str(tmp_path / "run")]) == 2
    one_line_error(capsys, str(path), "20000000 tests", "limit of 100000 per campaign", "split the plan")
    assert peak.bytes < REFUSED_PEAK_BYTES  # 2e7 tests would be a table of gigabytes
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("heights, preloads", [(10_000, 1_000), (2_000, 3), (5_001, 1)])
def test_plans_with_too_many_conditions_are_refused(tmp_path, capsys, heights, preloads):
    text = (f"heights_m = [{', '.join(f'{0.05 + i * 1e-6:.6f}' for i in range(heights))}]\n"
            f"preloads_nm = [{', '.join(f'{0.1 * i:.1f}' for i in range(preloads))}]\n"
            "[[group]]\ninertia_kgm2 = 0.359\ndrop_mass_kg = 2.0\n")
    path = _plan(tmp_path, text)
    for command in (["plan", "--doe", str(path)], ["campaign", "--doe", str(path), "--out", str(tmp_path / "run")]):
        assert main(command) == 2
        one_line_error(capsys, str(path), f"{heights * preloads} test conditions", "limit of 5000 per plan")
    assert not (tmp_path / "run").exists()


def test_campaign_records_beyond_the_limit_are_refused(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["campaign", "--doe", str(_plan(tmp_path, SMALL_PLAN)), "--duration-s", "1e9", "--out", str(out)]) == 2
    one_line_error(capsys, "--duration-s", "4 drop test(s) of 1e+09 s", "record at most")
    assert not out.exists()


# ---- deep nesting --------------------------------------------------------------------------------
@pytest.mark.parametrize("kind, text", [
    ("coupling", "x = " + "[" * 20_000 + "]" * 20_000 + "\n"),
    ("coupling", "x = " + "{a = " * 5_000 + "1" + "}" * 5_000 + "\n"),
    ("doe", "x = " + "[" * 40 + "]" * 40 + "\n"),   # parses, but deeper than any config
    ("rig", "a.b.c.d.e.f.g.h.i.j.k.l.m.n.o.p.q.r.s.t.u.v.w.x.y.z.aa.bb.cc.dd.ee.ff.gg = 1\n"),
])
def test_deeply_nested_toml_is_one_line(tmp_path, capsys, kind, text):
    path = tmp_path / f"{kind}.toml"
    path.write_text(text)
    command = {"coupling": ["servo", str(path)], "doe": ["plan", "--doe", str(path)],
               "rig": ["plan", "--rig", str(path)]}[kind]
    assert main(command) == 2
    one_line_error(capsys, str(path), "nested too deeply")


def test_oversized_config_is_refused_unparsed(tmp_path, capsys):
    path = tmp_path / "big.toml"
    path.write_text("# padding\n" * 1_800_000)  # 18 MB
    assert main(["servo", str(path)]) == 2
    one_line_error(capsys, str(path), "larger than 16 MiB")


def test_deeply_nested_json_map_and_log_metadata(tmp_path, capsys):
    deep = "[" * 100_000 + "]" * 100_000
    map_file = tmp_path / "map.json"
    map_file.write_text(deep)
    assert main(["validate", "--map", str(map_file)]) == 2
    one_line_error(capsys, str(map_file), "nested too deeply")
    log = tmp_path / "deep.csv"
    log.write_text(f"# droptower-log 1\n# x = {deep}\ntime_s,angle_rad\n0,0\n")
    assert main(["channels", str(log)]) == 2
    one_line_error(capsys, str(log), "nested too deeply")


# ---- full disk -----------------------------------------------------------------------------------
@pytest.fixture
def disk_full_below(monkeypatch):
    """Every atomic write into a path containing the given part fails as a full disk does (after
    the temporary file was partly written)."""
    import droptower.io.droptower_log as log_module

    real_replace = os.replace

    def full(part: str) -> None:
        def replace(src, dst):
            if part in str(dst):
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            real_replace(src, dst)
        monkeypatch.setattr(log_module.os, "replace", replace)
    return full


def test_simulate_out_on_a_full_disk(tmp_path, capsys, disk_full_below):
    disk_full_below("full")
    target = tmp_path / "full" / "test.parquet"
    assert main(["simulate", "--inertia-kgm2", "0.359", "--drop-mass-kg", "2", "--height-m", "0.4",
                 "--duration-s", "0.02", "--out", str(target)]) == 2
    one_line_error(capsys, str(target), "cannot write (No space left on device)")
    assert list(target.parent.iterdir()) == []  # no partial file, no temporary file


def test_extract_out_on_a_full_disk(tmp_path, capsys, good_log, disk_full_below):
    disk_full_below("full")
    target = tmp_path / "full.csv"
    assert main(["extract", str(good_log), "--out", str(target)]) == 2
    one_line_error(capsys, str(target), "cannot write (No space left on device)")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("part", ["logs", "records", "manifest.json"])
def test_campaign_on_a_full_disk_stops_once_and_resumes(tmp_path, capsys, disk_full_below, part):
    """A full disk is not an "internal error", is printed once, stops the campaign (exit 2), and
    --resume finishes it once there is room."""
    out = tmp_path / "run"
    plan = _plan(tmp_path, SMALL_PLAN)
    disk_full_below(str(out / part))
    assert main(["campaign", "--doe", str(plan), "--out", str(out), "--workers", "1", "--chunk-size", "2"]) == 2
    line = one_line_error(capsys, "cannot write (No space left on device)", "continue with --resume")
    assert "internal error" not in line and str(out) in line
    assert not list(out.rglob("*.tmp"))
    disk_full_below("no such part")  # room again
    args = ["campaign", "--doe", str(plan), "--out", str(out), "--workers", "1", "--chunk-size", "2"]
    assert main(args + (["--resume"] if (out / "manifest.json").exists() else [])) == 0
    assert "4 extracted, 0 failed, 0 pending" in capsys.readouterr().out


def test_os_errors_outside_the_atomic_writer_are_one_line(tmp_path, capsys, monkeypatch):
    """The CLI's net: an OSError from any other write (here the plan's table) is one line, exit 2."""
    import droptower.io.tables as tables

    def refuse(*args, **kwargs):
        raise PermissionError(errno.EACCES, "Permission denied", str(tmp_path / "plan.csv"))
    monkeypatch.setattr(tables, "write_table", refuse)
    # a small plan: the shipped one predicts 90 conditions (the batch-parallel kernel) before the write
    assert main(["plan", "--doe", str(_plan(tmp_path, SMALL_PLAN)), "--out", str(tmp_path / "plan.csv")]) == 2
    one_line_error(capsys, "plan.csv: Permission denied")


# ---- files the user gave: exit codes, malformed, unreadable --------------------------------------
def test_every_per_file_error_exits_2_and_is_listed(tmp_path, capsys, good_log):
    empty, missing, binary = tmp_path / "empty.csv", tmp_path / "missing.csv", tmp_path / "noise.bin"
    empty.write_text("")
    binary.write_bytes(os.urandom(256))
    for bad in (empty, missing, binary):
        assert main(["extract", str(bad)]) == 2
        one_line_error(capsys, str(bad))
    assert main(["extract", str(empty), str(good_log), str(missing), "--json"]) == 2
    captured = capsys.readouterr()
    assert len(json.loads(captured.out)) == 1  # the good log is still evaluated
    assert "2 of 3 file(s) failed" in captured.err and str(empty) in captured.err and str(missing) in captured.err


@pytest.fixture(scope="module")
def mdf_files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    from asammdf import MDF, Signal

    folder = tmp_path_factory.mktemp("mdf")
    t = np.arange(1000) / 1000.0
    with MDF(version="4.10") as mdf:
        mdf.append([Signal(np.sin(t), t, name="angle", unit="rad"), Signal(np.cos(t), t, name="torque", unit="N*m")])
        mdf.save(folder / "good.mf4", overwrite=True)
    data = (folder / "good.mf4").read_bytes()
    garbled = bytearray(data)
    garbled[100:400] = b"\xff" * 300
    # marked unfinalised (identification "UnFinMF ", standard flags at byte 60): asammdf copies it
    # into its temporary folder before it finds the garbled blocks
    unfinalised = bytearray(garbled)
    unfinalised[0:8], unfinalised[60:62] = b"UnFinMF ", (1).to_bytes(2, "little")
    files = {"truncated": data[:200], "garbled": bytes(garbled), "zeroed": data[:64] + bytes(len(data) - 64),
             "unfinalised": bytes(unfinalised)}
    for name, content in files.items():
        (folder / f"{name}.mf4").write_bytes(content)
    return {name: folder / f"{name}.mf4" for name in files}


@pytest.mark.parametrize("name", ["truncated", "garbled", "zeroed", "unfinalised"])
def test_malformed_mdf4_is_one_line_naming_the_file(capsys, mdf_files, name):
    path = mdf_files[name]
    assert main(["channels", str(path)]) == 2
    line = one_line_error(capsys, str(path), "cannot read (MDF file")
    assert "mmap" not in line


def test_no_file_is_left_in_the_temporary_folder_after_a_failure(tmp_path, capsys, mdf_files, monkeypatch):
    import tempfile

    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    empty, binary, text = tmp_path / "empty.csv", tmp_path / "noise.bin", tmp_path / "text.tdms"
    empty.write_text("")
    binary.write_bytes(bytes(range(256)) * 8)
    text.write_text("not tdms")
    bad = [*mdf_files.values(), empty, binary, text]
    for command in ("channels", "extract"):
        for path in bad:
            assert main([command, str(path)]) == 2
            one_line_error(capsys, str(path))
            assert list(scratch.iterdir()) == [], (command, path.name)


def test_unreadable_file_does_not_stop_the_batch(tmp_path, capsys, good_log, monkeypatch):
    """As a user without read permission sees it (os.access False, open refused): the file is one
    failure of the batch, the others are evaluated (no root needed to test it)."""
    locked = tmp_path / "locked.csv"
    locked.write_bytes(good_log.read_bytes())
    real_access, real_open = os.access, builtins.open

    def access(path, mode, *args, **kwargs):
        return False if Path(path) == locked else real_access(path, mode, *args, **kwargs)

    def open_(file, *args, **kwargs):
        if isinstance(file, (str, Path)) and Path(file) == locked:
            raise PermissionError(errno.EACCES, "Permission denied", str(file))
        return real_open(file, *args, **kwargs)
    monkeypatch.setattr(os, "access", access)
    monkeypatch.setattr(builtins, "open", open_)
    assert main(["extract", str(locked), str(good_log), "--json"]) == 2
    captured = capsys.readouterr()
    assert [Path(r["file"]).name for r in json.loads(captured.out)] == [good_log.name]
    assert f"{locked}: cannot read (Permission denied)" in captured.err and "1 of 2 file(s) failed" in captured.err


# ---- values: absurd, infinite, in messages -------------------------------------------------------
@pytest.mark.parametrize("option, value, needle", [
    ("--lever-length-m", "inf", "--lever-length-m: must be > 0 and at most 10, got inf"),
    ("--lever-length-m", "nan", "got nan"),
    ("--lever-length-m", "1e308", "got 1e+308"),
    ("--inertia-kgm2", "inf", "--inertia-kgm2: must be > 0"),
    ("--sample-rate-hz", "1e308", "--sample-rate-hz: must be > 0"),
])
def test_extract_refuses_infinite_and_absurd_rig_values(capsys, good_log, option, value, needle):
    assert main(["extract", str(good_log), option, value]) == 2
    one_line_error(capsys, needle)


def test_log_metadata_must_be_finite(tmp_path, capsys, good_log):
    text = good_log.read_text().replace("# lever_length_m = 0.2", "# lever_length_m = Infinity")
    assert "Infinity" in text
    path = tmp_path / "inf.csv"
    path.write_text(text)
    assert main(["extract", str(path)]) == 2
    one_line_error(capsys, str(path), "lever_length_m: must be > 0, got inf")


@pytest.mark.parametrize("option, value", [("--inertia-kgm2", "1e308"), ("--inertia-kgm2", "1e-308"),
                                           ("--drop-mass-kg", "1e308"), ("--drop-mass-kg", "1e-308")])
def test_absurd_test_values_are_refused_without_overflow(capsys, option, value):
    args = {"--inertia-kgm2": "0.359", "--drop-mass-kg": "2", "--height-m": "1", option: value}
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no overflow RuntimeWarning on the way
        assert main(["simulate", *[x for kv in args.items() for x in kv]]) == 2
    line = one_line_error(capsys, option, f"{float(value):g}", "times the fixtures of rig")
    assert "steps_per_sample" not in line  # the value is named, not the time step


@pytest.mark.parametrize("args, needle", [
    (["--amplitude-deg", "1e308"], "every amplitude must lie within 1e-06-90 deg, got 1e+308 deg"),
    (["--amplitude-deg", "1e-308"], "got 1e-308 deg"),   # underflow: once blamed the sample rate
    (["--amplitude-deg", "0.5,180"], "got 0.5, 180 deg"),
    (["--preload-nm", "1e308"], "preload 1e+308 N*m is beyond +-1e+06 N*m"),
])
def test_servo_refuses_absurd_amplitudes_and_preloads(capsys, args, needle):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["servo", "rapp2022_nr60", "--frequency-hz", "10", *args]) == 2
    line = one_line_error(capsys, needle)
    assert "sample-rate" not in line and "NaN" not in line


@pytest.mark.parametrize("content, needle", [
    ("time_s,angle_rad,torque_nm\n0,0.045,1\n0.001,0.046,2\n0.0005,0.047,3\n", "(0.001 s -> 0.0005 s)"),
    ("".join(f"{i / 1000},0.045,1\n" for i in range(400)), "constant signal (0.045"),
])
def test_messages_show_plain_numbers(tmp_path, capsys, content, needle):
    path = tmp_path / "log.csv"
    path.write_text("# droptower-log 1\n# inertia_kgm2 = 0.359\n# lever_length_m = 0.2\n"
                    + ("" if content.startswith("time_s") else "time_s,angle_rad,torque_nm\n") + content)
    assert main(["extract", str(path)]) == 2
    one_line_error(capsys, str(path), needle)


# ---- campaign folders: resume, lock, file modes --------------------------------------------------
def test_resume_needs_a_campaign(tmp_path, capsys):
    for out in (tmp_path / "absent", tmp_path):
        assert main(["campaign", "--resume", "--out", str(out)]) == 2
        one_line_error(capsys, str(out), "holds no campaign to resume")
    assert not (tmp_path / "absent").exists()


def test_a_second_campaign_into_a_busy_folder_is_refused(tmp_path, capsys):
    from droptower.campaign.folder import folder_lock

    out = tmp_path / "run"
    args = ["campaign", "--doe", str(_plan(tmp_path, SMALL_PLAN)), "--out", str(out), "--workers", "1"]
    with folder_lock(out):  # a running campaign holds it
        assert main(args) == 2
        one_line_error(capsys, str(out), "another droptower campaign is running in this folder")
    # released when the holder ends: the folder (holding only the lock file) takes a campaign
    assert main(args) == 0
    capsys.readouterr()
    with folder_lock(out):
        assert main(args + ["--resume"]) == 2
        one_line_error(capsys, str(out), "another droptower campaign is running in this folder")


def _lock_in_another_process(folder: Path) -> str:
    """Take the campaign folder's lock in a second process (forked: the modules are imported
    already) and give back its error, or "" if it got the lock."""
    from droptower.campaign.folder import folder_lock

    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: say what happened and leave at once (no pytest teardown in here)
        try:
            with folder_lock(folder):
                said = ""
        except DroptowerError as exc:
            said = exc.message
        except BaseException as exc:  # whatever it was, the parent's assertion shows it
            said = f"unexpected {exc!r}"
        os.write(write, said.encode())
        os._exit(0)
    os.close(write)
    with os.fdopen(read) as pipe:
        said = pipe.read()
    os.waitpid(pid, 0)
    return said


def test_the_lock_is_held_across_processes(tmp_path):
    """flock is per open file: a second process sees the lock of the first."""
    from droptower.campaign.folder import folder_lock

    out = tmp_path / "run"
    with folder_lock(out):
        said = _lock_in_another_process(out)
    assert "another droptower campaign is running" in said
    assert _lock_in_another_process(out) == ""


@pytest.mark.parametrize("umask, mode", [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_written_files_honour_the_umask(tmp_path, good_log, umask, mode):
    old = os.umask(umask)
    try:
        log = small_log(tmp_path / "sim.csv")
        assert main(["extract", str(good_log), "--out", str(tmp_path / "results.csv")]) == 0
        out = tmp_path / "run"
        assert main(["campaign", "--doe", str(_plan(tmp_path, SMALL_PLAN)), "--out", str(out), "--workers", "1"]) == 0
    finally:
        os.umask(old)
    written = [log, tmp_path / "results.csv", out / "manifest.json", out / "results.csv", *out.glob("logs/*"),
               *out.glob("records/*")]
    assert {oct(p.stat().st_mode & 0o777) for p in written} == {oct(mode)}


# ---- numba without a writable cache -------------------------------------------------------------
@pytest.mark.slow
def test_kernels_compile_without_a_writable_cache():
    """No location numba may cache in (a read-only install, no writable home): every module
    imports (each compiles through the project's cache guard; a bare cache=True fails at import),
    every kernel of the package is built without a cache (numba's NullCache), and a kernel that
    calls another compiles so and gives the same value as here. (One small kernel: compiling the
    whole coupling kernel uncached took most of this test's time and tests numba, not the guard.)"""
    code = textwrap.dedent("""
        import importlib, pkgutil
        import numba.core.caching as caching
        def refuse(self):
            raise OSError("read-only file system")
        caching._CacheLocator.ensure_cache_path = refuse
        import numpy as np
        from numba.core.dispatcher import Dispatcher
        import droptower as dt
        from droptower.rheology import kernels
        modules = [importlib.import_module(m.name) for m in pkgutil.walk_packages(dt.__path__, "droptower.")
                   if not m.name.endswith("__main__")]  # running the CLI is not importing it
        caches = {type(v._cache).__name__ for m in modules for v in vars(m).values() if isinstance(v, Dispatcher)}
        n_kernels = sum(isinstance(v, Dispatcher) for m in modules for v in vars(m).values())
        value = kernels._interp(2.0, np.array([0.0, 1.0, 3.0]), np.array([0.0, 2.0, 1.0]), 3)
        print(kernels.CACHE, ",".join(sorted(caches)), n_kernels, repr(float(value)))
    """)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=300)
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr
    cache, caches, n_kernels, value = proc.stdout.split()
    from droptower.rheology import kernels

    assert cache == "False" and caches == "NullCache" and int(n_kernels) >= 30, proc.stdout
    here = kernels._interp(2.0, np.array([0.0, 1.0, 3.0]), np.array([0.0, 2.0, 1.0]), 3)
    assert float(value) == float(here) == 1.5  # on the segment from (1, 2) to (3, 1)


def test_cache_falls_back_to_a_private_folder(monkeypatch):
    from numba.core import config

    from droptower.rheology.numba_cache import cache_available

    monkeypatch.setattr(config, "CACHE_DIR", "")
    asked = []

    def numba_finds_only_a_set_cache_dir() -> None:
        asked.append(config.CACHE_DIR)
        if not config.CACHE_DIR:
            raise RuntimeError("cannot cache function '_probe': no locator available")
    assert cache_available(numba_finds_only_a_set_cache_dir)
    assert asked[0] == "" and Path(asked[1]).is_dir() and "droptower-numba-cache" in asked[1]

    def never() -> None:
        raise RuntimeError("cannot cache function '_probe': no locator available")
    monkeypatch.setattr(config, "CACHE_DIR", "")
    assert not cache_available(never) and config.CACHE_DIR == ""


# ---- the process end ----------------------------------------------------------------------------
@pytest.mark.slow
def test_installed_extract_ends_with_its_own_exit_code(tmp_path, good_log):
    """The console script leaves without the interpreter's teardown (native thread pools once
    aborted it, exit 134, after complete output): a few runs, Parquet and CSV read and written,
    end with the command's code and their full output (the long loop was run by hand); the last
    run also names a missing file, so it ends with exit code 2, the good logs' output flushed."""
    from test_cli_installed import _run

    parquet = small_log(tmp_path / "p.parquet")
    for i, missing in enumerate(([], [], [str(tmp_path / "missing.csv")])):
        proc = _run("extract", str(good_log), str(parquet), *missing, "--out", str(tmp_path / f"r{i}.parquet"), "--json")
        assert proc.returncode == (2 if missing else 0) and "terminate called" not in proc.stderr, proc.stderr
        assert len(json.loads(proc.stdout)) == 2 and (tmp_path / f"r{i}.parquet").is_file()
    assert "missing.csv: no such file" in proc.stderr
