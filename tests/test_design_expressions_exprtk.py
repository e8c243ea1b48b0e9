"""ExprTk's language as OpenVCAD documents it: statements, locals, if/switch, logic, functions.

Every construct is evaluated against numpy on sample points; the example lines of
OpenVCAD 3's "Math expressions" guide are taken one by one.
"""

import math
import pickle
import textwrap

import numpy as np
import pytest
import scipy.special

import fgslice.design.expressions as expressions
from fgslice.compat.script import load_script
from fgslice.design import parse_design
from fgslice.design.attributes import attribute_fields
from fgslice.design.expressions import LITERALS, combine_expressions, compile_expression
from fgslice.errors import DesignError, DesignSyntaxError

RNG = np.random.default_rng(11)
X = RNG.uniform(-3, 3, 301)
Y = RNG.uniform(-3, 3, 301)
Z = RNG.uniform(-3, 3, 301)
D = RNG.uniform(-2, 2, 301)
RHO = np.hypot(X, Y)
R = np.sqrt(X**2 + Y**2 + Z**2)


def ev(text, x=X, y=Y, z=Z, d=None):
    return compile_expression(text)(x, y, z, d)


def value(text):
    return float(ev(text, 0.0, 0.0, 0.0))


def truth(mask):
    return mask.astype(np.float64)


# -- OpenVCAD 3's guide, line by line ----------------------------------------------------

GUIDE = [
    # coordinate systems
    ("x", lambda: X),
    ("y", lambda: Y),
    ("z", lambda: Z),
    ("rho", lambda: RHO),
    ("phic", lambda: np.arctan2(Y, X)),
    ("r", lambda: R),
    ("theta", lambda: np.arctan2(Y, X)),
    ("phis", lambda: np.arccos(Z / R)),
    ("sqrt(x^2 + y^2)", lambda: RHO),
    ("atan2(y, x)", lambda: np.arctan2(Y, X)),
    ("acos(z / r)", lambda: np.arccos(Z / R)),
    # arithmetic
    ("x + y", lambda: X + Y),
    ("x - y", lambda: X - Y),
    ("x * y", lambda: X * Y),
    ("x / y", lambda: X / Y),
    ("x % y", lambda: np.fmod(X, Y)),
    ("x ^ y", lambda: X**Y),  # NaN for a negative x and a fractional y, in both
    # assignment to a local, and each compound assignment
    ("var t := 0; t := x", lambda: X),
    ("var t := x; t += y", lambda: X + Y),
    ("var t := x; t -= y", lambda: X - Y),
    ("var t := x; t *= y", lambda: X * Y),
    ("var t := x; t /= y", lambda: X / Y),
    ("var t := x; t %= y", lambda: np.fmod(X, Y)),
    # equalities and inequalities
    ("x == y", lambda: truth(X == Y)),
    ("x = y", lambda: truth(X == Y)),
    ("round(x) = round(y)", lambda: truth(np.round(X) == np.round(Y))),
    ("x <> y", lambda: truth(X != Y)),
    ("x != y", lambda: truth(X != Y)),
    ("x < y", lambda: truth(X < Y)),
    ("x <= y", lambda: truth(X <= Y)),
    ("x > y", lambda: truth(X > Y)),
    ("x >= y", lambda: truth(X >= Y)),
    # boolean operations
    ("true", lambda: np.ones_like(X)),
    ("false", lambda: np.zeros_like(X)),
    ("x > 0 and y > 0", lambda: truth((X > 0) & (Y > 0))),
    ("x > 0 or y > 0", lambda: truth((X > 0) | (Y > 0))),
    ("not (x > 0)", lambda: truth(~(X > 0))),
    ("x > 0 xor y > 0", lambda: truth((X > 0) ^ (Y > 0))),
    ("x > 0 nand y > 0", lambda: truth(~((X > 0) & (Y > 0)))),
    ("x > 0 nor y > 0", lambda: truth(~((X > 0) | (Y > 0)))),
    ("mand(x > 0, y > 0, z > 0)", lambda: truth((X > 0) & (Y > 0) & (Z > 0))),
    ("mor(x > 1, y > 1, z > 1)", lambda: truth((X > 1) | (Y > 1) | (Z > 1))),
    # general-purpose functions
    ("abs(x)", lambda: np.abs(X)),
    ("avg(x, y, z)", lambda: (X + Y + Z) / 3),
    ("ceil(x)", lambda: np.ceil(X)),
    ("floor(x)", lambda: np.floor(X)),
    ("sqrt(rho)", lambda: np.sqrt(RHO)),
    ("log(rho)", lambda: np.log(RHO)),
    ("exp(x)", lambda: np.exp(X)),
    ("pow(rho, y)", lambda: RHO**Y),
    ("max(x, y, z)", lambda: np.maximum(np.maximum(X, Y), Z)),
    ("min(x, y, z)", lambda: np.minimum(np.minimum(X, Y), Z)),
    ("clamp(-1, x, 1)", lambda: np.clip(X, -1, 1)),
    # trigonometry
    ("sin(x)", lambda: np.sin(X)),
    ("cos(x)", lambda: np.cos(X)),
    ("tan(x)", lambda: np.tan(X)),
    ("asin(x / 3)", lambda: np.arcsin(X / 3)),
    ("acos(x / 3)", lambda: np.arccos(X / 3)),
    ("atan(x)", lambda: np.arctan(X)),
    ("deg2rad(x)", lambda: np.deg2rad(X)),
    ("rad2deg(x)", lambda: np.rad2deg(X)),
    # constants and literals
    ("pi", lambda: np.full_like(X, np.pi)),
    ("e", lambda: np.full_like(X, np.e)),
    ("3.14159", lambda: np.full_like(X, 3.14159)),
    # tips
    ("(x + y) * z", lambda: (X + Y) * Z),
    ("rho * sin(phis) + z", lambda: RHO * np.sin(np.arccos(Z / R)) + Z),
    ("clamp(0, x / 3, 1)", lambda: np.clip(X / 3, 0, 1)),
]


