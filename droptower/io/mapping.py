"""Channel mapping: pick the channels of a :class:`Record` for each role and convert to SI.

Drop tests (:func:`map_channels`): roles ``time``, ``impact_force``, ``angle``, ``distance``
(laser distance, turned into an angle with the sensor radius: angle = arctan(distance / radius),
see :func:`laser_angle`), ``torque``. Servo records (:func:`map_servo_channels`): ``time`` and
either ``angle`` and ``torque`` (torsional) or ``displacement`` and ``force`` (translational:
mounts, bushings, dampers), each checked against its dimension (m, mm, µm, in; N, kN, lbf,
kip) and converted to SI. A role is given as
``NAME`` or ``NAME:UNIT`` (the unit overrides a missing or wrong unit in the file), or ``-`` to
leave an optional role out (``roles={ROLE: 'NAME[:UNIT]'}``). Roles not given are found by name: first the
droptower-log names (``time_s``, ``angle_rad``, ...), then common names matched
case-insensitively (``Time``, ``Winkel``, ``Torque [N*m]``, ...).

Every check names the file: a missing channel (with the list of what the file has), NaN gaps
or catman invalid markers in a used channel, non-monotonic or duplicated time, channels on
different time bases (resampled onto the angle's time base only when the rates differ by an
integer factor), a constant signal, a time base that is not uniform (time stamps rounded to
their printed precision are a uniform one, see :mod:`droptower.io.timebase`).
"""
from __future__ import annotations

import math
import re
from typing import Iterable

import numpy as np

from droptower.errors import DroptowerError, expects, not_in_range
from droptower.io.channels import Channel, Record
from droptower.io.droptower_log import unit_from_name
from droptower.io.signals import DropSignals, ServoSignals
from droptower.io.timebase import regular_time
from droptower.units import to_si

#: roles of a drop test (:func:`map_channels`)
ROLES = ("time", "impact_force", "angle", "distance", "torque")
#: roles of a servo record (:func:`map_servo_channels`): torsional or translational
SERVO_ROLES = ("time", "angle", "torque", "displacement", "force")
#: units -> (motion role, load role) of a servo record
SERVO_KINDS = {"torsional": ("angle", "torque"), "translational": ("displacement", "force")}
KINDS = {"time": "time", "impact_force": "force", "angle": "angle", "distance": "length", "torque": "torque",
         "displacement": "length", "force": "force"}

#: role -> droptower-log column name (first choice when no role is given).
OWN_NAMES = {"time": "time_s", "impact_force": "impact_force_n", "angle": "angle_rad",
             "distance": "laser_distance_m", "torque": "torque_nm", "displacement": "displacement_m",
             "force": "force_n"}

#: role -> common channel names (lower case, unit and separators stripped), matched when the
#: own-format name is absent. A name matches if it equals one of these or starts with one
#: followed by a non-letter (catman's "Time  1 - default sample rate").
COMMON_NAMES = {
    "time": ("time", "zeit", "t", "timestamp", "running time", "time s"),
    "impact_force": ("impact force", "force", "kraft", "schlagkraft", "impactforce", "f"),
    "angle": ("angle", "winkel", "torsion angle", "verdrehwinkel", "drehwinkel", "phi", "rotation"),
    "distance": ("laser distance", "laser", "distance", "abstand", "weg", "displacement"),
    "torque": ("torque", "drehmoment", "moment", "md"),
    "displacement": ("displacement", "weg", "verschiebung", "position", "stroke", "travel", "deflection",
                     "auslenkung", "x"),
    "force": ("force", "kraft", "load", "f"),
}

_UNIT_IN_NAME = re.compile(r"\s*[\[(][^\])]*[\])]\s*$")


