"""Rig and test-plan files: validated models and loaders (SI units, unknown fields are errors).

A rig file (``rig_configs/rigs/*.toml``) describes a drop tower: lever, fixtures, limits, the
restitution of the mass-lever contact, the simulation's time step and the sensors. A test plan
(``rig_configs/doe/*.toml``) lists groups of (inertia, drop mass) crossed with drop heights,
preloads and repeats (Rapp et al. 2022, Table 2, docs/theory.md#rig); :meth:`DOE.tests` expands it into one row
per test. See ``rig_configs/rigs/rapp2022.toml`` and ``rig_configs/doe/rapp2022_table2.toml``.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
from pydantic import Field, NonNegativeFloat, NonNegativeInt, PositiveFloat, PositiveInt, PrivateAttr, model_validator

from droptower.configs import display_name, read_toml, resolve
from droptower.errors import DroptowerError, not_in_range
from droptower.limits import MAX_CAMPAIGN_TESTS, MAX_PLAN_CONDITIONS
from droptower.rates import RIG_SAMPLE_RATE_HZ
from droptower.rig.uncertainty import RigUncertainty
from droptower.units import GRAVITY_M_PER_S2
from droptower.config_validation import StrictModel, validate

if TYPE_CHECKING:
    from droptower.rheology import Coupling

# time-step limits (checked before a run; see check_time_step)
STIFFNESS_LIMIT = 0.1     # dt sqrt(K_max/J): symplectic Euler is stable below 2, accurate well below
DAMPING_LIMIT = 0.1       # dt d_max / J
PENETRATION_LIMIT = 0.1   # v1 dt / striker radius: the striker must not sink into the lever in a step
PULSE_LIMIT = 0.1         # dt / contact duration: the impact time resolved within its force pulse


#: How far a test's inertia and drop mass may lie outside the rig's fixtures (a factor either way).
FIXTURE_FACTOR = 100.0


def _range(values: list[float], what: str) -> list[float]:
    if len(values) != 2 or not values[0] <= values[1]:
        raise ValueError(f"{what} must be [min, max] with min <= max")
    return values


#: The preload's quasi-static ramp to the twist (s), on the drop tower (:mod:`droptower.rig.preload`),
#: the servo bench (:mod:`droptower.servo.bench`) and in identification's re-simulated drops.
PRELOAD_RAMP_S = 2.0
#: The hold at the preload twist before the test (s), everywhere the preload is set: long against
#: the slowest relaxation of the reference coupling (its filler network recovers with
#: tau_r = 10 s, docs/theory.md#filler-network: after 60 s within e^-6 = 0.25 % of settled). With
#: 30 s a 1 kN*m preload still moved rapp2022_nr60's decay period by 0.3 % (60 s: 4e-6), where
#: Rapp et al. 2022 (Fig. 11) see no influence of the preload.
PRELOAD_HOLD_S = 60.0


# ------------------------------------------------------------------ rig
class Simulation(StrictModel):
    """How the pymunk scene is stepped (see :mod:`droptower.rig.scene`)."""

    steps_per_sample: PositiveInt = Field(2, description="Internal simulation steps per output sample (simulation only).")
    solver_iterations: PositiveInt = Field(10, description="pymunk impulse-solver passes per step (simulation only).")
    striker_radius_m: PositiveFloat = Field(0.005, description="Radius of the drop mass's round striker, m (simulation only).")
    preload_ramp_s: PositiveFloat = Field(PRELOAD_RAMP_S, description="Quasi-static ramp to the preload twist, s (simulation only).")
    preload_hold_s: PositiveFloat = Field(PRELOAD_HOLD_S, description="Hold before the drop so rate-dependent parts relax, s "
                                                          "(simulation only).")


class Resonance(StrictModel):
    """Test-setup resonance on the force-measurement side (Rapp et al. 2022: ringing on the torque only).

    The measured torque is T + strength * (H(T) - T), H a 2nd-order low-pass of unit DC gain
    with this natural frequency and damping ratio.
    """

    frequency_hz: PositiveFloat = Field(description="Natural frequency of the setup resonance, Hz.")
    damping_ratio: PositiveFloat = Field(description="Damping ratio of the setup resonance (Lehr's D), dimensionless.")
    strength: NonNegativeFloat = Field(1.0, description="Share of the resonance in the measured torque, 0 (none) to 1.")


class Laser(StrictModel):
    """Laser distance sensor on the lever: it reads the lever's displacement at radius_m from the pivot, radius * tan(angle), plus noise."""

    radius_m: PositiveFloat = Field(description="Horizontal distance of the laser spot from the pivot, m: the angle "
                                    "is arctan(distance / radius_m). Used by extraction.")
    noise_m: NonNegativeFloat = Field(0.0, description="Standard deviation of the laser's noise, m (simulation only).")