@pytest.mark.parametrize("text, reference", GUIDE, ids=[t for t, _ in GUIDE])
def test_the_guides_examples_match_numpy(text, reference):
    with np.errstate(invalid="ignore"):
        expected = reference()
    np.testing.assert_allclose(ev(text), expected, rtol=1e-13, atol=1e-14)


def test_the_signed_distance_of_the_guide():
    np.testing.assert_array_equal(ev("d", d=D), D)
    np.testing.assert_allclose(ev("var depth := -d; clamp(0, depth / 2, 1)", d=D), np.clip(-D / 2, 0, 1))


def test_the_guides_assignment_to_a_coordinate_is_refused_with_a_local_as_the_fix():
    with pytest.raises(DesignError) as info:
        compile_expression("y := x", file="part.py", line=7, column=30)
    err = info.value
    assert (err.line, err.column) == (7, 30)
    assert "cannot assign to 'y'" in err.message and "read-only" in err.message
    assert "var t := y" in err.hint


# -- statements and locals ----------------------------------------------------------------


@pytest.mark.parametrize(
    "text, reference",
    [
        ("var a := x; a + 1", lambda: X + 1),
        ("var t := x/3 + 236; clamp(220, t, 256)", lambda: np.clip(X / 3 + 236, 220, 256)),
        ("var a := x; var b := a * y; b - a;", lambda: X * Y - X),
        ("var n; n + x", lambda: X),
        ("var t := 1; t += x; t *= 2; t -= y; t /= 4; t", lambda: ((1 + X) * 2 - Y) / 4),
        ("var t := x; t := t * t; t := t * t; t", lambda: X**4),
        ("var t := x; (t := 2 t) + t", lambda: 4 * X),  # left to right
        ("var a := 1; var b := (a += x); a + b", lambda: 2 * (1 + X)),
        ("var t := x; t", lambda: X),
        ("var t := x", lambda: X),  # a declaration's value is its initial value
        ("x; y; z", lambda: Z),
        ("{ var u := x; u * 2 } + { var u := y; u }", lambda: 2 * X + Y),
        ("{x + 1} * 2", lambda: (X + 1) * 2),
        ("VAR T := X; T += Y; t", lambda: X + Y),
    ],
)
def test_statements_and_locals(text, reference):
    np.testing.assert_allclose(ev(text), reference(), rtol=1e-13, atol=1e-14)