@expects(options=["builtins.str"])
def parse_channel_options(options: Iterable[str], roles_known: tuple[str, ...] = ROLES, *,
                          what: str = "channel option", spec: str = "NAME") -> dict[str, str]:
    """``["angle=Winkel:deg", "time=t"]`` -> ``{"angle": "Winkel:deg", "time": "t"}``.

    Parses ``ROLE=NAME[:UNIT]`` texts (the command line's channel options); a role not in ``roles_known`` (the drop
    test's by default; :data:`SERVO_ROLES` for servo records), a missing ``=`` or a role given
    twice is a :class:`DroptowerError`. ``what`` and ``spec`` name the option and its value in the
    messages (a conditions table's ``"condition column"``, ``"COLUMN"``).
    """
    roles: dict[str, str] = {}
    for option in options:
        role, sep, value = option.partition("=")
        role = role.strip()
        if not sep or not value.strip():
            raise DroptowerError(f"{what} {option!r}: expected ROLE={spec}[:UNIT]")
        if role not in roles_known:
            raise DroptowerError(f"{what} {option!r}: unknown role '{role}' (roles: {', '.join(roles_known)})")
        if role in roles:
            raise DroptowerError(f"{what}s: role '{role}' given twice")
        roles[role] = value.strip()
    return roles


def _normalise_name(name: str) -> str:
    text = _UNIT_IN_NAME.sub("", name).strip().lower()
    return re.sub(r"[\s_\-]+", " ", text)


def _find_default(record: Record, role: str) -> str | None:
    if OWN_NAMES[role] in record.channels:
        return OWN_NAMES[role]
    candidates = COMMON_NAMES[role]
    matches = []
    for name in record.channels:
        norm = _normalise_name(name)
        suffix_free = norm.rsplit(" ", 1)[0] if unit_from_name(name.replace(" ", "_")) and " " in norm else norm
        for cand in candidates:
            if norm == cand or suffix_free == cand or (norm.startswith(cand) and not norm[len(cand)].isalpha()):
                matches.append(name)
                break
    if len(matches) > 1:
        raise DroptowerError(
            f"several channels could be the {role} channel ({', '.join(repr(m) for m in matches)}); "
            f"choose one with `roles={{'{role}': 'NAME'}}`", file=record.path)
    return matches[0] if matches else None


def _resolve(record: Record, role: str, spec: str) -> tuple[Channel, str]:
    """The channel and unit a ``NAME[:UNIT]`` spec names."""
    name, unit = spec, None
    if spec not in record.channels and ":" in spec:
        name, unit = spec.rsplit(":", 1)
    if name not in record.channels:
        raise DroptowerError(
            f"no channel '{name}' for role {role} (the file has: {', '.join(repr(n) for n in record.channels) or 'none'})",
            file=record.path)
    channel = record.channels[name]
    if unit is None:
        unit = channel.unit or unit_from_name(name)
        if not unit:
            raise DroptowerError(f"channel '{name}' has no unit; give it as `roles={{'{role}': '{name}:UNIT'}}`",
                                 file=record.path)
    return channel, unit


def check_units(record: Record, roles: dict[str, str]) -> None:
    """Refuse a unit that cannot be converted for its role, in the words of :func:`map_channels`
    (``channels`` checks a mapping this way without reading the values)."""
    for role, spec in roles.items():
        name, _, unit = spec.rpartition(":")
        if role in KINDS and spec not in record.channels and name in record.channels:
            to_si(np.zeros(0), unit, KINDS[role], file=record.path, channel=name)


def _check_values(record: Record, channel: Channel, values: np.ndarray) -> None:
    where = f"channel '{channel.name}'"
    if channel.invalid is not None and channel.invalid.any():
        idx = np.flatnonzero(channel.invalid)
        raise DroptowerError(f"{idx.size} catman invalid-value markers (-1000000), first at sample {idx[0]}",
                             file=record.path, where=where)
    bad = ~np.isfinite(values)
    if bad.any():
        idx = np.flatnonzero(bad)
        raise DroptowerError(f"{idx.size} NaN/missing values (a gap), first at sample {idx[0]}",
                             file=record.path, where=where)
    if values.size < 2:
        raise DroptowerError(f"only {values.size} sample(s)", file=record.path, where=where)


