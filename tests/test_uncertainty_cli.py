"""Input uncertainties on the command line (``--uncertainty INPUT=VALUE[:distribution]`` over
the rig file's ``[uncertainty]``) and in Python (:func:`override_uncertainty`), and
``extract``'s per-drop uncertainty columns."""
from __future__ import annotations

import json
import math

import pytest
from hypothesis import given, settings, strategies as st

from droptower.cli.main import main
from droptower.errors import DroptowerError
from droptower.extract.synthetic import SyntheticDrop
from droptower.rig.uncertainty import SPEC_NAMES, FixtureUncertainty, RigUncertainty, override_uncertainty, \
    parse_uncertainty_spec

DEG = math.pi / 180


def test_specs_override_the_rig_files_table_per_input_and_per_fixture():
    base = RigUncertainty(inertias_kgm2=[FixtureUncertainty(nominal=0.359, value=0.01),
                                         FixtureUncertainty(nominal=0.5233, value=0.02)],
                          lever_length_m={"value": 0.001})
    out = override_uncertainty(base, ["inertia_kgm2@0.359=0.0036", "laser_radius_m=0.0005:rectangular",
                                      "laser_radius_m=0.0002"])
    assert out.inertia(0.359).value == 0.0036 and out.inertia(0.5233).value == 0.02
    assert out.laser_radius_m.value == 0.0002 and out.laser_radius_m.distribution == "normal"  # the later wins
    assert out.lever_length_m.value == 0.001  # the rig file's stays
    assert base.inertia(0.359).value == 0.01  # the base is not changed
    rect = override_uncertainty(None, ["sample_rate_hz=0.3:rectangular"]).sample_rate_hz
    assert rect.standard == pytest.approx(0.3 / math.sqrt(3))  # GUM 4.3.7
    assert override_uncertainty(None, []) is None


@pytest.mark.parametrize("spec, match", [
    ("lever_length_m", "NAME=VALUE"), ("lever_m=0.1", "unknown input"), ("inertia_kgm2=0.1", "which fixture"),
    ("lever_length_m@0.2=0.1", "takes no @NOMINAL"), ("lever_length_m=abc", "must be numbers"),
    ("lever_length_m=-1", ">= 0"), ("lever_length_m=0.1:uniform", "normal or rectangular"),
    ("inertia_kgm2@0=0.1", "nominal > 0")])
def test_a_bad_spec_is_one_line_naming_it(spec, match):
    with pytest.raises(DroptowerError, match=match):
        parse_uncertainty_spec(spec)


@settings(derandomize=True, max_examples=40, deadline=None)
@given(st.sampled_from(sorted(SPEC_NAMES)), st.floats(0, 1e3, allow_nan=False),
       st.sampled_from(["", ":normal", ":rectangular"]))
def test_every_input_round_trips(name, value, dist):
    nominal = "@0.5" if name in ("inertia_kgm2", "drop_mass_kg") else ""
    field, _, entry = parse_uncertainty_spec(f"{name}{nominal}={value!r}{dist}")
    assert field == SPEC_NAMES[name] and entry.value == value and entry.distribution == (dist[1:] or "normal")


def test_extract_adds_u_u95_and_the_dominant_input_and_says_when_none_is_given(tmp_path, capsys):
    drop = SyntheticDrop(duration_s=0.1, seed=3)
    path = str(drop.write(tmp_path / "d.csv"))
    j = drop.metadata()["inertia_kgm2"]
    assert main(["extract", path, "--json"]) == 0
    out = capsys.readouterr()
    assert "input uncertainties: not given" in out.err and "stiffness_nm_per_deg_U95" not in json.loads(out.out)[0]
    assert main(["extract", path, "--json", "--uncertainty", f"inertia_kgm2@{j}={0.02 * j}",
                 "--uncertainty-method", "gum"]) == 0
    out = capsys.readouterr()
    row = json.loads(out.out)[0]
    assert "given: inertia_kgm2" in out.err
    assert row["stiffness_nm_per_deg_dominant"] == "inertia_kgm2"
    # c = J(ω² + δ²): u² = u_fit² + (0.02·c)², U95 = 2u (GUM, k = 2)
    assert row["stiffness_nm_per_deg_u"] ** 2 == pytest.approx(
        row["stiffness_nm_per_deg_std"] ** 2 + (0.02 * row["stiffness_nm_per_deg"]) ** 2, rel=1e-6)
    assert row["stiffness_nm_per_deg_U95"] == pytest.approx(2 * row["stiffness_nm_per_deg_u"])
    assert "laser_radius_m" in row["uncertainty_not_given"]
    assert main(["extract", path, "--uncertainty", "inertia_kgm2=0.1"]) == 2
    assert "--uncertainty" in capsys.readouterr().err
