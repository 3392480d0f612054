"""The rig's input uncertainties: the rig file's ``[uncertainty]`` table, GUM type-B
distributions (a rectangular half-width a gives u = a/√3), defaults *not given*, one-line errors."""
import math
from pathlib import Path

import pytest
import tomli_w

from droptower.configs import preset_dir, read_toml
from droptower.errors import DroptowerError
from droptower.rig.config import load_rig
from droptower.rig.uncertainty import FixtureUncertainty, InputUncertainty, RigUncertainty

TABLE = {
    "lever_length_m": {"value": 0.0005, "distribution": "rectangular"},
    "laser_radius_m": {"value": 0.0002},
    "inertias_kgm2": [{"nominal": 0.359, "value": 0.0036, "source": "CAD model, 1 %"}],
    "drop_masses_kg": [{"nominal": 2.0, "value": 0.002, "distribution": "rectangular"}],
    "torque_calibration_rel": {"value": 0.005},
}


def _rig_with(tmp_path: Path, table: dict) -> Path:
    data = read_toml(preset_dir("rigs") / "rapp2022.toml")
    data["uncertainty"] = table
    path = tmp_path / "rig.toml"
    path.write_text(tomli_w.dumps(data))
    return path


def test_the_preset_states_no_uncertainty_and_nothing_is_invented():
    rig = load_rig("rapp2022")
    assert rig.uncertainty is None
    empty = RigUncertainty()
    assert all(getattr(empty, name) is None for name in RigUncertainty.model_fields)


def test_a_rig_file_states_its_input_uncertainties(tmp_path):
    given = load_rig(_rig_with(tmp_path, TABLE)).uncertainty
    assert given.lever_length_m.standard == pytest.approx(0.0005 / math.sqrt(3), rel=1e-15)  # GUM 4.3.7
    assert given.laser_radius_m.standard == 0.0002                                           # normal: u itself
    assert given.inertia(0.359).standard == 0.0036
    assert given.inertia(0.359 * (1 + 1e-9)) is given.inertia(0.359)
    assert given.inertia(0.1557) is None                                                     # fixture not given
    assert given.drop_mass(2.0).standard == pytest.approx(0.002 / math.sqrt(3))
    assert given.sample_rate_hz is None and given.laser_calibration_rel is None


@pytest.mark.parametrize("table, where", [
    ({"lever_length_m": {"value": -1.0}}, "lever_length_m"),
    ({"laser_radius_m": {"value": 1e-4, "distribution": "triangular"}}, "distribution"),
    ({"inertias_kgm2": [{"value": 0.01}]}, "nominal"),
    ({"inertia_kgm2": {"value": 0.01}}, "inertia_kgm2"),
])
def test_a_malformed_table_is_one_line_naming_the_file_and_the_field(tmp_path, table, where):
    with pytest.raises(DroptowerError) as err:
        load_rig(_rig_with(tmp_path, table))
    text = str(err.value)
    assert "\n" not in text and "rig.toml" in text and where in text and "uncertainty" in text


def test_every_input_is_described_in_the_schema():
    schema = RigUncertainty.model_json_schema()
    for name, prop in schema["properties"].items():
        assert len(prop.get("description", "")) > 30, name
    assert InputUncertainty(value=3.0, distribution="rectangular").standard == pytest.approx(math.sqrt(3.0))
    assert FixtureUncertainty(nominal=1.0, value=0.1).standard == 0.1


def test_the_examples_of_the_guide_and_the_module_validate():
    import re
    import tomllib

    import droptower.rig.uncertainty as module

    guide = (Path(__file__).resolve().parents[1] / "docs" / "guide" / "uncertainty.md").read_text(encoding="utf-8")
    examples = [re.search(r"```toml\n(.*?)```", guide, re.S).group(1),
                re.search(r"::\n\n(.*?)\n\"\"\"", module.__doc__ + '"""', re.S).group(1)]
    for text in examples:
        table = tomllib.loads(re.sub(r"(?m)^    ", "", text))["uncertainty"]
        given = RigUncertainty.model_validate(table)
        assert given.inertia(0.359) is not None and given.lever_length_m.distribution == "rectangular"
