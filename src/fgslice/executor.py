"""Run a per-layer function over many layers: serially, in a local process pool, or on Dask.

Every executor yields results in input order, so output built from them is identical
whatever the executor and the number of workers. Workers receive the shared job state
once (fork inheritance locally, a scattered object on Dask), then only runs of
consecutive layer indices (:func:`_runs`), one task per run. A local worker leaves each
run's results in shared memory (:class:`_ResultSlots`) rather than in the pool's pipe.
"""

from __future__ import annotations

import contextlib
import ctypes
import gc
import itertools
import mmap
import multiprocessing
import os
import pickle
import signal
import sys
import time
import traceback
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from multiprocessing.reduction import ForkingPickler
from typing import Any

from fgslice.errors import SliceError
from fgslice.heap import retain_freed_memory
from fgslice.interrupts import default_termination, sigint_held

_STATE: Any = None
_SLOTS: "_ResultSlots | None" = None
_PR_SET_PDEATHSIG = 1


def _init_worker(state: Any, parent: int, slots: "_ResultSlots | None") -> None:
    """Keep the job state and the result slots; leave Ctrl-C to the parent, which stops
    the pool and cleans up, and end with the parent however it ends (no orphaned worker
    keeps computing)."""
    global _STATE, _SLOTS
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    default_termination()
    _die_with_parent(parent)
    retain_freed_memory()
    _STATE, _SLOTS = state, slots


def _die_with_parent(parent: int) -> None:
    """Ask Linux to SIGKILL this process when its parent (pid ``parent``) exits
    (``PR_SET_PDEATHSIG``); exit now if it already has."""
    if not sys.platform.startswith("linux"):
        return
    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    if os.getppid() != parent:
        os._exit(1)


class Consumer:
    """``fn(messages, *args)`` running in a forked process alongside this one.

    ``messages`` is an iterator over what :meth:`send` is given, ending when
    :meth:`result` is called; :meth:`result` returns what ``fn`` returned (or raises what
    it raised). The process ignores Ctrl-C and dies with its parent, like the pool's
    workers; :meth:`close` ends it early. Use as a context manager to always close it.
    """

    def __init__(self, fn: Callable[..., Any], *args: Any) -> None:
        context = multiprocessing.get_context("fork")
        self._conn, child = context.Pipe()
        self._outcome: tuple[str, Any] | None = None
        self._process = context.Process(target=_consume, args=(fn, child, os.getpid(), args), daemon=True)
        with _forking():
            self._process.start()
        child.close()

    def send(self, message: Any) -> None:
        """Hand ``message`` to the consumer's iterator.

        Raises:
            Exception: what the consumer raised, if it stopped on an error.
            SliceError: the consumer's process died.
        """
        if self._outcome is not None:
            return
        try:
            self._conn.send(message)
        except OSError:  # the consumer stopped: its outcome is waiting, or it died
            self._receive()

    def result(self) -> Any:
        """End the messages and return the consumer's result. The process, which exits
        once it has sent its result, is waited for by :meth:`close`.

        Raises:
            Exception: what the consumer raised.
            SliceError: the consumer's process died.
        """
        self.send(_END)
        return self._receive()

    def _receive(self) -> Any:
        if self._outcome is None:
            try:
                self._outcome = self._conn.recv()
            except (EOFError, OSError):
                self.close()
                self._outcome = ("error", SliceError(
                    "a worker process died while slicing (killed, or out of memory); no output was written",
                    hint="retry with --jobs 1 to slice in one process"))
        kind, value = self._outcome
        if kind == "error":
            raise value
        return value

    def close(self) -> None:
        """Stop the process if it still runs (idempotent). It is killed (SIGKILL), not
        asked to stop: a process forked a moment before still has the parent's handler
        that only notes SIGTERM (:func:`_forking`), and would never end."""
        if self._conn.closed:
            return
        if self._process.is_alive():
            self._process.kill()
        self._process.join()
        self._conn.close()

    def __enter__(self) -> "Consumer":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


_END = "__end__"


