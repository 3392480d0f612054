"""The servo-hydraulic points a map is validated against: the sweeps of docs/theory.md#servo run on the
virtual servo bench, or measured servo results read from a table.

Both give a *servo table*, one row per (sweep, point):

- ``sweep``: ``frequency`` (a frequency sweep at constant amplitude) or ``amplitude``;
- ``amplitude_deg``, ``frequency_hz``: the point;
- ``servo_stiffness_nm_per_deg``: the stiffness compared with the map (see ``stiffness_definition``);
- ``servo_damping_ratio``: the drop tower's damping ratio d = E_diss / E_el of the linear
  Kelvin-Voigt coupling with the servo's loss factor (docs/theory.md#damping-measures,
  :func:`droptower.sdof.drop_tower_equivalent_damping_ratio`): the map's damping is the drop
  tower's d_ratio (Rapp et al. 2022, eq. 16), so it is compared with this, like with like;
- ``servo_loss_factor`` (eta = K''/K') and ``servo_relative_damping_psi`` (psi = W_D / W_el,
  DIN 740-2), reported alongside; ``servo_dynamic_stiffness_nm_per_deg`` (|K*|) when known.

Measured results (CSV or Parquet), accepted columns (units in the names):

- required: ``amplitude_deg`` (or ``amplitude_rad``) and ``frequency_hz``;
- stiffness, the first present of ``storage_stiffness_nm_per_deg``,
  ``storage_stiffness_nm_per_rad`` (K', preferred: the drop tower's c = J(omega^2 + delta^2) is
  K' of the equivalent Kelvin-Voigt coupling), ``dynamic_stiffness_nm_per_deg``,
  ``dynamic_stiffness_nm_per_rad`` (|K*| = K' sqrt(1 + eta^2));
- damping, the first present of ``drop_tower_equivalent_damping_ratio``, ``loss_factor``,
  ``loss_angle_deg`` (eta = tan), ``relative_damping_psi`` (eta from psi = 2 pi eta / sqrt(1 + eta^2),
  the linear coupling's DIN 740-2 value);
- optional ``sweep`` (``frequency`` or ``amplitude``); without it each point goes to the sweep
  with more points through it (its amplitude's frequencies vs. its frequency's amplitudes).

The servo bench's JSON saved as a table, and the ``servo_results.csv`` that
:func:`~droptower.compare.files.write_validation` writes, are accepted as they are. Results of a translational
servo test (``amplitude_mm``, ``storage_stiffness_n_per_m``, ...: a mount, bushing or damper)
are recognised and refused with the reason: the map is the torsional drop tower's, and no
lever turns a displacement into its angle.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from droptower import sdof
from droptower.errors import DroptowerError
from droptower.io.fields import field_name
from droptower.io.table_reader import COMMON_ALIASES, read_table
from droptower.rates import SERVO_SAMPLE_RATE_HZ

#: docs/theory.md#servo: frequency sweeps at these amplitudes (deg) up to these frequencies (Hz) ...
FREQUENCY_SWEEPS = {0.5: 100.0, 1.5: 60.0, 2.5: 20.0}
#: ... and amplitude sweeps at these frequencies (Hz) up to these amplitudes (deg).
AMPLITUDE_SWEEPS = {1.0: 10.0, 10.0: 6.0, 30.0: 2.0}
#: Sweep steps (each sweep is cut at its maximum, which is always a step). The grids hold the
#: other sweeps' constants (1, 10, 30 Hz; 0.5, 1.5, 2.5 deg), so the sweeps cross at points.
FREQUENCY_STEPS_HZ = (1.0, 2.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0, 100.0)
AMPLITUDE_STEPS_DEG = (0.1, 0.2, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0)
#: Fewer steps for a quick run (CI's reduced study).
REDUCED_FREQUENCY_STEPS_HZ = (1.0, 10.0, 30.0, 60.0, 100.0)
REDUCED_AMPLITUDE_STEPS_DEG = (0.2, 0.5, 1.5, 2.5, 6.0, 10.0)

STIFFNESS_COLUMNS = ("storage_stiffness_nm_per_deg", "storage_stiffness_nm_per_rad", "dynamic_stiffness_nm_per_deg",
                     "dynamic_stiffness_nm_per_rad")
DAMPING_COLUMNS = ("drop_tower_equivalent_damping_ratio", "loss_factor", "loss_angle_deg", "relative_damping_psi")
SERVO_COLUMNS = ("sweep", "amplitude_deg", "frequency_hz", "servo_stiffness_nm_per_deg", "servo_damping_ratio",
                 "servo_loss_factor", "servo_relative_damping_psi", "servo_dynamic_stiffness_nm_per_deg")


@dataclass(frozen=True)
class ServoPoints:
    """A servo table (module docstring) and where it came from.

    stiffness_definition / damping_definition: which servo quantity the columns hold, in words;
    raw: the bench's full table (every :func:`droptower.servo.run_grid` column plus ``sweep``)
    or the file as read: readable again by :func:`read_servo_results`.
    """

    table: pd.DataFrame
    source: str
    stiffness_definition: str
    damping_definition: str
    raw: pd.DataFrame


def sweep_points(reduced: bool = False) -> pd.DataFrame:
    """The (sweep, amplitude_deg, frequency_hz) rows of the docs/theory.md#servo sweeps."""
    f_steps = REDUCED_FREQUENCY_STEPS_HZ if reduced else FREQUENCY_STEPS_HZ
    a_steps = REDUCED_AMPLITUDE_STEPS_DEG if reduced else AMPLITUDE_STEPS_DEG
    rows = []
    for amplitude, f_max in FREQUENCY_SWEEPS.items():
        rows += [("frequency", amplitude, f) for f in sorted({*(f for f in f_steps if f <= f_max), f_max})]
    for frequency, a_max in AMPLITUDE_SWEEPS.items():
        rows += [("amplitude", a, frequency) for a in sorted({*(a for a in a_steps if a <= a_max), a_max})]
    return pd.DataFrame(rows, columns=["sweep", "amplitude_deg", "frequency_hz"])


