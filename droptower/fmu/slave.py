"""The model inside a droptower coupling FMU (FMI 2.0 co-simulation, built by pythonfmu).

Inputs ``angle_rad`` (the coupling's twist, rad) and ``angle_rate_rad_per_s`` (its rate, rad/s;
0 when left unconnected); output ``torque_nm`` (N·m). Over a communication step from t to
t + Δ the angle is the input at t extrapolated with the rate, φ(t + τ) = φ(t) + φ'(t)·τ (a
first-order hold; without a rate the zero-order hold FMI assumes), and the coupling steps
through it with ``ceil(Δ/h)`` equal steps of at most the internal step h
(``internal_step_s``), the angle linear between them as in ``Coupling.simulate``. The torque
after the step is the coupling's at the step's end. Parameters: every number of every element
of the coupling (``element_1.stiffness``, ...), fixed at initialisation; the coupling is
rebuilt from them, so a changed parameter is validated as a coupling file would be.

This file is copied into the FMU's resources beside ``coupling.json`` (the coupling's
elements, written by :func:`droptower.fmu.build.build_fmu`); it imports ``droptower`` at run time.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

# Load scipy's BLAS/LAPACK (and with it scipy's bundled libgfortran) now, when pythonfmu
# instantiates the model, not on the first kernel call: there numba imports
# scipy.linalg.cython_blas lazily (numba.np.arraymath), from inside the FMI call, and a host that
# had not loaded scipy.linalg itself then aborted at exit in libgfortran's exit handler
# (glibc "corrupted double-linked list", exit 134). docs/fmu.md has the reproduction.
import scipy.linalg  # noqa: F401  (imported for its side effect)
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

COUPLING_FILE = "coupling.json"


class DroptowerCoupling(Fmi2Slave):
    """A droptower coupling: angle (and rate) in, torque out."""

    author = "droptower"
    description = "droptower coupling: angle_rad (and angle_rate_rad_per_s) in, torque_nm out"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        spec = json.loads((Path(self.resources) / COUPLING_FILE).read_text())
        self.coupling_data = spec["coupling"]
        self.angle_rad = 0.0
        self.angle_rate_rad_per_s = 0.0
        self.torque_nm = 0.0
        self.internal_step_s = float(spec["internal_step_s"])
        self.coupling = None
        self.state = None
        self.register_variable(Real("angle_rad", causality=Fmi2Causality.input, start=0.0,
                                    description="coupling twist [rad]"))
        self.register_variable(Real("angle_rate_rad_per_s", causality=Fmi2Causality.input, start=0.0,
                                    description="twist rate [rad/s], 0 for a zero-order hold of the angle"))
        self.register_variable(Real("torque_nm", causality=Fmi2Causality.output,
                                    description="coupling torque [N*m]"))
        self.register_variable(Real("internal_step_s", causality=Fmi2Causality.parameter,
                                    variability=Fmi2Variability.fixed, start=self.internal_step_s,
                                    description="largest internal time step [s]"))
        for i, element in enumerate(self.coupling_data["element"]):
            for key, value in element.items():
                if isinstance(value, (int, float)) and not isinstance(value, bool):
                    self.register_variable(Real(
                        f"element_{i + 1}.{key}", causality=Fmi2Causality.parameter,
                        variability=Fmi2Variability.fixed, start=float(value),
                        description=f"{element['kind']} {key} (SI, see the coupling file format)",
                        getter=_getter(element, key), setter=_setter(element, key)))

    def exit_initialization_mode(self):
        from droptower.rheology.loader import parse_coupling

        self.coupling = parse_coupling(self.coupling_data)
        self.state = self.coupling.new_state(1)
        if not (math.isfinite(self.internal_step_s) and self.internal_step_s > 0):
            raise ValueError(f"internal_step_s must be > 0, got {self.internal_step_s}")
        # the torque at the initial angle, reached from the relaxed state within one internal step
        self.coupling.step(self.state, self.angle_rad, self.internal_step_s)
        self.torque_nm = float(self.state.torque_nm[0])

    def do_step(self, current_time: float, step_size: float) -> bool:
        n = max(1, math.ceil(step_size / self.internal_step_s * (1.0 - 1e-12)))
        dt = step_size / n
        angles = self.angle_rad + self.angle_rate_rad_per_s * dt * np.arange(1, n + 1)
        torque = self.coupling.simulate(angles, dt, state=self.state, record_energy=False).torque_nm
        self.torque_nm = float(torque[-1])
        return True


def _getter(element: dict, key: str):
    return lambda: float(element[key])


def _setter(element: dict, key: str):
    def put(value: float) -> None:
        element[key] = type(element[key])(value) if isinstance(element[key], int) else float(value)
    return put
