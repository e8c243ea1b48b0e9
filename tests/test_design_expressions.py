"""The expression language: values against numpy, precedence, names, shapes, errors."""

import builtins
import math
import pickle

import numpy as np
import pytest
import scipy.special

import fgslice.design.expressions as expressions
from fgslice.design.expressions import CONSTANTS, FUNCTIONS, VARIABLES, combine_expressions, compile_expression
from fgslice.errors import DesignError, DesignSyntaxError, FieldError

RNG = np.random.default_rng(7)
X = RNG.uniform(-3, 3, 257)
Y = RNG.uniform(-3, 3, 257)
Z = RNG.uniform(-3, 3, 257)


def ev(text, x=X, y=Y, z=Z, d=None):
    return compile_expression(text)(x, y, z, d)


def value(text):
    """The value of a constant expression (evaluated on a 1-point grid)."""
    return float(ev(text, 0.0, 0.0, 0.0))


# -- operators, precedence, associativity ------------------------------------------------


@pytest.mark.parametrize(
    "text, expected",
    [
        ("7 + 2", 9.0),
        ("7 - 2", 5.0),
        ("7 * 2", 14.0),
        ("7 / 2", 3.5),
        ("7 % 3", 1.0),
        ("-7 % 3", -1.0),  # fmod: sign of the dividend
        ("7.5 % 2", 1.5),
        ("2 ^ 10", 1024.0),
        ("2 ^ 3 ^ 2", 512.0),  # right-associative
        ("-2 ^ 2", -4.0),  # unary minus looser than ^
        ("2 ^ -1", 0.5),
        ("2 ^ -1 ^ 2", 0.5),  # 2^(-(1^2))
        ("(-2) ^ 2", 4.0),
        ("1 + 2 * 3", 7.0),
        ("(1 + 2) * 3", 9.0),
        ("8 / 4 / 2", 1.0),  # left-associative
        ("8 - 4 - 2", 2.0),
        ("2 * 3 ^ 2", 18.0),
        ("--3", 3.0),
        ("-+-3", 3.0),
        ("3 - -2", 5.0),
        ("2 * -3", -6.0),
        ("-3 * 2 + 10", 4.0),
        ("1 < 2", 1.0),
        ("2 < 1", 0.0),
        ("2 <= 2", 1.0),
        ("3 > 2", 1.0),
        ("2 >= 3", 0.0),
        ("2 == 2", 1.0),
        ("2 != 2", 0.0),
        ("1 + 1 == 2", 1.0),  # arithmetic binds tighter than comparison
        ("1 and 0", 0.0),
        ("2 and 3", 1.0),
        ("0 or 0", 0.0),
        ("0 or -1", 1.0),
        ("not 0", 1.0),
        ("not 5", 0.0),
        ("not not 5", 1.0),
        ("not 1 < 0", 1.0),  # not (1 < 0)
        ("1 or 1 and 0", 1.0),  # and binds tighter than or
        ("0 and 1 or 1", 1.0),
        ("1 ? 2 : 3", 2.0),
        ("0 ? 2 : 3", 3.0),
        ("0 ? 1 : 0 ? 2 : 3", 3.0),  # right-associative ternary
        ("1 ? 0 ? 5 : 6 : 7", 6.0),
        ("1 < 2 ? 10 : 20", 10.0),
        ("1 or 0 ? 4 : 5", 4.0),  # ?: is the loosest
        ("if(1, 2, 3)", 2.0),
        ("if(0, 2, 3)", 3.0),
        ("pi", math.pi),
        ("e", math.e),
        ("2 pi", 2 * math.pi),
        ("2pi", 2 * math.pi),
        ("2(3)", 6.0),
        ("2(3)(4)", 24.0),
        ("(1+1)(2+1)", 6.0),
        ("-4.5(2-4)", 9.0),
    ],
)
def test_operator_values(text, expected):
    assert value(text) == pytest.approx(expected, rel=1e-15, abs=0)


