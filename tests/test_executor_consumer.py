"""executor.Consumer: a function over a stream of messages in a forked process."""

import gc
import os

import numpy as np
import pytest

from fgslice import executor
from fgslice.errors import SliceError
from fgslice.executor import Consumer, _ResultSlots, map_ordered


def total_and_pid(messages, scale):
    return sum(m * scale for m in messages), os.getpid()


def fail_on_three(messages):
    for m in messages:
        if m == 3:
            raise SliceError("three is not allowed")
    return "never"


def test_consumer_sums_its_messages_in_another_process():
    with Consumer(total_and_pid, 2) as consumer:
        for k in range(1000):
            consumer.send(k)
        total, pid = consumer.result()
    assert total == 2 * sum(range(1000)) and pid != os.getpid()


def test_consumer_error_reaches_the_caller_even_if_it_stops_reading():
    consumer = Consumer(fail_on_three)
    with pytest.raises(SliceError, match="three"):
        for k in range(20000):  # far more than a pipe buffers once the consumer stopped
            consumer.send(k)
        consumer.result()
    consumer._process.join(10)  # it exits by itself once its error is sent
    assert consumer._process.exitcode == 0
    consumer.close()


def test_closing_a_consumer_ends_its_process():
    consumer = Consumer(total_and_pid, 1)
    consumer.send(1)
    consumer.close()
    assert not consumer._process.is_alive()
    consumer.close()


def test_a_killed_consumer_is_reported_when_next_sent_to():
    import signal
    import time

    consumer = Consumer(total_and_pid, 1)
    consumer.send(1)
    os.kill(consumer._process.pid, signal.SIGKILL)
    time.sleep(0.2)
    with pytest.raises(SliceError, match="worker process died"):
        for k in range(20000):
            consumer.send(k)


def frozen_objects(messages):
    return gc.get_freeze_count()


def frozen_in_worker(state, item):
    return gc.get_freeze_count(), os.getpid()


def test_forked_processes_leave_the_parents_objects_out_of_their_collections():
    marker = [[] for _ in range(1000)]  # containers (tracked by the collector) the parent holds at the fork
    with Consumer(frozen_objects) as consumer:
        assert consumer.result() >= len(marker)
    results = list(map_ordered(frozen_in_worker, None, range(4), jobs=2))
    assert all(count >= len(marker) for count, _ in results)
    assert all(pid != os.getpid() for _, pid in results)
    assert gc.get_freeze_count() == 0  # the parent's own collections are unchanged


def square_and_pid(state, item):
    return item * item + state, os.getpid()


@pytest.mark.parametrize("count", [2, 10, 1000])
def test_pool_results_come_in_order_however_the_items_are_grouped_into_tasks(count):
    results = list(map_ordered(square_and_pid, 7, range(count), jobs=2))
    assert [value for value, _ in results] == [i * i + 7 for i in range(count)]
    assert os.getpid() not in {pid for _, pid in results}


@pytest.mark.parametrize("scheduler", [None, "tcp://127.0.0.1:1"])
def test_a_probed_map_of_cheap_items_runs_them_all_here(scheduler):
    """The first item, timed, says the others take far less than a pool costs: no
    worker is started, no scheduler contacted (the address above answers nothing)."""
    results = list(map_ordered(square_and_pid, 1, range(40), jobs=2, scheduler=scheduler, probe=True))
    assert results == [(i * i + 1, os.getpid()) for i in range(40)]


def slow_square_and_pid(state, item):
    import time

    time.sleep(0.05)
    return square_and_pid(state, item)


def test_a_probed_map_of_costly_items_gives_all_but_the_first_to_the_workers():
    """10 items of 50 ms: 0.45 s for the rest in one process, over SERIAL_WORK_S."""
    results = list(map_ordered(slow_square_and_pid, 1, range(10), jobs=2, probe=True))
    assert [value for value, _ in results] == [i * i + 1 for i in range(10)]
    assert results[0][1] == os.getpid() and os.getpid() not in {pid for _, pid in results[1:]}


def test_a_probed_map_with_one_job_yields_each_item_once_here():
    results = list(map_ordered(square_and_pid, 0, range(5), jobs=1, probe=True))
    assert results == [(i * i, os.getpid()) for i in range(5)]


def test_items_go_to_the_pool_in_consecutive_runs_enough_to_balance_the_workers_and_single_at_the_end():
    from fgslice.executor import TASKS_PER_WORKER, _runs

    for count, jobs in [(10, 2), (240, 2), (500, 2), (500, 8), (3, 4), (100_000, 2)]:
        runs = _runs(list(range(count)), jobs, window=64)
        assert [i for run in runs for i in run] == list(range(count))
        assert len(runs) >= min(count, jobs * TASKS_PER_WORKER)
        assert 2 * jobs * len(runs[0]) <= 64 or len(runs[0]) == 1  # two runs per worker in the window
        size, last = len(runs[0]), min(count, jobs * len(runs[0]))
        assert [len(run) for run in runs[len(runs) - last :]] == [1] * last  # the workers end together
        assert len({len(run) for run in runs[: len(runs) - last - 1]}) <= 1 and max(map(len, runs)) == size


