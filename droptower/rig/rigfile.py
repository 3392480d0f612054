"""A lab's own rig file from its numbers, and the rig file's schema as documentation.

:func:`new_rig` builds a :class:`~droptower.rig.config.RigConfig` from what a lab knows of its
tower (lever length, laser radius, named fixtures, drop masses, sample rate) and fills the
fields only the simulation uses with stated assumptions (:data:`ASSUMED`); :func:`rig_toml`
writes it as a commented TOML file that :func:`~droptower.rig.config.load_rig` reads back.
:func:`rig_schema_markdown` is the reference of every field of a rig file (name, type, unit,
default, meaning), generated from the pydantic models' ``Field(description=...)``: the page
docs/guide/rig-file.md holds its output, and a test compares the two so they cannot drift.
"""
from __future__ import annotations

import math
import re
import typing
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from droptower.errors import DroptowerError, expects
from droptower.rig.config import RigConfig, check_pre_trigger
from droptower.config_validation import validate

#: what ``rig new`` assumes for the fields only the simulation (or planning) uses, and why
ASSUMED: dict[str, tuple[Any, str]] = {
    "drop_height_range_m": ([0.005, 6.0], "the drop heights of Rapp et al. 2022, Table 1"),
    "preload_range_nm": ([0.0, 0.0], "no preload"),
    "coupling_limit_deg": (28.0, "the natural-rubber coupling of Rapp et al. 2022"),
    "restitution": (0.5, "steel on steel, reproduces the paper's choice of masses (docs/theory.md#impact)"),
    "sensors.pre_trigger_s": (0.005, "5 ms before the impact"),
    "sensors.laser.noise_m": (0.0, "noise-free (simulation only)"),
    "sensors.torque.noise_nm": (0.0, "noise-free (simulation only)"),
    "sensors.torque.range_nm": (10000.0, "a 10 kN*m flange (simulation only)"),
    "sensors.impact_force.contact_duration_s": (3e-4, "the ~0.3 ms pulse of Rapp et al. 2022"),
    "sensors.impact_force.noise_n": (0.0, "noise-free (simulation only)"),
    "sensors.impact_force.range_n": (222000.0, "a 222 kN piezo sensor (simulation only)"),
}


@expects(fixtures=dict, drop_masses_kg=(list, tuple))
def new_rig(*, lever_length_m: float, laser_radius_m: float, fixtures: dict[str, float], drop_masses_kg: list[float],
            sample_rate_hz: float, name: str = "", description: str = "", source: str = "",
            drop_height_range_m: list[float] | None = None, preload_range_nm: list[float] | None = None,
            restitution: float | None = None, coupling_limit_deg: float | None = None) -> RigConfig:
    """A rig from a lab's numbers; the simulation-only fields as :data:`ASSUMED` says.

    Parameters
    ----------
    lever_length_m : float
        Lever arm L, rotation axis to impact point (m).
    laser_radius_m : float
        Horizontal distance of the laser spot from the pivot (m).
    fixtures : dict
        Fixture name -> rotating inertia J (kg*m^2), e.g. ``{"L1": 0.12}``.
    drop_masses_kg : list of float
        The drop masses (kg).
    sample_rate_hz : float
        The data acquisition's sample rate (Hz).
    name, description, source : str
        The rig's name, one line on it, where its numbers come from.
    drop_height_range_m, preload_range_nm : list of float, optional
        [lowest, highest] drop height (m) and preload (N*m).
    restitution : float, optional
        Restitution k of the mass-lever contact (0..1).
    coupling_limit_deg : float, optional
        Largest twist the rig may impose (deg).

    Returns
    -------
    RigConfig
        Validated (a bad value is a one-line DroptowerError naming the parameter).
    """
    if not fixtures:
        raise DroptowerError("a rig needs at least one fixture", where="fixtures")
    data = {
        "name": name, "description": description, "source": source or "the lab's numbers; other fields assumed",
        "lever_length_m": lever_length_m, "inertias_kgm2": list(fixtures.values()), "fixtures": dict(fixtures),
        "drop_masses_kg": list(drop_masses_kg),
        "drop_height_range_m": drop_height_range_m or ASSUMED["drop_height_range_m"][0],
        "preload_range_nm": preload_range_nm or ASSUMED["preload_range_nm"][0],
        "coupling_limit_deg": coupling_limit_deg if coupling_limit_deg is not None else ASSUMED["coupling_limit_deg"][0],
        "restitution": restitution if restitution is not None else ASSUMED["restitution"][0],
        "sensors": {
            "sample_rate_hz": sample_rate_hz, "pre_trigger_s": ASSUMED["sensors.pre_trigger_s"][0],
            "laser": {"radius_m": laser_radius_m, "noise_m": ASSUMED["sensors.laser.noise_m"][0]},
            "torque": {"noise_nm": ASSUMED["sensors.torque.noise_nm"][0],
                       "range_nm": ASSUMED["sensors.torque.range_nm"][0]},
            "impact_force": {"contact_duration_s": ASSUMED["sensors.impact_force.contact_duration_s"][0],
                             "noise_n": ASSUMED["sensors.impact_force.noise_n"][0],
                             "range_n": ASSUMED["sensors.impact_force.range_n"][0]},
        },
    }
    try:
        rig = validate(RigConfig, data, None)
        check_pre_trigger(rig)
        return rig
    except DroptowerError as exc:  # name the parameter, not the file's field
        where = exc.where or ""
        for field, parameter in _PARAMETERS:
            if field in where:
                raise DroptowerError(exc.problem, where=parameter) from None
        raise


