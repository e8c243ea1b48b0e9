"""The .vcad language: syntax, primitives and operators, materials files, errors with locations."""

import json
import math

import numpy as np
import pytest

from fgslice.design import load_design, parse_design
from fgslice.design.materials import builtin_library, load_library
from fgslice.errors import DesignError, DesignSyntaxError, FgsliceError, MeshError

PAPER_COLUMN_1 = """fgrade(["z/70", "1-z/70)"],
       ["blue", "yellow"]) {
    cylinder(15, 70);
}
"""


def at(design, *point):
    return design.fractions(*(np.array([c], dtype=float) for c in point))[0]


def sdf(design, *point):
    return float(design.sdf(*(np.array([c], dtype=float) for c in point))[0])


def error_of(text, **kwargs) -> FgsliceError:
    with pytest.raises(FgsliceError) as info:
        parse_design(text, file="part.vcad", **kwargs)
    return info.value


def test_root_box_and_voxel_are_hints_and_the_body_is_a_union():
    design = parse_design(
        "ROOT((-50,-50,-50),(50,50,50),(.1,.1,.1)) { Sphere(5, \"RED\"); translate(10,0,0) { cube(4, \"blue\"); } }"
    )
    assert design.hint_bounds == ((-50, -50, -50), (50, 50, 50))
    assert design.voxel_size == (0.1, 0.1, 0.1)
    assert design.bounds() == ((-5, -5, -5), (12, 5, 5))
    assert [m.name for m in design.materials] == ["red", "blue"]
    np.testing.assert_allclose(at(design, 10, 0, 0), [0, 1])


@pytest.mark.parametrize(
    "text, point, expected",
    [
        ("sphere(5);", (0, 0, 3), -2),
        ("cube(4)", (3, 0, 0), 1),
        ("rectprism((2, 4, 6));", (0, 0, 4), 1),
        ("rectprism(2, 4, 6, \"red\");", (0, 3, 0), 1),
        ("cylinder(10, 30, \"red\");", (0, 0, 16), 1),
        ("strut((0,0,0),(10,0,0),1);", (5, 0, 3), 2),
        ("function((-5,-5,-5),(5,5,5),\"x*x+y*y+z*z-9\");", (0, 0, 0), -5),
        ("function((-5,-5,-5),(5,5,5),\"x*x+y*y+z*z-9\");", (0, 0, 7), 40),
        ("difference() { cube(10); cylinder(2, 20); }", (0, 0, 0), 2),
        ("intersection() { cube(10); translate(5, 0, 0) { cube(10); } }", (0, 0, 0), 0),
        ("union() { sphere(1); translate((5,0,0)) { sphere(1); } }", (5, 0, 0), -1),
        ("rotate(0, 0, 90) { translate(5, 0, 0) { sphere(1); } }", (0, 5, 0), -1),
        ("scale(2, 2, 2) { sphere(1); }", (3, 0, 0), 1),
        ("scale(2) { sphere(1); }", (0, 0, 1), -1),
    ],
)
def test_primitives_and_operators(text, point, expected):
    assert sdf(parse_design(text), *point) == pytest.approx(expected)


def test_numbers_comments_and_multiline_strings():
    text = """/* block
    comment */ translate(-40, .5, 5.) { // line comment
        fgrade(["x/1e1",
                "1 -
                 x/10"], ["red", "blue"]) { cube(1e1); }
    }"""
    design = parse_design(text)
    assert design.bounds() == ((-45, -4.5, 0), (-35, 5.5, 10))
    np.testing.assert_allclose(at(design, -37, 0.5, 5), [0.3, 0.7])


def test_fgrade_frame_is_the_fgrade_node_and_child_transforms_do_not_move_it():
    text = """translate(100, 0, 0) {
        fgrade(["z/70", "1-z/70"], ["blue", "yellow"]) { translate(0, 0, 35) { cylinder(15, 70); } }
    }"""
    design = parse_design(text)
    np.testing.assert_allclose(at(design, 100, 0, 17.5), [0.25, 0.75])
    assert design.bounds() == ((85, -15, 0), (115, 15, 70))


def test_fgrade_d_variable_and_thresh_mode():
    design = parse_design('fgrade(["-d/5", "1+d/5"], ["red", "blue"], "THRESH") { sphere(5); }')
    np.testing.assert_allclose(at(design, 0, 0, 0), [1, 0])
    np.testing.assert_allclose(at(design, 4, 0, 0), [0, 1])
    prob = parse_design('fgrade(["-d/5", "1+d/5"], ["red", "blue"], "prob") { sphere(5); }')
    np.testing.assert_allclose(at(prob, 4, 0, 0), [0.2, 0.8])


def test_three_materials_fractions_sum_to_one():
    design = parse_design('fgrade(["x", "y", "1-x-y"], ["red", "green", "blue"]) { cube(1); }')
    np.testing.assert_allclose(at(design, 0.2, 0.3, 0), [0.2, 0.3, 0.5])


