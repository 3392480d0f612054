"""Test helper: malformed per-file conditions tables, with what a command must make of them.

A hypothesis strategy (:func:`malformed_tables`) draws a conditions table for a set of logs with
any mix of the problems a lab's sheet has — files missing from it, rows for files not given,
a file listed twice, a row without a file name, a word where a number belongs, a unit pint does
not know, no rows at all — as CSV (German dialect: ``;`` and decimal commas) or xlsx, and
:class:`Malformed` says what every command that takes ``--conditions`` must do with it: a
problem of the whole table (unknown unit, empty) is one error line and exit 2 before any log is
read; otherwise each file the table cannot give conditions for fails on its own (one line naming
it, exit 2), every other file is evaluated, the table's bad rows are warned about once, and no
traceback is ever printed. :func:`check_outcome` checks a command's exit code and stderr
against it; the extract test uses it, and map/identify/validate/report can run the same.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd
from hypothesis import strategies as st

#: the problems a drawn table may have
PROBLEMS = ("missing", "extra", "duplicate", "no_file", "wrong_type", "unknown_unit", "empty")
#: problems that leave nothing to do (exit 2 before any log is read)
TABLE_PROBLEMS = ("unknown_unit", "empty")


@dataclass
class Malformed:
    """A drawn table and what must come of it.

    table: its path; problems: what is wrong with it (of :data:`PROBLEMS`); whole_table: a
    problem of the whole table (exit 2, nothing evaluated); failing: the given logs (names)
    that must fail on their own; good: the given logs that must be evaluated; warned: how many
    bad rows the table has (each one warning line).
    """

    table: Path
    problems: tuple[str, ...]
    whole_table: bool
    failing: set[str] = field(default_factory=set)
    good: set[str] = field(default_factory=set)
    warned: int = 0


def _write(frame: pd.DataFrame, path: Path) -> None:
    if path.suffix == ".xlsx":
        frame.to_excel(path, index=False)
    else:
        frame.to_csv(path, index=False, sep=";", decimal=",")


@st.composite
def malformed_tables(draw, folder: Path, truth: pd.DataFrame) -> Malformed:
    """A malformed conditions table in ``folder`` for the logs ``truth["file"]`` (names; its
    columns ``inertia_kgm2``, ``drop_mass_kg``, ``drop_height_m``, ``temperature_c`` in SI)."""
    files = list(truth["file"])
    problems = draw(st.lists(st.sampled_from(PROBLEMS), min_size=1, max_size=3, unique=True))
    suffix = draw(st.sampled_from([".csv", ".xlsx"]))
    rows = [dict(r) for r in truth[["file", "inertia_kgm2", "drop_mass_kg", "drop_height_m", "temperature_c"]]
            .to_dict(orient="records")]
    failing: set[str] = set()
    warned = 0
    # the problems concern different files where they can (a missing file cannot also be listed twice)
    order = draw(st.permutations(files))
    pick = iter(order)
    if "missing" in problems:
        gone = next(pick)
        rows = [r for r in rows if r["file"] != gone]
        failing.add(gone)
    if "duplicate" in problems:
        twice = next(pick, None)
        if twice is not None:
            rows.append(dict(next(r for r in rows if r["file"] == twice)))
            failing.add(twice)
            warned += 1
    if "wrong_type" in problems:
        bad = next(pick, None)
        if bad is not None:
            for r in rows:
                if r["file"] == bad:
                    r["drop_mass_kg"] = draw(st.sampled_from(["schwer", "2 kg?", "zwei"]))
            failing.add(bad)
            warned += 1
    if "extra" in problems:
        rows.append({"file": "not_given_rep9.csv", "inertia_kgm2": 0.25, "drop_mass_kg": 1.0, "drop_height_m": 0.04,
                     "temperature_c": 23.0})
    if "no_file" in problems:
        rows.append({"file": None, "inertia_kgm2": 0.25, "drop_mass_kg": 1.0, "drop_height_m": 0.04,
                     "temperature_c": 23.0})
        warned += 1
    height = "Fallhoehe [mm]" if "unknown_unit" not in problems else "Fallhoehe [blorp]"
    frame = pd.DataFrame(rows, columns=["file", "inertia_kgm2", "drop_mass_kg", "drop_height_m", "temperature_c"])
    frame = pd.DataFrame({"Datei": frame["file"], "Traegheit [kg m^2]": frame["inertia_kgm2"],
                          "Fallmasse [kg]": frame["drop_mass_kg"], height: frame["drop_height_m"] * 1e3,
                          "Temperatur [degC]": frame["temperature_c"]})
    if "empty" in problems:
        frame = frame.iloc[0:0]
    path = folder / f"conditions_{draw(st.integers(0, 10**9))}{suffix}"
    _write(frame, path)
    whole = any(p in problems for p in TABLE_PROBLEMS)
    return Malformed(path, tuple(problems), whole, set() if whole else failing,
                     set() if whole else set(files) - failing, 0 if whole else warned)


def check_outcome(case: Malformed, code: int, err: str, evaluated: set[str]) -> None:
    """A command's exit ``code``, its stderr ``err`` and the logs it ``evaluated`` (names) as
    ``case`` requires: one line per problem, exit 2 or a per-file failure, never a traceback,
    nothing lost."""
    assert "Traceback" not in err, err
    if case.whole_table:
        assert code == 2, err
        assert evaluated == set(), evaluated
        errors = [line for line in err.splitlines() if "error:" in line]
        assert len(errors) == 1 and str(case.table) in errors[0], err
        return
    assert code == (2 if case.failing else 0), (code, err)
    assert evaluated == case.good, (evaluated, case.good, err)
    for name in case.failing:
        assert any("error:" in line and name in line for line in err.splitlines()), (name, err)
    warnings = [line for line in err.splitlines() if "warning:" in line and str(case.table) in line]
    assert len(warnings) == case.warned, err
