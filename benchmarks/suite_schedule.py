"""How xdist's schedulers would spread the suite over its workers, from measured test times.

    python benchmarks/suite_schedule.py DURATIONS COLLECTED SLOW [--workers 2] [--draws 60]

DURATIONS is the output of ``pytest -n 2 -q --durations=0`` (setup, call and teardown of each
test are added up), COLLECTED of ``pytest --collect-only -q`` (the collection order), SLOW of
``pytest --collect-only -q -m slow``. xdist's own scheduler classes (``load``, ``worksteal``) are
driven by simulated workers that run each test for its measured time (a worker holds the next
test before it runs one, as xdist's do; a steal is answered between two tests), on the
collection order and on the order of ``tests/conftest.py`` (files with the most slow tests
first). Printed: each worker's time in tests and when the last one ends, against the balanced
time (sum / workers, the baseline); then the same over random draws of every test's time
(x lognormal, sigma 0.3: a loaded machine).
"""
from __future__ import annotations

import argparse
import heapq
import random
import re
import statistics
import sys
from collections import Counter, deque
from pathlib import Path
from types import SimpleNamespace

from xdist.scheduler.load import LoadScheduling
from xdist.scheduler.worksteal import WorkStealingScheduling

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from conftest import heavy_files_first  # noqa: E402  (the suite's own order, not a copy)

_SHUTDOWN = object()


class _Worker:
    """A simulated xdist worker: the queue it was sent, the test it holds next, the one it runs."""

    def __init__(self, name: str, sim: Simulation) -> None:
        self.name, self.sim = name, sim
        self.gateway = SimpleNamespace(id=name)
        self.queue: deque = deque()
        self.shutting_down = False
        self.holding = self.running = None
        self.done = False
        self.busy_s = self.last_end_s = 0.0

    def send_runtest_some(self, indices) -> None:
        self.queue.extend(indices)

    def shutdown(self) -> None:
        if not self.shutting_down:
            self.shutting_down = True
            self.queue.append(_SHUTDOWN)

    def send_steal(self, indices) -> None:
        self.sim.steals.append((self, list(indices)))

    def answer_steal(self, indices: list[int]) -> None:
        wanted = set(indices)
        stolen = indices if wanted <= set(self.queue) else []  # all or nothing, as xdist's worker
        if stolen:
            self.queue = deque(i for i in self.queue if i not in wanted)
        self.sim.scheduler.remove_pending_tests_from_node(self, stolen)


class Simulation:
    """One run of ``kind`` ("load" or "worksteal") over ``order`` (node ids) with ``seconds`` per id."""

    def __init__(self, kind: str, order: list[str], seconds: dict[str, float], workers: int = 2) -> None:
        config = SimpleNamespace(getvalue=lambda name: ["popen"] * workers, getoption=lambda name: None)
        quiet = SimpleNamespace(loadsched=lambda *args: None, workstealsched=lambda *args: None)
        self.scheduler = (LoadScheduling if kind == "load" else WorkStealingScheduling)(config, log=quiet)
        self.order, self.seconds, self.steals, self.now = order, seconds, [], 0.0
        self.workers = [_Worker(f"gw{i}", self) for i in range(workers)]
        for w in self.workers:
            self.scheduler.add_node(w)
        for w in self.workers:
            self.scheduler.add_node_collection(w, order)

    def _advance(self, events: list) -> None:
        while self.steals:
            victim, indices = self.steals.pop(0)
            victim.answer_steal(indices)
        for w in self.workers:
            if w.running is not None or w.done:
                continue
            if w.holding is None and w.queue:
                w.holding = w.queue.popleft()
            if w.holding is _SHUTDOWN:
                w.done = True
            elif w.holding is not None and w.queue:  # an xdist worker runs a test once it holds the next
                w.running, w.holding = w.holding, w.queue.popleft()
                seconds = self.seconds.get(self.order[w.running], 0.0)
                heapq.heappush(events, (self.now + seconds, w.name, w, w.running, seconds))

    def run(self) -> dict[str, tuple[float, float]]:
        """Per worker: (time in tests, end of its last test), s."""
        events: list = []
        self.scheduler.schedule()
        self._advance(events)
        while events:
            self.now, _, w, index, seconds = heapq.heappop(events)
            w.running, w.busy_s, w.last_end_s = None, w.busy_s + seconds, self.now
            self.scheduler.mark_test_complete(w, index, seconds)
            self._advance(events)
        assert all(w.done for w in self.workers) and not self.scheduler.has_pending
        return {w.name: (w.busy_s, w.last_end_s) for w in self.workers}


def read_durations(path: Path) -> dict[str, float]:
    seconds: Counter = Counter()
    for line in path.read_text().splitlines():
        m = re.match(r"([0-9.]+)s (call|setup|teardown)\s+(\S+)", line)
        if m:
            seconds[m[3]] += float(m[1])
    return dict(seconds)


def node_ids(path: Path) -> list[str]:
    return [line.strip() for line in path.read_text().splitlines() if "::" in line]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("durations", type=Path)
    parser.add_argument("collected", type=Path)
    parser.add_argument("slow", type=Path)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--draws", type=int, default=60)
    args = parser.parse_args()
    seconds, order, slow = read_durations(args.durations), node_ids(args.collected), set(node_ids(args.slow))
    cases = [("load", "collection order", order), ("worksteal", "collection order", order),
             ("worksteal", "slow files first", heavy_files_first(order, slow))]
    balanced = sum(seconds.get(t, 0.0) for t in order) / args.workers
    print(f"{len(order)} tests, {len(slow)} slow; balanced test time {balanced:.1f} s")
    for kind, name, case in cases:
        per_worker = Simulation(kind, case, seconds, args.workers).run()
        end = max(last for _, last in per_worker.values())
        print(f"{kind:9s} {name:16s}: last test ends at {end:6.1f} s, {end / balanced:.2f} x balanced; "
              + ", ".join(f"{w} {busy:.0f} s in tests" for w, (busy, _) in per_worker.items()))
    for kind, name, case in cases:
        over = []
        for draw in range(args.draws):
            rng = random.Random(draw)
            drawn = {t: s * rng.lognormvariate(0.0, 0.3) for t, s in seconds.items()}
            end = max(last for _, last in Simulation(kind, case, drawn, args.workers).run().values())
            over.append(end - sum(drawn.get(t, 0.0) for t in order) / args.workers)
        over.sort()
        print(f"{kind:9s} {name:16s}: over balanced, {args.draws} draws: mean {statistics.mean(over):5.1f} s, "
              f"90 % {over[int(0.9 * len(over))]:5.1f} s, max {over[-1]:5.1f} s")


if __name__ == "__main__":
    main()
