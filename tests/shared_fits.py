"""One fit per distinct call, shared by the tests of a module (no tests in this module).

Several tests prove different things about the same identification: the library's figures,
the command line's report of it, its exit code, the coupling it writes, its place in a
``compare-models`` table. The fits are deterministic (seeded searches, fixed data), so a call
with the same family, data, settings and options gives the same result; :func:`share_fits`
makes the library compute it once per module and hand every later identical call a copy.
The key holds every argument that reaches the fit (the data by content, not by identity), so
a call that differs in anything is fitted anew; what the callers do with the result (the
command line's reports, writing, exit codes) runs every time.
"""
from __future__ import annotations

import copy
import dataclasses
import hashlib
from contextlib import contextmanager
from typing import Any, Callable, Iterator

import numpy as np
import pytest

import droptower.identify as identify_package
from droptower.identify import drop_campaign, dropfit, strategies


def fingerprint(obj: Any) -> Any:
    """A hashable value equal for equal contents (arrays by their bytes)."""
    if obj is None or isinstance(obj, (bool, int, float, str)):
        return obj
    if isinstance(obj, np.ndarray):
        return ("array", obj.shape, obj.dtype.str, hashlib.sha1(np.ascontiguousarray(obj).tobytes()).hexdigest())
    if isinstance(obj, np.generic):
        return obj.item()
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return (type(obj).__name__, tuple((f.name, fingerprint(getattr(obj, f.name))) for f in dataclasses.fields(obj)))
    if isinstance(obj, dict) or hasattr(obj, "items"):
        return ("map", tuple(sorted((str(k), fingerprint(v)) for k, v in obj.items())))
    if isinstance(obj, (list, tuple)):
        return ("seq", tuple(fingerprint(v) for v in obj))
    return (type(obj).__name__, repr(obj))


def _previous_start(kind: str, previous: dict[str, Any] | None) -> Any:
    """What of ``previous`` reaches the fit: only the contained family's result it starts from."""
    inner = strategies.SEARCH_THROUGH.get(kind)
    first = (previous or {}).get(inner) if inner else None
    if first is None:
        return None
    return (inner, fingerprint(list(first.parameters.values())), first.fit_error.nrmse, first.evaluations,
            "global_search" in first.extra)


def _given_options(kind: str, segments: list, options: dict[str, Any] | None) -> Any:
    """``options`` less those equal to the family's defaults (a family that starts from the one
    it contains passes it the defaults of the options they share: the same fit as none)."""
    from droptower.identify.data import DataScale
    from droptower.identify.families import family_class

    if not options:
        return fingerprint({})
    try:
        defaults = family_class(kind)(DataScale.of(segments)).options
    except Exception:  # noqa: BLE001 - an unknown kind or bad data: the fit itself says so
        defaults = {}
    return fingerprint({k: v for k, v in options.items() if k not in defaults or defaults[k] != v})


#: The fits :func:`share_fits` keeps per test file (``keep``), for this process.
_KEPT: dict[str, dict[Any, Any]] = {}


class FitCache:
    """Memoised :func:`~droptower.identify.strategies.identify` and
    :func:`~droptower.identify.dropfit.identify_drops`; ``calls`` / ``fits`` count them, ``keys``
    lists every call's key."""

    def __init__(self, servo: Callable[..., Any], drop: Callable[..., Any], store: dict[Any, Any] | None = None):
        self._servo, self._drop = servo, drop
        self._store: dict[Any, Any] = {} if store is None else store
        self.calls = self.fits = 0
        self.keys: list[Any] = []  # every call's key, in order (two calls of equal keys read the same data)

    def _get(self, key: Any, fit: Callable[[], Any]) -> Any:
        self.calls += 1
        self.keys.append(key)
        if key not in self._store:
            self.fits += 1
            self._store[key] = fit()
        return copy.deepcopy(self._store[key])  # a caller that changes its copy changes no other test's

    def servo(self, kind: str, segments: list, *, init=None, bounds=None, options=None, holdout=None, previous=None,
              file=None, search: str = "auto", seed: int = 0) -> Any:
        key = ("servo", kind, fingerprint(segments), fingerprint(init or None), fingerprint(bounds or None),
               _given_options(kind, segments, options), fingerprint(holdout), _previous_start(kind, previous), file, search, seed)
        return self._get(key, lambda: self._servo(kind, segments, init=init, bounds=bounds, options=options,
                                                  holdout=holdout, previous=previous, file=file, search=search,
                                                  seed=seed))

    def drop(self, kind: str, decays: list, *, excluded=None, settings=None, init=None, bounds=None,
             options=None) -> Any:
        settings = dropfit.DropFitSettings() if settings is None else settings
        key = ("drop", kind, fingerprint(decays), fingerprint(excluded or []), fingerprint(settings),
               fingerprint(init or None), fingerprint(bounds or None), fingerprint(options or {}))
        return self._get(key, lambda: self._drop(kind, decays, excluded=excluded, settings=settings, init=init,
                                                 bounds=bounds, options=options))


@contextmanager
def share_fits(*modules: Any, keep: str | None = None) -> Iterator[FitCache]:
    """Route every call of ``identify`` / ``identify_drops`` (the library's own, the command
    line's, ``compare_models``'s, and the names the test ``modules`` imported) through one
    :class:`FitCache`. With ``keep`` (a test file's module name) its fits outlive the context
    in this process: when worksteal splits the file into two blocks of one worker, the second
    block's fixture finds the first's fits (the same keys, so the same fits)."""
    servo, drop = strategies.identify, dropfit.identify_drops
    cache = FitCache(servo, drop, None if keep is None else _KEPT.setdefault(keep, {}))
    with pytest.MonkeyPatch.context() as mp:
        for target in (strategies, identify_package, *modules):
            if getattr(target, "identify", None) is servo:
                mp.setattr(target, "identify", cache.servo)
        for target in (dropfit, drop_campaign, *modules):
            if getattr(target, "identify_drops", None) is drop:
                mp.setattr(target, "identify_drops", cache.drop)
        yield cache