def test_comments_as_in_exprtk():
    text = "var t := x; # the base\n// doubled:\nt * 2 /* twice */ + y"
    np.testing.assert_allclose(ev(text), 2 * X + Y)
    np.testing.assert_allclose(ev("if (x > 0) x; // positive\n /* else */ else -x; # negative"), np.abs(X))
    np.testing.assert_allclose(ev("x // 2"), X)
    np.testing.assert_allclose(ev("x / 2"), X / 2)
    with pytest.raises(DesignSyntaxError) as info:
        located("x + 1 /* never closed")
    assert (info.value.line, info.value.column) == (3, 16) and "'*/'" in info.value.hint
    with pytest.raises(DesignSyntaxError, match="empty expression"):
        compile_expression("# nothing but a comment")


def test_locals_are_graph_nodes_computed_once(monkeypatch):
    calls = []

    def counting(x, out=None):
        calls.append(1)
        return np.sin(x, out=out)

    monkeypatch.setitem(expressions._KERNELS, "sin", counting)
    values = compile_expression("var s := sin(x); s * s + s")(X, Y, Z)
    np.testing.assert_allclose(values, np.sin(X) ** 2 + np.sin(X))
    assert len(calls) == 1


def test_constant_locals_fold_to_a_constant():
    expr = compile_expression("var a := 2; var b := a^3; if (b > 7) b + pi else 0")
    assert expr._program.steps == []
    np.testing.assert_allclose(expr(X, Y, Z), np.full_like(X, 8 + math.pi))


def test_expressions_with_locals_combine_and_pickle():
    first = compile_expression("var s := sin(x) * cos(y); (1 + s) / 2")
    second = compile_expression("var t := sin(x) * cos(y); 1 - (1 + t) / 2")
    a, b = combine_expressions([first, second])(X, Y, Z)
    np.testing.assert_allclose(a + b, np.ones_like(X), rtol=1e-14)
    clone = pickle.loads(pickle.dumps(second))
    np.testing.assert_array_equal(clone(X, Y, Z), b)


# -- conditionals ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    "text, reference",
    [
        ("if (x > 0) 1; else 2;", lambda: np.where(X > 0, 1.0, 2.0)),
        ("if (x > 0) 1 else 2", lambda: np.where(X > 0, 1.0, 2.0)),
        ("if (x > 0) { 1 } else { 2 }", lambda: np.where(X > 0, 1.0, 2.0)),
        ("if (x > 0) x; else if (y > 0) y; else z;", lambda: np.where(X > 0, X, np.where(Y > 0, Y, Z))),
        ("if (x > 0) if (y > 0) 1 else 2 else 3", lambda: np.where(X > 0, np.where(Y > 0, 1.0, 2.0), 3.0)),
        ("1 + if (x > 0) 2 else 3", lambda: np.where(X > 0, 3.0, 4.0)),
        ("if (x > 0) x + 1 else x - 1 ^ 2", lambda: np.where(X > 0, X + 1, X - 1)),  # a branch extends
        ("if (x > 0) { 2 } else { 3 } + 1", lambda: np.where(X > 0, 3.0, 4.0)),  # a block branch ends at '}'
        ("if (x > 0) 2; else { 3 } * 10", lambda: np.where(X > 0, 20.0, 30.0)),
        (
            "if (x > 0) { 2 } else if (x < -1) { 3 } else { 4 } * 10",
            lambda: np.where(X > 0, 20.0, np.where(X < -1, 30.0, 40.0)),
        ),
        ("if(x > 0, x, y)", lambda: np.where(X > 0, X, Y)),
        ("x > 0 ? x : y", lambda: np.where(X > 0, X, Y)),
        ("if (x > 0) { var u := 3; u * x } else 0", lambda: np.where(X > 0, 3 * X, 0.0)),
        (
            "var t := 0; if (x > 0) { t := 5; } else { t := -5; }; t",
            lambda: np.where(X > 0, 5.0, -5.0),
        ),
        (
            "var t := 0; if (x > 1) t := 1; else if (x < -1) t := -1; t",
            lambda: np.where(X > 1, 1.0, np.where(X < -1, -1.0, 0.0)),
        ),
        ("var t := x; if (y > 0) t *= 2; t", lambda: np.where(Y > 0, 2 * X, X)),
        ("var t := x; x > 0 ? (t := 1) : 0; t", lambda: np.where(X > 0, 1.0, X)),
        ("if (true) x else y", lambda: X),
        ("if (false) x else y", lambda: Y),
    ],
)
def test_if_statements_and_conditional_assignments(text, reference):
    np.testing.assert_allclose(ev(text), reference(), rtol=1e-13, atol=1e-14)


