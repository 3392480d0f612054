"""Log files to result rows: read (any format), map channels, extract. Used by
``droptower extract`` and the benchmark."""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from droptower.extract.extractor import extract
from droptower.extract.result import ExtractionResult
from droptower.extract.window import Window
from droptower.io.logsettings import LogSettings
from droptower.io.signals import DropSignals


@dataclass(frozen=True)
class Settings(LogSettings):
    """How to read (:class:`~droptower.io.logsettings.LogSettings`) and evaluate the logs of one
    batch: sample_rate_hz: time base for files without one; window: the evaluated window;
    reader_options: CSV settings for :func:`droptower.io.read_any`.
    """

    sample_rate_hz: float | None = None
    window: Window = Window()
    reader_options: dict[str, Any] = field(default_factory=dict)


def extract_file(path: str | Path, settings: Settings) -> tuple[DropSignals, ExtractionResult]:
    """Read, map and extract one log; any problem is a DroptowerError naming the file."""
    signals = settings.read_signals(path, sample_rate_hz=settings.sample_rate_hz, reader_options=settings.reader_options)
    given = {key: value if value is not None or key in signals.metadata else settings.defaults.get(key)
             for key, value in (("inertia_kgm2", settings.inertia_kgm2), ("lever_length_m", settings.lever_length_m))}
    result = extract(signals, **given, window=settings.window)
    return signals, result


def _scalar(value: Any) -> Any:
    if value is None or isinstance(value, (str, bool, int, float)):
        return value
    return json.dumps(value, default=str)


def _same(a: Any, b: Any) -> bool:
    try:
        return math.isclose(float(a), float(b), rel_tol=1e-12)
    except (TypeError, ValueError):
        return a == b


def result_row(path: str | Path, signals: DropSignals, result: ExtractionResult) -> dict[str, Any]:
    """One table row: ``file``, the log's metadata (nested values as JSON text), then every result
    of :meth:`ExtractionResult.as_dict`. A metadata key that is also a result is left out when
    the values agree (``inertia_kgm2`` used from the log) and kept as ``log_<key>`` when they
    differ (``--inertia-kgm2`` overrode the log's)."""
    results = result.as_dict()
    row: dict[str, Any] = {"file": str(path)}
    for key, value in signals.metadata.items():
        if key in results or key == "file":
            if _same(value, results.get(key)):
                continue
            key = f"log_{key}"
        row[key] = _scalar(value)
    row.update(results)
    return row


def json_safe(row: dict[str, Any]) -> dict[str, Any]:
    """NaN and infinities -> None, so the row is strict JSON."""
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in row.items()}
