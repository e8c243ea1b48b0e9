"""How fgslice's processes hand memory back to the system (glibc's allocator).

Set in fgslice's own processes only: the ``fgslice`` command (:func:`fgslice.cli.run`)
and the pool workers and consumer processes it forks (:mod:`fgslice.executor`). A program
that calls the library keeps its own allocator settings; its forked workers still get
these.
"""

from __future__ import annotations

import ctypes
import sys

_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3

HEAP_TRIM_BYTES = 64 << 20
"""Free memory at the top of the heap that a process keeps for its next allocations, bytes."""

HEAP_MMAP_BYTES = 32 << 20
"""Allocations from this size on get pages of their own (smaller ones come from the heap), bytes."""


def retain_freed_memory() -> bool:
    """Have this process's allocator (glibc) keep the memory it frees for reuse.

    By default glibc gives freed memory back to the system as soon as about 128 KB are
    free at the top of the heap, and serves arrays from about that size up with pages of
    their own. Each layer allocates and frees tens of MB of arrays and geometries, so the
    same memory would be handed back and faulted in again, zeroed by the kernel, layer
    after layer. With up to :data:`HEAP_TRIM_BYTES` kept and allocations below
    :data:`HEAP_MMAP_BYTES` served from the heap, freed memory is reused instead; the
    peak memory of a process (its high-water mark) does not grow.

    Returns:
        True when set; False where the C library is not glibc (nothing changes).
    """
    if not sys.platform.startswith("linux"):
        return False
    libc = ctypes.CDLL(None)
    if not hasattr(libc, "gnu_get_libc_version"):
        return False
    return bool(libc.mallopt(_M_TRIM_THRESHOLD, HEAP_TRIM_BYTES)) and bool(libc.mallopt(_M_MMAP_THRESHOLD, HEAP_MMAP_BYTES))
