"""Readers and writers: every file format into one channel model (:class:`Record`).

``read_any(path)`` reads any supported log; ``map_channels(record, roles, sensor_radius_m=...)``
turns it into SI :class:`DropSignals`; ``write_log`` / ``read_log`` are the project's own
log format (what the virtual rig writes).
"""
from droptower.io.channels import Channel, Record
from droptower.io.droptower_log import read_log, write_log
from droptower.io.mapping import map_channels, parse_channel_options
from droptower.io.readers import read_any
from droptower.io.signals import DropSignals

__all__ = ["Channel", "Record", "DropSignals", "read_any", "read_log", "write_log", "map_channels",
           "parse_channel_options"]