def test_an_if_without_else_is_nan_where_false():
    values = ev("if (x > 0) x;")
    np.testing.assert_array_equal(values[X > 0], X[X > 0])
    assert np.isnan(values[X <= 0]).all()


@pytest.mark.parametrize(
    "text, reference",
    [
        ("switch { case x < -1: -1; case x > 1: 1; default: 0; }", lambda: np.select([X < -1, X > 1], [-1.0, 1.0], 0.0)),
        ("switch { case x > 0: 1; case x > 1: 2; default: 3; }", lambda: np.where(X > 0, 1.0, 3.0)),  # first true case
        ("switch { default: x; case y > 0: y; }", lambda: np.where(Y > 0, Y, X)),
        ("switch { case x > 0: { var u := x; u * u }; default: 0; }", lambda: np.where(X > 0, X * X, 0.0)),
        (
            "var t := 0; switch { case x < 0: t := 1; case y < 0: t := 2; default: t := 3; }; t * 10",
            lambda: np.select([X < 0, Y < 0], [10.0, 20.0], 30.0),
        ),
        ("SWITCH { CASE X > 0: 1; DEFAULT: 2; }", lambda: np.where(X > 0, 1.0, 2.0)),
    ],
)
def test_switch_takes_the_first_true_case(text, reference):
    np.testing.assert_allclose(ev(text), reference(), rtol=1e-13, atol=1e-14)


def test_a_switch_without_default_is_nan_where_no_case_holds():
    values = ev("switch { case x > 0: 1; }")
    np.testing.assert_array_equal(values[X > 0], 1.0)
    assert np.isnan(values[X <= 0]).all()


# -- logic -----------------------------------------------------------------------------------------


def test_extended_logic_operators():
    a, b = X > 0, Y > 0
    np.testing.assert_array_equal(ev("x > 0 xnor y > 0"), truth(a == b))
    np.testing.assert_array_equal(ev("x > 0 & y > 0"), truth(a & b))
    np.testing.assert_array_equal(ev("x > 0 | y > 0"), truth(a | b))
    # xor is as loose as or, nand as tight as and
    np.testing.assert_array_equal(ev("x > 0 xor y > 0 and z > 0"), truth(a ^ (b & (Z > 0))))
    np.testing.assert_array_equal(ev("x > 0 or y > 0 nand z > 0"), truth(a | ~(b & (Z > 0))))
    assert value("true and not false") == 1.0
    assert value("mand(1)") == 1.0 and value("mand(0.5, 2)") == 1.0 and value("mor(0, 0, 0)") == 0.0
    assert dict(LITERALS) == {"true": 1.0, "false": 0.0}


def test_logic_treats_nan_as_true_like_exprtk():
    nan = np.array([np.nan])
    for text, expected in [("x xor 1", 0.0), ("x nand 1", 0.0), ("x nor 0", 0.0), ("mand(x, 1)", 1.0), ("mor(x, 0)", 1.0)]:
        assert compile_expression(text)(nan, 0.0, 0.0)[0] == expected, text


def test_short_circuit_operators_assign_only_where_they_evaluate():
    np.testing.assert_array_equal(ev("var t := 0; x > 0 & (t := 3) > 0; t"), np.where(X > 0, 3.0, 0.0))
    np.testing.assert_array_equal(ev("var t := 0; x > 0 | (t := 3) > 0; t"), np.where(X > 0, 0.0, 3.0))
    np.testing.assert_array_equal(ev("var t := 0; mand(x > 0, y > 0, (t := 7)); t"), np.where((X > 0) & (Y > 0), 7.0, 0.0))
    np.testing.assert_array_equal(ev("var t := 0; mor(x > 0, (t := 7)); t"), np.where(X > 0, 0.0, 7.0))
    np.testing.assert_array_equal(ev("var t := 0; x > 0 and (t := 3) > 0; t"), np.full_like(X, 3.0))  # 'and' evaluates both


# -- functions, as ExprTk defines them --------------------------------------------------------------