class TorqueSensor(StrictModel):
    """Flange torque from a force sensor; ``range_nm`` is its full scale (saturates beyond)."""

    noise_nm: NonNegativeFloat = Field(0.0, description="Standard deviation of the torque noise, N*m (simulation only).")
    range_nm: PositiveFloat = Field(description="Full scale of the torque sensor, N*m: the simulated torque saturates "
                                    "beyond it.")
    resonance: Resonance | None = Field(None, description="Ringing of the setup on the torque only (table "
                                        "[sensors.torque.resonance]); none if absent.")


class ForceSensor(StrictModel):
    """Piezo impact-force sensor at the lever tip; each contact is a half-sine pulse."""

    contact_duration_s: PositiveFloat = Field(3e-4, description="Duration of one contact's half-sine force pulse, s.")
    noise_n: NonNegativeFloat = Field(0.0, description="Standard deviation of the force noise, N (simulation only).")
    range_n: PositiveFloat = Field(description="Full scale of the impact-force sensor, N (simulation only).")


class Sensors(StrictModel):
    """The rig's data acquisition: sample rate (Hz), pre-trigger time (s) and its three sensors."""

    sample_rate_hz: PositiveFloat = Field(RIG_SAMPLE_RATE_HZ, description="Sample rate of the data acquisition, Hz.")
    pre_trigger_s: PositiveFloat = Field(0.005, description="Time recorded before the impact, s (the baseline for "
                                         "offsets and preload); shorter than the fall from the lowest height.")
    laser: Laser = Field(description="Laser distance sensor on the lever (table [sensors.laser]).")
    torque: TorqueSensor = Field(description="Flange torque sensor (table [sensors.torque]).")
    impact_force: ForceSensor = Field(description="Impact-force sensor at the lever tip (table [sensors.impact_force]).")


