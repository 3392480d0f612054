"""Any coupling file as a model family: its element structure kept, its numbers scaled.

Option ``template`` names a coupling TOML (a preset name such as ``rapp2022_nr60``, or a
path). Every non-zero real number of every element becomes a free scale factor (bounds
1/``factor_range`` .. ``factor_range``, optimised as its logarithm); a lookup table gets one
factor for all its values (the breakpoints stay), so a monotone table stays monotone.
Integers (counts, exponents such as the elastoslide's p), zeros and an element's settings (its
``SETTINGS``: bookkeeping time constants, a band fixing its number of terms) stay as they are. The
family follows whatever the template becomes: nothing here knows its elements. Strategy:
joint least squares from the template (all factors 1).
"""
from __future__ import annotations

import copy
import re
from typing import Any

import numpy as np

from droptower.errors import DroptowerError
from droptower.identify.data import Segment
from droptower.identify.families.base import Family
from droptower.identify.families.stages import Setup, result_of
from droptower.identify.fit import FitVariable
from droptower.identify.result import Identification
from droptower.rheology import Coupling, load_coupling


def _slug(text: str) -> str:
    return re.sub(r"[^0-9a-z]+", "_", text.lower()).strip("_")


class TemplateFamily(Family):
    """Scale factors on the numbers of a coupling file (option ``template``)."""

    kind = "template"
    title = "coupling template with fitted scale factors"
    source = "droptower identify (template family)"
    OPTIONS = {"template": "rapp2022_nr60", "factor_range": 30.0}

    def _parameters(self) -> list[FitVariable]:
        template = self.options["template"]
        if not isinstance(template, (str, Coupling)):
            raise DroptowerError(f"option template must be a coupling preset name or file, got {template!r}")
        self.template = template if isinstance(template, Coupling) else load_coupling(str(template))
        if self.template.units != self.scale.units:
            raise DroptowerError(f"the template {self.template.name} is {self.template.units}, the records are "
                                 f"{self.scale.units}: use a template of the records' kind")
        self.base = [el.model_dump(exclude_none=True) for el in self.template.elements]
        r = float(self.options["factor_range"])
        if not r > 1:
            raise DroptowerError(f"option factor_range must be > 1, got {r}")
        #: (element index, key, table?) per factor
        self.fields: list[tuple[int, str, bool]] = []
        names = []
        for i, el in enumerate(self.base):
            label = f"e{i + 1}_{_slug(str(el.get('name') or el['kind']))}"
            settings = type(self.template.elements[i]).SETTINGS
            for key, value in el.items():
                if key in settings:  # set-up, not material: e.g. a band fixing the number of terms
                    continue
                if isinstance(value, float) and value != 0.0:
                    self.fields.append((i, key, False))
                elif isinstance(value, dict) and isinstance(value.get("y"), list) and any(value["y"]):
                    self.fields.append((i, key, True))
                else:
                    continue
                names.append(f"{label}_{key}_factor")
        if not self.fields:
            raise DroptowerError(f"the template {self.template.name} has no real numbers to fit")
        return [FitVariable(n, 1.0 / r, r) for n in names]

    def guess(self) -> np.ndarray:
        return np.ones(len(self.fields))

    def elements(self, v: np.ndarray) -> list[dict[str, Any]]:
        out = copy.deepcopy(self.base)
        for (i, key, table), factor in zip(self.fields, v):
            if table:
                out[i][key]["y"] = [float(factor) * y for y in out[i][key]["y"]]
            else:
                out[i][key] = float(factor) * out[i][key]
        return out

    def coupling_data(self, v: np.ndarray, *, name: str = "", description: str = "") -> dict[str, Any]:
        return {"name": name or f"identified_{self.template.name}",
                "description": description or f"{self.template.description} (scale factors fitted)",
                "source": f"{self.template.source}; template {self.template.name}", "units": self.template.units,
                "element": self.elements(np.asarray(v, float))}


def identify_template(s: Setup, segments: list[Segment], start: float, **_) -> Identification:
    r = s.fit(segments, s.x0.copy(), None, f"joint scale factors of {s.family.template.name}")
    return result_of(s, segments, r.values.copy(), [r], start)


FAMILY = TemplateFamily
strategy = identify_template
