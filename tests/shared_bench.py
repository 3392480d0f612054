"""One servo-bench run per distinct call, shared by the tests of a module (no tests in this module).

``validate`` and ``report`` compare the routes with servo points: with ``--coupling`` (or a
campaign's own coupling) they first run the sweeps on the virtual servo bench
(:func:`droptower.compare.servo_points.run_sweeps`), and a model-based map is then evaluated at
those points by re-simulating its coupling on the bench, nominal and band sets in one batch
(:func:`droptower.compare.model_map.bench_first_harmonics`). Both are deterministic simulations
of their inputs, so the same coupling (by content), parameter sets and points give the same
numbers: :func:`share_bench` computes each once per module and hands every later identical call
a copy. The key holds everything that reaches the simulation; what the callers do with the
result (the comparison, the verdicts, the tables and pages written) runs every time, as in
:mod:`shared_fits`.
"""
from __future__ import annotations

import copy
import hashlib
from contextlib import contextmanager
from typing import Any, Callable, Iterator

import numpy as np
import pytest


def _array_key(value: Any) -> tuple:
    a = np.ascontiguousarray(np.asarray(value, float))
    return (a.shape, hashlib.sha1(a.tobytes()).hexdigest())


def _coupling_key(coupling: Any) -> Any:
    """A coupling by content (a preset's name, a file or a loaded one alike): its TOML text and
    parameter rows; None where it cannot be loaded (the call itself then says why)."""
    from droptower.rheology import Coupling, coupling_to_toml, load_coupling

    try:
        loaded = coupling if isinstance(coupling, Coupling) else load_coupling(coupling)
        return (coupling_to_toml(loaded), _array_key(loaded.params))
    except Exception:  # noqa: BLE001 - not cached; the real call raises its own error
        return None


#: The runs :func:`share_bench` keeps per name (``keep``), for this process.
_KEPT: dict[str, dict[Any, Any]] = {}


class BenchCache:
    """Memoised sweeps and model-map bench evaluations; ``calls`` / ``runs`` count them."""

    def __init__(self, run_sweeps: Callable[..., Any], first_harmonics: Callable[..., Any],
                 store: dict[Any, Any] | None = None):
        self._run_sweeps, self._first_harmonics = run_sweeps, first_harmonics
        self._store: dict[Any, Any] = {} if store is None else store
        self.calls = self.runs = 0

    def _get(self, key: Any, run: Callable[[], Any]) -> Any:
        self.calls += 1
        if key[1] is None:  # a coupling that does not load: its own error, never a stored result
            return run()
        if key not in self._store:
            self.runs += 1
            self._store[key] = run()
        return copy.deepcopy(self._store[key])  # a caller that changes its copy changes no other test's

    def run_sweeps(self, coupling: Any, reduced: bool = False, *args: Any, **kwargs: Any) -> Any:
        key = ("sweeps", _coupling_key(coupling), bool(reduced), args, tuple(sorted(kwargs.items())))
        return self._get(key, lambda: self._run_sweeps(coupling, reduced, *args, **kwargs))

    def bench_first_harmonics(self, elements: Any, params: Any, amplitude_deg: Any, frequency_hz: Any) -> np.ndarray:
        a = np.atleast_1d(np.asarray(amplitude_deg, float))
        key = ("harmonics", _coupling_key(elements), _array_key(np.atleast_2d(params)), _array_key(a),
               _array_key(np.broadcast_to(np.asarray(frequency_hz, float), a.shape)))
        return self._get(key, lambda: self._first_harmonics(elements, params, amplitude_deg, frequency_hz))


@contextmanager
def share_bench(keep: str | None = None) -> Iterator[BenchCache]:
    """Route every call of ``run_sweeps`` (``droptower.compare``'s and its module's, which
    ``validate`` and the report's routes section import when they run) and of the model map's
    ``bench_first_harmonics`` through one :class:`BenchCache`. With ``keep`` (a name) its runs
    outlive the context in this process: session fixtures that each open it under one name
    (``validate`` and ``report`` of one model map against one bench) share them."""
    import droptower.compare as compare_package
    from droptower.compare import model_map, servo_points

    cache = BenchCache(servo_points.run_sweeps, model_map.bench_first_harmonics,
                       None if keep is None else _KEPT.setdefault(keep, {}))
    with pytest.MonkeyPatch.context() as mp:
        for target in (servo_points, compare_package):
            mp.setattr(target, "run_sweeps", cache.run_sweeps)
        mp.setattr(model_map, "bench_first_harmonics", cache.bench_first_harmonics)
        yield cache
