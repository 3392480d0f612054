"""The virtual drop tower (Rapp et al. 2022, docs/theory.md#rig, #impact, #decay): a pymunk scene whose restitution impact
drives the rheological coupling, sampled like the real rig, and predictions of a test plan before it runs
(:func:`plan`; the interactive planner page is :mod:`droptower.planner`).

- :mod:`.config`: rig and test-plan files (:func:`load_rig`, :func:`load_doe`);
- :mod:`.rigfile`: a lab's rig file from its numbers (:func:`new_rig`, :func:`rig_toml`), the schema reference;
- :mod:`.impact_law`: closed forms of the impact law and the free decay, the second-impact check;
- :mod:`.preload`: the quasi-static pre-twist of the coupling;
- :mod:`.scene`: the pymunk scene, many tests in one space;
- :mod:`.sensors`: laser, flange torque, impact force; seeded noise;
- :mod:`.simulate`: tests -> :class:`DropResult` (summary, channels, log);
- :mod:`.lever_decay`: the lever's free decay on the coupling, compiled (plan and identification);
- :mod:`.predictions`: predictions per test condition, batched through the coupling;
- :mod:`.plots`: Rapp et al. 2022, Fig. 4 and the plan's figure.

:mod:`.scene` (pymunk) is imported when a simulation runs, so identification and the plan,
which integrate the lever themselves (:mod:`.lever_decay`), load without pymunk.
"""
from __future__ import annotations

import sys
import types
from typing import TYPE_CHECKING, Any

from droptower.lazy_names import lazy_names

if TYPE_CHECKING:
    from droptower.rig.config import DOE, RigConfig, load_doe, load_rig
    from droptower.rig.predictions import plan
    from droptower.rig.rigfile import new_rig, rig_toml
    from droptower.rig.simulate import DropResult, DropTest, simulate

#: name -> module, imported on first use: reading a rig file (every command that reads logs with
#: ``rig=``) imports neither pymunk nor the compiled coupling that simulating a test needs
_LAZY: dict[str, str] = {"DOE": "droptower.rig.config", "RigConfig": "droptower.rig.config",
                         "load_doe": "droptower.rig.config", "load_rig": "droptower.rig.config",
                         "plan": "droptower.rig.predictions", "new_rig": "droptower.rig.rigfile",
                         "rig_toml": "droptower.rig.rigfile", "DropResult": "droptower.rig.simulate",
                         "DropTest": "droptower.rig.simulate", "simulate": "droptower.rig.simulate"}

__all__ = ["DOE", "DropResult", "DropTest", "RigConfig", "load_doe", "load_rig", "new_rig", "plan", "rig_toml",
           "simulate"]


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())


class _Package(types.ModuleType):
    """This package's module: the function :func:`simulate` keeps its name when its module
    ``droptower.rig.simulate`` is imported (the import system binds a submodule to its package's
    attribute of the same name, which the eager ``from ... import simulate`` used to overwrite)."""

    def __setattr__(self, name: str, value: Any) -> None:
        if name in _LAZY and isinstance(value, types.ModuleType):
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
