"""Coupling TOML files -> :class:`Coupling`, with one-line errors naming file, element and field.

File layout (SI, torsional units; see ``rig_configs/couplings/README.md``)::

    name = "example"
    description = "spring + Maxwell branch"
    source = "the zero-dimensional model paper, Table 2"          # where the numbers come from
    units = "torsional"                   # or "translational" (m, N): labels only
    [[element]]
    kind = "spring"
    stiffness = 12000.0                   # N*m/rad
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

import tomli_w
from pydantic import Field

from droptower.configs import read_toml, resolve
from droptower.errors import DroptowerError, expects
from droptower.limits import MAX_ELEMENTS
from droptower.rheology.coupling import Coupling
from droptower.rheology.elements import ELEMENT_KINDS, ElementUnion
from droptower.config_validation import StrictModel, validate


class CouplingFile(StrictModel):
    """A coupling TOML file as validated: name, description, source, units and its elements."""

    name: str = ""
    description: str = ""
    source: str = ""
    units: Literal["torsional", "translational"] = "torsional"
    element: list[ElementUnion] = Field(min_length=1)


def _name_element(list_name: str, index: int, item: Any) -> str:
    kind = item.get("kind") if isinstance(item, dict) else None
    return f"{list_name} {index + 1} ({kind})" if kind else f"{list_name} {index + 1}"


@expects(data="builtins.dict")
def parse_coupling(data: dict[str, Any], file: str | Path | None = None) -> Coupling:
    """Build a coupling from the parsed contents of a coupling file."""
    elements = data.get("element")
    if isinstance(elements, list) and len(elements) > MAX_ELEMENTS:  # before validating a million of them
        raise DroptowerError(f"{len(elements)} elements exceed the limit of {MAX_ELEMENTS} per coupling: "
                             "combine them (e.g. one masing or elastoslide element with n sliders)", file=file)
    for i, item in enumerate(data.get("element", []) if isinstance(data.get("element"), list) else []):
        kind = item.get("kind") if isinstance(item, dict) else None
        if kind is None:
            raise DroptowerError("missing field kind", file=file, where=f"element {i + 1}")
        if kind not in ELEMENT_KINDS:
            raise DroptowerError(f"unknown element kind {kind!r} (known: {', '.join(ELEMENT_KINDS)})",
                                 file=file, where=f"element {i + 1}")
    spec = validate(CouplingFile, data, file, _name_element)
    return Coupling(spec.element, name=spec.name or (Path(file).stem if file else ""),
                    description=spec.description, source=spec.source, units=spec.units,
                    path=Path(file) if file else None)


def load_coupling(path: str | Path) -> Coupling:
    """Load a coupling TOML file, or a shipped preset by name (``"rapp2022_nr60"``)."""
    path = resolve(path, "couplings")
    return parse_coupling(read_toml(path), path)


@expects(coupling="droptower.rheology.coupling.Coupling")
def coupling_to_toml(coupling: Coupling) -> str:
    """TOML text of a coupling (its first parameter set), readable by :func:`load_coupling`."""
    data = {"name": coupling.name, "description": coupling.description, "source": coupling.source,
            "units": coupling.units,
            "element": [el.model_dump(exclude_none=True, exclude_defaults=False) for el in coupling.elements]}
    return tomli_w.dumps(data)
