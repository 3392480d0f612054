"""The rig's input uncertainties: what a calibration certificate or a tolerance says about each
quantity the extraction takes as known (GUM, JCGM 100:2008, 4.3; docs/guide/uncertainty.md).

A rig file states them in its ``[uncertainty]`` table; every one is optional and defaults to
*not given* (None): nothing is invented, and a budget lists what was not given instead of
counting it as zero. Each is one :class:`InputUncertainty`: a ``value`` and the ``distribution``
it belongs to, ``"normal"`` (``value`` is the standard uncertainty u) or ``"rectangular"``
(``value`` is the half-width a of the interval the true value lies in, u = a/√3, GUM 4.3.7).
Absolute inputs carry the unit in their name (``lever_length_m``); calibrations are relative
(``torque_calibration_rel``: 0.005 is 0.5 % of the reading). Fixtures (lever inertias, drop
masses) are listed with the nominal value they belong to, so the table reads on its own::

    [uncertainty]
    lever_length_m = { value = 0.0005, distribution = "rectangular" }
    laser_radius_m = { value = 0.0002 }
    inertias_kgm2 = [{ nominal = 0.359, value = 0.0036 }, { nominal = 0.5233, value = 0.005 }]
    drop_masses_kg = [{ nominal = 2.0, value = 0.002, distribution = "rectangular" }]
    drop_height_m = { value = 0.001 }
    torque_calibration_rel = { value = 0.005 }
    laser_calibration_rel = { value = 0.002, distribution = "rectangular" }
    sample_rate_hz = { value = 0.4 }
"""
from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, NonNegativeFloat, PositiveFloat

from droptower.config_validation import StrictModel

#: relative tolerance within which a drop's inertia or mass is the fixture of an entry's ``nominal``
FIXTURE_MATCH_REL = 1e-6


class InputUncertainty(StrictModel):
    """One input's uncertainty: ``value`` in the input's unit (relative for ``*_rel``) and the
    distribution assumed for the input (GUM 4.3)."""

    value: NonNegativeFloat = Field(description="normal: the standard uncertainty u; rectangular: the half-width a "
                                                "(u = a/sqrt(3)); in the input's unit, relative for *_rel inputs")
    distribution: Literal["normal", "rectangular"] = Field(
        "normal", description="the input's distribution: 'normal' (value = u) or 'rectangular' (value = half-width a)")
    source: str = Field("", description="where the figure comes from (a certificate, a tolerance); free text")

    @property
    def standard(self) -> float:
        """The standard uncertainty u: ``value`` (normal) or ``value``/√3 (rectangular, GUM 4.3.7)."""
        return self.value if self.distribution == "normal" else self.value / math.sqrt(3.0)


class FixtureUncertainty(InputUncertainty):
    """The uncertainty of one fixture (a lever inertia, a drop mass), named by its ``nominal`` value."""

    nominal: PositiveFloat = Field(description="the fixture's nominal value (as the rig and the logs give it), SI")


class RigUncertainty(StrictModel):
    """The standard uncertainties of the rig's inputs; each None (the default) is *not given*.

    Python takes the same model as the rig file's ``[uncertainty]`` table:
    ``RigUncertainty(inertias_kgm2=[FixtureUncertainty(nominal=0.359, value=0.0036)])``.
    """

    inertias_kgm2: list[FixtureUncertainty] | None = Field(
        None, description="each lever fixture's moment of inertia J (kg*m^2), by its nominal value; the stiffness "
                          "c = J(w^2 + d^2) and the impact energy carry it")
    lever_length_m: InputUncertainty | None = Field(
        None, description="the lever length L (m), axis to impact point; the impact energy carries it")
    laser_radius_m: InputUncertainty | None = Field(
        None, description="the laser spot's radius r (m); the angle arctan(s/r), so the amplitude, carries u_r/r")
    drop_masses_kg: list[FixtureUncertainty] | None = Field(
        None, description="each drop mass m (kg), by its nominal value; the impact energy (impact law) carries it")
    drop_height_m: InputUncertainty | None = Field(
        None, description="the drop height h (m), the same for every height; the impact energy (impact law) carries it")
    torque_calibration_rel: InputUncertainty | None = Field(
        None, description="the torque flange's calibration, relative to the reading; the torque amplitude and the "
                          "torque stiffness c_M2 carry it")
    laser_calibration_rel: InputUncertainty | None = Field(
        None, description="the laser's calibration (distance), relative to the reading; the amplitude carries it")
    force_calibration_rel: InputUncertainty | None = Field(
        None, description="the impact-force sensor's calibration, relative; the impact energy from the force "
                          "impulse carries twice it")
    sample_rate_hz: InputUncertainty | None = Field(
        None, description="the sample clock's rate (Hz); the frequency carries u_fs/fs, the stiffness twice it")

    def inertia(self, inertia_kgm2: float) -> FixtureUncertainty | None:
        """The entry of the fixture ``inertia_kgm2`` (kg·m²), None when not given."""
        return _fixture(self.inertias_kgm2, inertia_kgm2)

    def drop_mass(self, drop_mass_kg: float) -> FixtureUncertainty | None:
        """The entry of the drop mass ``drop_mass_kg`` (kg), None when not given."""
        return _fixture(self.drop_masses_kg, drop_mass_kg)


