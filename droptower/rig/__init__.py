"""The virtual drop tower (Rapp et al. 2022, docs/theory.md#rig, #impact, #decay): a pymunk scene whose restitution impact
drives the rheological coupling, sampled like the real rig, and a planner for test campaigns.

- :mod:`.config`: rig and test-plan files (:func:`load_rig`, :func:`load_doe`);
- :mod:`.rigfile`: a lab's rig file from its numbers (:func:`new_rig`, :func:`rig_toml`), the schema reference;
- :mod:`.impact`: closed forms of the impact law and the free decay, the second-impact check;
- :mod:`.preload`: the quasi-static pre-twist of the coupling;
- :mod:`.scene`: the pymunk scene, many tests in one space;
- :mod:`.sensors`: laser, flange torque, impact force; seeded noise;
- :mod:`.simulate`: tests -> :class:`DropResult` (summary, channels, log);
- :mod:`.lever`: the lever's free decay on the coupling, compiled (plan and identification);
- :mod:`.planner`: predictions per test condition, batched through the coupling;
- :mod:`.plots`: Rapp et al. 2022, Fig. 4 and the plan's figure.
"""
from droptower.rig.config import DOE, RigConfig, load_doe, load_rig
from droptower.rig.planner import plan
from droptower.rig.rigfile import new_rig, rig_toml
from droptower.rig.simulate import DropResult, DropTest, simulate

__all__ = ["DOE", "DropResult", "DropTest", "RigConfig", "load_doe", "load_rig", "new_rig", "plan", "rig_toml",
           "simulate"]
