"""Log files to result rows: read (any format), map channels, extract. Used by
``droptower extract`` and the benchmark."""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from droptower.errors import DroptowerError, expects
from droptower.extract.drop_spans import MIN_DROP_SPACING_S, PRE_TRIGGER_S, DropSpan, drop_signals, find_drops
from droptower.extract.extractor import extract
from droptower.extract.geometry import geometry_checks
from droptower.extract.result import ExtractionResult
from droptower.extract.window import Window
from droptower.io.logsettings import LogSettings
from droptower.io.signals import DropSignals
from droptower.jsonsafe import json_safe
from droptower.units import GRAVITY_M_PER_S2


@dataclass(frozen=True)
class Settings(LogSettings):
    """How to read (:class:`~droptower.io.logsettings.LogSettings`) and evaluate the logs of one
    batch: sample_rate_hz: time base for files without one; window: the evaluated window;
    reader_options: CSV settings for :func:`droptower.io.read_any`; drops: the drop numbers
    (from 1) to evaluate in each record (None: all); drop_conditions: drop number -> its
    conditions (``drop_height_m``, ``drop_mass_kg``, ``inertia_kgm2``, ``preload_nm``) over the
    log's metadata and the per-file ``conditions`` (drop conditions apply to one drop of a
    recording of several; the file's conditions to all its drops); pre_trigger_s,
    min_drop_spacing_s: see :func:`droptower.extract.drop_spans.find_drops`.
    """

    sample_rate_hz: float | None = None
    window: Window = Window()
    reader_options: dict[str, Any] = field(default_factory=dict)
    drops: frozenset[int] | None = None
    drop_conditions: dict[int, dict[str, float]] = field(default_factory=dict)
    pre_trigger_s: float = PRE_TRIGGER_S
    min_drop_spacing_s: float = MIN_DROP_SPACING_S

    def __post_init__(self):
        super().__post_init__()
        for name, least in (("sample_rate_hz", "> 0"), ("pre_trigger_s", ">= 0"), ("min_drop_spacing_s", "> 0")):
            value = getattr(self, name)
            if value is not None and not (isinstance(value, (int, float)) and math.isfinite(value)
                                          and (value > 0 or (least == ">= 0" and value == 0))):
                raise DroptowerError(f"must be a finite number {least}, got {value!r}", where=f"Settings.{name}")
        if not isinstance(self.window, Window):
            raise DroptowerError(f"expected a Window, got {type(self.window).__name__}", where="Settings.window")


@dataclass
class Drop:
    """One drop of a log: its span in the record, its signals and its result, or the error
    that stopped its evaluation (the other drops of the log are still evaluated)."""

    span: DropSpan
    drops_in_file: int
    signals: DropSignals
    result: ExtractionResult | None = None
    error: DroptowerError | None = None


#: a drop's flag when the next drop's impact comes before its oscillation died out
DECAY_CUT = "decay_cut_by_next_drop"


@expects(path=(str, Path), settings=Settings)
def extract_drops(path: str | Path, settings: Settings) -> list[Drop]:
    """Every drop of one log (or those ``settings.drops`` names), each evaluated on its own
    samples (:func:`droptower.extract.drop_spans.find_drops`). A problem of the whole file (unreadable,
    a drop number it does not have) is a DroptowerError naming the file; a drop that cannot be
    evaluated carries its error (naming the file and, in a recording of several, the drop)."""
    signals = settings.read_signals(path, sample_rate_hz=settings.sample_rate_hz, reader_options=settings.reader_options)
    try:
        spans = find_drops(signals, pre_trigger_s=settings.pre_trigger_s, min_spacing_s=settings.min_drop_spacing_s)
    except DroptowerError:  # no impact stands out of the whole record: the single-drop evaluation says why
        spans = [DropSpan(1, 0, signals.time_s.size, 0, None)]
    missing = sorted(set(settings.drops or ()) - {s.index for s in spans})
    if missing:
        raise DroptowerError(f"`drops` names drop(s) {', '.join(map(str, missing))}, the record holds "
                             f"{len(spans)} drop(s)", file=Path(path))
    drops = []
    for span in spans:
        if settings.drops is not None and span.index not in settings.drops:
            continue
        part = drop_signals(signals, span, settings.drop_conditions.get(span.index))
        drop = Drop(span, len(spans), part)
        try:
            drop.result = _extract(part, settings)
            if span.cut:
                drop.result.flags = (*drop.result.flags, DECAY_CUT)
            _record_geometry(part, drop.result, settings)
        except DroptowerError as exc:
            problem = exc.problem if len(spans) == 1 else f"drop {span.index}: {exc.problem}"
            drop.error = DroptowerError(problem, file=Path(path), where=exc.where)
        drops.append(drop)
    return drops


