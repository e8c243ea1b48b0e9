"""Hostile input at the file level: design files and G-code.

Complements ``test_design_expressions_fuzz.py`` (expression text) and
``test_design_language_fuzz.py`` (token soup, generated trees, random bytes) with: every
refusal of a design carries its location; nothing of a design is ever executed as Python
(``eval``/``exec``/``compile``/``__import__`` are made to fail while parsing); dunder
names, attribute access, unicode, huge numbers and deep nesting inside whole designs;
and the G-code reader and verifier on random text and bytes.
"""

from __future__ import annotations

import builtins
import contextlib
import math
import sys

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from fgslice.design import parse_design
from fgslice.errors import DesignSyntaxError, FgsliceError, GcodeError
from fgslice.machine.gcode_reader import GcodeProgram, read_gcode
from fgslice.machine.verify import verify_gcode
from fgslice.settings import load_settings

FUZZ = settings(max_examples=150, deadline=2000, suppress_health_check=[HealthCheck.too_slow])
FILE = "hostile.vcad"
POINTS = np.linspace(-3.0, 3.0, 7)

WARM_UP = """
union() {
  fgrade(["x/2 + 0.5", "0.5 - x/2"], ["blue", "yellow"], "thresh") { sphere(2); cube(1); }
  difference() { rectprism(1, 2, 3); cylinder(1, 2, "red"); }
  translate(1, 2, 3) { rotate(10, 20, 30) { scale(1, 2, 3) { strut((0,0,0), (1,1,1), 0.5); } } }
  intersection() { function((-1,-1,-1), (1,1,1), "x*x + y*y + z*z - 1"); sphere(1); }
}
"""


class CodeExecuted(AssertionError):
    """Raised by the trapped builtins: parsing tried to run code."""


@contextlib.contextmanager
def no_code_execution():
    """Make ``eval``, ``exec``, ``compile`` and imports of anything not yet loaded fail
    inside the block.

    A warm-up parse first loads every module parsing needs; after that, any of these
    calls while parsing can only come from design text reaching Python.
    """
    parse_design(WARM_UP, file=FILE).sdf(POINTS, POINTS, POINTS)
    loaded = set(sys.modules)
    saved = {name: getattr(builtins, name) for name in ("eval", "exec", "compile", "__import__")}

    def trapped(name):
        def fail(*args, **kwargs):
            raise CodeExecuted(f"{name} called while parsing a design: {args[:1]!r}")

        return fail

    def guarded_import(name, *args, **kwargs):
        if name not in loaded:
            raise CodeExecuted(f"import of {name!r} while parsing a design")
        return saved["__import__"](name, *args, **kwargs)

    for name in ("eval", "exec", "compile"):
        setattr(builtins, name, trapped(name))
    builtins.__import__ = guarded_import
    try:
        yield
    finally:
        for name, value in saved.items():
            setattr(builtins, name, value)


def loads_or_located_error(text: str) -> None:
    """Parse ``text``; a refusal must be an FgsliceError naming the file (and line/column
    for syntax errors); a design that loads must evaluate without another exception."""
    try:
        with no_code_execution():
            design = parse_design(text, file=FILE)
    except FgsliceError as err:
        assert err.file == FILE, err.format()
        if isinstance(err, DesignSyntaxError) and "NUL bytes" not in err.message:
            assert err.line is not None and err.line >= 1 and err.column is not None and err.column >= 1, err.format()
        assert err.format().startswith(FILE)
        return
    with np.errstate(all="ignore"):
        try:
            design.bounds()
            design.sdf(POINTS, POINTS, POINTS)
            design.fractions(POINTS, POINTS, POINTS)
        except FgsliceError:
            pass


PAYLOADS = [
    "__import__('os').system('touch /tmp/fgslice-pwned')",
    "__import__",
    "__builtins__",
    "__class__",
    "x.__class__.__mro__",
    "().__class__.__bases__[0].__subclasses__()",
    "open('/etc/passwd').read()",
    "eval('1')",
    "exec('import os')",
    "lambda: 0",
    "sphere.__globals__",
    "x.real",
    "getattr(x, 'y')",
    "{{7*7}}",
    "${x}",
    "%s%s%s",
    "{0.__class__}",
]

SLOTS = [
    "sphere({p});",
    'sphere(1, "{p}");',
    'fgrade(["{p}", "1 - x"], ["blue", "yellow"]) {{ sphere(1); }}',
    'function((-1, -1, -1), (1, 1, 1), "{p}");',
    "{p}(1);",
    "union() {{ {p}; }}",
    "translate({p}, 0, 0) {{ sphere(1); }}",
    "{p} {{ sphere(1); }}",
    'mesh("{p}");',
]


@FUZZ
@given(st.sampled_from(PAYLOADS), st.sampled_from(SLOTS))
def test_code_in_any_slot_is_never_executed(payload, slot):
    loads_or_located_error(slot.format(p=payload))


@FUZZ
@given(st.text(alphabet=st.characters(blacklist_categories=["Cs"]), max_size=200))
@example("sphere(1); // \u202e\u2066 bidi\nsphere(2);")
@example("sph\u0435re(1);")
@example("sphere(\uff11);")
@example('sphere(1, "\U0001f600");')
def test_unicode_text_loads_or_is_refused_with_a_location(text):
    loads_or_located_error(text)


@FUZZ
@given(st.sampled_from(SLOTS), st.text(alphabet=st.characters(min_codepoint=0x80, blacklist_categories=["Cs"]), min_size=1, max_size=8))
def test_unicode_in_any_slot_is_refused_with_a_location(slot, junk):
    loads_or_located_error(slot.format(p=junk))