class RigConfig(StrictModel):
    """A drop tower (Rapp et al. 2022, Table 1). SI units; angles in degrees only where named ``_deg``."""

    name: str = Field("", description="The rig's name (default: the file's stem).")
    description: str = Field("", description="One line on the rig.")
    source: str = Field("", description="Where its numbers come from (measured, drawing, paper, assumed).")
    lever_length_m: PositiveFloat = Field(description="Lever arm L from the rotation axis to the impact point, m. "
                                          "Used by extraction (impact energy, geometry checks).")
    inertias_kgm2: list[PositiveFloat] = Field(min_length=1, description="Rotating inertia J of each lever fixture "
                                               "(lever arm plus the coupling's driven side), kg*m^2. May be left out "
                                               "when [fixtures] names them.")
    fixtures: dict[str, PositiveFloat] = Field({}, description="Table [fixtures]: fixture name = its inertia J in "
                                               "kg*m^2 (e.g. L1 = 0.12); names a conditions table's fixture column "
                                               "and each result's fixture. Each must be one of inertias_kgm2.")
    drop_masses_kg: list[PositiveFloat] = Field(min_length=1, description="The rig's drop masses m1, kg.")
    drop_height_range_m: list[PositiveFloat] = Field(description="[lowest, highest] drop height h, m.")
    preload_range_nm: list[NonNegativeFloat] = Field([0.0, 0.0], description="[lowest, highest] preload torque, N*m.")
    coupling_limit_deg: PositiveFloat = Field(description="Largest twist of the coupling the rig may impose, degrees "
                                              "(planning and simulation).")
    restitution: float = Field(0.5, ge=0.0, le=1.0, description="Newton's restitution k of the mass-lever contact, "
                               "0 to 1 (impact law, docs/theory.md#impact; the impact-energy check).")
    gravity_m_per_s2: PositiveFloat = Field(GRAVITY_M_PER_S2, description="Gravitational acceleration g, m/s^2.")
    simulation: Simulation = Field(Simulation(), description="How the virtual rig is stepped (table [simulation]; "
                                   "simulation only).")
    sensors: Sensors = Field(description="Data acquisition and sensors (table [sensors]).")
    uncertainty: RigUncertainty | None = Field(
        None, description="Standard uncertainties of the rig's inputs (table [uncertainty]; "
                          "droptower.rig.uncertainty, docs/guide/uncertainty.md); not given by default.")

    @model_validator(mode="before")
    @classmethod
    def _fixture_inertias(cls, data: Any) -> Any:
        # a rig file may name its fixtures instead of listing their inertias: the list follows
        if isinstance(data, dict) and isinstance(data.get("fixtures"), dict) and data["fixtures"] \
                and "inertias_kgm2" not in data:
            data = {**data, "inertias_kgm2": list(data["fixtures"].values())}
        return data

    @model_validator(mode="after")
    def _check(self):
        _range(self.drop_height_range_m, "drop_height_range_m")
        _range(self.preload_range_nm, "preload_range_nm")
        for name, inertia in self.fixtures.items():
            if not any(math.isclose(inertia, j, rel_tol=1e-9) for j in self.inertias_kgm2):
                raise ValueError(f"fixture '{name}' ({inertia:g} kg*m^2) is not one of inertias_kgm2 "
                                 f"({', '.join(f'{j:g}' for j in self.inertias_kgm2)}); give one of them or [fixtures] alone")
        return self

    def fixture_inertia_kgm2(self, name: str) -> float:
        """The inertia (kg*m^2) of the fixture called ``name``; a name the rig does not have is a
        :class:`DroptowerError` listing its fixtures."""
        if name not in self.fixtures:
            have = ", ".join(f"{n} ({j:g} kg*m^2)" for n, j in self.fixtures.items()) or "none named"
            raise self.error(f"no fixture '{name}' (fixtures: {have})", "field fixtures")
        return float(self.fixtures[name])

    def fixture_name(self, inertia_kgm2: float) -> str | None:
        """The name of the fixture whose inertia is ``inertia_kgm2`` (kg*m^2, within 0.5 %), or
        None (no named fixture has it)."""
        for name, inertia in self.fixtures.items():
            if math.isclose(inertia, inertia_kgm2, rel_tol=0.005):
                return name
        return None

    _path: Path | None = PrivateAttr(None)  # the file it came from (set by the loader)

    @property
    def path(self) -> Path | None:
        return self._path

    # -- derived
    @property
    def dt_s(self) -> float:
        """Internal step of the simulation (s)."""
        return 1.0 / (self.sensors.sample_rate_hz * self.simulation.steps_per_sample)

    @property
    def coupling_limit_rad(self) -> float:
        return math.radians(self.coupling_limit_deg)

    @property
    def is_preset(self) -> bool:
        """True for a rig shipped with droptower (``rapp2022``), not a lab's own file."""
        return self.path is not None and display_name(self.path, "rigs") != str(self.path)

    def geometry_text(self) -> str:
        """The geometry extraction takes from this rig, on one line: where it came from, lever
        length, laser radius and fixtures."""
        origin = f"shipped preset {self.label}" if self.is_preset else f"rig file {self.label}"
        fixtures = (", ".join(f"{n} {j:g}" for n, j in self.fixtures.items()) if self.fixtures
                    else ", ".join(f"{j:g}" for j in self.inertias_kgm2))
        return (f"{origin}: lever length {self.lever_length_m:g} m, laser radius {self.sensors.laser.radius_m:g} m, "
                f"fixtures {fixtures} kg*m^2")

    @property
    def label(self) -> str:
        """The rig as messages name it: a shipped preset by its name, a file by its path."""
        return display_name(self.path, "rigs") or self.name or "rig"

    def error(self, problem: str, where: str) -> DroptowerError:
        """A one-line error attributed to this rig file and a field."""
        return DroptowerError(problem, file=self.label, where=where)

    def check_test(self, inertia_kgm2: float, drop_mass_kg: float, drop_height_m: float, preload_nm: float,
                   *, file: str | Path | None = None, where: str = "",
                   labels: dict[str, str] | None = None) -> None:
        """Reject a test this rig cannot run: non-positive values, height or preload out of range.

        The error names ``file`` and ``where`` plus the field (``labels`` renames fields, e.g.
        ``{"drop_height_m": "height"}``: a caller's own names for its values).
        """
        labels = labels or {}

        def at(name: str) -> str:
            return f"{where}: {labels.get(name, name)}" if where else labels.get(name, name)

        for name, value in (("inertia_kgm2", inertia_kgm2), ("drop_mass_kg", drop_mass_kg),
                            ("drop_height_m", drop_height_m)):
            if not (math.isfinite(value) and value > 0):
                raise not_in_range(value, at(name), file=file)
        # far outside the rig's own levers and masses the impact law and the time step overflow
        for name, value, fixtures, unit in (("inertia_kgm2", inertia_kgm2, self.inertias_kgm2, "kg*m^2"),
                                            ("drop_mass_kg", drop_mass_kg, self.drop_masses_kg, "kg")):
            lo, hi = min(fixtures) / FIXTURE_FACTOR, max(fixtures) * FIXTURE_FACTOR
            if not lo <= value <= hi:
                raise DroptowerError(f"{value:g} {unit} is outside {lo:.3g}-{hi:.3g} {unit}, 1/{FIXTURE_FACTOR:g} to "
                                     f"{FIXTURE_FACTOR:g} times the fixtures of rig {self.label}",
                                     file=file, where=at(name))
        lo, hi = self.drop_height_range_m
        if not lo <= drop_height_m <= hi:
            raise DroptowerError(f"drop height {drop_height_m:g} m is outside the range {lo:g}-{hi:g} m of rig "
                                 f"{self.label} (field drop_height_range_m)", file=file,
                                 where=at("drop_height_m"))
        lo, hi = self.preload_range_nm
        if not (math.isfinite(preload_nm) and lo <= preload_nm <= hi):
            raise DroptowerError(f"preload {preload_nm:g} N*m is outside the range {lo:g}-{hi:g} N*m of rig "
                                 f"{self.label} (field preload_range_nm)", file=file,
                                 where=at("preload_nm"))

    def check_time_step(self, coupling: "Coupling", inertia_kgm2: np.ndarray, pretwist_rad: np.ndarray,
                            impact_velocity_m_per_s: np.ndarray) -> None:
        """Reject an internal step too coarse for the coupling or the impact (error names the rig field)."""
        dt = self.dt_s
        where = "field simulation.steps_per_sample"
        j_min = float(np.min(inertia_kgm2))
        name = display_name(coupling.path, "couplings") or coupling.name or "the coupling"
        stiffness = coupling.max_tangent_stiffness(self.coupling_limit_rad + float(np.max(np.abs(pretwist_rad))),
                                                   step_s=dt)
        omega_dt = dt * math.sqrt(stiffness / j_min)
        if omega_dt > STIFFNESS_LIMIT:
            need = math.ceil(self.simulation.steps_per_sample * omega_dt / STIFFNESS_LIMIT)
            raise self.error(f"internal step {dt:.3g} s is too coarse for the stiffness of {name} "
                             f"({stiffness:.4g} N*m/rad on J = {j_min:g} kg*m^2): dt*sqrt(K/J) = {omega_dt:.3g} > "
                             f"{STIFFNESS_LIMIT}; use steps_per_sample >= {need}", where)
        # a rate-independent loss (the payne element's K''/w) damps by the frequency of the motion:
        # the lever's swing, a tenth of its frequency on the stiffest coupling leaving room for
        # the coupling's softening with amplitude (a hundredfold in stiffness)
        lever_hz = math.sqrt(stiffness / float(np.max(inertia_kgm2))) / (2 * math.pi)
        damping_dt = dt * coupling.max_damping(min_frequency_hz=0.1 * lever_hz, step_s=dt) / j_min
        if damping_dt > DAMPING_LIMIT:
            need = math.ceil(self.simulation.steps_per_sample * damping_dt / DAMPING_LIMIT)
            raise self.error(f"internal step {dt:.3g} s is too coarse for the damping of {name}: dt*d/J = "
                             f"{damping_dt:.3g} > {DAMPING_LIMIT}; use steps_per_sample >= {need}", where)
        sink = float(np.max(impact_velocity_m_per_s)) * dt / self.simulation.striker_radius_m
        if sink > PENETRATION_LIMIT:
            need = math.ceil(self.simulation.steps_per_sample * sink / PENETRATION_LIMIT)
            raise self.error(f"internal step {dt:.3g} s is too coarse for the impact: the drop mass moves "
                             f"{sink:.2g} striker radii per step (> {PENETRATION_LIMIT}); use steps_per_sample >= {need}",
                             where)
        pulse = dt / self.sensors.impact_force.contact_duration_s
        if pulse > PULSE_LIMIT:
            need = math.ceil(self.simulation.steps_per_sample * pulse / PULSE_LIMIT)
            raise self.error(f"internal step {dt:.3g} s is too coarse for the impact: more than {PULSE_LIMIT} of the "
                             f"contact duration; use steps_per_sample >= {need}", where)


