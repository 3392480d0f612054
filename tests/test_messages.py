"""One wording per situation across commands: every command is given the same wrong inputs (a
missing file, an unreadable file, a folder where a file belongs, a bad unit, an ambiguous unit,
a bad range) and must say it in the same words, naming the file or flag; errors about an output
place blame the output place."""
from __future__ import annotations

import builtins
import errno
import io
import os
from pathlib import Path

import pytest

from droptower.cli.main import main
from droptower.extract.synthetic import SyntheticDrop
from droptower.io.droptower_log import write_log

#: the same tests' map fitted once per process by this module's commands and calls (tests/conftest.py)
pytestmark = pytest.mark.usefixtures("shared_map_fits")

SIMULATE = ["--inertia-kgm2", "0.359", "--drop-mass-kg", "2", "--height-m", "1"]


def commands(file: dict[str, Path], out: Path) -> dict[str, list[str]]:
    """Every command reading a file, with the file of the kind it reads (``file[suffix]``)."""
    csv, toml, js = str(file["csv"]), str(file["toml"]), str(file["json"])
    return {
        "channels": ["channels", csv],
        "extract": ["extract", csv],
        "identify": ["identify", csv, "--family", "zerodim6"],
        "identify --params": ["identify", csv, "--family", "zerodim6", "--params", toml],
        "identify --from-drop-tests": ["identify", "--from-drop-tests", csv, "--family", "elastoslide"],
        "compare-models": ["compare-models", csv],
        "map": ["map", csv],
        "report": ["report", csv],
        "validate --map": ["validate", "--map", js, "--coupling", "rapp2022_nr60", "--out", str(out / "v")],
        "simulate --coupling": ["simulate", "--coupling", toml, *SIMULATE],
        "simulate --rig": ["simulate", "--rig", toml, *SIMULATE],
        "plan --doe": ["plan", "--doe", toml],
        "campaign --doe": ["campaign", "--doe", toml, "--out", str(out / "c")],
        "servo": ["servo", toml],
        "evaluate-servo": ["evaluate-servo", csv],
    }


def _error(capsys, argv: list[str]) -> str:
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, (argv, err)
    assert "Traceback" not in err and "internal error" not in err, err
    return err


def test_a_missing_file_is_no_such_file_everywhere(tmp_path, capsys) -> None:
    missing = {s: tmp_path / "nothing" / f"missing.{s}" for s in ("csv", "toml", "json")}
    for name, argv in commands(missing, tmp_path).items():
        err = _error(capsys, argv)
        said = [line for line in err.splitlines() if "missing." in line]
        # a config may also have been meant as a preset's name: the shipped ones follow
        assert said and all(line.endswith(("missing.csv: no such file", "missing.json: no such file",
                                           "missing.toml: no such file"))
                            or "missing.toml: no such file, and no shipped " in line for line in said), (name, err)


def test_a_folder_where_a_file_belongs_is_not_a_file(tmp_path, capsys) -> None:
    folders = {s: tmp_path / f"folder.{s}" for s in ("csv", "toml", "json")}
    for folder in folders.values():
        folder.mkdir()
    for name, argv in commands(folders, tmp_path).items():
        if name in ("map", "report", "identify --from-drop-tests"):
            continue  # these take folders (a campaign, a folder of logs)
        err = _error(capsys, argv)
        assert any(line.endswith(": not a file") and "folder." in line for line in err.splitlines()), (name, err)


