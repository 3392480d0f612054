"""Values as strict JSON data: the one conversion every JSON the package writes goes through.

Policy (:func:`json_safe`):

- NaN and +/-infinity become ``None`` (JSON ``null``: "no value"; strict JSON, RFC 8259, has no
  NaN, and a reader in another language would fail on Python's ``NaN`` token);
- numpy scalars become the Python ``bool``, ``int`` or ``float`` they hold, numpy arrays
  (nested) lists, tuples and sets lists;
- mappings become dicts with string keys (a non-string key is written as ``json.dumps`` would
  write it: ``1`` -> ``"1"``, ``True`` -> ``"true"``);
- paths become their text, dates and times their ISO 8601 text;
- ``None``, ``bool``, ``int`` and ``str`` stay as they are; anything else becomes its ``str()``.

The result ``json.dumps(..., allow_nan=False)`` always accepts.
"""
from __future__ import annotations

import datetime as dt
import json
import math
from collections.abc import Mapping
from os import PathLike
from typing import Any

import numpy as np

__all__ = ["json_safe"]


def json_safe(value: Any) -> Any:
    """``value`` as strict JSON data (see the module's policy: NaN and infinities as None).

    Parameters
    ----------
    value
        Any nesting of mappings, sequences, numpy arrays and scalars, paths and numbers.

    Returns
    -------
    The same data built from dict, list, str, int, float, bool and None only.
    """
    if value is None or (isinstance(value, (str, bool, int)) and not isinstance(value, np.generic)):
        return value
    if isinstance(value, float):  # numpy's float64 too
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.ndarray):
        return json_safe(value.tolist())
    if isinstance(value, np.generic):
        return json_safe(value.item())
    if isinstance(value, Mapping):
        return {_key(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, set, frozenset)):
        return [json_safe(v) for v in value]
    if isinstance(value, PathLike):
        return str(value)
    if isinstance(value, (dt.date, dt.time)):
        return value.isoformat()
    return str(value)


def _key(key: Any) -> str:
    if isinstance(key, str):
        return key
    key = json_safe(key)
    return key if isinstance(key, str) else json.dumps(key)
