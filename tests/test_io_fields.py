"""Field names for torsional and translational records: every family's parameter and derived
names have a translational twin without a torsional unit, and the twin reads back."""
from __future__ import annotations

import math

import numpy as np
import pytest

from droptower.identify.data import DataScale
from droptower.identify.families import FAMILIES
from droptower.io.fields import field_name, torsional_fields, translate_fields

TORSIONAL_TOKENS = {"nm", "nms", "rad", "rad2", "rad3", "deg", "torque", "angle"}


@pytest.mark.parametrize("kind", sorted(set(FAMILIES) - {"template"}))
def test_every_family_name_has_a_translational_twin_that_reads_back(kind):
    family = FAMILIES[kind](DataScale(0.002, 0.002, 100.0, 5e4, 0.1, 5.0, "translational"))
    v = family.initial()
    names = family.names + list(family.derived(v))
    for name in names:
        twin = field_name(name, "translational")
        assert not TORSIONAL_TOKENS & set(twin.split("_")[1:]), twin
        assert torsional_fields({twin: 2.5}, "translational") == {name: 2.5}
        assert field_name(name, "torsional") == name
    assert family.coupling(v).units == "translational"


def test_values_in_degrees_become_millimetres_and_back():
    report = {"amplitude_deg": 1.0, "stiffness_nm_per_deg": 10.0, "loss_angle_deg": 5.0,
              "levels": [{"amplitude_deg": [1.0, 2.0]}], "k1_nm_per_rad": 3.0, "n": 7}
    out = translate_fields(report, "translational")
    # 1 deg of the torsional reading is pi/180 rad, i.e. pi/180 m: 17.45 mm
    assert out["amplitude_mm"] == pytest.approx(1000 * math.pi / 180)
    assert out["stiffness_n_per_mm"] == pytest.approx(10.0 * 180 / math.pi / 1000)
    assert out["loss_angle_deg"] == 5.0 and out["k1_n_per_m"] == 3.0 and out["n"] == 7
    np.testing.assert_allclose(out["levels"][0]["amplitude_mm"], [1000 * math.pi / 180, 2000 * math.pi / 180])
    back = torsional_fields({"amplitude_mm": out["amplitude_mm"], "bounds_n_per_mm": (1.0, 2.0)}, "translational")
    assert back["amplitude_deg"] == pytest.approx(1.0)
    assert back["bounds_nm_per_deg"] == pytest.approx((1e3 * math.pi / 180, 2e3 * math.pi / 180))
    assert translate_fields(report, "torsional") is report
