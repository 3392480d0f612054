"""Stages the families' identification strategies share (docs/theory.md#elements).

:class:`Setup` binds a family to its data and starting values; :func:`result_of` makes the
:class:`~droptower.identify.fit.Identification` of one parameter vector; the helpers find the
parts of the data that show one effect: static averages (:func:`static_stiffness`), slow
ramps and sweeps (:func:`split_by_speed`, :func:`sweeps`), steady sine blocks
(:func:`steady_blocks`) and their amplitude or frequency levels (:func:`levels`).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from droptower.errors import DroptowerError
from droptower.identify.cycles import Block, blocks, cycles
from droptower.identify.data import DataScale, Segment, characteristic_frequency
from droptower.identify.families.base import Family
from droptower.identify.fit import (FitResult, FitVariable, check_in_bounds, clip_to_bounds, least_squares_fit, simulate)
from droptower.identify.result import Identification, Metrics
from droptower.identify.result import fitted_parameters
from droptower.io.fields import field_name

#: Records whose characteristic frequency is below this count as quasi-static ramps (Hz).
SLOW_FREQUENCY_HZ = 0.5
#: Relative tolerance of the least-squares stages that only prepare starting values.
STAGE_TOL = 1e-5


# ---------------------------------------------------------------------------- set-up
@dataclass
class Setup:
    """A family bound to its data, with the starting values.

    given: which initial values came from the user (strategies do not overwrite them with
    their own estimates); bounded: which bounds came from the user (strategies do not
    narrow them).
    """

    family: Family
    x0: np.ndarray
    given: np.ndarray
    bounded: np.ndarray

    @property
    def max_nfev(self) -> int | None:
        return int(self.family.options["max_nfev"]) or None

    def index(self, name: str) -> int:
        return self.family.names.index(name)

    def set_estimate(self, x: np.ndarray, name: str, value: float) -> None:
        """Use a strategy's estimate for ``name`` unless the user gave its initial value."""
        i = self.index(name)
        if not self.given[i] and np.isfinite(value):
            x[i] = clip_to_bounds([self.family.parameters[i]], [value])[0]

    def free(self, names: list[str]) -> np.ndarray:
        mask = np.zeros(len(self.family.names), bool)
        mask[[self.index(n) for n in names]] = True
        return mask

    def fit(self, segments: list[Segment], x: np.ndarray, names: list[str] | None, stage: str,
            per_segment: np.ndarray | None = None, tol: float = 1e-7) -> FitResult:
        free = None if names is None else self.free(names)
        return least_squares_fit(self.family, segments, x, free=free, stage=stage, max_nfev=self.max_nfev,
                                 per_segment=per_segment, tol=tol)


def setup(family_cls: type[Family], segments: list[Segment], init: dict[str, float] | None = None,
          bounds: dict[str, tuple[float, float]] | None = None, options: dict[str, Any] | None = None,
          file: str | None = None) -> Setup:
    """Bind family ``family_cls`` to ``segments``: scaled bounds (``bounds`` overrides some), the
    family's first guess, the user's initial values ``init`` (checked against the bounds)."""
    return setup_family(family_cls(DataScale.of(segments), options), init, bounds, file)


def setup_family(family: Family, init: dict[str, float] | None = None,
                 bounds: dict[str, tuple[float, float]] | None = None, file: str | None = None) -> Setup:
    """A family (already scaled to its data) with the user's bounds and initial values."""
    kind = family.kind
    names = family.names
    for what, given in (("initial values", init or {}), ("bounds", bounds or {})):
        unknown = sorted(set(given) - set(names))
        if unknown:
            units = family.scale.units  # named as the user names them for these records
            raise DroptowerError(f"unknown parameter(s) {', '.join(field_name(n, units) for n in unknown)} in the "
                                 f"{what} for family {kind} (parameters: "
                                 f"{', '.join(field_name(n, units) for n in names)})", file=file)
    bounded = np.zeros(len(names), bool)
    for name, (lo, hi) in (bounds or {}).items():
        i = names.index(name)
        bounded[i] = True
        p = family.parameters[i]
        if not (lo < hi) or (p.log and lo <= 0):
            raise DroptowerError(f"bounds of {name} must satisfy {'0 < ' if p.log else ''}lower < upper, "
                                 f"got [{lo:g}, {hi:g}]", file=file)
        family.parameters[i] = FitVariable(p.name, float(lo), float(hi), p.log, p.scale)
    x0 = family.initial()
    given = np.zeros(len(names), bool)
    for name, value in (init or {}).items():
        i = names.index(name)
        check_in_bounds([family.parameters[i]], np.array([float(value)]), file)
        x0[i], given[i] = float(value), True
    return Setup(family, x0, given, bounded)


