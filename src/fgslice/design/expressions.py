"""The safe expression language of design files, compiled to vectorized numpy code.

An expression such as ``(1+sin(0.025*x+0.0375*y)*cos(0.0375*x-0.025*y))/2`` is parsed
by a LALR grammar (lark, built once at import) into a hash-consed graph (equal
subexpressions are one node; constants are folded), which is scheduled into a flat list
of numpy steps over a register file that reuse dead temporaries in place. Several
expressions combined with :func:`combine_expressions` share one graph, so what they have
in common is computed once. Nothing of the text is ever passed to ``eval``/``exec``:
only the names in :data:`FUNCTIONS`, :data:`VARIABLES` and :data:`CONSTANTS` exist.

Conventions: coordinates in mm, angles in radians; evaluation is float64 and the result
has the broadcast shape of ``x, y, z`` (and ``d`` when given). Comparisons and logic
return 1.0/0.0 and treat any nonzero value (NaN included) as true. Names and keywords
are case-insensitive. The reference is ``docs/expressions.md``.

Errors point into the file holding the expression: ``compile_expression`` takes the
line and column where the text starts, and every :class:`~fgslice.errors.DesignSyntaxError`
or :class:`~fgslice.errors.DesignError` carries the file line/column of the offending
token and a ``source_line``: the file's own line when ``compile_expression`` is given the
file's lines (``file_lines``), else the expression's line, indented on its first line so
the caret lines up with the file column.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import lark
import numpy as np

from fgslice.design.lark_cache import cached_lark
from fgslice.errors import DesignError, DesignSyntaxError, FgsliceError, FieldError, did_you_mean

__all__ = [
    "CONSTANTS",
    "FUNCTIONS",
    "MAX_DEPTH",
    "MAX_LENGTH",
    "VARIABLES",
    "Expression",
    "ExpressionGroup",
    "Function",
    "combine_expressions",
    "compile_expression",
]

MAX_LENGTH = 100_000
"""Longest expression text accepted, in characters."""

MAX_DEPTH = 200
"""Deepest nesting accepted, of parentheses and of operations."""

# Operator precedence, loosest first: ?: / or / and / not / comparisons (non-chaining) /
# + - / * / % / unary sign / implicit multiplication / ^ (right-associative; its exponent
# may carry a sign). The right operand of an implicit multiplication never starts with a
# number or a sign, so "x 2" and "1.2.3" are errors and "a -b" is a subtraction. A name
# directly followed by "(" is a call (CALLNAME), whitespace allowed in between.
_GRAMMAR = r"""
?start: ternary
?ternary: or_test "?" ternary ":" ternary | or_test
?or_test: and_test ("or" and_test)+ -> or_ | and_test
?and_test: not_test ("and" not_test)+ -> and_ | not_test
?not_test: NOT+ comparison -> not_ | comparison
?comparison: sum COMPARE sum | sum
?sum: product (ADDOP product)+ | product
?product: unary (MULOP unary)+ | unary
?unary: ADDOP+ implicit -> signed | implicit
?implicit: power jpower+ | power
?power: atom "^" exponent | atom
?jpower: jatom "^" exponent -> power | jatom
?exponent: ADDOP+ power -> signed | power
?atom: NUMBER | jatom
?jatom: NAME | call | "(" ternary ")"
call: CALLNAME (ternary ("," ternary)*)? ")"

