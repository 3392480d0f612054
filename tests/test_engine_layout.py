"""The identification runs through ONE engine whose layers call each other one way: following
the model family's name from the entry points (``identify_from_drop_tests`` for drop tests,
``identify`` for servo records) down every call of a tiny fit, no module of
:mod:`droptower.identify` is entered more than :data:`MAX_VISITS` times along one call path.

A visit is a run of consecutive frames of one module on the call stack (frames outside
``droptower.identify``, e.g. SciPy's optimiser calling back, are transparent): a driver that
hands a callback to a search which calls back into the driver, which calls the fitter, which
calls back into the driver's closure, visits the driver four times. Counted with
:func:`sys.setprofile` on the fits themselves, so a new callback path fails the test whatever
its name."""
from __future__ import annotations

import sys
from collections import Counter
from typing import Any, Callable

import pytest

from droptower.identify.droplogs import ReadSettings
from droptower.identify.dropfit import DropFitSettings
from droptower.identify.drop_campaign import DropCampaign, identify_from_drop_tests
from droptower.identify.strategies import identify

from test_engine_regression import _servo_records
from test_identify_engine import _decays

#: Entries of one module along one call path at most.
MAX_VISITS = 3
ROOM = "droptower.identify"


def visits(run: Callable[[], Any]) -> tuple[dict[str, int], list[str]]:
    """Per module of :data:`ROOM`, the most entries along one call path while ``run()`` runs,
    and the worst path (the modules entered, in order)."""
    stack: list[tuple[str | None, Counter, tuple[str, ...]]] = []
    worst: dict[str, int] = {}
    worst_path: list[tuple[str, ...]] = [()]

    def profile(frame, event, arg):
        if event == "call":
            name = frame.f_globals.get("__name__", "")
            prev, counts, path = stack[-1] if stack else (None, Counter(), ())
            if name.startswith(ROOM) and name != prev:
                counts = counts.copy()
                counts[name] += 1
                path = path + (f"{name}.{frame.f_code.co_name}",)
                if counts[name] > worst.get(name, 0):
                    worst[name] = counts[name]
                    if counts[name] == max(worst.values()):
                        worst_path[0] = path
                prev = name
            stack.append((prev, counts, path))
        elif event == "return" and stack:
            stack.pop()

    sys.setprofile(profile)
    try:
        run()
    finally:
        sys.setprofile(None)
    return worst, list(worst_path[0])


#: Few evaluations per local fit: every stage of the search runs (escalation, loose prior, the
#: exponent's walk, basin moves, a deferred branch), cheaply.
QUICK = DropFitSettings(holdout_fraction=0.0, conditioning=None, max_nfev=2)


def _drops(kind: str, options: dict | None = None) -> Callable[[], Any]:
    campaign = DropCampaign(_decays(kind, n_tests=3, duration_s=0.02), [], QUICK, dict(options or {}), ReadSettings())
    return lambda: identify_from_drop_tests(campaign, kind)


@pytest.mark.parametrize("kind,options", [("elastoslide", None), ("masing", None), ("filled_rubber", {"n": 4})])
def test_a_drop_fit_enters_no_module_more_than_three_times(kind, options):
    worst, path = visits(_drops(kind, options))
    over = {m: n for m, n in worst.items() if n > MAX_VISITS}
    assert not over, f"entered more than {MAX_VISITS} times along one call path: {over}; path: {' -> '.join(path)}"


@pytest.mark.parametrize("kind,search", [("elastoslide", "never"), ("zerodim6", "always")])
def test_a_servo_fit_enters_no_module_more_than_three_times(kind, search):
    segments = _servo_records(kind)
    worst, path = visits(lambda: identify(kind, segments, search=search, options={"max_nfev": 3}))
    over = {m: n for m, n in worst.items() if n > MAX_VISITS}
    assert not over, f"entered more than {MAX_VISITS} times along one call path: {over}; path: {' -> '.join(path)}"


def test_the_count_sees_a_callback_that_comes_back():
    """The measure itself: a driver that hands a callback to a loop in another module, which
    calls it, is entered twice along that path; the loop once more when the callback calls it."""
    import types

    a, b = types.ModuleType(f"{ROOM}.driver"), types.ModuleType(f"{ROOM}.loop")
    exec("def drive(b):\n    return b.loop(back)\n\ndef back(b):\n    return b.leaf()\n", a.__dict__)
    exec("import sys\ndef loop(f):\n    return f(sys.modules[__name__])\n\ndef leaf():\n    return 1\n", b.__dict__)
    sys.modules[b.__name__] = b
    try:
        worst, path = visits(lambda: a.drive(b))
    finally:
        del sys.modules[b.__name__]
    assert worst == {a.__name__: 2, b.__name__: 2}
    assert [p.rsplit(".", 1)[1] for p in path] == ["drive", "loop", "back", "leaf"]


def test_the_families_hooks_are_declared_and_never_looked_up():
    """Every optional hook a family may offer is declared on the base class with a default
    (the engine calls it on every family), so no module of the room asks whether a family has
    one: no ``hasattr`` at all, no ``getattr`` of a hook's name."""
    import ast
    import inspect
    from pathlib import Path

    from droptower.identify.families.base import Family

    hooks = {"DEFERRED", "without_branch", "branch_off", "guess_from_readings", "basin_moves", "idle_parameters",
             "choices", "move_choice", "derived", "substeps"}
    assert hooks <= set(dir(Family))
    room = Path(inspect.getfile(Family)).parents[1]
    found = []
    for path in room.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("hasattr", "getattr"):
                name = node.args[1].value if len(node.args) > 1 and isinstance(node.args[1], ast.Constant) else None
                if node.func.id == "hasattr" or name in hooks:
                    found.append(f"{path.relative_to(room)}:{node.lineno} {node.func.id}({name!r})")
    assert not found, found