def run_sweeps(coupling, reduced: bool = False, sample_rate_hz: float = SERVO_SAMPLE_RATE_HZ) -> ServoPoints:
    """Run the sweeps on the virtual servo bench (:func:`droptower.servo.run_grid`), each
    distinct point once: per frequency one batch of all its amplitudes."""
    from droptower.rheology import Coupling, load_coupling
    from droptower.servo import run_grid

    model = coupling if isinstance(coupling, Coupling) else load_coupling(coupling)
    if model.units == "translational":
        raise DroptowerError(f"{model.name} is a translational coupling: the sweeps are the torsional drop tower's "
                             "(amplitudes in deg); run it on the servo bench in its own units instead (droptower.servo.run_grid, "
                             "amplitudes in m)")
    points = sweep_points(reduced)
    runs = []
    for frequency, rows in points.groupby("frequency_hz"):
        amplitudes = np.sort(rows["amplitude_deg"].unique())
        runs.append(run_grid(model, np.radians(amplitudes), [float(frequency)], sample_rate_hz=sample_rate_hz))
    bench = pd.concat(runs, ignore_index=True)
    bench["amplitude_deg"] = bench["amplitude_deg"].round(9)
    table = points.merge(bench, on=["amplitude_deg", "frequency_hz"], how="left", validate="many_to_one")
    servo = _servo_table(table, "storage_stiffness_nm_per_deg", "drop_tower_equivalent_damping_ratio")
    return ServoPoints(servo, f"virtual servo bench, coupling {model.name}", *_definitions(
        "storage_stiffness_nm_per_deg", "drop_tower_equivalent_damping_ratio"), raw=table)