@pytest.mark.parametrize(
    "text, expected",
    [
        ("roundn(1.2345678, 4)", 1.2346),  # ExprTk's own example
        ("roundn(-1.2345, 3)", -1.235),  # halves away from zero
        ("roundn(2.5, 0)", 3.0),
        ("roundn(1.25, -3)", 1.0),  # n below 0 counts as 0
        ("roundn(1.23456, 2.9)", 1.23),  # n is floored
        ("root(27, 3)", 3.0),
        ("root(-8, 3)", -2.0),  # a real odd root of a negative number
        ("root(16, 4)", 2.0),
        ("logn(8, 2)", 3.0),
        ("log10(1000)", 3.0),
        ("log2(8)", 3.0),
        ("log1p(-1)", -math.inf),
        ("expm1(1e-10)", math.expm1(1e-10)),
        ("sum(1, 2, 3, 4)", 10.0),
        ("mul(1, 2, 3, 4)", 24.0),
        ("mod(-7, 3)", -1.0),
        ("equal(1, 1 + 1e-11)", 1.0),
        ("equal(1e6, 1e6 + 1e-5)", 1.0),  # relative to max(1, |x|, |y|)
        ("equal(1e6, 1e6 + 1e-3)", 0.0),
        ("not_equal(1, 1 + 1e-11)", 0.0),
        ("not_equal(0, 1e-9)", 1.0),
        ("inrange(0, 0, 1)", 1.0),
        ("inrange(0, 1, 1)", 1.0),
        ("inrange(0, 1.5, 1)", 0.0),
        ("iclamp(0, 0.3, 1)", 0.0),
        ("iclamp(0, 0.5, 1)", 0.0),  # the middle goes to lo
        ("iclamp(0, 0.7, 1)", 1.0),
        ("iclamp(0, 1.5, 1)", 1.5),
        ("iclamp(0, -2, 1)", -2.0),
        ("ncdf(0)", 0.5),
        ("ncdf(1.959963984540054)", 0.975),
        ("erfc(0.5)", math.erfc(0.5)),
        ("sinc(0)", 1.0),
        ("sinc(pi / 2)", 2 / math.pi),
        ("sec(0)", 1.0),
        ("csc(pi / 2)", 1.0),
        ("cot(pi / 4)", 1.0),
        ("deg2grad(90)", 100.0),
        ("grad2deg(100)", 90.0),
        ("acosh(1)", 0.0),
        ("atanh(0.5)", math.atanh(0.5)),
        ("asinh(1)", math.asinh(1)),
        ("sinh(1) + cosh(1)", math.e),
        ("tanh(100)", 1.0),
    ],
)
def test_exprtk_functions_hand_values(text, expected):
    assert value(text) == pytest.approx(expected, rel=1e-14, abs=1e-15)


def test_exprtk_functions_nan_cases():
    assert math.isnan(value("root(-8, 2)"))  # even root of a negative number
    assert math.isnan(value("root(-8, 2.5)"))
    assert math.isnan(value("log1p(-2)"))
    nan = np.array([np.nan])
    assert compile_expression("sinc(x)")(nan, 0.0, 0.0)[0] == 1.0  # ExprTk: |NaN| >= eps is false
    assert compile_expression("inrange(0, x, 1)")(nan, 0.0, 0.0)[0] == 1.0  # neither x < lo nor x > hi
    assert compile_expression("equal(x, x)")(nan, 0.0, 0.0)[0] == 0.0


def test_exprtk_functions_on_arrays():
    np.testing.assert_allclose(ev("roundn(x, 1)"), np.sign(X) * np.floor(np.abs(X) * 10 + 0.5) / 10, rtol=1e-15)
    np.testing.assert_allclose(ev("root(x, 5)"), np.sign(X) * np.abs(X) ** 0.2, rtol=1e-14)
    np.testing.assert_allclose(ev("ncdf(x)"), 0.5 * scipy.special.erfc(-X / np.sqrt(2)), rtol=1e-15)
    np.testing.assert_allclose(ev("sinc(x)"), np.sinc(X / np.pi), rtol=1e-14)
    np.testing.assert_array_equal(ev("inrange(y, x, z)"), truth((X >= Y) & (X <= Z)))


# -- refusals --------------------------------------------------------------------------------------

# an expression starting at line 3, column 10 of "design.py"
def located(text):
    return compile_expression(text, file="design.py", line=3, column=10)


