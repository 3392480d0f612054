"""Map forms: the stiffness c(φ̂, f) and the stiffness-over-damping c/d(φ̂, f) as sums of terms.

Rapp et al. 2022 writes both equations as sums of "coefficient × shape" terms (eq. 19, eq. 20); a
:class:`MapForm` is such a pair of term lists, so the paper's form and forms beyond it are
evaluated, fitted and stored the same way. Units are the paper's: φ̂ (``a``) in deg, f in Hz,
c and c/d in N·m/deg. Term kinds:

=================  ===================  ==============================================
kind               term                 why
=================  ===================  ==============================================
``constant``       k                    a level (eq. 20's term with k9 = 0)
``amplitude``      k·φ̂                  a slow linear trend with amplitude
``sqrt_frequency`` k·√f                 eq. 19's viscoelastic frequency term
``exp_amplitude``  k·10^(−e·φ̂)          eq. 19/20's Prony-like amplitude terms
``exp_frequency``  k·10^(−e·f)          eq. 19's frequency term
``exp_velocity``   k·10^(−e·φ̂·f)        damping that fades with the velocity amplitude
                                        φ̂·ω = 2π·φ̂·f (rate-dependent damping splits the
                                        inertia cases, which eq. 20 cannot)
=================  ===================  ==============================================

Coefficients are named ``k1, k2, …`` in order, stiffness terms first, each term its factor
then its exponent (if it has one): the paper's form gets exactly the paper's k1…k13.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike

LN10 = float(np.log(10.0))

#: kind -> (coefficient unit, exponent unit or None, text with {k} and {e} for the names)
KINDS: dict[str, tuple[str, str | None, str]] = {
    "constant": ("nm_per_deg", None, "{k}"),
    "amplitude": ("nm_per_deg2", None, "{k}*a"),
    "frequency": ("nm_per_deg_per_hz", None, "{k}*f"),
    "sqrt_frequency": ("nm_per_deg_per_sqrt_hz", None, "{k}*sqrt(f)"),
    "exp_amplitude": ("nm_per_deg", "per_deg", "{k}*10^(-{e}*a)"),
    "exp_frequency": ("nm_per_deg", "per_hz", "{k}*10^(-{e}*f)"),
    "exp_velocity": ("nm_per_deg", "s_per_deg", "{k}*10^(-{e}*a*f)"),
}
UNIT_TEXT = {"nm_per_deg": "N*m/deg", "nm_per_deg2": "N*m/deg^2", "per_deg": "1/deg", "per_hz": "1/Hz",
             "nm_per_deg_per_sqrt_hz": "N*m/(deg*sqrt(Hz))", "nm_per_deg_per_hz": "N*m/(deg*Hz)", "s_per_deg": "s/deg"}


def _points(a: ArrayLike, f: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Amplitudes and frequencies as float arrays of one shape (broadcast only if they differ:
    the fits evaluate an equation tens of thousands of times on the same points)."""
    a, f = np.asarray(a, float), np.asarray(f, float)
    return (a, f) if a.shape == f.shape else np.broadcast_arrays(a, f)


def _variable(kind: str, a: np.ndarray, f: np.ndarray) -> np.ndarray:
    """The variable a term's shape is a function of."""
    if kind in ("amplitude", "exp_amplitude"):
        return a
    if kind in ("frequency", "sqrt_frequency", "exp_frequency"):
        return f
    if kind == "exp_velocity":
        return a * f
    return np.ones_like(a)


