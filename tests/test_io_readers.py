"""Readers: catman .BIN against HBM's sample files, own log round trip, CSV sniffing, MDF4,
TDMS, Parquet, and one-line errors for unreadable files."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from droptower.errors import DroptowerError, WriteError
from droptower.io import read_any, read_log, write_log
from droptower.io.catman import read_catman
from droptower.io.csvfmt import read_csv_log
from droptower.io.droptower_log import atomic_write

REFERENCE = Path(__file__).resolve().parent / "data" / "catman"  # shipped test data (MIT, see its LICENSE.txt)
CATMAN_FILES = {2: "2byteJob1_2022_04_12_13_32_10.bin", 4: "4byteJob1_2022_04_12_13_31_47.bin",
                8: "8byteJob1_2022_04_12_13_31_23.bin"}
UNCONNECTED = ("Poti5K TABLE 5-wire plus minus", "Thermocouple Type K")


def catman_file(precision: int) -> Path:
    return REFERENCE / CATMAN_FILES[precision]


# ---------------------------------------------------------------- catman binary

# documented in tests/data/catman/README.md: (channel, unit, sample index, value)
DOCUMENTED = {
    8: [("Time  1 - default sample rate", "s", -1, 0.33000001567415893),
        ("poti5k", "Ohm", 0, 0.59202677), ("Baumer encoder 2500", "mm", 0, 222.76800537)],
    2: [("poti5k", "Ohm", 0, 0.65017971), ("U10M 500kN", "Ohm", 0, -1.7351624)],
}


@pytest.mark.parametrize("precision", [2, 4, 8])
def test_catman_structure(precision):
    record = read_any(catman_file(precision))
    assert record.format == "catman binary"
    assert len(record.channels) == 10
    assert record.names()[0] == "Time  1 - default sample rate"
    for channel in record.channels.values():
        assert channel.values.size == 100 and channel.sample_rate_hz == 300.0
        assert channel.metadata["precision_bytes"] == precision
    # the time channel runs 0 .. 99/300 s (to the stored precision)
    time = record["Time  1 - default sample rate"].values
    np.testing.assert_allclose(time, np.arange(100) / 300.0, atol={2: 2e-5, 4: 1e-7, 8: 1e-7}[precision])
    # unconnected sensors hold catman's -1000000 marker throughout: NaN + invalid mask, counted
    for name in UNCONNECTED:
        channel = record[name]
        assert np.isnan(channel.values).all() and channel.invalid.all()
    assert record.metadata["invalid_count"] == 200
    assert record["poti5k"].invalid is None
    assert record.metadata["job"]["Default sample rate"] == "300 Hz"  # from the .TST beside it


@pytest.mark.parametrize("precision", [2, 8])
def test_catman_documented_values(precision):
    record = read_catman(catman_file(precision))
    for name, unit, index, value in DOCUMENTED[precision]:
        channel = record[name]
        assert channel.unit == unit
        # the README gives 8 significant digits, the exactly stored time value in full
        assert channel.values[index] == pytest.approx(value, rel=5e-9 if index == 0 else 0)


def test_catman_4byte_is_float32_of_same_kind():
    record = read_catman(catman_file(4))
    poti = record["poti5k"].values
    assert np.array_equal(poti, poti.astype(np.float32).astype(np.float64))  # exactly float32 values
    assert 0.5 < poti.min() and poti.max() < 0.7  # same potentiometer position as the other files


@pytest.mark.parametrize("cut", [1, 100, 500, 32_768 + 100])
def test_catman_truncated_file_is_one_line_error(tmp_path, cut):
    source = catman_file(8)
    bad = tmp_path / "cut.bin"
    bad.write_bytes(source.read_bytes()[:cut])
    with pytest.raises(DroptowerError, match=r"cut\.bin: .*(truncated|not a catman)") as info:
        read_any(bad)
    assert "\n" not in str(info.value)


def test_non_catman_bin_is_refused(tmp_path):
    bad = tmp_path / "other.bin"
    bad.write_bytes(b"\x00\x01hello world" * 10)
    with pytest.raises(DroptowerError, match=r"other\.bin: not a catman binary file"):
        read_any(bad)


# ---------------------------------------------------------------- own log format

def _columns(n: int = 2000, seed: int = 3) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    rng = np.random.default_rng(seed)
    time = np.arange(n) / 38_400.0
    channels = {
        "angle_rad": rng.normal(size=n) * 1e-2,
        "torque_nm": rng.normal(size=n) * 1e3,
        "impact_force_n": rng.standard_cauchy(size=n),
        "laser_distance_m": np.concatenate([[-0.0, 5e-324, 1e308, np.pi], rng.normal(size=n - 4) * 1e-9]),
    }
    return time, channels


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_own_log_round_trip_is_bit_exact(tmp_path, suffix):
    time, channels = _columns()
    metadata = {"inertia_kgm2": np.float64(0.0123), "coupling": "BoWex M-32 ü", "seed": np.int64(7),
                "drop_height_m": 0.25, "flags": ["a", "b"], "rig": {"lever_length_m": 0.3}}
    path = write_log(tmp_path / f"test{suffix}", time, channels, metadata)
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary file left behind
    record = read_log(path)
    assert record.names() == ["time_s", *channels]
    assert record["time_s"].values.view(np.int64).tolist() == time.view(np.int64).tolist()
    for name, values in channels.items():
        assert np.array_equal(record[name].values.view(np.int64), values.view(np.int64)), name  # bit-exact, -0.0 too
        assert record[name].time_s is record["time_s"].values
    assert record.metadata == json.loads(json.dumps({**metadata, "inertia_kgm2": 0.0123, "seed": 7}))
    assert {n: c.unit for n, c in record.channels.items()} == {
        "time_s": "s", "angle_rad": "rad", "torque_nm": "N*m", "impact_force_n": "N", "laser_distance_m": "m"}
    assert read_any(path).metadata == record.metadata  # read_any recognises the own format


def test_own_csv_layout(tmp_path):
    path = write_log(tmp_path / "x.csv", np.array([0.0, 0.5]), {"angle_deg": np.array([0.1, 1 / 3])}, {"k": "v"})
    assert path.read_text(encoding="utf-8") == (
        '# droptower-log 1\n# k = "v"\ntime_s,angle_deg\n0,0.1\n0.5,0.3333333333333333\n')


def test_atomic_write_replaces_whole_or_not_at_all(tmp_path):
    path = tmp_path / "table.csv"
    atomic_write(path, lambda tmp: Path(tmp).write_text("old"))
    assert path.read_text() == "old"

    def fails(tmp):
        assert Path(tmp).parent == tmp_path  # same folder: os.replace stays on one file system
        Path(tmp).write_text("half")
        raise OSError("disk full")

    with pytest.raises(WriteError, match=r"table\.csv: cannot write \(disk full\)"):  # one line naming the file
        atomic_write(path, fails)
    assert path.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["table.csv"]


def test_own_log_errors(tmp_path):
    with pytest.raises(DroptowerError, match=r"x\.txt: unknown log suffix"):
        write_log(tmp_path / "x.txt", np.zeros(2), {}, {})
    with pytest.raises(DroptowerError, match=r"y\.csv: channel 'a_m' has shape"):
        write_log(tmp_path / "y.csv", np.zeros(3), {"a_m": np.zeros(2)}, {})
    bad = tmp_path / "bad.csv"
    bad.write_text("# droptower-log 1\n# k = {oops\ntime_s\n0\n")
    with pytest.raises(DroptowerError, match=r"bad\.csv: line 2: metadata value is not JSON"):
        read_log(bad)
    bad.write_text("# droptower-log 2\ntime_s\n0\n")
    with pytest.raises(DroptowerError, match=r"bad\.csv: unsupported droptower-log version"):
        read_log(bad)
    bad.write_text("# droptower-log 1\nangle_rad\n0\n")
    with pytest.raises(DroptowerError, match=r"bad\.csv: no 'time_s' column \(has: angle_rad\)"):
        read_log(bad)
    bad.write_text("# droptower-log 1\ntime_s,angle_rad\n0,1\n1,oops\n")
    with pytest.raises(DroptowerError, match=r"bad\.csv: column 'angle_rad' is not numeric"):
        read_log(bad)


# ---------------------------------------------------------------- CSV / ASCII

def test_csv_semicolon_decimal_comma_unit_row(tmp_path):
    path = tmp_path / "komma.csv"
    path.write_text("Zeit;Winkel;Moment\ns;°;kN·m\n0,0;0,5;1,25\n0,001;-0,6;1,5\n0,002;0,7;-1,75\n", encoding="cp1252")
    record = read_any(path)
    assert record.metadata["delimiter"] == ";" and record.metadata["decimal"] == ","
    assert [(c.name, c.unit) for c in record.channels.values()] == [("Zeit", "s"), ("Winkel", "°"), ("Moment", "kN·m")]
    assert record["Winkel"].values.tolist() == [0.5, -0.6, 0.7]
    assert record["Moment"].values.tolist() == [1.25, 1.5, -1.75]


def test_csv_units_in_brackets_and_header_lines(tmp_path):
    path = tmp_path / "export.txt"
    path.write_text("catman ASCII export\nTest: coupling 4\n\nTime [s]\tTorque [N*m]\tForce (kN)\n"
                    "0\t1\t-1000000\n0.5\t2\t3\n1\t3\t4\n")
    record = read_any(path)
    assert [(c.name, c.unit) for c in record.channels.values()] == [("Time", "s"), ("Torque", "N*m"), ("Force", "kN")]
    assert record.metadata["header"] == ["catman ASCII export", "Test: coupling 4"]
    force = record["Force"]  # catman's invalid marker in an ASCII export: NaN and flagged
    assert np.isnan(force.values[0]) and force.invalid.tolist() == [True, False, False]


def test_mts793_dat_with_repeated_buffers(tmp_path):
    header = "Data Acquisition\t\tTime:\t{}\tSec\nRunning Time\tRotation\tTorque\nSec\tdeg\tN-m\n"
    path = tmp_path / "specimen.dat"
    path.write_text("MTS793|MPT|DEU|1|2|,|.|:|49|1|1|A\n\n" + header.format(4) + "0,0\t0,1\t5\n0,1\t0,2\t6\n\n"
                    + header.format(8) + "0,2\t0,3\t7\n0,3\t0,4\t8\n")
    record = read_any(path)
    assert record.format == "MTS 793" and record.metadata["decimal"] == ","
    assert [(c.name, c.unit) for c in record.channels.values()] == [
        ("Running Time", "Sec"), ("Rotation", "deg"), ("Torque", "N-m")]
    assert record["Rotation"].values.tolist() == [0.1, 0.2, 0.3, 0.4]


def test_mts793_comma_delimited(tmp_path):
    path = tmp_path / "lotus.dat"
    path.write_text('MTS793|BTW|ENU|1|1|.|/|:|1|0|0|A\n\n"Time","Angle","Torque"\n"s","rad","N*m"\n'
                    "0.0,0.1,5\n0.1,0.2,6\n0.2,0.3,7\n")
    record = read_any(path)
    assert [(c.name, c.unit) for c in record.channels.values()] == [("Time", "s"), ("Angle", "rad"), ("Torque", "N*m")]


def test_csv_floats_read_back_exact(tmp_path):
    values = np.random.default_rng(0).normal(size=(500, 3)) * np.array([1e-9, 1.0, 1e6])
    path = tmp_path / "exact.csv"
    path.write_text("a,b,c\n" + "\n".join(",".join(map(repr, row)) for row in values.tolist()) + "\n")
    record = read_any(path)
    for i, name in enumerate("abc"):
        assert np.array_equal(record[name].values, values[:, i])


def test_csv_explicit_options_and_no_header(tmp_path):
    path = tmp_path / "plain.txt"
    path.write_text("some note\nanother\nt angle\n0 1\n1 2\n2 4\n")
    record = read_csv_log(path, delimiter=" ", header_lines=2, unit_row=False)
    assert record.names() == ["t", "angle"] and record["angle"].values.tolist() == [1, 2, 4]
    path.write_text("0 1\n1 2\n2 4\n")
    assert read_any(path).names() == ["column 1", "column 2"]


def test_csv_bad_inputs(tmp_path):
    path = tmp_path / "words.csv"
    path.write_text("this is\nnot a log\n")
    with pytest.raises(DroptowerError, match=r"words\.csv: no numeric data rows"):
        read_any(path)
    path = tmp_path / "stray.csv"
    path.write_text("t,a\n0,1\n1,2\n2,x\n")
    with pytest.raises(DroptowerError, match=r"stray\.csv: column 'a': non-numeric value 'x' at data row 3"):
        read_any(path)
    with pytest.raises(DroptowerError, match=r"missing\.csv: no such file"):
        read_any(tmp_path / "missing.csv")
    with pytest.raises(DroptowerError, match=r"unknown reader option"):
        read_any(path, delimter=";")


# ---------------------------------------------------------------- MDF4, TDMS, Parquet

def test_mdf4_round_trip(tmp_path):
    asammdf = pytest.importorskip("asammdf")
    t1, t2 = np.arange(200) / 2048.0, np.arange(800) / 8192.0
    mdf = asammdf.MDF(version="4.10")
    mdf.append([asammdf.Signal(np.sin(t1), t1, name="Winkel", unit="deg"),
                asammdf.Signal(np.cos(t1), t1, name="Moment", unit="N*m")])
    mdf.append([asammdf.Signal(t2 ** 2, t2, name="Kraft", unit="kN")])
    mdf.save(tmp_path / "drop.mf4", overwrite=True)
    record = read_any(tmp_path / "drop.mf4")
    assert record.format == "MDF" and record.names() == ["Winkel", "Moment", "Kraft"]
    assert record["Moment"].unit == "N*m" and np.array_equal(record["Moment"].values, np.cos(t1))
    assert np.array_equal(record["Kraft"].time(), t2) and np.array_equal(record["Winkel"].time(), t1)
    (tmp_path / "fake.mf4").write_text("not mdf")
    with pytest.raises(DroptowerError, match=r"fake\.mf4: not an MDF file"):
        read_any(tmp_path / "fake.mf4")


def test_tdms_round_trip(tmp_path):
    nptdms = pytest.importorskip("nptdms")
    t = np.arange(300) / 2048.0
    with nptdms.TdmsWriter(tmp_path / "drop.tdms") as writer:
        writer.write_segment([
            nptdms.ChannelObject("drop", "angle", np.sin(t), properties={
                "unit_string": "deg", "wf_increment": 1 / 2048.0, "wf_start_offset": -0.01}),
            nptdms.ChannelObject("drop", "torque", np.cos(t), properties={"unit_string": "kN*m"}),
        ])
    record = read_any(tmp_path / "drop.tdms")
    assert record.names() == ["drop/angle", "drop/torque"]
    angle = record["drop/angle"]
    assert angle.unit == "deg" and angle.sample_rate_hz == 2048.0
    np.testing.assert_allclose(angle.time(), t - 0.01, rtol=0, atol=1e-15)
    assert np.array_equal(record["drop/torque"].values, np.cos(t))
    (tmp_path / "bad.tdms").write_bytes(b"junk" * 10)
    with pytest.raises(DroptowerError, match=r"bad\.tdms: cannot read \(TDMS file"):
        read_any(tmp_path / "bad.tdms")


def test_generic_parquet(tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.table({"Torque [N*m]": [1.0, 2.0], "angle_deg": [0.1, 0.2], "Force": [5, 6], "note": ["a", "b"]})
    schema = table.schema.set(2, pa.field("Force", pa.int64(), metadata={"unit": "kN"}))
    pq.write_table(table.cast(schema), tmp_path / "g.parquet")
    record = read_any(tmp_path / "g.parquet")
    assert record.format == "parquet"
    assert [(c.name, c.unit) for c in record.channels.values()] == [("Torque", "N*m"), ("angle_deg", "deg"), ("Force", "kN")]
    (tmp_path / "h.parquet").write_text("nope")
    with pytest.raises(DroptowerError, match=r"h\.parquet: cannot read \(Parquet file"):
        read_any(tmp_path / "h.parquet")


def test_unknown_suffix_is_sniffed(tmp_path):
    source = catman_file(4)
    copy = tmp_path / "renamed.data"
    shutil.copy(source, copy)
    assert read_any(copy).format == "catman binary"
    time, channels = _columns(20)
    log = write_log(tmp_path / "log.csv", time, channels, {})
    renamed = log.rename(tmp_path / "log.txt")
    assert read_any(renamed).format == "droptower-log csv"
