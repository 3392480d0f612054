"""Readers and writers: every file format into one channel model (:class:`Record`).

``read_any(path)`` reads any supported log; ``map_channels(record, roles, sensor_radius_m=...)``
turns a drop test into SI :class:`DropSignals`, ``map_servo_channels(record, roles)`` a servo
record (torsional, or translational: displacement and force) into SI :class:`ServoSignals`;
``write_log`` / ``read_log`` are the project's own log format (what the virtual rig writes);
``read_conditions(table)`` / ``conditions_from_names(pattern)`` give each log its test
conditions (:class:`Conditions`: a lab's sheet keyed by file, or its file names).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from droptower.io.channels import Channel, Record
from droptower.io.droptower_log import read_log, write_log
from droptower.io.mapping import map_channels, map_servo_channels, parse_channel_options
from droptower.io.readers import read_any
from droptower.io.signals import DropSignals, ServoSignals
from droptower.lazy_names import lazy_names

if TYPE_CHECKING:
    from droptower.io.conditions import Conditions, conditions_from_names, read_conditions

#: names imported on first use: the conditions tables need pandas, which reading and extracting a
#: log does not
_LAZY: dict[str, str] = {"Conditions": "droptower.io.conditions", "conditions_from_names": "droptower.io.conditions",
                         "read_conditions": "droptower.io.conditions"}

__all__ = ["Channel", "Record", "DropSignals", "ServoSignals", "read_any", "read_log", "write_log", "map_channels",
           "map_servo_channels", "parse_channel_options", "Conditions", "read_conditions", "conditions_from_names"]


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
