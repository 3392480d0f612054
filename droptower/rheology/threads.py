"""A batch kernel's rows spread over threads: the serial build run on contiguous chunks of rows.

The batch kernels (:func:`droptower.rheology.kernels.run_history`, the lever's free decay in
:mod:`droptower.rig.lever_decay`) compute every row of a batch independently and release the GIL
(``nogil``), so chunks of rows on as many threads compute what one call computes, row by row
with the same code: the results are bit-identical. This replaces numba parallel builds
(``parallel=True``, ``prange``), each a second compilation of a large kernel (8-10 s of CPU on
a cold cache).

The number of threads is numba's (:func:`numba.get_num_threads`: ``NUMBA_NUM_THREADS``, or what
:func:`numba.set_num_threads` set for the calling thread; a campaign's worker processes set 1 and
stay on their own thread). The pool is made on first use in each process: a pool made before a
fork has no threads in the child.
"""
from __future__ import annotations

import os
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor

#: Batches at least this large are spread over the threads. (Smaller ones, and single steps, are
#: not: too little work to pay for handing chunks to other threads.)
PARALLEL_BATCH = 8

_pool: ThreadPoolExecutor | None = None
_pool_pid: int | None = None
_pool_lock = threading.Lock()


def thread_count() -> int:
    """The threads a batch may use: numba's setting for the calling thread, read without launching
    numba's threading layer where nothing launched it (then nothing set it either)."""
    import numba
    from numba.core import config
    from numba.np.ufunc import parallel

    if getattr(parallel, "_is_initialized", True):  # a numba without the flag: ask (launches its layer)
        return int(numba.get_num_threads())
    return int(config.NUMBA_NUM_THREADS)


def _executor() -> ThreadPoolExecutor:
    global _pool, _pool_pid
    with _pool_lock:
        if _pool is None or _pool_pid != os.getpid():
            from numba.core import config

            _pool = ThreadPoolExecutor(max_workers=max(int(config.NUMBA_NUM_THREADS) - 1, 1),
                                       thread_name_prefix="droptower-rows")
            _pool_pid = os.getpid()
        return _pool


def chunk_bounds(batch: int, chunks: int) -> list[tuple[int, int]]:
    """``chunks`` contiguous ranges [lo, hi) covering ``range(batch)``, sizes differing by one at most."""
    size, extra = divmod(batch, chunks)
    bounds, lo = [], 0
    for c in range(chunks):
        hi = lo + size + (c < extra)
        bounds.append((lo, hi))
        lo = hi
    return bounds


def run_rows(kernel: Callable[..., object], args: Sequence[object], rows: Sequence[int], batch: int,
             threads: int | None = None) -> None:
    """Call ``kernel(*args)`` on contiguous chunks of a batch's rows, one chunk per thread.

    Parameters
    ----------
    kernel : callable
        A compiled kernel that computes each row of its batch independently and writes its results
        into its arguments (it returns nothing), built with ``nogil=True``.
    args : sequence
        The kernel's arguments.
    rows : sequence of int
        Positions in ``args`` of the arrays whose leading axis is the batch's rows (C-contiguous:
        a chunk ``a[lo:hi]`` is a view of the same type, so no other build is compiled). One of
        another leading size (parameters shared by every row, ``params.shape[0] == 1``; an empty
        record ``(0, 0)``) is passed whole to every chunk.
    batch : int
        The number of rows.
    threads : int, optional
        At most this many threads (:func:`thread_count` by default); batches smaller than
        :data:`PARALLEL_BATCH` and one thread run in the calling thread, in one call.

    An exception raised in any chunk is raised here once every chunk has finished.
    """
    n = min(thread_count() if threads is None else int(threads), batch)
    if batch < PARALLEL_BATCH or n <= 1:
        kernel(*args)
        return
    per_row = set(rows)

    def chunk(lo: int, hi: int) -> list[object]:
        return [a[lo:hi] if i in per_row and a.shape[0] == batch else a for i, a in enumerate(args)]

    bounds = chunk_bounds(batch, n)
    pool = _executor()
    futures: list[Future] = [pool.submit(kernel, *chunk(lo, hi)) for lo, hi in bounds[1:]]
    error: BaseException | None = None
    try:
        kernel(*chunk(*bounds[0]))  # the calling thread takes the first chunk
    except BaseException as exc:  # the others still write into the arrays: wait for them first
        error = exc
    for future in futures:
        exc = future.exception()
        if error is None and exc is not None:
            error = exc
    if error is not None:
        raise error
