"""Every public function and class of every package's ``__all__``, fed random wrong input (NaN,
inf, empty, mismatched, wrong-typed), raises only DroptowerError, TypeError or ValueError (never
an AttributeError, IndexError or KeyError from inside), and drops no sample silently: a
function that accepts a non-finite sample answers it sample for sample (NaN in, NaN out).

Then the array entry points on valid records with one random non-finite sample: each refuses it,
naming the array and the sample."""
from __future__ import annotations

import importlib
import inspect
import pkgutil
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

import droptower
from droptower.errors import DroptowerError

ALLOWED = (DroptowerError, TypeError, ValueError)


def _public() -> dict[str, object]:
    """qualified name -> callable, for every name in the ``__all__`` of droptower and its packages."""
    out = {}
    modules = [droptower] + [importlib.import_module(f"droptower.{m.name}")
                             for m in pkgutil.iter_modules(droptower.__path__) if m.ispkg and m.name != "cli"]
    for module in modules:
        for name in getattr(module, "__all__", ()):
            obj = getattr(module, name)
            if callable(obj) and not (isinstance(obj, type) and issubclass(obj, BaseException)):
                out[f"{module.__name__}.{name}"] = obj
    return out


PUBLIC = _public()
NAMES = sorted(PUBLIC)


def _required(func) -> list[inspect.Parameter]:
    try:
        params = inspect.signature(func).parameters.values()
    except (TypeError, ValueError):
        return []
    return [p for p in params if p.default is p.empty and p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]


def _non_finite_array(n: int, index: int, value: float) -> np.ndarray:
    a = np.linspace(0.0, 1.0, n)
    a[index % n] = value
    return a


bad_values = st.one_of(
    st.sampled_from([None, 3, -1.5, 0, True, "", "no_such_file.csv", [], {}, (), object(), b"\x00",
                     float("nan"), float("inf"), -float("inf"), np.array([]), np.zeros((2, 3)), np.zeros((0, 4)),
                     {"a": 1}, ["a", 2], ("x", None)]),
    st.builds(_non_finite_array, st.integers(1, 40), st.integers(0, 39),
              st.sampled_from([float("nan"), float("inf"), -float("inf")])),
    st.builds(lambda n: np.linspace(0.0, 1.0, n), st.integers(0, 5)),  # short or mismatched with its neighbours
    st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=5),
)


def _non_finite(value) -> np.ndarray | None:
    """The non-finite mask of a numeric array argument (None if not one or all finite)."""
    if isinstance(value, float):
        value = np.array([value])
    if isinstance(value, np.ndarray) and value.dtype.kind == "f" and value.size and not np.isfinite(value).all():
        return ~np.isfinite(value)
    return None


def test_the_property_test_covers_every_package():
    packages = {name.rsplit(".", 1)[0] for name in NAMES}
    assert {"droptower", "droptower.extract", "droptower.identify", "droptower.io", "droptower.maps",
            "droptower.rheology", "droptower.rig", "droptower.servo", "droptower.compare", "droptower.campaign",
            "droptower.design", "droptower.planner", "droptower.fmu"} <= packages
    assert len(NAMES) > 50


@settings(max_examples=600, derandomize=True, deadline=None, suppress_health_check=list(HealthCheck))
@given(st.data())
def test_wrong_input_gives_a_clear_error(tmp_path_factory, data):
    name = data.draw(st.sampled_from(NAMES), label="function")
    func = PUBLIC[name]
    args = [data.draw(bad_values, label=p.name) for p in _required(func)]
    work = tmp_path_factory.mktemp("api")
    with pytest.MonkeyPatch.context() as mp, warnings.catch_warnings():
        mp.chdir(work)  # a function that writes (a log, a page) writes here
        warnings.simplefilter("ignore")
        try:
            result = func(*args)
        except ALLOWED as exc:
            assert str(exc), f"{name}: an error without a message"
            return
        except BaseException as exc:  # the defect this test exists for
            raise AssertionError(f"{name}({', '.join(type(a).__name__ for a in args)}) raised "
                                 f"{type(exc).__name__}: {exc}") from exc
    if isinstance(func, type):  # a record / result container: built as given, checked where it is used
        return
    for arg in args:  # a function that accepted a non-finite sample answers it sample for sample
        mask = _non_finite(arg)
        if mask is not None:
            out = np.asarray(result, dtype=float)
            if isinstance(arg, float) and out.ndim == 0:  # a scalar answered by a scalar is sample for sample
                out = out.reshape(1)
            assert out.shape == mask.shape and np.array_equal(~np.isfinite(out), mask), \
                f"{name} accepted a non-finite sample and did not answer it sample for sample"


# --------------------------------------------------------------------------- array entry points
def _record(n: int):
    t = np.arange(n) / 1000.0
    angle = 0.01 * np.sin(2 * np.pi * 5.0 * t) + 0.002 * np.sin(2 * np.pi * 13.0 * t)
    return [t, angle, 1000.0 * angle]


def _segment(arrays):
    from droptower.identify import make_segment

    return make_segment(*arrays)


def _servo(arrays):
    from droptower.servo import evaluate_cycles

    return evaluate_cycles(*arrays, 5.0, 0.0, 2)


def _history(arrays):
    from droptower.rheology.loader import parse_coupling

    coupling = parse_coupling({"name": "k", "element": [{"kind": "spring", "stiffness": 1e4}]})
    return coupling.simulate(arrays[1], 1e-3)


def _signals(arrays):
    from droptower.extract import extract
    from droptower.io import DropSignals

    return extract(DropSignals(arrays[0], arrays[1], arrays[2], metadata={"inertia_kgm2": 0.1}))


ENTRY = {"make_segment": (_segment, ("time_s", "angle_rad", "torque_nm")),
         "evaluate_cycles": (_servo, ("time_s", "angle_rad", "torque_nm")),
         "Coupling.simulate": (_history, ("angle_rad",)),
         "extract": (_signals, ("time_s", "angle_rad", "torque_nm"))}


@settings(max_examples=80, derandomize=True, deadline=None)
@given(st.sampled_from(sorted(ENTRY)), st.integers(0, 2), st.integers(400, 2048), st.floats(0, 1),
       st.sampled_from([float("nan"), float("inf"), -float("inf")]))
def test_one_non_finite_sample_is_refused_by_name_and_index(entry, which, n, where, value):
    call, names = ENTRY[entry]
    arrays = _record(n)
    which = {1: 1}.get(len(names), which)  # the history has only the angle
    index = min(int(where * n), n - 1)
    arrays[which] = arrays[which].copy()
    arrays[which][index] = value
    name = names[which] if len(names) > 1 else names[0]
    with pytest.raises(DroptowerError) as info:
        call(arrays)
    text = str(info.value)
    assert name in text and (f"sample {index}" in text or "NaN" in text), text