def _extract(signals: DropSignals, settings: Settings) -> ExtractionResult:
    defaults = settings.geometry_defaults
    given = {key: value if value is not None or key in signals.metadata else defaults.get(key)
             for key, value in (("inertia_kgm2", settings.inertia_kgm2), ("lever_length_m", settings.lever_length_m))}
    if given["inertia_kgm2"] is None and signals.metadata.get("inertia_kgm2") is None:
        raise DroptowerError(settings.no_inertia_reason(signals.metadata))
    gravity = settings.rig.gravity_m_per_s2 if settings.rig is not None else None  # the rig's g, when given
    return extract(signals, **given, window=settings.window, gravity_m_per_s2=gravity)


def _record_geometry(signals: DropSignals, result: ExtractionResult, settings: Settings) -> None:
    """What the drop's result needs to say about its geometry: the rig, the lever length and
    laser radius used (into the drop's metadata, so the row carries them), its fixture (the
    conditions', else the rig's name for its inertia), its temperature, and the geometry
    cross-checks (:mod:`droptower.extract.geometry`) as outputs and flags."""
    meta = signals.metadata
    rig = settings.rig
    lever = settings.lever_length_m
    if lever is None:
        lever = meta.get("lever_length_m", settings.geometry_defaults.get("lever_length_m"))
    try:
        lever = float(lever) if lever is not None else None
    except (TypeError, ValueError):
        lever = None
    if settings.lever_length_m is not None and meta.get("lever_length_m") not in (None, settings.lever_length_m):
        meta["log_lever_length_m"] = meta["lever_length_m"]
    meta["rig"] = rig.label if rig is not None else meta.get("rig", "")
    meta["lever_length_m"] = lever if lever is not None else math.nan
    meta.setdefault("sensor_radius_m", math.nan)
    if meta.get("fixture") is None:
        meta["fixture"] = (rig.fixture_name(result.inertia_kgm2) if rig is not None else None) or ""
    meta.setdefault("temperature_c", math.nan)
    restitution = rig.restitution if rig is not None else None
    if restitution is None and meta.get("restitution") is not None:
        try:
            restitution = float(meta["restitution"])
        except (TypeError, ValueError):
            restitution = None
    outputs, flags = geometry_checks(result, meta, lever, restitution,
                                     rig.gravity_m_per_s2 if rig is not None else GRAVITY_M_PER_S2)
    result.geometry = outputs
    result.flags = (*result.flags, *flags)


def extract_file(path: str | Path, settings: Settings, drop_index: int = 1) -> tuple[DropSignals, ExtractionResult]:
    """Read, map and extract one drop of one log (by default its first; a single-drop log's
    only one); any problem is a DroptowerError naming the file."""
    drops = extract_drops(path, replace(settings, drops=frozenset({drop_index})))
    if drops[0].error is not None:
        raise drops[0].error
    return drops[0].signals, drops[0].result


def _scalar(value: Any) -> Any:
    if value is None or isinstance(value, (str, bool, int, float)):
        return value
    return json.dumps(json_safe(value))


def _same(a: Any, b: Any) -> bool:
    try:
        return math.isclose(float(a), float(b), rel_tol=1e-12)
    except (TypeError, ValueError):
        return a == b


@expects(signals="droptower.io.signals.DropSignals", result="droptower.extract.result.ExtractionResult")
def result_row(path: str | Path, signals: DropSignals, result: ExtractionResult, drop_index: int = 1) -> dict[str, Any]:
    """One table row: ``file``, ``drop_index`` (the drop's number in its log, from 1),
    ``t_impact_s`` (its impact on the log's clock), the log's metadata (nested values as JSON
    text, the drop's conditions included), then every result of
    :meth:`ExtractionResult.to_dict`. A metadata key that is also a result is left out when
    the values agree (``inertia_kgm2`` used from the log) and kept as ``log_<key>`` when they
    differ (a given ``inertia_kgm2`` overrode the log's)."""
    results = result.to_dict()
    row: dict[str, Any] = {"file": str(path), "drop_index": int(drop_index), "t_impact_s": result.impact_time_s}
    for key, value in signals.metadata.items():
        if key in results or key in row:
            if _same(value, results.get(key)):
                continue
            key = f"log_{key}"
        row[key] = _scalar(value)
    row.update(results)
    return row
