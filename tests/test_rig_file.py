"""The rig file: `rig new` writes one from a lab's numbers that loads back with exactly those
numbers, `rig check` prints its geometry, and the schema page is the model's (it cannot drift)."""
from __future__ import annotations

from pathlib import Path

import pytest

from droptower.cli.main import main
from droptower.errors import DroptowerError
from droptower.rig.config import RigConfig, load_rig
from droptower.rig.rigfile import ASSUMED, SCHEMA_BEGIN, SCHEMA_END, new_rig, rig_schema_markdown, rig_toml

PAGE = Path(__file__).resolve().parents[1] / "docs" / "guide" / "rig-file.md"
LAB = ["--lever-length-m", "0.25", "--laser-radius-m", "0.25", "--fixture", "L1=0.12", "--fixture", "L2=0.25",
       "--fixture", "L3=0.40", "--drop-mass-kg", "1", "--drop-mass-kg", "2", "--sample-rate-hz", "19200"]


def test_schema_page_is_generated_from_the_model():
    text = PAGE.read_text(encoding="utf-8")
    generated = text.split(SCHEMA_BEGIN, 1)[1].split(SCHEMA_END, 1)[0].strip()
    assert generated == rig_schema_markdown().strip(), "run python -m droptower.rig.rigfile"


def _models(model):
    yield model
    for field in model.model_fields.values():
        for sub in (field.annotation, *getattr(field.annotation, "__args__", ())):
            if isinstance(sub, type) and hasattr(sub, "model_fields"):
                yield from _models(sub)


def test_every_field_is_described_with_its_unit():
    """Each field of every rig table has a description in the model; one whose name carries a
    unit shows it in the reference."""
    schema = rig_schema_markdown()
    for model in _models(RigConfig):
        for name, field in model.model_fields.items():
            assert field.description, f"{model.__name__}.{name} has no Field(description=...)"
            assert f"| `{name}` |" in schema
    assert "| `lever_length_m` | number | m | **required** |" in schema
    assert "| `inertias_kgm2` | list of number | kg*m^2 |" in schema


def test_rig_new_round_trip(tmp_path, capsys):
    out = tmp_path / "lab_rig.toml"
    assert main(["rig", "new", str(out), *LAB]) == 0
    rig = load_rig(out)
    assert (rig.lever_length_m, rig.sensors.laser.radius_m, rig.sensors.sample_rate_hz) == (0.25, 0.25, 19200.0)
    assert rig.fixtures == {"L1": 0.12, "L2": 0.25, "L3": 0.40} and rig.inertias_kgm2 == [0.12, 0.25, 0.40]
    assert rig.drop_masses_kg == [1.0, 2.0]
    text = out.read_text()
    assert text.count("# assumed:") == len(ASSUMED)  # every assumption stated, nothing else
    assert rig_toml(rig).splitlines()[1:] == text.splitlines()[1:]
    capsys.readouterr()
    assert main(["rig", "check", str(out)]) == 0
    shown = capsys.readouterr().out
    assert "lever length    0.25 m" in shown and "laser radius    0.25 m" in shown and "fixture L2" in shown
    assert main(["rig", "new", str(out), *LAB]) == 2  # exists
    assert "give --force" in capsys.readouterr().err


@pytest.mark.parametrize(("change", "flag"), [
    (["--lever-length-m", "-1"], "--lever-length-m"), (["--laser-radius-m", "0"], "--laser-radius-m"),
    (["--fixture", "L9"], "--fixture"), (["--drop-height-range-m", "0.0001", "1"], "--drop-height-range-m"),
])
def test_rig_new_names_the_flag(tmp_path, capsys, change, flag):
    out = tmp_path / "bad.toml"
    assert main(["rig", "new", str(out), *LAB, *change]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and flag in err and "`" not in err
    assert not out.exists()


def test_new_rig_names_python_parameters():
    with pytest.raises(DroptowerError, match="^laser_radius_m: "):
        new_rig(lever_length_m=0.2, laser_radius_m=-1, fixtures={"a": 0.1}, drop_masses_kg=[1], sample_rate_hz=1e4)


def test_rig_check_of_a_preset_says_so(capsys):
    assert main(["rig", "check", "rapp2022"]) == 0
    assert "a shipped preset" in capsys.readouterr().out
