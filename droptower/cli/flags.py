"""The command line's names for what the library's messages call by their Python names.

Library messages (``droptower/`` outside ``cli/``) name a value by the Python parameter or the
configuration key that gives it, in backticks: ``give `inertia_kgm2` or `rig```; a channel
role by the Python expression ``roles={'angle': 'NAME[:UNIT]'}``; an error's ``where`` by the
bare parameter name (``workers``) when the error names no file. When the command line reports such a message it says its own
flags instead (``give --inertia-kgm2 or --rig``, ``--channel angle=NAME[:UNIT]``, ``--workers:
must be at least 1``), through :func:`cli_text` and :func:`cli_message`.
"""
from __future__ import annotations

import re

from droptower.errors import DroptowerError

#: Python parameter or config key -> the flag that gives it on the command line
FLAGS: dict[str, str] = {
    "inertia_kgm2": "--inertia-kgm2",
    "lever_length_m": "--lever-length-m",
    "sensor_radius_m": "--sensor-radius-m",
    "sample_rate_hz": "--sample-rate-hz",
    "sample_interval_s": "--sample-interval-s",
    "lever_arm_m": "--lever-arm-m",
    "settle_cycles": "--settle-cycles",
    "rig": "--rig",
    "roles": "--channel",
    "workers": "--workers",
    "scheduler": "--scheduler",
    "duration_s": "--duration-s",
    "chunk_size": "--chunk-size",
    "resume": "--resume",
    "out": "--out",
    "frequencies_hz": "--frequency-hz",
    "cycles": "--cycles",
    "preloads_nm": "--preloads-nm",
    "drops": "--drops",
    "amplitude_deg": "--amplitude-deg",
    "frequency_hz": "--frequency-hz",
    "amplitude_deg/frequency_hz": "--amplitude-deg/--frequency-hz",
    "max_tests": "--max-tests",
    "for_identification": "--for-identification",
    "columns": "--column",
    "verbose": "--verbose",
    "coupling_file": "--model-coupling",
    "results": "--results",
    "reference": "--reference",
    "servo_results": "--servo-results",
    "servo_columns": "--servo-column",
    "sheet": "--sheet",
    "repeats": "--repeats",
    "uncertainty_pct": "--uncertainty-pct",
    "family": "--family",
    "template": "--template",
    "conditions": "--conditions",
    "uncertainty": "--uncertainty",
    "u95_ref_rel": "--servo-u95-rel",
}

_ROLE = re.compile(r"`roles=\{'(\w+)': '([^']*)'\}`")
_ASSIGNED = re.compile(r"`([\w/]+)=([^`]*)`")
_NAMED = re.compile(r"`([\w/]+)`")


def _flag(name: str) -> str:
    return FLAGS.get(name, name)


def cli_text(text: str) -> str:
    """``text`` of a library message with its Python names replaced by the command's flags."""
    text = _ROLE.sub(lambda m: f"--channel {m.group(1)}={m.group(2)}", text)
    text = _ASSIGNED.sub(lambda m: f"{_flag(m.group(1))} {m.group(2)}" if m.group(1) in FLAGS else m.group(0), text)
    return _NAMED.sub(lambda m: _flag(m.group(1)) if m.group(1) in FLAGS else m.group(0), text)


def cli_error(exc: DroptowerError) -> DroptowerError:
    """``exc`` as the command line reports it (same type, file and meaning; flags for names)."""
    # a ``where`` inside a file is a field of that file (a log's ``lever_length_m``), not a parameter
    where = cli_text(_flag(exc.where)) if exc.where and exc.file is None else exc.where
    translated = DroptowerError.__new__(type(exc))
    DroptowerError.__init__(translated, cli_text(exc.problem), file=exc.file, where=where)
    return translated


def cli_message(exc: DroptowerError) -> str:
    """The one line the command line prints for ``exc``."""
    return cli_error(exc).message
