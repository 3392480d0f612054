"""What ``@pytest.mark.slow`` means: a test that takes more than SLOW_S seconds of wall time on
one quiet core (numba's compilation of a kernel the test is first to call included). Unmarked
tests over the limit are listed at the end of the run, so the marker stays true; a quick run
while editing is ``pytest -m "not slow"``. (Machine-dependent, so it is reported, not failed.)"""
from __future__ import annotations

import pytest

SLOW_S = 5.0

_unmarked: list[tuple[float, str]] = []


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    if report.when == "call" and report.duration > SLOW_S and "slow" not in report.keywords:
        _unmarked.append((report.duration, report.nodeid))


def pytest_terminal_summary(terminalreporter, exitstatus, config) -> None:
    if _unmarked:
        terminalreporter.section(f"tests over {SLOW_S:g} s without @pytest.mark.slow")
        for duration, nodeid in sorted(_unmarked, reverse=True):
            terminalreporter.write_line(f"{duration:6.1f} s  {nodeid}")
