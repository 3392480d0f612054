"""What ``@pytest.mark.slow`` means: a test that takes more than SLOW_S seconds of wall time on
one quiet core (numba's compilation of a kernel the test is first to call included). Unmarked
tests over the limit are listed at the end of the run, so the marker stays true; a quick run
while editing is ``pytest -m "not slow"``. (Machine-dependent, so it is reported, not failed.)"""
from __future__ import annotations

import pytest

from regression import Regression

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


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--regenerate", action="store_true",
                     help="store the figures the tests measure (tests/regression.py) instead of comparing")


@pytest.fixture
def regression(request: pytest.FixtureRequest) -> Regression:
    """The test's stored figures (tests/data/regression/; ``python tests/regenerate.py``)."""
    return Regression(request.node, request.config.getoption("--regenerate"))


def pytest_collection_modifyitems(config, items) -> None:
    """Tests that store figures are marked ``regression`` (what ``tests/regenerate.py`` selects)."""
    for item in items:
        if "regression" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.regression)
