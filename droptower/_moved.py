"""Modules renamed so that a name says what is inside; the old import paths keep working for
one release with a :class:`DeprecationWarning`.

The old files are gone (a rename, which version control follows); a finder on
:data:`sys.meta_path`, installed by ``import droptower``, answers an old dotted name with the
module at its new one, so ``import droptower.rig.planner`` and
``from droptower.decayfit import fit_decay`` still work and warn once per process.
"""
from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import sys
import warnings
from types import ModuleType

#: old dotted module name -> its new one (each goes in the release after its rename)
MOVED_MODULES: dict[str, str] = {
    "droptower.validation": "droptower.config_validation",
    "droptower.compare.validation": "droptower.compare.map_vs_servo",
    "droptower.rig.planner": "droptower.rig.predictions",
    "droptower.decayfit": "droptower.damped_cosine",
    "droptower.extract.drops": "droptower.extract.drop_spans",
    "droptower.rig.impact": "droptower.rig.impact_law",
    "droptower.extract.impact": "droptower.extract.impact_detection",
    "droptower.maps.fit": "droptower.maps.fitting",
    "droptower.rig.lever": "droptower.rig.lever_decay",
    # the model ranking: "compare" is the map validation's package
    "droptower.identify.compare": "droptower.identify.ranking",
    # the campaign read for an identification and the one call, beside the fit (dropfit)
    "droptower.identify.drops": "droptower.identify.drop_campaign",
    "droptower.identify.search": "droptower.identify.engine.search",
}


class MovedModuleFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Import an old module name as the module at its new name, with a DeprecationWarning."""

    def find_spec(self, fullname: str, path: object = None, target: ModuleType | None = None
                  ) -> importlib.machinery.ModuleSpec | None:
        """A spec for an old name of :data:`MOVED_MODULES`; None for every other name."""
        if fullname not in MOVED_MODULES:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        """The new module itself (one module object under both names, so patches apply to both)."""
        new = MOVED_MODULES[spec.name]
        warnings.warn(f"{spec.name} is deprecated and will be removed in the next release: import {new}",
                      DeprecationWarning, stacklevel=2)
        return importlib.import_module(new)

    def exec_module(self, module: ModuleType) -> None:
        """Nothing to run: the new module was executed when it was imported."""


def install() -> None:
    """Put the finder first on :data:`sys.meta_path` (once)."""
    if not any(isinstance(finder, MovedModuleFinder) for finder in sys.meta_path):
        sys.meta_path.insert(0, MovedModuleFinder())