def _consume(fn: Callable[..., Any], conn: Any, parent: int, args: tuple) -> None:
    """The consumer process: run ``fn`` over the messages, send back its outcome."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    default_termination()
    _die_with_parent(parent)
    retain_freed_memory()

    def messages() -> Iterator[Any]:
        while (message := conn.recv()) != _END:
            yield message

    try:
        outcome = ("ok", fn(messages(), *args))
    except Exception as exc:  # handed to the parent, which raises it with this process's frames
        outcome = ("error", _WithTraceback(exc))
    try:
        conn.send(outcome)
    except Exception:  # an exception that does not pickle
        failed = outcome[1].exc
        conn.send(("error", SliceError(f"{type(failed).__name__}: {failed}")))
    conn.close()


class RemoteTraceback(Exception):
    """The traceback of an exception raised in another process, as text: the cause of
    that exception once it is raised here, so that a printed traceback shows both
    processes' frames (what :class:`concurrent.futures.ProcessPoolExecutor` does for its
    workers)."""

    def __str__(self) -> str:
        return self.args[0]


class _WithTraceback:
    """An exception and its traceback as text, pickled together; unpickled, the
    exception with :class:`RemoteTraceback` as its cause."""

    def __init__(self, exc: Exception) -> None:
        self.exc = exc
        self.text = "".join(traceback.format_exception(exc))

    def __reduce__(self) -> tuple:
        return _rebuild, (self.exc, self.text)


def _rebuild(exc: Exception, text: str) -> Exception:
    """``exc`` with its remote traceback ``text`` as its cause."""
    exc.__cause__ = RemoteTraceback(f'\n"""\n{text}"""')
    return exc


def _run(fn: Callable[[Any, Any], Any], state: Any, run: list) -> list:
    """``fn(state, item)`` for each item of a run (on a Dask worker, or via :func:`_call`)."""
    return [fn(state, item) for item in run]


def _call(fn: Callable[[Any, Any], Any], run: list) -> list:
    """A pool task: :func:`_run` with the state the worker was started with."""
    return _run(fn, _STATE, run)


def _call_into_slot(fn: Callable[[Any, Any], Any], run: list, slot: int) -> tuple:
    """A pool task: :func:`_call`, its results left in result slot ``slot``
    (:meth:`_ResultSlots.put`)."""
    return _SLOTS.put(slot, _call(fn, run))


RESULT_SLOTS_BYTES = 64 << 20
"""Shared memory for the result slots of one map, bytes, split evenly between its runs in
flight: a run whose pickled results are larger than its slot comes back through the
pool's pipe. Runs pickle to at most 0.9 MB on the Benchy (21 slots of 3 MiB) and 1.7 MB on
the vase (9 slots of 7 MiB)."""


class _SlotFull(Exception):
    """A run's pickled results do not fit in its slot."""


class _SlotWriter:
    """A file-like object that :class:`pickle.Pickler` writes into one result slot."""

    def __init__(self, view: memoryview) -> None:
        self.view = view
        self.end = 0

    def write(self, data: bytes | pickle.PickleBuffer) -> int:
        """Append ``data``: the pickler's frames (bytes) and, in protocol 5, the buffers
        of arrays (:class:`pickle.PickleBuffer`, copied as their raw bytes)."""
        raw = data.raw() if isinstance(data, pickle.PickleBuffer) else data
        end = self.end + len(raw)
        if end > len(self.view):
            raise _SlotFull
        self.view[self.end : end] = raw
        self.end = end
        return len(raw)


class _ResultSlots:
    """Shared memory in which pool workers leave the pickled results of their runs.

    Through the pool's pipe, a run's results travel 64 KB at a time: each piece is copied
    into the kernel and out again, and wakes up the reader, which gathers the pieces in
    a buffer and copies them once more before unpickling. Here the worker pickles them
    straight into a slot of an anonymous shared mapping that the workers inherit at the
    fork, and sends only the slot's number and the pickle's size; the parent unpickles
    from the slot and frees it. There is one slot per run in flight (the parent hands a
    free one with each task); results larger than a slot go through the pipe instead
    (:data:`RESULT_SLOTS_BYTES`).

    The vase's 500 layers come back in 72 runs, 116 MB in all: moving them costs two
    workers and their parent 0.26-0.34 s of CPU through the pipe and 0.13-0.16 s through
    slots (``benchmarks/bench_executor.py``). A slot's pages are faulted in once, by the
    worker and by the parent, and then reused; a map whose runs are all in flight at once
    would only write fresh pages, so it does without slots (the palette's 10 layers, 12
    alternating pairs of each row: 1-4 % slower with them).

    Attributes:
        size: bytes per slot.
        free: the parent's free slots.
    """

    def __init__(self, count: int, size: int) -> None:
        self.size = size
        self.memory = mmap.mmap(-1, count * size)
        self.free = list(range(count))

    def put(self, slot: int, results: list) -> tuple[int, int, list | None]:
        """Worker side: pickle ``results`` into ``slot``; ``(slot, size, None)``, or
        ``(slot, 0, results)`` when they do not fit (they then travel as the task's result)."""
        with memoryview(self.memory) as memory, memory[slot * self.size : (slot + 1) * self.size] as view:
            writer = _SlotWriter(view)
            try:
                ForkingPickler(writer, 5).dump(results)
            except _SlotFull:
                return slot, 0, results
        return slot, writer.end, None

    def take(self, stored: tuple[int, int, list | None]) -> list:
        """Parent side: the results :meth:`put` returned ``stored`` for, and their slot freed."""
        slot, size, results = stored
        if results is None:
            start = slot * self.size
            with memoryview(self.memory) as memory, memory[start : start + size] as view:
                results = ForkingPickler.loads(view)
        self.free.append(slot)
        return results

    def close(self) -> None:
        self.memory.close()