@pytest.mark.parametrize(
    "text, line, column, words",
    [
        ("var i := 0;\nwhile (i < 3) { i += 1; }", 4, 1, "loops are not supported: 'while'"),
        ("for (var i := 0; i < 10; i += 1) { x }", 3, 10, "loops are not supported: 'for'"),
        ("var t := 1;\n  repeat t += 1 until (t > 3)", 4, 3, "loops are not supported: 'repeat'"),
        ("x + 1;\n   WHILE(x) { 1 }", 4, 4, "loops are not supported: 'WHILE'"),
        ("if (x > 0) break; x", 3, 21, "loops are not supported: 'break'"),
        ("return [x]", 3, 10, "'return' is not supported"),
        ("'abc' + x", 3, 10, "strings are not supported"),
        ("var v[3] := {1, 2, 3}; v[0]", 3, 15, "vectors are not supported"),
        ("switch { default: 1; default: 2; }", 3, 31, "at most one default"),
        ("var t := 0; if (x > 0) { t := 5; } t", 3, 45, "unexpected name 't'"),
    ],
)
def test_loops_strings_and_vectors_are_refused_by_name_where_they_are(text, line, column, words):
    with pytest.raises(DesignSyntaxError) as info:
        located(text)
    err = info.value
    assert (err.file, err.line, err.column) == ("design.py", line, column)
    assert words in err.message
    assert err.hint and err.source_line is not None
    assert "^" in err.format()


def test_loop_hints_say_how_to_write_it():
    with pytest.raises(DesignSyntaxError) as info:
        compile_expression("while (x > 0) { x }")
    assert "closed form" in info.value.hint and "if/switch" in info.value.hint
    with pytest.raises(DesignSyntaxError) as info:
        compile_expression("var t := 0; if (x > 0) { t := 5; } t")
    assert "';' between statements" in info.value.hint


@pytest.mark.parametrize(
    "text, line, column, words, hint",
    [
        ("var t := 1;\n  y := x; y * 2", 4, 3, "cannot assign to 'y': the coordinates are read-only", "var t := y"),
        ("var t := 1;\n  t += 1; Z *= 2", 4, 11, "cannot assign to 'Z'", "var t := Z"),
        ("rho := 1", 3, 10, "cannot assign to 'rho'", "local"),
        ("d -= 1", 3, 10, "cannot assign to 'd'", "local"),
        ("pi := 3", 3, 10, "cannot assign to the constant 'pi'", "var t"),
        ("true := 0", 3, 10, "cannot assign to the constant 'true'", "var t"),
        ("t := x", 3, 10, "cannot assign to 't': it is not declared", "var t := ..."),
        ("var x := 1", 3, 14, "cannot declare 'x': it is a coordinate", "another name"),
        ("var sin := 1", 3, 14, "cannot declare 'sin': it is a function", "another name"),
        ("var t := 1; var t := 2", 3, 26, "'t' is already declared (line 3, column 14)", "t := ..."),
        ("var t := 1; { var t := 2 }", 3, 28, "'t' is already declared", "another name"),
        ("var t := t + 1", 3, 19, "unknown variable 't'", "var t := ..."),
        ("{ var u := 1 }; u", 3, 26, "unknown variable 'u'", "var u := ..."),
        ("swap(x, y)", 3, 10, "unknown function 'swap'", "third local"),
        ("if (x > 0, 1)", 3, 10, "if takes 3 arguments (c, a, b), got 2", "if(c, a, b)"),
        ("mand()", 3, 10, "mand takes at least 1 argument", "mand(a, ...)"),
        ("roundn(x)", 3, 10, "roundn takes 2 arguments (x, n), got 1", "roundn(x, n)"),
    ],
)
def test_assignments_and_declarations_are_checked_where_they_are(text, line, column, words, hint):
    with pytest.raises(DesignError) as info:
        located(text)
    err = info.value
    assert (err.file, err.line, err.column) == ("design.py", line, column)
    assert words in err.message
    assert hint in err.hint


def test_limits_still_hold_inside_blocks_and_statements():
    with pytest.raises(DesignSyntaxError, match="nested too deeply"):
        compile_expression("{" * 250 + "x" + "}" * 250)
    with pytest.raises(DesignSyntaxError, match="too long"):
        compile_expression("var t := 1; " + "t += 1; " * 20_000)
    assert value("var t := 0; " + "t += 1; " * 2000 + "t") == 2000.0
    assert value("if (1) " * 150 + "7" + " else 0" * 150) == 7.0


def test_multi_statement_text_is_never_evaluated_as_python(monkeypatch):
    import builtins

    def forbidden(*args, **kwargs):
        raise AssertionError("eval/exec called")

    monkeypatch.setattr(builtins, "eval", forbidden)
    monkeypatch.setattr(builtins, "exec", forbidden)
    expr = compile_expression("var t := rho; switch { case t > 1: 1; default: t; }")
    np.testing.assert_allclose(expr(X, Y, Z), np.where(RHO > 1, 1.0, RHO))


