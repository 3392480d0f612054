"""An exception in pymunk's collision callbacks stops the simulation instead of vanishing in cffi.

cffi prints an exception that leaves a callback and goes on as if it had returned: a Ctrl-C that
landed in the contact callbacks let a campaign run to its end with one test's record spoilt
(droptower/rig/callbacks.py).
"""
import gc
import signal
import sys
import threading

import numpy as np
import pymunk
import pytest

from droptower.rheology.loader import parse_coupling
from droptower.rig import scene
from droptower.rig.callbacks import raising_callback_errors
from droptower.rig.config import load_rig
from droptower.rig.simulate import DropTest, simulate

LINEAR = {"name": "linear", "element": [{"kind": "spring", "stiffness": 14000.0}, {"kind": "dashpot", "damping": 50.0}]}
TESTS = [DropTest(0.359, 2.0, 0.4), DropTest(0.1557, 1.0, 1.0)]


@pytest.fixture(scope="module")
def rig():
    return load_rig("rapp2022")


@pytest.fixture(scope="module")
def linear():
    return parse_coupling(LINEAR)


class Defect(Exception):
    pass


@pytest.fixture(autouse=True)
def no_leftover_spaces():
    """pymunk calls ``separate`` for the open contacts of a space it frees: a space of an earlier
    test, freed by the garbage collector while this test has patched a callback, would call it
    outside this test's simulation. No collection runs during the test (a full one before it
    cost ~0.3 s per test in a worker that has run many)."""
    enabled = gc.isenabled()
    gc.disable()
    yield
    if enabled:
        gc.enable()


@pytest.mark.parametrize("callback", ["begin", "separate"])
@pytest.mark.parametrize("error", [KeyboardInterrupt, Defect])
def test_an_exception_in_a_contact_callback_stops_the_simulation(rig, linear, monkeypatch, callback, error):
    original = getattr(scene._Contacts, callback)
    calls = []

    def failing(self, *args, **kwargs):  # once, as a Ctrl-C: pymunk calls ``separate`` again when the space is freed
        calls.append(args)
        original(self, *args, **kwargs)
        if len(calls) == 1:
            raise error("raised in the callback")

    monkeypatch.setattr(scene._Contacts, callback, failing)
    hook = sys.unraisablehook
    with pytest.raises(error, match="raised in the callback"):
        simulate(rig, linear, TESTS, duration_s=0.05)
    assert calls  # the callback ran, and its exception came out of the run, not out of cffi's printer
    assert sys.unraisablehook is hook  # restored


def test_ctrl_c_in_a_contact_callback_interrupts_the_simulation(rig, linear, monkeypatch):
    """The real signal, delivered while pymunk's ``begin`` callback runs: Python's SIGINT
    handler raises KeyboardInterrupt inside the callback."""
    if threading.current_thread() is not threading.main_thread():
        pytest.fail("signal handlers are set from the main thread only; pytest runs tests there")
    original = scene._Contacts.begin

    def signalled(self, *args, **kwargs):
        signal.raise_signal(signal.SIGINT)
        original(self, *args, **kwargs)

    monkeypatch.setattr(scene._Contacts, "begin", signalled)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            simulate(rig, linear, TESTS, duration_s=0.05)
    finally:
        signal.signal(signal.SIGINT, previous)


def test_the_same_tests_run_after_an_interrupted_one_are_unchanged(rig, linear, monkeypatch):
    """Nothing of an interrupted run lingers: the hook is gone and a rerun gives the same records."""
    before = simulate(rig, linear, TESTS, duration_s=0.05)

    raised = []

    def failing(self, *args, **kwargs):
        if not raised:
            raised.append(True)
            raise KeyboardInterrupt

    with monkeypatch.context() as patch:
        patch.setattr(scene._Contacts, "begin", failing)
        with pytest.raises(KeyboardInterrupt):
            simulate(rig, linear, TESTS, duration_s=0.05)
    after = simulate(rig, linear, TESTS, duration_s=0.05)
    for a, b in zip(before, after):
        np.testing.assert_array_equal(a.angle_rad, b.angle_rad)


def _callback_raising_in_a_space(error: BaseException) -> pymunk.Space:
    """A space whose first step calls a ``begin`` callback that raises ``error``."""
    space = pymunk.Space()
    ball = pymunk.Body(1.0, float("inf"))
    ball.position = (0.0, 0.4)
    circle = pymunk.Circle(ball, 0.5)
    circle.collision_type = 1
    floor = pymunk.Segment(space.static_body, (-5.0, 0.0), (5.0, 0.0), 0.0)
    floor.collision_type = 2
    space.add(ball, circle, floor)

    def begin(arbiter, space, data):
        raise error

    space.on_collision(1, 2, begin=begin)
    return space


def test_other_threads_and_other_unraisables_reach_the_previous_hook(monkeypatch):
    """Only this thread's cffi callbacks are kept; a callback's exception in an unwatched thread,
    and an exception of another origin (a ``__del__``), go to the hook that was there."""
    passed_on = []
    monkeypatch.setattr(sys, "unraisablehook", lambda u: passed_on.append((type(u.exc_value), u.err_msg or "", u.object)))

    class Finaliser:
        def __del__(self):
            raise Defect("in __del__")

    with raising_callback_errors() as check:
        other = threading.Thread(target=lambda: _callback_raising_in_a_space(Defect("other thread")).step(0.01))
        other.start()
        other.join()
        Finaliser()  # collected at once: its __del__ raises
        check()  # nothing of this thread's callbacks
        _callback_raising_in_a_space(Defect("this thread")).step(0.01)
        with pytest.raises(Defect, match="this thread"):
            check()
        check()  # raised once
    assert [t for t, _, _ in passed_on] == [Defect, Defect]
    assert "cffi callback" in passed_on[0][1] and passed_on[1][2].__name__ == "__del__"


def test_an_exception_kept_but_not_checked_is_raised_on_leaving():
    with pytest.raises(Defect, match="unchecked"):
        with raising_callback_errors():
            _callback_raising_in_a_space(Defect("unchecked")).step(0.01)
