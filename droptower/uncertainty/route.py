"""The rig's inputs in the model route's expanded uncertainties (GUM, JCGM 100:2008, 5.1.3 and
5.2; docs/guide/uncertainty.md#the-model-route).

The model route identifies a coupling from the drop tests (a lever re-simulated against each
decay; :func:`~droptower.identify.drop_campaign.identify_from_drop_tests`) and runs the identified
coupling on the virtual servo bench. The extraction took every input of the rig as known; an
input off by u moves the decays it enters, the same way for every decay that shares it (one J per
fixture, one lever, laser, flange, force sensor and clock for all), so its share does not average
out over the tests:

- J: each decay of its fixture is re-simulated with J + u, and its initial rate from the impulse,
  φ'(0+) = L·∫F dt / J (Rapp et al. 2022, "Theory of Impact Investigation"), scales by J/(J + u);
- the lever length L and the force sensor's calibration κ_F: that initial rate scales by
  (L + u)/L and 1/(1 + u);
- the laser's radius r and calibration κ_L: the angle read as s/r scales by r/(r + u) and
  1/(1 + u) (small angles), an initial rate from the angle's slope with it;
- the torque flange's calibration κ_T: the torque scales by 1/(1 + u);
- the sample clock f_s: every time label scales by f_s/(f_s + u), the impulse ∫F dt with it, an
  initial rate from the angle's slope inversely.

The identification's shift for each input follows from its own least-squares minimum (implicit
function theorem, Gauss-Newton: Δz = −(JᵀJ)⁺·Jᵀ·Δr, Δr the residual's change at the solution
when the decays move by one u; GUM 5.1.3's numerical sensitivity), the servo quantities' share
from the identified coupling run on the bench at ẑ + Δz. No refit: one residual evaluation of the
campaign per input. u_c² = u_fit² + Σ_k u_k² (the inputs independent of each other and of the fit).
"""
from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING, Any

import numpy as np

from droptower.errors import DroptowerError, expects
from droptower.rig.uncertainty import RigUncertainty

if TYPE_CHECKING:
    import pandas as pd

#: the inputs that move a drop-test identification (the drop mass and height do not: the rate
#: after the impact comes from the force impulse or the angle's slope, not the impact law)
ROUTE_INPUTS: tuple[str, ...] = ("inertia_kgm2", "lever_length_m", "laser_radius_m", "laser_calibration_rel",
                                 "torque_calibration_rel", "force_calibration_rel", "sample_rate_hz")
#: relative forward-difference step of the Jacobian in the optimised variables z
JACOBIAN_STEP = 1e-4


def _moved(decay: Any, name: str, ratio: float) -> Any:
    """``decay`` as the extraction reads it when input ``name``'s nominal value is off by the
    factor ``ratio`` (nominal + u over nominal); see the module docstring."""
    impulse = decay.rate_source == "impact_force"
    if name == "inertia_kgm2":
        return dataclasses.replace(decay, inertia_kgm2=decay.inertia_kgm2 * ratio,
                                   rate0_rad_per_s=decay.rate0_rad_per_s / ratio if impulse else decay.rate0_rad_per_s)
    if name in ("lever_length_m", "force_calibration_rel"):
        if not impulse:
            return decay
        return dataclasses.replace(decay, rate0_rad_per_s=decay.rate0_rad_per_s * (
            ratio if name == "lever_length_m" else 1.0 / ratio))
    if name in ("laser_radius_m", "laser_calibration_rel"):
        return dataclasses.replace(decay, angle_rad=decay.angle_rad / ratio, amplitude_rad=decay.amplitude_rad / ratio,
                                   angle_noise_rad=decay.angle_noise_rad / ratio,
                                   rate0_rad_per_s=decay.rate0_rad_per_s if impulse else decay.rate0_rad_per_s / ratio)
    if name == "torque_calibration_rel":
        return decay if decay.torque_nm is None else dataclasses.replace(decay, torque_nm=decay.torque_nm / ratio)
    if name == "sample_rate_hz":
        return dataclasses.replace(decay, time_s=decay.time_s / ratio, dt_s=decay.dt_s / ratio,
                                   frequency_hz=decay.frequency_hz * ratio,
                                   rate0_rad_per_s=decay.rate0_rad_per_s / ratio if impulse
                                   else decay.rate0_rad_per_s * ratio)
    raise DroptowerError(f"unknown input {name!r}: one of {', '.join(ROUTE_INPUTS)}", where=name)


def _stated(uncertainty: RigUncertainty, decays: list, lever_length_m: float | None,
            laser_radius_m: float | None) -> list[tuple[str, float | None, float]]:
    """(key, fixture's nominal J or None, relative standard uncertainty) of each input given."""
    out: list[tuple[str, float | None, float]] = []
    for j in sorted({d.inertia_kgm2 for d in decays}):
        entry = uncertainty.inertia(j)
        if entry is not None and entry.standard > 0:
            out.append((f"inertia_kgm2@{j:g}", j, entry.standard / j))
    nominal = {"lever_length_m": lever_length_m, "laser_radius_m": laser_radius_m,
               "sample_rate_hz": 1.0 / decays[0].dt_s}
    for name in ROUTE_INPUTS[1:]:
        entry = getattr(uncertainty, name)
        if entry is None or entry.standard == 0:
            continue
        if name.endswith("_rel"):
            out.append((name, None, entry.standard))
            continue
        if nominal[name] is None:
            raise DroptowerError(f"the {name} uncertainty is given but not its nominal value: give {name}",
                                 where=name)
        out.append((name, None, entry.standard / nominal[name]))
    return out


@expects(ident="droptower.identify.result.Identification", decays=list,
         uncertainty="droptower.rig.uncertainty.RigUncertainty")