def load_rig(path_or_name: str | Path) -> RigConfig:
    """Load a rig TOML file, or a shipped preset by name.

    Parameters
    ----------
    path_or_name : str or Path
        A rig TOML file, or the name of a shipped preset (``"rapp2022"``).

    Returns
    -------
    RigConfig
        The validated rig: levers and masses (SI), drop-height and preload ranges, sensors,
        simulation settings.

    Raises
    ------
    DroptowerError
        One line naming the file and the field, for a missing file or an invalid value.
    """
    path = resolve(path_or_name, "rigs")
    data = read_toml(path)
    rig = validate(RigConfig, data, path)
    rig._path = path
    rig.name = rig.name or path.stem
    check_pre_trigger(rig)
    return rig


def check_pre_trigger(rig: RigConfig) -> None:
    """The pre-trigger must be shorter than the fall from the lowest drop height (else a one-line
    error naming the field)."""
    fall_time = math.sqrt(2 * rig.drop_height_range_m[0] / rig.gravity_m_per_s2)
    if rig.sensors.pre_trigger_s >= fall_time:
        raise rig.error(f"pre-trigger {rig.sensors.pre_trigger_s} s must be shorter than the fall time "
                        f"{fall_time:.4g} s from the lowest drop height", "field sensors.pre_trigger_s")


