"""One exception family for everything fgslice refuses.

Every error a user can cause is an :class:`FgsliceError` (or a subclass). It carries
what went wrong, where (file, line, column where known) and how to fix it (``hint``).
The command line prints :meth:`FgsliceError.format` and exits non-zero; it never shows
a traceback for these.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable
from pathlib import Path


class FgsliceError(Exception):
    """Base class of every error fgslice reports to a user.

    Attributes:
        message: what is wrong, one sentence.
        file: the file at fault, if any.
        line: 1-based line in ``file``, if known.
        column: 1-based column in ``file``, if known.
        hint: how to fix it, if there is something useful to say.
        source_line: the text of the offending line, shown with a caret under ``column``.
    """

    exit_code = 2

    def __init__(
        self,
        message: str,
        *,
        file: str | Path | None = None,
        line: int | None = None,
        column: int | None = None,
        hint: str | None = None,
        source_line: str | None = None,
    ) -> None:
        super().__init__(message)
        self.message = message
        self.file = str(file) if file is not None else None
        self.line = line
        self.column = column
        self.hint = hint
        self.source_line = source_line

    @property
    def location(self) -> str:
        """``file:line:column`` with whatever parts are known, or an empty string."""
        parts = [p for p in (self.file, self.line, self.column) if p is not None]
        return ":".join(str(p) for p in parts)

    def format(self) -> str:
        """The message as the command line prints it (one to four short lines)."""
        where = self.location
        text = f"{where}: error: {self.message}" if where else f"error: {self.message}"
        if self.source_line is not None and self.column is not None:
            text += f"\n    {self.source_line.rstrip()}\n    {' ' * (self.column - 1)}^"
        if self.hint:
            text += f"\n  hint: {self.hint}"
        return text

    def __str__(self) -> str:
        return self.format()


class DesignSyntaxError(FgsliceError):
    """A design file or expression does not follow the language's grammar."""


class DesignError(FgsliceError):
    """A design is well formed but means something invalid (unknown name, bad arity...)."""


class FieldError(DesignError):
    """A field evaluated to NaN or infinity, or a callable returned a wrong shape."""


class MeshError(FgsliceError):
    """A mesh file is missing, unreadable or unusable."""


class SettingsError(FgsliceError):
    """A profile or setting is unknown, malformed or out of range."""


class SliceError(FgsliceError):
    """The design and settings cannot be turned into a print (too big, no layers...)."""


class ResourceError(SliceError):
    """A job would need an absurd amount of layers, samples, paths or memory."""


class GcodeError(FgsliceError):
    """A G-code file cannot be read, or fails verification."""


class OutputError(FgsliceError):
    """An output file cannot be written."""


def did_you_mean(name: str, candidates: Iterable[str]) -> str | None:
    """A ``did you mean 'x'?`` hint for a misspelt ``name``, or None if nothing is close."""
    matches = difflib.get_close_matches(name.lower(), [c.lower() for c in candidates], n=1, cutoff=0.6)
    if not matches:
        return None
    lookup = {c.lower(): c for c in candidates}
    return f"did you mean '{lookup[matches[0]]}'?"
