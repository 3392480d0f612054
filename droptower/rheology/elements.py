"""The element kinds a coupling TOML may use, validated, and compiled into kernel elements.

Each ``[[element]]`` table of a coupling file is one of the models below (field ``kind``).
All values are SI and torsional (rad, N*m, N*m/rad, N*m*s/rad, s); a file that says
``units = "translational"`` reads the same numbers as m, N, N/m, N*s/m.

Compilation turns an element into one or more kernel elements (:mod:`.kernels`): e.g. a
``prony`` series becomes a spring and n Maxwell branches, an ``elastoslide`` a spring and a
bank of rate-dependent sliders, ``mullins`` a spring (or static table) and a Maxwell branch.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Annotated, ClassVar, Literal, Union

import numpy as np
from numpy.typing import ArrayLike
from pydantic import Field, PositiveFloat, NonNegativeFloat, PositiveInt, field_validator, model_validator

from droptower.limits import MAX_ELEMENT_N
from droptower.rheology import kernels as K
from droptower.rheology import kinds
from droptower.config_validation import StrictModel


@dataclass(frozen=True)
class KernelElement:
    """One compiled element: kernel code and parameter vector, in the layout of its kind's
    record (:mod:`.kinds`), which also gives the number of internal state variables (a given
    ``n_internal`` must agree with it)."""

    code: int
    params: np.ndarray
    n_internal: int | None = None
    label: str = ""

    def __post_init__(self) -> None:
        kind = kinds.kind_of(self.code)
        kind.check(self.params)
        n = kind.internal_size(self.params)
        if self.n_internal is not None and self.n_internal != n:
            raise ValueError(f"a {kind.name} kernel element has {n} internal variables, not {self.n_internal}")
        object.__setattr__(self, "n_internal", n)

    @property
    def n_state(self) -> int:
        return K.N_HEADER + self.n_internal


class ElementSpec(StrictModel):
    """Common fields: ``kind`` and an optional ``name`` for reports. ``SETTINGS``: fields that
    set up the element rather than describe the material (time constants of its bookkeeping, a
    band that fixes the number of internal terms): identification keeps them as they are."""

    SETTINGS: ClassVar[frozenset[str]] = frozenset()
    name: str = ""

    def compile(self) -> list[KernelElement]:  # pragma: no cover - abstract
        raise NotImplementedError

    def label(self, index: int) -> str:
        return self.name or f"{self.kind}#{index}"  # type: ignore[attr-defined]


def _strictly_increasing(values: list[float], what: str) -> list[float]:
    if len(values) < 2:
        raise ValueError(f"{what} needs at least 2 points")
    if np.any(np.diff(values) <= 0):
        raise ValueError(f"{what} must be strictly increasing")
    if not np.all(np.isfinite(values)):
        raise ValueError(f"{what} must be finite")
    return values


def knot_energies(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Stored energy (integral of the piecewise-linear curve y(x) from 0) at each knot.

    Trapezoids accumulated from the first knot, shifted so that the energy at 0 is zero (the
    curve is linear on the segment holding 0 and passes through (0, 0)).
    """
    cumulative = np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * np.diff(x))])
    i = int(np.clip(np.searchsorted(x, 0.0, side="right") - 1, 0, x.size - 2))
    return cumulative - (cumulative[i] - 0.5 * y[i] * x[i])


# ------------------------------------------------------------------ springs
class Spring(ElementSpec):
    """Linear spring, T = stiffness * angle."""

    kind: Literal["spring"]
    stiffness: NonNegativeFloat  # N*m/rad

    def compile(self):
        return [KernelElement(K.LINEAR_SPRING, np.array([self.stiffness]))]


class SpringTable(ElementSpec):
    """Static nonlinear curve T(angle), piecewise linear (Scheiblegger et al.'s (2013) k1 table).

    The curve must pass through (0, 0) and rise monotonically (a passive, stable spring);
    outside the table it continues with the end slopes.
    """

    kind: Literal["spring_table"]
    angle: list[float]   # rad
    torque: list[float]  # N*m

    @field_validator("angle")
    @classmethod
    def _angles(cls, v):
        return _strictly_increasing(v, "angle")

    @model_validator(mode="after")
    def _curve(self):
        if len(self.torque) != len(self.angle):
            raise ValueError("torque and angle must have the same length")
        if np.any(np.diff(self.torque) <= 0):
            raise ValueError("torque must rise with angle (a falling static curve is unstable)")
        t0 = np.interp(0.0, self.angle, self.torque) if self.angle[0] <= 0 <= self.angle[-1] else None
        if t0 is None or abs(t0) > 1e-9 * max(1.0, max(abs(x) for x in self.torque)):
            raise ValueError("the static curve must pass through angle 0 with torque 0")
        return self

    def compile(self):
        x, y = np.asarray(self.angle), np.asarray(self.torque)
        return [KernelElement(K.TABLE_SPRING, np.concatenate([[x.size], x, y, knot_energies(x, y)]))]


class CubicSpring(ElementSpec):
    """T = A*angle^3 + B*angle (Heine & Plagemann's (2014) nonlinear spring)."""

    kind: Literal["cubic_spring"]
    a: float = Field(description="N*m/rad^3")
    b: float = Field(description="N*m/rad")

    @model_validator(mode="after")
    def _stable(self):
        if self.b < 0 or self.a < 0:
            raise ValueError("a and b must be >= 0 (a falling spring curve is unstable)")
        return self

    def compile(self):
        return [KernelElement(K.CUBIC_SPRING, np.array([self.a, self.b]))]


