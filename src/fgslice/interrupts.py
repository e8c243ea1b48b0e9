"""Holding back Ctrl-C (SIGINT) over steps that must not be cut in two.

Python runs a signal handler between any two bytecodes, so a Ctrl-C can land between
creating something and recording that it must be cleaned up (a temporary file made but
not yet named for removal, a context entered but its exit not yet registered), or inside
the interpreter's fork callbacks, which swallow the KeyboardInterrupt. Held back over
such a step, the Ctrl-C is delivered right after it, as a KeyboardInterrupt that the
caller's cleanup sees.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator


@contextlib.contextmanager
def sigint_held() -> Iterator[None]:
    """Hold back SIGINT (and SIGTERM, SIGHUP while :func:`raise_on_termination` is in
    force) over the block and deliver it right after, if one came.

    The Python-level handler is swapped for one that only notes the signal, rather than
    the main thread's signal mask changed: the kernel hands a process's SIGINT to any
    thread that does not block it (numpy's BLAS threads, say), and Python then runs its
    handler in the main thread all the same. A noted SIGINT is raised again once the
    previous handler is back, so it acts as it would have (KeyboardInterrupt by default).
    Only the main thread can set handlers: in any other thread the block runs as it is.
    Processes forked inside the block inherit the noting handler until they set their
    own (fgslice's workers ignore SIGINT).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    noted: list[int] = []
    # SIGTERM and SIGHUP too while they raise (:func:`raise_on_termination`)
    held = [signal.SIGINT] + [s for s in TERMINATING if getattr(signal.getsignal(s), "raises", False)]
    previous = {s: signal.signal(s, lambda signum, frame: noted.append(signum)) for s in held}
    try:
        yield
    finally:
        for s, action in previous.items():
            signal.signal(s, action)
        for s in dict.fromkeys(noted):
            signal.raise_signal(s)


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP (``timeout``, a closed terminal, a service manager), raised in
    the main thread like a Ctrl-C, so that the same cleanup runs (no temporary file left,
    workers stopped). ``signum`` is the signal's number."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


TERMINATING = (signal.SIGTERM, signal.SIGHUP)
"""The signals :func:`raise_on_termination` turns into :class:`Terminated`."""


@contextlib.contextmanager
def raise_on_termination() -> Iterator[None]:
    """Over the block, SIGTERM and SIGHUP raise :class:`Terminated` in the main thread (in
    any other thread the block runs as it is); the previous handlers are put back after.
    Processes forked meanwhile put the default action back (:func:`default_termination`)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        raise Terminated(signum)

    handler.raises = True  # held back by sigint_held like a Ctrl-C
    previous = {signum: signal.signal(signum, handler) for signum in TERMINATING}
    try:
        yield
    finally:
        for signum, action in previous.items():
            signal.signal(signum, action)


def default_termination() -> None:
    """SIGTERM and SIGHUP end this process at once again (in forked workers)."""
    for signum in TERMINATING:
        signal.signal(signum, signal.SIG_DFL)
