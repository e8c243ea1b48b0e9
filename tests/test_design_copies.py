"""Long runs of ``translate(x, y, z) { primitive; }`` read as arrays
(fgslice.design.statement_runs) and evaluated together (fgslice.design.copies): the same
sections, distances, materials, node count and errors as the parser's node per
statement, and the analytic volume of a large grid of cubes."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

import fgslice.design.statement_runs as statement_runs
from fgslice.design.copies import Copies
from fgslice.islands import MANY_ISLANDS, difference_by_islands, union_polygons
from fgslice.design.language import parse_design
from fgslice.design.nodes import walk
from fgslice.errors import FgsliceError

SHAPES = ["cube(0.6)", "sphere(0.45)", "rectprism(0.5, 0.8, 0.4)", "cylinder(0.35, 0.7)"]


def statements(n: int, seed: int = 0, pitch: float = 0.9, shapes=SHAPES, materials=("blue", "yellow")) -> list[str]:
    """A grid of primitives, kinds and materials in stretches of 25, some touching or overlapping."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(n)))
    out = []
    for i in range(n):
        x, y = (i % side) * pitch, (i // side) * pitch
        z = rng.uniform(-0.2, 0.2)
        shape = shapes[(i // 25) % len(shapes)]
        material = materials[(i // 50) % len(materials)]
        out.append(f'translate({x:.3f}, {y:.3f}, {z:.3f}) {{ {shape[:-1]}, "{material}"); }}')
    return out


def both(text: str, monkeypatch) -> tuple:
    fast = parse_design(text)
    with monkeypatch.context() as m:
        m.setattr(statement_runs, "MIN_RUN", 10**9)
        slow = parse_design(text)
    return fast, slow


def assert_same(fast, slow, zs=(-0.35, -0.2, 0.0, 0.13, 0.3), inside=True):
    assert fast.node_count == slow.node_count
    assert [m.name for m in fast.materials] == [m.name for m in slow.materials]
    assert np.array_equal(np.array(fast.bounds()), np.array(slow.bounds()), equal_nan=True)
    for z in zs:
        a, b = fast.section(z), slow.section(z)
        assert a.is_valid
        # the same polygons, vertex for vertex (to 1e-9 mm where overlapping copies are overlaid)
        assert shapely.normalize(a).equals_exact(shapely.normalize(b), tolerance=1e-9)
        assert a.area == pytest.approx(b.area, rel=1e-12)
    x, y, z = np.random.default_rng(5).uniform((-2, -2, -1), (16, 16, 1), (6000, 3)).T
    assert np.array_equal(fast.sdf(x, y, z), slow.sdf(x, y, z))
    assert (fast.sdf(x, y, z) <= 0).sum() > 100 or not inside
    assert np.array_equal(fast.fractions(x, y, z), slow.fractions(x, y, z))


def test_a_run_gives_the_same_design_as_a_node_per_statement(monkeypatch):
    text = "union() {\n  sphere(0.5);\n" + "\n".join(statements(240)) + "\n  // the end\n  cube(0.2);\n}\n"
    fast, slow = both(text, monkeypatch)
    copies = [n for n, *_ in walk(fast.root) if isinstance(n, Copies)]
    assert sum(c.count for c in copies) == 240
    assert {c.shape for c in copies} == {"box", "sphere", "cylinder"}
    assert not any(isinstance(n, Copies) for n, *_ in walk(slow.root))
    assert_same(fast, slow)


def test_overlapping_copies_join_as_the_parsers_union(monkeypatch):
    text = "union() {\n" + "\n".join(statements(200, pitch=0.4, shapes=["cube(0.6)", "sphere(0.3)"])) + "\n}\n"
    fast, slow = both(text, monkeypatch)
    assert len(fast.section(0.0).geoms) < 50  # the copies overlap into a few regions
    assert_same(fast, slow)


def test_runs_outside_a_union_are_nodes_per_statement(monkeypatch):
    for op in ("intersection()", "difference()", "translate(1, 2, 0)"):
        text = f"{op} {{\n  cube(40);\n" + "\n".join(statements(100)) + "\n}\n"
        fast, slow = both(text, monkeypatch)
        assert not any(isinstance(n, Copies) for n, *_ in walk(fast.root))
        assert_same(fast, slow, inside=op != "intersection()")


def error_of(text: str):
    with pytest.raises(FgsliceError) as info:
        parse_design(text)
    e = info.value
    return e.message, e.line, e.column, e.source_line


@pytest.mark.parametrize("bad", ["cube(0)", "sphere(-1)", 'cube(1, "nonesuch")', "cube(1e999)"])
def test_errors_in_a_run_are_reported_where_the_parser_reports_them(monkeypatch, bad):
    lines = statements(200)
    lines[150] = f"translate(3, 4, 0) {{ {bad}; }}"
    text = "union() {\n" + "\n".join(lines) + "\n}\n"
    fast = error_of(text)
    monkeypatch.setattr(statement_runs, "MIN_RUN", 10**9)
    assert fast == error_of(text)
    assert fast[1] == 152


def test_positions_after_a_run_are_unchanged(monkeypatch):
    text = "union() {\n" + "\n".join(statements(200)) + "\n  sphere(2) oops\n}\n"
    fast = error_of(text)
    monkeypatch.setattr(statement_runs, "MIN_RUN", 10**9)
    assert fast == error_of(text)
    assert fast[1] == 203  # "oops" expects "(", finds the closing brace


def test_statements_in_strings_and_comments_are_not_runs():
    body = "\n".join(statements(100, shapes=["cube(0.6)"]))
    text = "union() {\n/*\n" + body + "\n*/\n  sphere(1);\n}\n"
    design = parse_design(text)
    assert design.node_count == 2
    assert statement_runs.find_runs(f'union() {{ function((0,0,0),(1,1,1), "{body}"); }}')[1] == []


def test_union_polygons_keeps_islands_and_joins_neighbours():
    boxes = shapely.box(np.arange(200.0), 0, np.arange(200.0) + 0.5, 1)
    assert shapely.equals(union_polygons(boxes), shapely.union_all(boxes))
    assert len(union_polygons(boxes).geoms) == 200
    touching = shapely.box(np.arange(200.0), 0, np.arange(200.0) + 1.0, 1)
    joined = union_polygons(touching)
    assert len(joined.geoms) == 1 and joined.area == pytest.approx(200)
    assert union_polygons([]).is_empty


def test_a_large_grid_of_cubes_has_its_analytic_volume():
    """20 000 cubes of 0.6 mm at a 0.7 mm pitch, three 0.2 mm layers: every section holds
    every cube's square, the sections' volume is the cubes'."""
    n, side = 20_000, 142
    text = "union() {\n" + "\n".join(
        f"translate({(i % side) * 0.7:.1f}, {(i // side) * 0.7:.1f}, 0) {{ cube(0.6); }}" for i in range(n)) + "\n}\n"
    design = parse_design(text)
    assert design.node_count == 2 * n + 1
    sections = design.sections([-0.2, 0.0, 0.2])
    assert [len(s.geoms) for s in sections] == [n] * 3
    assert sum(s.area for s in sections) * 0.2 == pytest.approx(n * 0.6**3, rel=1e-9)


def test_difference_by_islands_is_the_difference():
    rng = np.random.default_rng(7)
    a = union_polygons(shapely.box(*(lambda x, y: (x, y, x + 0.8, y + 0.8))(*rng.uniform(0, 40, (2, 300)))))
    b = union_polygons(shapely.buffer(shapely.points(rng.uniform(0, 40, (200, 2))), 0.6))
    got = difference_by_islands(a, b)
    assert got.is_valid
    assert shapely.symmetric_difference(got, shapely.difference(a, b)).area < 1e-9
    assert len(got.geoms) > MANY_ISLANDS
    assert difference_by_islands(a, shapely.Polygon()).equals(a)
