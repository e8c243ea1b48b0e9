"""heap.retain_freed_memory: fgslice's processes reuse the memory they free instead of
faulting it in again, allocation after allocation."""

import subprocess
import sys

import pytest

from fgslice.executor import Consumer, map_ordered

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's allocator only")

CHURN = """
import resource
import numpy as np

def churn(n, rounds):
    for _ in range(rounds):
        a = np.ones(n); b = np.ones(n // 2); del a; c = np.ones(n // 3); del b, c

def churn_faults(n=3 << 17, rounds=20):
    # page faults of allocating and freeing 3 MB arrays, after one round that touches
    # (and, in a forked process, copies) the pages they will take
    churn(n, 1)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    churn(n, rounds)
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before
"""
namespace: dict = {}
exec(CHURN, namespace)
churn_faults = namespace["churn_faults"]


def faults_in_consumer(messages):
    return churn_faults()


def faults_in_worker(state, item):
    return churn_faults()


def plain_process_faults(retain: bool) -> int:
    """Page faults of the churn in a fresh interpreter, with or without retention."""
    setup = "from fgslice.heap import retain_freed_memory; assert retain_freed_memory()\n" if retain else ""
    code = setup + CHURN + "print(churn_faults())"
    return int(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout)


def test_a_plain_process_faults_its_freed_arrays_in_again_and_a_retaining_one_does_not():
    without, with_ = plain_process_faults(False), plain_process_faults(True)
    assert without > 200  # 3 MB arrays: glibc hands them back to the system on every free
    assert with_ < without / 10


def test_consumers_and_pool_workers_reuse_freed_memory():
    with Consumer(faults_in_consumer) as consumer:
        assert consumer.result() < 20
    assert max(map_ordered(faults_in_worker, None, range(4), jobs=2)) < 20
