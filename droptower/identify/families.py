"""The model families of the source papers, as parameter vectors <-> couplings.

Each family names its parameters (unit as suffix), scales their bounds and a first guess to
the data (:class:`~droptower.identify.data.DataScale`), and builds a coupling of the
rheological core from a parameter vector. :meth:`Family.batch` builds ONE coupling whose
parameter sets (rows of ``Coupling.params``) are many parameter vectors: the fitting engine
simulates them all in one call of the core.

Families (NOTES §2): ``zerodim6`` and ``zerodim20`` (seed 000), ``elastoslide`` (seed 001),
``pfeffer`` (seed 002), ``masing`` (seed 003), ``overlay`` (seed 004's map).
"""
from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from droptower.errors import DroptowerError
from droptower.identify.data import DataScale
from droptower.identify.fit import Parameter, clip_to_bounds
from droptower.rheology import Coupling, parse_coupling


class Family:
    """Base of the model families.

    kind: the name on the command line; title, source: for reports and coupling files;
    OPTIONS: family options (``[options]`` of ``--params INIT.toml``) with their defaults.
    """

    kind: ClassVar[str] = ""
    title: ClassVar[str] = ""
    source: ClassVar[str] = ""
    OPTIONS: ClassVar[dict[str, Any]] = {}

    def __init__(self, scale: DataScale, options: dict[str, Any] | None = None):
        self.scale = scale
        options = dict(options or {})
        unknown = set(options) - set(self.OPTIONS) - set(COMMON_OPTIONS)
        if unknown:
            known = sorted(set(self.OPTIONS) | set(COMMON_OPTIONS))
            raise DroptowerError(f"unknown option(s) {', '.join(sorted(unknown))} for model {self.kind} "
                                 f"(known: {', '.join(known)})")
        self.options = {**COMMON_OPTIONS, **self.OPTIONS, **options}
        self.parameters: list[Parameter] = self._parameters()

    # -------------------------------------------------------------- per family
    def _parameters(self) -> list[Parameter]:  # pragma: no cover - abstract
        raise NotImplementedError

    def guess(self) -> np.ndarray:  # pragma: no cover - abstract
        """A first guess from the data's scale (physical values)."""
        raise NotImplementedError

    def elements(self, v: np.ndarray) -> list[dict[str, Any]]:  # pragma: no cover - abstract
        """The ``[[element]]`` tables of the coupling for parameter vector ``v``."""
        raise NotImplementedError

    def derived(self, v: np.ndarray) -> dict[str, float]:
        """Quantities computed from the parameters, for reports."""
        return {}

    @property
    def substeps(self) -> int:
        """Integration steps per data sample (option ``substeps``)."""
        n = int(self.options["substeps"])
        if n < 1:
            raise DroptowerError(f"option substeps must be a positive integer, got {self.options['substeps']}")
        return n

    # -------------------------------------------------------------- common
    @property
    def names(self) -> list[str]:
        return [p.name for p in self.parameters]

    def initial(self) -> np.ndarray:
        return clip_to_bounds(self.parameters, self.guess())

    def vector(self, values: dict[str, float]) -> np.ndarray:
        """Parameter vector from a name -> value mapping (all names required)."""
        missing = [n for n in self.names if n not in values]
        if missing:
            raise DroptowerError(f"missing parameter(s) {', '.join(missing)} for model {self.kind}")
        return np.array([float(values[n]) for n in self.names])

    def coupling(self, v: np.ndarray, *, name: str = "", description: str = "") -> Coupling:
        """The coupling of one parameter vector."""
        data = {"name": name or f"identified_{self.kind}", "description": description or self.title,
                "source": self.source, "units": "torsional", "element": self.elements(np.asarray(v, float))}
        return parse_coupling(data)

    def batch(self, values: np.ndarray) -> Coupling:
        """One coupling whose parameter sets are the rows of ``values`` (M, n)."""
        values = np.atleast_2d(values)
        return Coupling.stack([self.coupling(v) for v in values])


#: Options every family takes: max_nfev (evaluation limit of each least-squares stage; 0: 20
#: per free parameter + 20), skip_s (seconds at each record's start left out of the fit),
#: substeps (integration steps per sample: the rig and the bench integrate finer than they
#: sample, and a model fitted on the sample step alone absorbs that step's discretisation).
COMMON_OPTIONS: dict[str, Any] = {"max_nfev": 0, "skip_s": 0.0, "substeps": 1}


