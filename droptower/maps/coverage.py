"""What a map does not cover, said: fixtures and test conditions that dropped out entirely, with
why and what would avoid it, and a temperature span too wide for one map.

A lab's campaign over several lever fixtures loses a whole fixture when every one of its drops
strikes twice (docs/theory.md#double-impact: the drop mass follows the lever down when it is not
much lighter than the lever's equivalent mass J/L²). :func:`coverage_notes` names every fixture
(or inertia), drop mass and drop height whose tests were all left out, with the reasons counted,
and for double impacts the planner's advice: the drop masses and heights at which the
closed-form decay of the fixture's own measured frequency and decay (docs/theory.md#decay)
leaves the lever's tip before the drop mass catches up within one period
(:func:`droptower.rig.impact_law.second_impact_time`, the criterion of ``droptower plan``).
"""
from __future__ import annotations

import math
from collections import Counter
from typing import Any

import numpy as np
import pandas as pd

from droptower.errors import expects
from droptower.maps.results import ExcludedTest

#: A map whose tests span more than this temperature range (K) says so: an elastomer's stiffness
#: and damping change with temperature, so one map over them mixes states.
TEMPERATURE_SPAN_K = 5.0
#: Drop masses searched for the advice: this many, geometrically spaced from 2 % of the heaviest
#: tested drop mass up to it.
ADVICE_MASS_STEPS = 60
#: Samples per period of the closed-form decay checked for a second impact.
ADVICE_SAMPLES_PER_PERIOD = 400


def _level_names(table: pd.DataFrame) -> list[tuple[str, str]]:
    """(column, how it is named) of the nested groupings a campaign's conditions form."""
    named = "fixture" in table.columns and table["fixture"].astype(str).str.strip().replace("nan", "").ne("").any()
    first = ("fixture", "fixture") if named else ("inertia_kgm2", "inertia")
    return [level for level in (first, ("drop_mass_kg", "drop mass"), ("drop_height_m", "drop height"))
            if level[0] in table.columns and table[level[0]].notna().any()]


def _shown(column: str, value: Any, rows: pd.DataFrame) -> str:
    if column == "fixture":
        j = pd.to_numeric(rows.get("inertia_kgm2", pd.Series(dtype=float)), errors="coerce").dropna().unique()
        return f"fixture {value}" + (f" (J = {j[0]:g} kg*m^2)" if len(j) == 1 else "")
    unit = {"inertia_kgm2": "kg*m^2", "drop_mass_kg": "kg", "drop_height_m": "m"}[column]
    label = {"inertia_kgm2": "inertia", "drop_mass_kg": "drop mass", "drop_height_m": "drop height"}[column]
    return f"{label} {float(value):g} {unit}"


def dropped_groups(table: pd.DataFrame, usable_index: pd.Index) -> list[tuple[dict[str, Any], pd.DataFrame]]:
    """The coarsest condition groups (fixture or inertia, then drop mass, then drop height) none of
    whose tests is usable: (the group's key values, its rows), a group inside one named already
    left out."""
    levels = [c for c, _ in _level_names(table)]
    out: list[tuple[dict[str, Any], pd.DataFrame]] = []
    named: list[dict[str, Any]] = []
    for depth in range(1, len(levels) + 1):
        keys = levels[:depth]
        for values, rows in table.groupby(keys, sort=True, dropna=True):
            values = values if isinstance(values, tuple) else (values,)
            key = dict(zip(keys, values))
            if rows.index.isin(usable_index).any():
                continue
            if any(all(key.get(k) == v for k, v in parent.items()) for parent in named):
                continue
            named.append(key)
            out.append((key, rows))
    return out


def double_impact_advice(inertia_kgm2: float, frequency_hz: float, decay_per_s: float, lever_length_m: float,
                         restitution: float, drop_masses_kg: list[float], drop_heights_m: list[float],
                         rig_masses_kg: tuple[float, ...] = ()) -> str:
    """The planner's advice for a fixture whose drops struck twice: the heaviest drop mass (kg) at
    which the lever's closed-form decay (its measured frequency (Hz) and decay coefficient
    (1/s), docs/theory.md#decay) clears the drop mass for one period at every tested drop height
    (m) (docs/theory.md#double-impact), and which of the rig's drop masses do. One line."""
    heights = np.asarray(sorted(set(drop_heights_m)), float)
    omega = 2.0 * math.pi * frequency_hz
    period = 1.0 / frequency_hz
    t = np.linspace(0.0, period, ADVICE_SAMPLES_PER_PERIOD + 1)

    def strikes_twice(mass: float) -> bool:
        from droptower.rig.impact_law import drop_mass_path, impact_velocities, lever_tip_path, second_impact_time

        iv = impact_velocities(mass, inertia_kgm2, lever_length_m, heights, restitution)
        angle = (iv.rate_after_rad_per_s[:, None] / omega) * np.exp(-decay_per_s * t) * np.sin(omega * t)
        x1 = drop_mass_path(iv.drop_mass_after_m_per_s[:, None], t[None, :])
        hits = second_impact_time(t, x1, lever_tip_path(angle, lever_length_m), period)
        return bool(np.any(np.isfinite(hits)))

    tested = max(drop_masses_kg)
    masses = np.geomspace(0.02 * tested, tested, ADVICE_MASS_STEPS)
    clear = [m for m in masses if not strikes_twice(float(m))]
    equivalent = inertia_kgm2 / lever_length_m ** 2
    heights_text = f"{', '.join(f'{h:g}' for h in heights)} m"
    if not clear:
        text = (f"no drop mass up to {tested:g} kg clears the lever for one period at {heights_text}; a fixture "
                f"of more inertia would (the lever's equivalent mass J/L^2 = {equivalent:.3g} kg)")
    else:
        text = (f"a drop mass of at most {max(clear):.2g} kg would avoid it at {heights_text} (the lever's "
                f"equivalent mass J/L^2 = {equivalent:.3g} kg, restitution {restitution:.2g})")
    if rig_masses_kg:
        ok = [m for m in rig_masses_kg if not strikes_twice(float(m))]
        text += (f"; of the rig's drop masses, {', '.join(f'{m:g} kg' for m in ok)} would" if ok
                 else "; none of the rig's drop masses would")
    return text