def _fixture(entries: list[FixtureUncertainty] | None, nominal: float) -> FixtureUncertainty | None:
    for entry in entries or ():
        if math.isclose(entry.nominal, nominal, rel_tol=FIXTURE_MATCH_REL):
            return entry
    return None


#: the names an input is given by in :func:`override_uncertainty` (a fixture's: ``NAME@NOMINAL``)
#: -> the :class:`RigUncertainty` field it sets
SPEC_NAMES: dict[str, str] = {
    "inertia_kgm2": "inertias_kgm2", "drop_mass_kg": "drop_masses_kg", "lever_length_m": "lever_length_m",
    "laser_radius_m": "laser_radius_m", "drop_height_m": "drop_height_m",
    "torque_calibration_rel": "torque_calibration_rel", "laser_calibration_rel": "laser_calibration_rel",
    "force_calibration_rel": "force_calibration_rel", "sample_rate_hz": "sample_rate_hz",
}
_FIXTURES = ("inertias_kgm2", "drop_masses_kg")


def parse_uncertainty_spec(spec: str) -> tuple[str, float | None, InputUncertainty]:
    """One input uncertainty written ``NAME=VALUE[:normal|rectangular]``; a fixture's as
    ``NAME@NOMINAL=VALUE[:...]`` (``inertia_kgm2@0.359=0.0036``: the fixture of nominal 0.359 kg·m²).
    NAME is a key of :data:`SPEC_NAMES`; VALUE the standard uncertainty (normal, the default) or
    the half-width (rectangular), in NAME's unit (relative for ``*_rel``).

    Returns
    -------
    tuple
        The :class:`RigUncertainty` field, the fixture's nominal (None for a non-fixture) and the entry.
    """
    from droptower.errors import DroptowerError

    if not isinstance(spec, str) or "=" not in spec:
        raise DroptowerError(f"{spec!r} is not NAME=VALUE[:normal|rectangular]", where="uncertainty")
    name, _, rest = (part.strip() for part in spec.partition("="))
    value_text, _, distribution = (part.strip() for part in rest.partition(":"))
    name, _, nominal_text = (part.strip() for part in name.partition("@"))
    field = SPEC_NAMES.get(name)
    if field is None:
        raise DroptowerError(f"{spec!r}: unknown input {name!r}; the inputs are {', '.join(SPEC_NAMES)}",
                             where="uncertainty")
    if (field in _FIXTURES) != bool(nominal_text):
        raise DroptowerError(f"{spec!r}: " + (f"a fixture's input is {name}@NOMINAL=VALUE (which fixture)"
                                               if field in _FIXTURES else f"{name} takes no @NOMINAL"),
                             where="uncertainty")
    try:
        value = float(value_text)
        nominal = float(nominal_text) if nominal_text else None
    except ValueError:
        raise DroptowerError(f"{spec!r}: the value and nominal must be numbers", where="uncertainty") from None
    if not (math.isfinite(value) and value >= 0) or (nominal is not None and not (math.isfinite(nominal) and nominal > 0)):
        raise DroptowerError(f"{spec!r}: the value must be finite and >= 0, a nominal > 0", where="uncertainty")
    if distribution not in ("", "normal", "rectangular"):
        raise DroptowerError(f"{spec!r}: the distribution is normal or rectangular, got {distribution!r}",
                             where="uncertainty")
    kind = distribution or "normal"
    entry = (FixtureUncertainty(nominal=nominal, value=value, distribution=kind) if nominal is not None
             else InputUncertainty(value=value, distribution=kind))
    return field, nominal, entry


def override_uncertainty(base: RigUncertainty | None, specs: "list[str] | tuple[str, ...]") -> RigUncertainty | None:
    """``base`` (a rig file's ``[uncertainty]``, or None) with the inputs of ``specs``
    (:func:`parse_uncertainty_spec` each) over it: a later spec for the same input (the same
    fixture) replaces the earlier and the rig file's. None when neither gives anything."""
    if not specs:
        return base
    data = (base or RigUncertainty()).model_copy(deep=True)
    updates: dict[str, object] = {}
    for spec in specs:
        field, nominal, entry = parse_uncertainty_spec(spec)
        if nominal is None:
            updates[field] = entry
            continue
        entries = list(updates.get(field) or getattr(data, field) or [])
        entries = [e for e in entries if not math.isclose(e.nominal, nominal, rel_tol=FIXTURE_MATCH_REL)]
        updates[field] = [*entries, entry]
    return data.model_copy(update=updates)