def test_an_unreadable_file_is_cannot_read_everywhere(tmp_path, capsys, monkeypatch) -> None:
    """As a user without read permission sees it (the open refused; no root needed)."""
    files = {s: tmp_path / f"locked.{s}" for s in ("csv", "toml", "json")}
    for f in files.values():
        f.write_text("x = 1\n")
    locked = set(files.values())
    real_open, real_io_open = builtins.open, io.open

    def refusing(real):
        def open_(file, *args, **kwargs):
            if isinstance(file, (str, os.PathLike)) and Path(file) in locked:
                raise PermissionError(errno.EACCES, "Permission denied", str(file))
            return real(file, *args, **kwargs)
        return open_
    monkeypatch.setattr(builtins, "open", refusing(real_open))
    monkeypatch.setattr(io, "open", refusing(real_io_open))
    for name, argv in commands(files, tmp_path).items():
        err = _error(capsys, argv)
        said = [line for line in err.splitlines() if "locked." in line]
        assert said and all(line.endswith(": cannot read (Permission denied)") for line in said), (name, err)


@pytest.fixture(scope="module")
def log(tmp_path_factory) -> Path:
    drop = SyntheticDrop(inertia_kgm2=0.359, seed=1)
    time, channels = drop.channels()
    return write_log(tmp_path_factory.mktemp("messages") / "drop.csv", time, channels, drop.metadata())


@pytest.mark.parametrize("unit, words", [
    ("furlong", "channel 'angle_rad': unit 'furlong' is not an angle unit (expected e.g. rad, deg)"),
    ("parsec*foo", "channel 'angle_rad': unknown unit 'parsec*foo'"),
    # pint reads grad as gradians, German lab software writes it for degrees: refused, not guessed
    ("grad", "channel 'angle_rad': unit 'grad' is ambiguous: gradians (0.9 deg, as pint reads it) or degrees"),
])
def test_a_bad_unit_is_said_alike_by_every_command_reading_logs(log, capsys, unit, words) -> None:
    channel = ["--channel", f"angle=angle_rad:{unit}"]
    for argv in (["channels", str(log)], ["extract", str(log)], ["identify", str(log), "--family", "zerodim6"],
                 ["compare-models", str(log)], ["identify", "--from-drop-tests", str(log), "--family", "elastoslide"]):
        err = _error(capsys, [*argv, *channel])
        assert f"{log}: {words}" in err or f"{log.name}: {words}" in err or f"excluded {log}: {words}" in err, \
            (argv, err)


@pytest.mark.parametrize("flag, value, runs", [
    ("--inertia-kgm2", "-1", [["simulate", "--drop-mass-kg", "2", "--height-m", "1"], ["extract", "LOG"],
                              ["identify", "--from-drop-tests", "LOG", "--family", "elastoslide"]]),
    ("--lever-length-m", "-1", [["extract", "LOG"], ["identify", "--from-drop-tests", "LOG", "--family", "elastoslide"]]),
    ("--duration-s", "-1", [["simulate", *SIMULATE], ["plan"], ["campaign", "--out", "OUT"]]),
    ("--amplitude-deg", "-1", [["servo", "rapp2022_nr60"]]),
    ("--frequency-hz", "-1", [["servo", "rapp2022_nr60"]]),
])
def test_a_bad_range_is_said_alike(log, tmp_path, capsys, flag, value, runs) -> None:
    for argv in runs:
        argv = [str(log) if a == "LOG" else str(tmp_path / "c") if a == "OUT" else a for a in argv]
        err = _error(capsys, [*argv, flag, value])
        lines = [line for line in err.splitlines() if line.strip()]
        assert len(lines) == 1 and lines[0].startswith(f"droptower: error: {flag}: must be > 0"), (argv, err)
        assert lines[0].endswith(f"got {value}"), err


def test_range_errors_name_a_preset_by_its_name(capsys) -> None:
    err = _error(capsys, ["simulate", "--inertia-kgm2", "0.359", "--drop-mass-kg", "2", "--height-m", "100"])
    assert "of rig rapp2022 (field drop_height_range_m)" in err and "rig_configs" not in err