def read_servo_results(path: str | Path, columns: dict[str, str] | None = None) -> ServoPoints:
    """Measured servo results (columns in the module docstring) read as
    :func:`droptower.io.table_reader.read_table` reads tables: any delimiter, decimal comma,
    units row or ``Name [unit]``, lab names (``Amplitude [°]; Frequenz [Hz]; Verlustfaktor``),
    ``columns`` mapping NAME -> SOURCE[:UNIT]; problems are one-line errors."""
    path = Path(path)
    translational = {field_name(name, "translational"): () for name in SERVO_COLUMNS} | {"amplitude_m": ()}
    translational = {k: v for k, v in translational.items() if k not in SERVO_COLUMNS}
    raw = read_table(path, {**SERVO_COLUMNS, **translational}, columns, what="servo results").copy()
    found = [c for c in translational if c in raw.columns]
    if found:
        raise DroptowerError(f"translational servo results ({', '.join(found)}): the map is the torsional drop "
                             "tower's and cannot be compared with a displacement test; identify a model from the "
                             "translational records instead (droptower identify, droptower servo)", file=path)
    if "amplitude_deg" not in raw.columns and "amplitude_rad" in raw.columns:
        raw["amplitude_deg"] = np.degrees(pd.to_numeric(raw["amplitude_rad"], errors="coerce"))
    stiffness = next((c for c in STIFFNESS_COLUMNS if c in raw.columns), None)
    damping = next((c for c in DAMPING_COLUMNS if c in raw.columns), None)
    missing = [c for c in ("amplitude_deg", "frequency_hz") if c not in raw.columns]
    if stiffness is None:
        missing.append(f"a stiffness column ({' or '.join(STIFFNESS_COLUMNS)})")
    if damping is None:
        missing.append(f"a damping column ({' or '.join(DAMPING_COLUMNS)})")
    if missing:
        raise DroptowerError(f"servo results lack {'; '.join(missing)} (has: {', '.join(map(str, raw.columns)) or 'none'})",
                             file=path)
    for column in ("amplitude_deg", "frequency_hz", stiffness, damping):
        values = pd.to_numeric(raw[column], errors="coerce").to_numpy(float)
        bad = ~np.isfinite(values) | ((values < 0) if column == damping else (values <= 0))
        if bad.any():
            row = int(np.argmax(bad))
            raise DroptowerError(f"column {column}: row {row + 1} is not a {'non-negative' if column == damping else 'positive'} "
                                 f"number ('{raw[column].iloc[row]}')", file=path)
        raw[column] = values
    if "sweep" in raw.columns:
        kinds = raw["sweep"].astype(str).str.strip().str.lower().str.replace(" sweep", "", regex=False)
        if not kinds.isin(["frequency", "amplitude"]).all():
            bad = raw["sweep"][~kinds.isin(["frequency", "amplitude"])].iloc[0]
            raise DroptowerError(f"column sweep: {bad!r} is neither 'frequency' nor 'amplitude'", file=path)
        raw["sweep"] = kinds
    else:
        raw["sweep"] = _infer_sweeps(raw["amplitude_deg"].to_numpy(float), raw["frequency_hz"].to_numpy(float))
    return ServoPoints(_servo_table(raw, stiffness, damping), str(path), *_definitions(stiffness, damping), raw=raw)


#: the columns read_servo_results looks for, with the names labs give them
SERVO_COLUMNS: dict[str, tuple[str, ...]] = {
    "amplitude_deg": COMMON_ALIASES["amplitude_deg"], "amplitude_rad": (),
    "frequency_hz": COMMON_ALIASES["frequency_hz"],
    "storage_stiffness_nm_per_deg": ("storage stiffness", "k'", "speichersteifigkeit", "c'"),
    "storage_stiffness_nm_per_rad": (),
    "dynamic_stiffness_nm_per_deg": ("dynamic stiffness", "|k*|", "k*", "dynamische steifigkeit"),
    "dynamic_stiffness_nm_per_rad": (),
    "drop_tower_equivalent_damping_ratio": (),
    "loss_factor": ("loss factor", "verlustfaktor", "eta", "tan delta"),
    "loss_angle_deg": ("loss angle", "verlustwinkel"),
    "relative_damping_psi": ("relative damping", "psi", "relative dämpfung", "verhältnismäßige dämpfung"),
    "sweep": ("sweep type", "versuchsart"),
}


