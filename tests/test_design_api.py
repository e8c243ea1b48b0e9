"""The Python API: trees with callables and expression strings, validation, materials."""

import json
import math

import numpy as np
import pytest

from fgslice.design import api, load_design
from fgslice.design.base import Design
from fgslice.errors import DesignError, FgsliceError, FieldError


def at(design, *point):
    return design.fractions(*(np.array([c], dtype=float) for c in point))[0]


def test_api_tree_matches_the_language_tree(tmp_path):
    python = api.design(
        api.fgrade(
            [lambda x, y, z: z / 70, "1 - z/70"],
            ["blue", "yellow"],
            api.translate((0, 0, 35), api.cylinder(15, 70)),
        )
    )
    path = tmp_path / "c.vcad"
    path.write_text('fgrade(["z/70", "1-z/70"], ["blue", "yellow"]) { translate(0,0,35) { cylinder(15, 70); } }')
    text = load_design(path)
    assert isinstance(python, Design)
    rng = np.random.default_rng(1)
    x, y, z = rng.uniform(-20, 20, 500), rng.uniform(-20, 20, 500), rng.uniform(-5, 75, 500)
    np.testing.assert_allclose(python.sdf(x, y, z), text.sdf(x, y, z))
    np.testing.assert_allclose(python.fractions(x, y, z), text.fractions(x, y, z))
    assert python.section(30).area == pytest.approx(math.pi * 225, rel=1e-3)


def test_callable_fields_get_numpy_arrays_and_d_when_asked():
    seen = {}

    def blue(x, y, z):
        seen["type"] = type(x)
        return np.clip(x / 10 + 0.5, 0, 1)

    design = api.design(api.fgrade([blue, lambda x, y, z, d: 0.5 + 0 * d], ["blue", "red"], api.cube(10)))
    assert seen == {} or seen["type"] is np.ndarray
    np.testing.assert_allclose(at(design, 2.5, 0, 0), [0.75 / 1.25, 0.5 / 1.25])
    assert seen["type"] is np.ndarray


def test_scalar_returning_callable_is_broadcast():
    design = api.design(api.fgrade([lambda x, y, z: 0.25, lambda x, y, z: 0.75], ["red", "blue"], api.sphere(1)))
    f = design.fractions(np.zeros(4), np.zeros(4), np.zeros(4))
    np.testing.assert_allclose(f, [[0.25, 0.75]] * 4)


def test_failing_or_misshaped_callable_is_a_field_error():
    boom = api.design(api.fgrade([lambda x, y, z: 1 / 0, lambda x, y, z: x], ["red", "blue"], api.sphere(1)))
    with pytest.raises(FieldError, match="ZeroDivisionError"):
        boom.fractions(np.zeros(2), np.zeros(2), np.zeros(2))
    wrong = api.design(api.fgrade([lambda x, y, z: np.ones(7), lambda x, y, z: x], ["red", "blue"], api.sphere(1)))
    with pytest.raises(FieldError):
        wrong.fractions(np.zeros(2), np.zeros(2), np.zeros(2))


@pytest.mark.parametrize(
    "build, words",
    [
        (lambda: api.sphere(0), "positive"),
        (lambda: api.cylinder(1, -2), "positive"),
        (lambda: api.rectprism((1, 2)), "3 numbers"),
        (lambda: api.cube("big"), "number"),
        (lambda: api.union(), "no children"),
        (lambda: api.translate((1, 2, 3)), "no children"),
        (lambda: api.union(api.sphere(1), "cube"), "must be nodes"),
        (lambda: api.scale((1, 0, 1), api.sphere(1)), "non-zero"),
        (lambda: api.fgrade(["x"], ["red", "blue"], api.sphere(1)), "1 fields but 2 materials"),
        (lambda: api.fgrade(["x", "1-x"], ["red", "blue"], api.sphere(1), mode="dither"), "prob"),
        (lambda: api.fgrade([3, "x"], ["red", "blue"], api.sphere(1)), "callable"),
        (lambda: api.function((0, 0, 0), (1, 0, 1), "x"), "below"),
        (lambda: api.design(api.sphere(1, "reed")), "did you mean 'red'"),
        (lambda: api.design("sphere"), "takes a node"),
        (lambda: api.mesh("no/such/file.stl"), "not found"),
    ],
)
def test_bad_api_input_is_a_clear_error(build, words):
    with pytest.raises(FgsliceError) as info:
        build()
    assert words in info.value.format()
    assert isinstance(info.value, DesignError) or words == "not found"


def test_design_with_a_materials_file_and_section_spacing(tmp_path):
    path = tmp_path / "m.json"
    path.write_text(json.dumps({"materials": [{"name": "ink", "r": 0, "g": 0, "b": 128}]}))
    design = api.design(api.sphere(1, "ink"), path, section_spacing=0.05)
    assert design.materials[0].rgba == pytest.approx((0, 0, 128 / 255, 1))
    assert design.section_spacing == 0.05


def test_sampled_section_of_a_tilted_cylinder():
    design = api.design(api.rotate((90, 0, 0), api.cylinder(5, 20)))
    section = design.section(0)
    assert section.is_valid
    assert section.area == pytest.approx(200, rel=0.02)
    np.testing.assert_allclose(section.bounds, (-5, -10, 5, 10), atol=0.1)


def test_function_shape_section_is_sampled_at_the_spacing():
    ball = api.function((-6, -6, -6), (6, 6, 6), lambda x, y, z: x * x + y * y + z * z - 25)
    design = api.design(ball)
    assert design.section(3).area == pytest.approx(math.pi * 16, rel=0.01)
    assert design.section(3, spacing=0.5).area == pytest.approx(math.pi * 16, rel=0.03)
