"""Agreement of two results by their E_n number (ISO 13528, proficiency testing; JCGM 100's
expanded uncertainties): E_n = (x_lab − x_ref)/√(U_lab² + U_ref²), the two results agree when
|E_n| ≤ 1. The reference (a servo bench) states its own expanded uncertainty per point, or one
relative figure for all; where it states none, there is no verdict but "bench uncertainty not
given"."""
from __future__ import annotations

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from droptower.errors import DroptowerError, expects, finite_values

#: the verdicts of :func:`en_verdicts`
VERDICTS: tuple[str, ...] = ("agrees", "disagrees", "bench uncertainty not given")


def en_number(x_lab: ArrayLike, u95_lab: ArrayLike, x_ref: ArrayLike, u95_ref: ArrayLike) -> np.ndarray:
    """E_n = (x_lab − x_ref)/√(U_lab² + U_ref²) (ISO 13528), signed; U are expanded (95 %)
    uncertainties in the unit of x, finite and ≥ 0 (NaN: not given, E_n NaN there). The four
    have one shape (scalars, or arrays of one length); a point where both U are 0 has no E_n
    and is refused."""
    names = ("x_lab", "u95_lab", "x_ref", "u95_ref")
    arrays = []
    for name, value in zip(names, (x_lab, u95_lab, x_ref, u95_ref)):
        if value is None or isinstance(value, (str, bytes)):
            raise TypeError(f"en_number: {name} must be numbers, got {type(value).__name__}")
        arrays.append(np.asarray(value, float))
    if len({a.shape for a in arrays}) > 1:
        raise DroptowerError("x_lab, u95_lab, x_ref and u95_ref must have one shape, got "
                             + ", ".join(str(a.shape) for a in arrays), where="x_ref")
    x1, u1, x2, u2 = arrays
    for name, u in (("u95_lab", u1), ("u95_ref", u2)):
        if np.any(u < 0) or np.any(np.isinf(u)):
            raise DroptowerError("an expanded uncertainty must be finite and >= 0 (NaN: not given)", where=name)
    scale = np.sqrt(u1 * u1 + u2 * u2)
    if np.any(scale == 0):
        raise DroptowerError("U_lab and U_ref are both 0 at a point: E_n needs an uncertainty", where="u95_ref")
    return (x1 - x2) / scale


def en_verdicts(x_lab: ArrayLike, u95_lab: ArrayLike, x_ref: ArrayLike, u95_ref: ArrayLike | None = None, *,
                u95_ref_rel: float | None = None) -> pd.DataFrame:
    """E_n number and verdict per point.

    Parameters
    ----------
    x_lab, u95_lab : array_like
        The drop tower's values and their expanded uncertainties (95 %), same unit; finite.
    x_ref : array_like
        The reference's (the bench's) values; finite.
    u95_ref : array_like, optional
        The reference's expanded uncertainties per point (NaN: not given at that point).
    u95_ref_rel : float, optional
        One relative expanded uncertainty for every reference value (0.02: 2 % of x_ref), where
        ``u95_ref`` gives none.

    Returns
    -------
    pandas.DataFrame
        ``en_number`` (NaN where the bench gives no uncertainty) and ``verdict`` (one of
        :data:`VERDICTS`: |E_n| ≤ 1 agrees) per point.
    """
    x1, u1, x2 = (np.atleast_1d(finite_values(v, name)) for v, name in
                  ((x_lab, "x_lab"), (u95_lab, "u95_lab"), (x_ref, "x_ref")))
    if u95_ref_rel is not None and not (isinstance(u95_ref_rel, (int, float)) and np.isfinite(u95_ref_rel)
                                        and u95_ref_rel >= 0):
        raise DroptowerError(f"must be a finite number >= 0, got {u95_ref_rel!r}", where="u95_ref_rel")
    try:
        x1, u1, x2 = np.broadcast_arrays(x1, u1, x2)
        u2 = np.full(x2.shape, np.nan) if u95_ref is None else np.broadcast_to(np.asarray(u95_ref, float), x2.shape)
    except ValueError:
        raise DroptowerError(f"{x1.size} values and {x2.size} reference values (or their uncertainties) do not "
                             "match", where="x_ref") from None
    if u95_ref_rel is not None:
        u2 = np.where(np.isfinite(u2), u2, u95_ref_rel * np.abs(x2))
    en = en_number(x1, u1, x2, u2)
    verdict = np.where(np.isnan(u2), VERDICTS[2], np.where(np.abs(en) <= 1.0, VERDICTS[0], VERDICTS[1]))
    return pd.DataFrame({"en_number": en, "verdict": verdict})