def _restitution(rows: pd.DataFrame, lever_length_m: float) -> float | None:
    """Newton's restitution k of the rows' impacts from their impulse (docs/theory.md#impact):
    v1' = v1 - impulse/m1 and v1' = v1 (m1 - k m2)/(m1 + m2), m2 = J/L^2; the median."""
    need = ("impact_impulse_n_s", "drop_mass_kg", "drop_height_m", "inertia_kgm2")
    if not all(c in rows.columns for c in need):
        return None
    v = rows[list(need)].apply(pd.to_numeric, errors="coerce").dropna()
    v = v[(v > 0).all(axis=1)]
    if v.empty:
        return None
    from droptower.rig.impact_law import G

    m1, m2 = v["drop_mass_kg"], v["inertia_kgm2"] / lever_length_m ** 2
    v1 = np.sqrt(2.0 * G * v["drop_height_m"])
    after = v1 - v["impact_impulse_n_s"] / m1
    k = (m1 - after * (m1 + m2) / v1) / m2
    k = k[np.isfinite(k) & (k >= 0) & (k <= 1)]
    return float(np.median(k)) if len(k) else None


def _median(rows: pd.DataFrame, column: str) -> float:
    if column not in rows.columns:
        return math.nan
    values = pd.to_numeric(rows[column], errors="coerce").dropna()
    return float(values.median()) if len(values) else math.nan


@expects(table=pd.DataFrame, usable=pd.DataFrame, excluded=[ExcludedTest])
def coverage_notes(table: pd.DataFrame, usable: pd.DataFrame, excluded: list[ExcludedTest],
                   rig: Any | None = None) -> list[str]:
    """One line per fixture or condition that dropped out of the map entirely (named, the
    reasons counted, and for double impacts :func:`double_impact_advice`), and one if the
    usable tests span more than :data:`TEMPERATURE_SPAN_K`.

    Parameters
    ----------
    table : DataFrame
        The whole results table (rows of every test).
    usable, excluded
        :func:`~droptower.maps.results.select_tests`' split of it.
    rig : RigConfig, optional
        The rig: its lever length and restitution (else the table's ``lever_length_m`` column and
        the restitution measured by the impulse) and its drop masses for the advice.
    """
    reasons = {e.test: e.reason for e in excluded}
    names = table["file"].astype(str) if "file" in table.columns else pd.Series(
        [f"row {i + 1}" for i in range(len(table))], index=table.index)
    notes = []
    for key, rows in dropped_groups(table, usable.index):
        why = Counter(part.strip() for n in names.loc[rows.index] for part in reasons.get(n, "").split(";")
                      if part.strip())
        what = ", ".join(_shown(c, v, rows) for c, v in key.items())
        shown = "; ".join(f"{r} x{n}" for r, n in why.most_common())
        line = f"{what}: all {len(rows)} test(s) left out of the map ({shown or 'no usable values'})"
        if any("double_impact" in r for r in why):
            # the fixture's frequency and decay from its usable drops where it has any: a second
            # impact disturbs the fit of the flagged ones
            first, value = next(iter(key.items()))
            clean = usable[usable[first] == value] if first in usable.columns else usable.iloc[:0]
            line += f"; {_advice(rows, rig, clean if len(clean) else rows)}"
        notes.append(line)
    span = temperature_span_k(usable)
    if span is not None and span > TEMPERATURE_SPAN_K:
        notes.append(f"the map's tests span {span:.1f} K of temperature (more than {TEMPERATURE_SPAN_K:g} K): "
                     "the coupling's stiffness and damping change with temperature; fit a map per temperature")
    return notes


def temperature_span_k(table: pd.DataFrame) -> float | None:
    """max - min of the ``temperature_c`` column (K), None where the table has no temperatures."""
    if "temperature_c" not in table.columns:
        return None
    t = pd.to_numeric(table["temperature_c"], errors="coerce").dropna()
    return float(t.max() - t.min()) if len(t) else None


def _advice(rows: pd.DataFrame, rig: Any | None, decays: pd.DataFrame) -> str:
    lever = rig.lever_length_m if rig is not None else _median(rows, "lever_length_m")
    j = _median(rows, "inertia_kgm2")
    f, delta = _median(decays, "frequency_hz"), _median(decays, "decay_coefficient_per_s")
    if not math.isfinite(lever) or not math.isfinite(j):
        return "the advice on drop mass and height needs the lever length and the inertia (the rig)"
    if not (math.isfinite(f) and f > 0 and math.isfinite(delta)):
        return "no measured frequency and decay of these drops to advise a drop mass on"
    k = rig.restitution if rig is not None else _restitution(rows, lever)
    if k is None:
        return "the advice needs the impact's restitution (the rig)"
    masses = pd.to_numeric(rows["drop_mass_kg"], errors="coerce").dropna().tolist() if "drop_mass_kg" in rows else []
    heights = pd.to_numeric(rows["drop_height_m"], errors="coerce").dropna().tolist() if "drop_height_m" in rows else []
    if not masses or not heights:
        return "the advice needs the drops' masses and heights (the conditions)"
    return double_impact_advice(j, f, delta, lever, k, masses, heights,
                                tuple(rig.drop_masses_kg) if rig is not None else ())
