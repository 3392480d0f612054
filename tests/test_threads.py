"""Large batches on threads (droptower/rheology/threads.py): chunks of rows through the serial
kernel give the serial kernel's results bit for bit, every row once; errors reach the caller; a
forked process and a campaign worker (one numba thread) run correctly."""
from __future__ import annotations

import multiprocessing
import threading
from concurrent.futures import ProcessPoolExecutor
from unittest import mock

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from droptower.campaign.executors import _one_thread
from droptower.rheology import Coupling
from droptower.rheology import threads as T
from droptower.rig.lever_decay import SYMPLECTIC_EULER, VERLET, LeverDecay
from test_kinds import _element, _history

#: kinds whose parameter layout does not depend on the random draw (variable_maxwell's does), so
#: rows of random parameters stack
KINDS = ("spring", "maxwell", "elastoslide", "masing", "pfeffer", "payne", "filler_network", "power_law", "mullins",
         "prony", "spring_table", "cubic_spring", "dashpot")


def _rows(seed: int, batch: int, shared: bool) -> Coupling:
    """A coupling of several element kinds with random parameters: one set for every row
    (``shared``) or one per row."""
    if shared:
        return Coupling([_element(k, seed) for k in KINDS])
    return Coupling.stack([Coupling([_element(k, seed + i) for k in KINDS]) for i in range(batch)])


def _spy_pool():
    """``threads._executor`` counting its calls (the chunks went to the pool)."""
    calls = []
    real = T._executor

    def executor():
        calls.append(1)
        return real()
    return mock.patch.object(T, "_executor", executor), calls


@settings(max_examples=12, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), batch=st.integers(T.PARALLEL_BATCH, 23), threads=st.integers(2, 5),
       shared=st.booleans(), record_energy=st.booleans())
def test_histories_on_threads_equal_the_serial_kernel(seed, batch, threads, shared, record_energy):
    """Random parameter sets (shared or per row) and histories; batches not divisible by the
    thread count included: every output and the advanced state are bit-identical to one call."""
    coupling = _rows(seed, batch, shared)
    h = 2e-4
    x = np.stack([_history(seed + i, n=300, h=h) for i in range(batch)])
    start = coupling.new_state(batch)
    start.values[...] = coupling.simulate(x[:, :50], h, state=coupling.new_state(batch)).state.values
    with mock.patch.object(T, "thread_count", lambda: 1):
        serial = coupling.simulate(x, h, state=start.copy(), record_energy=record_energy)
    spy, calls = _spy_pool()
    with mock.patch.object(T, "thread_count", lambda: threads), spy:
        chunked = coupling.simulate(x, h, state=start.copy(), record_energy=record_energy)
    assert calls, "the batch did not go to the thread pool"
    for name in ("torque_nm", "stored_energy_j", "dissipated_energy_j"):
        assert np.array_equal(getattr(chunked, name), getattr(serial, name)), name
    assert np.array_equal(chunked.state.values, serial.state.values)
    assert np.array_equal(chunked.state.angle_rad, serial.state.angle_rad)


@settings(max_examples=8, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), batch=st.integers(T.PARALLEL_BATCH, 19), threads=st.integers(2, 5),
       shared=st.booleans(), scheme=st.sampled_from([SYMPLECTIC_EULER, VERLET]))
def test_lever_decays_on_threads_equal_the_serial_kernel(seed, batch, threads, shared, scheme):
    """The lever's free decay, advanced in two calls (its carried angle, rate and acceleration
    chunked too): bit-identical to the serial kernel."""
    coupling = _rows(seed, batch, shared)
    rng = np.random.default_rng(seed)
    inertia, rate0 = rng.uniform(0.1, 0.5, batch), rng.uniform(-3.0, 3.0, batch)

    def decay():
        lever = LeverDecay(coupling, coupling.new_state(batch), inertia, rate0, 2e-4, scheme)
        return [*lever.advance(150), *lever.advance(77), lever.phi, lever.rate, lever.acc, lever.state.values]
    with mock.patch.object(T, "thread_count", lambda: 1):
        serial = decay()
    spy, calls = _spy_pool()
    with mock.patch.object(T, "thread_count", lambda: threads), spy:
        chunked = decay()
    assert calls
    for a, b in zip(chunked, serial):
        assert np.array_equal(a, b)


def _recorder(log: list, fail_at: int | None = None):
    """A kernel that records (thread, rows) of each call and writes each row's index into ``out``."""
    def kernel(shared_params, rows, out, empty):
        log.append((threading.get_ident(), rows[0], rows[-1] + 1, shared_params.shape[0], empty.shape))
        if fail_at is not None and rows[0] <= fail_at <= rows[-1]:
            raise ZeroDivisionError(f"row {fail_at}")
        out[:] = rows * 2
    return kernel