def route_input_values(ident: Any, decays: list, settings: Any, uncertainty: RigUncertainty, *,
                       lever_length_m: float | None = None,
                       laser_radius_m: float | None = None) -> dict[str, np.ndarray]:
    """Each given input's shifted parameter values of a drop-test identification (the family's
    parameters, as ``ident.params``): input key -> values (n,) at ẑ + Δz, Δz the identification's
    shift for one standard uncertainty of that input. Arguments as :func:`route_input_sets`."""
    from droptower.identify.dropfit import DropProblem

    used = set(ident.tests_used)
    fitting = [d for d in decays if d.name in used]
    if len(fitting) < 1:
        raise DroptowerError("model route inputs: none of the identification's fitting tests are among the given "
                             "decays; give the decays it was fitted to")
    stated = _stated(uncertainty, fitting, lever_length_m, laser_radius_m)
    params = ident.family_model.parameters
    values = ident.params.vector()
    idx = np.flatnonzero(np.isfinite(ident.params.stderr_vector()))
    z0 = np.array([params[i].to_z(values[i]) for i in idx])
    rows = np.tile(values, (idx.size + 1, 1))
    for j, i in enumerate(idx):
        rows[j + 1, i] = params[i].to_value(z0[j] + JACOBIAN_STEP)
    res = DropProblem(ident.family_model, fitting, settings).residuals(rows)
    jac = ((res[1:] - res[0]) / JACOBIAN_STEP).T
    pinv = np.linalg.pinv(jac)
    out: dict[str, np.ndarray] = {}
    for key, fixture, rel in stated:
        name = key.split("@")[0]
        moved = [_moved(d, name, 1.0 + rel) if fixture is None or math.isclose(d.inertia_kgm2, fixture, rel_tol=1e-9)
                 else d for d in fitting]
        dz = -pinv @ (DropProblem(ident.family_model, moved, settings).residuals(values[None])[0] - res[0])
        v = np.array(values, float)
        v[idx] = [params[i].to_value(zi) for i, zi in zip(idx, z0 + dz)]
        out[key] = v
    return out


@expects(ident="droptower.identify.result.Identification", decays=list,
         uncertainty="droptower.rig.uncertainty.RigUncertainty")
def route_input_sets(ident: Any, decays: list, settings: Any, uncertainty: RigUncertainty, *,
                     lever_length_m: float | None = None,
                     laser_radius_m: float | None = None) -> dict[str, np.ndarray]:
    """Each given input's shifted parameter set of a drop-test identification.

    Parameters
    ----------
    ident : Identification
        A drop-test identification (:func:`~droptower.identify.drop_campaign.identify_from_drop_tests`).
    decays : list of DropDecay
        The decays it was fitted to (its ``tests_used`` among them).
    settings : DropFitSettings
        The fit's settings (``DropCampaign.settings``).
    uncertainty : RigUncertainty
        The rig's input uncertainties; a fixture's J is matched to the decays' inertia.
    lever_length_m, laser_radius_m : float, optional
        The nominal lever length and laser radius (m) the logs were read with; needed only when
        their uncertainty is given (relative: u/L, u/r).

    Returns
    -------
    dict
        Input key (``inertia_kgm2@0.359``, ``lever_length_m``, ...) -> the identified coupling's
        raw parameter set (n,) at ẑ + Δz, Δz the identification's shift for one standard
        uncertainty of that input.
    """
    values = route_input_values(ident, decays, settings, uncertainty, lever_length_m=lever_length_m,
                                laser_radius_m=laser_radius_m)
    return {key: ident.family_model.coupling(v).params[0] for key, v in values.items()}


def route_parameter_budget(ident: Any, input_values: dict[str, np.ndarray]) -> "pd.DataFrame":
    """The identified parameters' budget: one row per free parameter with its ``value``, the
    fit's ``u_fit`` (the identification's standard error), each input's share ``u_<input>``
    (|shift| for one standard uncertainty, :func:`route_input_values`), ``u_inputs``, ``u_c``,
    ``U95`` (k = 2) and the ``dominant`` term (``fit`` or an input key)."""
    import pandas as pd

    values, std = ident.params.vector(), ident.params.stderr_vector()
    rows = []
    for i, name in enumerate(ident.params):  # vector() is in the dict's order
        if not np.isfinite(std[i]):
            continue
        shares = {key: abs(float(v[i] - values[i])) for key, v in input_values.items()}
        u_in = math.sqrt(sum(x * x for x in shares.values()))
        terms = {"fit": float(std[i]), **shares}
        rows.append({"parameter": name, "value": float(values[i]), "u_fit": float(std[i]),
                     **{f"u_{k}": x for k, x in shares.items()}, "u_inputs": u_in,
                     "u_c": math.hypot(float(std[i]), u_in), "U95": 2.0 * math.hypot(float(std[i]), u_in),
                     "dominant": max(terms, key=terms.get)})
    return pd.DataFrame(rows)


def nominal_geometry(decays: list, read: Any = None) -> tuple[float | None, float | None]:
    """The nominal lever length and laser radius (m) drop-test logs were read with: the reading's
    overrides (:class:`~droptower.identify.droplogs.ReadSettings`), else the first decay's
    metadata, else the rig's defaults the reading holds; None where nothing says."""
    def first(*values: Any) -> float | None:
        return next((float(v) for v in values if v is not None), None)

    meta = decays[0].metadata if decays else {}
    defaults = getattr(read, "defaults", None) or {}
    lever = first(getattr(read, "lever_length_m", None), meta.get("lever_length_m"), defaults.get("lever_length_m"))
    laser = first(getattr(read, "sensor_radius_m", None), meta.get("sensor_radius_m"), meta.get("laser_radius_m"),
                  defaults.get("sensor_radius_m"))
    return lever, laser
