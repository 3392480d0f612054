"""One characteristic-map fit per distinct set of tests, shared by the tests that ask for it (no
tests in this module).

A map (Rapp et al. 2022, eq. 19/20, or another form) is a deterministic fit of its tests'
amplitudes, frequencies, stiffnesses and damping ratios: :func:`droptower.maps.select.fit_form`
takes nothing else (the form, those four arrays, the cross-validation groups and method). The
commands that read one campaign's tests each fit it again — ``map`` of every table format
``extract --out`` writes, ``map FOLDER`` and ``report FOLDER`` of the same logs, ``report`` of a
campaign whose map ``map`` already fitted — and :func:`share_map_fits` makes the fit run once
per distinct input and hands every later call a copy. The key is the fit's whole input, by
content (not the file, the format or the path it was read from), so a table that reads back
with one bit changed is fitted anew; everything around the fit (reading, selecting the tests,
the exclusions, the map's file, the printout) runs every time, as in :mod:`shared_fits`.

Not for the tests whose claim is the fit itself (its determinism, its cross-validation against
refits): they call the library without it.
"""
from __future__ import annotations

import copy
import hashlib
from contextlib import contextmanager
from typing import Any, Iterator

import numpy as np
import pytest

#: the fits kept for this process: the session fixtures of tests/conftest.py and the modules that
#: read the same tests (test_lab_folder_e2e.py's map and report of one folder) share them
_KEPT: dict[Any, Any] = {}


def _key(form: Any, arrays: tuple[np.ndarray, ...], cv_method: str) -> Any:
    digest = hashlib.sha1()
    for a in arrays:
        a = np.ascontiguousarray(a)
        digest.update(repr((a.dtype.str, a.shape)).encode())
        digest.update(a.tobytes() if a.dtype.kind != "O" else repr(a.tolist()).encode())
    return (repr(form), digest.hexdigest(), cv_method)


class MapFitCache:
    """Memoised :func:`~droptower.maps.select.fit_form`; ``calls`` / ``fits`` count them."""

    def __init__(self, fit_form: Any, store: dict[Any, Any]):
        self._fit_form, self._store = fit_form, store
        self.calls = self.fits = 0

    def fit_form(self, form: Any, a: np.ndarray, f: np.ndarray, c: np.ndarray, d: np.ndarray, groups: np.ndarray,
                 cv_method: str) -> Any:
        key = _key(form, (a, f, c, d, groups), cv_method)
        self.calls += 1
        if key not in self._store:
            self.fits += 1
            self._store[key] = self._fit_form(form, a, f, c, d, groups, cv_method)
        return copy.deepcopy(self._store[key])  # a caller that changes its copy changes no other test's


@contextmanager
def share_map_fits() -> Iterator[MapFitCache]:
    """Route every map fit (``droptower.maps.select.fit_form``, which ``fit_map`` calls for the
    library, the commands and the report alike) through one :class:`MapFitCache` whose fits
    outlive the context in this process."""
    from droptower.maps import select

    cache = MapFitCache(select.fit_form, _KEPT)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(select, "fit_form", cache.fit_form)
        yield cache
