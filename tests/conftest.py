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


@pytest.fixture(scope="module")
def shared_map_fits():
    """One characteristic-map fit per distinct input for the module that asks for it
    (``pytestmark = pytest.mark.usefixtures("shared_map_fits")``; tests/shared_map_fits.py): its
    commands and library calls that fit the same tests (Table 4's, one table in several formats,
    one campaign) fit them once per process."""
    from shared_map_fits import share_map_fits

    with share_map_fits() as cache:
        yield cache


@pytest.fixture(scope="session")
def lab_folder_and_drops(tmp_path_factory: pytest.TempPathFactory):
    """The lab's 54-file folder (``write_lab_folder``'s defaults: the German dialect, the
    ``rapp2022_nr60`` drops, the lab's rig file and conditions sheet; records of 0.12 s after the
    impact, as test_lab_downstream.py's folders: four periods and more of the slowest fixture),
    written once per process, and the simulated drops it was written from (``DropResult``s in the
    order of its logs)."""
    import importlib

    from labfolder import write_lab_folder

    simulation = importlib.import_module("droptower.rig.simulate")  # the module (the package's name is the function)
    drops: list = []

    def simulate_and_keep(*args, **kwargs):
        results = simulate(*args, **kwargs)
        drops.extend(results)
        return results

    simulate = simulation.simulate
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(simulation, "simulate", simulate_and_keep)
        lab = write_lab_folder(tmp_path_factory.mktemp("lab54") / "lab", duration_s=0.12)
    assert len(drops) == len(lab.logs)
    return lab, drops


@pytest.fixture(scope="session")
def lab_folder(lab_folder_and_drops):
    """The lab's 54-file folder, for the tests that only read it (tests/test_lab_folder_e2e.py,
    tests/test_extract_lab.py, tests/test_lab_downstream.py)."""
    return lab_folder_and_drops[0]


@pytest.fixture(scope="session")
def lab_work(tmp_path_factory: pytest.TempPathFactory):
    """Where the commands run on the lab's folder write (the session fixtures below)."""
    return tmp_path_factory.mktemp("lab54_work")


@pytest.fixture(scope="session")
def lab_extracted(lab_folder, lab_work):
    """``extract`` of the whole folder with the lab's rig file and sheet: the command's
    :class:`labfolder.Step` and its ``--out`` table (results.csv)."""
    from labfolder import droptower

    out = lab_work / "results.csv"
    return droptower("extract", *lab_folder.logs, "--conditions", lab_folder.sheet, "--rig", lab_folder.rig,
                     "--out", out), out


@pytest.fixture(scope="session")
def lab_extracted_preset(lab_folder, lab_work):
    """The same ``extract`` with the shipped preset rig ``rapp2022`` instead of the lab's rig file
    (results_preset.csv)."""
    from labfolder import droptower

    out = lab_work / "results_preset.csv"
    return droptower("extract", *lab_folder.logs, "--conditions", lab_folder.sheet, "--rig", "rapp2022",
                     "--out", out), out


@pytest.fixture(scope="session")
def lab_model_mapped(lab_folder, lab_work):
    """The model route on the folder: ``map FOLDER --family template --template rapp2022_nr60``
    with the lab's rig and sheet, the paper's map (map_folder.json) and the model-based map
    (model_map.json) beside it; the command's :class:`labfolder.Step`. The paper's map of these
    tests is fitted once per process (tests/shared_map_fits.py)."""
    from labfolder import droptower
    from shared_map_fits import share_map_fits

    with share_map_fits():  # its paper map is the extracted table's (test_lab_folder_e2e.py maps and reports it)
        return droptower("map", lab_folder.folder, "--conditions", lab_folder.sheet, "--rig", lab_folder.rig,
                         "--out", lab_work / "map_folder.json", "--family", "template", "--template",
                         "rapp2022_nr60", "--model-out", lab_work / "model_map.json")


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
        groups = {item.nodeid.split("::")[0]: "lab folder" for item in items
                  if LAB_FOLDER_STEPS & set(getattr(item, "fixturenames", ()))}
        position = {node: k for k, node in enumerate(heavy_files_first([item.nodeid for item in items], slow, groups))}
        items.sort(key=lambda item: position[item.nodeid])


#: the session fixtures on the lab's 54-file folder: the files that read them run next to each
#: other (:func:`heavy_files_first`'s groups), so one worker builds them for all
LAB_FOLDER_STEPS = {"lab_folder", "lab_folder_and_drops", "lab_extracted", "lab_extracted_preset", "lab_model_mapped"}


def heavy_files_first(node_ids: list[str], slow: set[str], groups: dict[str, str] | None = None) -> list[str]:
    """``node_ids`` with their test files by their number of ``slow`` tests, most first, each
    file's tests together and in their own order (module fixtures are set up once per worker).
    The files of one of ``groups`` (test file -> group name: files that read the same session
    fixtures) go together, at the place of their summed ``slow`` tests, the heaviest file first.

    Under ``--dist worksteal`` (pyproject's addopts) a worker that runs out of tests takes the
    second half of the other's queue, from its end: the long tests start first and the short ones
    fill the tail, so no worker waits at the end on a long test that started late
    (CONTRIBUTING.md#test-suite-timeline).
    """
    def file(node: str) -> str:
        return node.split("::")[0]

    count = Counter(file(node) for node in node_ids if node in slow)
    group = {file(node): (groups or {}).get(file(node), file(node)) for node in node_ids}
    group_count: Counter = Counter()
    for name, in_group in group.items():
        group_count[in_group] += count[name]
    first: dict[str, int] = {}  # a group's place among equals: its first file's in node_ids
    for node in node_ids:
        first.setdefault(group[file(node)], len(first))
    return sorted(node_ids, key=lambda node: (-group_count[group[file(node)]], first[group[file(node)]],
                                              -count[file(node)]))  # stable: their order among equals