def test_paper_column_1_points_at_the_stray_parenthesis():
    err = error_of(PAPER_COLUMN_1)
    assert isinstance(err, DesignSyntaxError)
    assert (err.file, err.line, err.column) == ("part.vcad", 1, 24)
    assert PAPER_COLUMN_1.splitlines()[0][err.column - 1] == ")"


@pytest.mark.parametrize(
    "text, cls, line, column, words",
    [
        ("sphere(5", DesignSyntaxError, 1, 9, "end of file"),
        ("sphere(5,,);", DesignSyntaxError, 1, 10, "unexpected ','"),
        ("sphere(5) $", DesignSyntaxError, 1, 11, "unexpected character"),
        ('cube(2);\nsphere("abc);', DesignSyntaxError, 2, 8, "unterminated string"),
        ("cube(2); /* open", DesignSyntaxError, 1, 10, "unterminated comment"),
        ("sphre(5);", DesignError, 1, 1, "did you mean 'sphere'"),
        ("unoin() { sphere(1); }", DesignError, 1, 1, "did you mean 'union'"),
        ("cylinder(1);", DesignError, 1, 1, "cylinder takes (r, h[, material]), got 1 argument"),
        ('cylinder(1, "x");', DesignError, 1, 14, "argument 2 must be a number"),
        ("rectprism((1, 2), \"red\");", DesignError, 1, 11, "vector of 3 numbers"),
        ('sphere(1, "bleu");', DesignError, 1, 12, "did you mean 'blue'"),
        ('fgrade(["x"], ["red", "blue"]) { cube(1); }', DesignError, 1, 15, "1 expressions but 2 materials"),
        ('fgrade(["x", "1-x"], ["red", "blue"], "random") { cube(1); }', DesignError, 1, 40, "prob"),
        ('fgrade(["x", "1-q"], ["red", "blue"]) { cube(1); }', DesignError, 1, 17, "'q'"),
        ('fgrade(["x", "1-x"], ["red", "rde"]) { cube(1); }', DesignError, 1, 31, "did you mean 'red'"),
        ('fgrade(["x", "sni(x)"], ["red", "blue"]) { cube(1); }', DesignError, 1, 15, "sin"),
        ("union() { }", DesignError, 1, 1, "no children"),
        ("translate(1, 2, 3);", DesignError, 1, 1, "no children"),
        ("sphere(1) { cube(1); }", DesignError, 1, 1, "takes no { } block"),
        ("sphere(-1);", DesignError, 1, 1, "positive"),
        ("scale(1, 0, 1) { sphere(1); }", DesignError, 1, 1, "non-zero"),
        ("sphere(1); cube(1);", DesignError, 1, 12, "union()"),
        ("", DesignError, None, None, "empty"),
        ('function((0,0,0),(1,1,1),"d") ;', DesignError, 1, 27, "only defined in fgrade"),
        ('mesh("nowhere.stl");', MeshError, 1, 7, "not found"),
    ],
)
def test_errors_carry_location(text, cls, line, column, words):
    err = error_of(text)
    assert isinstance(err, cls)
    assert words in err.format()
    assert (err.line, err.column) == (line, column)
    if line is not None:
        source = text.splitlines()[line - 1]
        # the caret sits under the same character in the message as in the file
        assert err.source_line[column - 1 : column] == source[column - 1 : column]


def test_deep_nesting_is_refused_clearly():
    depth = 5000
    text = "union() {" * depth + "sphere(1);" + "}" * depth
    err = error_of(text)
    assert "levels deep" in err.message


def test_moderate_nesting_works():
    depth = 150
    text = "translate(1, 0, 0) {" * depth + "sphere(1);" + "}" * depth
    assert sdf(parse_design(text), 150, 0, 0) == pytest.approx(-1)


def test_load_design_reads_files_and_refuses_non_text(tmp_path):
    path = tmp_path / "part.vcad"
    path.write_text('cylinder(10, 30, "red");')
    assert load_design(path).bounds() == ((-10, -10, -15), (10, 10, 15))
    binary = tmp_path / "binary.vcad"
    binary.write_bytes(bytes(range(256)))
    with pytest.raises(DesignSyntaxError, match="not a text file"):
        load_design(binary)
    with pytest.raises(DesignError, match="not found"):
        load_design(tmp_path / "missing.vcad")


def test_mesh_paths_resolve_from_the_design_folder_then_the_cwd(tmp_path, monkeypatch):
    trimesh = pytest.importorskip("trimesh")
    box = trimesh.creation.box(extents=(10, 20, 30))
    box.apply_translation((100, 0, 0))
    (tmp_path / "meshes").mkdir()
    box.export(tmp_path / "meshes" / "box.stl")
    design_dir = tmp_path / "designs"
    design_dir.mkdir()
    (design_dir / "part.vcad").write_text('mesh("../meshes/box.stl", "red");')
    design = load_design(design_dir / "part.vcad")
    np.testing.assert_allclose(design.bounds(), ((95, -10, -15), (105, 10, 15)))
    assert design.section(0).area == pytest.approx(200)
    monkeypatch.chdir(tmp_path)
    assert parse_design('mesh("meshes/box.stl");').section(14).area == pytest.approx(200)


