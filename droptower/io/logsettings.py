"""How a batch of drop-test logs is read into SI signals: what extraction and identification share."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from droptower.io.mapping import find_roles, map_channels
from droptower.io.readers import read_any
from droptower.io.signals import DropSignals

if TYPE_CHECKING:
    from droptower.io.conditions import Conditions
    from droptower.rig.config import RigConfig


def rig_defaults(rig: "RigConfig | None") -> dict[str, float]:
    """What a rig gives a log that lacks it: lever length (m), laser radius (m) and, for a rig
    with a single lever fixture, its inertia (kg*m^2; with several, the log's metadata or the
    conditions say which)."""
    if rig is None:
        return {}
    out = {"lever_length_m": float(rig.lever_length_m), "sensor_radius_m": float(rig.sensors.laser.radius_m)}
    if len(rig.inertias_kgm2) == 1:
        out["inertia_kgm2"] = float(rig.inertias_kgm2[0])
    return out


@dataclass(frozen=True)
class LogSettings:
    """roles: channel mapping (role -> ``NAME[:UNIT]``); inertia_kgm2 (kg*m^2), lever_length_m
    (m): override the logs' metadata; defaults: values (``inertia_kgm2``, ``lever_length_m``,
    ``sensor_radius_m``) used where a log's metadata lacks them, e.g. from the rig;
    sensor_radius_m: laser spot radius (m) for a distance channel, over the log's own
    ``laser_radius_m``; conditions: per-file test conditions (:mod:`droptower.io.conditions`: a
    conditions table or file-name pattern), merged over each log's metadata (a log value they
    replace is kept as ``log_<key>``); rig: the rig (:func:`droptower.rig.load_rig`) whose lever
    length, laser radius and single fixture fill what a log lacks (under ``defaults``), whose
    named fixtures name each result's ``fixture``."""

    roles: dict[str, str] = field(default_factory=dict)
    inertia_kgm2: float | None = None
    lever_length_m: float | None = None
    defaults: dict[str, float] = field(default_factory=dict)
    sensor_radius_m: float | None = None
    conditions: "Conditions | None" = None
    rig: "RigConfig | None" = None

    def __post_init__(self):
        from droptower.io.conditions import Conditions
        from droptower.rig.config import RigConfig

        for name, kind, how in (("conditions", Conditions, "read_conditions(path) or conditions_from_names(pattern)"),
                                ("rig", RigConfig, "load_rig(path)")):
            value = getattr(self, name)
            if value is not None and not isinstance(value, kind):
                raise TypeError(f"{type(self).__name__}.{name} must be a {kind.__name__} ({how}), got "
                                f"{type(value).__name__}")

    @property
    def geometry_defaults(self) -> dict[str, float]:
        """``defaults`` over the rig's (:func:`rig_defaults`)."""
        return {**rig_defaults(self.rig), **self.defaults}

    def no_inertia_reason(self, metadata: dict[str, Any]) -> str:
        """Why a log with this ``metadata`` has no rotating inertia, in terms of what these
        settings were given (a rig of several fixtures, conditions without inertia or fixture),
        never asking for what was given; Python names in backticks (a command reports its flags)."""
        rig = self.rig
        fixture = metadata.get("fixture")
        if self.conditions is not None:
            said = f"name fixture '{fixture}', which " if fixture is not None else "give neither inertia nor fixture: "
            if fixture is not None and rig is not None and rig.fixtures:
                where = f"is not one of the named fixtures of rig {rig.label} ({', '.join(rig.fixtures)})"
            elif fixture is not None and rig is not None:
                where = f"rig {rig.label} cannot resolve: it names no fixtures (add a [fixtures] table to it)"
            elif fixture is not None:
                where = "needs a `rig` with named fixtures to give its inertia"
            else:
                where = "add an inertia or fixture column"
            return f"no rotating inertia: the conditions from {self.conditions.source} {said}{where}"
        if rig is not None:
            fixtures = ", ".join(f"{n} {j:g}" for n, j in rig.fixtures.items()) or ", ".join(f"{j:g}" for j in rig.inertias_kgm2)
            return (f"no rotating inertia: rig {rig.label} has {len(rig.inertias_kgm2)} fixtures ({fixtures} kg*m^2) and "
                    "the log's metadata does not say which was used; give `conditions` (a table with a fixture or inertia "
                    "column per file) or `inertia_kgm2` for every log")
        return ("no rotating inertia: the log has no 'inertia_kgm2' metadata; give `inertia_kgm2`, `conditions` (per "
                "file) or a `rig` with a single fixture")

    def read_signals(self, path: str | Path, *, sample_rate_hz: float | None = None,
                     reader_options: dict[str, Any] | None = None, radius_flags: str = "`sensor_radius_m` or `rig`",
                     sample_rate_flag: str | None = "`sample_rate_hz`") -> DropSignals:
        """Read one log (any format) and map its channels; problems are DroptowerErrors naming the
        file (and ``radius_flags`` / ``sample_rate_flag``: the parameters that give what is missing, which a
        command reports as its flags). A file the ``conditions`` lack is a DroptowerError naming it."""
        conditions = self.conditions.for_path(path) if self.conditions is not None else {}
        record = read_any(path, **(reader_options or {}))
        default_radius = self.geometry_defaults.get("sensor_radius_m")
        signals = map_channels(record, self.roles, sensor_radius_m=self.sensor_radius_m, sample_rate_hz=sample_rate_hz,
                               default_sensor_radius_m=default_radius, radius_flags=radius_flags,
                               sample_rate_flag=sample_rate_flag)
        specs = find_roles(record, self.roles)
        if "angle" not in specs and "distance" in specs:  # the angle came from the laser: say at which radius
            radius = self.sensor_radius_m
            if radius is None:
                radius = record.metadata.get("laser_radius_m", default_radius)
            signals.metadata["sensor_radius_m"] = float(radius)
        for key, value in conditions.items():
            old = signals.metadata.get(key)
            if old is not None and old != value:
                signals.metadata[f"log_{key}"] = old
            signals.metadata[key] = value
        return signals