@FUZZ
@given(st.sampled_from(["1e309", "-1e309", "1" + "0" * 400, "1e308", "1.7976931348623157e308", "4.9e-324", "1e-400"]),
       st.sampled_from(["sphere({n});", "rectprism({n}, 1, 1);", "translate({n}, 0, 0) {{ sphere(1); }}",
                        "scale({n}, 1, 1) {{ sphere(1); }}", "rotate({n}, 0, 0) {{ cube(1); }}",
                        "cylinder(1, {n});", 'fgrade(["{n} * x", "1"], ["blue", "red"]) {{ sphere(1); }}']))
def test_huge_and_tiny_numbers_load_with_finite_bounds_or_are_refused(number, template):
    text = template.format(n=number)
    loads_or_located_error(text)
    try:
        design = parse_design(text, file=FILE)
    except FgsliceError:
        return
    lo, hi = design.bounds()
    assert all(math.isfinite(v) for v in (*lo, *hi)), f"{text} loads with bounds {lo}, {hi}"


@pytest.mark.parametrize("number", ["1e309", "-1e999", "9" * 400])
def test_an_overflowing_number_is_a_syntax_error_at_its_column(number):
    with pytest.raises(DesignSyntaxError) as info:
        parse_design(f"union() {{\n  sphere({number});\n}}\n", file=FILE)
    assert (info.value.line, info.value.column) == (2, 10)
    assert "number" in info.value.message


@settings(max_examples=10, deadline=2000)
@given(st.integers(min_value=1, max_value=1_000),
       st.sampled_from(["union() {{ {} }}", "translate(1, 0, 0) {{ {} }}", "scale(2, 2, 2) {{ {} }}",
                        'fgrade(["x", "1-x"], ["blue", "red"]) {{ {} }}', "difference() {{ {} sphere(0.1); }}"]))
@example(1_000, "union() {{ {} }}")
@example(1_000, 'fgrade(["x", "1-x"], ["blue", "red"]) {{ {} }}')
def test_deeply_nested_designs_load_or_are_refused_fast(depth, wrapper):
    head, tail = wrapper.split("{}")
    text = head.format() * depth + "sphere(1);" + tail.format() * depth
    loads_or_located_error(text)


@settings(max_examples=10, deadline=2000)
@given(st.integers(min_value=1, max_value=20_000), st.sampled_from(["(", "sin(", "-(", "max(1, "]))
@example(20_000, "(")
def test_deeply_nested_expressions_inside_a_design(depth, opener):
    expr = opener * depth + "x" + ")" * depth
    loads_or_located_error(f'fgrade(["{expr}", "1"], ["blue", "red"]) {{ sphere(1); }}')


# ---------------------------------------------------------------------------- G-code

GCODE_SETTINGS = load_settings("marlin-mixing")
GCODE_WORDS = [
    "G0", "G1", "G2", "G3", "G28", "G90", "G91", "G92", "M82", "M83", "M104", "M109", "M140", "M221", "M163",
    "M164", "M165", "M42", "M106", "M107", "T0", "T7", "T99999999999999999999", "X", "Y", "Z", "E", "F", "I",
    "J", "R", "S", "P", "A", "B", "X1", "Y-2.5", "Z0.2", "E0.05", "E-1", "F1200", "X1e999", "Ynan", "Einf",
    "X--1", "Y1.2.3", "S300", "P1.5", "A0.5", "B0.5", "I5", "J-5", "R0", ";LAYER_CHANGE", ";Z:", ";Z:abc",
    ";TYPE:", ";WIDTH:-1", ";STATE:", ";STATE:99", ";LAYER:x", ";", "(", ")", "*", "N10", "\t", " ", "\r",
    "\n", "\x00", "\xff", "é",
]


def read_or_gcode_error(data: str | bytes) -> None:
    try:
        program = read_gcode(data)
    except GcodeError as err:
        assert err.format()
        return
    assert isinstance(program, GcodeProgram)
    assert np.all(np.isfinite(program.end)) and np.all(np.isfinite(program.e))
    faults = verify_gcode(program, GCODE_SETTINGS)
    assert all(f.line >= 1 and f.message for f in faults)


@FUZZ
@given(st.binary(max_size=400))
def test_random_bytes_are_read_or_refused(data):
    read_or_gcode_error(data)


@FUZZ
@given(st.text(max_size=400))
def test_random_text_is_read_or_refused(text):
    read_or_gcode_error(text + "\nG1 X1 Y1\n")


@FUZZ
@given(st.lists(st.lists(st.sampled_from(GCODE_WORDS), max_size=6).map(" ".join), min_size=1, max_size=40))
@example(["G1 X1 Y1", "G2 X1 Y1 R0", "G3 X2 Y2 I0 J0 E1", "G92 E1e999", "G91", "G1 X1e308 Y1e308", "G1 X1e308"])
@example(["M83", "G1 X10 Y10 E1", "G1 X10 Y10 E1", "G2 X10 Y10 I0 J0 E1"])
def test_gcode_word_soup_is_read_or_refused(lines):
    read_or_gcode_error("\n".join(lines) + "\n")


@FUZZ
@given(st.lists(st.sampled_from(GCODE_WORDS), max_size=60).map(" ".join))
def test_gcode_words_on_one_line_from_a_file(tmp_path_factory, text):
    path = tmp_path_factory.getbasetemp() / "soup.gcode"
    path.write_text(text, encoding="utf-8", errors="surrogateescape")
    try:
        faults = verify_gcode(path, GCODE_SETTINGS)
    except GcodeError as err:
        assert err.format()
    else:
        assert all(f.line >= 1 for f in faults)
