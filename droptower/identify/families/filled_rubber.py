"""A generic filled-elastomer model (docs/theory.md#filled-rubber): family and strategy.

Three mechanisms in parallel, as isolator and rail-vehicle engineers model filled rubber
(Berg 1998; Sjöberg 2002; García Tárrago et al. 2007): an equilibrium spring that may stiffen
at large strain (``cubic_spring``, its cubic term may be 0), a rate-independent friction network
whose stiffness breaks down with the amplitude and recovers in time (``filler_network``: the
Payne and Mullins effects) and a fractional viscoelastic branch (``power_law``, Bagley & Torvik
1983) whose level, exponent and band are fitted. Every number is free within bounds scaled to
the data; the filler network's bookkeeping times are options.

The first guess comes from the data's harmonic readings (K' and K'' of the steady sine blocks
of servo records, or of the drop tests' first cycles, :func:`~droptower.identify.droplogs.first_cycle_readings`):
the family's closed-form K*(A, f) is fitted to them, which splits the stiffness into spring and
network by its amplitude trend and gives the power-law level by its frequency trend. Then the
joint least squares on the records (and the global search where that fit is poor).

From servo records the family holds a fifth part by default, the large-strain network
(``large_strain_network``: a stiffening spring softened by scragging and a stiffening friction
network, Grant, Fenves & Whittaker 2004; docs/theory.md#large-strain-network): real filled rubber
at strains of order one (high-damping rubber bearings). Its parameters follow the others; with it
the equilibrium spring is linear and the stiffening Maxwell branch is left out.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import ArrayLike
from scipy.optimize import least_squares
from scipy.stats import qmc

from droptower.errors import DroptowerError
from droptower.identify.cycles import evaluate_block
from droptower.identify.data import Segment
from droptower.identify.families.base import Family, stiffness_parameter
from droptower.identify.families.stages import Setup, result_of, steady_blocks
from droptower.identify.engine.problem import Variables
from droptower.identify.fit import FitVariable, clip_to_bounds
from droptower.identify.result import Identification
from droptower.identify.noise import servo_noise
from droptower.identify.verdict import servo_verdict
from droptower.rheology.elements import (filler_network_complex_stiffness, power_law_complex_stiffness,
                                         power_law_exponent)
from droptower.rheology.numba_cache import cache_available, compile_once_across_processes

#: Relative margin that keeps the power-law band's term count at the ``terms`` option exactly
#: (PowerLaw rounds the terms per decade times the decades up).
_TERMS_MARGIN = 1e-9
#: Starts of the first guess's fit to the harmonic readings (a Latin hypercube over the bounds).
GUESS_STARTS = 12
#: The power-law band's placement (min_frequency_hz, band_decades): left out of the first guess.
_BAND = (8, 9)
#: First harmonic of |sin| sin: the stiffening spring (k0 + g |e|) e at e = E sin is k0 + g 8/(3 pi) E.
_ABS_SIN_HARMONIC = 8.0 / (3.0 * math.pi)
#: The large-strain network is kept where it lowers the four parts' RMS error below this share
#: (the bearing of tests/test_identify_large_strain.py: 0.50; a six-parameter coupling's records: 0.996).
LARGE_STRAIN_GAIN = 0.8
#: A large-strain part whose gain is below this share of its scale is off (:meth:`FilledRubberFamily.idle_parameters`).
IDLE_SHARE = 1e-2
#: Parameters of the family without the large-strain network (those follow them).
_N_BASE = 13
#: Relative Newton step below which :func:`stiffening_maxwell_stiffness` stops (converged to rounding).
_NEWTON_TOLERANCE = 1e-10


def stiffening_maxwell_stiffness(k0: ArrayLike, gain: ArrayLike, damping: ArrayLike, amplitude_rad: ArrayLike,
                                 frequency_hz: ArrayLike, iterations: int = 60) -> np.ndarray:
    """K' + i K'' (N*m/rad) of a Maxwell branch whose spring force is (k0 + g |e|) e (spring
    ``k0`` N*m/rad, ``gain`` g N*m/rad^2, dashpot ``damping`` c N*m*s/rad) in a steady harmonic
    motion of amplitude A (rad) at f (Hz), on the first harmonic (equivalent linearisation): the
    spring's elongation amplitude E and its secant k(E) = k0 + g 8/(3 pi) E solve
    E = A omega c / |k(E) + i omega c|, and the branch is a linear Maxwell k(E) || omega c:
    K* = k(E) i omega c / (k(E) + i omega c).

    E is the root of q(E) = E^2 (k(E)^2 + (omega c)^2) - (A omega c)^2, a quartic whose
    coefficients are all >= 0: increasing and convex for E > 0. Newton's method started at the
    linear branch's E_0 = A omega c / |k0 + i omega c| (>= the root, as k(E) >= k0) therefore
    falls monotonically onto it; it stops once every step is below 1e-10 of E (the next one,
    quadratically smaller, would be below the double's resolution; ``iterations`` is a cap that
    convergence never nears). With g = 0 E_0 is the root.

    ``k0``, ``gain`` and ``damping`` may be arrays of parameter sets that broadcast with the
    amplitudes and frequencies (e.g. (M, 1) against (N,) gives (M, N)).
    """
    wc = 2.0 * math.pi * np.asarray(frequency_hz, float) * np.asarray(damping, float)
    args = (k0, np.asarray(gain, float) * _ABS_SIN_HARMONIC, amplitude_rad, wc)
    flat = np.empty((4,) + np.broadcast(*args).shape)  # contiguous, writeable: the kernel's one signature
    for row, x in zip(flat, args):
        row[...] = x
    k = _stiffening_secant(*flat.reshape(4, -1), int(iterations)).reshape(flat.shape[1:])
    wc = flat[3]
    return k * 1j * wc / (k + 1j * wc)


@njit(cache=cache_available(), nogil=True, error_model="numpy")
def _stiffening_secant(k0, g, amp, wc, iterations):  # pragma: no cover - compiled
    """Secant k(E) = k0 + g E at each elongation root of :func:`stiffening_maxwell_stiffness`,
    elementwise over equal-length arrays (compiled: the first guess evaluates the closed form
    some ten thousand times per fit)."""
    out = np.empty(amp.size)
    for i in range(amp.size):
        e = amp[i] * wc[i] / math.hypot(k0[i], wc[i])
        if g[i] > 0.0:
            target = (amp[i] * wc[i]) ** 2
            for _ in range(iterations):
                k = k0[i] + g[i] * e
                slope = 2.0 * e * (k * k + wc[i] * wc[i]) + 2.0 * g[i] * k * e * e
                if not slope > 0.0:
                    break
                step = (e * e * (k * k + wc[i] * wc[i]) - target) / slope
                e = max(e - step, 0.0)
                if not step > _NEWTON_TOLERANCE * e:  # quadratic convergence: the next step would be ~0
                    break
        out[i] = k0[i] + g[i] * e
    return out


def _closed_form_fields(*checks: tuple[dict[str, Any], tuple[str, ...]]) -> None:
    """The checks the specs make on the fields their closed forms read (finite and > 0, a band of
    positive width), without building the specs: ``checks`` are (element, fields) pairs, each
    element a spec's fields as :meth:`FilledRubberFamily.elements` writes them (numbers, or
    columns of parameter sets); :class:`DroptowerError` where a spec would refuse, naming the
    first refused field and the value of a set it refuses."""
    for element, keys in checks:
        for key in keys:
            x = np.asarray(element[key])
            refused = ~((x > 0) & (x < math.inf))  # a NaN fails both
            if refused.any():
                raise DroptowerError(f"field {key} of element {element['name']} of model filled_rubber must be "
                                     f"finite and > 0, got {float(x.flat[np.argmax(refused)])}")
        if "max_frequency" in element and not element["max_frequency"] > element["min_frequency"]:
            raise DroptowerError(f"element {element['name']} of model filled_rubber: max_frequency must exceed "
                                 f"min_frequency, got {element['max_frequency']} <= {element['min_frequency']}")


class FilledRubberFamily(Family):
    """Equilibrium spring b x + a x^3 || filler network (Iwan, breakdown and recovery) || power-law branch.

    Options: ``n`` (Jenkins elements of the network), ``recovery_time_s`` and
    ``centre_relaxation_time_s`` (the network's bookkeeping times), ``terms`` (Maxwell terms of
    the power-law band, whatever its width, so that every parameter set has one structure),
    ``stiffening_branch`` (the stiffening Maxwell branch), ``large_strain`` (the large-strain
    network, docs/theory.md#large-strain-network: None, the default, lets the servo strategy
    turn it on and a drop-test fit leave it off; True or False force it) and
    ``large_strain_sliders`` (its Jenkins elements) and ``large_strain_sides`` (True, the
    default: the network's scragging kept apart on each side of 0; False: shared, as before).
    """

    kind = "filled_rubber"
    title = "filled elastomer: spring (cubic) + filler network (Payne/Mullins) + power-law branch"
    source = ("Berg 1998; Sjöberg 2002; García Tárrago et al. 2007 (elastic + friction + fractional); "
              "Bagley & Torvik 1983; docs/theory.md#filled-rubber")
    OPTIONS = {"n": 32, "recovery_time_s": 10.0, "centre_relaxation_time_s": 5.0, "terms": 12,
               "stiffening_branch": True, "large_strain": None, "large_strain_sliders": 16,
               "large_strain_sides": True}

    def _parameters(self) -> list[FitVariable]:
        s = self.scale
        amp, f = s.amplitude_rad, max(s.frequency_hz, 1e-3)
        if int(self.options["terms"]) < 2 or int(self.options["n"]) < 2:
            raise DroptowerError(f"options terms and n of model {self.kind} must be integers >= 2, got "
                                 f"{self.options['terms']} and {self.options['n']}")
        for key in ("recovery_time_s", "centre_relaxation_time_s"):
            if not float(self.options[key]) > 0:
                raise DroptowerError(f"option {key} of model {self.kind} must be > 0, got {self.options[key]}")
        cubic = s.torque_nm / amp ** 3
        return [stiffness_parameter("k_nm_per_rad", s, 1e-3, 10.0),
                FitVariable("a_nm_per_rad3", 0.0, 10.0 * cubic, log=False, scale=cubic),
                stiffness_parameter("kf_nm_per_rad", s, 1e-3, 30.0),
                FitVariable("critical_angle_rad", 1e-4 * amp, 10.0 * amp),
                FitVariable("exponent", 0.1, 2.0),
                FitVariable("breakdown_angle_rad", 1e-3 * amp, 100.0 * amp),
                stiffness_parameter("kp_nm_per_rad", s, 1e-4, 10.0),
                FitVariable("matrix_loss_factor", 0.01, 5.0),
                FitVariable("min_frequency_hz", 1e-3 * f, 30.0 * f),
                FitVariable("band_decades", 0.3, 6.0),
                stiffness_parameter("kv_nm_per_rad", s, 1e-4, 10.0),
                FitVariable("kv_gain_nm_per_rad2", 0.0, 10.0 * s.stiffness_nm_per_rad / amp, log=False,
                          scale=s.stiffness_nm_per_rad / amp),
                FitVariable("tau_v_s", 1e-2 / (2 * math.pi * f), 1e2 / (2 * math.pi * f))] + (
            self._large_strain_parameters() if self.large_strain else [])

    @property
    def large_strain(self) -> bool:
        """Whether the couplings hold the large-strain network (option ``large_strain``; None, the
        default, leaves the choice to the caller: the servo strategy turns it on, a drop-test fit
        keeps the family without it)."""
        return bool(self.options["large_strain"])

    def with_large_strain(self) -> "FilledRubberFamily":
        """The same family with the large-strain network (its parameters after the others) and
        without the stiffening Maxwell branch: the network's spring carries the stiffening, softened
        by the scragging as the filler's is (an unscragged stiffening term, the equilibrium spring's
        cubic term or the branch's, extrapolates to larger amplitudes unsoftened: on the bearing of
        tests/test_identify_large_strain.py it doubles the error on the unseen amplitude)."""
        return type(self)(self.scale, {**self.options, "large_strain": True, "stiffening_branch": False})

    def _large_strain_parameters(self) -> list[FitVariable]:
        """The large-strain network's parameters (docs/theory.md#large-strain-network), each gain
        free to vanish: the virgin spring's stiffness, its stiffening read as the stiffness it adds
        at the data's amplitude A, the stiffening's order, the network's stiffness and largest slip
        (over A) and spread, its hardening g A^2, the scragging damage's largest value, angle (over
        A), exponent and travel (over A)."""
        s = self.scale
        k, amp = s.stiffness_nm_per_rad, s.amplitude_rad
        if int(self.options["large_strain_sliders"]) < 2:
            raise DroptowerError(f"option large_strain_sliders of model {self.kind} must be an integer >= 2, got "
                                 f"{self.options['large_strain_sliders']}")
        return [FitVariable("ks_nm_per_rad", 0.0, 10.0 * k, log=False, scale=k),
                FitVariable("ks_hardening_nm_per_rad", 0.0, 10.0 * k, log=False, scale=k),
                FitVariable("ks_hardening_order", 0.5, 6.0, log=False, scale=1.0),
                FitVariable("kn_nm_per_rad", 0.0, 30.0 * k, log=False, scale=k),
                FitVariable("slip_angle_rad", 1e-3 * amp, 3.0 * amp),
                FitVariable("slip_spread", 0.2, 8.0),
                FitVariable("network_hardening", 0.0, 30.0, log=False, scale=1.0),
                FitVariable("scragging", 0.0, 0.999, log=False, scale=1.0),
                FitVariable("scragging_angle_rad", 0.05 * amp, 5.0 * amp),
                FitVariable("scragging_exponent", 0.3, 4.0),
                FitVariable("scragging_travel_rad", 0.05 * amp, 30.0 * amp),
                FitVariable("travel_softening", 0.0, 3.0, log=False, scale=1.0),
                FitVariable("travel_exponent", 0.2, 1.5),
                FitVariable("slip_hardening", 0.0, 10.0, log=False, scale=1.0)]

    #: The stiffening Maxwell branch's parameters: a drop-test fit searches first with the branch
    #: off (:meth:`branch_off`) and frees them in its wider search after a poor verdict, so a
    #: coupling the other three parts represent pays no search over three more dimensions.
    DEFERRED = ("kv_nm_per_rad", "kv_gain_nm_per_rad2", "tau_v_s")

    def without_branch(self) -> "FilledRubberFamily":
        """The same family (the same parameters) whose couplings leave the stiffening Maxwell branch
        out: a nonlinear branch makes every step of the core iterate, even at a negligible stiffness.
        Its parameters are this family's (the user's bounds on them kept), not the defaults."""
        out = type(self)(self.scale, {**self.options, "stiffening_branch": False})
        out.parameters = list(self.parameters)
        return out

    def branch_off(self, v: np.ndarray) -> np.ndarray:
        """``v`` with the stiffening Maxwell branch off: its spring at its lower bound (1e-4 of the
        data's stiffness), no gain; its relaxation time kept."""
        out = np.array(v, float)
        out[10], out[11] = self.parameters[10].lower, 0.0
        return out

    @property
    def reference_frequency_hz(self) -> float:
        """The power-law branch's reference frequency: the data's characteristic frequency (Hz)."""
        return max(self.scale.frequency_hz, 1e-3)

    def guess(self) -> np.ndarray:
        s = self.scale
        k, amp, f = s.stiffness_nm_per_rad, s.amplitude_rad, self.reference_frequency_hz
        base = [0.3 * k, 0.0, 0.6 * k, 0.1 * amp, 0.5, 0.4 * amp, 0.1 * k, 0.5, 0.01 * f, 3.0,
                0.05 * k, 0.0, 1.0 / (2 * math.pi * f)]
        # the large-strain network: a scragged spring, a network of slips up to A/4, a little of each
        large = [1.0 * k, 0.2 * k, 1.7, 10.0 * k, 0.12 * amp, 4.0, 0.5, 0.8, 1.5 * amp, 1.0, 5.0 * amp,
                 0.05, 0.5, 0.5]
        return np.array(base + (large if self.large_strain else []))

    def elements(self, v: np.ndarray) -> list[dict[str, Any]]:
        out = self._element_fields(*(float(x) for x in v[:_N_BASE]))
        if self.large_strain:
            out.append(self._large_strain_fields(*(float(x) for x in v[_N_BASE:])))
        return out

    def idle_parameters(self, v: np.ndarray) -> list[str]:
        """Names of the large-strain network's shape parameters whose part is switched off in
        ``v`` (its gain below :data:`IDLE_SHARE` of its scale: the data's stiffness, or 1 for the
        scragging): the stiffening's order without stiffening, the network's slips and hardening
        without network, the scragging's angle, exponent and travel without scragging. A part that
        small cannot place its shape, so the data cannot hold those off a bound: such a bound is
        not a bound hit (as a gain at its lower bound of 0 is not)."""
        if not self.large_strain:
            return []
        params, values = self.parameters[_N_BASE:], np.asarray(v, float)[_N_BASE:]
        off = {p.name: val <= IDLE_SHARE * p.scale for p, val in zip(params, values)}
        idle = {"ks_hardening_nm_per_rad": ("ks_hardening_order",),
                "kn_nm_per_rad": ("slip_angle_rad", "slip_spread", "network_hardening"),
                "scragging": ("scragging_angle_rad", "scragging_exponent", "scragging_travel_rad"),
                "travel_softening": ("travel_exponent",)}
        return [name for gain, names in idle.items() if off[gain] for name in names]

    def _large_strain_fields(self, ks: float, hardening: float, order: float, kn: float, slip: float, spread: float,
                             network_hardening: float, scragging: float, scragging_angle: float,
                             scragging_exponent: float, travel: float, travel_softening: float,
                             travel_exponent: float, slip_hardening: float) -> dict[str, Any]:
        """The large-strain network's element of its parameters (:meth:`_large_strain_parameters`):
        the travel and the reversal's angle read over the data's amplitude A."""
        amp = self.scale.amplitude_rad
        return {"kind": "large_strain_network", "name": "large_strain", "stiffness": ks,
                "gain": hardening / amp ** order, "exponent": order, "network_stiffness": kn, "slip": slip,
                "spread": spread, "friction_gain": network_hardening / amp ** 2, "damage": scragging,
                "damage_angle": scragging_angle, "damage_exponent": scragging_exponent, "damage_travel": travel,
                "travel_softening": travel_softening / amp ** travel_exponent, "travel_exponent": travel_exponent,
                "slip_hardening": slip_hardening / amp, "damage_sides": bool(self.options["large_strain_sides"]),
                "n": int(self.options["large_strain_sliders"])}

    def _element_fields(self, k: Any, a: Any, kf: Any, ac: Any, m: Any, ab: Any, kp: Any, eta: Any, f_min: float,
                        decades: float, kv: Any, gain: Any, tau_v: Any) -> list[dict[str, Any]]:
        """:meth:`elements` of the parameters: numbers, or (the closed form's batch) columns of
        parameter sets, all but the band (``f_min``, ``decades``: numbers, the band sets the
        power law's terms)."""
        terms = int(self.options["terms"])
        return [{"kind": "cubic_spring", "name": "equilibrium", "a": a, "b": k},
                {"kind": "filler_network", "name": "filler_network", "stiffness": kf, "critical_angle": ac,
                 "exponent": m, "breakdown_angle": ab, "recovery_time": float(self.options["recovery_time_s"]),
                 "centre_relaxation_time": float(self.options["centre_relaxation_time_s"]), "n": int(self.options["n"])},
                {"kind": "power_law", "name": "matrix", "storage_stiffness": kp, "loss_factor": eta,
                 "reference_frequency": self.reference_frequency_hz, "min_frequency": f_min,
                 "max_frequency": f_min * 10.0 ** decades,
                 "terms_per_decade": (terms - 1) / decades * (1.0 - _TERMS_MARGIN)}] + (
                [{"kind": "variable_maxwell", "name": "amplitude_viscous", "stiffness": kv, "stiffness_gain": gain,
                  "damping": kv * tau_v}] if self.options["stiffening_branch"] and not self.large_strain else [])

    def derived(self, v: np.ndarray) -> dict[str, float]:
        eta, f_min, decades = float(v[7]), float(v[8]), float(v[9])
        return {"max_frequency_hz": f_min * 10.0 ** decades, "matrix_exponent": power_law_exponent(eta),
                "reference_frequency_hz": self.reference_frequency_hz,
                "cv_nms_per_rad": float(v[10]) * float(v[12])}

    # ------------------------------------------------------------------ closed form
    def harmonic_stiffness(self, v: np.ndarray, amplitude_rad: np.ndarray, frequency_hz: np.ndarray) -> np.ndarray:
        """K' + i K'' (N*m/rad) of parameter set ``v`` in a steady harmonic motion of amplitude A
        (rad) at frequency f (Hz): :meth:`harmonic_stiffness_rows` of the one set."""
        return self.harmonic_stiffness_rows(np.asarray(v, float)[None, :], amplitude_rad, frequency_hz)[0]

    def harmonic_stiffness_rows(self, rows: np.ndarray, amplitude_rad: np.ndarray,
                                frequency_hz: np.ndarray) -> np.ndarray:
        """K' + i K'' (N*m/rad), shape (M,) + the readings' shape, of each parameter set (row of
        ``rows``, (M, 13)) in a steady harmonic motion of amplitude A (rad) at frequency f (Hz):
        the cubic spring's first harmonic b + 3/4 a A^2, the network broken down to its
        equilibrium at A (:func:`~droptower.rheology.elements.filler_network_complex_stiffness`),
        the power-law band's Prony series (:func:`~droptower.rheology.elements.power_law_complex_stiffness`)
        and the stiffening Maxwell branch linearised on its first harmonic
        (:func:`stiffening_maxwell_stiffness`). The elements' closed forms are called once per
        distinct band (it sets the power law's terms) on the columns of the numbers
        :meth:`elements` writes, after the checks their specs make on every row (the first guess
        evaluates this some ten thousand times per fit: building the specs would dominate)."""
        rows = np.asarray(rows, float)
        amp, freq = np.asarray(amplitude_rad, float), np.asarray(frequency_hz, float)
        band = rows[:, _BAND[0]:_BAND[1] + 1]
        if len(rows) == 1 or (band == band[0]).all():  # the first guess's case: one band
            return self._closed_form(rows, amp, freq)
        out = np.empty((len(rows),) + np.broadcast_shapes(amp.shape, freq.shape), complex)
        _, group = np.unique(band, axis=0, return_inverse=True)
        for g in np.unique(group):
            sel = group.ravel() == g
            out[sel] = self._closed_form(rows[sel], amp, freq)
        return out

    def _closed_form(self, rows: np.ndarray, amp: np.ndarray, freq: np.ndarray) -> np.ndarray:
        """:meth:`harmonic_stiffness_rows` of parameter sets that share one band."""
        columns = np.ascontiguousarray(rows.T).reshape(rows.shape[::-1] + (1,) * max(amp.ndim, freq.ndim))
        band = [float(rows[0, i]) for i in _BAND]
        spring, network, matrix, *viscous = self._element_fields(*columns[:_BAND[0]], *band,
                                                                  *columns[_BAND[1] + 1:_N_BASE])
        _closed_form_fields((network, ("stiffness", "critical_angle", "exponent", "breakdown_angle")),
                            (matrix, ("storage_stiffness", "loss_factor", "reference_frequency", "min_frequency",
                                      "terms_per_decade")))
        k_network = filler_network_complex_stiffness(network["stiffness"], network["critical_angle"], network["exponent"],
                                                     network["breakdown_angle"], network["n"], amp)
        k_matrix = power_law_complex_stiffness(matrix["storage_stiffness"], matrix["loss_factor"],
                                               matrix["reference_frequency"], matrix["min_frequency"],
                                               matrix["max_frequency"], matrix["terms_per_decade"], freq)
        k_viscous = (stiffening_maxwell_stiffness(viscous[0]["stiffness"], viscous[0]["stiffness_gain"],
                                                  viscous[0]["damping"], amp, freq) if viscous else 0.0)
        return spring["b"] + 0.75 * spring["a"] * amp ** 2 + k_network + k_matrix + k_viscous

    def guess_from_readings(self, amplitude_rad: np.ndarray, frequency_hz: np.ndarray, stiffness: np.ndarray,
                            x0: np.ndarray, given: np.ndarray, seed: int = 0) -> np.ndarray:
        """A first guess from harmonic readings: the closed form (:meth:`harmonic_stiffness`)
        fitted by least squares to K' and K'' at each reading's amplitude (rad) and frequency
        (Hz) (``stiffness`` complex, N*m/rad), from :data:`GUESS_STARTS` Latin-hypercube starts
        and ``x0``; the band stays at ``x0``'s (the readings span too narrow a band to place it),
        and so do the ``given`` parameters. ``x0`` where fewer than three readings. The
        forward-difference Jacobian's shifted points go to :meth:`harmonic_stiffness_rows` in one
        call (least_squares' ``workers``), its steps and differences SciPy's own."""
        amp, freq, k_obs = (np.asarray(a) for a in (amplitude_rad, frequency_hz, stiffness))
        ok = np.isfinite(amp) & np.isfinite(freq) & np.isfinite(k_obs) & (amp > 0)
        amp, freq, k_obs = amp[ok], freq[ok], k_obs[ok]
        if amp.size < 3:
            return x0
        params = self.parameters
        idx = [i for i in range(min(len(params), _N_BASE)) if not given[i] and i not in _BAND]
        if not idx:
            return x0
        lo, hi = np.array([params[i].z_bounds() for i in idx]).T
        weight = 1.0 / np.abs(k_obs)
        variables = Variables(params, np.array(idx))

        def values(z: np.ndarray) -> np.ndarray:
            """Every parameter of the optimised variables ``z`` (..., len(idx)): ``x0`` but ``idx``."""
            z = np.asarray(z, float)
            v = np.broadcast_to(np.asarray(x0, float), z.shape[:-1] + (len(x0),)).copy()
            v[..., idx] = variables.values(z)
            return v

        def residuals(rows: np.ndarray) -> np.ndarray:
            d = (self.harmonic_stiffness_rows(rows, amp, freq) - k_obs) * weight
            return np.concatenate([d.real, d.imag], axis=-1)

        def resid(z: np.ndarray) -> np.ndarray:
            return residuals(values(z)[None, :])[0]

        def jacobian_points(_fun: Any, points: Any) -> np.ndarray:
            """scipy's map over the forward-difference Jacobian's shifted points (``workers``):
            their residuals in one call of the batched closed form, not one call each."""
            return residuals(values(np.array(list(points), float)))

        z0 = np.clip([params[i].to_z(x0[i]) for i in idx], lo, hi)
        starts = [z0] + list(lo + qmc.LatinHypercube(d=len(idx), seed=seed).random(GUESS_STARTS) * (hi - lo))
        best, cost = x0, math.inf
        for z in starts:
            try:
                r = least_squares(resid, z, bounds=(lo, hi), method="trf", max_nfev=40 * len(idx), xtol=1e-6,
                                  workers=jacobian_points)
            except (ValueError, DroptowerError):  # a start the element refuses
                continue
            if r.cost < cost:
                best, cost = values(r.x), float(r.cost)
        return clip_to_bounds(params, best)


def servo_readings(segments: list[Segment]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(amplitude rad, frequency Hz, K' + i K'' N*m/rad) of every steady sine block of the records
    (the lab's evaluation of its cycles after the first)."""
    rows = []
    for sb in steady_blocks(segments):
        seg = segments[sb.segment]
        ev = evaluate_block(seg.measured_angle, seg.measured_torque, seg.dt_s, sb.block)
        if ev is not None and np.isfinite(seg.measured_torque[sb.block.start:sb.block.stop]).all():
            h = ev.harmonics[0]
            rows.append((h.angle_amplitude_rad, h.frequency_hz, h.complex_stiffness_nm_per_rad))
    if not rows:
        return np.empty(0), np.empty(0), np.empty(0, complex)
    a, f, k = zip(*rows)
    return np.array(a), np.array(f), np.array(k, complex)


def identify_filled_rubber(s: Setup, segments: list[Segment], start: float, **_) -> Identification:
    """The closed form fitted to the steady blocks' K' and K'' (the first guess), then the joint
    least squares on all records. With option ``large_strain`` None (the default) the family's
    four parts are fitted first, and only where that fit is poor is ``s`` turned into the family
    with the large-strain network (in place: the global search that may follow searches it) and
    fitted again from its own first guess; that fit is kept where its RMS error is below
    :data:`LARGE_STRAIN_GAIN` times the four parts'. A coupling the four parts represent so
    stays one of four parts and pays nothing for the fifth; one they miss for another reason
    pays one more local fit (a six-parameter coupling's records: 20 s against 2 s) and keeps
    its four parts."""
    amp, freq, stiffness = servo_readings(segments)
    extra = {"readings": int(amp.size)}
    stage = "joint (from the harmonic readings' fit)" if amp.size >= 3 else "joint"
    fam: FilledRubberFamily = s.family  # type: ignore[assignment]
    auto = fam.options["large_strain"] is None
    if fam.large_strain:  # asked for: fitted with the network at once
        _with_large_strain(s)
        return _large_strain_fit(s, segments, start, (amp, freq, stiffness), stage, extra)
    x = fam.guess_from_readings(amp, freq, stiffness, s.x0.copy(), s.given)
    r = s.fit(segments, x, None, stage)
    plain = result_of(s, segments, r.values.copy(), [r], start, extra=extra)
    if not auto or not _poor(plain, segments, fam):
        return plain
    kept = (s.family, s.x0, s.given, s.bounded)
    _with_large_strain(s)
    rich = _large_strain_fit(s, segments, start, (amp, freq, stiffness), stage,
                             {**extra, "four_parts": {"nrmse": plain.fit_error.nrmse, "verdict": "poor fit"}})
    if rich.fit_error.rmse_nm < LARGE_STRAIN_GAIN * plain.fit_error.rmse_nm:
        return rich
    # no clear gain: the family stays as it was (and so does the global search that may follow)
    s.family, s.x0, s.given, s.bounded = kept
    plain.extra["large_strain"] = {"nrmse": rich.fit_error.nrmse, "kept": False}
    return plain


def _poor(result: Identification, segments: list[Segment], fam: FilledRubberFamily) -> bool:
    """Whether the servo verdict on ``result`` is "poor fit" (as the servo strategies' caller
    judges it: the RMS error against the records' noise floor with the last stage's step error
    in quadrature, the parameters on a bound that count)."""
    values = np.array(list(result.parameters.values()), float)
    return servo_verdict(result, servo_noise(segments), fam.parameters, fam.idle_parameters(values)).poor


def _large_strain_fit(s: Setup, segments: list[Segment], start: float, readings: tuple, stage: str,
                      extra: dict[str, Any]) -> Identification:
    """The family with the large-strain network fitted: its first guess from the readings (the
    four parts' closed form, the network's parameters at their start), then the joint least
    squares on every parameter not held."""
    fam: FilledRubberFamily = s.family  # type: ignore[assignment]
    x = fam.guess_from_readings(*readings, s.x0.copy(), s.given)
    r = s.fit(segments, x, [n for n, g in zip(fam.names, s.given) if not g], stage)
    return result_of(s, segments, r.values.copy(), [r], start, extra=extra)


def _with_large_strain(s: Setup) -> FilledRubberFamily:
    """Turn ``s`` (in place) into the family with the large-strain network
    (:meth:`FilledRubberFamily.with_large_strain`; a family that has it already keeps its
    parameters): the user's bounds and initial values kept, the network's from its first guess;
    the parameters of the stiffening it replaces (the equilibrium spring's cubic term at 0, the
    stiffening branch's, which the couplings leave out) held unless the user gave them, as given
    values are in the global search."""
    old: FilledRubberFamily = s.family  # type: ignore[assignment]
    if not old.large_strain:
        fam = old.with_large_strain()
        fam.parameters[:_N_BASE] = old.parameters
        extra = len(fam.parameters) - _N_BASE
        s.family = fam
        s.x0 = np.concatenate([s.x0, fam.guess()[_N_BASE:]])
        s.given = np.concatenate([s.given, np.zeros(extra, bool)])
        s.bounded = np.concatenate([s.bounded, np.zeros(extra, bool)])
    fam = s.family  # type: ignore[assignment]
    held = np.isin(fam.names, REPLACED_BY_LARGE_STRAIN) & ~s.given
    s.x0 = np.where(held, fam.branch_off(s.x0), s.x0)
    cubic = fam.names.index("a_nm_per_rad3")
    if held[cubic]:
        s.x0[cubic] = 0.0
    s.given = s.given | held
    # the scragging's limit held at its bound: D_inf = 1 - exp(-(x_max / x_D)^r), the stretched
    # exponential of Gallardo et al. 2023's Mullins factor, goes on softening at a larger amplitude
    # where a free D_max < 1 is spent on the fitted blocks and stops it (docs/theory.md#large-strain-network)
    scragging = fam.names.index("scragging")
    if not (s.given[scragging] or s.bounded[scragging]):
        s.x0[scragging] = fam.parameters[scragging].upper
        s.given[scragging] = True
    return fam


#: The parameters the large-strain network replaces: held (at 0, or unused) when it is on.
REPLACED_BY_LARGE_STRAIN = ("a_nm_per_rad3", "kv_nm_per_rad", "kv_gain_nm_per_rad2", "tau_v_s")


FAMILY = FilledRubberFamily
strategy = identify_filled_rubber

compile_once_across_processes(globals())  # a kernel no cache holds is compiled by one process at a time