def _stiffness(name: str, s: DataScale, lo: float = 1e-4, hi: float = 1e3) -> Parameter:
    return Parameter(name, lo * s.stiffness_nm_per_rad, hi * s.stiffness_nm_per_rad)


# ---------------------------------------------------------------- seed 000
class ZeroDim6(Family):
    """Seed 000's six-parameter model: spring K1 || Maxwell(K2, C2) || Maxwell(K3(e), C3).

    K3 = k3 + gain |e| with e the branch spring's deformation (linear in the deformation, as
    in seed 000 Fig. 11). The Maxwell branches are parameterised by relaxation times tau =
    C / K; the slow branch relaxes slower than ``tau_split_s``, the fast one faster.
    """

    kind = "zerodim6"
    title = "zero-dimensional six-parameter model: K1 || Maxwell(K2, C2) || Maxwell(K3 + gain |e|, C3)"
    source = "seed 000 (zero-dimensional model), section 5 / Fig. 11"
    OPTIONS = {"tau_split_s": 0.1}

    def _parameters(self):
        s, split = self.scale, float(self.options["tau_split_s"])
        return [_stiffness("k1_nm_per_rad", s), _stiffness("k2_nm_per_rad", s),
                Parameter("tau2_s", split, 1e4), _stiffness("k3_nm_per_rad", s),
                Parameter("k3_gain_nm_per_rad2", 0.0, 1e3 * s.stiffness_nm_per_rad / s.amplitude_rad, log=False,
                          scale=s.stiffness_nm_per_rad / s.amplitude_rad),
                Parameter("tau3_s", 1e-6, split)]

    def guess(self):
        s = self.scale
        k = s.stiffness_nm_per_rad
        tau3 = 0.3 / (2 * np.pi * max(s.frequency_hz, 1e-3))
        return np.array([0.5 * k, 0.3 * k, 10 * float(self.options["tau_split_s"]), 0.5 * k, 0.0, tau3])

    def elements(self, v):
        k1, k2, tau2, k3, gain, tau3 = v
        return [{"kind": "spring", "name": "K1", "stiffness": k1},
                {"kind": "maxwell", "name": "K2-C2", "stiffness": k2, "damping": k2 * tau2},
                {"kind": "variable_maxwell", "name": "K3-C3", "stiffness": k3, "stiffness_gain": gain,
                 "damping": k3 * tau3}]

    def derived(self, v):
        k1, k2, tau2, k3, gain, tau3 = v
        return {"c2_nms_per_rad": k2 * tau2, "c3_nms_per_rad": k3 * tau3}


#: Where the lookup tables of ``zerodim20`` get their end-clamp points (times the last breakpoint).
FAR = 1e3