@pytest.mark.parametrize("batch, threads", [(8, 2), (9, 2), (23, 5), (8, 3), (10, 16), (7, 4), (30, 1)])
def test_chunks_cover_every_row_once(batch, threads):
    """Contiguous chunks, sizes within one, each row once; shared and empty arrays passed whole;
    below PARALLEL_BATCH or on one thread: one call in the calling thread."""
    log, out = [], np.full(batch, -1)
    T.run_rows(_recorder(log), (np.zeros((1, 3)), np.arange(batch), out, np.empty((0, 0))), (0, 1, 2, 3), batch,
               threads=threads)
    assert np.array_equal(out, np.arange(batch) * 2)
    spans = sorted((lo, hi) for _, lo, hi, _, _ in log)
    expected = 1 if batch < T.PARALLEL_BATCH or threads == 1 else min(threads, batch)
    assert len(spans) == expected and spans[0][0] == 0 and spans[-1][1] == batch
    assert all(a[1] == b[0] for a, b in zip(spans, spans[1:]))
    sizes = [hi - lo for lo, hi in spans]
    assert max(sizes) - min(sizes) <= 1
    assert all(p == 1 and e == (0, 0) for *_, p, e in log)
    if expected == 1:
        assert log[0][0] == threading.get_ident()
    else:
        assert len({ident for ident, *_ in log}) > 1


@pytest.mark.parametrize("fail_at", [0, 5, 8])  # the caller's chunk, another's, the last row
def test_an_error_in_a_chunk_is_raised_once_all_chunks_are_done(fail_at):
    batch, log, out = 9, [], np.full(9, -1)
    with pytest.raises(ZeroDivisionError, match=f"row {fail_at}"):
        T.run_rows(_recorder(log, fail_at), (np.zeros((1, 3)), np.arange(batch), out, np.empty((0, 0))), (1, 2),
                   batch, threads=3)
    assert len(log) == 3  # every chunk ran (and had finished: the arrays are no longer written)
    done = [i for i in range(batch) if not any(lo <= fail_at < hi and lo <= i < hi for _, lo, hi, _, _ in log)]
    assert np.array_equal(out[done], np.array(done) * 2)


def _calls_in_child(batch: int) -> tuple[int, int, bool]:
    """In a worker process: how many chunks a large batch took, on how many threads, right or not."""
    log, out = [], np.full(batch, -1)
    T.run_rows(_recorder(log), (np.zeros((1, 3)), np.arange(batch), out, np.empty((0, 0))), (1, 2), batch)
    return len(log), len({ident for ident, *_ in log}), bool(np.array_equal(out, np.arange(batch) * 2))


def test_a_forked_process_makes_its_own_threads_and_a_campaign_worker_stays_on_one():
    """The parent's pool (used before the fork) has no threads in a forked child: the child makes
    its own. A campaign worker (numba.set_num_threads(1), executors._one_thread) runs one call."""
    T.run_rows(_recorder([]), (np.zeros((1, 3)), np.arange(16), np.zeros(16, int), np.empty((0, 0))), (1, 2), 16,
               threads=2)  # the parent's pool exists and has threads
    fork = multiprocessing.get_context("fork")
    with mock.patch.object(T, "thread_count", lambda: 2), ProcessPoolExecutor(1, mp_context=fork) as pool:
        assert pool.submit(_calls_in_child, 16).result(timeout=120) == (2, 2, True)
    with ProcessPoolExecutor(1, mp_context=fork, initializer=_one_thread) as pool:
        assert pool.submit(_calls_in_child, 16).result(timeout=120) == (1, 1, True)


ROW_LOOP = '''
import numpy as np
from numba import njit
{options}

@njit({kwargs})
def rows(x):
    out = np.empty_like(x)
    for b in range(x.shape[0]):
        out[b] = 2.0 * x[b]
    return out
'''


def test_numba_says_nothing_about_row_loops_on_its_parallel_pipeline(tmp_path, monkeypatch):
    """A row loop built with row_loop_options (parallel=True over a plain range) compiles without
    numba's "no transformation for parallel execution" warning even where every warning is shown;
    a function of another file built with parallel=True alone still gets it."""
    import importlib
    import warnings

    from numba.core.errors import NumbaPerformanceWarning

    (tmp_path / "quiet_rows.py").write_text(ROW_LOOP.format(
        options="from droptower.rheology.numba_cache import row_loop_options", kwargs="**row_loop_options(__file__)"))
    (tmp_path / "loud_rows.py").write_text(ROW_LOOP.format(options="", kwargs="parallel=True"))
    monkeypatch.syspath_prepend(str(tmp_path))
    seen = {}
    for name in ("quiet_rows", "loud_rows"):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            assert np.array_equal(importlib.import_module(name).rows(np.arange(4.0)), 2.0 * np.arange(4.0))
        seen[name] = [w for w in caught if issubclass(w.category, NumbaPerformanceWarning)]
    assert seen["quiet_rows"] == [] and len(seen["loud_rows"]) == 1
