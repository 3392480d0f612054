"""Channel mapping and unit conversion: roles, units via pint, time bases, and every bad-input
case as a one-line DroptowerError naming the file."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from droptower.errors import DroptowerError
from droptower.io import Channel, Record, map_channels, map_servo_channels, parse_channel_options, read_any, write_log
from droptower.units import si_factor, to_si

REFERENCE = Path(__file__).resolve().parent / "data" / "catman"  # shipped test data (MIT, see its LICENSE.txt)


def _signals(n=400, rate=2048.0):
    time = np.arange(n) / rate
    angle = 0.02 * np.exp(-30 * time) * np.sin(2 * np.pi * 40 * time)
    return time, angle


def _record(channels: dict[str, tuple[str, np.ndarray]], **kw) -> Record:
    return Record(path=Path("lab/drop_07.csv"),
                  channels={name: Channel(name=name, unit=unit, values=np.asarray(values, float), **kw)
                            for name, (unit, values) in channels.items()})


# ---------------------------------------------------------------- units

@pytest.mark.parametrize("unit, kind, factor", [
    ("s", "time", 1.0), ("ms", "time", 1e-3), ("Sec", "time", 1.0),
    ("N", "force", 1.0), ("kN", "force", 1e3),
    ("rad", "angle", 1.0), ("mrad", "angle", 1e-3), ("deg", "angle", math.pi / 180), ("°", "angle", math.pi / 180),
    ("mm", "length", 1e-3), ("m", "length", 1.0), ("µm", "length", 1e-6),
    ("N*m", "torque", 1.0), ("Nm", "torque", 1.0), ("N·m", "torque", 1.0), ("N m", "torque", 1.0),
    ("N-m", "torque", 1.0), ("kN*m", "torque", 1e3), ("kNm", "torque", 1e3), ("[N*m]", "torque", 1.0),
])
def test_unit_factors(unit, kind, factor):
    assert si_factor(unit, kind) == pytest.approx(factor, rel=1e-15)


def test_tonf_is_the_metric_tonne_force():
    """``tonf`` (published isolator records: Gallardo et al. 2023's bearing) is 1000 kgf =
    9806.65 N exactly (the standard gravity's definition), in any spelling the files use; pint's
    own ``ton_force`` stays the US short ton-force (2000 lbf = 8896.443230521 N), a different unit."""
    assert si_factor("tonf", "force") == 9806.65 == si_factor("[tonf]", "force") == 1000 * si_factor("kgf", "force")
    assert si_factor("tonf*m", "torque") == 9806.65 and si_factor("ton_force", "force") == pytest.approx(8896.443230521, rel=1e-12)
    with pytest.raises(ValueError, match="not a length unit"):
        si_factor("tonf", "length")


def test_to_si_converts_values():
    np.testing.assert_allclose(to_si(np.array([0.0, 90.0, -180.0]), "deg", "angle"), [0.0, math.pi / 2, -math.pi])
    np.testing.assert_array_equal(to_si(np.array([1.5, 2.0]), "kNm", "torque"), [1500.0, 2000.0])


@pytest.mark.parametrize("unit, kind, message", [
    ("furlongs_per_fortnight", "length", "unknown unit 'furlongs_per_fortnight'"),
    ("Ohm", "force", "unknown unit 'Ohm'"),
    ("mm", "angle", "unit 'mm' is not an angle unit"),
    ("%", "angle", "unit '%' is not an angle unit"),
    ("N", "torque", "unit 'N' is not a torque unit"),
    ("s", "length", "unit 's' is not a length unit"),
    ("", "time", "no unit given"),
])
def test_unknown_or_wrong_unit_is_an_error_naming_file_and_channel(unit, kind, message):
    with pytest.raises(DroptowerError, match=rf"^log\.csv: channel 'x': {message}"):
        to_si(np.zeros(2), unit, kind, file="log.csv", channel="x")


# ---------------------------------------------------------------- roles

def test_own_format_default_roles(tmp_path):
    time, angle = _signals()
    path = write_log(tmp_path / "own.parquet", time, {
        "angle_rad": angle, "torque_nm": 900 * angle, "impact_force_n": np.exp(-time), "laser_distance_m": 0.1 * np.tan(angle)},
        {"inertia_kgm2": 0.01})
    signals = map_channels(read_any(path), sensor_radius_m=0.1)
    assert np.array_equal(signals.time_s, time) and np.array_equal(signals.angle_rad, angle)
    assert np.array_equal(signals.torque_nm, 900 * angle) and signals.impact_force_n is not None
    assert signals.metadata == {"inertia_kgm2": 0.01} and signals.source == path
    # the laser distance instead, converted with the sensor radius
    by_laser = map_channels(read_any(path), {"distance": "laser_distance_m"}, sensor_radius_m=0.1)
    np.testing.assert_allclose(by_laser.angle_rad, angle, rtol=1e-15, atol=0)


def test_common_names_units_and_overrides():
    time, angle = _signals()
    record = _record({"Zeit": ("ms", 1e3 * time), "Winkel": ("deg", np.degrees(angle)),
                      "Drehmoment": ("kN*m", 0.9 * angle), "Kraft": ("", np.exp(-time))})
    with pytest.raises(DroptowerError, match=r"drop_07\.csv: channel 'Kraft' has no unit; give it as `roles=\{'impact_force': 'Kraft:UNIT'\}`"):
        map_channels(record, sensor_radius_m=None)
    signals = map_channels(record, {"impact_force": "Kraft:kN"}, sensor_radius_m=None)
    np.testing.assert_allclose(signals.time_s, time, rtol=1e-15)
    np.testing.assert_allclose(signals.angle_rad, angle, rtol=1e-14)
    np.testing.assert_allclose(signals.torque_nm, 900 * angle, rtol=1e-14)
    np.testing.assert_allclose(signals.impact_force_n, 1e3 * np.exp(-time), rtol=1e-15)
    # a unit override wins over a wrong unit in the file
    fixed = map_channels(record, {"angle": "Winkel:rad", "impact_force": "Kraft:N"}, sensor_radius_m=None)
    np.testing.assert_array_equal(fixed.angle_rad, np.degrees(angle))


def test_distance_in_mm_needs_radius():
    time, angle = _signals()
    record = _record({"t": ("s", time), "Laser": ("mm", 1e3 * 0.08 * np.tan(angle))})  # R tan(phi)
    signals = map_channels(record, sensor_radius_m=0.08)
    np.testing.assert_allclose(signals.angle_rad, angle, rtol=1e-13, atol=1e-18)
    with pytest.raises(DroptowerError, match=r"drop_07\.csv: a laser distance channel needs the laser spot radius "
                                             r"\(m\): the log carries no 'laser_radius_m'; give `sensor_radius_m` or `rig`"):
        map_channels(record, sensor_radius_m=None)
    with pytest.raises(DroptowerError, match=r"give --rig$"):  # a command names its own flags
        map_channels(record, sensor_radius_m=None, radius_flags="--rig")


def test_laser_radius_from_the_log_metadata():
    """The log's own ``laser_radius_m`` is used; a given radius overrides it, a default (the rig's)
    only fills in where the log has none."""
    time, angle = _signals()
    record = _record({"t": ("s", time), "Laser": ("m", 0.15 * np.tan(angle))})
    record.metadata["laser_radius_m"] = 0.15
    np.testing.assert_allclose(map_channels(record, sensor_radius_m=None).angle_rad, angle, rtol=1e-13, atol=1e-18)
    np.testing.assert_allclose(map_channels(record, sensor_radius_m=None, default_sensor_radius_m=0.3).angle_rad,
                               angle, rtol=1e-13, atol=1e-18)
    given = map_channels(record, sensor_radius_m=0.3).angle_rad
    np.testing.assert_allclose(given, np.arctan(0.15 * np.tan(angle) / 0.3), rtol=1e-13, atol=1e-18)
    record.metadata["laser_radius_m"] = -1.0
    with pytest.raises(DroptowerError, match=r"laser spot radius \(the log's metadata laser_radius_m\): must be > 0, got -1$"):
        map_channels(record, sensor_radius_m=None)


def test_time_from_sample_rate():
    _, angle = _signals()
    record = _record({"angle": ("rad", angle)})
    signals = map_channels(record, sensor_radius_m=None, sample_rate_hz=2048.0)
    assert signals.sample_rate_hz == pytest.approx(2048.0) and signals.time_s[0] == 0.0
    with pytest.raises(DroptowerError, match=r"drop_07\.csv: no time channel and no sample rate; give "
                                             r"`roles=\{'time': 'NAME\[:UNIT\]'\}` or `sample_rate_hz`"):
        map_channels(record, sensor_radius_m=None)
    own_rate = _record({"angle": ("rad", angle)}, sample_rate_hz=1000.0)
    assert map_channels(own_rate, sensor_radius_m=None).time_s[1] == 1e-3


def test_catman_file_maps_with_its_sample_rate():
    path = REFERENCE / "8byteJob1_2022_04_12_13_31_23.bin"
    record = read_any(path)
    signals = map_channels(record, {"angle": "poti5k:deg", "torque": "U10M 500kN:N*m"}, sensor_radius_m=None)
    np.testing.assert_allclose(signals.time_s, np.arange(100) / 300.0, rtol=0, atol=1e-15)
    assert signals.angle_rad[0] == pytest.approx(math.radians(0.59202677), rel=1e-8)
    # an unconnected sensor (catman -1000000 markers) is refused, not used as data
    with pytest.raises(DroptowerError, match=r"8byteJob1.*: channel 'Thermocouple Type K': 100 catman invalid-value markers"):
        map_channels(record, {"angle": "poti5k:deg", "impact_force": "Thermocouple Type K"}, sensor_radius_m=None)


def test_resampling_by_integer_factor():
    time, angle = _signals(400, 2048.0)
    fast_time = np.arange(1597) / 8192.0  # 4x the rate, covering the angle's time span
    force = np.sin(2 * np.pi * 5 * fast_time)
    record = Record(path=Path("lab/mixed.mf4"), channels={
        "angle": Channel("angle", "rad", angle, time_s=time),
        "force": Channel("force", "N", force, time_s=fast_time)})
    signals = map_channels(record, sensor_radius_m=None)
    np.testing.assert_array_equal(signals.impact_force_n, force[::4])  # samples coincide at 4x
    odd_time = np.arange(1200) / 6144.0 * 1.01
    record.channels["force"] = Channel("force", "N", np.sin(odd_time), time_s=odd_time)
    with pytest.raises(DroptowerError, match=r"mixed\.mf4: channel 'force': sampled at .* Hz, the angle at 2048 Hz: not an integer ratio"):
        map_channels(record, sensor_radius_m=None)


@pytest.mark.parametrize("case, message", [
    ("missing", r"no channel 'Winkel' for role angle \(the file has: 'time', 'torque', 'force'\)"),
    ("no_angle", r"no angle channel found; name it with `roles=\{'angle': 'NAME"),
    ("nan", r"channel 'torque': 1 NaN/missing values \(a gap\), first at sample 7"),
    ("backwards", r"time of channel 'time': time is non-monotonic \(goes backwards\) at sample 11"),
    ("duplicate", r"time of channel 'time': time is duplicated at sample 11"),
    ("constant", r"channel 'force': constant signal"),
    ("lengths", r"channel 'force': has 399 samples, the angle has 400, and no time base of its own"),
    ("ambiguous", r"several channels could be the torque channel \('torque', 'Torque 2'\)"),
    ("role", r"unknown channel role\(s\) spin"),
])
def test_bad_input_names_the_file(case, message):
    time, angle = _signals()
    channels = {"time": ("s", time), "angle": ("rad", angle), "torque": ("N*m", 900 * angle),
                "force": ("N", np.exp(-time))}
    roles = None
    if case == "missing":
        del channels["angle"]
        roles = {"angle": "Winkel"}
    elif case == "no_angle":
        del channels["angle"]
    elif case == "nan":
        channels["torque"][1][7] = np.nan
    elif case in ("backwards", "duplicate"):
        channels["time"][1][11] = channels["time"][1][10] - (1e-5 if case == "backwards" else 0.0)
    elif case == "constant":
        channels["force"] = ("N", np.full(time.size, 3.0))
    elif case == "lengths":
        channels["force"] = ("N", np.exp(-time[:-1]))
    elif case == "ambiguous":
        channels["Torque 2"] = ("N*m", angle)
    elif case == "role":
        roles = {"spin": "angle"}
    record = _record(channels)
    with pytest.raises(DroptowerError, match=r"^lab/drop_07\.csv: " + message) as info:
        map_channels(record, roles, sensor_radius_m=None)
    assert "\n" not in str(info.value)


def test_parse_channel_options():
    assert parse_channel_options(["angle=Winkel:deg", "time = Zeit", "torque=Torque [N*m]"]) == {
        "angle": "Winkel:deg", "time": "Zeit", "torque": "Torque [N*m]"}
    for bad, message in [(["angle"], "expected ROLE=NAME"), (["spin=x"], "unknown role 'spin'"),
                         (["angle=a", "angle=b"], "role 'angle' given twice"), (["angle="], "expected ROLE=NAME")]:
        with pytest.raises(DroptowerError, match=message):
            parse_channel_options(bad)


def test_name_with_colon_is_not_split():
    time, angle = _signals()
    record = _record({"t": ("s", time), "Ch 1: angle": ("deg", np.degrees(angle))})
    signals = map_channels(record, {"angle": "Ch 1: angle"}, sensor_radius_m=None)
    np.testing.assert_allclose(signals.angle_rad, angle, rtol=1e-14)


def test_dash_leaves_a_role_out_and_offset_channels_are_aligned():
    time, angle = _signals()
    record = Record(path=Path("lab/d.tdms"), channels={
        "angle": Channel("angle", "rad", angle, sample_rate_hz=2048.0),
        "force": Channel("force", "N", np.full(time.size, 2.0), sample_rate_hz=2048.0),
        "torque": Channel("torque", "N*m", np.sin(np.arange(-1, time.size) / 2048.0), sample_rate_hz=2048.0,
                          start_s=-1 / 2048.0)})
    with pytest.raises(DroptowerError, match=r"channel 'force': constant signal"):
        map_channels(record, sensor_radius_m=None)
    signals = map_channels(record, {"impact_force": "-"}, sensor_radius_m=None)
    assert signals.impact_force_n is None
    # the torque starts one sample earlier: aligned with the angle's samples
    np.testing.assert_allclose(signals.torque_nm, np.sin(time), rtol=0, atol=1e-15)
    record.channels["torque"] = Channel("torque", "N*m", np.sin(time), sample_rate_hz=2048.0, start_s=-1 / 2048.0)
    with pytest.raises(DroptowerError, match=r"d\.tdms: channel 'torque': covers -0.000488281..0.194336 s, the angle 0..0.194824 s"):
        map_channels(record, {"impact_force": "-"}, sensor_radius_m=None)


# ---------------------------------------------------------------- servo records
@pytest.mark.parametrize("length_unit", ["m", "mm", "µm", "in"])
@pytest.mark.parametrize("force_unit", ["N", "kN", "lbf", "kip"])
def test_translational_servo_record_in_any_length_and_force_unit(length_unit, force_unit):
    import pint

    ureg = pint.UnitRegistry()
    time, x_m = _signals()
    f_n = 5e5 * x_m + 3.0
    record = _record({"Time": ("s", time), "Weg": (length_unit, ureg.Quantity(x_m, "m").to(length_unit).magnitude),
                      "Kraft": (force_unit, ureg.Quantity(f_n, "N").to(force_unit).magnitude)})
    signals = map_servo_channels(record)
    assert signals.units == "translational" and signals.notes == []
    np.testing.assert_allclose(signals.motion_si, x_m, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(signals.load_si, f_n, rtol=1e-12)
    np.testing.assert_array_equal(signals.time_s, time)


def test_servo_roles_kind_and_their_errors():
    time, angle = _signals()
    torsional = _record({"t": ("s", time), "Winkel": ("deg", np.degrees(angle)), "Md": ("kN*m", angle)})
    signals = map_servo_channels(torsional)
    assert signals.units == "torsional"
    np.testing.assert_allclose(signals.motion_si, angle, rtol=1e-14)
    np.testing.assert_allclose(signals.load_si, 1e3 * angle, rtol=1e-14)
    both = _record({"t": ("s", time), "angle": ("rad", angle), "displacement": ("mm", angle)})
    with pytest.raises(DroptowerError, match="both an angle channel 'angle' and a displacement channel 'displacement'"):
        map_servo_channels(both)
    assert map_servo_channels(both, {"displacement": "displacement"}).units == "translational"
    with pytest.raises(DroptowerError, match=r"not a mix \(angle, force\)"):
        map_servo_channels(both, {"angle": "angle", "force": "displacement"})
    with pytest.raises(DroptowerError, match=r"unit 'mm' is not an angle unit .*`roles=\{'displacement': 'displacement:mm'\}`"):
        map_servo_channels(both, {"angle": "displacement"})
    with pytest.raises(DroptowerError, match=r"unknown role 'impact_force'"):
        parse_channel_options(["impact_force=F"], ("time", "angle", "torque", "displacement", "force"))