@pytest.mark.parametrize(
    "text, reference",
    [
        ("2x", lambda: 2 * X),
        ("2 x", lambda: 2 * X),
        ("2x^2", lambda: 2 * X**2),
        ("x y", lambda: X * Y),
        ("x y z", lambda: X * Y * Z),
        ("2 pi rho", lambda: 2 * np.pi * np.hypot(X, Y)),
        ("(x+1)(y+1)", lambda: (X + 1) * (Y + 1)),
        ("-4.5(rho-4)", lambda: -4.5 * (np.hypot(X, Y) - 4)),
        ("3 sin(x)", lambda: 3 * np.sin(X)),
        ("(y+1) x", lambda: X * (Y + 1)),
        ("x^2 y", lambda: X**2 * Y),
        ("2^x y", lambda: 2.0**X * Y),
    ],
)
def test_implicit_multiplication(text, reference):
    np.testing.assert_allclose(ev(text), reference(), rtol=1e-14, atol=1e-14)


def test_implicit_product_binds_tighter_than_division_and_looser_than_power():
    np.testing.assert_allclose(ev("x/2y"), X / (2 * Y), rtol=1e-14)
    np.testing.assert_allclose(ev("1/2x^2"), 1 / (2 * X**2), rtol=1e-14)
    np.testing.assert_allclose(ev("-2x"), -2 * X, rtol=1e-14)


def test_arithmetic_on_arrays_matches_numpy():
    np.testing.assert_allclose(ev("x + y * z - x / y"), X + Y * Z - X / Y, rtol=1e-14)
    np.testing.assert_allclose(ev("x % 0.7"), np.fmod(X, 0.7), rtol=1e-14)
    np.testing.assert_allclose(ev("abs(x) ^ y"), np.abs(X) ** Y, rtol=1e-14)
    np.testing.assert_array_equal(ev("x < y"), (X < Y).astype(float))
    np.testing.assert_array_equal(ev("x > 0 and y > 0"), ((X > 0) & (Y > 0)).astype(float))
    np.testing.assert_array_equal(ev("x > 0 or y > 0"), ((X > 0) | (Y > 0)).astype(float))
    np.testing.assert_array_equal(ev("x > 0 ? y : z"), np.where(X > 0, Y, Z))
    np.testing.assert_array_equal(ev("if(x > 0, y, 1)"), np.where(X > 0, Y, 1.0))
    np.testing.assert_array_equal(ev("not x > 0"), (X <= 0).astype(float))


def test_operands_are_never_modified_in_place():
    x, y, z = X.copy(), Y.copy(), Z.copy()
    compile_expression("x*2 + y*3 - sin(z) + x")(x, y, z)
    np.testing.assert_array_equal(x, X)
    np.testing.assert_array_equal(y, Y)
    np.testing.assert_array_equal(z, Z)
    out = compile_expression("x")(x, y, z)
    out[:] = 0.0
    np.testing.assert_array_equal(x, X)


# -- functions -------------------------------------------------------------------------------

A = np.abs(X) + 0.1
U = np.clip(X / 3.5, -1, 1)