def test_corrupt_mesh_keeps_the_call_location(tmp_path):
    (tmp_path / "bad.stl").write_bytes(b"solid x\nfacet normal oops\n")
    (tmp_path / "part.vcad").write_text('union() {\n  mesh("bad.stl");\n}')
    with pytest.raises(MeshError) as info:
        load_design(tmp_path / "part.vcad")
    assert (info.value.line, info.value.column) == (2, 9)
    assert "bad.stl" in info.value.message


def test_materials_file_accepts_both_scales(tmp_path):
    byte_scale = tmp_path / "m255.json"
    byte_scale.write_text(json.dumps({"materials": [{"name": "Foam", "r": 255, "g": 0, "b": 51}]}))
    unit_scale = tmp_path / "m1.json"
    unit_scale.write_text(json.dumps({"materials": [{"name": "foam", "r": 1, "g": 0, "b": 0.2, "a": 0.5}]}))
    assert load_library(byte_scale).get("FOAM").rgba == pytest.approx((1, 0, 0.2, 1))
    assert load_library(unit_scale).get("foam").rgba == pytest.approx((1, 0, 0.2, 0.5))
    design = parse_design('sphere(1, "foam");', materials=str(unit_scale))
    assert design.materials[0].rgba == pytest.approx((1, 0, 0.2, 0.5))
    assert load_library(unit_scale).get("red") == builtin_library().get("red")


@pytest.mark.parametrize(
    "content, words",
    [
        ("{not json", "not valid JSON"),
        ('{"colors": []}', "'materials' list"),
        ('{"materials": [{"r": 1, "g": 1, "b": 1}]}', "no 'name'"),
        ('{"materials": [{"name": "x", "r": 300, "g": 1, "b": 1}]}', "channel 'r'"),
        ('{"scale": 1, "materials": [{"name": "x", "r": 30, "g": 1, "b": 1}]}', "exceeds 1"),
    ],
)
def test_bad_materials_files(tmp_path, content, words):
    path = tmp_path / "m.json"
    path.write_text(content)
    with pytest.raises(DesignError, match=words):
        load_library(path)


def test_builtin_library_has_the_common_colors():
    library = builtin_library()
    for name in ("red", "green", "blue", "yellow", "cyan", "magenta", "white", "black", "gray", "orange", "purple"):
        assert all(0 <= c <= 1 for c in library.get(name).rgba)


def test_paper_vase_gradient_matches_the_formula():
    design = parse_design(
        'fgrade(["(1+sin(0.025*x+0.0375*y)*\n   cos(0.0375*x-0.025*y))/2", '
        '"1-(1+sin(0.025*x+0.0375*y)*cos(0.0375*x-0.025*y))/2"], ["yellow", "blue"]) { cube(100); }'
    )
    x, y = 12.0, -30.0
    expected = (1 + math.sin(0.025 * x + 0.0375 * y) * math.cos(0.0375 * x - 0.025 * y)) / 2
    np.testing.assert_allclose(at(design, x, y, 0), [expected, 1 - expected])


def test_deep_nesting_is_refused_before_parsing_with_its_location():
    import time

    text = "union(){" * 20000 + "sphere(1);" + "}" * 20000
    started = time.perf_counter()
    with pytest.raises(DesignError) as info:
        parse_design(text, file="deep.vcad")
    assert time.perf_counter() - started < 1.0
    assert info.value.line == 1 and info.value.column == 8 * 200 + 8


@pytest.mark.parametrize("digit", ["\U0001fbf0", "\u0661", "\uff15"])
def test_non_ascii_digits_are_not_numbers_in_designs(digit):
    with pytest.raises(DesignSyntaxError):
        parse_design(f"sphere({digit});")


@pytest.mark.parametrize(
    "text, line, column, shown",
    [
        ('union() {\n  fgrade(["x/10 +* 2", "1 - x"], ["red", "blue"]) { cube(5); }\n}',
         2, 18, '  fgrade(["x/10 +* 2", "1 - x"], ["red", "blue"]) { cube(5); }'),
        ('fgrade(["x/10",\n   "1 - foo(x)"], ["red", "blue"]) { cube(5); }',
         2, 9, '   "1 - foo(x)"], ["red", "blue"]) { cube(5); }'),
        ('function((-1, -1, -1), (1, 1, 1), "x +\n   y +* z", "red");', 2, 7, '   y +* z", "red");'),
    ],
    ids=["one-line", "second-string", "multi-line"],
)
def test_an_error_inside_an_expression_shows_the_files_own_line(text, line, column, shown):
    err = error_of(text)
    assert (err.line, err.column) == (line, column)
    assert err.source_line == shown
    caret = err.format().splitlines()[2]
    assert caret.index("^") - 4 == column - 1