def _check_time(record: Record, name: str, time: np.ndarray) -> None:
    where = f"time of channel '{name}'"
    if not np.isfinite(time).all():
        raise DroptowerError(f"NaN in time at sample {int(np.flatnonzero(~np.isfinite(time))[0])}",
                             file=record.path, where=where)
    step = np.diff(time)
    if (step > 0).all():
        return
    i = int(np.flatnonzero(step <= 0)[0])
    kind = "duplicated" if step[i] == 0 else "non-monotonic (goes backwards)"
    raise DroptowerError(f"time is {kind} at sample {i + 1} ({float(time[i])!r} s -> {float(time[i + 1])!r} s)",
                         file=record.path, where=where)


def _onto(record: Record, channel: Channel, values: np.ndarray, base_time: np.ndarray, base: str = "angle"
          ) -> np.ndarray:
    """``values`` on the time base ``base_time`` (the angle's): as is if the lengths and time
    stamps agree, interpolated if the channel's own rate differs by an integer factor (or it is
    offset in time), else an error."""
    own = channel.time()
    if values.size == base_time.size:
        step = (base_time[-1] - base_time[0]) / (base_time.size - 1)
        if own is None or own.size != values.size or np.abs(own - base_time).max() <= 0.01 * step:
            return values
    where = f"channel '{channel.name}'"
    if own is None or own.size != values.size:
        raise DroptowerError(f"has {values.size} samples, the {base} has {base_time.size}, and no time base of its own",
                             file=record.path, where=where)
    rate = (own.size - 1) / (own[-1] - own[0])
    base_rate = (base_time.size - 1) / (base_time[-1] - base_time[0])
    ratio = max(rate, base_rate) / min(rate, base_rate)
    if abs(ratio - round(ratio)) > 1e-6 * ratio:
        raise DroptowerError(f"sampled at {rate:.6g} Hz, the {base} at {base_rate:.6g} Hz: not an integer ratio, "
                             "cannot put them on one time base", file=record.path, where=where)
    half = 0.5 / min(rate, base_rate)
    if own[0] > base_time[0] + half or own[-1] < base_time[-1] - half:
        raise DroptowerError(f"covers {own[0]:.6g}..{own[-1]:.6g} s, the {base} {base_time[0]:.6g}..{base_time[-1]:.6g} s",
                             file=record.path, where=where)
    return np.interp(base_time, own, values)


def find_roles(record: Record, roles: dict[str, str] | None = None,
               problems: list[str] | None = None) -> dict[str, str]:
    """role -> ``NAME[:UNIT]`` of the channel :func:`map_channels` uses for it: the given
    ``roles`` (``-`` leaves one out), the others found by name; roles found nowhere are absent.
    An ambiguous name match is a :class:`DroptowerError`, or with a ``problems`` list, its
    message is appended there and the role left out (``droptower channels`` shows them all)."""
    roles = dict(roles or {})
    unknown = set(roles) - set(ROLES)
    if unknown:
        raise DroptowerError(f"unknown channel role(s) {', '.join(sorted(unknown))} (roles: {', '.join(ROLES)})",
                             file=record.path)
    unused = {role for role, spec in roles.items() if spec.strip() in ("-", "none")}
    specs = {role: spec for role, spec in roles.items() if role not in unused}
    explicit = set(specs)
    if {"angle", "distance"} <= explicit:
        raise DroptowerError("give either an angle or a distance channel, not both", file=record.path)
    for role in ROLES:
        if role in specs or role in unused or (role == "distance" and "angle" in specs) or (
                role == "angle" and "distance" in specs):
            continue
        try:
            found = _find_default(record, role)
        except DroptowerError as exc:
            if problems is None:
                raise
            problems.append(exc.problem)
            continue
        if found is not None:
            specs[role] = found
    if "angle" in specs and "distance" in specs and "distance" not in explicit:
        del specs["distance"]  # both found by name: the angle channel is the direct measurement
    return specs