FUNCTION_CASES = {
    "abs": ("abs(x)", lambda: np.abs(X)),
    "avg": ("avg(x, y, z)", lambda: (X + Y + Z) / 3),
    "ceil": ("ceil(x)", lambda: np.ceil(X)),
    "floor": ("floor(x)", lambda: np.floor(X)),
    "sqrt": ("sqrt(abs(x) + 0.1)", lambda: np.sqrt(A)),
    "log": ("log(abs(x) + 0.1)", lambda: np.log(A)),
    "exp": ("exp(x)", lambda: np.exp(X)),
    "pow": ("pow(abs(x) + 0.1, y)", lambda: A**Y),
    "max": ("max(x, y, z, 0.5)", lambda: np.maximum.reduce([X, Y, Z, np.full_like(X, 0.5)])),
    "min": ("min(x, y)", lambda: np.minimum(X, Y)),
    "clamp": ("clamp(-1, x, 1.5)", lambda: np.clip(X, -1, 1.5)),
    "sin": ("sin(x)", lambda: np.sin(X)),
    "cos": ("cos(x)", lambda: np.cos(X)),
    "tan": ("tan(x)", lambda: np.tan(X)),
    "asin": ("asin(x / 3.5)", lambda: np.arcsin(X / 3.5)),
    "acos": ("acos(x / 3.5)", lambda: np.arccos(X / 3.5)),
    "atan": ("atan(x)", lambda: np.arctan(X)),
    "atan2": ("atan2(y, x)", lambda: np.arctan2(Y, X)),
    "hypot": ("hypot(x, y)", lambda: np.hypot(X, Y)),
    "sgn": ("sgn(x)", lambda: np.sign(X)),
    "frac": ("frac(x)", lambda: X - np.trunc(X)),
    "round": ("round(x)", lambda: np.sign(X) * np.floor(np.abs(X) + 0.5)),
    "trunc": ("trunc(x)", lambda: np.trunc(X)),
    "deg2rad": ("deg2rad(x * 60)", lambda: X * 60 * np.pi / 180),
    "rad2deg": ("rad2deg(x)", lambda: X * 180 / np.pi),
    "erf": ("erf(x)", lambda: scipy.special.erf(X)),
    "if": ("if(x - y, x, z)", lambda: np.where(X != Y, X, Z)),
    "log10": ("log10(abs(x) + 0.1)", lambda: np.log10(A)),
    "log2": ("log2(abs(x) + 0.1)", lambda: np.log2(A)),
    "logn": ("logn(abs(x) + 0.1, 3)", lambda: np.log(A) / np.log(3)),
    "log1p": ("log1p(abs(x))", lambda: np.log1p(np.abs(X))),
    "expm1": ("expm1(x)", lambda: np.expm1(X)),
    "root": ("root(x, 3)", lambda: np.cbrt(X)),
    "roundn": ("roundn(x, 2)", lambda: np.sign(X) * np.floor(np.abs(X) * 100 + 0.5) / 100),
    "sum": ("sum(x, y, z)", lambda: X + Y + Z),
    "mul": ("mul(x, y, z)", lambda: X * Y * Z),
    "mod": ("mod(x, 0.7)", lambda: np.fmod(X, 0.7)),
    "equal": ("equal(x, x + 1e-11 * y)", lambda: (np.abs(1e-11 * Y) <= 1e-10 * np.maximum(1, np.abs(X))).astype(float)),
    "not_equal": ("not_equal(x, x + 1e-10 * y)", lambda: (np.abs(1e-10 * Y) > 1e-10 * np.maximum(1, np.abs(X))).astype(float)),
    "inrange": ("inrange(-1, x, 1.5)", lambda: ((X >= -1) & (X <= 1.5)).astype(float)),
    "iclamp": ("iclamp(-1, x, 1.5)", lambda: np.where((X <= -1) | (X >= 1.5), X, np.where(X <= 0.25, -1.0, 1.5))),
    "erfc": ("erfc(x)", lambda: scipy.special.erfc(X)),
    "ncdf": ("ncdf(x)", lambda: scipy.special.ndtr(X)),
    "sinh": ("sinh(x)", lambda: np.sinh(X)),
    "cosh": ("cosh(x)", lambda: np.cosh(X)),
    "tanh": ("tanh(x)", lambda: np.tanh(X)),
    "asinh": ("asinh(x)", lambda: np.arcsinh(X)),
    "acosh": ("acosh(abs(x) + 1)", lambda: np.arccosh(np.abs(X) + 1)),
    "atanh": ("atanh(x / 3.5)", lambda: np.arctanh(X / 3.5)),
    "sec": ("sec(x)", lambda: 1 / np.cos(X)),
    "csc": ("csc(x)", lambda: 1 / np.sin(X)),
    "cot": ("cot(x)", lambda: 1 / np.tan(X)),
    "sinc": ("sinc(x)", lambda: np.sin(X) / X),
    "deg2grad": ("deg2grad(x)", lambda: X * 400 / 360),
    "grad2deg": ("grad2deg(x)", lambda: X * 360 / 400),
    "mand": ("mand(x > 0, y > 0, z > 0)", lambda: ((X > 0) & (Y > 0) & (Z > 0)).astype(float)),
    "mor": ("mor(x > 1, y > 1)", lambda: ((X > 1) | (Y > 1)).astype(float)),
}