@dataclass(frozen=True)
class Equation:
    """One equation (stiffness or c/d) as a tuple of term kinds, with its parameter layout:
    ``linear`` and ``exponents`` are the positions of the factors and the exponents in its
    parameter vector (a factor first, then its exponent if the kind has one)."""

    terms: tuple[str, ...]

    def __post_init__(self) -> None:
        unknown = [t for t in self.terms if t not in KINDS]
        if unknown or not self.terms:
            raise ValueError(f"unknown or no term kinds {unknown} (known: {', '.join(KINDS)})")

    # the layout is asked for at every evaluation of a fit (tens of thousands of times): computed once
    @cached_property
    def linear(self) -> tuple[int, ...]:
        return tuple(self._layout()[0])

    @cached_property
    def exponents(self) -> tuple[int, ...]:
        return tuple(self._layout()[1])

    @cached_property
    def size(self) -> int:
        return len(self.terms) + sum(KINDS[t][1] is not None for t in self.terms)

    def _layout(self) -> tuple[list[int], list[int]]:
        linear, exponents, i = [], [], 0
        for t in self.terms:
            linear.append(i)
            i += 1
            if KINDS[t][1] is not None:
                exponents.append(i)
                i += 1
        return linear, exponents

    def units(self) -> list[str]:
        """Unit suffix of every parameter, in order."""
        out = []
        for t in self.terms:
            unit, exp_unit, _ = KINDS[t]
            out += [unit] + ([exp_unit] if exp_unit else [])
        return out

    def basis(self, exponents: ArrayLike, a: ArrayLike, f: ArrayLike) -> np.ndarray:
        """Columns for fixed exponents: (N, terms), so that value = basis @ factors."""
        a, f = _points(a, f)
        e = iter(np.asarray(exponents, float))
        cols = np.empty((*a.shape, len(self.terms)))
        for j, t in enumerate(self.terms):
            x = _variable(t, a, f)
            if t == "sqrt_frequency":
                cols[..., j] = np.sqrt(x)
            elif KINDS[t][1] is not None:
                cols[..., j] = 10.0 ** (-next(e) * x)
            else:
                cols[..., j] = x
        return cols

    def basis_on_grid(self, grids: list[np.ndarray], a: ArrayLike, f: ArrayLike) -> Callable[[tuple[int, ...]], np.ndarray]:
        """The basis at grid points of the exponents: ``basis_on_grid(grids, a, f)(ix)`` is
        ``basis([grids[k][ix[k]] ...], a, f)`` bit for bit, each exponent term's column at each
        grid value computed once (a search evaluates the same columns at thousands of points)."""
        a, f = _points(a, f)
        fixed = self.basis(np.zeros(len(self.exponents)), a, f)  # the exponent columns are replaced
        kinds = [(j, t) for j, t in enumerate(self.terms) if KINDS[t][1] is not None]
        tables = [(j, np.stack([10.0 ** (-e * _variable(t, a, f)) for e in np.asarray(g, float)]))
                  for (j, t), g in zip(kinds, grids)]

        def at(ix: tuple[int, ...]) -> np.ndarray:
            cols = fixed.copy()
            for (j, table), i in zip(tables, ix):
                cols[..., j] = table[i]
            return cols
        return at

    def value(self, params: ArrayLike, a: ArrayLike, f: ArrayLike) -> np.ndarray:
        p = np.asarray(params, float)
        return self.basis(p[list(self.exponents)], a, f) @ p[list(self.linear)]

    def jacobian(self, params: ArrayLike, a: ArrayLike, f: ArrayLike) -> np.ndarray:
        """∂value/∂params at each point: (N, size)."""
        return self.value_and_jacobian(params, a, f)[1]

    def value_and_jacobian(self, params: ArrayLike, a: ArrayLike, f: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`value` and :meth:`jacobian` (bit for bit) from one evaluation of the basis."""
        p = np.asarray(params, float)
        a, f = _points(a, f)
        columns = self.basis(p[list(self.exponents)], a, f)
        out, i = np.empty((*a.shape, self.size)), 0
        for j, t in enumerate(self.terms):
            out[..., i] = columns[..., j]
            i += 1
            if KINDS[t][1] is not None:  # d/de of k·10^(−e·x)
                out[..., i] = -p[i - 1] * LN10 * _variable(t, a, f) * columns[..., j]
                i += 1
        return columns @ p[list(self.linear)], out

    def text(self, names: list[str]) -> str:
        """The equation with the given parameter names, e.g. ``k1*10^(-k2*a) + k3*sqrt(f)``."""
        it, parts = iter(names), []
        for t in self.terms:
            k = next(it)
            parts.append(KINDS[t][2].format(k=k, e=next(it) if KINDS[t][1] else ""))
        return " + ".join(parts)


@dataclass(frozen=True)
class MapForm:
    """A map: stiffness c(φ̂, f) [N·m/deg] and c/d(φ̂, f) [N·m/deg]; d = c / (c/d)."""

    name: str
    stiffness: Equation
    ratio: Equation

    @property
    def stiffness_names(self) -> list[str]:
        return [f"k{i + 1}" for i in range(self.stiffness.size)]

    @property
    def ratio_names(self) -> list[str]:
        n = self.stiffness.size
        return [f"k{n + i + 1}" for i in range(self.ratio.size)]

    @property
    def units(self) -> dict[str, str]:
        """coefficient name -> unit suffix, stiffness then c/d."""
        return dict(zip(self.stiffness_names + self.ratio_names, self.stiffness.units() + self.ratio.units()))

    def equations(self) -> dict[str, str]:
        """The two equations as text (the ``equations`` of ``map.json``)."""
        ref = "  (Rapp et al. 2022, eq. 19)" if self.stiffness == PAPER.stiffness else ""
        ref20 = "  (Rapp et al. 2022, eq. 20)" if self.ratio == PAPER.ratio else ""
        return {"stiffness_nm_per_deg": self.stiffness.text(self.stiffness_names) + ref,
                "damping_ratio": f"stiffness_nm_per_deg / ({self.ratio.text(self.ratio_names)}){ref20}",
                "a": "amplitude_deg", "f": "frequency_hz"}

    def to_dict(self) -> dict[str, object]:
        return {"name": self.name, "stiffness_terms": list(self.stiffness.terms), "ratio_terms": list(self.ratio.terms)}


#: Rapp et al. 2022, eq. 19 and eq. 20: the default and the reference.
PAPER = MapForm("paper", Equation(("exp_amplitude", "exp_amplitude", "sqrt_frequency", "exp_frequency")),
                Equation(("exp_amplitude", "exp_amplitude", "exp_amplitude")))
#: Stiffness and c/d that also fall with the velocity amplitude φ̂·f: what ``auto`` chooses on
#: the paper's Table 4 (every coefficient identifiable; see README), as a fixed form.
VELOCITY = MapForm("velocity", Equation(("exp_amplitude", "sqrt_frequency", "exp_velocity")),
                   Equation(("constant", "exp_amplitude", "exp_velocity")))
#: The fixed forms by name (``fit_map(form=...)``); ``auto`` chooses terms by cross-validation.
FORMS = {f.name: f for f in (PAPER, VELOCITY)}
#: The terms ``auto`` chooses from (any sub-multiset; see :mod:`droptower.maps.select`).
AUTO_STIFFNESS_TERMS = ("exp_amplitude", "exp_amplitude", "sqrt_frequency", "exp_frequency", "exp_velocity")
AUTO_RATIO_TERMS = ("constant", "amplitude", "exp_amplitude", "exp_amplitude", "exp_velocity")