# ------------------------------------------------------------------ viscous
class Dashpot(ElementSpec):
    """Linear dashpot, T = damping * rate."""

    kind: Literal["dashpot"]
    damping: NonNegativeFloat  # N*m*s/rad

    def compile(self):
        return [KernelElement(K.DASHPOT, np.array([self.damping]))]


class Maxwell(ElementSpec):
    """Spring in series with a dashpot (the zero-dimensional model paper, eq. 1); relaxation time damping/stiffness."""

    kind: Literal["maxwell"]
    stiffness: PositiveFloat  # N*m/rad
    damping: PositiveFloat    # N*m*s/rad

    def compile(self):
        return [KernelElement(K.MAXWELL, np.array([self.stiffness, self.damping]))]


class PronyTerm(StrictModel):
    stiffness: PositiveFloat      # N*m/rad
    relaxation_time: PositiveFloat  # s


class Prony(ElementSpec):
    """Generalized Maxwell: equilibrium stiffness plus Maxwell terms (k_i, tau_i)."""

    kind: Literal["prony"]
    equilibrium_stiffness: NonNegativeFloat  # N*m/rad
    terms: list[PronyTerm] = Field(min_length=1)

    def compile(self):
        out = [KernelElement(K.LINEAR_SPRING, np.array([self.equilibrium_stiffness]))]
        for t in self.terms:
            out.append(KernelElement(K.MAXWELL, np.array([t.stiffness, t.stiffness * t.relaxation_time])))
        return out


class PowerLaw(ElementSpec):
    """A power-law (fractional, "springpot") viscoelastic branch over a band of relaxation
    frequencies, as a Prony series spread over the decades of the band.

    The springpot K*(f) = storage_stiffness (1 + i loss_factor) (f / reference_frequency)^alpha,
    alpha = (2/pi) atan(loss_factor) (Bagley & Torvik's fractional derivative model), has the
    relaxation spectrum H(tau) = K0 sin(alpha pi)/pi (tau0/tau)^alpha over every time scale.
    This branch keeps the part of it whose relaxation frequencies 1/(2 pi tau) lie in
    [min_frequency, max_frequency]: Maxwell terms log-spaced over the band, ``terms_per_decade``
    per decade, each weighted by H times the spacing in ln tau (the midpoint rule in log time,
    whose aliasing error falls like exp(-pi^2 / spacing): 2e-4 at two terms per decade). Inside
    the band, away from its edges, the loss follows the springpot's; the storage lacks the
    spectrum's slower part (for a small alpha most of it: the branch relaxes completely below
    the band, so a held preload relaxes it). :meth:`complex_stiffness` gives K* as compiled.
    """

    SETTINGS: ClassVar[frozenset[str]] = frozenset({"reference_frequency", "min_frequency", "max_frequency",
                                                     "terms_per_decade"})
    kind: Literal["power_law"]
    storage_stiffness: PositiveFloat       # N*m/rad, K' at the reference frequency
    loss_factor: PositiveFloat             # -, K''/K' inside the band
    reference_frequency: PositiveFloat     # Hz
    min_frequency: PositiveFloat           # Hz, lowest relaxation frequency of the band
    max_frequency: PositiveFloat           # Hz, highest
    terms_per_decade: PositiveFloat = 2.0  # -

    @model_validator(mode="after")
    def _band(self):
        if not self.max_frequency > self.min_frequency:
            raise ValueError("max_frequency must exceed min_frequency")
        if self.terms().shape[0] > 200:
            raise ValueError("the band needs more than 200 terms: narrow it or use fewer terms per decade")
        return self

    @property
    def alpha(self) -> float:
        """The power-law exponent (:func:`power_law_exponent`)."""
        return power_law_exponent(self.loss_factor)

    def terms(self) -> np.ndarray:
        """(n, 2): stiffness (N*m/rad) and relaxation time (s) of each Maxwell term."""
        return power_law_terms(self.storage_stiffness, self.loss_factor, self.reference_frequency,
                               self.min_frequency, self.max_frequency, self.terms_per_decade)

    def compile(self):
        k, tau = self.terms().T
        return [KernelElement(K.MAXWELL_BANK, np.concatenate([[k.size], k, k * tau]))]

    def complex_stiffness(self, frequency_hz: ArrayLike) -> np.ndarray:
        """K*(f) (N*m/rad) of the Prony series as compiled (:func:`power_law_complex_stiffness`)."""
        return power_law_complex_stiffness(self.storage_stiffness, self.loss_factor, self.reference_frequency,
                                           self.min_frequency, self.max_frequency, self.terms_per_decade,
                                           frequency_hz)


def power_law_exponent(loss_factor: ArrayLike) -> float | np.ndarray:
    """The exponent alpha = (2/pi) atan(eta) of a power law whose loss factor is eta at every
    frequency (Bagley & Torvik 1983): a float for a number, an array of the shape of an array."""
    alpha = 2 / np.pi * np.arctan(loss_factor)
    return float(alpha) if np.ndim(alpha) == 0 else alpha


@lru_cache(maxsize=64)
def _log_tau_grid(min_frequency: float, max_frequency: float, terms_per_decade: float) -> tuple[np.ndarray, np.ndarray]:
    """(ln tau, tau) of a power-law band's terms (read-only, cached: a fit varies the level and
    the exponent far more often than the band)."""
    lo, hi = np.log(1 / (2 * np.pi * max_frequency)), np.log(1 / (2 * np.pi * min_frequency))
    n = int(np.ceil((hi - lo) / np.log(10) * terms_per_decade)) + 1
    log_tau = np.linspace(lo, hi, n)
    tau = np.exp(log_tau)
    log_tau.flags.writeable = tau.flags.writeable = False
    return log_tau, tau