def test_every_function_is_tested():
    assert set(FUNCTION_CASES) == set(FUNCTIONS)


@pytest.mark.parametrize("name", sorted(FUNCTION_CASES))
def test_function_matches_numpy(name):
    text, reference = FUNCTION_CASES[name]
    np.testing.assert_allclose(ev(text), reference(), rtol=1e-13, atol=1e-15)


@pytest.mark.parametrize(
    "text, expected",
    [
        ("round(2.5)", 3.0),
        ("round(-2.5)", -3.0),
        ("round(0.49999)", 0.0),
        ("frac(-2.75)", -0.75),
        ("frac(2.75)", 0.75),
        ("trunc(-2.7)", -2.0),
        ("sgn(-3)", -1.0),
        ("sgn(0)", 0.0),
        ("clamp(0, 5, 1)", 1.0),
        ("clamp(0, -5, 1)", 0.0),
        ("max(3)", 3.0),
        ("min(3, 1, 2)", 1.0),
        ("avg(1, 2, 3, 4)", 2.5),
        ("pow(2, 0.5)", math.sqrt(2)),
        ("atan2(1, -1)", 3 * math.pi / 4),
        ("hypot(3, 4)", 5.0),
        ("deg2rad(180)", math.pi),
        ("rad2deg(pi)", 180.0),
        ("erf(0.5)", math.erf(0.5)),
        ("log(e)", 1.0),
        ("exp(0)", 1.0),
        ("ceil(-1.5)", -1.0),
        ("floor(-1.5)", -2.0),
        ("asin(1)", math.pi / 2),
        ("acos(-1)", math.pi),
    ],
)
def test_function_hand_values(text, expected):
    assert value(text) == pytest.approx(expected, rel=1e-15, abs=1e-15)


def test_variadic_functions_mix_constants_and_arrays():
    np.testing.assert_allclose(ev("max(1, x)"), np.maximum(1, X))
    np.testing.assert_allclose(ev("avg(x)"), X)
    np.testing.assert_allclose(ev("min(x, 0, y)"), np.minimum(np.minimum(X, 0), Y))


# -- variables ---------------------------------------------------------------------------------


def test_variables_match_their_definitions():
    np.testing.assert_array_equal(ev("x"), X)
    np.testing.assert_array_equal(ev("y"), Y)
    np.testing.assert_array_equal(ev("z"), Z)
    np.testing.assert_allclose(ev("rho"), np.sqrt(X**2 + Y**2), rtol=1e-15)
    np.testing.assert_allclose(ev("phi"), np.arctan2(Y, X), rtol=1e-15)
    np.testing.assert_allclose(ev("r"), np.sqrt(X**2 + Y**2 + Z**2), rtol=1e-15)
    np.testing.assert_allclose(ev("phis"), np.arccos(Z / np.sqrt(X**2 + Y**2 + Z**2)), rtol=1e-13)
    np.testing.assert_array_equal(ev("phic"), ev("phi"))
    np.testing.assert_array_equal(ev("theta"), ev("phi"))
    d = RNG.normal(size=X.shape)
    np.testing.assert_array_equal(ev("d", d=d), d)


def test_phi_range_is_half_open_and_phis_is_zero_at_origin():
    x = np.array([-1.0, -1.0, -0.0, 0.0, 0.0, 1.0, -1.0])
    y = np.array([0.0, -0.0, -0.0, 0.0, -1.0, 0.0, -1e-300])
    phi = ev("phi", x, y, 0.0)
    assert np.all(phi > -np.pi) and np.all(phi <= np.pi)
    assert phi[0] == np.pi and phi[1] == np.pi and phi[6] == np.pi
    assert phi[4] == -np.pi / 2 and phi[5] == 0.0
    phis = ev("phis", np.array([0.0, 0.0, 0.0, 1.0]), 0.0, np.array([0.0, 2.0, -2.0, 0.0]))
    np.testing.assert_allclose(phis, [0.0, 0.0, np.pi, np.pi / 2])