NOT: "not"
COMPARE: "<=" | ">=" | "==" | "!=" | "<" | ">"
ADDOP: "+" | "-"
MULOP: "*" | "/" | "%"
NUMBER: /([0-9]+(\.[0-9]*)?|\.[0-9]+)(e[+-]?[0-9]+)?/
CALLNAME.2: /(?!(and|or|not)[ \t\r\n]*\()[a-z][a-z0-9_]*[ \t\r\n]*\(/
NAME: /[a-z][a-z0-9_]*/
%ignore /[ \t\r\n]+/
"""

_PARSER = cached_lark(_GRAMMAR, lexer="basic", propagate_positions=True)

# The language is case-insensitive and has no strings: the text is parsed with ASCII
# letters lowered (length-preserving, so token offsets index the original text too).
_LOWER = str.maketrans("ABCDEFGHIJKLMNOPQRSTUVWXYZ", "abcdefghijklmnopqrstuvwxyz")


# -- the vocabulary ------------------------------------------------------------------


@dataclass(frozen=True)
class Function:
    """A function of the language.

    Attributes:
        name: lowercase name.
        params: parameter names, in order (for a variadic function: the repeated one).
        variadic: takes one or more arguments.
        summary: what it computes (one line, for the reference and error hints).
    """

    name: str
    params: tuple[str, ...]
    variadic: bool
    summary: str

    @property
    def signature(self) -> str:
        """How a call reads, e.g. ``clamp(lo, x, hi)`` or ``max(a, ...)``."""
        args = f"{self.params[0]}, ..." if self.variadic else ", ".join(self.params)
        return f"{self.name}({args})"


def _frac(x, out=None):
    """Fractional part with the sign of ``x``: ``x - trunc(x)``."""
    return np.subtract(x, np.trunc(x), out=out)


def _round(x, out=None):
    """Round half away from zero (like C's ``round``), unlike numpy's half-to-even."""
    return np.copysign(np.floor(np.absolute(x) + 0.5), x, out=out)


def _clamp(lo, x, hi, out=None):
    """``x`` limited to ``[lo, hi]`` (``hi`` wins where ``lo > hi``)."""
    return np.clip(x, lo, hi, out=out)


def _not(x, out=None):
    """Logical not: 1.0 where ``x == 0``, else 0.0."""
    return np.equal(x, 0.0, out=out)


def _truth(x, out=None):
    """Truth value: 1.0 where ``x != 0`` (NaN included), else 0.0."""
    return np.not_equal(x, 0.0, out=out)


def _select(c, a, b):
    """``a`` where ``c`` is nonzero, else ``b`` (both are evaluated everywhere)."""
    return np.where(np.not_equal(c, 0.0), a, b)


def _erf(x, out=None):
    """The error function, elementwise (scipy is imported on first use: it takes ~0.4 s)."""
    from scipy.special import erf

    return erf(x, out=out)


_FUNCTION_TABLE: list[tuple[str, tuple[str, ...], bool, Callable | None, str]] = [
    ("abs", ("x",), False, np.absolute, "absolute value"),
    ("avg", ("a",), True, None, "mean of the arguments"),
    ("ceil", ("x",), False, np.ceil, "smallest integer >= x"),
    ("floor", ("x",), False, np.floor, "largest integer <= x"),
    ("sqrt", ("x",), False, np.sqrt, "square root (NaN for x < 0)"),
    ("log", ("x",), False, np.log, "natural logarithm (NaN for x < 0, -inf at 0)"),
    ("exp", ("x",), False, np.exp, "e to the power x"),
    ("pow", ("x", "y"), False, np.power, "x to the power y, same as x^y"),
    ("max", ("a",), True, np.maximum, "largest argument (NaN if any is NaN)"),
    ("min", ("a",), True, np.minimum, "smallest argument (NaN if any is NaN)"),
    ("clamp", ("lo", "x", "hi"), False, _clamp, "x limited to [lo, hi]"),
    ("sin", ("x",), False, np.sin, "sine, x in radians"),
    ("cos", ("x",), False, np.cos, "cosine, x in radians"),
    ("tan", ("x",), False, np.tan, "tangent, x in radians"),
    ("asin", ("x",), False, np.arcsin, "arc sine in [-pi/2, pi/2] (NaN outside [-1, 1])"),
    ("acos", ("x",), False, np.arccos, "arc cosine in [0, pi] (NaN outside [-1, 1])"),
    ("atan", ("x",), False, np.arctan, "arc tangent in (-pi/2, pi/2)"),
    ("atan2", ("y", "x"), False, np.arctan2, "angle of the point (x, y) in [-pi, pi]"),
    ("hypot", ("x", "y"), False, np.hypot, "sqrt(x^2 + y^2) without overflow"),
    ("sgn", ("x",), False, np.sign, "sign: -1, 0 or 1"),
    ("frac", ("x",), False, _frac, "fractional part x - trunc(x), sign of x"),
    ("round", ("x",), False, _round, "nearest integer, halves away from zero"),
    ("trunc", ("x",), False, np.trunc, "integer part, towards zero"),
    ("deg2rad", ("x",), False, np.deg2rad, "degrees to radians"),
    ("rad2deg", ("x",), False, np.rad2deg, "radians to degrees"),
    ("erf", ("x",), False, _erf, "error function"),
    ("if", ("c", "a", "b"), False, None, "a where c is nonzero, else b (same as c ? a : b)"),
]

FUNCTIONS: Mapping[str, Function] = MappingProxyType(
    {name: Function(name, params, variadic, summary) for name, params, variadic, _, summary in _FUNCTION_TABLE}
)
"""Every function of the language by lowercase name."""

_KERNELS: dict[str, Callable] = {name: kernel for name, _, _, kernel, _ in _FUNCTION_TABLE if kernel is not None}

VARIABLES: Mapping[str, str] = MappingProxyType(
    {
        "x": "x coordinate, mm",
        "y": "y coordinate, mm",
        "z": "z coordinate, mm",
        "rho": "distance from the z axis, sqrt(x^2 + y^2), mm",
        "phi": "azimuth atan2(y, x) in (-pi, pi], radians",
        "phic": "same as phi (cylindrical azimuth)",
        "theta": "same as phi",
        "r": "distance from the origin, sqrt(x^2 + y^2 + z^2), mm",
        "phis": "polar angle from +z, acos(z / r) in [0, pi] (0 at the origin), radians",
        "d": "signed distance of the fgrade's child (negative inside), mm",
    }
)
"""Every variable of the language by lowercase name (aliases included)."""

CONSTANTS: Mapping[str, float] = MappingProxyType({"pi": math.pi, "e": math.e})
"""The named constants."""

_CANONICAL = {"phic": "phi", "theta": "phi"}

_BINARY = {
    "+": np.add,
    "-": np.subtract,
    "*": np.multiply,
    "/": np.divide,
    "%": np.fmod,
    "<": np.less,
    "<=": np.less_equal,
    ">": np.greater,
    ">=": np.greater_equal,
    "==": np.equal,
    "!=": np.not_equal,
}


# -- locations -------------------------------------------------------------------------


class _Source:
    """The expression text and where it starts in its file; builds located errors."""

    def __init__(self, text: str, file: str | Path | None, line: int, column: int,
                 file_lines: Sequence[str] | None = None) -> None:
        self.text = text
        self.file = file
        self.line = line
        self.column = column
        self.lines = text.split("\n")
        spanned = None if file_lines is None else tuple(file_lines[: len(self.lines)])
        self.file_lines = spanned if spanned is not None and len(spanned) == len(self.lines) else None

    def position(self, offset: int) -> tuple[int, int]:
        """1-based (line, column) in the file of character ``offset`` of the text."""
        offset = max(0, min(offset, len(self.text)))
        row = self.text.count("\n", 0, offset)
        col = offset - (self.text.rfind("\n", 0, offset) + 1) + 1
        if row == 0:
            return self.line, self.column + col - 1
        return self.line + row, col

    def source_line(self, file_line: int) -> str:
        """The file's ``file_line`` when its lines are known, else the expression's text on
        it, indented on its first line like the file."""
        if self.file_lines is not None:
            return self.file_lines[file_line - self.line]
        text = self.lines[file_line - self.line]
        return " " * (self.column - 1) + text if file_line == self.line else text

    def error(self, cls: type[FgsliceError], message: str, offset: int, hint: str | None = None) -> FgsliceError:
        """An error of class ``cls`` located at character ``offset`` of the text."""
        line, column = self.position(offset)
        return cls(message, file=self.file, line=line, column=column, hint=hint, source_line=self.source_line(line))

    def end_offset(self) -> int:
        """Offset just past the last non-blank character."""
        return len(self.text.rstrip(" \t\r\n"))


# -- syntax errors ---------------------------------------------------------------------

_ALLOWED = "numbers, names, f(...), ( ), + - * / % ^, < <= > >= == !=, and, or, not, ? :"

_CHAR_HINTS = {
    '"': "strings are not part of the expression language",
    "'": "strings are not part of the expression language",
    "[": "subscripts are not part of the expression language; group with ( )",
    "]": "subscripts are not part of the expression language; group with ( )",
    "{": "group with ( )",
    "}": "group with ( )",
    ".": "attribute access is not part of the expression language",
    "_": "names start with a letter; names beginning with '_' do not exist",
    "=": "compare with '=='; expressions cannot assign",
    "&": "write 'and'",
    "|": "write 'or'",
    "!": "write 'not', or '!=' to compare",
    "π": "write 'pi'",
    "×": "write '*'",
    "·": "write '*'",
    "÷": "write '/'",
    "−": "write '-' (ASCII minus)",
    "²": "write '^2'",
    "³": "write '^3'",
}

_TOKEN_NAMES = {
    "LPAR": "'('",
    "RPAR": "')'",
    "COMMA": "','",
    "NUMBER": "a number",
    "NAME": "a name",
    "CALLNAME": "a function call",
    "ADDOP": "'+'/'-'",
    "MULOP": "'*'/'/'/'%'",
    "COMPARE": "a comparison",
    "CIRCUMFLEX": "'^'",
    "QMARK": "'?'",
    "COLON": "':'",
    "AND": "'and'",
    "OR": "'or'",
    "NOT": "'not'",
    "$END": "the end of the expression",
}


def _expected(names: set[str]) -> str:
    """``expected a number, a name or '('`` from lark's terminal names."""
    readable = sorted({_TOKEN_NAMES.get(n, n) for n in names})
    if not readable:
        return "the expression cannot continue here"
    if len(readable) > 6:
        return "expected an operator, ')' or the end of the expression"
    return "expected " + (readable[0] if len(readable) == 1 else ", ".join(readable[:-1]) + " or " + readable[-1])


def _unmatched_paren(text: str) -> int | None:
    """Offset of the first '(' never closed, or None."""
    opened: list[int] = []
    for i, ch in enumerate(text):
        if ch == "(":
            opened.append(i)
        elif ch == ")" and opened:
            opened.pop()
    return opened[0] if opened else None


def _syntax_error(src: _Source, exc: lark.exceptions.UnexpectedInput) -> FgsliceError:
    """Turn lark's complaint into a located DesignSyntaxError with a hint."""
    text = src.text
    if isinstance(exc, lark.exceptions.UnexpectedCharacters):
        ch = text[exc.pos_in_stream]
        hint = _CHAR_HINTS.get(ch, f"expressions are made of {_ALLOWED}")
        return src.error(DesignSyntaxError, f"unexpected character {ch!r}", exc.pos_in_stream, hint)
    token = getattr(exc, "token", None)
    expected = set(getattr(exc, "expected", ()) or ())
    if token is None or token.type == "$END":
        opened = _unmatched_paren(text)
        if opened is not None and "RPAR" in expected:
            line, column = src.position(opened)
            return src.error(
                DesignSyntaxError,
                f"missing ')' to close the '(' at line {line}, column {column}",
                src.end_offset(),
                "add the closing parenthesis",
            )
        return src.error(DesignSyntaxError, "the expression ends too early", src.end_offset(), _expected(expected))
    value = text[token.start_pos : token.end_pos]
    offset = token.start_pos
    if token.type == "NUMBER":
        what, hint = f"number '{value}'", "a number cannot follow a value directly; write '*' to multiply"
    elif token.type == "COMMA":
        what, hint = "','", "commas only separate the arguments of a function call"
    elif token.type == "RPAR" and "RPAR" not in expected and _unmatched_paren(text[:offset]) is None:
        what, hint = "')'", "this ')' has no matching '('"
    elif token.type == "COMPARE" and "COMPARE" not in expected and "$END" in expected:
        what, hint = f"'{value}'", "comparisons do not chain: write 'a < b and b < c'"
    elif token.type == "MULOP" and value == "*" and text[:offset].rstrip().endswith("*"):
        what, hint = "'*'", "write '^' for powers"
    elif token.type == "CALLNAME":
        what, hint = f"call of '{value[:-1].rstrip()}'", _expected(expected)
    elif token.type == "NAME":
        what, hint = f"name '{value}'", _expected(expected)
    else:
        what, hint = f"'{value}'", _expected(expected)
    return src.error(DesignSyntaxError, f"unexpected {what}", offset, hint)


# -- compilation to a shared, hash-consed program -----------------------------------------

_BLOCK = 1 << 16
"""Points evaluated per block: large arrays are processed in blocks of whole rows."""

_LEAVES = ("x", "y", "z", "d")
"""Input variables; the other variables are derived from them inside the program."""


def _azimuth(y, x, out=None):
    """phi = atan2(y, x) in (-pi, pi], radians."""
    phi = np.arctan2(y, x, out=out)
    np.copyto(phi, np.pi, where=phi <= -np.pi)  # atan2(-0.0, x<0) is -pi; the range is (-pi, pi]
    return phi


def _polar(z, radius):
    """phis = acos(z / r) in [0, pi], radians; 0 at the origin."""
    cosine = np.ones(np.broadcast_shapes(np.shape(z), np.shape(radius)))  # acos(1) = 0 at the origin
    np.divide(z, radius, out=cosine, where=radius > 0)
    np.clip(cosine, -1.0, 1.0, out=cosine)
    return np.arccos(cosine, out=cosine)


_COMMUTATIVE = frozenset(
    [np.add, np.multiply, np.maximum, np.minimum, np.hypot, np.equal, np.not_equal, np.logical_and, np.logical_or]
)
"""Kernels whose two arguments may be swapped (sorted so ``a*b`` and ``b*a`` are shared)."""

_BOOLEAN = frozenset(
    [np.less, np.less_equal, np.greater, np.greater_equal, np.equal, np.not_equal, np.logical_and, np.logical_or, _not, _truth]
)
"""Kernels returning booleans: they are given a float64 output so values stay float64."""

_NO_OUT = frozenset([_select, _polar])
"""Kernels that allocate their own result (no ``out=``)."""


class _Graph:
    """A hash-consed expression DAG: equal operations on equal operands are one node.

    Node ``i`` is ``("var", name)``, ``("const", value)`` or ``(kernel, argument ids)``;
    arguments always precede their users, so node order is a valid evaluation order.
    Operations on constants only are folded into constants.
    """

    def __init__(self) -> None:
        self.nodes: list[tuple] = []
        self._index: dict[tuple, int] = {}

    def _add(self, key: tuple, node: tuple) -> int:
        found = self._index.get(key)
        if found is None:
            found = self._index[key] = len(self.nodes)
            self.nodes.append(node)
        return found

    def const_value(self, i: int) -> float | None:
        """The value of node ``i`` when it is a constant, else None."""
        node = self.nodes[i]
        return node[1] if node[0] == "const" else None

    def const(self, value: float) -> int:
        return self._add(("const", float(value).hex()), ("const", float(value)))

    def var(self, name: str) -> int:
        """The node of variable ``name`` (canonical); derived variables are built from x, y, z."""
        if name in _LEAVES:
            return self._add(("var", name), ("var", name))
        if name == "rho":
            return self.apply(np.hypot, (self.var("x"), self.var("y")))
        if name == "phi":
            return self.apply(_azimuth, (self.var("y"), self.var("x")))
        if name == "r":
            return self.apply(np.hypot, (self.var("rho"), self.var("z")))
        return self.apply(_polar, (self.var("z"), self.var("r")))

    def apply(self, kernel: Callable, args: Sequence[int]) -> int:
        """The node of ``kernel(*args)``: folded when every argument is a constant."""
        values = [self.const_value(a) for a in args]
        if all(v is not None for v in values):
            with np.errstate(all="ignore"):
                return self.const(float(kernel(*values)))
        args = tuple(sorted(args)) if kernel in _COMMUTATIVE else tuple(args)
        return self._add((kernel, args), (kernel, args))

    def merge(self, other: _Graph) -> list[int]:
        """Add every node of ``other`` to this graph; returns the new id of each."""
        ids: list[int] = []
        for node in other.nodes:
            if node[0] == "var":
                ids.append(self.var(node[1]))
            elif node[0] == "const":
                ids.append(self.const(node[1]))
            else:
                ids.append(self.apply(node[0], [ids[a] for a in node[1]]))
        return ids


class _Program:
    """The steps computing the ``roots`` of a graph, each shared value computed once.

    Registers are node ids. A step writes its result into an argument it consumes last
    (``out=``) when that argument already has the block's full shape; otherwise numpy
    allocates the natural broadcast shape, so values depending only on broadcast inputs
    (a grid's row of x, a single z) stay as small as their inputs.
    """

    def __init__(self, graph: _Graph, roots: Sequence[int]) -> None:
        self.roots = tuple(roots)
        live = set(self.roots)
        for i in range(len(graph.nodes) - 1, -1, -1):
            node = graph.nodes[i]
            if i in live and node[0] not in ("var", "const"):
                live.update(node[1])
        uses = dict.fromkeys(live, 0)
        for root in self.roots:
            uses[root] += 1
        for i in live:
            node = graph.nodes[i]
            if node[0] not in ("var", "const"):
                for a in node[1]:
                    uses[a] += 1
        self.template: list = [None] * len(graph.nodes)
        self.temporary = [False] * len(graph.nodes)
        self.leaves = {}
        self.steps: list[tuple] = []
        for i in sorted(live):
            node = graph.nodes[i]
            if node[0] == "const":
                self.template[i] = node[1]
                continue
            if node[0] == "var":
                self.leaves[node[1]] = i
                continue
            kernel, args = node
            self.temporary[i] = True
            for a in args:
                uses[a] -= 1
            dead = tuple(a for a in dict.fromkeys(args) if uses[a] == 0 and self.temporary[a])
            mode = 2 if kernel in _NO_OUT else 1 if kernel in _BOOLEAN else 0
            self.steps.append((kernel, args, i, dead, mode))

    def run(self, inputs: Mapping[str, np.ndarray], shape: tuple[int, ...]) -> list:
        """The roots' values on one block (natural broadcast shapes, at most ``shape``)."""
        r = self.template.copy()
        for name, i in self.leaves.items():
            r[i] = inputs[name]
        with np.errstate(all="ignore"):
            for kernel, args, dst, dead, mode in self.steps:
                values = [r[a] for a in args]
                if mode == 2:
                    r[dst] = kernel(*values)
                else:
                    out = None
                    for a in dead:
                        if r[a].shape == shape:
                            out = r[a]
                            break
                    if out is None and mode == 1:
                        out = np.empty(np.broadcast_shapes(*(np.shape(v) for v in values)))
                    r[dst] = kernel(*values) if out is None else kernel(*values, out=out)
                for a in dead:
                    r[a] = None
        return [r[i] for i in self.roots]

    def evaluate(self, coords: Mapping[str, np.ndarray], shape: tuple[int, ...]) -> list[np.ndarray]:
        """New float64 arrays of ``shape``, one per root, from broadcast-compatible ``coords``."""
        ndim = max(len(shape), 1)
        full = shape if shape else (1,)
        inputs = {name: values.reshape((1,) * (ndim - values.ndim) + values.shape) for name, values in coords.items()}
        row = math.prod(full[1:])
        if full[0] * row <= _BLOCK:
            results = self.run(inputs, full)
            outs = []
            for i, value in zip(self.roots, results, strict=True):
                owned = self.temporary[i] and value.shape == full and not any(value is o for o in outs)
                outs.append(value if owned else np.array(np.broadcast_to(value, full), dtype=np.float64))
            return [o.reshape(shape) for o in outs]
        # Blocks of whole rows keep the temporaries in cache and the allocations small;
        # inputs constant along the first axis are passed whole.
        outs = [np.empty(full) for _ in self.roots]
        rows = max(1, _BLOCK // max(row, 1))
        for start in range(0, full[0], rows):
            block = slice(start, start + rows)
            part = {name: v[block] if v.shape[0] > 1 else v for name, v in inputs.items()}
            block_shape = outs[0][block].shape
            for out, value in zip(outs, self.run(part, block_shape), strict=True):
                out[block] = value
        return [o.reshape(shape) for o in outs]


class _Compiler:
    """Walks the parse tree (iteratively) into a hash-consed graph; folds constants."""

    def __init__(self, src: _Source) -> None:
        self.src = src
        self.graph = _Graph()
        self.used: set[str] = set()
        self.d_offset: int | None = None

    def emit(self, kernel: Callable, args: list[int]) -> int:
        """The node of ``kernel(*args)`` (a ufunc-like callable taking ``out=``)."""
        return self.graph.apply(kernel, args)

    def fold(self, kernels: list[Callable], operands: list[int]) -> int:
        """Left fold: ``((a0 k0 a1) k1 a2) ...`` as a flat run of steps."""
        acc = operands[0]
        for kernel, operand in zip(kernels, operands[1:], strict=True):
            acc = self.emit(kernel, [acc, operand])
        return acc

    # leaves
    def number(self, token: lark.Token) -> int:
        value = float(token.value)
        if not math.isfinite(value):
            text = self.src.text[token.start_pos : token.end_pos]
            shown = text if len(text) <= 24 else text[:20] + "..."
            raise self.src.error(
                DesignSyntaxError, f"number too large: '{shown}'", token.start_pos, "numbers must be below about 1.8e308"
            )
        return self.graph.const(value)

    def name(self, token: lark.Token) -> int:
        name = token.value
        if name in CONSTANTS:
            return self.graph.const(CONSTANTS[name])
        if name in VARIABLES:
            canonical = _CANONICAL.get(name, name)
            self.used.add(canonical)
            if canonical == "d" and self.d_offset is None:
                self.d_offset = token.start_pos
            return self.graph.var(canonical)
        original = self.src.text[token.start_pos : token.end_pos]
        if name in FUNCTIONS:
            raise self.src.error(
                DesignError,
                f"'{original}' is a function, not a value",
                token.start_pos,
                f"call it: {FUNCTIONS[name].signature}",
            )
        hint = did_you_mean(name, [*VARIABLES, *CONSTANTS]) or "variables are " + ", ".join(VARIABLES) + "; constants pi, e"
        raise self.src.error(DesignError, f"unknown variable '{original}'", token.start_pos, hint)

    # operations
    def call(self, token: lark.Token, args: list[int]) -> int:
        name = token.value[:-1].rstrip(" \t\r\n")
        shown = self.src.text[token.start_pos : token.start_pos + len(name)]
        if name not in FUNCTIONS:
            if name in VARIABLES or name in CONSTANTS:
                raise self.src.error(
                    DesignError,
                    f"'{shown}' is not a function",
                    token.start_pos,
                    f"write {shown}*(...) to multiply",
                )
            hint = did_you_mean(name, FUNCTIONS) or "functions are " + ", ".join(FUNCTIONS)
            raise self.src.error(DesignError, f"unknown function '{shown}'", token.start_pos, hint)
        function = FUNCTIONS[name]
        n = len(args)
        if function.variadic and n < 1:
            raise self.src.error(
                DesignError, f"{name} takes at least 1 argument, got 0", token.start_pos, f"write {function.signature}"
            )
        if not function.variadic and n != len(function.params):
            count = len(function.params)
            plural = "argument" if count == 1 else "arguments"
            raise self.src.error(
                DesignError,
                f"{name} takes {count} {plural} ({', '.join(function.params)}), got {n}",
                token.start_pos,
                f"write {function.signature}",
            )
        if name == "if":
            return self.emit(_select, args)
        if name == "avg":
            return self.emit(np.divide, [self.fold([np.add] * (n - 1), args), self.graph.const(float(n))])
        if function.variadic:
            return self.fold([_KERNELS[name]] * (n - 1), args)
        return self.emit(_KERNELS[name], args)

    def node(self, tree: lark.Tree, args: list[int]) -> int:
        kind = tree.data
        children = tree.children
        if kind == "call":
            return self.call(children[0], args)
        if kind == "ternary":
            return self.emit(_select, args)
        if kind in ("sum", "product"):
            ops = [_BINARY[c.value] for c in children if isinstance(c, lark.Token) and c.type in ("ADDOP", "MULOP")]
            return self.fold(ops, args)
        if kind == "implicit":
            return self.fold([np.multiply] * (len(args) - 1), args)
        if kind == "power":
            return self.emit(np.power, args)
        if kind == "signed":
            minus = sum(1 for c in children if isinstance(c, lark.Token) and c.value == "-")
            return self.emit(np.negative, args) if minus % 2 else args[0]
        if kind == "comparison":
            return self.emit(_BINARY[children[1].value], args)
        if kind == "not_":
            nots = sum(1 for c in children if isinstance(c, lark.Token) and c.type == "NOT")
            return self.emit(_not if nots % 2 else _truth, args)
        if kind == "and_":
            return self.fold([np.logical_and] * (len(args) - 1), args)
        if kind == "or_":
            return self.fold([np.logical_or] * (len(args) - 1), args)
        raise AssertionError(f"grammar rule without a compiler: {kind}")

    def compile(self, root: lark.Tree | lark.Token) -> int:
        """Post-order walk with an explicit stack (no recursion), checking the depth."""
        values: list[int] = []
        stack: list[tuple[lark.Tree | lark.Token, int, bool]] = [(root, 0, False)]
        while stack:
            item, depth, expanded = stack.pop()
            if isinstance(item, lark.Token):
                values.append(self.number(item) if item.type == "NUMBER" else self.name(item))
                continue
            if expanded:
                n = sum(1 for c in item.children if _is_operand(c))
                args = values[len(values) - n :]
                del values[len(values) - n :]
                values.append(self.node(item, args))
                continue
            if depth >= MAX_DEPTH:
                raise self.src.error(
                    DesignSyntaxError,
                    f"expression nested too deeply (more than {MAX_DEPTH} levels)",
                    item.meta.start_pos,
                    "split it into simpler expressions",
                )
            stack.append((item, depth, True))
            stack.extend((c, depth + 1, False) for c in reversed(item.children) if _is_operand(c))
        return values[0]


def _deep_paren(text: str) -> int | None:
    """Offset of the first '(' nested deeper than :data:`MAX_DEPTH`, or None."""
    codes = np.frombuffer(text.encode("utf-32-le", "surrogatepass"), dtype=np.uint32)
    depth = np.cumsum((codes == ord("(")).astype(np.int64) - (codes == ord(")")))
    over = np.flatnonzero(depth > MAX_DEPTH)
    return int(over[0]) if over.size else None


def _is_operand(child: lark.Tree | lark.Token) -> bool:
    return isinstance(child, lark.Tree) or child.type in ("NUMBER", "NAME")


# -- the compiled expression ---------------------------------------------------------------


class Expression:
    """A compiled expression: call it on coordinate arrays to get float64 values.

    Attributes:
        text: the expression as written.
        variables: canonical lowercase names of the variables it uses (``phic`` and
            ``theta`` appear as ``phi``); ``'d'`` means the caller must pass ``d``.
        file, line, column: where the text starts (for messages).
        file_lines: the file's lines the text spans, shown in messages (None: the text's own).
    """

    __slots__ = ("text", "variables", "file", "line", "column", "file_lines", "_graph", "_root", "_program", "_d_offset")

    def __init__(
        self,
        text: str,
        variables: frozenset[str],
        file: str | None,
        line: int,
        column: int,
        graph: _Graph,
        root: int,
        d_offset: int | None,
        file_lines: tuple[str, ...] | None = None,
    ) -> None:
        self.text = text
        self.variables = variables
        self.file = file
        self.line = line
        self.column = column
        self.file_lines = file_lines
        self._graph = graph
        self._root = root
        self._program = _Program(graph, [root])
        self._d_offset = d_offset

    def __repr__(self) -> str:
        return f"Expression({self.text!r})"

    def __reduce__(self):
        return (_recompile, (self.text, self.file, self.line, self.column, self.file_lines))

    def _source(self) -> _Source:
        return _Source(self.text, self.file, self.line, self.column, self.file_lines)

    def _missing_d(self) -> FgsliceError:
        return self._source().error(
            DesignError,
            "'d' (the signed distance of the fgrade's child) is not available here",
            self._d_offset or 0,
            "use d only in the material expressions of an fgrade",
        )

    def __call__(self, x, y, z, d=None) -> np.ndarray:
        """Values at the points ``(x, y, z)`` (mm; broadcast-compatible arrays or scalars).

        ``d`` (the signed distance of the fgrade's child, mm) is needed only when
        ``'d' in self.variables``. Returns a new float64 array of the broadcast shape.
        NaN/inf results are returned as such; see :meth:`evaluate_checked`.
        """
        if d is None and "d" in self.variables:
            raise self._missing_d()
        coords, shape = _coordinates(x, y, z, d)
        return self._program.evaluate(coords, shape)[0]

    def evaluate_checked(self, x, y, z, d=None) -> np.ndarray:
        """Like calling the expression, but raise :class:`FieldError` on NaN or inf.

        The error names the expression's location and the first offending point (in C
        order of the broadcast arrays) with its coordinates in mm.
        """
        values = self(x, y, z, d)
        bad = ~np.isfinite(values)
        if not bad.any():
            return values
        index = np.unravel_index(int(np.argmax(bad)), values.shape)
        point = [float(np.broadcast_to(np.asarray(c, dtype=np.float64), values.shape)[index]) for c in (x, y, z)]
        where = f"x={point[0]:g}, y={point[1]:g}, z={point[2]:g}"
        if d is not None:
            where += f", d={float(np.broadcast_to(np.asarray(d, dtype=np.float64), values.shape)[index]):g}"
        value = float(values[index])
        kind = "NaN (not a number)" if math.isnan(value) else f"{value:g}"
        short = " ".join(self.text.split())
        short = short if len(short) <= 60 else short[:57] + "..."
        line, column = self.line, self.column
        raise FieldError(
            f"expression '{short}' is {kind} at {where}",
            file=self.file,
            line=line,
            column=column,
            hint="look for division by zero, log or sqrt of a negative number, or a huge power; "
            "guard with max(..., 1e-9) or clamp(lo, x, hi)",
            source_line=self._source().source_line(line),
        )


class ExpressionGroup:
    """Several expressions evaluated together, every common subexpression computed once.

    With ``a = "(1+sin(x)*cos(y))/2"`` and ``b = "1-(1+sin(x)*cos(y))/2"`` the sine,
    cosine, product and halving are computed once and ``b`` costs one subtraction.
    Built by :func:`combine_expressions`.

    Attributes:
        expressions: the member expressions, in order.
        variables: the union of their variables.
    """

    __slots__ = ("expressions", "variables", "_program")

    def __init__(self, expressions: Sequence[Expression]) -> None:
        self.expressions = tuple(expressions)
        self.variables = frozenset().union(*(e.variables for e in self.expressions))
        graph = _Graph()
        roots = [graph.merge(e._graph)[e._root] for e in self.expressions]
        self._program = _Program(graph, roots)

    def __repr__(self) -> str:
        return f"ExpressionGroup({[e.text for e in self.expressions]!r})"

    def __reduce__(self):
        return (combine_expressions, (self.expressions,))

    def __call__(self, x, y, z, d=None) -> list[np.ndarray]:
        """The members' values at the points (as :meth:`Expression.__call__`), one new array each."""
        if d is None:
            for e in self.expressions:
                if "d" in e.variables:
                    raise e._missing_d()
        coords, shape = _coordinates(x, y, z, d)
        return self._program.evaluate(coords, shape)


def combine_expressions(expressions: Sequence[Expression]) -> ExpressionGroup:
    """One program evaluating all ``expressions`` with shared subexpressions computed once."""
    return ExpressionGroup(expressions)


def _coordinates(x, y, z, d) -> tuple[dict[str, np.ndarray], tuple[int, ...]]:
    """float64 arrays of the inputs (``d`` when given) and their broadcast shape."""
    coords = {"x": np.asarray(x, dtype=np.float64), "y": np.asarray(y, dtype=np.float64)}
    coords["z"] = np.asarray(z, dtype=np.float64)
    if d is not None:
        coords["d"] = np.asarray(d, dtype=np.float64)
    return coords, np.broadcast_shapes(*(a.shape for a in coords.values()))


def _recompile(text: str, file: str | None, line: int, column: int, file_lines: tuple[str, ...] | None) -> Expression:
    """Unpickling: compile the text again (compiled steps are closures)."""
    return compile_expression(text, file=file, line=line, column=column, file_lines=file_lines)


def compile_expression(
    text: str,
    *,
    file: str | Path | None = None,
    line: int = 1,
    column: int = 1,
    file_lines: Sequence[str] | None = None,
) -> Expression:
    """Compile expression ``text`` whose first character is at ``line``/``column`` of ``file``.

    ``file_lines``: the file's lines from ``line`` on (more are ignored); errors then show
    the file's own line under their caret.

    Raises:
        DesignSyntaxError: the text is not an expression of the language (including text
            longer than :data:`MAX_LENGTH`, nesting deeper than :data:`MAX_DEPTH` and
            numbers that overflow float64).
        DesignError: an unknown name, a function used as a value, a wrong argument count.
    """
    src = _Source(text, None if file is None else str(file), line, column, file_lines)
    if len(text) > MAX_LENGTH:
        raise src.error(
            DesignSyntaxError,
            f"expression too long ({len(text)} characters; the limit is {MAX_LENGTH})",
            0,
            "split it into simpler expressions",
        )
    if not text.strip(" \t\r\n"):
        raise src.error(DesignSyntaxError, "empty expression", 0, "write a value, e.g. 'z/70'")
    too_deep = _deep_paren(text)
    if too_deep is not None:
        raise src.error(
            DesignSyntaxError,
            f"parentheses nested too deeply (more than {MAX_DEPTH} levels)",
            too_deep,
            "split it into simpler expressions",
        )
    try:
        tree = _PARSER.parse(text.translate(_LOWER))
    except lark.exceptions.UnexpectedInput as exc:
        raise _syntax_error(src, exc) from None
    compiler = _Compiler(src)
    root = compiler.compile(tree)
    return Expression(
        text, frozenset(compiler.used), src.file, line, column, compiler.graph, root, compiler.d_offset, src.file_lines
    )