def power_law_terms(storage_stiffness: ArrayLike, loss_factor: ArrayLike, reference_frequency: ArrayLike,
                    min_frequency: float, max_frequency: float, terms_per_decade: float) -> np.ndarray:
    """(..., n, 2): stiffness (N*m/rad) and relaxation time (s) of each Maxwell term of a
    :class:`PowerLaw` branch (its fields, SI; not validated): the springpot's relaxation
    spectrum over the band by the midpoint rule in ln tau. Numbers give (n, 2); the level, loss
    factor and reference frequency may be arrays of parameter sets (broadcast together, their
    shape before the terms' axis), the band is one number each (it sets n)."""
    alpha = np.asarray(power_law_exponent(loss_factor))[..., None]  # the terms' axis last
    k0 = np.asarray(storage_stiffness, float)[..., None] / np.cos(alpha * np.pi / 2)  # K0 (i w tau0)^alpha has K' = K0 cos(alpha pi/2) at w tau0 = 1
    tau0 = 1 / (2 * np.pi * np.asarray(reference_frequency, float)[..., None])
    log_tau, tau = _log_tau_grid(float(min_frequency), float(max_frequency), float(terms_per_decade))
    weight = k0 * np.sin(alpha * np.pi) / np.pi * (tau0 / tau) ** alpha * (log_tau[1] - log_tau[0])
    out = np.empty(weight.shape + (2,))
    out[..., 0], out[..., 1] = weight, tau
    return out


def power_law_complex_stiffness(storage_stiffness: ArrayLike, loss_factor: ArrayLike, reference_frequency: ArrayLike,
                                min_frequency: float, max_frequency: float, terms_per_decade: float,
                                frequency_hz: ArrayLike) -> np.ndarray:
    """K*(f) (N*m/rad) at frequencies f (Hz) of a :class:`PowerLaw` branch's Prony series as
    compiled (its fields, SI; not validated): a pure function of numbers, which the first guess
    of a fit evaluates some ten thousand times. The level, loss factor and reference frequency
    may be arrays of parameter sets that broadcast with the frequencies (e.g. (M, 1) against
    (N,) gives (M, N)); the band is one for all (:func:`power_law_terms`)."""
    s = 2j * np.pi * np.asarray(frequency_hz, float)[..., None]
    terms = power_law_terms(storage_stiffness, loss_factor, reference_frequency, min_frequency, max_frequency,
                            terms_per_decade)
    k, tau = terms[..., 0], terms[..., 1]
    return np.sum(k * s * tau / (1 + s * tau), axis=-1)


# ------------------------------------------------------------------ friction
def _bank(stiffness: np.ndarray, yield_torque: np.ndarray, rate: float = 0.0, exponent: int = 0,
          constriction: tuple[float, float] = (0.0, 0.0)) -> KernelElement:
    n = stiffness.size
    params = np.concatenate([[n, rate, exponent, constriction[0], constriction[1]], stiffness, yield_torque,
                             stiffness / yield_torque, yield_torque / stiffness])
    return KernelElement(K.SLIDER_BANK, params)


class Prandtl(ElementSpec):
    """Jenkins element: spring in series with a Coulomb slider."""

    kind: Literal["prandtl"]
    stiffness: PositiveFloat     # N*m/rad
    yield_torque: PositiveFloat  # N*m

    def compile(self):
        return [_bank(np.array([self.stiffness]), np.array([self.yield_torque]))]


class Constriction(StrictModel):
    """Heine & Plagemann's (2014) loop-waist scaling S(x) = (|tanh(P x)| + K) / (1 + K)."""

    p: PositiveFloat               # 1/rad
    k: NonNegativeFloat            # -


def _at_most_max_n(n: int) -> int:
    """A discretised element's ``n``: memory and run time grow with it (32-100 resolve a distribution)."""
    if n > MAX_ELEMENT_N:
        raise ValueError(f"n = {n} exceeds the limit of {MAX_ELEMENT_N} elements (memory and run time grow "
                         "with n; 32-100 resolve a yield distribution): use fewer")
    return n


def masing_yield_torques(max_yield_torque: float, alpha: float, n: int) -> np.ndarray:
    """Heine & Plagemann 2014: R_i = R exp(alpha (eta_i - 1)), eta_i = (i - 1)/(n - 1), i = 1..n."""
    eta = np.arange(n) / max(n - 1, 1)
    return max_yield_torque * np.exp(alpha * (eta - 1.0))


class Masing(ElementSpec):
    """n Prandtl elements in parallel, equal stiffness, exponentially distributed limits (Heine & Plagemann 2014)."""

    kind: Literal["masing"]
    n: PositiveInt = 7
    stiffness: PositiveFloat         # N*m/rad, of each Prandtl element
    max_yield_torque: PositiveFloat  # N*m, R
    alpha: NonNegativeFloat          # -, spread of the limits
    constriction: Constriction | None = None

    _n_limit = field_validator("n")(_at_most_max_n)

    def compile(self):
        yields = masing_yield_torques(self.max_yield_torque, self.alpha, self.n)
        c = (self.constriction.p, self.constriction.k) if self.constriction else (0.0, 0.0)
        return [_bank(np.full(self.n, self.stiffness), yields, constriction=c)]


