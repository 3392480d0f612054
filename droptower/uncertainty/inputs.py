"""A drop's inputs: the rig's stated uncertainties (:class:`~droptower.rig.uncertainty.RigUncertainty`)
resolved for one drop, with the nominal values the extraction used (GUM 4.1, the input quantities X_i).

An input is *given* when its uncertainty is stated; one not stated is listed as *not given*
and left out of the combined uncertainty (a budget never counts it as zero silently).
Calibrations are factors (reading / true value) of nominal 1 whose standard uncertainty is the
relative one; the others carry the unit in their name.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from droptower.errors import DroptowerError, expects
from droptower.rig.uncertainty import InputUncertainty, RigUncertainty

#: the inputs, in the order a budget lists them: name -> unit
INPUTS: dict[str, str] = {
    "inertia_kgm2": "kg*m^2", "lever_length_m": "m", "laser_radius_m": "m", "drop_mass_kg": "kg",
    "drop_height_m": "m", "torque_calibration_rel": "1", "laser_calibration_rel": "1",
    "force_calibration_rel": "1", "sample_rate_hz": "Hz",
}


@dataclass(frozen=True)
class Input:
    """One given input of one drop: its name (a key of :data:`INPUTS`), nominal value (SI, 1 for
    a calibration factor), standard uncertainty u (same unit) and distribution."""

    name: str
    nominal: float
    standard_uncertainty: float
    distribution: Literal["normal", "rectangular"] = "normal"

    @property
    def half_width(self) -> float:
        """Half-width a of a rectangular input, a = √3·u (GUM 4.3.7); NaN for a normal one."""
        return math.sqrt(3.0) * self.standard_uncertainty if self.distribution == "rectangular" else math.nan


@dataclass(frozen=True)
class DropInputs:
    """The inputs of one drop: ``given`` (name -> :class:`Input`), the names ``not_given`` (no
    uncertainty stated) and ``unused``: a drop mass or height stated for the rig but without a
    nominal value for this drop (its log carries none: its impact energy came from the force
    impulse, which they do not enter)."""

    given: dict[str, Input]
    not_given: tuple[str, ...]
    unused: tuple[str, ...] = ()


@expects(uncertainty=(RigUncertainty, type(None)))
def drop_inputs(uncertainty: RigUncertainty | None, *, inertia_kgm2: float, lever_length_m: float | None = None,
                laser_radius_m: float | None = None, drop_mass_kg: float | None = None,
                drop_height_m: float | None = None, sample_rate_hz: float | None = None) -> DropInputs:
    """Resolve the rig's stated uncertainties for one drop.

    Parameters
    ----------
    uncertainty : RigUncertainty or None
        The rig's input uncertainties (None: none given).
    inertia_kgm2 : float
        The drop's lever inertia J (kg·m²), the fixture whose entry applies.
    lever_length_m, laser_radius_m, drop_mass_kg, drop_height_m : float, optional
        The nominal values the extraction used (m, m, kg, m); an input whose uncertainty is given
        needs its nominal value (a relative uncertainty u/x needs x).
    sample_rate_hz : float, optional
        The log's nominal sample rate (Hz).

    Returns
    -------
    DropInputs
        The given inputs with nominal value, standard uncertainty and distribution; the rest
        named as not given (or unused).

    Raises
    ------
    DroptowerError
        An uncertainty is given for an input whose nominal value is not known (but a drop mass
        or height: those are ``unused``).
    """
    u = uncertainty or RigUncertainty()
    stated: dict[str, tuple[InputUncertainty | None, float | None]] = {
        "inertia_kgm2": (u.inertia(inertia_kgm2), inertia_kgm2),
        "lever_length_m": (u.lever_length_m, lever_length_m),
        "laser_radius_m": (u.laser_radius_m, laser_radius_m),
        "drop_mass_kg": (u.drop_mass(drop_mass_kg) if drop_mass_kg is not None else
                         (u.drop_masses_kg[0] if u.drop_masses_kg else None), drop_mass_kg),
        "drop_height_m": (u.drop_height_m, drop_height_m),
        "torque_calibration_rel": (u.torque_calibration_rel, 1.0),
        "laser_calibration_rel": (u.laser_calibration_rel, 1.0),
        "force_calibration_rel": (u.force_calibration_rel, 1.0),
        "sample_rate_hz": (u.sample_rate_hz, sample_rate_hz),
    }
    given, not_given, unused = {}, [], []
    for name, (entry, nominal) in stated.items():
        if entry is None:
            not_given.append(name)
            continue
        if nominal is None and name in ("drop_mass_kg", "drop_height_m"):
            unused.append(name)
            continue
        if nominal is None or not (math.isfinite(nominal) and nominal > 0):
            raise DroptowerError(f"the uncertainty of `{name}` is given but not its nominal value: give `{name}`",
                                 where=name)
        given[name] = Input(name, float(nominal), entry.standard, entry.distribution)
    return DropInputs(given, tuple(not_given), tuple(unused))