# ------------------------------------------------------------------ test plan
class Group(StrictModel):
    """One (inertia, drop mass) combination; heights, preloads, repeats default to the plan's."""

    name: str = ""
    inertia_kgm2: PositiveFloat
    drop_mass_kg: PositiveFloat
    heights_m: list[PositiveFloat] | None = Field(None, min_length=1)
    preloads_nm: list[NonNegativeFloat] | None = Field(None, min_length=1)
    repeats: PositiveInt | None = None


class DOE(StrictModel):
    """A test plan: every group x heights x preloads x repeats (Rapp et al. 2022, Table 2)."""

    name: str = ""
    description: str = ""
    source: str = ""
    base_seed: NonNegativeInt = 0
    repeats: PositiveInt = 1
    heights_m: list[PositiveFloat] = Field(min_length=1)
    preloads_nm: list[NonNegativeFloat] = [0.0]
    group: list[Group] = Field(min_length=1)

    _path: Path | None = PrivateAttr(None)

    @property
    def path(self) -> Path | None:
        return self._path

    @property
    def n_conditions(self) -> int:
        """Number of test conditions (group x heights x preloads), counted without expanding them."""
        return sum(len(g.heights_m or self.heights_m) * len(g.preloads_nm or self.preloads_nm) for g in self.group)

    @property
    def n_tests(self) -> int:
        """Number of tests (conditions x repeats), counted without expanding them."""
        return sum(len(g.heights_m or self.heights_m) * len(g.preloads_nm or self.preloads_nm)
                   * (g.repeats or self.repeats) for g in self.group)

    def tests(self) -> pd.DataFrame:
        """One row per test: test_id, case, inertia_kgm2, drop_mass_kg, drop_height_m,
        preload_nm, repeat (0-based), seed (base_seed + test_id). At most
        :data:`~droptower.limits.MAX_CAMPAIGN_TESTS` rows (else a one-line error)."""
        if self.n_tests > MAX_CAMPAIGN_TESTS:
            raise DroptowerError(f"{self.n_tests} tests (groups x heights x preloads x repeats) exceed the limit of "
                                 f"{MAX_CAMPAIGN_TESTS} per campaign: split the plan into several files (e.g. by "
                                 "group or height range) and run one campaign folder each", file=display_name(self.path, "doe"))
        rows = []
        for i, g in enumerate(self.group):
            for h in g.heights_m or self.heights_m:
                for p in g.preloads_nm or self.preloads_nm:
                    for r in range(g.repeats or self.repeats):
                        rows.append((g.name or f"group {i + 1}", g.inertia_kgm2, g.drop_mass_kg, h, p, r))
        df = pd.DataFrame(rows, columns=["case", "inertia_kgm2", "drop_mass_kg", "drop_height_m", "preload_nm",
                                         "repeat"])
        df.insert(0, "test_id", range(len(df)))
        df["seed"] = self.base_seed + df["test_id"]
        return df

    def conditions(self) -> pd.DataFrame:
        """The distinct test conditions (repeats collapsed), with their number of repeats."""
        rows = [(g.name or f"group {i + 1}", g.inertia_kgm2, g.drop_mass_kg, h, p, g.repeats or self.repeats)
                for i, g in enumerate(self.group)
                for h in g.heights_m or self.heights_m for p in g.preloads_nm or self.preloads_nm]
        keys = ["case", "inertia_kgm2", "drop_mass_kg", "drop_height_m", "preload_nm"]
        # a condition listed twice (a height given twice) is one condition with the repeats of both
        return pd.DataFrame(rows, columns=[*keys, "repeats"]).groupby(keys, sort=False)["repeats"].sum().reset_index()

    def check(self, rig: RigConfig) -> None:
        """Every test must be runnable on ``rig`` (else a one-line error naming this file and group)."""
        for i, g in enumerate(self.group):
            for h in g.heights_m or self.heights_m:
                for p in g.preloads_nm or self.preloads_nm:
                    rig.check_test(g.inertia_kgm2, g.drop_mass_kg, h, p, file=display_name(self.path, "doe"),
                                   where=f"group {i + 1} ({g.name})" if g.name else f"group {i + 1}",
                                   labels={"drop_height_m": "heights_m", "preload_nm": "preloads_nm"})


