"""Agreement of two results by their E_n number (ISO 13528, proficiency testing; JCGM 100's
expanded uncertainties): E_n = (x_lab − x_ref)/√(U_lab² + U_ref²), the two results agree when
|E_n| ≤ 1. The reference (a servo bench) states its own expanded uncertainty per point, or one
relative figure for all; where it states none, there is no verdict but "bench uncertainty not
given"."""
from __future__ import annotations

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from droptower.errors import DroptowerError

#: the verdicts of :func:`en_verdicts`
VERDICTS: tuple[str, ...] = ("agrees", "disagrees", "bench uncertainty not given", "drop-tower uncertainty not given")


def en_number(x_lab: ArrayLike, u95_lab: ArrayLike, x_ref: ArrayLike, u95_ref: ArrayLike) -> np.ndarray:
    """E_n = (x_lab − x_ref)/√(U_lab² + U_ref²) (ISO 13528), signed; U are expanded (95 %)
    uncertainties in the unit of x. NaN where an input is NaN; ±inf for different values with
    no uncertainty at all, 0 for equal ones."""
    x1, u1, x2, u2 = (np.asarray(v, float) for v in (x_lab, u95_lab, x_ref, u95_ref))
    diff = x1 - x2
    scale = np.sqrt(u1 * u1 + u2 * u2)
    with np.errstate(divide="ignore", invalid="ignore"):
        en = diff / scale
    return np.where(scale == 0, np.where(diff == 0, 0.0, np.copysign(np.inf, diff)), en)


def en_verdicts(x_lab: ArrayLike, u95_lab: ArrayLike, x_ref: ArrayLike, u95_ref: ArrayLike | None = None, *,
                u95_ref_rel: float | None = None) -> pd.DataFrame:
    """E_n number and verdict per point.

    Parameters
    ----------
    x_lab, u95_lab : array_like
        The drop tower's values and their expanded uncertainties (95 %), same unit.
    x_ref : array_like
        The reference's (the bench's) values.
    u95_ref : array_like, optional
        The reference's expanded uncertainties per point (NaN: not given at that point).
    u95_ref_rel : float, optional
        One relative expanded uncertainty for every reference value (0.02: 2 % of x_ref), where
        ``u95_ref`` gives none.

    Returns
    -------
    pandas.DataFrame
        ``en_number`` and ``verdict`` (one of :data:`VERDICTS`) per point.
    """
    x1, u1, x2 = (np.atleast_1d(np.asarray(v, float)) for v in (x_lab, u95_lab, x_ref))
    if u95_ref_rel is not None and not (np.isfinite(u95_ref_rel) and u95_ref_rel >= 0):
        raise DroptowerError(f"must be a finite number >= 0, got {u95_ref_rel!r}", where="u95_ref_rel")
    u2 = np.full(x2.shape, np.nan) if u95_ref is None else np.atleast_1d(np.asarray(u95_ref, float)) * np.ones(x2.shape)
    if u95_ref_rel is not None:
        u2 = np.where(np.isfinite(u2), u2, u95_ref_rel * np.abs(x2))
    if np.any(u1 < 0) or np.any(u2 < 0):
        raise DroptowerError("an expanded uncertainty is negative", where="u95_lab" if np.any(u1 < 0) else "u95_ref")
    en = en_number(x1, u1, x2, u2)
    verdict = np.where(~np.isfinite(u2), VERDICTS[2],
                       np.where(~np.isfinite(u1), VERDICTS[3], np.where(np.abs(en) <= 1.0, VERDICTS[0], VERDICTS[1])))
    en = np.where(np.isfinite(u1) & np.isfinite(u2), en, np.nan)
    return pd.DataFrame({"en_number": en, "verdict": verdict})