#: a rig field, as a validation error names it -> the parameter of :func:`new_rig` that gives it
_PARAMETERS = (("laser: field radius_m", "laser_radius_m"), ("sample_rate_hz", "sample_rate_hz"),
               ("inertias_kgm2", "fixtures"), ("fixtures", "fixtures"), ("lever_length_m", "lever_length_m"),
               ("drop_masses_kg", "drop_masses_kg"), ("drop_height_range_m", "drop_height_range_m"),
               ("preload_range_nm", "preload_range_nm"), ("restitution", "restitution"),
               ("coupling_limit_deg", "coupling_limit_deg"), ("pre_trigger_s", "drop_height_range_m"))


def _given(rig: RigConfig, dotted: str) -> bool:
    """True if the field at ``dotted`` differs from what :data:`ASSUMED` fills in."""
    node: Any = rig
    for part in dotted.split("."):
        node = getattr(node, part)
    return node != ASSUMED[dotted][0]


def _value(value: Any) -> str:
    import tomli_w

    if isinstance(value, list):  # one line: the lab's numbers at a glance
        return "[" + ", ".join(_value(v) for v in value) + "]"
    return tomli_w.dumps({"v": value}).split("=", 1)[1].strip()


@expects(rig="droptower.rig.config.RigConfig")
def rig_toml(rig: RigConfig) -> str:
    """The rig as a TOML file :func:`~droptower.rig.config.load_rig` reads; every field an
    assumption filled is marked ``# assumed: why``."""
    lines = ["# Drop-tower rig file (droptower rig new). SI units; fields: docs/guide/rig-file.md"]

    def field(name: str, value: Any, dotted: str | None = None) -> None:
        dotted = dotted or name
        note = f"  # assumed: {ASSUMED[dotted][1]}" if dotted in ASSUMED and not _given(rig, dotted) else ""
        lines.append(f"{name} = {_value(value)}{note}")

    for name in ("name", "description", "source", "lever_length_m", "inertias_kgm2", "drop_masses_kg",
                 "drop_height_range_m", "preload_range_nm", "coupling_limit_deg", "restitution", "gravity_m_per_s2"):
        field(name, getattr(rig, name))
    if rig.fixtures:
        lines += ["", "[fixtures]  # name = rotating inertia J in kg*m^2"]
        lines += [f"{_value(n) if not n.replace('_', '').replace('-', '').isalnum() else n} = {_value(j)}"
                  for n, j in rig.fixtures.items()]
    s = rig.sensors
    lines += ["", "[sensors]"]
    field("sample_rate_hz", s.sample_rate_hz, "sensors.sample_rate_hz")
    field("pre_trigger_s", s.pre_trigger_s, "sensors.pre_trigger_s")
    lines += ["", "[sensors.laser]"]
    field("radius_m", s.laser.radius_m, "sensors.laser.radius_m")
    field("noise_m", s.laser.noise_m, "sensors.laser.noise_m")
    lines += ["", "[sensors.torque]"]
    field("noise_nm", s.torque.noise_nm, "sensors.torque.noise_nm")
    field("range_nm", s.torque.range_nm, "sensors.torque.range_nm")
    if s.torque.resonance is not None:
        lines += ["", "[sensors.torque.resonance]"]
        for name in ("frequency_hz", "damping_ratio", "strength"):
            field(name, getattr(s.torque.resonance, name), f"sensors.torque.resonance.{name}")
    lines += ["", "[sensors.impact_force]"]
    for name in ("contact_duration_s", "noise_n", "range_n"):
        field(name, getattr(s.impact_force, name), f"sensors.impact_force.{name}")
    sim = rig.simulation
    lines += ["", "[simulation]  # simulation only"]
    for name in type(sim).model_fields:
        lines.append(f"{name} = {_value(getattr(sim, name))}")
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------ schema reference
def _type_name(annotation: Any) -> tuple[str, type | None]:
    """How a field's type reads in the reference, and the sub-model it is (if any; a list of
    tables names its entries' model too)."""
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return "table", annotation
    if origin is typing.Literal:
        return "one of " + ", ".join(f"`{a}`" for a in args), None
    if origin in (typing.Union, getattr(__import__("types"), "UnionType", None)):
        inner = [a for a in args if a is not type(None)]
        name, model = _type_name(inner[0])
        return f"{name} (optional)", model
    if origin is list:
        name, model = _type_name(args[0])
        return f"list of {name}", model
    if origin is dict:
        return f"table of {_type_name(args[1])[0]}", None
    base = getattr(annotation, "__origin__", None) or annotation
    for meta_base in (float, int, str, bool):
        if base is meta_base or (isinstance(base, type) and issubclass(base, meta_base)):
            return {float: "number", int: "integer", str: "text", bool: "true/false"}[meta_base], None
    # pydantic's constrained types (PositiveFloat) are Annotated[float, ...]
    args = typing.get_args(annotation)
    return (_type_name(args[0])[0] if args else str(annotation)), None


