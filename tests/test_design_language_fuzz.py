"""Fuzzing the .vcad parser: any text or bytes either loads or raises FgsliceError."""

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fgslice.design import load_design, parse_design
from fgslice.errors import FgsliceError

TOKENS = [
    "root", "union", "intersection", "difference", "translate", "rotate", "scale", "fgrade",
    "sphere", "cube", "rectprism", "cylinder", "function", "strut", "mesh", "SPHERE", "sphre",
    "(", ")", "{", "}", "[", "]", ",", ";", " ", "\n", "0", "1", "-2", ".5", "5.", "1e1", "-40",
    '"red"', '"blue"', '"x"', '"z/70"', '"1-z/70)"', '"thresh"', '"prob"', '"sin(x)*d"', '"q"',
    '"', "//", "/*", "*/", "\x00", "é",
]

SETTINGS = settings(max_examples=200, deadline=2000, suppress_health_check=[HealthCheck.too_slow])


def parse_or_error(text: str) -> None:
    try:
        design = parse_design(text, file="fuzz.vcad")
    except FgsliceError as exc:
        assert exc.format()
        return
    x = np.linspace(-2, 2, 5)
    with np.errstate(all="ignore"):
        try:
            design.sdf(x, x, x)
            design.fractions(x, x, x)
        except FgsliceError:
            pass


@SETTINGS
@given(st.lists(st.sampled_from(TOKENS), max_size=40))
def test_token_soup_loads_or_raises_fgslice_error(tokens):
    parse_or_error("".join(tokens))


@st.composite
def designs(draw, depth=0):
    """Mostly well-formed nodes with random arguments."""
    number = st.sampled_from(["1", "2.5", "-1", "0", ".5", "1e1"])
    if depth > 3 or draw(st.booleans()):
        name = draw(st.sampled_from(["sphere", "cube", "cylinder", "rectprism", "strut", "function"]))
        args = draw(st.lists(st.one_of(number, st.just('"red"'), st.just("(1,2,3)"), st.just('"x-1"')), max_size=4))
        return f"{name}({', '.join(args)});"
    name = draw(st.sampled_from(["union", "difference", "intersection", "translate", "rotate", "scale", "fgrade"]))
    args = draw(
        st.lists(st.one_of(number, st.just('["x", "1-x"]'), st.just('["red", "blue"]'), st.just('"thresh"')), max_size=3)
    )
    children = draw(st.lists(designs(depth + 1), max_size=3))
    return f"{name}({', '.join(args)}) {{ {' '.join(children)} }}"


@SETTINGS
@given(designs())
def test_generated_designs_load_or_raise_fgslice_error(text):
    parse_or_error(text)


@SETTINGS
@given(data=st.binary(max_size=200))
def test_random_bytes_load_or_raise_fgslice_error(tmp_path_factory, data):
    path = tmp_path_factory.getbasetemp() / "random.vcad"
    path.write_bytes(data)
    try:
        load_design(path)
    except FgsliceError as exc:
        assert exc.format()


def test_five_thousand_nested_unions_give_a_clear_error():
    depth = 5000
    text = "union() {" * depth + "sphere(1);" + "}" * depth
    try:
        parse_design(text)
    except FgsliceError as exc:
        assert "levels deep" in exc.message
