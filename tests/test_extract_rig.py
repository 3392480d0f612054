"""The extractor on the virtual drop tower's logs: a linear Kelvin–Voigt coupling (spring and
dashpot) of known stiffness and damping goes through the pymunk rig, its sensors and the log
file, and comes back out of ``extract_file`` (Rapp et al. 2022, eq. 15-17)."""
from __future__ import annotations

import numpy as np
import pytest

from droptower import sdof
from droptower.extract import Settings, extract_file
from droptower.rheology.loader import parse_coupling
from droptower.rig.config import load_rig
from droptower.rig.simulate import DropTest, simulate


def test_linear_coupling_through_the_virtual_rig(tmp_path):
    inertia, stiffness, d_ratio = 0.359, 14_000.0, 1.5
    r = float(sdof.decay_ratio(d_ratio))
    omega = np.sqrt(stiffness / (inertia * (1 + r * r)))
    coupling = parse_coupling({"name": "kelvin-voigt", "element": [
        {"kind": "spring", "stiffness": stiffness}, {"kind": "dashpot", "damping": 2 * inertia * r * omega}]})
    rig = load_rig("rapp2022")
    tests = [DropTest(inertia, 2.0, 0.2, 0.0, seed=1), DropTest(inertia, 2.0, 1.4, 1000.0, seed=2)]
    for drop in simulate(rig, coupling, tests, duration_s=0.15):
        path = drop.write_log(tmp_path / f"h{drop.test.drop_height_m}.csv")
        _, result = extract_file(path, Settings(sensor_radius_m=rig.sensors.laser.radius_m))
        assert result.stiffness_nm_per_rad == pytest.approx(stiffness, rel=0.01)
        assert result.damping_ratio == pytest.approx(d_ratio, rel=0.03)
        assert result.frequency_hz == pytest.approx(omega / (2 * np.pi), rel=0.005)
        assert result.stiffness_torque_nm_per_rad == pytest.approx(stiffness, rel=0.02)
        assert result.double_impact == drop.double_impact
        assert result.torque_offset_nm == pytest.approx(drop.test.preload_nm, abs=20.0)
        # the force impulse and the fitted start velocity agree (angular momentum, docs/theory.md#impact)
        assert result.lever_rate_after_rad_per_s == pytest.approx(result.decay_fit_initial_rate_rad_per_s, rel=0.02)