def laser_distance(angle_rad: np.ndarray, radius_m: float) -> np.ndarray:
    """What the laser reads (m) at the lever angle ``angle_rad``: it looks along a fixed vertical
    line at the horizontal distance ``radius_m`` from the axis, as the drop mass falls along one at
    the lever length L, so it sees the lever surface move by radius * tan(angle) (the impact
    geometry's L tan(phi), docs/theory.md#impact), not the arc radius * angle (0.09 % apart at 3 deg)."""
    return radius_m * np.tan(angle_rad)


def laser_angle(distance_m: np.ndarray, radius_m: float) -> np.ndarray:
    """The lever angle (rad) from the laser distance (m): the inverse of :func:`laser_distance`."""
    return np.arctan(np.asarray(distance_m) / radius_m)


def _sensor_radius(record: Record, given: float | None, default: float | None, flags: str) -> float:
    """The laser spot radius (m): given, else the log's ``laser_radius_m``, else the default."""
    value, origin = given, flags
    if value is None and record.metadata.get("laser_radius_m") is not None:
        value, origin = record.metadata["laser_radius_m"], "the log's metadata laser_radius_m"
    if value is None:
        value = default
    if value is None:
        raise DroptowerError(f"a laser distance channel needs the laser spot radius (m): the log carries no "
                             f"'laser_radius_m'; give {flags}", file=record.path)
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise DroptowerError(f"{origin}: {value!r} is not a number", file=record.path) from None
    if not (math.isfinite(value) and value > 0):
        raise not_in_range(value, f"laser spot radius ({origin})", file=record.path)
    return value


@expects(record="droptower.io.channels.Record")
def map_channels(record: Record, roles: dict[str, str] | None = None, *, sensor_radius_m: float | None,
                 sample_rate_hz: float | None = None, default_sensor_radius_m: float | None = None,
                 radius_flags: str = "`sensor_radius_m` or `rig`",
                 sample_rate_flag: str | None = "`sample_rate_hz`") -> DropSignals:
    """Pick the channels for each role from ``record`` and return SI :class:`DropSignals`.

    roles: role -> ``NAME`` or ``NAME:UNIT``; roles not given are found by name; ``-`` leaves a
        role out (e.g. a dead force sensor).
    sensor_radius_m: radius of the laser spot on the flange (m), needed for ``distance``; if
        None, the log's metadata ``laser_radius_m``, else ``default_sensor_radius_m`` (a rig's).
    sample_rate_hz: builds the time base when the file has no time channel and no rate.
    radius_flags, sample_rate_flag: the parameters that give these, named in the errors (a command
        reports them as its flags).
    """
    specs = find_roles(record, roles)
    explicit = {role for role, spec in (roles or {}).items() if spec.strip() not in ("-", "none")}
    angle_role = "angle" if "angle" in specs else "distance"
    if angle_role not in specs:
        raise DroptowerError(
            "no angle channel found; name it with `roles={'angle': 'NAME[:UNIT]'}` or `roles={'distance': 'NAME[:UNIT]'}` "
            f"(the file has: {', '.join(repr(n) for n in record.channels) or 'none'})", file=record.path)

    signals: dict[str, np.ndarray] = {}
    channels: dict[str, Channel] = {}
    for role in ("angle", "distance", "torque", "impact_force"):
        if role not in specs:
            continue
        channel, unit = _resolve(record, role, specs[role])
        values = to_si(channel.values, unit, KINDS[role], file=record.path, channel=channel.name)
        _check_values(record, channel, values)
        if np.ptp(values) == 0.0:
            raise DroptowerError(f"constant signal ({float(channel.values[0])!r} {unit} throughout)",
                                 file=record.path, where=f"channel '{channel.name}'")
        signals[role], channels[role] = values, channel

    angle_channel = channels[angle_role]
    time, notes = _time_base(record, specs, explicit, angle_channel, signals[angle_role].size, sample_rate_hz,
                             sample_rate_flag=sample_rate_flag)
    own_time = angle_channel.time()

    # the angle defines the time base; other channels are aligned with its samples (through its
    # own time stamps if it has them, since the time channel may be a rounded copy of them)
    reference = time if own_time is None else np.asarray(own_time, dtype=np.float64)
    for role, channel in channels.items():
        if role != angle_role:
            signals[role] = _onto(record, channel, signals[role], reference)
    angle = signals.get("angle")
    if angle is None:
        radius = _sensor_radius(record, sensor_radius_m, default_sensor_radius_m, radius_flags)
        angle = laser_angle(signals["distance"], radius)
    return DropSignals(time_s=time, angle_rad=angle, torque_nm=signals.get("torque"),
                       impact_force_n=signals.get("impact_force"), metadata=dict(record.metadata),
                       source=record.path, notes=notes)