class YieldDistribution(StrictModel):
    """A user-supplied yield-force distribution: points f* and their weights (normalised)."""

    yield_torque: list[PositiveFloat]  # N*m (f* per unit of the distribution)
    weight: list[PositiveFloat]

    @model_validator(mode="after")
    def _same_length(self):
        if len(self.weight) != len(self.yield_torque) or not self.weight:
            raise ValueError("yield_torque and weight must be non-empty lists of the same length")
        _at_most_max_n(len(self.weight))
        return self


def exponential_bins(phi0: float, n: int, f_min: float, f_max: float) -> tuple[np.ndarray, np.ndarray]:
    """Discretise phi(f*) = phi0 exp(-phi0 f*) into n elements over [f_min, f_max].

    Bin edges are spaced evenly in probability inside [f_min, f_max]; the mass below
    f_min and above f_max is lumped into the first and last bins. Each element carries its
    bin's probability as weight and the bin's conditional mean f* as yield force, so the
    total weight is 1 and the full-slip force (1/phi0) is exact.
    """
    cdf_lo = 1.0 - np.exp(-phi0 * f_min)
    cdf_hi = 1.0 - np.exp(-phi0 * f_max)
    inner = np.linspace(cdf_lo, cdf_hi, n + 1)
    inner[0], inner[-1] = 0.0, 1.0
    edges = np.append(-np.log1p(-inner[:-1]) / phi0, np.inf)
    weights = np.diff(inner)

    def partial_mean(f):  # integral of f phi(f) df from 0 to f
        with np.errstate(invalid="ignore"):
            val = (1.0 - np.exp(-phi0 * f) * (1.0 + phi0 * f)) / phi0
        return np.where(np.isinf(f), 1.0 / phi0, val)

    means = np.diff(partial_mean(edges)) / weights
    return weights, means


class Elastoslide(ElementSpec):
    """Distributed rate-dependent elastoslide model (the elastoslide paper, docs/theory.md#elastoslide).

    A parallel spring k0 plus a continuum of elastoslide elements (leading spring k, slider
    yield force f* with density phi(f*)), discretised into ``n`` elements. The default
    density is exponential with parameter ``phi0`` (eq. 25) over the yield range
    ``[yield_min, yield_max]`` (default: 0 to the 99.9 % quantile); a user distribution may
    be given instead.
    """

    kind: Literal["elastoslide"]
    phi0: PositiveFloat | None = None   # 1/(N*m)
    k: PositiveFloat                    # N*m/rad, leading spring
    k0: NonNegativeFloat                # N*m/rad, parallel spring
    v_r: PositiveFloat                  # rad/s, reference slip rate
    p: PositiveInt = 7                  # odd exponent
    n: PositiveInt = 32
    yield_min: NonNegativeFloat | None = None  # N*m
    yield_max: PositiveFloat | None = None     # N*m
    distribution: YieldDistribution | None = None

    _n_limit = field_validator("n")(_at_most_max_n)

    @field_validator("p")
    @classmethod
    def _odd(cls, v):
        if v % 2 == 0:
            raise ValueError("p must be an odd integer (an even p makes the slip rate ignore the force's sign)")
        return v

    @model_validator(mode="after")
    def _distribution(self):
        if self.distribution is None and self.phi0 is None:
            raise ValueError("give phi0 (exponential distribution) or a distribution")
        if self.distribution is not None and self.phi0 is not None:
            raise ValueError("give either phi0 or a distribution, not both")
        if self.distribution is not None and (self.yield_min is not None or self.yield_max is not None):
            raise ValueError("yield_min and yield_max apply to the exponential distribution (phi0), not to a given one")
        if self.distribution is None:
            lo = self.yield_min or 0.0
            hi = self.yield_max if self.yield_max is not None else -np.log(1e-3) / self.phi0
            if not hi > lo:
                raise ValueError(f"yield range [{lo}, {hi}] is empty: yield_max must exceed yield_min")
            if lo * self.phi0 > 5.0:
                raise ValueError("yield_min lies beyond 99 % of the distribution: the yield range misses it")
        return self

    def bins(self) -> tuple[np.ndarray, np.ndarray]:
        """(weights, yield forces f*) of the discrete elements."""
        if self.distribution is not None:
            w = np.asarray(self.distribution.weight, float)
            return w / w.sum(), np.asarray(self.distribution.yield_torque, float)
        lo = self.yield_min or 0.0
        hi = self.yield_max if self.yield_max is not None else -np.log(1e-3) / self.phi0
        return exponential_bins(self.phi0, self.n, lo, hi)

    def compile(self):
        w, f = self.bins()
        # element i: spring k w_i, slider limit w_i f*_i, so k e / f* is the same ratio
        bank = _bank(self.k * w, w * f, rate=self.v_r, exponent=self.p)
        return [KernelElement(K.LINEAR_SPRING, np.array([self.k0])), bank] if self.k0 > 0 else [bank]


# ------------------------------------------------------------------ the zero-dimensional model paper
class Table(StrictModel):
    """A lookup table (x, y) with linear interpolation."""

    x: list[float]
    y: list[PositiveFloat]

    @model_validator(mode="after")
    def _shape(self):
        _strictly_increasing(self.x, "x")
        if len(self.x) != len(self.y):
            raise ValueError("x and y must have the same length")
        return self