def _name_group(list_name: str, index: int, item: Any) -> str:
    name = item.get("name") if isinstance(item, dict) else None
    return f"{list_name} {index + 1} ({name})" if name else f"{list_name} {index + 1}"


def load_doe(path_or_name: str | Path) -> DOE:
    """Load a test-plan (DOE) TOML file, or a shipped preset by name.

    Parameters
    ----------
    path_or_name : str or Path
        A test-plan TOML file, or the name of a shipped preset (``"rapp2022_table2"``).

    Returns
    -------
    DOE
        The plan: lever groups (inertia in kg·m², drop mass in kg) × drop heights (m) × preloads
        (N·m) × repeats; :meth:`DOE.tests` lists its tests.

    Raises
    ------
    DroptowerError
        One line naming the file, for a missing file, an invalid value or a plan of more than
        :data:`~droptower.limits.MAX_PLAN_CONDITIONS` conditions.
    """
    path = resolve(path_or_name, "doe")
    doe = validate(DOE, read_toml(path), path, _name_group)
    if doe.n_conditions > MAX_PLAN_CONDITIONS:  # before anything loops over them
        raise DroptowerError(f"{doe.n_conditions} test conditions (groups x heights x preloads) exceed the limit of "
                             f"{MAX_PLAN_CONDITIONS} per plan: split the plan into several files (e.g. by group or "
                             "height range)", file=path)
    doe._path = path
    doe.name = doe.name or path.stem
    return doe
