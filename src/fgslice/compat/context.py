"""The state of one script run: the script, the roots it rendered, where a call was made.

:func:`fgslice.compat.script.load_script` opens a :class:`Run` for the duration of the
script; the compatibility modules read it through :func:`current` (the script's folder
for relative mesh paths, the list :func:`~fgslice.compat.pyvcad_rendering.Render` appends
to) and locate their errors with :func:`site`.
"""

from __future__ import annotations

import contextlib
import linecache
import sys
from contextvars import ContextVar
from dataclasses import dataclass, field
from pathlib import Path

from fgslice.design.nodes import NOWHERE, Where
from fgslice.errors import FgsliceError

_PACKAGE_DIR = str(Path(__file__).resolve().parent)


@dataclass
class Run:
    """One run of a design script: its path and the roots passed to Render / Export;
    ``projects``: by ``id`` of a compiled root, the last slicer project compiling it
    (:mod:`fgslice.compat.slicer_project`; None for other compilers)."""

    path: Path
    rendered: list = field(default_factory=list)
    exported: list = field(default_factory=list)
    projects: dict = field(default_factory=dict)


_current: ContextVar[Run | None] = ContextVar("fgslice_pyvcad_run", default=None)


def current() -> Run | None:
    """The run in progress, or None when the compatibility modules are used directly."""
    return _current.get()


@contextlib.contextmanager
def running(path: Path):
    """Make a :class:`Run` of ``path`` current for the ``with`` block and yield it."""
    token = _current.set(Run(path))
    try:
        yield _current.get()
    finally:
        _current.reset(token)


def where_of_line(file: str, line: int) -> Where:
    """A :class:`Where` at ``line`` of ``file``, its text read through linecache."""
    text = linecache.getline(file, line).rstrip("\n")
    column = len(text) - len(text.lstrip()) + 1 if text.strip() else None
    return Where(file, line, column, text if column else None)


def site() -> Where:
    """Where the caller's caller outside this package is: the line of the script making a call."""
    frame = sys._getframe(1)
    while frame is not None and str(Path(frame.f_code.co_filename).resolve().parent) == _PACKAGE_DIR:
        frame = frame.f_back
    return NOWHERE if frame is None else where_of_line(frame.f_code.co_filename, frame.f_lineno)


def locate(error: FgsliceError, where: Where) -> FgsliceError:
    """``error`` placed at ``where`` unless it already names a file; returns ``error``."""
    if error.file is None and where.file is not None:
        error.file, error.line = where.file, where.line
        if error.source_line is None:
            error.column, error.source_line = where.column, where.source_line
    return error
