"""executor.Consumer: a function over a stream of messages in a forked process."""

import gc
import os

import pytest

from fgslice.errors import SliceError
from fgslice.executor import Consumer, map_ordered


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
    assert not consumer._process.is_alive()


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
    marker = [object() for _ in range(1000)]  # objects the parent holds at the fork
    with Consumer(frozen_objects) as consumer:
        assert consumer.result() >= len(marker)
    results = list(map_ordered(frozen_in_worker, None, range(4), jobs=2))
    assert all(count >= len(marker) for count, _ in results)
    assert all(pid != os.getpid() for _, pid in results)
    assert gc.get_freeze_count() == 0  # the parent's own collections are unchanged