# -- in designs ------------------------------------------------------------------------------------


def test_a_vcad_fgrade_with_statements():
    design = parse_design(
        'fgrade(["var t := clamp(0, (x + 10) / 20, 1); t", "var t := clamp(0, (x + 10) / 20, 1); 1 - t"],'
        ' ["blue", "yellow"]) { sphere(12); }',
        file="part.vcad",
    )
    x = np.array([-10.0, -5.0, 0.0, 5.0, 10.0])
    fractions = design.fractions(x, 0 * x, 0 * x)
    np.testing.assert_allclose(fractions[:, 0], (x + 10) / 20, atol=1e-12)
    np.testing.assert_allclose(fractions.sum(axis=1), 1.0)


def test_an_openvcad3_script_with_exprtk_expressions_gives_its_field(tmp_path):
    script = tmp_path / "design.py"
    script.write_text(textwrap.dedent('''\
        import pyvcad as pv

        bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(120, 10, 10))
        bar.set_attribute(pv.DefaultAttributes.TEMPERATURE,
                          pv.FloatAttribute("var t := x/3 + 236; clamp(220, t, 256)"))
        bar.set_attribute(pv.DefaultAttributes.DENSITY, pv.FloatAttribute(
            "switch { case x < -20: 0.2; case x > 20: 0.8; default: 0.5 + x / 100; }"))
        bar.set_attribute(pv.DefaultAttributes.MODULUS, pv.FloatAttribute(
            "var s := 0; if (x > 0) s := roundn(x / 7, 1); else s := -1; s"))
        root = bar
    '''))
    design = load_script(script)
    fields = attribute_fields(design)
    x = np.array([-60.0, -45.0, -10.0, 0.0, 12.0, 45.0, 60.0])
    zero = 0 * x
    np.testing.assert_allclose(fields.values("temperature", x, zero, zero), np.clip(x / 3 + 236, 220, 256))
    np.testing.assert_allclose(fields.values("density", x, zero, zero), np.select([x < -20, x > 20], [0.2, 0.8], 0.5 + x / 100))
    modulus = np.where(x > 0, np.sign(x) * np.floor(np.abs(x / 7) * 10 + 0.5) / 10, -1.0)
    np.testing.assert_allclose(fields.values("modulus", x, zero, zero), modulus)


def test_an_openvcad3_script_with_a_loop_fails_at_its_line(tmp_path):
    script = tmp_path / "design.py"
    script.write_text(
        "import pyvcad as pv\n"
        "bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(20, 10, 10))\n"
        'bar.set_attribute(pv.DefaultAttributes.TEMPERATURE, pv.FloatAttribute("var t := 0; while (t < x) t += 1; t"))\n'
        "root = bar\n"
    )
    with pytest.raises(DesignSyntaxError) as info:
        load_script(script)
    assert info.value.line == 3 and "loops are not supported: 'while'" in info.value.message


# -- fuzzing the statement syntax ----------------------------------------------------------------------

from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

STATEMENT_TOKENS = [
    "var", "t", "u", "x", "y", "d", "pi", "true", "false", "1", "2.5", ":=", "+=", "-=", "*=", "/=", "%=", ";",
    "if", "if (", "else", "; else", "switch", "case", "default", ":", "?", "{", "}", "(", ")", ",", "+", "-", "*",
    "^", "=", "==", "<>", "!=", "<", "and", "or", "xor", "nand", "nor", "xnor", "&", "|", "&&", "not", "mand(",
    "mor(", "roundn(", "sum(", "sin(", "while", "for", "repeat", "until", "return", "[", "]", "'", "~", "\n",
]
PX = np.array([-2.0, -0.5, 0.0, 0.5, 3.0])


@settings(max_examples=300, deadline=2000, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.sampled_from(STATEMENT_TOKENS), max_size=30))
def test_random_statement_token_sequences_compile_or_fail_located(tokens):
    text = " ".join(tokens)
    try:
        expr = compile_expression(text, file="fuzz.py", line=2, column=5)
    except (DesignSyntaxError, DesignError) as err:
        assert err.line is not None and err.line >= 2 and err.column is not None and err.column >= 1
        assert err.message and err.hint and err.format()
        return
    out = expr(PX, PX, PX, d=PX)
    assert out.shape == PX.shape and out.dtype == np.float64
