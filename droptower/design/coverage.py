"""The target region of a campaign and how much of it a set of tests covers.

A characteristic map (Rapp et al. 2022, eq. 19-20) interpolates between the tested
(amplitude, frequency) points: inside the convex hull of the tests it is an interpolation,
outside it an extrapolation. A target region is therefore *covered* where it lies inside that
hull. Amplitudes span decades and the map's terms are exponential in the amplitude, so the
plane is taken as (log10 amplitude, frequency): a hull there follows the map's own geometry.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from droptower.errors import DroptowerError, expects

#: Grid points per axis over the target region (coverage is the fraction of them covered).
GRID_POINTS = 21


@dataclass(frozen=True)
class Target:
    """The region an engineer wants measured: amplitude (deg, the extractor's reference
    amplitude) and frequency (Hz) ranges; preloads (N*m) each condition is tested at."""

    amplitude_deg: tuple[float, float]
    frequency_hz: tuple[float, float]
    preloads_nm: tuple[float, ...] = (0.0,)

    def __post_init__(self) -> None:
        for name, (lo, hi), flag in (("amplitude", self.amplitude_deg, "amplitude_deg"),
                                     ("frequency", self.frequency_hz, "frequency_hz")):
            if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo <= hi):
                raise DroptowerError(f"the {name} range must be two positive numbers LOW:HIGH with LOW <= HIGH, "
                                     f"got {lo:g}:{hi:g}", where=flag)
        if not self.preloads_nm or not all(math.isfinite(p) and p >= 0 for p in self.preloads_nm):
            raise DroptowerError("preloads must be non-negative numbers (N*m)", where="preloads_nm")

    def grid(self, n: int = GRID_POINTS) -> np.ndarray:
        """(n*n, 2) points over the region in the plane (log10 amplitude_deg, frequency_hz)."""
        a = np.linspace(math.log10(self.amplitude_deg[0]), math.log10(self.amplitude_deg[1]), n)
        f = np.linspace(self.frequency_hz[0], self.frequency_hz[1], n)
        aa, ff = np.meshgrid(a, f, indexing="ij")
        return np.column_stack([aa.ravel(), ff.ravel()])


def plane(amplitude_deg: np.ndarray, frequency_hz: np.ndarray) -> np.ndarray:
    """Points (N, 2) in the plane (log10 amplitude_deg, frequency_hz)."""
    return np.column_stack([np.log10(np.asarray(amplitude_deg, float)), np.asarray(frequency_hz, float)])


def in_hull(points: np.ndarray, queries: np.ndarray, rel_tol: float = 1e-9) -> np.ndarray:
    """Which ``queries`` (M, 2) lie in the convex hull of ``points`` (N, 2) (bool (M,)); a
    query on the hull's edge (within ``rel_tol`` of the axes' spans) counts as inside.

    Fewer than three points, or points on one line, span no area: then only queries on the
    points themselves count.
    """
    points = np.asarray(points, float)
    queries = np.asarray(queries, float)
    points = points[np.all(np.isfinite(points), axis=1)]
    if len(points) == 0:
        return np.zeros(len(queries), bool)
    # both axes to unit span, so Qhull's tolerances see comparable numbers
    lo = points.min(axis=0)
    span = np.where(np.ptp(points, axis=0) > 0, np.ptp(points, axis=0), 1.0)
    p, q = (points - lo) / span, (queries - lo) / span
    try:
        if len(p) < 3:
            raise QhullError("fewer than three points")
        # the hull's facets as half-planes n.x + c <= 0 (unit normals: c is a distance)
        eq = ConvexHull(p).equations
        return np.all(q @ eq[:, :2].T + eq[:, 2] <= rel_tol, axis=1)
    except QhullError:
        d = np.min(np.linalg.norm(q[:, None, :] - p[None, :, :], axis=2), axis=1)
        return d <= rel_tol


@expects(target="droptower.design.coverage.Target")
def covered_fraction(points: np.ndarray, target: Target, n: int = GRID_POINTS) -> float:
    """Fraction of the target's grid that lies in the hull of ``points`` (log10 deg, Hz)."""
    return float(np.mean(in_hull(points, target.grid(n))))