def test_variables_reports_canonical_names_used():
    assert compile_expression("x + RHO").variables == frozenset({"x", "rho"})
    assert compile_expression("theta + phic").variables == frozenset({"phi"})
    assert compile_expression("phis * 2 pi").variables == frozenset({"phis"})
    assert compile_expression("1 + pi").variables == frozenset()
    assert compile_expression("d < 0 ? 1 : 0").variables == frozenset({"d"})


def test_derived_variables_are_computed_only_when_used(monkeypatch):
    def forbidden(*args, **kwargs):
        raise AssertionError("derived variable computed")

    monkeypatch.setattr(np, "hypot", forbidden)
    monkeypatch.setattr(np, "arctan2", forbidden)
    monkeypatch.setattr(np, "arccos", forbidden)
    expr_xyz = compile_expression("x + y * z")
    expr_rho = compile_expression("rho")
    np.testing.assert_allclose(expr_xyz(X, Y, Z), X + Y * Z)
    with pytest.raises(AssertionError, match="derived"):
        expr_rho(X, Y, Z)


def test_names_are_case_insensitive():
    np.testing.assert_allclose(ev("SIN(X) + Cos(y) * RHO - PI + E"), ev("sin(x) + cos(y) * rho - pi + e"))
    assert value("1 AND 0 Or NOT 0") == 1.0
    assert value("IF(1, 2, 3)") == 2.0
    assert compile_expression("PhIs + THETA").variables == frozenset({"phis", "phi"})


@pytest.mark.parametrize(
    "text, expected",
    [("5", 5.0), (".5", 0.5), ("5.", 5.0), ("1e1", 10.0), ("2.5E-3", 0.0025), ("1E+2", 100.0), ("007", 7.0)],
)
def test_number_forms(text, expected):
    assert value(text) == expected


def test_vocabulary_exports():
    assert {"x", "y", "z", "rho", "phi", "phic", "theta", "r", "phis", "d"} == set(VARIABLES)
    assert set(CONSTANTS) == {"pi", "e"}
    assert FUNCTIONS["clamp"].signature == "clamp(lo, x, hi)"
    assert FUNCTIONS["max"].variadic and not FUNCTIONS["atan2"].variadic


# -- shapes and blocks ------------------------------------------------------------------------


def test_result_has_the_broadcast_shape():
    xs = np.linspace(-1, 1, 5)[:, None]
    ys = np.linspace(-2, 2, 4)[None, :]
    out = compile_expression("x + 2y")(xs, ys, 0.0)
    assert out.shape == (5, 4)
    np.testing.assert_allclose(out, xs + 2 * ys)
    const = compile_expression("2 + 3")(xs, ys, 0.0)
    assert const.shape == (5, 4) and np.all(const == 5.0)
    assert compile_expression("x")(1.0, 2.0, 3.0).shape == ()
    assert compile_expression("x + d")(np.zeros(3), 0, 0, d=np.ones((2, 1))).shape == (2, 3)
    assert compile_expression("z")(np.zeros(0), 0, 0).shape == (0,)
    ints = compile_expression("x / 2")(np.arange(4), 0, 0)
    assert ints.dtype == np.float64 and ints[1] == 0.5


def test_large_arrays_evaluated_in_blocks_match_numpy():
    n = 3 * expressions._BLOCK + 17
    x = np.linspace(-100, 100, n)
    y = np.cos(x)
    text = "(1+sin(0.025*x+0.0375*y)*cos(0.0375*x-0.025*y))/2 + rho - x"
    reference = (1 + np.sin(0.025 * x + 0.0375 * y) * np.cos(0.0375 * x - 0.025 * y)) / 2 + np.hypot(x, y) - x
    np.testing.assert_allclose(compile_expression(text)(x, y, 0.0), reference, rtol=1e-12, atol=1e-12)
    gx = np.linspace(-5, 5, 700)[:, None]
    gy = np.linspace(-5, 5, 300)[None, :]
    grid = compile_expression("phi + 0.5 z")(gx, gy, 2.0)
    np.testing.assert_allclose(grid, np.arctan2(np.broadcast_to(gy, grid.shape), gx) + 1.0, rtol=1e-14)


