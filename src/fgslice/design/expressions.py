"""The safe expression language of design files, compiled to vectorized numpy code.

An expression such as ``(1+sin(0.025*x+0.0375*y)*cos(0.0375*x-0.025*y))/2`` is parsed
by a LALR grammar (lark, built once at import) into a hash-consed graph (equal
subexpressions are one node; constants are folded), which is scheduled into a flat list
of numpy steps over a register file that reuse dead temporaries in place. Several
expressions combined with :func:`combine_expressions` share one graph, so what they have
in common is computed once. Nothing of the text is ever passed to ``eval``/``exec``:
only the names in :data:`FUNCTIONS`, :data:`VARIABLES`, :data:`CONSTANTS` and
:data:`LITERALS` exist, and locals the text declares.

The language is the part of ExprTk (which OpenVCAD compiles its expression strings with)
that has a meaning for a field: statements separated by ``;`` whose value is the last
one's, local variables (``var t := x/3; t^2``) with assignment and compound assignment,
``if (c) a; else b;`` statements, ``switch``, the extended logic operators and ExprTk's
functions with its definitions. Statements run at compile time on graph nodes, so a
local costs nothing at evaluation and a conditional assignment is a selection. Loops,
strings and vectors are refused by name. Coordinates cannot be assigned.

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

from fgslice.design import expression_kernels as kernels
from fgslice.design.lark_cache import cached_lark
from fgslice.errors import DesignError, DesignSyntaxError, FgsliceError, FieldError, did_you_mean

__all__ = [
    "CONSTANTS",
    "FUNCTIONS",
    "LITERALS",
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

# A text is a list of statements separated by ';' (a trailing ';' is allowed); its value is
# the last one's. A statement declares a local (var t := ...) or is an expression. Operator
# precedence, loosest first: assignment t := / += -= *= /= %= (right-associative, to
# locals only) / ?: / or nor xor xnor | / and nand & / not / comparisons (non-chaining) /
# + - / * / % / unary sign / implicit multiplication / ^ (right-associative; its exponent
# may carry a sign). The right operand of an implicit multiplication never starts with a
# number or a sign, so "x 2" and "1.2.3" are errors and "a -b" is a subtraction. A name
# directly followed by "(" is a call (CALLNAME), whitespace allowed in between; "if (" opens
# either the call if(c, a, b) or the statement if (c) a [;] else b. An if statement, a
# switch and a block { ...; ... } are operands of the unary level: "2 * if (c) a else b"
# works, but nothing multiplies them implicitly or raises them to a power, so a missing ';'
# after "}" is an error, not a product. A branch that is a block ends with it, as in ExprTk
# ("if (c) {a} else {b} + 1" adds 1 to either: the reduce/reduce conflict is settled by
# ifstmt's priority); any other branch extends as far as an expression can (shift/reduce
# conflicts, resolved by shifting; an else belongs to the nearest if). These are the
# grammar's only conflicts: expressions without an if statement parse as before.
# "; else" is one token (_ELSE, comments allowed in between), so that "if (c) a; else b"
# is not read as two statements.
# Loop keywords are lexed (LOOP) only to be refused by name. Comments are ExprTk's:
# "// ..." and "# ..." to the end of the line, "/* ... */".
_GRAMMAR = r"""
start: _statements
_statements: _statement (";" _statement)* ";"?
_statement: declare | expr
declare: "var" NAME (ASSIGN expr)?
?expr: assign | ternary
assign: NAME (ASSIGN | UPDATE) expr
?ternary: or_test "?" ternary ":" ternary | or_test
?or_test: and_test (orop and_test)+ -> logic | and_test
?and_test: not_test (andop not_test)+ -> logic | not_test
!orop: "or" | "nor" | "xor" | "xnor" | "|"
!andop: "and" | "nand" | "&"
?not_test: NOT+ comparison -> not_ | comparison
?comparison: sum COMPARE sum | sum
?sum: product (ADDOP product)+ | product
?product: unary (MULOP unary)+ | unary
?unary: ADDOP+ implicit -> signed | implicit
?implicit: power jpower+ | power | ifstmt | switch | block
?power: atom "^" exponent | atom
?jpower: jatom "^" exponent -> power | jatom
?exponent: ADDOP+ power -> signed | power
?atom: NUMBER | jatom
?jatom: NAME | call | "(" expr ")" | ifcall
call: CALLNAME (expr ("," expr)*)? ")"
ifcall: IF expr ("," expr)+ ")"
ifstmt.2: IF expr ")" (block | expr) (_ELSE (block | ifstmt | expr))?
switch: "switch" "{" (case | default)* "}"
case: "case" expr ":" expr ";"
default: "default" ":" expr ";"
block: "{" _statements "}"