def result_of(s: Setup, segments: list[Segment], x: np.ndarray, stages: list[FitResult], start: float,
            fit: Metrics | None = None, **kw) -> Identification:
    """An :class:`Identification` of one parameter vector ``x`` (the last stage's)."""
    fam = s.family
    final = stages[-1]

    def predict(segs: list[Segment]) -> list[np.ndarray]:
        return simulate(fam, x[None, :], segs)[0]

    return Identification(fam.kind, fitted_parameters(fam.parameters, x, final.std_error, final.free), final.at_bounds,
                          fit or final.metrics, fam.coupling(x), stages=stages, predict=predict,
                          derived=fam.derived(x), wall_s=time.perf_counter() - start, family_model=fam, **kw)


# ---------------------------------------------------------------------------- helpers
def static_stiffness(segments: list[Segment]) -> float | None:
    """Mean torque over mean angle in the second half of each preloaded record (N*m/rad).

    Whole cycles are averaged where the second half oscillates. In a periodic steady state a
    Maxwell branch (or the Pfeffer branch) carries no mean torque, so this is the parallel
    static spring (the zero-dimensional model paper's K1 "from average values"; Scheiblegger et al.'s (2013) k_stat). None if no
    record has a mean angle clearly away from 0.
    """
    num = den = 0.0
    for seg in segments:
        x, y = seg.measured_angle, seg.measured_torque
        half = x.size // 2
        cyc = [c for c in cycles(x, seg.dt_s) if c.start >= half]
        a, b = (cyc[0].start, cyc[-1].stop) if len(cyc) >= 2 else (half, x.size)
        ok = np.isfinite(y[a:b])
        if ok.sum() < 2:
            continue
        xm, ym = float(np.mean(x[a:b][ok])), float(np.mean(y[a:b][ok]))
        swing = 0.5 * float(np.ptp(x[a:b]))
        if abs(xm) > 0.1 * swing and abs(xm) > 0.02 * float(np.max(np.abs(x))):
            num += xm * ym
            den += xm * xm
    return num / den if den > 0 else None


def split_by_speed(segments: list[Segment]) -> tuple[list[Segment], list[Segment]]:
    """(quasi-static records, dynamic records) by characteristic frequency."""
    slow = [s for s in segments if characteristic_frequency(s) < SLOW_FREQUENCY_HZ]
    return slow, [s for s in segments if characteristic_frequency(s) >= SLOW_FREQUENCY_HZ]


def sweeps(segments: list[Segment]) -> list[Segment]:
    """Dynamic records made of steady sine blocks (sweeps, sines), not steps or random ones."""
    _, fast = split_by_speed(segments)
    return [s for s in fast if blocks(s.measured_angle, s.dt_s)]


@dataclass(frozen=True)
class SteadyBlock:
    """A block of steady sine cycles in segment ``segment`` (index) with its lab evaluation."""

    segment: int
    block: Block
    window: Segment

    @property
    def amplitude_rad(self) -> float:
        return self.block.amplitude_rad

    @property
    def frequency_hz(self) -> float:
        return self.block.frequency_hz


def steady_blocks(segments: list[Segment]) -> list[SteadyBlock]:
    """Every block of steady sine cycles in the data, as a window of its record (the history
    from the record's start, the torque compared on the block's cycles after the first)."""
    out = []
    for i, seg in enumerate(segments):
        for b in blocks(seg.measured_angle, seg.dt_s):
            out.append(SteadyBlock(i, b, seg.window(b.first_cycle_stop, b.stop,
                                                    name=f"{seg.name} {math.degrees(b.amplitude_rad):.3g} deg "
                                                         f"{b.frequency_hz:.3g} Hz")))
    return out


def levels(values: list[float], rel_tol: float = 0.1) -> list[list[int]]:
    """Indices of ``values`` grouped into levels (sorted; a new level starts more than
    ``rel_tol`` above the level's first value)."""
    order = np.argsort(values)
    out: list[list[int]] = []
    for i in order:
        if out and values[i] <= values[out[-1][0]] * (1 + rel_tol):
            out[-1].append(int(i))
        else:
            out.append([int(i)])
    return out