def test_group_computes_shared_subexpressions_once(monkeypatch):
    calls = {"sin": 0, "cos": 0}

    def counting(name, kernel):
        def run(*args, **kwargs):
            calls[name] += 1
            return kernel(*args, **kwargs)

        return run

    monkeypatch.setitem(expressions._KERNELS, "sin", counting("sin", np.sin))
    monkeypatch.setitem(expressions._KERNELS, "cos", counting("cos", np.cos))
    field = "(1+sin(0.025*x+0.0375*y)*cos(0.0375*x-0.025*y))/2"
    first = compile_expression(field)
    second = compile_expression(f"1-({field})")
    swapped = compile_expression("(cos(x*0.0375-y*0.025)*sin(y*0.0375+0.025*x)+1)/2")
    group = combine_expressions([first, second, swapped])
    x, y = RNG.uniform(-100, 100, (2, 1000))
    a, b, c = group(x, y, 0.0)
    assert calls == {"sin": 1, "cos": 1}
    reference = (1 + np.sin(0.025 * x + 0.0375 * y) * np.cos(0.0375 * x - 0.025 * y)) / 2
    np.testing.assert_allclose(a, reference, rtol=1e-14)
    np.testing.assert_allclose(b, 1 - reference, rtol=1e-14)
    np.testing.assert_allclose(c, reference, rtol=1e-14)
    assert not np.shares_memory(a, c)
    assert group.variables == frozenset({"x", "y"})


def test_group_members_keep_their_values_and_errors():
    group = combine_expressions([compile_expression("rho"), compile_expression("x"), compile_expression("2"), compile_expression("d + rho")])
    values = group(X, Y, Z, d=np.ones_like(X))
    np.testing.assert_allclose(values[0], np.hypot(X, Y))
    np.testing.assert_array_equal(values[1], X)
    assert not np.shares_memory(values[1], X)
    np.testing.assert_array_equal(values[2], np.full_like(X, 2.0))
    np.testing.assert_allclose(values[3], np.hypot(X, Y) + 1)
    with pytest.raises(DesignError, match="'d'"):
        group(X, Y, Z)
    clone = pickle.loads(pickle.dumps(group))
    np.testing.assert_allclose(clone(X, Y, Z, d=0.0)[3], np.hypot(X, Y))


def test_broadcast_inputs_stay_small_until_combined(monkeypatch):
    seen = []

    def recording(x, out=None):
        seen.append(np.shape(x))
        return np.sin(x, out=out)

    monkeypatch.setitem(expressions._KERNELS, "sin", recording)
    xs = np.linspace(-50, 50, 300)[None, :]
    ys = np.linspace(-50, 50, 500)[:, None]
    values = compile_expression("sin(0.1*x) * cos(y) + z")(xs, ys, 2.0)
    assert seen and all(shape == (1, 300) for shape in seen)
    np.testing.assert_allclose(values, np.sin(0.1 * xs) * np.cos(ys) + 2.0, rtol=1e-14)
    assert values.shape == (500, 300)


def test_expression_survives_pickling():
    expr = compile_expression("rho^2 + d", file="part.vcad", line=4, column=7)
    clone = pickle.loads(pickle.dumps(expr))
    assert clone.text == expr.text and clone.variables == expr.variables
    assert (clone.file, clone.line, clone.column) == ("part.vcad", 4, 7)
    np.testing.assert_array_equal(clone(X, Y, Z, d=Z), expr(X, Y, Z, d=Z))


def test_nothing_is_passed_to_eval_or_exec(monkeypatch):
    def forbidden(*args, **kwargs):
        raise AssertionError("eval/exec called")

    monkeypatch.setattr(builtins, "eval", forbidden)
    monkeypatch.setattr(builtins, "exec", forbidden)
    expr = compile_expression("max(x, y) ? clamp(0, rho/2, 1) : -2^phis")
    assert expr(X, Y, Z).shape == X.shape


# -- errors -------------------------------------------------------------------------------------

