"""Bad coupling files: one-line DroptowerError naming the file, the element (index and kind) and
the field; ``droptower servo BAD.toml`` exits with code 2 and no traceback."""
from __future__ import annotations


import pytest

from droptower.errors import DroptowerError
from droptower.rheology import load_coupling

GOOD = '[[element]]\nkind = "spring"\nstiffness = 1000.0\n\n'
ELASTO = 'kind = "elastoslide"\nphi0 = 0.01\nk = 1e4\nk0 = 0.0\nv_r = 1.0\n'

#: name -> (text of the bad element, placed second after a good spring, words the message must hold)
BAD_ELEMENTS = {
    "unknown kind": ('kind = "springy"\nstiffness = 1.0\n', ["element 2", "'springy'", "kind"]),
    "missing parameter": ('kind = "maxwell"\nstiffness = 1.0\n', ["element 2 (maxwell)", "damping", "missing"]),
    "missing kind": ('stiffness = 1.0\n', ["element 2", "kind", "missing"]),
    "negative parameter": ('kind = "maxwell"\nstiffness = 1.0\ndamping = -2.0\n', ["element 2 (maxwell)", "damping", "greater than 0"]),
    "negative yield": ('kind = "prandtl"\nstiffness = 1.0\nyield_torque = -1.0\n', ["element 2 (prandtl)", "yield_torque"]),
    "not a number": ('kind = "spring"\nstiffness = "stiff"\n', ["element 2 (spring)", "stiffness", "number"]),
    "nan": ('kind = "spring"\nstiffness = nan\n', ["element 2 (spring)", "stiffness"]),
    "unknown field": ('kind = "dashpot"\ndamping = 1.0\ndampnig = 2.0\n', ["element 2 (dashpot)", "dampnig", "unknown field"]),
    "even p": (ELASTO + 'p = 6\n', ["element 2 (elastoslide)", "field p", "odd"]),
    "p zero": (ELASTO + 'p = 0\n', ["element 2 (elastoslide)", "field p"]),
    "empty yield range": (ELASTO + 'yield_min = 50.0\nyield_max = 20.0\n', ["element 2 (elastoslide)", "yield_max", "yield_min"]),
    "yield range beyond the distribution": (ELASTO + 'yield_min = 5000.0\n', ["element 2 (elastoslide)", "yield_min"]),
    "phi0 and distribution": (ELASTO + '[element.distribution]\nyield_torque = [1.0]\nweight = [1.0]\n',
                              ["element 2 (elastoslide)", "phi0", "distribution"]),
    "distribution lengths": ('kind = "elastoslide"\nk = 1e4\nk0 = 0.0\nv_r = 1.0\n[element.distribution]\n'
                             'yield_torque = [1.0, 2.0]\nweight = [1.0]\n', ["element 2 (elastoslide)", "distribution", "same length"]),
    "masing constriction": ('kind = "masing"\nstiffness = 1.0\nmax_yield_torque = 1.0\nalpha = 1.0\n'
                            '[element.constriction]\np = -1.0\nk = 0.1\n', ["element 2 (masing)", "constriction", "field p"]),
    "table not through zero": ('kind = "spring_table"\nangle = [0.1, 0.2]\ntorque = [1.0, 2.0]\n',
                               ["element 2 (spring_table)", "angle 0"]),
    "falling table": ('kind = "spring_table"\nangle = [-0.1, 0.0, 0.1]\ntorque = [1.0, 0.0, -1.0]\n',
                      ["element 2 (spring_table)", "torque"]),
    "mullins generating energy": ('kind = "mullins"\ntau = 0.1\nslow_stiffness = 2000.0\nfast_stiffness = 1000.0\n',
                                  ["element 2 (mullins)", "fast_stiffness"]),
    "friction range": ('kind = "pfeffer"\nk1 = 1.0\nalpha = 1.0\nbeta = 0.1\ngamma = 0.01\n[element.friction]\n'
                       'max_torque = 1.0\nmin_yield_angle = 0.1\nmax_yield_angle = 0.01\n',
                       ["element 2 (pfeffer)", "friction", "max_yield_angle"]),
    "prony term": ('kind = "prony"\nequilibrium_stiffness = 1.0\n[[element.terms]]\nstiffness = 1.0\nrelaxation_time = -1.0\n',
                   ["element 2 (prony)", "relaxation_time"]),
}


def _assert_one_line(err: DroptowerError, path, words):
    text = str(err)
    assert "\n" not in text
    assert text.startswith(str(path))
    for w in words:
        assert w in text, f"{w!r} not in {text!r}"


@pytest.mark.parametrize("name", list(BAD_ELEMENTS))
def test_bad_element(tmp_path, name):
    body, words = BAD_ELEMENTS[name]
    path = tmp_path / "bad.toml"
    path.write_text(GOOD + "[[element]]\n" + body)
    with pytest.raises(DroptowerError) as info:
        load_coupling(path)
    _assert_one_line(info.value, path, words)


def test_infinite_parameter(tmp_path):
    """TOML has an inf literal; a Maxwell stiffness of inf would give NaN torques."""
    path = tmp_path / "bad.toml"
    path.write_text(GOOD + '[[element]]\nkind = "maxwell"\nstiffness = inf\ndamping = 1.0\n')
    with pytest.raises(DroptowerError) as info:
        load_coupling(path)
    _assert_one_line(info.value, path, ["element 2 (maxwell)", "stiffness"])


@pytest.mark.parametrize("text, words", [
    ("", ["element", "missing"]),                                        # no element at all
    ('name = "x"\n[[element]]\nkind = "spring"\nstiffness = 1.0\n[[element]\n', ["not valid TOML"]),
    ('units = "imperial"\n' + GOOD, ["units"]),
    ('[element]\nkind = "spring"\nstiffness = 1.0\n', ["element", "list"]),   # a table, not an array of tables
    ('colour = "red"\n' + GOOD, ["colour", "unknown field"]),
], ids=["empty", "malformed", "units", "not a list", "unknown top-level field"])
def test_bad_file(tmp_path, text, words):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(DroptowerError) as info:
        load_coupling(path)
    _assert_one_line(info.value, path, words)


def test_unreadable_file(tmp_path):
    path = tmp_path / "binary.toml"
    path.write_bytes(b"\xff\xfe\x00 not text \x80")
    with pytest.raises(DroptowerError) as info:
        load_coupling(path)
    _assert_one_line(info.value, path, [])


def test_missing_file_names_the_presets(tmp_path):
    path = tmp_path / "nowhere.toml"
    with pytest.raises(DroptowerError) as info:
        load_coupling(path)
    assert "\n" not in str(info.value) and "nowhere.toml" in str(info.value)
    assert "rapp2022_nr60" in str(info.value)


@pytest.mark.parametrize("name", ["even p", "unknown kind", "malformed"])
def test_servo_cli_exit_code_2(tmp_path, capsys, name):
    from droptower.cli.main import main

    path = tmp_path / "bad.toml"
    if name == "malformed":
        path.write_text(GOOD + "[[element]\n")
    else:
        path.write_text(GOOD + "[[element]]\n" + BAD_ELEMENTS[name][0])
    assert main(["servo", str(path)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and str(path) in lines[0]