def _time_base(record: Record, specs: dict[str, str], explicit: set[str], reference: Channel, n: int,
               sample_rate_hz: float | None, role: str = "angle",
               sample_rate_flag: str | None = None) -> tuple[np.ndarray, list[str]]:
    """The time base (s) of the ``n`` samples of the ``reference`` channel (of ``role``): an explicit time
    channel, else the given sample rate, else the channel's own time base, else a time channel
    found by name; checked (strictly increasing, uniform up to the stamps' printed precision)
    and with the notes of what was assumed. ``sample_rate_flag``: the command's flag for a
    sample rate, named in the error when there is no time base."""
    own_time = reference.time()
    if "time" in explicit or ("time" in specs and sample_rate_hz is None and own_time is None):
        time_channel, unit = _resolve(record, "time", specs["time"])
        time = to_si(time_channel.values, unit, "time", file=record.path, channel=time_channel.name)
        _check_values(record, time_channel, time)
        if time.size != n:
            raise DroptowerError(f"time channel '{time_channel.name}' has {time.size} samples, "
                                 f"the {role} channel '{reference.name}' has {n}", file=record.path)
        time_name = time_channel.name
    elif sample_rate_hz is not None:
        if not sample_rate_hz > 0:
            raise DroptowerError(f"sample rate must be > 0 Hz, got {sample_rate_hz}", file=record.path)
        time, time_name = np.arange(n) / float(sample_rate_hz), f"{sample_rate_hz} Hz"
    elif own_time is not None:
        time, time_name = np.asarray(own_time, dtype=np.float64), reference.name
    else:
        also = f" or {sample_rate_flag}" if sample_rate_flag else ""
        raise DroptowerError(f"no time channel and no sample rate; give `roles={{'time': 'NAME[:UNIT]'}}`{also}",
                             file=record.path)
    _check_time(record, time_name, time)
    time, note = regular_time(time, file=record.path, where=f"time of channel '{time_name}'")
    return time, [note] if note else []


def find_servo_roles(record: Record, roles: dict[str, str] | None = None,
                     problems: list[str] | None = None) -> tuple[str, dict[str, str]]:
    """The kind of a servo record (``"torsional"`` or ``"translational"``) and role ->
    ``NAME[:UNIT]`` of the channels :func:`map_servo_channels` uses: the given ``roles`` (of
    :data:`SERVO_ROLES`; ``-`` leaves one out), the others of the same kind found by name. The
    kind is the given roles' (a mix of the two is an error), else that of the one motion channel
    found by name (an angle or a displacement). With a ``problems`` list, an ambiguity is
    appended there instead of raised."""
    roles = dict(roles or {})
    unknown = set(roles) - set(SERVO_ROLES)
    if unknown:
        raise DroptowerError(f"unknown channel role(s) {', '.join(sorted(unknown))} for a servo record "
                             f"(roles: {', '.join(SERVO_ROLES)})", file=record.path)
    unused = {role for role, spec in roles.items() if spec.strip() in ("-", "none")}
    specs = {role: spec for role, spec in roles.items() if role not in unused}
    kinds = sorted({units for units, pair in SERVO_KINDS.items() for role in pair if role in specs})
    if len(kinds) > 1:
        raise DroptowerError("give angle and torque (torsional) or displacement and force (translational) channels, "
                             f"not a mix ({', '.join(sorted(set(specs) - {'time'}))})", file=record.path)

    def by_name(role: str) -> str | None:
        try:
            return _find_default(record, role)
        except DroptowerError as exc:
            if problems is None:
                raise
            problems.append(exc.problem)
            return None

    if kinds:
        units = kinds[0]
    else:
        found = {units: by_name(pair[0]) for units, pair in SERVO_KINDS.items()}
        found = {units: name for units, name in found.items() if name is not None}
        if len(found) > 1:
            text = (f"both an angle channel '{found['torsional']}' and a displacement channel "
                    f"'{found['translational']}'; choose one with `roles={{'angle': 'NAME'}}` or `roles={{'displacement': 'NAME'}}`")
            if problems is None:
                raise DroptowerError(text, file=record.path)
            problems.append(text)
        units = next(iter(found), "torsional")
    for role in ("time", *SERVO_KINDS[units]):
        if role not in specs and role not in unused:
            name = by_name(role)
            if name is not None:
                specs[role] = name
    return units, specs