# A multi-line expression whose text starts at line 3, column 10 of "design.vcad".
MULTI = "(1 + sin(0.025*x +\n    0.0375*y) *\n  cos(0.0375*x - 0.025*{bad}))/2"


def located(text):
    return compile_expression(text, file="design.vcad", line=3, column=10)


def test_unknown_variable_on_a_later_line():
    with pytest.raises(DesignError) as info:
        located(MULTI.format(bad="yy"))
    err = info.value
    assert type(err) is DesignError
    assert (err.file, err.line, err.column) == ("design.vcad", 5, 24)
    assert "unknown variable 'yy'" in err.message and err.hint == "did you mean 'y'?"
    assert err.source_line == "  cos(0.0375*x - 0.025*yy))/2"
    assert err.source_line[err.column - 1 : err.column + 1] == "yy"


def test_error_on_the_first_line_is_offset_by_the_start_column():
    with pytest.raises(DesignError) as info:
        located("1 + sinn(x)")
    err = info.value
    assert (err.line, err.column) == (3, 14)
    assert err.hint == "did you mean 'sin'?"
    # the source line is indented so that the caret (column) points at the name
    assert err.source_line[err.column - 1 : err.column + 3] == "sinn"
    assert "^" in err.format().splitlines()[2]


@pytest.mark.parametrize(
    "text, line, column, words",
    [
        ("clamp(1,\n 2)", 3, 10, "clamp takes 3 arguments (lo, x, hi), got 2"),
        ("x +\n  atan2(y)", 4, 3, "atan2 takes 2 arguments (y, x), got 1"),
        ("1 + sin(x, y)", 3, 14, "sin takes 1 argument (x), got 2"),
        ("\n max()", 4, 2, "max takes at least 1 argument, got 0"),
        ("2 *\n  foo(x)", 4, 3, "unknown function 'foo'"),
        ("x + sin", 3, 14, "'sin' is a function, not a value"),
        ("rho(x - 1)", 3, 10, "'rho' is not a function"),
        ("x + Rhoo", 3, 14, "unknown variable 'Rhoo'"),
    ],
)
def test_design_errors_are_located(text, line, column, words):
    with pytest.raises(DesignError) as info:
        located(text)
    assert type(info.value) is DesignError
    assert (info.value.line, info.value.column) == (line, column)
    assert words in info.value.message
    assert info.value.hint


@pytest.mark.parametrize(
    "text, line, column, words",
    [
        ("1 +\n  * 2", 4, 3, "unexpected '*'"),
        ("(x +\n  y", 4, 4, "missing ')' to close the '(' at line 3, column 10"),
        ("x)", 3, 11, "unexpected ')'"),
        ("1.2.3", 3, 13, "unexpected number '.3'"),
        ("x 2", 3, 12, "unexpected number '2'"),
        ("a < b < c", 3, 16, "unexpected '<'"),
        ("x.y", 3, 11, "unexpected character '.'"),
        ("__import__('os')", 3, 10, "unexpected character '_'"),
        ("x.__class__", 3, 11, "unexpected character '.'"),
        ("a[0]", 3, 11, "unexpected character '['"),
        ("lambda x: x", 3, 18, "unexpected ':'"),
        ("'abc'", 3, 10, "unexpected character \"'\""),
        ('"x"', 3, 10, "unexpected character '\"'"),
        ("1, 2", 3, 11, "unexpected ','"),
        ("2 ** 3", 3, 13, "unexpected '*'"),
        ("2π", 3, 11, "unexpected character 'π'"),
        ("x ? 1", 3, 15, "ends too early"),
        ("", 3, 10, "empty expression"),
        ("\n  \n", 3, 10, "empty expression"),
        ("x +\n 1e999", 4, 2, "number too large"),
        ("sin(x,)", 3, 16, "unexpected ')'"),
    ],
)
def test_syntax_errors_are_located(text, line, column, words):
    with pytest.raises(DesignSyntaxError) as info:
        located(text)
    err = info.value
    assert (err.file, err.line, err.column) == ("design.vcad", line, column)
    assert words in err.message
    assert err.hint
    assert err.source_line is not None