class Mullins(ElementSpec):
    """The zero-dimensional model paper, eq. 3: the angle split by a first-order low-pass (time constant tau) into a
    slow part carried by ``slow_stiffness`` (or the static curve ``slow_curve``) and a fast
    part carried by ``fast_stiffness``.

    T = k1 LP(x) + k2 (x - LP(x)) = k1 x + (k2 - k1) HP(x): a spring k1 in parallel with a
    Maxwell branch (k2 - k1, tau (k2 - k1)). After a change of mean load the fast stiffness
    acts first and relaxes to the slow one over tau: the first cycles are stiffer.
    k2 >= k1 is required (otherwise the element would generate energy).
    """

    kind: Literal["mullins"]
    tau: PositiveFloat                        # s
    slow_stiffness: PositiveFloat | None = None  # N*m/rad
    slow_curve: SpringTable | None = None
    fast_stiffness: PositiveFloat             # N*m/rad

    @model_validator(mode="after")
    def _passive(self):
        if (self.slow_stiffness is None) == (self.slow_curve is None):
            raise ValueError("give exactly one of slow_stiffness and slow_curve")
        if self.fast_stiffness < self.slow_stiffness_at_zero():
            raise ValueError("fast_stiffness must be >= the slow stiffness at angle 0 (else the element is not passive)")
        return self

    def slow_stiffness_at_zero(self) -> float:
        """k1: the slow stiffness, or the slope of the slow curve's segment at angle 0 (N*m/rad)."""
        if self.slow_curve is None:
            return float(self.slow_stiffness)
        a, t = np.asarray(self.slow_curve.angle), np.asarray(self.slow_curve.torque)
        i = int(np.clip(np.searchsorted(a, 0.0, side="right") - 1, 0, a.size - 2))
        return float((t[i + 1] - t[i]) / (a[i + 1] - a[i]))

    def compile(self):
        if self.slow_curve is not None:
            slow = self.slow_curve.compile()
        else:
            slow = [KernelElement(K.LINEAR_SPRING, np.array([self.slow_stiffness]))]
        dk = self.fast_stiffness - self.slow_stiffness_at_zero()
        if dk <= 0:
            return slow
        return slow + [KernelElement(K.MAXWELL, np.array([dk, dk * self.tau]))]


class ForceTable(StrictModel):
    """A static curve: force y (N*m) over deformation x (rad), rising, through (0, 0)."""

    x: list[float]
    y: list[float]

    @model_validator(mode="after")
    def _shape(self):
        _strictly_increasing(self.x, "x")
        if len(self.x) != len(self.y):
            raise ValueError("x and y must have the same length")
        if np.any(np.diff(self.y) <= 0):
            raise ValueError("the force must rise with the deformation")
        if not self.x[0] <= 0.0 <= self.x[-1] or abs(np.interp(0.0, self.x, self.y)) > 1e-9 * max(map(abs, self.y)):
            raise ValueError("the curve must pass through deformation 0 with force 0")
        return self


class VariableMaxwell(ElementSpec):
    """Maxwell branch with deformation-dependent stiffness and rate-dependent damping (the zero-dimensional model paper).

    The branch spring's force at its own deformation e (so the branch stays passive) is
    (k0 + gain |e|) e; or k(e) e with k from ``stiffness_table`` (x in rad, y in N*m/rad; the
    end values hold beyond the table); or ``force_table`` (x in rad, y in N*m): a static curve
    in series with the dashpot, e.g. a softening curve that relaxes under a held preload. The
    dashpot force is c(|v|) v with c from ``damping_table`` (x in rad/s, y in N*m*s/rad) or the
    constant ``damping``. The six-parameter model uses k0 + gain; the 20-parameter one the two
    9-point tables. Spring and dashpot forces must rise with deformation and rate.
    """

    kind: Literal["variable_maxwell"]
    stiffness: PositiveFloat | None = None       # N*m/rad (k0)
    stiffness_gain: NonNegativeFloat = 0.0       # N*m/rad^2
    stiffness_table: Table | None = None
    force_table: ForceTable | None = None
    damping: PositiveFloat | None = None         # N*m*s/rad
    damping_table: Table | None = None

    @model_validator(mode="after")
    def _choice(self):
        if sum(v is not None for v in (self.stiffness, self.stiffness_table, self.force_table)) != 1:
            raise ValueError("give exactly one of stiffness, stiffness_table and force_table")
        if (self.damping is None) == (self.damping_table is None):
            raise ValueError("give exactly one of damping and damping_table")
        if self.damping_table is not None:
            if self.damping_table.x[0] != 0:
                raise ValueError("damping_table must start at rate 0")
            if not _rises(self.damping_table.x, self.damping_table.y):
                raise ValueError("damping_table makes the dashpot force c(v) v fall with the rate")
        if self.stiffness_table is not None and not _rises(self.stiffness_table.x, self.stiffness_table.y):
            raise ValueError("stiffness_table makes the spring force k(e) e fall with the deformation")
        return self

    def compile(self):
        table = self.stiffness_table or self.force_table
        ct = self.damping_table
        nk = len(table.x) if table else 0
        nc = len(ct.x) if ct else 0
        params = [self.stiffness or 0.0, self.stiffness_gain, self.damping or 0.0, nk, nc,
                  1.0 if self.force_table else 0.0]
        if table:
            params += list(table.x) + list(table.y)
        if ct:
            params += list(ct.x) + list(ct.y)
        if self.force_table:
            x, y = np.asarray(table.x), np.asarray(table.y)
            params += list(knot_energies(x, y)) + list(np.diff(y) / np.diff(x))
        return [KernelElement(K.VARIABLE_MAXWELL, np.array(params, float))]


def _rises(x: list[float], coefficient: list[float]) -> bool:
    """Whether coefficient(x) * x, with the coefficient linear between knots and constant
    beyond them, rises with x (checked densely on every segment)."""
    xs = np.asarray(x, float)
    grid = np.unique(np.concatenate([np.linspace(a, b, 64) for a, b in zip(xs[:-1], xs[1:])]))
    force = np.interp(grid, xs, coefficient) * grid
    return bool(np.all(np.diff(force) > 0))