class ZeroDim20(Family):
    """Seed 000's lookup-table model with the Mullins filter, 20 parameters.

    Mullins filter (eq. 3): slow stiffness, fast minus slow stiffness, time constant tau (3);
    a Maxwell branch whose spring stiffness is a 9-point table over its deformation
    (breakpoints evenly over +-the largest amplitude of the data) and whose damping is an
    8-point table over its rate (0 .. the largest rate of the data): 9 + 8 = 17. Seed 000
    reduced its 45 lookup values to 20; this is one such choice. Beyond their breakpoints the
    tables hold their end values. Within them it contains the six-parameter model exactly
    (tables linear in |e| and constant), so it starts from that fit.
    """

    kind = "zerodim20"
    title = "zero-dimensional lookup-table model with Mullins filter (20 parameters)"
    source = "seed 000 (zero-dimensional model), section 4, eq. 3"
    OPTIONS = {"deformation_max_rad": 0.0, "rate_max_rad_per_s": 0.0}
    N_STIFF = 9
    N_DAMP = 8

    def _parameters(self):
        s = self.scale
        self.set_breakpoints(float(self.options["deformation_max_rad"]) or s.amplitude_rad,
                             float(self.options["rate_max_rad_per_s"]) or s.rate_rad_per_s)
        c_hi = 1e3 * s.stiffness_nm_per_rad
        return ([_stiffness("k_slow_nm_per_rad", s), _stiffness("k_fast_minus_slow_nm_per_rad", s),
                 Parameter("tau_mullins_s", 1e-3, 1e4)]
                + [_stiffness(f"k3_{i + 1}_nm_per_rad", s) for i in range(self.N_STIFF)]
                + [Parameter(f"c3_{i + 1}_nms_per_rad", 1e-9 * c_hi, c_hi) for i in range(self.N_DAMP)])

    def set_breakpoints(self, deformation_max_rad: float, rate_max_rad_per_s: float) -> None:
        """Table breakpoints: stiffness over +-deformation_max (the branch spring's own
        deformation), damping over 0 .. rate_max (its dashpot's rate)."""
        self.deformation_rad = np.linspace(-deformation_max_rad, deformation_max_rad, self.N_STIFF)
        self.rate_rad_per_s = np.linspace(0.0, rate_max_rad_per_s, self.N_DAMP)

    def guess(self):
        return self.from_zerodim6(ZeroDim6(self.scale).guess())

    def from_zerodim6(self, v6: np.ndarray) -> np.ndarray:
        """The 20 parameters that reproduce a six-parameter model exactly."""
        k1, k2, tau2, k3, gain, tau3 = v6
        return np.concatenate([[k1, k2, tau2], k3 + gain * np.abs(self.deformation_rad),
                               np.full(self.N_DAMP, k3 * tau3)])

    def elements(self, v):
        k_slow, dk, tau = v[:3]
        ks = v[3:3 + self.N_STIFF]
        cs = v[3 + self.N_STIFF:]
        # beyond its breakpoints a table holds its end value (one more point far out): the
        # core extrapolates linearly, which could turn a falling damping table negative on
        # data faster than the fitting data (a lookup table's usual end clamp)
        e, far = self.deformation_rad, FAR * self.deformation_rad[-1]
        return [{"kind": "mullins", "name": "Mullins filter", "tau": tau, "slow_stiffness": k_slow,
                 "fast_stiffness": k_slow + dk},
                {"kind": "variable_maxwell", "name": "K3-C3 tables",
                 "stiffness_table": {"x": [-far, *e.tolist(), far], "y": [ks[0], *ks.tolist(), ks[-1]]},
                 "damping_table": {"x": [*self.rate_rad_per_s.tolist(), FAR * self.rate_rad_per_s[-1]],
                                   "y": [*cs.tolist(), cs[-1]]}}]


