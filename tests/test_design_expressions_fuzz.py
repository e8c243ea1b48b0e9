"""Fuzzing the expression compiler: any text compiles or fails with a design error, fast."""

import numpy as np
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from fgslice.design.expressions import CONSTANTS, FUNCTIONS, MAX_DEPTH, VARIABLES, compile_expression
from fgslice.errors import DesignError, DesignSyntaxError

FUZZ = settings(max_examples=200, deadline=2000, suppress_health_check=[HealthCheck.too_slow])

PX = np.array([-2.0, -0.5, 0.0, 0.5, 3.0])
PY = np.array([1.0, -1.0, 0.0, 2.0, -3.0])
PZ = np.array([0.5, 0.0, 0.0, -1.0, 2.0])
PD = np.array([-1.0, 0.0, 0.25, 1.0, 5.0])

TOKENS = [
    *FUNCTIONS,
    *VARIABLES,
    *CONSTANTS,
    "SIN",
    "Rho",
    "PI",
    "foo",
    "_x",
    "__import__",
    "0",
    "1",
    "2.5",
    ".5",
    "5.",
    "1e3",
    "2.5E-3",
    "1e999",
    "+",
    "-",
    "*",
    "/",
    "%",
    "^",
    "**",
    "<",
    "<=",
    ">",
    ">=",
    "==",
    "!=",
    "=",
    "and",
    "or",
    "not",
    "?",
    ":",
    "(",
    ")",
    ",",
    "[",
    "]",
    ".",
    "'",
    '"',
    "lambda",
    " ",
    "\n",
    "\t",
    "π",
]


def compile_or_design_error(text):
    """Compile ``text``; when it compiles, evaluate it on a few points."""
    try:
        expr = compile_expression(text, file="fuzz.vcad", line=2, column=5)
    except (DesignSyntaxError, DesignError) as err:
        assert err.line is not None and err.line >= 2
        assert err.column is not None and err.column >= 1
        assert err.message and err.format()
        return None
    out = expr(PX, PY, PZ, d=PD)
    assert out.shape == PX.shape and out.dtype == np.float64
    assert expr.variables <= {"x", "y", "z", "rho", "phi", "r", "phis", "d"}
    return out


@FUZZ
@given(st.text(max_size=120))
def test_random_text(text):
    compile_or_design_error(text)


@FUZZ
@given(st.lists(st.sampled_from(TOKENS), max_size=40))
def test_random_token_sequences(tokens):
    compile_or_design_error(" ".join(tokens))


@FUZZ
@given(st.lists(st.sampled_from(TOKENS), max_size=40))
def test_random_token_sequences_without_spaces(tokens):
    compile_or_design_error("".join(tokens))


@settings(max_examples=8, deadline=2000)
@given(st.integers(min_value=1, max_value=10_000), st.sampled_from(["(", "-(", "sin(", "(1+"]))
@example(10_000, "(")
@example(10_000, "sin(")
def test_deep_nesting_compiles_or_is_rejected(depth, opener):
    text = opener * depth + "x" + ")" * depth
    out = compile_or_design_error(text)
    if depth > MAX_DEPTH:
        assert out is None
    elif opener == "(":
        np.testing.assert_array_equal(out, PX)


@settings(max_examples=5, deadline=2000)
@given(st.integers(min_value=1, max_value=10_000))
@example(10_000)
def test_unbalanced_deep_nesting_is_a_syntax_error(depth):
    for text in ("(" * depth + "x", "x" + ")" * depth, "(" * depth):
        try:
            compile_expression(text)
        except DesignSyntaxError:
            continue
        raise AssertionError(f"accepted {text[:20]!r}")


@FUZZ
@given(st.text(alphabet=st.characters(min_codepoint=128), min_size=1, max_size=20), st.sampled_from(["x+", "sin(", ""]))
def test_unicode_is_rejected(junk, prefix):
    try:
        compile_expression(prefix + junk)
    except DesignSyntaxError as err:
        assert "unexpected character" in err.message
    else:
        raise AssertionError("non-ASCII text compiled")


@FUZZ
@given(st.integers(min_value=0, max_value=400), st.integers(min_value=1, max_value=600))
def test_huge_numbers(exponent, digits):
    for text in (f"1e{exponent}", "9" * digits, f"x + 1.5e{exponent}"):
        try:
            out = compile_expression(text)(PX, PY, PZ)
        except DesignSyntaxError as err:
            assert "number too large" in err.message
            assert float(text.split()[-1]) == np.inf
        else:
            assert np.all(np.isfinite(out))


PAYLOADS = [
    "__import__('os').system('true')",
    "x.__class__",
    "().__class__.__bases__[0]",
    "x[0]",
    "sin.__globals__",
    "lambda: 1",
    "exec('1')",
    "open('f')",
    "'a' + 'b'",
    "[x for x in y]",
    "{1: 2}",
    "x if y else z",
    "x;; y",
    "(x, y)",
    "f'{x}'",
    "x @ y",
    "`x`",
    "x := 1",
    "#x",
    "\\x",
]


@FUZZ
@given(st.sampled_from(PAYLOADS), st.sampled_from(["", "x + ", "max(1, ", "1 ? "]), st.sampled_from(["", ")", " + 1"]))
def test_code_outside_the_language_never_compiles(payload, prefix, suffix):
    try:
        compile_expression(prefix + payload + suffix)
    except (DesignSyntaxError, DesignError):
        return
    raise AssertionError(f"compiled {prefix + payload + suffix!r}")


# Random well-formed expressions against a numpy reference: fully parenthesized text.
LEAVES = st.sampled_from(
    [("x", lambda: PX), ("y", lambda: PY), ("z", lambda: PZ), ("2.5", lambda: 2.5), ("pi", lambda: np.pi)]
)
BINARY = [
    ("+", np.add),
    ("-", np.subtract),
    ("*", np.multiply),
    ("/", np.divide),
    ("^", np.power),
    ("<", lambda a, b: np.less(a, b).astype(np.float64)),
]
UNARY = [("sin", np.sin), ("abs", np.abs), ("exp", np.exp), ("sgn", np.sign), ("floor", np.floor)]


def _combine(children):
    binary = st.tuples(st.sampled_from(BINARY), children, children).map(
        lambda t: (f"({t[1][0]}){t[0][0]}({t[2][0]})", lambda: t[0][1](t[1][1](), t[2][1]()))
    )
    unary = st.tuples(st.sampled_from(UNARY), children).map(
        lambda t: (f"{t[0][0]}({t[1][0]})", lambda: t[0][1](t[1][1]()))
    )
    negate = children.map(lambda c: (f"-({c[0]})", lambda: np.negative(c[1]())))
    return st.one_of(binary, unary, negate)


@FUZZ
@given(st.recursive(LEAVES, _combine, max_leaves=12))
def test_random_expressions_match_numpy(case):
    text, reference = case
    with np.errstate(all="ignore"):
        expected = np.broadcast_to(np.asarray(reference(), dtype=np.float64), PX.shape)
    out = compile_expression(text)(PX, PY, PZ)
    np.testing.assert_allclose(out, expected, rtol=1e-12, atol=1e-300, equal_nan=True)