def test_an_unknown_table_name_lists_the_shipped_tables(capsys) -> None:
    err = _error(capsys, ["map", "rapp2022_table5"])
    assert err.strip() == ("droptower: error: rapp2022_table5: no such file, and no shipped table of that name "
                           "(shipped: rapp2022_table4)")
    err = _error(capsys, ["simulate", "--coupling", "nr60", *SIMULATE])  # the same words for presets
    assert "nr60: no such file, and no shipped coupling preset of that name (shipped: rapp2022_nr60," in err


def test_help_texts_say_what_the_docs_say(capsys) -> None:
    conventions = (Path(__file__).resolve().parents[1] / "docs" / "conventions.md").read_text()
    assert "failures at the end, exit code 2" in " ".join(conventions.split())
    assert main(["campaign", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "exit code 2" in text and "exit code 1" not in text
    assert main(["compare-models", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    # with a hold-out the families are ranked by it (docs/guide/identification.md): the help says so
    assert "the families are ranked by their nRMSE on it" in text and "ranks the models" not in text
    assert "the ranking stays on the fitting data" not in text


def test_output_places_are_blamed_not_inputs(log, tmp_path, capsys) -> None:
    """A plot folder or output file that cannot be made is named as such; the input is not blamed."""
    blocked = tmp_path / "a_file"
    blocked.write_text("")
    place = blocked / "p"  # below a file: cannot be a folder
    for argv in (["extract", str(log), "--plot", str(place)], ["extract", str(log), "--out", str(place / "r.csv")],
                 ["map", "rapp2022_table4", "--plot", str(place)], ["map", "rapp2022_table4", "--out", str(place / "m.json")],
                 ["servo", "rapp2022_nr60", "--amplitude-deg", "1", "--frequency-hz", "10", "--plot", str(place / "l.png")],
                 ["plan", "--plot", str(place / "plan.png")]):
        err = _error(capsys, argv)
        lines = [line for line in err.splitlines() if line.strip()]
        assert len(lines) == 1 and lines[0].startswith(f"droptower: error: {place}"), (argv, err)
        assert "cannot write" in lines[0] or "cannot create" in lines[0], err
        assert f"{log}:" not in err, err


def test_every_file_written_gets_one_summary_line(log, tmp_path, capsys) -> None:
    """``droptower: wrote PATH (what)`` on stderr for each file or folder written (stdout keeps
    the results); --quiet silences it."""
    # a plan of two conditions (the default is Table 2's 90: the same lines, 90 predictions more)
    (tmp_path / "two.toml").write_text('name = "two"\nheights_m = [0.2, 1.0]\n[[group]]\n'
                                       'inertia_kgm2 = 0.359\ndrop_mass_kg = 2.0\n')
    runs = [
        (["simulate", *SIMULATE, "--duration-s", "0.05", "--out", "T/t.csv", "--plot", "T/t.png"], ["T/t.csv", "T/t.png"]),
        (["extract", str(log), "--out", "T/r.csv", "--plot", "T/fits"], ["T/r.csv", "T/fits"]),
        (["plan", "--doe", "T/two.toml", "--out", "T/plan.csv", "--plot", "T/plan.png"], ["T/plan.csv", "T/plan.png"]),
        (["servo", "rapp2022_nr60", "--amplitude-deg", "1", "--frequency-hz", "10", "--plot", "T/l.png"], ["T/l.png"]),
        (["map", "rapp2022_table4", "--out", "T/m.csv", "--plot", "T/figs"], ["T/m.csv", "T/figs"]),
    ]
    for argv, written in runs:
        argv = [a.replace("T/", f"{tmp_path}/") for a in argv]
        assert main(argv) == 0
        err = capsys.readouterr().err
        lines = [line for line in err.splitlines() if line.startswith("droptower: wrote ")]
        assert [line.split(" (")[0] for line in lines] == [f"droptower: wrote {tmp_path}/{w[2:]}" for w in written], err
        assert all(line.endswith(")") for line in lines)
    assert main(["-q", "extract", str(log), "--out", str(tmp_path / "quiet.csv")]) == 0
    assert "wrote" not in capsys.readouterr().err
