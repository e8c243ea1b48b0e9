"""Long runs of simple statements read without the general parser.

A design listing a hundred thousand ``translate(x, y, z) { cube(s); }`` lines (a grid of
parts written by a script) would cost the LALR parser and the node builder about 0.3 ms
per line. A run of at least :data:`MIN_RUN` such statements one after another, each a
``translate`` of three numbers holding one ``cube``, ``sphere``, ``rectprism`` (three
numbers) or ``cylinder`` with an optional material, is found here with one regular
expression, its numbers read into arrays, and its text replaced by a placeholder node
of the same length (the same line breaks, so that every position the parser reports
after it is unchanged). The builder turns a placeholder inside a ``union`` or ``root``
into :class:`~fgslice.design.copies.Copies` (one per stretch of one kind and material)
and anywhere else, or when a number is out of range, into the same nodes, checks and
errors as the parser's path (:meth:`StatementRun.arguments`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

MIN_RUN = 64
"""Fewest consecutive statements read as a run."""

PLACEHOLDER = "fgslice_statement_run"
"""Name of the placeholder node ``PLACEHOLDER(k)`` standing for run ``k`` (the fast path
is off for a text that contains this name)."""

_NUMBER = r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"
_STATEMENT = (
    rf"(?<![A-Za-z_0-9])(?i:translate)\s*\(\s*({_NUMBER})\s*,\s*({_NUMBER})\s*,\s*({_NUMBER})\s*\)\s*\{{\s*"
    rf"((?i:cube|sphere|rectprism|cylinder))\s*\(\s*({_NUMBER})(?:\s*,\s*({_NUMBER}))?(?:\s*,\s*({_NUMBER}))?"
    r'(?:\s*,\s*"([^"]*)")?\s*\)\s*;?\s*\}'
)
_SCAN = re.compile(r'"[^"]*"|//[^\n]*|/\*.*?\*/|' + _STATEMENT, re.DOTALL)
_SIZES = {"cube": 1, "sphere": 1, "cylinder": 2, "rectprism": 3}


@dataclass
class StatementRun:
    """Consecutive simple statements: ``offsets`` ``(n, 3)`` of the translations, the
    primitive ``names`` (lower case), their ``sizes`` ``(n, 3)`` (NaN past each
    primitive's arguments) and ``materials`` (None where not given), and the regular
    expression ``matches`` (their positions, for errors and :meth:`arguments`)."""

    offsets: np.ndarray
    names: list[str]
    sizes: np.ndarray
    materials: list[str | None]
    matches: list[re.Match]

    @property
    def count(self) -> int:
        return len(self.names)

    def arguments(self, i: int):
        """Statement ``i`` as the parser's path would see it: the translation's numbers
        and the primitive's arguments, each ``(kind, text, offset)`` with ``kind``
        ``number`` or ``string`` and ``offset`` the position of its first character."""
        m = self.matches[i]
        numbers = [("number", m.group(g), m.start(g)) for g in (1, 2, 3)]
        given = [("number", m.group(g), m.start(g)) for g in (5, 6, 7) if m.group(g) is not None]
        if m.group(8) is not None:
            given.append(("string", m.group(8), m.start(8)))
        return numbers, (m.group(4), m.start(4)), given


def find_runs(text: str) -> tuple[str, list[StatementRun]]:
    """``text`` with every run of at least :data:`MIN_RUN` simple statements inside a
    block replaced by a placeholder of the same length and line breaks, and the runs."""
    if PLACEHOLDER in text.lower():
        return text, []
    groups: list[list[re.Match]] = []
    current: list[re.Match] = []
    last_end = -1
    for m in _SCAN.finditer(text):
        name, _, second, third = m.group(4, 5, 6, 7)
        if name is None or _SIZES[name.lower()] != 1 + (second is not None) + (third is not None):
            current, last_end = _close(current, groups), -1
            continue
        start = m.start()
        if current and start != last_end and not text[last_end:start].isspace():
            current = _close(current, groups)
        current.append(m)
        last_end = m.end()
    _close(current, groups)
    if not groups:
        return text, []
    pieces, runs, at, depth = [], [], 0, 0
    for matches in groups:
        start, end = matches[0].start(), matches[-1].end()
        depth += _braces(text, at, start)  # a run's own braces balance
        if depth < 1:
            continue
        replacement = _placeholder(len(runs), text[start:end])
        if replacement is None:
            continue
        pieces += [text[at:start], replacement]
        runs.append(_read(matches))
        at = end
    pieces.append(text[at:])
    return "".join(pieces), runs


def _close(current: list, groups: list) -> list:
    if len(current) >= MIN_RUN:
        groups.append(current)
    return []


_BLOCKS = re.compile(r'"[^"]*"|//[^\n]*|/\*.*?\*/|([{}])', re.DOTALL)


def _braces(text: str, start: int, end: int) -> int:
    """Braces opened less braces closed from ``start`` to ``end`` (outside strings and
    comments; both positions outside them)."""
    depth = 0
    for m in _BLOCKS.finditer(text, start, end):
        if m.group(1):
            depth += 1 if m.group(1) == "{" else -1
    return depth


def _placeholder(k: int, run: str) -> str | None:
    """``PLACEHOLDER(k)`` padded to ``run``'s length with its line breaks kept."""
    node = f"{PLACEHOLDER}({k})"
    lines = [len(line) for line in run.split("\n")]
    if len(lines) == 1:
        return node + " " * (lines[0] - len(node))
    if sum(lines[:-1]) < len(node):
        return None
    spare, blank = len(node), []
    for length in lines[:-1]:
        cut = min(spare, length)
        spare -= cut
        blank.append(" " * (length - cut))
    return node + "\n".join(blank + [" " * lines[-1]])


def _read(matches: list[re.Match]) -> StatementRun:
    rows = [m.groups() for m in matches]
    columns = list(zip(*rows))
    offsets = np.array([columns[0], columns[1], columns[2]], dtype=float).T
    sizes = np.array([[v if v is not None else "nan" for v in columns[i]] for i in (4, 5, 6)], dtype=float).T
    return StatementRun(offsets, [n.lower() for n in columns[3]], sizes, list(columns[7]), matches)