_UNITS = (("_nm_per_deg", "N*m/deg"), ("_kgm2", "kg*m^2"), ("_m_per_s2", "m/s^2"), ("_deg", "deg"), ("_hz", "Hz"),
          ("_nm", "N*m"), ("_kg", "kg"), ("_s", "s"), ("_m", "m"), ("_n", "N"))


def _unit(name: str) -> str:
    return next((unit for suffix, unit in _UNITS if name.endswith(suffix)), "")


def _default(field: Any) -> str:
    from pydantic_core import PydanticUndefined

    if field.default is PydanticUndefined:
        return "**required**"
    value = field.default
    if isinstance(value, BaseModel):
        return "(its defaults)"
    if value is None:
        return "none"
    if isinstance(value, float) and math.isfinite(value):
        return f"`{value:g}`"
    return f"`{value!r}`" if not isinstance(value, str) else (f'`"{value}"`' if value else '`""`')


def rig_schema_markdown() -> str:
    """The reference of every rig-file field, one table per TOML table, from the models; a
    sub-model that several fields of one table share (every input of ``[uncertainty]``) is one
    table naming them all, not the same table once per field."""
    out: list[str] = []

    def table(model: type[BaseModel], title: str) -> None:
        doc = re.sub(r":\w+:`~?([^`]+)`", r"`\1`", (model.__doc__ or "").strip().split("\n\n")[0])
        doc = " ".join(doc.replace("``", "`").split())  # the docstring's line breaks and indents are one space
        rows = ["| Field | Type | Unit | Default | Meaning |", "|---|---|---|---|---|"]
        subs: dict[type, list[str]] = {}
        for name, field in model.model_fields.items():
            kind, sub = _type_name(field.annotation)
            description = (field.description or "").replace("|", "\\|")
            rows.append(f"| `{name}` | {kind} | {_unit(name)} | {_default(field)} | {description} |")
            if sub is not None:
                subs.setdefault(sub, []).append(name)
        out.append(f"### `[{title}]`\n\n{doc}\n" if title else f"### Top level\n\n{doc}\n")
        out.append("\n".join(rows) + "\n")
        for sub, names in subs.items():
            if len(names) == 1:
                table(sub, f"{title}.{names[0]}" if title else names[0])
            else:  # one table for the fields that share it, named by all of them
                table(sub, f"{title}.<{' | '.join(names)}>" if title else f"<{' | '.join(names)}>")

    table(RigConfig, "")
    return "\n".join(out)


#: the markers between which docs/guide/rig-file.md holds :func:`rig_schema_markdown`'s output
SCHEMA_BEGIN, SCHEMA_END = "<!-- rig-schema: begin (generated by droptower.rig.rigfile) -->", "<!-- rig-schema: end -->"


def update_schema_page(page: str | Path) -> bool:
    """Rewrite the generated part of ``page`` (between :data:`SCHEMA_BEGIN` and
    :data:`SCHEMA_END`); True if it changed. ``python -m droptower.rig.rigfile`` runs it on
    docs/guide/rig-file.md."""
    page = Path(page)
    text = page.read_text(encoding="utf-8")
    head, _, rest = text.partition(SCHEMA_BEGIN)
    _, _, tail = rest.partition(SCHEMA_END)
    new = f"{head}{SCHEMA_BEGIN}\n\n{rig_schema_markdown()}\n{SCHEMA_END}{tail}"
    if new != text:
        page.write_text(new, encoding="utf-8")
    return new != text


if __name__ == "__main__":  # pragma: no cover - the docs' generator
    print("updated" if update_schema_page(Path(__file__).resolve().parents[2] / "docs/guide/rig-file.md") else "unchanged")
