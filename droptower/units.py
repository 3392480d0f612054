"""Unit conversion at the edges: file units into SI, through pint (no hand-written table).

Log files write units in many spellings (``Nm``, ``N·m``, ``kNm``, ``°``, ``Grad``); they are
normalised to pint syntax, parsed by pint and checked against the expected kind of quantity.
A unit pint does not know, or one of the wrong dimension, is a :class:`DroptowerError`; so is
the lowercase ``grad``, which pint (and most tools) read as gradians (0.9°) and German lab
software writes for degrees: it is refused as ambiguous rather than guessed.
"""
from __future__ import annotations

import re
from functools import lru_cache

import numpy as np

from droptower.errors import DroptowerError

#: the acceleration of gravity (m/s^2) of Rapp et al. 2022's impact law: the rig file's default
#: (``gravity_m_per_s2``) and what the extraction uses when no rig is given
GRAVITY_M_PER_S2 = 9.81

#: kind -> the SI unit values are converted to.
SI_UNITS: dict[str, str] = {"time": "s", "angle": "rad", "torque": "N*m", "force": "N", "length": "m"}

#: a unit token of a field name (``torque_nm``, ``damping_nms_per_rad``) -> how the unit is printed
#: in a message or a report: one spelling per unit, so a torque never reads "nm" (nanometres)
PRINTED_UNITS: dict[str, str] = {"nm": "N*m", "nms": "N*m*s", "n": "N", "ns": "N*s", "rad": "rad", "m": "m",
                                 "deg": "deg", "mm": "mm", "s": "s", "hz": "Hz", "kg": "kg", "kgm2": "kg*m^2"}


def printed_unit(token: str) -> str:
    """How the field-name unit token ``token`` (``nm``, ``rad``, ``n_per_m``) is printed: N*m, rad,
    N/m; a token not in :data:`PRINTED_UNITS` is printed with ``_per_`` as ``/``, ``_`` as ``*``."""
    num, _, den = token.partition("_per_")
    parts = [PRINTED_UNITS.get(t, t) for t in num.split("_")]
    out = "*".join(parts)
    return f"{out}/{printed_unit(den)}" if den else out

# Spellings pint does not read as meant: "Nm" would parse as a (nonsensical) unit, not N*m;
# German lab software writes "Grad" for degrees (pint would read a gigaradian).
_ALIASES = [
    (re.compile(r"^([kM]?)N\s*[·.*\s-]?\s*m$"), r"\1N*m"),
    (re.compile(r"^(Grad|°)$"), "deg"),
    (re.compile(r"^(sec|Sec|S)$"), "s"),
]


_NM_INSIDE = re.compile(r"(?<![A-Za-z])([kM]?)Nm(?![A-Za-z])")
_GRAD_INSIDE = re.compile(r"(?<![A-Za-z])Grad(?![A-Za-z])")
_AMBIGUOUS_GRAD = re.compile(r"(?<![A-Za-z])grad(?![A-Za-z])")
AMBIGUOUS_GRAD = "is ambiguous: gradians (0.9 deg, as pint reads it) or degrees (German 'Grad'); write deg or gon"


def _refuse_ambiguous(unit: str, text: str) -> None:
    if _AMBIGUOUS_GRAD.search(text):
        raise ValueError(f"unit '{unit}' {AMBIGUOUS_GRAD}")


#: Units pint's default registry lacks that published records use: the metric tonne-force
#: ``tonf`` (1000 kgf = 9806.65 N exactly; pint's ``tf``, its ``metric_ton_force``), the force
#: unit of Chilean and Japanese isolator tests (Gallardo et al. 2023's bearing record). Pint's
#: own ``ton_force`` is the US short ton-force (8896 N): ``tonf`` is deliberately the metric one.
EXTRA_UNITS = ("tonf = metric_ton_force",)


@lru_cache(maxsize=None)
def _registry():
    import pint

    registry = pint.UnitRegistry()
    for definition in EXTRA_UNITS:
        registry.define(definition)
    return registry