def _infer_sweeps(amplitude: np.ndarray, frequency: np.ndarray) -> list[str]:
    a, f = np.round(amplitude, 6), np.round(frequency, 6)
    per_amplitude = pd.Series(f).groupby(a).nunique()
    per_frequency = pd.Series(a).groupby(f).nunique()
    return ["frequency" if per_amplitude[x] >= per_frequency[y] else "amplitude" for x, y in zip(a, f)]


def _eta_from(table: pd.DataFrame, damping: str) -> np.ndarray:
    """Loss factor eta from whichever damping column the table has (docs/theory.md#damping-measures)."""
    values = table[damping].to_numpy(float)
    if damping == "loss_factor":
        return values
    if damping == "loss_angle_deg":
        return np.tan(np.radians(values))
    if damping == "relative_damping_psi":  # psi = 2 pi eta / sqrt(1 + eta^2) for a linear coupling (DIN 740-2)
        with np.errstate(invalid="ignore"):
            return values / np.sqrt(4 * math.pi**2 - values**2)
    # the drop-tower-equivalent d: back to r = delta/omega (eq. 16 inverted), then eta = 2r / (1 + r^2)
    return sdof.loss_factor(sdof.decay_ratio(values), 1.0)


def _servo_table(table: pd.DataFrame, stiffness: str, damping: str) -> pd.DataFrame:
    eta = table["loss_factor"].to_numpy(float) if "loss_factor" in table.columns else _eta_from(table, damping)
    c = table[stiffness].to_numpy(float) * (math.pi / 180.0 if stiffness.endswith("_per_rad") else 1.0)
    if "dynamic_stiffness_nm_per_deg" in table.columns:
        dynamic = table["dynamic_stiffness_nm_per_deg"].to_numpy(float)
    elif "dynamic_stiffness_nm_per_rad" in table.columns:
        dynamic = np.radians(table["dynamic_stiffness_nm_per_rad"].to_numpy(float))
    elif stiffness.startswith("storage"):
        dynamic = c * np.sqrt(1 + eta**2)
    else:
        dynamic = c
    d = (table[damping].to_numpy(float) if damping == "drop_tower_equivalent_damping_ratio"
         else sdof.drop_tower_equivalent_damping_ratio(eta))
    psi = (table["relative_damping_psi"].to_numpy(float) if "relative_damping_psi" in table.columns
           else sdof.relative_damping(sdof.decay_ratio_from_loss_factor(eta), 1.0))
    out = pd.DataFrame({"sweep": table["sweep"].to_numpy(), "amplitude_deg": table["amplitude_deg"].to_numpy(float),
                        "frequency_hz": table["frequency_hz"].to_numpy(float), "servo_stiffness_nm_per_deg": c,
                        "servo_damping_ratio": d, "servo_loss_factor": eta, "servo_relative_damping_psi": psi,
                        "servo_dynamic_stiffness_nm_per_deg": dynamic})
    return out.sort_values(["sweep", "amplitude_deg", "frequency_hz"], kind="stable", ignore_index=True)


def _definitions(stiffness: str, damping: str) -> tuple[str, str]:
    stiffness_text = {
        "storage_stiffness_nm_per_deg": "storage stiffness K' (first harmonic)",
        "storage_stiffness_nm_per_rad": "storage stiffness K' (first harmonic)",
        "dynamic_stiffness_nm_per_deg": "dynamic stiffness |K*| (no K' given)",
        "dynamic_stiffness_nm_per_rad": "dynamic stiffness |K*| (no K' given)",
    }[stiffness]
    source = {"drop_tower_equivalent_damping_ratio": "given", "loss_factor": "from the loss factor",
              "loss_angle_deg": "from the loss angle", "relative_damping_psi": "from psi"}[damping]
    return (f"map stiffness (Rapp et al. 2022, eq. 19, c = J(omega^2 + delta^2)) vs servo {stiffness_text}",
            "damping ratio d = E_diss/E_el of the drop tower (Rapp et al. 2022, eq. 16): map vs the servo's "
            f"drop-tower-equivalent d of the linear coupling with its loss factor eta ({source}; docs/theory.md#damping-measures)")
