"""What ``@pytest.mark.slow`` means: a test that takes more than SLOW_S seconds of wall time on
one quiet core (numba's compilation of a kernel the test is first to call included). Unmarked
tests over the limit are listed at the end of the run, so the marker stays true; a quick run
while editing is ``pytest -m "not slow"``. (Machine-dependent, so it is reported, not failed.)"""
from __future__ import annotations

import os
from collections import Counter

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


@pytest.fixture(scope="session")
def lab_folder(tmp_path_factory: pytest.TempPathFactory):
    """The lab's 54-file folder (``write_lab_folder``'s defaults: the German dialect, the
    ``rapp2022_nr60`` drops, the lab's rig file and conditions sheet), written once per process
    for the tests that only read it (tests/test_lab_folder_e2e.py, tests/test_extract_lab.py)."""
    from labfolder import write_lab_folder

    return write_lab_folder(tmp_path_factory.mktemp("lab54") / "lab")


@pytest.hookimpl(trylast=True)  # after pytest's own ordering by fixture scope, which this keeps
def pytest_collection_modifyitems(config, items) -> None:
    """Tests that store figures are marked ``regression`` (what ``tests/regenerate.py`` selects);
    under xdist the files with the most ``slow`` tests run first (:func:`heavy_files_first`)."""
    for item in items:
        if "regression" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.regression)
    # only xdist's workers collect to run in parallel: one process gains nothing from the order,
    # and ``pytest --collect-only`` keeps the files' own order (benchmarks/suite_schedule.py reads it)
    if "PYTEST_XDIST_WORKER" in os.environ and not (config.getoption("failedfirst", False)
                                                    or config.getoption("newfirst", False)):
        slow = {item.nodeid for item in items if item.get_closest_marker("slow")}
        position = {node: k for k, node in enumerate(heavy_files_first([item.nodeid for item in items], slow))}
        items.sort(key=lambda item: position[item.nodeid])


def heavy_files_first(node_ids: list[str], slow: set[str]) -> list[str]:
    """``node_ids`` with their test files by their number of ``slow`` tests, most first, each
    file's tests together and in their own order (module fixtures are set up once per worker).

    Under ``--dist worksteal`` (pyproject's addopts) a worker that runs out of tests takes the
    second half of the other's queue, from its end: the long tests start first and the short ones
    fill the tail, so no worker waits at the end on a long test that started late
    (CONTRIBUTING.md#test-suite-timeline).
    """
    count = Counter(node.split("::")[0] for node in node_ids if node in slow)
    return sorted(node_ids, key=lambda node: -count[node.split("::")[0]])  # stable: their order among equals
