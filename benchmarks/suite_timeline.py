"""A pytest plugin that writes the timeline of a run, one JSON line per event, one file per
process (the xdist controller and each worker) in the folder ``$SUITE_TIMELINE_DIR``.

Loaded by ``benchmarks/bench_suite.py`` (``-p suite_timeline`` with this folder on the path, which
xdist passes on to its workers). Events: the process's start (from ``/proc``), collection start
and end, each test's start and end (setup, call and teardown), each numba compilation (its
dispatcher, nesting depth, start and end). Every line carries the wall clock ``t`` (s since the
epoch) and the process's CPU time ``cpu`` (s), so a loaded machine does not hide where the CPU went.
"""
from __future__ import annotations

import json
import os
import time

_DIR = os.environ.get("SUITE_TIMELINE_DIR")
_WORKER = os.environ.get("PYTEST_XDIST_WORKER", "controller")
_out = None
_depth = 0


def _process_start() -> float | None:
    """When this process started (s since the epoch), from /proc; None where there is no /proc."""
    try:
        with open("/proc/self/stat") as stat:
            ticks = int(stat.read().rsplit(")", 1)[1].split()[19])  # field 22: start time in clock ticks
        with open("/proc/stat") as proc_stat:
            boot = next(int(line.split()[1]) for line in proc_stat if line.startswith("btime"))
        return boot + ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, StopIteration):
        return None


def _write(event: str, **fields: object) -> None:
    if _out is not None:
        _out.write(json.dumps({"event": event, "worker": _WORKER, "t": time.time(),
                               "cpu": time.process_time(), **fields}) + "\n")


def _listen_to_numba() -> None:
    """Record every compilation numba does (a cache load is not one); nested ones carry their depth."""
    from numba.core import event as numba_event

    class Compilations(numba_event.Listener):
        def on_start(self, event: numba_event.Event) -> None:
            global _depth
            _write("compile_start", function=_name(event), depth=_depth)
            _depth += 1

        def on_end(self, event: numba_event.Event) -> None:
            global _depth
            _depth -= 1
            _write("compile_end", function=_name(event), depth=_depth)

    numba_event.register("numba:compile", Compilations())


def _name(event) -> str:
    func = event.data["dispatcher"].py_func
    return f"{func.__module__}.{func.__qualname__}"


def pytest_configure(config) -> None:
    global _out
    if _DIR is None or _out is not None:
        return
    os.makedirs(_DIR, exist_ok=True)
    _out = open(os.path.join(_DIR, f"{_WORKER}-{os.getpid()}.jsonl"), "a", buffering=1)
    _write("process_start", process_start=_process_start())
    _listen_to_numba()


def pytest_collection(session) -> None:
    _write("collection_start")


def pytest_collection_finish(session) -> None:
    _write("collection_finish", items=len(session.items))


def pytest_runtest_logstart(nodeid: str, location) -> None:
    _write("test_start", test=nodeid)


def pytest_runtest_logfinish(nodeid: str, location) -> None:
    _write("test_finish", test=nodeid)


def pytest_unconfigure(config) -> None:
    _write("end")