#: the quantities :func:`route_agreement` judges: the validation table's ``map_<q>`` against ``servo_<q>``
AGREEMENT_QUANTITIES: tuple[str, ...] = ("stiffness_nm_per_deg", "damping_ratio")


@expects(table=pd.DataFrame, map_u95=dict)
def route_agreement(table: pd.DataFrame, map_u95: dict[str, ArrayLike], *, servo_u95: dict[str, ArrayLike] | None = None,
                    u95_ref_rel: float | None = None) -> pd.DataFrame:
    """E_n per servo point of one route (a validation table: ``map_<q>`` and ``servo_<q>`` per
    point, :func:`droptower.compare.map_vs_servo.compare_with_servo`).

    Parameters
    ----------
    table : pandas.DataFrame
        The route's validation table.
    map_u95 : dict
        Quantity of :data:`AGREEMENT_QUANTITIES` -> the route's expanded uncertainty (95 %) per point,
        in the quantity's unit; a quantity left out is not judged.
    servo_u95 : dict, optional
        Quantity -> the bench's own expanded uncertainty per point (NaN: not given there).
    u95_ref_rel : float, optional
        One relative expanded uncertainty of the bench (0.02: 2 %), where ``servo_u95`` gives none.

    Returns
    -------
    pandas.DataFrame
        ``sweep``, ``amplitude_deg``, ``frequency_hz``, ``in_range`` and per quantity ``map_<q>``,
        ``map_<q>_U95``, ``servo_<q>``, ``servo_<q>_U95``, ``<q>_en_number``, ``<q>_verdict``.
    """
    keep = [c for c in ("sweep", "amplitude_deg", "frequency_hz", "in_range") if c in table.columns]
    out = table[keep].copy()
    for q, u95 in map_u95.items():
        if q not in AGREEMENT_QUANTITIES:
            raise DroptowerError(f"unknown quantity {q!r}; the quantities are {', '.join(AGREEMENT_QUANTITIES)}",
                                 where="map_u95")
        ref_u = (servo_u95 or {}).get(q)
        verdicts = en_verdicts(table[f"map_{q}"].to_numpy(float), u95, table[f"servo_{q}"].to_numpy(float),
                               ref_u, u95_ref_rel=u95_ref_rel)
        x2 = table[f"servo_{q}"].to_numpy(float)
        given = np.full(len(table), np.nan) if ref_u is None else np.broadcast_to(np.asarray(ref_u, float), x2.shape)
        if u95_ref_rel is not None:
            given = np.where(np.isfinite(given), given, u95_ref_rel * np.abs(x2))
        out[f"map_{q}"] = table[f"map_{q}"].to_numpy(float)
        out[f"map_{q}_U95"] = np.broadcast_to(np.asarray(u95, float), x2.shape)
        out[f"servo_{q}"] = x2
        out[f"servo_{q}_U95"] = given
        out[f"{q}_en_number"] = verdicts["en_number"].to_numpy()
        out[f"{q}_verdict"] = verdicts["verdict"].to_numpy()
    return out


@expects(agreements=dict)
def format_agreement(agreements: dict[str, pd.DataFrame]) -> str:
    """Per route and quantity: how many servo points agree (|E_n| ≤ 1), disagree, or have no
    bench uncertainty, inside the hull and in all; the largest |E_n|."""
    lines = ["agreement with the servo bench (E_n = (x_map - x_servo)/sqrt(U_map^2 + U_servo^2), ISO 13528; "
             "|E_n| <= 1 agrees):"]
    if not agreements:
        lines.append("  no route's expanded uncertainty is known: the paper map's needs the tests it was fitted to, "
                     "the model-based map's its bands")
    for route, t in agreements.items():
        if not isinstance(t, pd.DataFrame):
            raise TypeError(f"format_agreement: agreements[{route!r}] must be a DataFrame (route_agreement's), "
                            f"got {type(t).__name__}")
        for q in AGREEMENT_QUANTITIES:
            if f"{q}_verdict" not in t.columns:
                continue
            parts = []
            for region, rows in (("inside", t[t["in_range"].astype(bool)] if "in_range" in t.columns else t.iloc[:0]),
                                 ("all", t)):
                v = rows[f"{q}_verdict"]
                if v.eq(VERDICTS[2]).all() and len(v):
                    parts.append(f"{region}: bench uncertainty not given")
                    continue
                en = np.abs(rows[f"{q}_en_number"].to_numpy(float))
                worst = f", max |E_n| {np.nanmax(en):.2f}" if np.isfinite(en).any() else ""
                parts.append(f"{region}: {int(v.eq(VERDICTS[0]).sum())}/{len(v)} agree{worst}")
            lines.append(f"  {route}, {q}: " + "; ".join(parts))
    return "\n".join(lines)