#: A pool is handed the items in runs of consecutive ones, about this many runs per
#: worker: each task costs the parent about 0.3 ms (futures, queues, threads), so a
#: 240-layer run in 64 tasks instead of 240 saves it ~0.05 s of CPU (the last few items
#: still go one per run, :func:`_runs`).
TASKS_PER_WORKER = 32


def _runs(items: list, jobs: int, window: int) -> list[list]:
    """``items`` cut into consecutive runs, :data:`TASKS_PER_WORKER` per worker or more,
    and short enough for two runs per worker to fit in ``window`` items. The last
    ``jobs`` runs' worth of items go one per run: the workers finish within an item of
    each other, and the last results arrive one by one, so that what the writer and the
    verifier still have to do once the workers are done is one item's share."""
    size = max(1, min(len(items) // (jobs * TASKS_PER_WORKER), window // (2 * jobs)))
    head = len(items) - min(len(items), jobs * size)
    return [items[i : min(i + size, head)] for i in range(0, head, size)] + [[item] for item in items[head:]]


SERIAL_WORK_S = 0.2
"""A map probed first (``map_ordered(probe=True)``) whose other items would take less
than this in one process runs them there: a local pool costs about 0.1 s before its first
result (forking, each worker's first touch of the inherited memory), and two workers
halve the rest. The vase's 32 batches of outlines, ``--jobs 2``: 0.145 s through a pool,
0.09 s here; from the slice's start to its first layer task, 0.15 -> 0.13 s (medians of
8 alternating runs)."""


def default_jobs() -> int:
    """All cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:
        return max(1, os.cpu_count() or 1)


def map_ordered(
    fn: Callable[[Any, Any], Any],
    state: Any,
    items: Iterable[Any],
    *,
    jobs: int = 1,
    scheduler: str | None = None,
    window: int = 64,
    probe: bool = False,
) -> Iterator[Any]:
    """Yield ``fn(state, item)`` for each item, in order.

    Args:
        fn: a module-level function (picklable by reference).
        state: shared, read-only job state handed to every call.
        items: the work items (layer indices, usually).
        jobs: local worker processes; 1 runs in this process.
        scheduler: address of a Dask scheduler (``tcp://host:port``); overrides ``jobs``.
        window: at most this many results are in flight or waiting, bounding memory.
        probe: run the first item in this process, timed, and the others too when they
            would take less than :data:`SERIAL_WORK_S` at its pace (for maps of items
            that may be too cheap to be worth the workers).

    Raises:
        SliceError: a worker process died (killed, out of memory) or the scheduler
            cannot be reached.
    """
    items = list(items)
    if probe and items and (scheduler or jobs > 1):
        started = time.perf_counter()
        first = fn(state, items[0])
        items = items[1:]
        if (time.perf_counter() - started) * len(items) < SERIAL_WORK_S:
            scheduler, jobs = None, 1
        yield first
    if scheduler:
        yield from _map_dask(fn, state, items, scheduler, window)
    elif jobs <= 1 or len(items) <= 1:
        for item in items:
            yield fn(state, item)
    else:
        yield from _map_pool(fn, state, items, jobs, window)


@contextlib.contextmanager
def _forking() -> Iterator[None]:
    """Around the calls that fork worker or consumer processes: Ctrl-C held back
    (:func:`~fgslice.interrupts.sigint_held`: one handled during a fork would be swallowed
    by the interpreter's fork callbacks; processes forked meanwhile inherit the handler
    that only notes it, until they ignore SIGINT, :func:`_init_worker`) and the heap
    frozen (:func:`_heap_frozen`)."""
    with sigint_held(), _heap_frozen():
        yield


@contextlib.contextmanager
def _heap_frozen() -> Iterator[None]:
    """Hide this process's objects from the garbage collector of the processes forked meanwhile.

    A forked child shares the parent's memory pages until it writes to them, and each
    full collection in the child would walk (and write to the headers of) every object
    inherited from the parent, copying the pages they lie on. Frozen before the fork
    (``gc.freeze``), the parent's objects are left out of the child's collections; the
    parent unfreezes them right after, so its own collections are unchanged. Palette,
    strategy 1, 16 colors, ``--jobs 2``: 124-126 k page faults -> 120-122 k, and 1.45 ->
    1.33 s wall in six alternating runs each (a noisy figure on a shared machine).
    """
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


def _runs_in_flight(runs: list[list], window: int) -> int:
    """How many of ``runs`` are in flight at once: ``window`` items in whole runs, two at least."""
    return min(len(runs), max(2, window // len(runs[0])))


def _in_order(submit: Callable[[list], Any], receive: Callable[[Any], list], runs: list[list], window: int,
              pending: deque, opening: contextlib.AbstractContextManager) -> Iterator[Any]:
    """Each run's results in order: ``submit(run)`` gives a future of the run, ``receive``
    its list of results; at most ``window`` items (:func:`_runs_in_flight`) are in flight.
    The first submissions are made inside ``opening``; ``pending`` holds the futures in
    flight, for the caller to cancel."""
    iterator = iter(runs)
    with opening:
        pending.extend(submit(run) for run in itertools.islice(iterator, _runs_in_flight(runs, window)))
    while pending:
        results = receive(pending.popleft())
        pending.extend(submit(run) for run in itertools.islice(iterator, 1))
        yield from results


def _map_pool(fn, state, items, jobs, window) -> Iterator[Any]:
    runs = _runs(items, jobs, window)
    in_flight = _runs_in_flight(runs, window)
    slots = _ResultSlots(in_flight, RESULT_SLOTS_BYTES // in_flight) if len(runs) > in_flight else None
    context = multiprocessing.get_context("fork")
    pool = ProcessPoolExecutor(max_workers=jobs, mp_context=context, initializer=_init_worker,
                               initargs=(state, os.getpid(), slots))
    if slots:
        submit, receive = (lambda run: pool.submit(_call_into_slot, fn, run, slots.free.pop()),
                           lambda future: slots.take(future.result()))
    else:
        submit, receive = (lambda run: pool.submit(_call, fn, run)), (lambda future: future.result())
    pending: deque = deque()
    finished = False
    try:  # the first submission forks the workers
        yield from _in_order(submit, receive, runs, window, pending, _forking())
        finished = True
    except BrokenProcessPool:
        raise SliceError(
            "a worker process died while slicing (killed, or out of memory); no output was written",
            hint="retry with --jobs 1 to slice in one process",
        ) from None
    finally:
        if not finished:  # stopped early (an error, Ctrl-C, SIGTERM): the runs in flight are not awaited
            for process in list((getattr(pool, "_processes", None) or {}).values()):
                process.kill()  # not SIGTERM, which a worker just forked only notes (Consumer.close)
            _release_result_reader(pool)  # before cancelling: the ending thread fails the futures it holds
        for future in pending:
            future.cancel()
        pool.shutdown(wait=True, cancel_futures=True)
        if slots:
            slots.close()


RELEASE_SECONDS = 10.0
"""Longest a stopped pool's reader thread is fed to let it end (then it is left behind)."""


def _release_result_reader(pool: ProcessPoolExecutor) -> None:
    """Let the pool's reader thread end after its workers were killed.

    A worker killed while it was writing a result (an exception's traceback, a result
    larger than the pipe takes at once) leaves the reader thread waiting for the rest of
    the message; the pool's own end of the pipe stays open, so no end of file ever comes,
    and ``shutdown`` would wait for that thread forever. Zeros written into the pipe
    complete the message, which then does not unpickle: the thread marks the pool broken
    and ends, as it does when it sees the killed workers first.
    """
    thread = getattr(pool, "_executor_manager_thread", None)
    queue = getattr(pool, "_result_queue", None)
    if thread is None or queue is None:
        return
    thread.join(0.2)
    if not thread.is_alive():
        return
    fd = queue._writer.fileno()
    os.set_blocking(fd, False)
    zeros = bytes(1 << 16)
    deadline = time.monotonic() + RELEASE_SECONDS
    while thread.is_alive() and time.monotonic() < deadline:
        with contextlib.suppress(BlockingIOError):
            os.write(fd, zeros)
        thread.join(0.01)


def _map_dask(fn, state, items, scheduler, window) -> Iterator[Any]:
    try:
        from distributed import Client
    except ImportError:
        raise SliceError(
            "--scheduler needs dask.distributed, which is not installed",
            hint="pip install 'fgslice[dask]'",
        ) from None
    try:
        client = Client(scheduler, timeout="10s", set_as_default=False)
    except (OSError, TimeoutError) as exc:
        raise SliceError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
    pending: deque = deque()
    try:
        state_future = client.scatter(state, broadcast=True)
        workers = max(1, sum(client.nthreads().values()))
        runs = _runs(items, workers, window)
        yield from _in_order(lambda run: client.submit(_run, fn, state_future, run, pure=False),
                             lambda future: future.result(), runs, window, pending, contextlib.nullcontext())
    finally:
        for future in pending:
            future.cancel()
        client.close()
