"""Writing output files so that a failure never leaves a truncated or clobbered file.

Output goes to a temporary file in the destination folder and is renamed over the
destination only once it is complete; on any error or interruption the temporary file is
removed and the previous destination (if any) is untouched.
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from fgslice.errors import OutputError
from fgslice.interrupts import sigint_held


def check_writable(path: str | Path, *, inputs: tuple[str | Path, ...] = ()) -> Path:
    """Refuse early an output path that cannot be written or that names an input.

    Returns ``path`` as a :class:`~pathlib.Path`; ``inputs`` entries may be None (skipped).

    Raises:
        OutputError: the folder is missing or not writable, the path is a folder or
            another file that is not regular (a device, a FIFO), or it is one of
            ``inputs`` (fgslice never overwrites its input).
    """
    target = Path(path)
    resolved = target.resolve()
    for source in inputs:
        if source is not None and Path(source).resolve() == resolved:
            raise OutputError(
                f"output '{target}' is the input file; refusing to overwrite it",
                hint="choose another output name with -o",
            )
    if target.is_dir():
        raise OutputError(f"output '{target}' is a folder", hint="give a file name, e.g. -o part.gcode")
    _refuse_special(target)
    folder = resolved.parent
    if not folder.is_dir():
        raise OutputError(f"cannot write '{target}': folder '{folder}' does not exist", hint="create it first")
    if not os.access(folder, os.W_OK) or (target.exists() and not os.access(target, os.W_OK)):
        raise OutputError(f"cannot write '{target}': permission denied")
    return target


@contextlib.contextmanager
def atomic_output(path: str | Path, mode: str = "w") -> Iterator[IO]:
    """Open a temporary file beside ``path``; rename it to ``path`` when the block succeeds.

    ``mode`` is ``"w"`` (UTF-8 text, ``\\n`` line ends) or ``"wb"``; the file ends up
    with permissions 0644.

    The handle's ``name`` is the temporary file's path, so the block can re-read what it
    wrote (to verify it) before the rename.

    Any exception (including KeyboardInterrupt) removes the temporary file and re-raises;
    ``OSError`` while writing (a full disk, say) becomes :class:`OutputError`. A Ctrl-C
    is held back while the temporary file is made, so none leaves it behind unnamed. A
    caller entering this in a :class:`contextlib.ExitStack` holds it back over
    ``enter_context`` too (:func:`~fgslice.interrupts.sigint_held`), or a Ctrl-C between
    the file's creation and the registration of its cleanup would leave it.
    """
    target = Path(path)
    tmp: Path | None = None
    text = "b" not in mode
    try:
        with sigint_held():  # no Ctrl-C between making the file and naming it for removal
            fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part", dir=target.resolve().parent)
            tmp = Path(tmp_name)
        os.close(fd)
        with open(tmp, mode, encoding="utf-8" if text else None, newline="\n" if text else None) as handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(tmp, 0o644)
        _refuse_special(target)  # made since the output was checked
        os.replace(tmp, target)
    except OSError as exc:
        _discard(tmp)
        raise _output_error(target, exc) from None
    except BaseException:
        _discard(tmp)
        raise


def _refuse_special(target: Path) -> None:
    """Refuse an existing output that is not a regular file (a device, a FIFO, a socket):
    replacing it by renaming a file over it would destroy it (``/dev/null`` as root), and
    writing into it would not be atomic."""
    try:
        mode = target.stat().st_mode
    except OSError:  # a new path (or a dangling symlink): a file is made there
        return
    if not stat.S_ISREG(mode):
        kind = ("a character device" if stat.S_ISCHR(mode) else "a block device" if stat.S_ISBLK(mode)
                else "a FIFO (named pipe)" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode)
                else "not a regular file")
        raise OutputError(
            f"output '{target}' is {kind}: fgslice only writes regular files (replaced whole when complete)",
            hint="give a file name; '-o -' writes the G-code to standard output",
        )


def _discard(tmp: Path | None) -> None:
    """Remove the temporary file, even if a second Ctrl-C arrives meanwhile."""
    if tmp is None:
        return
    try:
        tmp.unlink(missing_ok=True)
    except KeyboardInterrupt:
        tmp.unlink(missing_ok=True)
        raise


def _output_error(target: Path, exc: OSError) -> OutputError:
    """The :class:`OutputError` for an ``OSError`` raised while writing ``target``."""
    kept = " (the previous file is unchanged)" if target.exists() else ""
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return OutputError(
            f"the disk is full: could not write '{target}' ({exc.strerror or exc}); nothing was written{kept}",
            hint=f"free space on the disk holding '{target.resolve().parent}', or write elsewhere with -o",
        )
    return OutputError(f"could not write '{target}': {exc.strerror or exc}; nothing was written{kept}")