# ------------------------------------------------------------------ Scheiblegger et al. 2013
class PfefferFriction(StrictModel):
    """Amplitude-dependent friction torque F_NL of Scheiblegger et al. 2013, as smoothed Coulomb friction.

    ``n`` Prandtl elements of equal stiffness whose limits are spread log-uniformly between
    ``min_yield_angle`` and ``max_yield_angle`` (rad, the elongation at which each slips), each
    carrying ``max_torque / n``: the friction torque then grows logarithmically with amplitude
    between those angles, as in Scheiblegger et al.'s (2013) "logarithmic increase of F_NL over amplitude".
    """

    max_torque: PositiveFloat       # N*m, full-slip friction torque
    min_yield_angle: PositiveFloat  # rad
    max_yield_angle: PositiveFloat  # rad
    n: PositiveInt = 12

    @model_validator(mode="after")
    def _range(self):
        if not self.max_yield_angle > self.min_yield_angle:
            raise ValueError("max_yield_angle must exceed min_yield_angle")
        return self

    def compile(self) -> KernelElement:
        yield_angles = np.geomspace(self.min_yield_angle, self.max_yield_angle, self.n)
        limit = np.full(self.n, self.max_torque / self.n)
        return _bank(limit / yield_angles, limit)


class Pfeffer(ElementSpec):
    """Pfeffer bushing model, frequency part (Scheiblegger et al. 2013, docs/theory.md#pfeffer).

    Main spring k1 in parallel with a dashpot c1 in series with (k2 || c2);
    alpha = k2/k1, beta = c2/c1, gamma = c1/k1 (s). Optional amplitude-dependent friction.
    """

    kind: Literal["pfeffer"]
    k1: PositiveFloat          # N*m/rad
    alpha: PositiveFloat       # -
    beta: NonNegativeFloat     # -
    gamma: PositiveFloat       # s
    friction: PfefferFriction | None = None

    def compile(self):
        out = [KernelElement(K.PFEFFER, np.array([self.k1, self.alpha, self.beta, self.gamma]))]
        if self.friction is not None:
            out.append(self.friction.compile())
        return out

    def complex_stiffness(self, omega: np.ndarray) -> np.ndarray:
        """K*(Omega) of docs/theory.md#pfeffer (N*m/rad), for the linear part."""
        iw = 1j * np.asarray(omega, float) * self.gamma
        return self.k1 * (1.0 + iw * (1.0 - 1.0 / (1.0 + self.beta + self.alpha / iw)))



# ------------------------------------------------------------------ Payne effect (docs/theory.md#payne)
class Payne(ElementSpec):
    """Kraus-type amplitude-dependent complex stiffness (the Payne effect of filled rubber).

    K'(A) = stiffness / (1 + (A/critical_angle)^(2 exponent)) and
    K''(A) = loss_stiffness + 2 loss_peak_stiffness (A/A_c)^m / (1 + (A/A_c)^(2m))
    (Kraus 1984), rate-independent, with exactly elliptic loops in a harmonic motion. The
    amplitude A and the frequency are read from the motion (envelopes of the half cycle under
    way), so a free decay stays a single damped mode; see :func:`kernels.payne`.
    """

    SETTINGS: ClassVar[frozenset[str]] = frozenset({"centre_relaxation_time", "rest_relaxation_time", "memory_time",
                                                     "reference_frequency"})
    kind: Literal["payne"]
    stiffness: PositiveFloat               # N*m/rad, dK' at zero amplitude
    critical_angle: PositiveFloat          # rad, A_c: half of dK' is lost there
    exponent: PositiveFloat = 0.6          # -, m (Kraus: ~0.5-0.7 for filled rubber)
    loss_stiffness: NonNegativeFloat = 0.0       # N*m/rad, K'' at zero amplitude
    loss_peak_stiffness: NonNegativeFloat = 0.0  # N*m/rad, dK''_m: the loss peak at A_c
    centre_relaxation_time: PositiveFloat = 10.0  # s, the centre follows the mean angle
    rest_relaxation_time: PositiveFloat = 0.1     # s, ... and at rest, a held one
    memory_time: PositiveFloat = 2.0        # s, longest half period read as an oscillation
    storage_frequency_exponent: NonNegativeFloat = 0.0  # -, K' ~ f^beta_s
    loss_frequency_exponent: NonNegativeFloat = 0.0     # -, K'' ~ f^beta_l
    reference_frequency: PositiveFloat = 30.0           # Hz, where the stiffnesses above hold

    def compile(self):
        names = set(kinds.PAYNE.params) - {"reference_omega"}
        params = kinds.PAYNE.pack(**{n: getattr(self, n) for n in names},
                                  reference_omega=2 * np.pi * self.reference_frequency)
        return [KernelElement(K.PAYNE, params)]

    def complex_stiffness(self, amplitude_rad: ArrayLike, frequency_hz: ArrayLike) -> np.ndarray:
        """K'(A, f) + i K''(A, f) (N*m/rad) in a harmonic motion of amplitude A (rad) and
        frequency f (Hz) about the centre (the centre's slow relaxation left out)."""
        u = (np.asarray(amplitude_rad, float) / self.critical_angle) ** self.exponent
        ratio = np.asarray(frequency_hz, float) / self.reference_frequency
        return (self.stiffness / (1 + u * u) * ratio ** self.storage_frequency_exponent
                + 1j * (self.loss_stiffness + 2 * self.loss_peak_stiffness * u / (1 + u * u))
                * ratio ** self.loss_frequency_exponent)


