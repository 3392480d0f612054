"""The package layout: renamed modules keep their old import paths for one release (with a
DeprecationWarning), and importing identification does not load the pymunk scene."""
from __future__ import annotations

import importlib
import subprocess
import sys
import warnings

import pytest

import droptower
from droptower._moved import MOVED_MODULES


@pytest.mark.parametrize("old", sorted(MOVED_MODULES))
def test_an_old_module_path_is_the_new_module_and_warns(old):
    new = MOVED_MODULES[old]
    sys.modules.pop(old, None)  # a previous import would return without the finder's warning
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        module = importlib.import_module(old)
    assert module is importlib.import_module(new)
    assert [w for w in caught if issubclass(w.category, DeprecationWarning) and new in str(w.message)]
    sys.modules.pop(old, None)


def test_the_new_module_files_exist_and_the_old_ones_are_gone():
    """A rename, not a copy: an old file left behind would shadow nothing but confuse a reader."""
    root = droptower.__path__[0]
    from pathlib import Path
    for old, new in MOVED_MODULES.items():
        assert Path(root, *new.split(".")[1:]).with_suffix(".py").is_file(), new
        assert not Path(root, *old.split(".")[1:]).with_suffix(".py").exists(), old


def test_an_unknown_module_is_still_refused():
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("droptower.rig.no_such_module")


def test_importing_identification_does_not_load_pymunk():
    """Identification integrates the lever itself (droptower.rig.lever_decay); the pymunk scene
    is the simulation's, imported when droptower.rig.simulate runs one."""
    code = ("import sys, droptower.identify, droptower.rig.lever_decay, droptower.rig.preload; "
            "print('pymunk' in sys.modules, 'droptower.rig.scene' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["False", "False"], done.stdout + done.stderr


def test_both_free_decays_share_one_torque_convention_on_a_preloaded_spring():
    """A linear spring K twisted by a preload T_rest: T - T_rest = K phi exactly, whichever
    integrator ran the decay (the rig's symplectic Euler, the identification's Verlet); the
    rig's torque_nm is the absolute torque K (twist + phi)."""
    import numpy as np

    from droptower.identify.lever import free_decay as identify_decay
    from droptower.rheology import parse_coupling
    from droptower.rig.predictions import free_decay as rig_decay
    from droptower.rig.preload import pretwist

    stiffness, preload = 2000.0, np.array([15.0, 0.0])
    spring = parse_coupling({"element": [{"kind": "spring", "stiffness": stiffness}]})
    inertia, rate0, step = np.array([0.05, 0.05]), np.array([3.0, 3.0]), 1 / 20000
    twist = pretwist(spring, preload, 1.0, 1.0)
    assert np.allclose(twist.torque_nm, preload, rtol=1e-9, atol=1e-9)

    rig = rig_decay(spring, inertia, rate0, twist, step)
    assert np.allclose(rig.torque_from_rest_nm, stiffness * rig.angle_rad, rtol=1e-12, atol=1e-9)
    assert np.allclose(rig.torque_nm, stiffness * (twist.angle_rad[:, None] + rig.angle_rad), rtol=1e-12, atol=1e-9)
    assert abs(rig.torque_nm[0, 0] - preload[0]) < 1e-9 and rig.torque_from_rest_nm[0, 0] == 0.0

    angle, torque = identify_decay(spring, inertia, rate0, 400, step, twist.state.copy())
    assert np.allclose(torque, stiffness * angle, rtol=1e-12, atol=1e-9)
    assert np.max(np.abs(torque[0])) > 1.0  # the decay moved: the check above is not 0 == 0


def test_the_version_is_defined_once():
    """pyproject.toml reads the version from droptower.__version__ (no second literal)."""
    import tomllib
    from pathlib import Path

    from setuptools.config.pyprojecttoml import read_configuration

    pyproject = Path(droptower.__file__).resolve().parents[1] / "pyproject.toml"
    project = tomllib.loads(pyproject.read_text(encoding="utf-8"))["project"]
    assert "version" not in project and "version" in project["dynamic"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # setuptools calls its [tool.setuptools] support beta
        assert read_configuration(pyproject, expand=True)["project"]["version"] == droptower.__version__


def test_the_preload_ramp_and_hold_are_one_fact():
    """The rig file's defaults, the servo bench's and identification's conditioning are one
    constant (a hold long against the reference coupling's 10 s network recovery)."""
    from droptower.identify.dropfit import DropFitSettings
    from droptower.rig import load_rig
    from droptower.rig.config import PRELOAD_HOLD_S, PRELOAD_RAMP_S, Simulation
    from droptower.servo import bench

    assert PRELOAD_HOLD_S >= 6 * 10.0  # e^-6 of the recovery time left
    assert (Simulation().preload_ramp_s, Simulation().preload_hold_s) == (PRELOAD_RAMP_S, PRELOAD_HOLD_S)
    sim = load_rig("rapp2022").simulation
    assert (sim.preload_ramp_s, sim.preload_hold_s) == (PRELOAD_RAMP_S, PRELOAD_HOLD_S)
    assert DropFitSettings().conditioning == (PRELOAD_RAMP_S, PRELOAD_HOLD_S)
    assert (bench.PRELOAD_RAMP_S, bench.PRELOAD_HOLD_S) == (PRELOAD_RAMP_S, PRELOAD_HOLD_S)


def test_the_impact_law_rate_uses_the_given_gravity():
    """The extraction's impact-law rate after the impact follows the free fall v1 = sqrt(2 g h):
    under 4 g it is exactly twice the rate under g (the rig's gravity, when a rig is given)."""
    import numpy as np

    from droptower.extract.extractor import lever_rate_after
    from droptower.io.signals import DropSignals
    from droptower.units import GRAVITY_M_PER_S2

    t = np.arange(100) / 1000.0
    signals = DropSignals(t, np.zeros_like(t), metadata={"drop_mass_kg": 5.0, "drop_height_m": 0.1,
                                                           "restitution": 0.5})
    standard, source = lever_rate_after(signals, 0.4, 0.2, float("nan"))
    heavy, _ = lever_rate_after(signals, 0.4, 0.2, float("nan"), 4 * GRAVITY_M_PER_S2)
    assert source == "impact_law" and standard > 0
    assert heavy == pytest.approx(2 * standard, rel=1e-12)


def test_map_validation_summary_dict_is_deprecated():
    from types import SimpleNamespace

    from droptower.compare import MapValidation

    validation = object.__new__(MapValidation)
    object.__setattr__(validation, "validation", SimpleNamespace(summary={"all": {"points": 3}}))
    with pytest.warns(DeprecationWarning, match="to_dict"):
        assert validation.summary_dict == {"all": {"points": 3}}


def test_every_package_ships_in_the_wheel():
    """Every package folder of ``droptower/`` (an ``__init__.py``) is listed in pyproject.toml's
    ``[tool.setuptools] packages``: a missing one installs without its modules, so a fresh
    ``pip install .`` (not the editable checkout) fails on import."""
    import tomllib
    from pathlib import Path

    root = Path(droptower.__file__).resolve().parent
    listed = set(tomllib.loads((root.parent / "pyproject.toml").read_text(encoding="utf-8"))
                 ["tool"]["setuptools"]["packages"])
    found = {".".join(("droptower", *p.parent.relative_to(root).parts)) for p in root.rglob("__init__.py")
             if "__pycache__" not in p.parts}
    assert found - listed == set()
