"""Field names that carry their unit, for torsional and translational records alike.

Inside, a translational record is computed exactly as a torsional one: its displacement (m)
takes the place of the angle (rad) and its force (N) that of the torque (N*m); the numbers do
not change, only their reading (as in a coupling file with ``units = "translational"``). The
names of parameters and report fields are written for the torsional reading
(``k1_nm_per_rad``); :func:`field_name` gives the translational one (``k1_n_per_m``), and
:func:`translate_fields` turns a whole report into it. The angle's display unit, the degree,
becomes the millimetre (values scaled: ``amplitude_deg`` -> ``amplitude_mm``,
``stiffness_nm_per_deg`` -> ``stiffness_n_per_mm``). A loss angle stays an angle.
:func:`torsional_fields` is the inverse, for names a user writes (initial values, bounds).
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import pandas as pd

UNITS = ("torsional", "translational")

#: unit tokens (after a field's first word): torsional -> translational
_UNIT_TOKENS = {"nm": "n", "nms": "ns", "rad": "m", "rad2": "m2", "rad3": "m3", "deg": "mm"}
#: quantity words (anywhere in a name)
_WORDS = {"torque": "force", "angle": "displacement"}
#: a degree on the display scale of the translational reading: 1 rad <-> 1 m, deg <-> mm
_DEG_TO_MM = 1000.0 * math.pi / 180.0
#: names that keep their reading (a phase angle is an angle for both kinds)
_KEEP = ("loss_angle", "phase")


def _check(units: str) -> None:
    if units not in UNITS:
        raise ValueError(f"units must be one of {', '.join(UNITS)}, got {units!r}")


def _convert(name: str, tokens: dict[str, str], words: dict[str, str]) -> tuple[str, float]:
    """``name`` with its tokens replaced, and the factor its value takes (a ``deg``/``mm`` token
    in the numerator or after ``per``)."""
    if any(keep in name for keep in _KEEP):
        return name, 1.0
    parts = name.split("_")
    factor, below = 1.0, False
    for i, part in enumerate(parts):
        if part == "per":
            below = True
        elif part in words:
            parts[i] = words[part]
        elif i > 0 and part in tokens:
            if part in ("deg", "mm"):
                scale = _DEG_TO_MM if part == "deg" else 1.0 / _DEG_TO_MM
                factor *= 1.0 / scale if below else scale
            parts[i] = tokens[part]
    return "_".join(parts), factor


def field_name(name: str, units: str) -> str:
    """The name of a field (``k1_nm_per_rad``) for records of ``units`` (``k1_n_per_m``)."""
    _check(units)
    return name if units == "torsional" else _convert(name, _UNIT_TOKENS, _WORDS)[0]


def translate_fields(value: Any, units: str) -> Any:
    """A report (nested dicts and lists) with every key named for ``units``, and the values of
    keys whose display unit changes (degrees -> millimetres) scaled."""
    _check(units)
    if units == "torsional":
        return value
    return _translate(value, 1.0, _UNIT_TOKENS, _WORDS)


def translate_table(table: "pd.DataFrame", units: str) -> "pd.DataFrame":
    """A table with its columns named for ``units`` and the degree columns in millimetres (from
    the column in rad beside it where there is one: no round-off of the degrees on the way)."""
    _check(units)
    if units == "torsional":
        return table
    out = table.copy()
    for column in table.columns:
        name, factor = _convert(str(column), _UNIT_TOKENS, _WORDS)
        if factor != 1.0:
            si = str(column).replace("_deg", "_rad")
            if si in table.columns:
                out[column] = table[si] * (1e3 if factor > 1.0 else 1e-3)
            else:
                out[column] = table[column] * factor
    return out.rename(columns=lambda c: _convert(str(c), _UNIT_TOKENS, _WORDS)[0])


def torsional_fields(values: dict[str, Any], units: str) -> dict[str, Any]:
    """Names a user wrote for records of ``units`` (``k1_n_per_m``) back to the torsional ones
    the families use, values scaled back; torsional names pass unchanged."""
    _check(units)
    if units == "torsional":
        return dict(values)
    inverse_tokens = {v: k for k, v in _UNIT_TOKENS.items()}
    inverse_words = {v: k for k, v in _WORDS.items()}
    out = {}
    for key, value in values.items():
        name, factor = _convert(key, inverse_tokens, inverse_words)
        out[name] = _scaled(value, factor)
    return out


def _scaled(value: Any, factor: float) -> Any:
    if factor == 1.0 or isinstance(value, bool):
        return value
    if isinstance(value, (int, float)):
        return value * factor
    if isinstance(value, (list, tuple)):
        return type(value)(_scaled(v, factor) for v in value)
    return value


def _translate(value: Any, factor: float, tokens: dict[str, str], words: dict[str, str]) -> Any:
    if isinstance(value, dict):
        out = {}
        for key, item in value.items():
            name, f = _convert(str(key), tokens, words) if isinstance(key, str) else (key, 1.0)
            out[name] = _translate(item, factor * f, tokens, words)
        return out
    if isinstance(value, (list, tuple)):
        return [_translate(v, factor, tokens, words) for v in value]
    return _scaled(value, factor)