NOT: "not"
COMPARE: "<=" | ">=" | "==" | "!=" | "<>" | "<" | ">" | "="
ASSIGN: ":="
UPDATE: "+=" | "-=" | "*=" | "/=" | "%="
ADDOP: "+" | "-"
MULOP: "*" | "/" | "%"
NUMBER: /([0-9]+(\.[0-9]*)?|\.[0-9]+)(e[+-]?[0-9]+)?/
IF.3: /if[ \t\r\n]*\(/
_ELSE.3: /(;([ \t\r\n]|\/\/[^\n]*|#[^\n]*|\/\*[\s\S]*?\*\/)*)?else(?![a-z0-9_])/
LOOP.3: /(while|for|repeat|until|break|continue|return)(?![a-z0-9_])/
CALLNAME.2: /(?!(and|or|not|nand|nor|xor|xnor|case)[ \t\r\n]*\()[a-z][a-z0-9_]*[ \t\r\n]*\(/
NAME: /[a-z][a-z0-9_]*/
COMMENT: /\/\/[^\n]*|#[^\n]*|\/\*[\s\S]*?\*\//
%ignore /[ \t\r\n]+/
%ignore COMMENT
"""


class _LoopKeyword(Exception):
    """Raised while lexing at a loop keyword, which the language refuses by name."""

    def __init__(self, token: lark.Token) -> None:
        super().__init__(token.value)
        self.token = token


class _RefuseLoops(lark.lark.PostLex):
    """Passes the tokens on and stops at the first loop keyword (``while``, ``for`` ...)."""

    always_accept = ("LOOP",)

    def process(self, stream):
        for token in stream:
            if token.type == "LOOP":
                raise _LoopKeyword(token)
            yield token

    def __repr__(self) -> str:  # part of the parser cache's key: stable across runs
        return "_RefuseLoops()"


_PARSER = cached_lark(_GRAMMAR, lexer="basic", propagate_positions=True, postlex=_RefuseLoops())

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
    ("log10", ("x",), False, np.log10, "base-10 logarithm"),
    ("log2", ("x",), False, np.log2, "base-2 logarithm"),
    ("logn", ("x", "n"), False, None, "base-n logarithm, log(x)/log(n)"),
    ("log1p", ("x",), False, np.log1p, "log(1 + x), accurate for small x"),
    ("expm1", ("x",), False, np.expm1, "e^x - 1, accurate for small x"),
    ("root", ("x", "n"), False, kernels.root, "n-th root x^(1/n); for x < 0 real only for an odd integer n, else NaN"),
    ("roundn", ("x", "n"), False, kernels.roundn, "x rounded to n decimals (n from 0 to 16), halves away from zero"),
    ("sum", ("a",), True, np.add, "sum of the arguments"),
    ("mul", ("a",), True, np.multiply, "product of the arguments"),
    ("mod", ("x", "y"), False, np.fmod, "remainder with the sign of x, same as x % y"),
    ("equal", ("x", "y"), False, None, "1 where |x - y| <= 1e-10 * max(1, |x|, |y|), else 0"),
    ("not_equal", ("x", "y"), False, None, "1 where |x - y| > 1e-10 * max(1, |x|, |y|), else 0"),
    ("inrange", ("lo", "x", "hi"), False, None, "1 where lo <= x <= hi, else 0"),
    ("iclamp", ("lo", "x", "hi"), False, None, "x outside (lo, hi); inside, the nearer of lo and hi (lo at the middle)"),
    ("erfc", ("x",), False, kernels.erfc, "complementary error function 1 - erf(x)"),
    ("ncdf", ("x",), False, None, "standard normal cumulative distribution, 0.5 erfc(-x/sqrt(2))"),
    ("sinh", ("x",), False, np.sinh, "hyperbolic sine"),
    ("cosh", ("x",), False, np.cosh, "hyperbolic cosine"),
    ("tanh", ("x",), False, np.tanh, "hyperbolic tangent"),
    ("asinh", ("x",), False, np.arcsinh, "inverse hyperbolic sine"),
    ("acosh", ("x",), False, np.arccosh, "inverse hyperbolic cosine (NaN for x < 1)"),
    ("atanh", ("x",), False, np.arctanh, "inverse hyperbolic tangent (NaN outside [-1, 1])"),
    ("sec", ("x",), False, None, "secant 1/cos(x)"),
    ("csc", ("x",), False, None, "cosecant 1/sin(x)"),
    ("cot", ("x",), False, None, "cotangent 1/tan(x)"),
    ("sinc", ("x",), False, kernels.sinc, "sin(x)/x, 1 where |x| < 2.2e-16"),
    ("deg2grad", ("x",), False, None, "degrees to gradians, x * 10/9"),
    ("grad2deg", ("x",), False, None, "gradians to degrees, x * 9/10"),
    ("mand", ("a",), True, None, "1 where every argument is nonzero, else 0"),
    ("mor", ("a",), True, None, "1 where any argument is nonzero, else 0"),
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

LITERALS: Mapping[str, float] = MappingProxyType({"true": 1.0, "false": 0.0})
"""The boolean literals, as the numbers logic returns."""

_UNSUPPORTED_FUNCTIONS = {
    "swap": "expressions have no references to swap; use a third local: var t := a; a := b; b := t",
    "shl": "write x * 2^n",
    "shr": "write x / 2^n",
}
"""Hints for ExprTk functions fgslice does not have."""

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
    "=": np.equal,
    "!=": np.not_equal,
    "<>": np.not_equal,
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

_ALLOWED = (
    "numbers, names, f(...), ( ), { }, + - * / % ^, < <= > >= == = != <>, and, or, not, ? :, "
    "var t := ..., ';' between statements, if, switch"
)

_STRINGS = "strings are not supported: fgslice's expressions compute numbers"
_VECTORS = "vectors and subscripts are not supported: use one local per value (var a := ...; var b := ...)"

_CHAR_HINTS = {
    '"': _STRINGS,
    "'": _STRINGS,
    "[": _VECTORS,
    "]": _VECTORS,
    ".": "attribute access is not part of the expression language",
    "_": "names start with a letter; names beginning with '_' do not exist",
    "!": "write 'not', or '!=' to compare",
    "~": "write the statements one after the other, separated by ';'",
    "$": "ExprTk's special functions ($f00 ...) are not supported; write the formula",
    "π": "write 'pi'",
    "×": "write '*'",
    "·": "write '*'",
    "÷": "write '/'",
    "−": "write '-' (ASCII minus)",
    "²": "write '^2'",
    "³": "write '^3'",
}

_CHAR_NAMES = {'"': "strings", "'": "strings", "[": "vectors", "]": "vectors"}
"""Characters that open something the language refuses by name."""

_TOKEN_NAMES = {
    "LPAR": "'('",
    "RPAR": "')'",
    "LBRACE": "'{'",
    "RBRACE": "'}'",
    "COMMA": "','",
    "SEMICOLON": "';'",
    "NUMBER": "a number",
    "NAME": "a name",
    "CALLNAME": "a function call",
    "IF": "'if ('",
    "ADDOP": "'+'/'-'",
    "MULOP": "'*'/'/'/'%'",
    "COMPARE": "a comparison",
    "ASSIGN": "':='",
    "UPDATE": "'+='/'-='/'*='/'/='/'%='",
    "CIRCUMFLEX": "'^'",
    "QMARK": "'?'",
    "COLON": "':'",
    "AND": "'and'",
    "NAND": "'nand'",
    "AMPERSAND": "'&'",
    "OR": "'or'",
    "NOR": "'nor'",
    "XOR": "'xor'",
    "XNOR": "'xnor'",
    "VBAR": "'|'",
    "NOT": "'not'",
    "VAR": "'var'",
    "SWITCH": "'switch'",
    "CASE": "'case'",
    "DEFAULT": "'default'",
    "_ELSE": "'else'",
    "$END": "the end of the expression",
}


def _expected(names: set[str]) -> str:
    """``expected a number, a name or '('`` from lark's terminal names."""
    readable = sorted({_TOKEN_NAMES.get(n, n) for n in names})
    if not readable:
        return "the expression cannot continue here"
    if len(readable) > 6:
        if "SEMICOLON" in names:
            return "expected an operator, ';' between statements, ')' or the end of the expression"
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


def _loop_error(src: _Source, token: lark.Token) -> FgsliceError:
    """The refusal of a loop keyword, by name."""
    word = src.text[token.start_pos : token.end_pos]
    if token.value == "return":
        return src.error(
            DesignSyntaxError, "'return' is not supported", token.start_pos,
            "the value of an expression is its last statement: write it last, without 'return'",
        )
    return src.error(
        DesignSyntaxError,
        f"loops are not supported: '{word}'",
        token.start_pos,
        "a field is evaluated at every point at once, without loops: write the result in closed form "
        "(sum(...), mul(...), a formula) or choose with if/switch",
    )


def _syntax_error(src: _Source, exc: lark.exceptions.UnexpectedInput) -> FgsliceError:
    """Turn lark's complaint into a located DesignSyntaxError with a hint."""
    text = src.text
    if isinstance(exc, lark.exceptions.UnexpectedCharacters):
        ch = text[exc.pos_in_stream]
        hint = _CHAR_HINTS.get(ch, f"expressions are made of {_ALLOWED}")
        refused = f" ({_CHAR_NAMES[ch]} are not supported)" if ch in _CHAR_NAMES else ""
        return src.error(DesignSyntaxError, f"unexpected character {ch!r}{refused}", exc.pos_in_stream, hint)
    token = getattr(exc, "token", None)
    expected = set(getattr(exc, "expected", ()) or ())
    if token is None or token.type == "$END":
        if next(iter(_PARSER.lex(text.translate(_LOWER))), None) is None:
            return src.error(DesignSyntaxError, "empty expression (only comments)", 0, "write a value, e.g. 'z/70'")
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
    elif token.type == "MULOP" and value == "*" and text[:offset].endswith("/"):
        what, hint = "'/*'", "this comment is never closed: end it with '*/'"
        offset -= 1
    elif token.type in ("AMPERSAND", "VBAR") and text[:offset].rstrip().endswith(value):
        word = "and" if value == "&" else "or"
        what, hint = f"'{value}'", f"write '{word}' (or a single '{value}')"
    elif token.type in ("ASSIGN", "UPDATE"):
        what, hint = f"'{value}'", "an assignment starts a statement or stands in parentheses: (t := ...)"
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
    [np.add, np.multiply, np.maximum, np.minimum, np.hypot, np.equal, np.not_equal, np.logical_and, np.logical_or,
     np.logical_xor]
)
"""Kernels whose two arguments may be swapped (sorted so ``a*b`` and ``b*a`` are shared)."""

_BOOLEAN = frozenset(
    [np.less, np.less_equal, np.greater, np.greater_equal, np.equal, np.not_equal, np.logical_and, np.logical_or,
     np.logical_xor, _not, _truth]
)
"""Kernels returning booleans: they are given a float64 output so values stay float64."""

_NO_OUT = frozenset([_select, _polar, kernels.sinc, kernels.root, kernels.roundn])
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
    """Walks the parse tree into a hash-consed graph; folds constants.

    Statements run in order at compile time: a local variable is the graph node of its
    current value, so assignments cost nothing at evaluation. Where a statement runs only
    at some points (a branch of a conditional or a switch, the right operand of ``&``,
    ``|``, ``mand``, ``mor``), each local it assigns becomes, after it, a selection between
    its values on both paths. The walk is recursive, one or two Python frames per level,
    and refuses nesting deeper than :data:`MAX_DEPTH`.
    """

    def __init__(self, src: _Source) -> None:
        self.src = src
        self.graph = _Graph()
        self.used: set[str] = set()
        self.d_offset: int | None = None
        self.scopes: list[dict[str, int]] = []
        self.declared: dict[str, int] = {}

    def emit(self, kernel: Callable, args: list[int]) -> int:
        """The node of ``kernel(*args)`` (a ufunc-like callable taking ``out=``)."""
        return self.graph.apply(kernel, args)

    def fold(self, kernels: list[Callable], operands: list[int]) -> int:
        """Left fold: ``((a0 k0 a1) k1 a2) ...`` as a flat run of steps."""
        acc = operands[0]
        for kernel, operand in zip(kernels, operands[1:], strict=True):
            acc = self.emit(kernel, [acc, operand])
        return acc

    def const(self, value: float) -> int:
        return self.graph.const(value)

    # local variables and the paths they are assigned on
    def lookup(self, name: str) -> dict[str, int] | None:
        """The innermost scope declaring ``name``, or None."""
        for scope in reversed(self.scopes):
            if name in scope:
                return scope
        return None

    def snapshot(self) -> list[dict[str, int]]:
        return [dict(scope) for scope in self.scopes]

    def restore(self, state: list[dict[str, int]]) -> None:
        for scope, saved in zip(self.scopes, state, strict=True):
            scope.update(saved)

    def join(self, condition: int, taken: list[dict[str, int]]) -> None:
        """Each local becomes its value in ``taken`` where ``condition`` is nonzero and its
        current value elsewhere."""
        for scope, values in zip(self.scopes, taken, strict=True):
            for name, value in values.items():
                scope[name] = self.choose(condition, value, scope[name])

    def choose(self, condition: int, a: int, b: int) -> int:
        """``a`` where ``condition`` is nonzero (NaN included), else ``b``."""
        if a == b:
            return a
        value = self.graph.const_value(condition)
        if value is not None:
            return a if value != 0.0 else b
        return self.emit(_select, [condition, a, b])

    def conditional(self, condition: int, then: lark.Tree | lark.Token, otherwise, depth: int) -> int:
        """``then`` where ``condition`` is nonzero, else ``otherwise`` (NaN when None)."""
        before = self.snapshot()
        a = self.visit(then, depth)
        taken = self.snapshot()
        self.restore(before)
        b = self.const(math.nan) if otherwise is None else self.visit(otherwise, depth)
        self.join(condition, taken)
        return self.choose(condition, a, b)

    def guarded(self, guard: int, item: lark.Tree | lark.Token, depth: int) -> int:
        """``item``'s value; its assignments take effect only where ``guard`` is nonzero."""
        before = self.snapshot()
        value = self.visit(item, depth)
        taken = self.snapshot()
        self.restore(before)
        self.join(guard, taken)
        return value

    def sequence(self, statements: Sequence, depth: int) -> int:
        """The value of the last statement, the others run first, in a scope of their own."""
        self.scopes.append({})
        value = self.const(math.nan)
        for statement in statements:
            value = self.visit(statement, depth)
        self.scopes.pop()
        return value

    def declare(self, token: lark.Token, value: int) -> int:
        name = token.value
        original = self.src.text[token.start_pos : token.end_pos]
        kind = (
            "a coordinate" if name in VARIABLES
            else "a constant" if name in CONSTANTS or name in LITERALS
            else "a function" if name in FUNCTIONS
            else None
        )
        if kind is not None:
            raise self.src.error(
                DesignError, f"cannot declare '{original}': it is {kind}", token.start_pos,
                "choose another name for the local variable",
            )
        if self.lookup(name) is not None:
            line, column = self.src.position(self.declared[name])
            raise self.src.error(
                DesignError, f"'{original}' is already declared (line {line}, column {column})", token.start_pos,
                f"assign it with {original} := ..., or choose another name",
            )
        self.scopes[-1][name] = value
        self.declared[name] = token.start_pos
        return value

    def assign(self, target: lark.Token, operator: lark.Token, item, depth: int) -> int:
        name = target.value
        original = self.src.text[target.start_pos : target.end_pos]
        scope = self.lookup(name)
        if scope is None:
            if name in VARIABLES:
                message = f"cannot assign to '{original}': the coordinates are read-only"
                hint = f"declare a local variable instead: var t := {original}; then assign t"
            elif name in CONSTANTS or name in LITERALS:
                message, hint = f"cannot assign to the constant '{original}'", "declare a local variable: var t := ..."
            elif name in FUNCTIONS:
                message, hint = f"cannot assign to '{original}': it is a function", "declare a local variable: var t := ..."
            else:
                message = f"cannot assign to '{original}': it is not declared"
                hint = f"declare it first: var {original} := ..."
            raise self.src.error(DesignError, message, target.start_pos, hint)
        value = self.visit(item, depth)
        if operator.type == "UPDATE":
            value = self.emit(_BINARY[operator.value[0]], [scope[name], value])
        scope[name] = value
        return value

    # leaves
    def number(self, token: lark.Token) -> int:
        value = float(token.value)
        if not math.isfinite(value):
            text = self.src.text[token.start_pos : token.end_pos]
            shown = text if len(text) <= 24 else text[:20] + "..."
            raise self.src.error(
                DesignSyntaxError, f"number too large: '{shown}'", token.start_pos, "numbers must be below about 1.8e308"
            )
        return self.const(value)

    def name(self, token: lark.Token) -> int:
        name = token.value
        scope = self.lookup(name)
        if scope is not None:
            return scope[name]
        if name in LITERALS:
            return self.const(LITERALS[name])
        if name in CONSTANTS:
            return self.const(CONSTANTS[name])
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
        known = [*VARIABLES, *CONSTANTS, *(n for scope in self.scopes for n in scope)]
        hint = did_you_mean(name, known) or (
            "variables are " + ", ".join(VARIABLES) + f"; constants pi, e; a local is declared with var {original} := ..."
        )
        raise self.src.error(DesignError, f"unknown variable '{original}'", token.start_pos, hint)

    # operations
    def check_call(self, token: lark.Token, name: str, n: int) -> Function:
        """The function ``name`` called at ``token`` with ``n`` arguments, or a located error."""
        shown = self.src.text[token.start_pos : token.start_pos + len(name)]
        if name not in FUNCTIONS:
            if name in VARIABLES or name in CONSTANTS or name in LITERALS or self.lookup(name) is not None:
                raise self.src.error(
                    DesignError,
                    f"'{shown}' is not a function",
                    token.start_pos,
                    f"write {shown}*(...) to multiply",
                )
            hint = _UNSUPPORTED_FUNCTIONS.get(name) or did_you_mean(name, FUNCTIONS) or "functions are " + ", ".join(FUNCTIONS)
            raise self.src.error(DesignError, f"unknown function '{shown}'", token.start_pos, hint)
        function = FUNCTIONS[name]
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
        return function

    def call(self, name: str, function: Function, args: list[int]) -> int:
        n = len(args)
        composite = _COMPOSITES.get(name)
        if composite is not None:
            return composite(self, *args)
        if name == "avg":
            return self.emit(np.divide, [self.fold([np.add] * (n - 1), args), self.const(float(n))])
        if function.variadic:
            return self.fold([_KERNELS[name]] * (n - 1), args)
        return self.emit(_KERNELS[name], args)

    def logic(self, children: list, depth: int) -> int:
        """``a op b op c ...`` left to right; ``&`` and ``|`` run their right operand's
        assignments only where it is evaluated (left to right short-circuit)."""
        acc = self.visit(children[0], depth)
        for i in range(1, len(children), 2):
            op = children[i].children[0].value
            if op == "&":
                operand = self.guarded(acc, children[i + 1], depth)
            elif op == "|":
                operand = self.guarded(self.emit(_not, [acc]), children[i + 1], depth)
            else:
                operand = self.visit(children[i + 1], depth)
            acc = _LOGIC[op](self, acc, operand)
        return acc

    def short_circuit(self, token: lark.Token, name: str, items: list, depth: int) -> int:
        """``mand``/``mor``: every argument after the first runs its assignments only
        where the result is still undecided."""
        self.check_call(token, name, len(items))
        acc = self.visit(items[0], depth)
        kernel = np.logical_and if name == "mand" else np.logical_or
        for item in items[1:]:
            guard = acc if name == "mand" else self.emit(_not, [acc])
            acc = self.emit(kernel, [acc, self.guarded(guard, item, depth)])
        return self.emit(_truth, [acc]) if len(items) == 1 else acc

    def switch(self, cases: list[lark.Tree], depth: int) -> int:
        """The first case whose condition holds, else the default (NaN without one)."""
        default = None
        branches: list[tuple[int, int, list[dict[str, int]]]] = []
        for case in cases:
            if case.data == "default":
                if default is not None:
                    raise self.src.error(
                        DesignSyntaxError, "a switch has at most one default", case.meta.start_pos,
                        "remove one of the defaults",
                    )
                default = case
        for case in cases:
            if case.data == "case":
                condition = self.visit(case.children[0], depth)
                before = self.snapshot()
                value = self.visit(case.children[1], depth)
                branches.append((condition, value, self.snapshot()))
                self.restore(before)
        result = self.const(math.nan) if default is None else self.visit(default.children[0], depth)
        for condition, value, taken in reversed(branches):
            self.join(condition, taken)
            result = self.choose(condition, value, result)
        return result

    def visit(self, item: lark.Tree | lark.Token, depth: int) -> int:
        """The node of ``item``'s value; statements in it update the locals."""
        if isinstance(item, lark.Token):
            return self.number(item) if item.type == "NUMBER" else self.name(item)
        if depth >= MAX_DEPTH:
            raise self.src.error(
                DesignSyntaxError,
                f"expression nested too deeply (more than {MAX_DEPTH} levels)",
                item.meta.start_pos,
                "split it into simpler expressions",
            )
        kind = item.data
        children = item.children
        deeper = depth + 1
        if kind in ("sum", "product"):
            operands = []
            ops = []
            for c in children:
                if isinstance(c, lark.Token) and c.type in ("ADDOP", "MULOP"):
                    ops.append(_BINARY[c.value])
                else:
                    operands.append(self.visit(c, deeper))
            return self.fold(ops, operands)
        if kind == "call":
            token = children[0]
            name = token.value[:-1].rstrip(" \t\r\n")
            if name in ("mand", "mor"):
                return self.short_circuit(token, name, children[1:], deeper)
            args = []
            for c in children[1:]:
                args.append(self.visit(c, deeper))
            return self.call(name, self.check_call(token, name, len(args)), args)
        if kind == "implicit":
            operands = []
            for c in children:
                operands.append(self.visit(c, deeper))
            return self.fold([np.multiply] * (len(operands) - 1), operands)
        if kind == "power":
            base = self.visit(children[0], deeper)
            return self.emit(np.power, [base, self.visit(children[1], deeper)])
        if kind == "signed":
            minus = sum(1 for c in children if isinstance(c, lark.Token) and c.value == "-")
            operand = self.visit(children[-1], deeper)
            return self.emit(np.negative, [operand]) if minus % 2 else operand
        if kind == "comparison":
            left = self.visit(children[0], deeper)
            return self.emit(_BINARY[children[1].value], [left, self.visit(children[2], deeper)])
        if kind == "not_":
            nots = sum(1 for c in children if isinstance(c, lark.Token) and c.type == "NOT")
            return self.emit(_not if nots % 2 else _truth, [self.visit(children[-1], deeper)])
        if kind == "logic":
            return self.logic(children, deeper)
        if kind == "ternary":
            return self.conditional(self.visit(children[0], deeper), children[1], children[2], deeper)
        if kind == "ifcall":
            self.check_call(children[0], "if", len(children) - 1)
            return self.conditional(self.visit(children[1], deeper), children[2], children[3], deeper)
        if kind == "ifstmt":
            otherwise = children[3] if len(children) > 3 else None
            return self.conditional(self.visit(children[1], deeper), children[2], otherwise, deeper)
        if kind == "switch":
            return self.switch(children, deeper)
        if kind == "block":
            return self.sequence(children, deeper)
        if kind == "assign":
            return self.assign(children[0], children[1], children[2], deeper)
        if kind == "declare":
            value = self.visit(children[2], deeper) if len(children) > 1 else self.const(0.0)
            return self.declare(children[0], value)
        raise AssertionError(f"grammar rule without a compiler: {kind}")

    def compile(self, root: lark.Tree) -> int:
        """The node of the text's value: its statements, at nesting level 0."""
        return self.sequence(root.children, 0)


_EQUAL_EPSILON = 1e-10
"""ExprTk's tolerance of equal/not_equal for doubles, relative to max(1, |x|, |y|)."""


def _tolerance(c: _Compiler, a: int, b: int) -> tuple[int, int]:
    """``|a - b|`` and ``1e-10 * max(1, |a|, |b|)`` (ExprTk's normalised epsilon)."""
    scale = c.emit(np.maximum, [c.const(1.0), c.emit(np.maximum, [c.emit(np.absolute, [a]), c.emit(np.absolute, [b])])])
    return c.emit(np.absolute, [c.emit(np.subtract, [a, b])]), c.emit(np.multiply, [scale, c.const(_EQUAL_EPSILON)])


def _iclamp(c: _Compiler, lo: int, x: int, hi: int) -> int:
    outside = c.emit(np.logical_or, [c.emit(np.less_equal, [x, lo]), c.emit(np.greater_equal, [x, hi])])
    lower = c.emit(np.less_equal, [c.emit(np.multiply, [c.const(2.0), x]), c.emit(np.add, [hi, lo])])
    return c.choose(outside, x, c.choose(lower, lo, hi))


_COMPOSITES: dict[str, Callable[..., int]] = {
    "logn": lambda c, x, n: c.emit(np.divide, [c.emit(np.log, [x]), c.emit(np.log, [n])]),
    "equal": lambda c, a, b: c.emit(np.less_equal, list(_tolerance(c, a, b))),
    "not_equal": lambda c, a, b: c.emit(np.greater, list(_tolerance(c, a, b))),
    "inrange": lambda c, lo, x, hi: c.emit(_not, [c.emit(np.logical_or, [c.emit(np.less, [x, lo]), c.emit(np.greater, [x, hi])])]),
    "iclamp": _iclamp,
    "ncdf": lambda c, x: c.emit(
        np.multiply, [c.const(0.5), c.emit(kernels.erfc, [c.emit(np.negative, [c.emit(np.divide, [x, c.const(math.sqrt(2.0))])])])]
    ),
    "sec": lambda c, x: c.emit(np.divide, [c.const(1.0), c.emit(np.cos, [x])]),
    "csc": lambda c, x: c.emit(np.divide, [c.const(1.0), c.emit(np.sin, [x])]),
    "cot": lambda c, x: c.emit(np.divide, [c.const(1.0), c.emit(np.tan, [x])]),
    "deg2grad": lambda c, x: c.emit(np.multiply, [x, c.const(10.0 / 9.0)]),
    "grad2deg": lambda c, x: c.emit(np.multiply, [x, c.const(9.0 / 10.0)]),
}
"""Functions compiled into operations of the language (ExprTk's definitions)."""

_LOGIC: dict[str, Callable[[_Compiler, int, int], int]] = {
    "and": lambda c, a, b: c.emit(np.logical_and, [a, b]),
    "&": lambda c, a, b: c.emit(np.logical_and, [a, b]),
    "or": lambda c, a, b: c.emit(np.logical_or, [a, b]),
    "|": lambda c, a, b: c.emit(np.logical_or, [a, b]),
    "xor": lambda c, a, b: c.emit(np.logical_xor, [a, b]),
    "nand": lambda c, a, b: c.emit(_not, [c.emit(np.logical_and, [a, b])]),
    "nor": lambda c, a, b: c.emit(_not, [c.emit(np.logical_or, [a, b])]),
    "xnor": lambda c, a, b: c.emit(_not, [c.emit(np.logical_xor, [a, b])]),
}
"""The binary logic operators: 1.0 or 0.0, any nonzero value (NaN included) is true."""


def _deep_paren(text: str) -> int | None:
    """Offset of the first '(' nested deeper than :data:`MAX_DEPTH`, or None."""
    codes = np.frombuffer(text.encode("utf-32-le", "surrogatepass"), dtype=np.uint32)
    depth = np.cumsum((codes == ord("(")).astype(np.int64) - (codes == ord(")")))
    over = np.flatnonzero(depth > MAX_DEPTH)
    return int(over[0]) if over.size else None


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
            numbers that overflow float64, and loops, strings and vectors, refused by name).
        DesignError: an unknown name, a function used as a value, a wrong argument count,
            an assignment to anything but a declared local, a local declared twice.
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
    except _LoopKeyword as loop:
        raise _loop_error(src, loop.token) from None
    compiler = _Compiler(src)
    root = compiler.compile(tree)
    return Expression(
        text, frozenset(compiler.used), src.file, line, column, compiler.graph, root, compiler.d_offset, src.file_lines
    )