@expects(record="droptower.io.channels.Record")
def map_servo_channels(record: Record, roles: dict[str, str] | None = None, *,
                       sample_rate_hz: float | None = None) -> ServoSignals:
    """A servo record's imposed motion and measured load in SI on one uniform time base.

    Torsional (``angle`` in rad, ``torque`` in N*m) or translational (``displacement`` in m,
    ``force`` in N), as :func:`find_servo_roles` finds them; every unit through pint and checked
    against the role's dimension. A record without a load channel gets ``load_si`` None (the
    caller says whether it needs one).
    """
    units, specs = find_servo_roles(record, roles)
    motion_role, load_role = SERVO_KINDS[units]
    if motion_role not in specs:
        raise DroptowerError("no angle channel found (nor a displacement channel); name it with `roles={'angle': 'NAME[:UNIT]'}` or "
                             f"`roles={{'displacement': 'NAME[:UNIT]'}}` (the file has: "
                             f"{', '.join(repr(n) for n in record.channels) or 'none'})", file=record.path)
    explicit = {role for role, spec in (roles or {}).items() if spec.strip() not in ("-", "none")}
    values: dict[str, np.ndarray] = {}
    channels: dict[str, Channel] = {}
    for role in (motion_role, load_role):
        if role not in specs:
            continue
        channel, unit = _resolve(record, role, specs[role])
        values[role] = _servo_si(record, role, channel, unit)
        channels[role] = channel
    motion = channels[motion_role]
    time, notes = _time_base(record, specs, explicit, motion, values[motion_role].size, sample_rate_hz, motion_role)
    own_time = motion.time()
    reference = time if own_time is None else np.asarray(own_time, dtype=np.float64)
    load = (_onto(record, channels[load_role], values[load_role], reference, motion_role)
            if load_role in values else None)
    return ServoSignals(time_s=time, motion_si=values[motion_role], load_si=load, units=units,
                        metadata=dict(record.metadata), source=record.path, notes=notes)


def _servo_si(record: Record, role: str, channel: Channel, unit: str) -> np.ndarray:
    """A servo channel in SI; a unit of the other kind's dimension (``in`` for an angle) gets
    the role to use instead."""
    other = {"angle": "displacement", "displacement": "angle", "torque": "force", "force": "torque"}[role]
    try:
        values = to_si(channel.values, unit, KINDS[role], file=record.path, channel=channel.name)
    except DroptowerError as exc:
        try:
            to_si(channel.values[:1], unit, KINDS[other])
        except DroptowerError:
            raise exc from None
        raise DroptowerError(f"{exc.problem}; a {KINDS[other]} unit: give it as `roles={{'{other}': "
                             f"'{channel.name}:{unit}'}}` (a {'translational' if other in ('displacement', 'force') else 'torsional'} record)",
                             file=record.path, where=exc.where) from None
    _check_values(record, channel, values)
    if np.ptp(values) == 0.0:
        raise DroptowerError(f"constant signal ({float(channel.values[0])!r} {unit} throughout)",
                             file=record.path, where=f"channel '{channel.name}'")
    return values
