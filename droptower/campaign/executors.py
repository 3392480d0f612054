"""Where the chunks run: in this process, on local cores, or on a Dask distributed cluster.

Every executor has ``run(fn, tasks)``, yielding ``(task, outcome or exception)`` as chunks
finish (in any order), and is a context manager. Local cores use
:class:`concurrent.futures.ProcessPoolExecutor` (one numba thread per worker: the workers
share the cores); one worker runs in this process. A Dask cluster is an optional extra
(``pip install droptower[distributed]``), imported only when asked for; its scheduler is
probed first, so an address that does not answer is a one-line error after ``timeout_s``.

Pools and clusters get the chunks in a bounded window (:data:`WINDOW_PER_WORKER` per worker):
a new chunk is submitted as one finishes, so a campaign of 45 000 tests holds a few dozen
tasks and outcomes in memory at any time, not 600 of each, and the scheduler's queue stays
short. A Dask worker that dies takes its running chunks with it; the scheduler gives them to
another worker (a chunk is idempotent: it rewrites only files that are the same bit for bit).
"""
from __future__ import annotations

import asyncio
import itertools
import os
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from typing import Any

from droptower.errors import DroptowerError

#: Seconds to wait for a Dask scheduler to answer.
SCHEDULER_TIMEOUT_S = 10.0
#: Chunks submitted ahead per worker: enough to keep every worker busy while the next is sent.
WINDOW_PER_WORKER = 4

Result = tuple[Any, Any]  # (task, outcome or the exception it raised)


def local_cores() -> int:
    """Cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


class InProcess:
    """Chunks one after another in this process (``workers=1``)."""

    description = "1 worker (this process)"

    def __enter__(self) -> "InProcess":
        return self

    def __exit__(self, *exc: Any) -> None:
        pass

    def start(self) -> None:
        """Nothing to start (see :meth:`LocalPool.start`)."""

    def run(self, fn: Callable[[Any], Any], tasks: Iterable[Any]) -> Iterator[Result]:
        for task in tasks:
            try:
                yield task, fn(task)
            except Exception as exc:  # reported by the runner; the other chunks go on
                yield task, exc


def _one_thread() -> None:
    import numba

    numba.set_num_threads(1)


class LocalPool:
    """Chunks on ``workers`` local processes."""

    def __init__(self, workers: int):
        self.workers = workers
        self.description = f"{workers} local worker processes"
        self.pool = ProcessPoolExecutor(max_workers=workers, initializer=_one_thread)

    def __enter__(self) -> "LocalPool":
        return self

    def __exit__(self, exc_type: Any, *exc: Any) -> None:
        # on Ctrl-C or an error, drop the chunks not started yet; running ones finish their files
        self.pool.shutdown(wait=True, cancel_futures=exc_type is not None)

    def start(self) -> None:
        """Start the worker processes now, before this process runs threads of its own: a pool
        forks all its workers at its first task, and a fork while another thread holds a lock
        (BLAS, logging) leaves the child waiting for it forever."""
        self.pool.submit(int).result()

    def run(self, fn: Callable[[Any], Any], tasks: Iterable[Any]) -> Iterator[Result]:
        pending = iter(tasks)
        futures: dict[Any, Any] = {}
        while True:
            for task in itertools.islice(pending, WINDOW_PER_WORKER * self.workers - len(futures)):
                futures[self.pool.submit(fn, task)] = task
            if not futures:
                return
            done, _ = wait(futures, return_when=FIRST_COMPLETED)
            for future in done:
                task = futures.pop(future)
                exc = future.exception()
                yield task, exc if exc is not None else future.result()


async def _identity(address: str, timeout_s: float) -> dict[str, Any]:
    from distributed.comm import connect

    comm = await connect(address, timeout=timeout_s)
    try:
        await comm.write({"op": "identity"})
        return await comm.read()
    finally:
        await comm.close()


class DaskCluster:
    """Chunks on the workers of the Dask distributed scheduler at ``address``."""

    def __init__(self, address: str, timeout_s: float = SCHEDULER_TIMEOUT_S):
        try:
            from distributed import Client
        except ImportError:
            raise DroptowerError("needs the optional Dask extra: pip install 'droptower[distributed]'",
                                 where="scheduler") from None
        try:
            reply = asyncio.run(asyncio.wait_for(_identity(address, timeout_s), timeout_s + 1.0))
        except Exception as exc:  # refused, timed out, malformed address, or not speaking Dask's protocol
            reason = "no answer" if isinstance(exc, (OSError, asyncio.TimeoutError)) else type(exc).__name__
            raise DroptowerError(f"the Dask scheduler at {address} does not answer within {timeout_s:g} s "
                                 f"({reason}: {' '.join(str(exc).split())[:120]})", where="scheduler") from None
        if not (isinstance(reply, dict) and reply.get("type") == "Scheduler"):
            raise DroptowerError(f"{address} answers, but is not a Dask scheduler", where="scheduler")
        self.client = Client(address, timeout=timeout_s, set_as_default=False)
        self.description = f"Dask scheduler {address} ({reply.get('n_workers', '?')} workers)"

    def __enter__(self) -> "DaskCluster":
        return self

    def __exit__(self, exc_type: Any, *exc: Any) -> None:
        pass  # the runner closes the client (it is asked before the folder is touched)

    def close(self) -> None:
        self.client.close()

    def run(self, fn: Callable[[Any], Any], tasks: Iterable[Any]) -> Iterator[Result]:
        from distributed import as_completed as dask_completed

        pending = iter(tasks)
        workers = max(1, len(self.client.scheduler_info(n_workers=-1).get("workers", {})))
        futures = {self.client.submit(fn, task, pure=False): task
                   for task in itertools.islice(pending, WINDOW_PER_WORKER * workers)}
        try:
            with self.client.as_current():  # not the process's default client: say which one
                finishing = dask_completed(list(futures))
                for future in finishing:
                    task = futures.pop(future)
                    exc = future.exception()
                    outcome = exc if exc is not None else future.result()
                    future.release()
                    for more in itertools.islice(pending, 1):  # one in, one out: the window stays full
                        new = self.client.submit(fn, more, pure=False)
                        futures[new] = more
                        finishing.add(new)
                    yield task, outcome
        finally:
            self.client.cancel([f for f in futures if not f.done()])


def make_executor(workers: int | None = None, scheduler: str | None = None,
                  timeout_s: float = SCHEDULER_TIMEOUT_S) -> InProcess | LocalPool | DaskCluster:
    """The executor for ``workers`` local processes (None: every local core) or, with
    ``scheduler`` (an address such as ``tcp://host:8786``), a Dask cluster."""
    if scheduler is not None:
        if workers is not None:
            raise DroptowerError("give `workers` (local cores) or `scheduler` (a Dask cluster), not both")
        return DaskCluster(scheduler, timeout_s)
    workers = local_cores() if workers is None else workers
    if workers < 1:
        raise DroptowerError(f"must be at least 1, got {workers}", where="workers")
    return InProcess() if workers == 1 else LocalPool(workers)