def test_syntax_error_hints():
    def hint(text):
        with pytest.raises(DesignSyntaxError) as info:
            compile_expression(text)
        return info.value.hint

    assert "chain" in hint("0 < x < 1")
    assert "'^'" in hint("x**2")
    assert "'*'" in hint("x 2")
    assert "pi" in hint("2π")
    assert "'and'" in hint("x && y")
    assert "function call" in hint("1, 2")
    assert "no matching" in hint("(x))")


def test_too_long_and_too_deep():
    with pytest.raises(DesignSyntaxError, match="too long"):
        compile_expression("x+" * 50_001 + "1")
    with pytest.raises(DesignSyntaxError, match="parentheses nested too deeply") as info:
        compile_expression("-(" * 300 + "x" + ")" * 300)
    assert info.value.column == 2 * (expressions.MAX_DEPTH + 1)  # the 201st '('
    with pytest.raises(DesignSyntaxError, match="expression nested too deeply") as info:
        compile_expression("x^" * 300 + "2")
    assert info.value.column == 2 * expressions.MAX_DEPTH + 1  # the 201st power
    with pytest.raises(DesignSyntaxError, match="parentheses nested too deeply") as info:
        compile_expression("1 + " + "(" * 10_000 + "x" + ")" * 10_000)
    assert info.value.column == 5 + expressions.MAX_DEPTH
    # nesting up to the limit, and long flat chains, are fine
    assert value("(" * expressions.MAX_DEPTH + "1" + ")" * expressions.MAX_DEPTH) == 1.0
    assert value("+".join(["1"] * 5000)) == 5000.0
    deep = compile_expression("sin(" * 150 + "x" + ")" * 150)
    np.testing.assert_allclose(deep(X, 0, 0), _nested_sin(X, 150))


def _nested_sin(x, n):
    for _ in range(n):
        x = np.sin(x)
    return x


# -- evaluation errors ----------------------------------------------------------------------------


def test_evaluate_checked_reports_the_first_bad_point():
    expr = located("log(x) +\n  1/(y - 2)")
    x = np.array([1.0, 2.0, 3.0, -1.0, 4.0])
    y = np.array([0.0, 2.0, 0.0, 0.0, 0.0])
    with pytest.raises(FieldError) as info:
        expr.evaluate_checked(x, y, 7.0)
    err = info.value
    assert (err.file, err.line, err.column) == ("design.vcad", 3, 10)
    assert "x=2, y=2, z=7" in err.message and "inf" in err.message
    with pytest.raises(FieldError, match="NaN .* at x=-1, y=0, z=7"):
        expr.evaluate_checked(x[[0, 3]], y[[0, 3]], 7.0)
    ok = expr.evaluate_checked(x[[0, 2]], y[[0, 2]], 7.0)
    np.testing.assert_allclose(ok, np.log(x[[0, 2]]) - 0.5)


def test_evaluate_checked_on_a_grid_and_with_d():
    expr = compile_expression("sqrt(d)")
    d = np.array([[1.0, 4.0], [-9.0, 16.0]])
    with pytest.raises(FieldError, match=r"at x=0\.5, y=3, z=0, d=-9"):
        expr.evaluate_checked(np.array([[0.0], [0.5]]), 3.0, 0.0, d=d)
    assert compile_expression("1/0").__call__(0, 0, 0) == np.inf
    with pytest.raises(FieldError):
        compile_expression("1/0").evaluate_checked(np.zeros(3), 0, 0)


def test_d_without_a_value_is_a_design_error():
    expr = located("x +\n  2 d")
    with pytest.raises(DesignError) as info:
        expr(X, Y, Z)
    assert (info.value.line, info.value.column) == (4, 5)
    np.testing.assert_allclose(expr(X, Y, Z, d=Y), X + 2 * Y)


@pytest.mark.parametrize("digit", ["\U0001fbf0", "\u0661", "\uff15"])
def test_non_ascii_digits_are_not_numbers(digit):
    with pytest.raises(DesignSyntaxError) as err:
        compile_expression(f"x+{digit}")
    assert "unexpected character" in err.value.message