# ------------------------------------------------------------------ filler network (Payne effect)
def log_logistic_bins(median: ArrayLike, exponent: ArrayLike, n: int, tail: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    """Discretise the log-logistic distribution F(a) = u^2 / (1 + u^2), u = (a / median)^exponent,
    into n points evenly spaced in ln a between the quantiles ``tail`` and 1 - ``tail``.

    Returns (weights summing to 1, points a_i): each point carries the probability of the cell
    between the midpoints to its neighbours; the first and last carry the tails beyond them.
    The points are (n,) for numbers; ``median`` and ``exponent`` may be arrays of distributions
    (broadcast together), whose shape then comes before the points' axis.
    """
    z, weights = _logit_cells(int(n), float(tail))
    return weights.copy(), np.asarray(median, float)[..., None] * np.exp(z / (2.0 * np.asarray(exponent, float)[..., None]))


@lru_cache(maxsize=64)
def _logit_cells(n: int, tail: float) -> tuple[np.ndarray, np.ndarray]:
    """(logits z_i, cell probabilities) of :func:`log_logistic_bins`, which depend on n and the
    tail only (read-only, cached)."""
    z_max = np.log((1.0 - tail) / tail)  # the logit of the upper quantile; ln(a/median) = z / (2 exponent)
    z = np.linspace(-z_max, z_max, n) if n > 1 else np.zeros(1)
    edges = np.r_[-np.inf, 0.5 * (z[1:] + z[:-1]), np.inf]
    cdf = 1.0 / (1.0 + np.exp(-edges))
    weights = np.diff(cdf)
    z.flags.writeable = weights.flags.writeable = False
    return z, weights


def filler_network_complex_stiffness(stiffness: ArrayLike, critical_angle: ArrayLike, exponent: ArrayLike,
                                     breakdown_angle: ArrayLike, n: int, amplitude_rad: ArrayLike) -> np.ndarray:
    """K'(A) + i K''(A) (N*m/rad) of a :class:`FillerNetwork` (its fields, SI; not validated) in
    a harmonic motion of amplitude A (rad) about the centre, once the network has broken down to
    g_eq(A) (recovery within a cycle and the centre's motion left out): Jenkins loops in closed
    form, sticking springs elastic. A pure function of numbers, which the first guess of a fit
    evaluates some ten thousand times (docs/theory.md#filler-network). The four numbers may be
    arrays of parameter sets that broadcast with the amplitudes (e.g. (M, 1) against (N,) gives
    (M, N)); ``n`` is one for all."""
    amp = np.asarray(amplitude_rad, float)[..., None]
    weights, a = log_logistic_bins(critical_angle, exponent, n)
    k = np.asarray(stiffness, float)[..., None] * weights
    ratio = np.minimum(a / amp, 1.0)
    theta = np.arccos(1.0 - 2.0 * ratio)  # the part of the half cycle an element sticks
    storage = k / np.pi * (theta - 0.5 * np.sin(2.0 * theta))
    loss = 4.0 * k * ratio * (1.0 - ratio) / np.pi
    return filler_network_intact_fraction(breakdown_angle, exponent, amp[..., 0]) * np.sum(storage + 1j * loss,
                                                                                           axis=-1)


def filler_network_intact_fraction(breakdown_angle: ArrayLike, exponent: ArrayLike, amplitude_rad: ArrayLike) -> np.ndarray:
    """g_eq(A) = 1 / (1 + (A / breakdown_angle)^(2 exponent)): a :class:`FillerNetwork`'s intact
    fraction after a motion of amplitude A (rad) about its centre (all three broadcast together)."""
    return 1.0 / (1.0 + (np.asarray(amplitude_rad, float) / breakdown_angle) ** (2 * exponent))


class FillerNetwork(ElementSpec):
    """The Payne effect of filled rubber from state variables valid for any history
    (:func:`droptower.rheology.kernels.filler_network` states its variables and energy books).

    An Iwan network of ``n`` Jenkins elements (spring in series with a Coulomb slider; stiffness
    ``stiffness`` in all, yield angles log-logistic about ``critical_angle`` with ``exponent``
    m: the share of springs still sticking at an amplitude A is 1 / (1 + (A/critical_angle)^(2m)),
    Kraus's 1984 storage shape): friction between filler clusters, a rate-independent loss and
    Masing loops. Its intact fraction g breaks down at once to 1 / (1 + (|e_c| /
    breakdown_angle)^(2m)) when the elongation about a slowly moving centre, e_c, grows, and
    recovers towards 1 with ``recovery_time``; the centre follows the angle, and the network's
    stress relaxes, with ``centre_relaxation_time`` (a held preload becomes the network's new
    rest state). The network re-forms only while held: those rates carry the factor
    1 / (1 + |rate| / ``rest_rate``), so a slow sine does not relax it (docs/theory.md#filler-network).
    """

    SETTINGS: ClassVar[frozenset[str]] = frozenset({"recovery_time", "centre_relaxation_time", "rest_rate", "n"})
    kind: Literal["filler_network"]
    stiffness: PositiveFloat                   # N*m/rad, the intact network's stiffness (all springs)
    critical_angle: PositiveFloat              # rad, median yield angle: half the springs slip beyond it
    exponent: PositiveFloat = 0.55             # -, m: the spread of the yield angles (Kraus: ~0.5-0.7)
    breakdown_angle: PositiveFloat             # rad, elongation about the centre that breaks half the network
    recovery_time: PositiveFloat = 10.0        # s, the broken network re-forms with it
    centre_relaxation_time: PositiveFloat = 5.0  # s, the centre follows a held angle with it
    rest_rate: PositiveFloat = 2e-7            # rad/s, the network re-forms at 1/(1 + |rate|/rest_rate) of its rate held
    n: PositiveInt = 32                        # -, Jenkins elements resolving the yield distribution

    _n_limit = field_validator("n")(_at_most_max_n)

    def sliders(self) -> tuple[np.ndarray, np.ndarray]:
        """(stiffness k_i N*m/rad, yield angle a_i rad) of the intact network's Jenkins elements."""
        weights, angles = log_logistic_bins(self.critical_angle, self.exponent, self.n)
        return self.stiffness * weights, angles

    def compile(self):
        k, a = self.sliders()
        params = np.concatenate([[self.n, self.breakdown_angle, 2 * self.exponent, self.recovery_time,
                                  self.centre_relaxation_time, self.rest_rate], k, a])
        return [KernelElement(K.FILLER_NETWORK, params)]

    def intact_fraction(self, amplitude_rad: ArrayLike) -> np.ndarray:
        """g_eq(A): the network's intact fraction after a motion of amplitude A about its centre."""
        return filler_network_intact_fraction(self.breakdown_angle, self.exponent, amplitude_rad)

    def complex_stiffness(self, amplitude_rad: ArrayLike) -> np.ndarray:
        """K'(A) + i K''(A) (N*m/rad) in a harmonic motion of amplitude A (rad) about the
        centre (:func:`filler_network_complex_stiffness`)."""
        return filler_network_complex_stiffness(self.stiffness, self.critical_angle, self.exponent,
                                                self.breakdown_angle, self.n, amplitude_rad)

class LargeStrainNetwork(ElementSpec):
    """Filled rubber at large strain (high-damping rubber): a stiffening spring softened by
    scragging damage and a stiffening friction network
    (:func:`droptower.rheology.kernels.large_strain_network` states its variables and energy books;
    Grant, Fenves & Whittaker 2004; docs/theory.md#large-strain-network).

    Torque (1 - D) (``stiffness`` + ``gain`` |x|^``exponent``) x + the network's: ``n`` Jenkins
    elements of ``network_stiffness`` in all, slipping at s_i = ``slip`` ((i + 1/2) / n)^``spread``,
    whose energy carries the factor 1 + ``friction_gain`` x^2. The damage D grows with the
    travel |dx| over ``damage_travel`` towards ``damage`` (1 - exp(-(x_max / ``damage_angle``)^
    ``damage_exponent``)), x_max the largest |x| seen, and does not recover. Every gain may be 0:
    ``gain`` 0 no stiffening, ``network_stiffness`` 0 no network, ``friction_gain`` 0 a plain Iwan
    network, ``damage`` 0 no softening (the element is then a linear spring || an Iwan network).
    """

    SETTINGS: ClassVar[frozenset[str]] = frozenset({"n"})
    kind: Literal["large_strain_network"]
    stiffness: NonNegativeFloat = 0.0         # N*m/rad, the virgin spring's linear stiffness
    gain: NonNegativeFloat = 0.0              # N*m/rad^(1+exponent), the stiffening term's coefficient
    exponent: PositiveFloat = 2.0             # -, the stiffening's order q: (k + a |x|^q) x
    network_stiffness: NonNegativeFloat = 0.0  # N*m/rad, the network's springs all sticking
    slip: PositiveFloat = 1.0                 # rad, the largest slip angle of the network
    spread: PositiveFloat = 1.0               # -, the slips s_i = slip ((i + 1/2)/n)^spread
    friction_gain: NonNegativeFloat = 0.0     # 1/rad^2, the network's energy factor 1 + g x^2
    damage: float = Field(0.0, ge=0.0, lt=1.0)  # -, the largest scragging damage D_max
    damage_angle: PositiveFloat = 1.0         # rad, x_D: the largest angle seen that sets D_inf
    damage_exponent: PositiveFloat = 1.0      # -, r: D_inf = D_max (1 - exp(-(x_max/x_D)^r))
    damage_travel: PositiveFloat = 1.0        # rad, L: the damage approaches D_inf over this travel
    n: PositiveInt = 24                       # -, Jenkins elements of the network

    _n_limit = field_validator("n")(_at_most_max_n)

    def slips(self) -> np.ndarray:
        """s_i (rad): the network's slip angles, smallest first."""
        return self.slip * ((np.arange(self.n) + 0.5) / self.n) ** self.spread

    def compile(self):
        params = np.concatenate([[self.n, self.stiffness, self.gain, self.exponent, self.network_stiffness / self.n,
                                  self.friction_gain, self.damage, self.damage_angle, self.damage_exponent,
                                  self.damage_travel], self.slips()])
        return [KernelElement(K.LARGE_STRAIN_NETWORK, params)]


ElementUnion = Annotated[
    Union[Spring, SpringTable, CubicSpring, Dashpot, Maxwell, Prony, Prandtl, Masing, Elastoslide,
          Mullins, VariableMaxwell, Pfeffer, Payne, PowerLaw, FillerNetwork, LargeStrainNetwork],
    Field(discriminator="kind"),
]

ELEMENT_KINDS = ("spring", "spring_table", "cubic_spring", "dashpot", "maxwell", "prony", "prandtl",
                 "masing", "elastoslide", "mullins", "variable_maxwell", "pfeffer", "payne", "power_law",
                 "filler_network", "large_strain_network")