# ---------------------------------------------------------------- seed 001
class ElastoslideFamily(Family):
    """Seed 001's distributed rate-dependent elastoslide model: phi0, k, k0, v_r, p; with
    option ``maxwell_terms`` (0-2, default 0) also Maxwell branches (c_i, tau_i) in parallel
    for viscous frequency dependence (the structure of the ``rapp2022_nr60`` preset).

    p (odd integer) is chosen by a search over ``p_candidates``, never by the gradient
    optimiser; ``n`` is the number of discrete elastoslide elements.
    """

    kind = "elastoslide"
    title = "distributed rate-dependent elastoslide model (phi0, k, k0, v_r, p)"
    source = "seed 001 (distributed rate-dependent elastoslide model), eq. 13-25"
    OPTIONS = {"n": 32, "p_candidates": [3, 5, 7, 9, 11], "maxwell_terms": 0}

    def _parameters(self):
        s = self.scale
        p = [int(v) for v in self.options["p_candidates"]]
        if not p or any(v < 1 or v % 2 == 0 for v in p):
            raise DroptowerError(f"p_candidates must be odd positive integers, got {p}")
        if int(self.options["maxwell_terms"]) not in (0, 1, 2):
            raise DroptowerError(f"option maxwell_terms must be 0, 1 or 2, got {self.options['maxwell_terms']}")
        maxwell = []
        for i in range(self.n_maxwell):
            maxwell += [_stiffness(f"c{i + 1}_nm_per_rad", s, 1e-6, 1e2), Parameter(f"tau{i + 1}_s", 1e-6, 1e3)]
        return [Parameter("phi0_per_nm", 1e-4 / s.torque_nm, 1e4 / s.torque_nm),
                _stiffness("k_nm_per_rad", s, 1e-3, 1e4), _stiffness("k0_nm_per_rad", s, 1e-6, 1e2),
                Parameter("v_r_rad_per_s", 1e-8, 1e4), Parameter("p", 1.0, 99.0, log=False)] + maxwell

    @property
    def n_maxwell(self) -> int:
        return int(self.options["maxwell_terms"])

    def guess(self):
        s = self.scale
        k = s.stiffness_nm_per_rad
        w = 2 * np.pi * max(s.frequency_hz, 1e-3)
        maxwell = [[0.05 * k, 1.0 / w], [0.05 * k, 0.1 / w]][:self.n_maxwell]
        return np.array([1.0 / (0.5 * s.torque_nm), 2.0 * k, 0.3 * k, 0.1 * s.rate_rad_per_s,
                         float(self.options["p_candidates"][len(self.options["p_candidates"]) // 2])]
                        + [v for term in maxwell for v in term])

    def derived(self, v):
        phi0, k, k0, v_r, p = v[:5]
        # invariant under phi0 -> phi0 / a, v_r -> v_r a^p: the identifiable combination
        out = {"mean_slip_torque_at_1_rad_per_s_nm": float((1.0 / phi0) * (1.0 / v_r) ** (1.0 / p))}
        for i in range(self.n_maxwell):
            out[f"d{i + 1}_nms_per_rad"] = float(v[5 + 2 * i] * v[6 + 2 * i])
        return out

    def elements(self, v):
        phi0, k, k0, v_r, p = v[:5]
        out = [{"kind": "elastoslide", "phi0": phi0, "k": k, "k0": k0, "v_r": v_r, "p": int(round(p)),
                "n": int(self.options["n"])}]
        for i in range(self.n_maxwell):
            c, tau = v[5 + 2 * i], v[6 + 2 * i]
            out.append({"kind": "maxwell", "name": f"Maxwell {i + 1}", "stiffness": c, "damping": c * tau})
        return out


def loading_curve(amplitude_rad: np.ndarray, phi0: float, k: float, k0: float) -> np.ndarray:
    """Seed 001 eq. 24: T = (1/phi0) (1 - exp(-k phi0 A)) + k0 A (N*m)."""
    return (1.0 - np.exp(-k * phi0 * amplitude_rad)) / phi0 + k0 * amplitude_rad


# ---------------------------------------------------------------- seed 002
class PfefferFamily(Family):
    """Seed 002's linear Pfeffer model: k1 || c1 in series with (k2 || c2); alpha = k2/k1,
    beta = c2/c1, gamma = c1/k1 (NOTES §2.3)."""

    kind = "pfeffer"
    title = "linear Pfeffer bushing model (k1, alpha, beta, gamma)"
    source = "seed 002 (Pfeffer bushing model, linearised), NOTES 2.3"
    OPTIONS = {"layout_frequency_hz": 0.0, "peak_frequency_hz": 0.0}

    def _parameters(self):
        return [_stiffness("k1_nm_per_rad", self.scale), Parameter("alpha", 1e-4, 1e3),
                Parameter("beta", 0.0, 1e3, log=False), Parameter("gamma_s", 1e-7, 1e3)]

    def guess(self):
        s = self.scale
        return np.array([0.5 * s.stiffness_nm_per_rad, 1.0, 0.01, 1.0 / (2 * np.pi * max(s.frequency_hz, 1e-3))])

    def elements(self, v):
        k1, alpha, beta, gamma = v
        return [{"kind": "pfeffer", "k1": k1, "alpha": alpha, "beta": beta, "gamma": gamma}]

    def derived(self, v):
        k1, alpha, beta, gamma = v
        return {"k2_nm_per_rad": alpha * k1, "c1_nms_per_rad": gamma * k1, "c2_nms_per_rad": beta * gamma * k1}


# ---------------------------------------------------------------- seed 003
class MasingFamily(Family):
    """Seed 003's Masing model: n Prandtl elements (stiffness k each, limits R e^{alpha(eta-1)})
    + cubic spring A x^3 + B x + two Maxwell elements (C_i, D_i = C_i tau_i), optionally with
    the constriction S(x) = (|tanh(P x)| + K)/(1 + K).

    Seed 003 works in units normalised by R; here R (N*m) is a parameter.
    """

    kind = "masing"
    title = "Masing model: Prandtl elements + cubic spring + two Maxwell elements"
    source = "seed 003 (Masing model with Prandtl elements), NOTES 2.4"
    OPTIONS = {"n": 7, "constriction": False, "amplitude_deg": 0.0, "frequency_hz": 0.0,
               "amplitude_function": "auto"}
    MASING = ("a_nm_per_rad3", "b_nm_per_rad", "k_nm_per_rad", "r_nm", "alpha")
    CONSTRICTION = ("p_c_per_rad", "k_c")
    MAXWELL = ("c1_nm_per_rad", "tau1_s", "c2_nm_per_rad", "tau2_s")

    def _parameters(self):
        s = self.scale
        k = s.stiffness_nm_per_rad
        out = [Parameter("a_nm_per_rad3", 0.0, 1e3 * s.torque_nm / s.amplitude_rad ** 3, log=False,
                         scale=s.torque_nm / s.amplitude_rad ** 3),
               Parameter("b_nm_per_rad", 0.0, 1e3 * k, log=False, scale=k),
               _stiffness("k_nm_per_rad", s, 1e-4, 1e4), Parameter("r_nm", 1e-6 * s.torque_nm, 1e3 * s.torque_nm),
               Parameter("alpha", 0.0, 30.0, log=False)]
        if self.options["constriction"]:
            out += [Parameter("p_c_per_rad", 1e-3 / s.amplitude_rad, 1e4 / s.amplitude_rad),
                    Parameter("k_c", 0.0, 1e3, log=False)]
        out += [_stiffness("c1_nm_per_rad", s), Parameter("tau1_s", 1e-6, 1e3),
                _stiffness("c2_nm_per_rad", s), Parameter("tau2_s", 1e-6, 1e3)]
        return out

    @property
    def n_masing(self) -> int:
        return len(self.MASING) + (len(self.CONSTRICTION) if self.options["constriction"] else 0)

    def guess(self):
        s = self.scale
        k = s.stiffness_nm_per_rad
        w = 2 * np.pi * max(s.frequency_hz, 1e-3)
        masing = [0.0, 0.3 * k, 2.0 * k / int(self.options["n"]), 0.3 * s.torque_nm / int(self.options["n"]), 2.0]
        if self.options["constriction"]:
            masing += [3.0 / s.amplitude_rad, 1.0]
        return np.array(masing + [0.2 * k, 3.0 / w, 0.2 * k, 0.1 / w])

    def elements(self, v):
        a, b, k, r, alpha = v[:5]
        masing = {"kind": "masing", "n": int(self.options["n"]), "stiffness": k, "max_yield_torque": r, "alpha": alpha}
        if self.options["constriction"]:
            masing["constriction"] = {"p": v[5], "k": v[6]}
        c1, tau1, c2, tau2 = v[self.n_masing:]
        return [{"kind": "cubic_spring", "a": a, "b": b}, masing,
                {"kind": "maxwell", "name": "Maxwell 1", "stiffness": c1, "damping": c1 * tau1},
                {"kind": "maxwell", "name": "Maxwell 2", "stiffness": c2, "damping": c2 * tau2}]

    def derived(self, v):
        c1, tau1, c2, tau2 = v[self.n_masing:]
        return {"d1_nms_per_rad": c1 * tau1, "d2_nms_per_rad": c2 * tau2}


# ---------------------------------------------------------------- seed 004
class OverlayFamily(Family):
    """Seed 004's characteristic map as a model: a linear Kelvin-Voigt coupling (spring k,
    dashpot c) whose k and c follow the map at each cycle's amplitude and frequency.

    The parameter vector is one (k, c) pair; the map is identified by the strategy.
    """

    kind = "overlay"
    title = "characteristic-map overlay: Kelvin-Voigt with map stiffness and damping"
    source = "seed 004 (drop-tower characteristic map), eq. 19-20"
    OPTIONS = {"amplitude_deg": 0.0, "frequency_hz": 0.0}

    def _parameters(self):
        s = self.scale
        return [_stiffness("k_nm_per_rad", s), Parameter("c_nms_per_rad", 1e-9 * s.stiffness_nm_per_rad,
                                                         1e3 * s.stiffness_nm_per_rad)]

    def guess(self):
        s = self.scale
        return np.array([s.stiffness_nm_per_rad, 0.1 * s.stiffness_nm_per_rad / (2 * np.pi * max(s.frequency_hz, 1e-3))])

    def elements(self, v):
        k, c = v
        return [{"kind": "spring", "stiffness": k}, {"kind": "dashpot", "damping": c}]


FAMILIES: dict[str, type[Family]] = {f.kind: f for f in (ZeroDim6, ZeroDim20, ElastoslideFamily, PfefferFamily,
                                                          MasingFamily, OverlayFamily)}


def family_class(kind: str) -> type[Family]:
    """The family of a ``--model`` name; a one-line error for an unknown one."""
    if kind not in FAMILIES:
        raise DroptowerError(f"unknown model kind {kind!r} (known: {', '.join(FAMILIES)})")
    return FAMILIES[kind]