def test_a_result_slot_holds_what_fits_and_hands_back_what_does_not():
    slots = _ResultSlots(2, 4096)
    small = [np.arange(10.0).reshape(5, 2).T, "G1 X1 Y2\n" * 100]  # a Fortran-ordered array, a text
    slot = slots.free.pop()
    stored = slots.put(slot, small)
    assert stored[0] == slot and stored[2] is None and 0 < stored[1] <= 4096
    back = slots.take(stored)
    assert slot in slots.free
    big = [np.arange(1000.0)]
    stored = slots.put(slots.free.pop(), big)
    assert stored[1:] == (0, big)  # too large for the slot: handed back as it is
    assert slots.take(stored) is big and sorted(slots.free) == [0, 1]
    slots.close()  # what was taken out no longer refers to the shared memory
    assert np.array_equal(back[0], small[0]) and back[1] == small[1] and back[0].flags.writeable


def filled(state, item):
    return np.full(item, float(item))


def test_pool_results_are_whole_whether_they_fit_a_result_slot_or_not(monkeypatch):
    monkeypatch.setattr(executor, "RESULT_SLOTS_BYTES", 64 * (64 << 10))  # 64 runs in flight: 64 KiB slots
    sizes = [10, 20_000, 5, 30_000, 1, 7_000] * 20  # 160 and 240 KB arrays overflow a slot
    results = list(map_ordered(filled, None, sizes, jobs=2))
    assert [len(r) for r in results] == sizes
    assert all((r == n).all() for r, n in zip(results, sizes))  # read after the pool and its slots are gone


def test_a_pool_map_left_early_closes_its_shared_memory_cleanly(monkeypatch):
    import multiprocessing

    closed = []
    close = _ResultSlots.close
    monkeypatch.setattr(_ResultSlots, "close", lambda self: (close(self), closed.append(self.memory.closed)))
    results = map_ordered(square_and_pid, 0, range(1000), jobs=2)
    assert [next(results)[0] for _ in range(3)] == [0, 1, 4]
    results.close()  # no view of the slots is left open, or closing their memory would raise
    assert closed == [True] and multiprocessing.active_children() == []


def _note_sigterm_then_sleep(marker):
    """What a process forked inside fgslice's fork guard does until it sets its own
    handlers: a SIGTERM is only noted (here, in a file), and the process goes on."""
    import signal
    import time

    signal.signal(signal.SIGTERM, lambda signum, frame: marker.write_text("noted"))
    time.sleep(20)


def sleep_noting_sigterm(messages, marker):
    _note_sigterm_then_sleep(marker)
    return "slept"


def test_closing_a_consumer_stops_it_even_if_it_only_notes_sigterm(tmp_path):
    import signal

    marker = tmp_path / "sigterm"
    consumer = Consumer(sleep_noting_sigterm, marker)
    consumer.send(1)
    consumer.close()
    assert consumer._process.exitcode == -signal.SIGKILL and not marker.exists()


def sleep_noting_sigterm_after_the_first(marker, item):
    if item:
        _note_sigterm_then_sleep(marker)
    return item


def test_a_pool_map_left_early_stops_workers_that_only_note_sigterm(tmp_path):
    import multiprocessing

    marker = tmp_path / "sigterm"
    results = map_ordered(sleep_noting_sigterm_after_the_first, marker, range(4), jobs=2, window=2)
    assert next(results) == 0
    results.close()
    assert multiprocessing.active_children() == [] and not marker.exists()


def large_result_or_error(state, item):
    if item == 3:
        raise SliceError("layer 3 failed " + "x" * 20000)  # a message larger than a pipe takes at once
    return b"x" * 3_000_000


def test_a_pool_map_stopped_by_an_error_ends_though_a_worker_dies_mid_result(capfd):
    """A worker killed while writing a large result leaves the pool's reader mid-message:
    the map must still end, with the error, and print nothing else."""
    import multiprocessing
    import threading

    for _ in range(5):
        outcome = []

        def run():
            try:
                for _ in map_ordered(large_result_or_error, None, range(40), jobs=2):
                    pass
            except SliceError as error:
                outcome.append(error)

        thread = threading.Thread(target=run, daemon=True)
        thread.start()
        thread.join(60)
        assert not thread.is_alive(), "the map never ended"
        assert outcome and "layer 3 failed" in str(outcome[0])
        assert multiprocessing.active_children() == []
    assert "Exception in thread" not in capfd.readouterr().err