def normalise_unit(unit: str) -> str:
    """A file's unit spelling in pint syntax (``"kNm"`` -> ``"kN*m"``, ``"°"`` -> ``"deg"``)."""
    text = unit.strip().strip("[]()").strip()
    for pattern, replacement in _ALIASES:
        text = pattern.sub(replacement, text)
    # the same spellings inside compound units: "Nm/°", "kNm/Grad"
    text = _GRAD_INSIDE.sub("deg", _NM_INSIDE.sub(r"\1N*m", text.replace("°", "deg")))
    return text.replace("·", "*").replace("²", "**2")


def is_unit(text: str) -> bool:
    """True if pint reads ``text`` (in any of the spellings above) as a unit; ``""`` counts."""
    text = normalise_unit(text)
    if not text:
        return True
    if text.replace(".", "").replace(",", "").lstrip("+-").isdigit():
        return False  # a number, not a unit (pint would read it as a dimensionless factor)
    try:
        _registry().parse_units(text)
    except Exception:  # pint raises many kinds of errors for text that is no unit
        return False
    return True


@lru_cache(maxsize=256)
def si_factor(unit: str, kind: str) -> float:
    """Factor that converts values in ``unit`` to the SI unit of ``kind`` (:data:`SI_UNITS`).

    Raises ValueError with the reason if the unit is unknown or of the wrong dimension.
    """
    if kind not in SI_UNITS:
        raise ValueError(f"unknown quantity kind {kind!r} (use {', '.join(SI_UNITS)})")
    text = normalise_unit(unit)
    if not text:
        raise ValueError(f"no unit given (expected a {kind} unit such as {SI_UNITS[kind]})")
    _refuse_ambiguous(unit, text)
    if text == SI_UNITS[kind]:
        return 1.0  # already SI (what droptower writes): pint's registry takes a second to build
    import pint

    ureg = _registry()
    try:
        quantity = ureg.Quantity(1.0, text)
    except (pint.errors.UndefinedUnitError, pint.errors.DefinitionSyntaxError, AssertionError,
            AttributeError, TypeError, ValueError) as exc:
        raise ValueError(f"unknown unit '{unit}'") from exc
    # radian is dimensionless in pint: an angle unit must reduce to radians, not to a bare number
    if kind == "angle" and quantity.to_root_units().units != ureg.radian:
        raise ValueError(f"unit '{unit}' is not an angle unit (expected e.g. rad, deg)")
    try:
        return float(quantity.to(SI_UNITS[kind]).magnitude)
    except pint.errors.DimensionalityError:
        raise ValueError(f"unit '{unit}' is not a {kind} unit (expected e.g. {SI_UNITS[kind]})") from None


def conversion_factor(unit: str, target: str) -> float:
    """Factor from ``unit`` (a file's spelling; ``""`` or ``-``: already in ``target``) to the pint
    unit ``target`` (``""``: a plain number). ValueError with the reason if it cannot be."""
    text = normalise_unit(unit)
    if text in ("", "-", "1"):
        return 1.0
    _refuse_ambiguous(unit, text)
    try:
        return float(_registry().Quantity(1.0, text).to(target or "dimensionless").magnitude)
    except Exception as exc:  # pint's errors: unknown unit, wrong dimension, bad syntax
        raise ValueError(f"unit '{unit}' cannot be read as {target or 'a plain number'} "
                         f"({type(exc).__name__})") from None


def to_si(values: np.ndarray, unit: str, kind: str, *, file: object = None, channel: str | None = None) -> np.ndarray:
    """``values`` (in ``unit``) converted to the SI unit of ``kind`` ('time', 'angle', 'torque',
    'force', 'length') as float64. An unknown or wrong unit raises :class:`DroptowerError`
    naming ``file`` and ``channel``."""
    try:
        factor = si_factor(unit, kind)
    except ValueError as exc:
        raise DroptowerError(str(exc), file=file, where=f"channel '{channel}'" if channel else None) from None
    values = np.asarray(values, dtype=np.float64)
    return values if factor == 1.0 else values * factor
