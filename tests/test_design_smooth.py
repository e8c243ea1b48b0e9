"""Smooth booleans: OpenVCAD's Union / Intersection / Difference with k > 0."""

import textwrap

import numpy as np
import pytest

from fgslice.compat.script import load_script
from fgslice.design.smooth import smooth_min

HEADER = "import pyvcad as pv\nimport pyvcad_rendering as viz\nmaterials = pv.default_materials\n"


def _load(tmp_path, body):
    path = tmp_path / "smooth.py"
    path.write_text(HEADER + textwrap.dedent(body))
    return load_script(path)


def test_smooth_min_is_the_sharp_min_apart_and_fills_within_k():
    a, b = np.array([0.0, 0.0, 1.0]), np.array([5.0, 0.0, 1.2])
    assert np.allclose(smooth_min(a, b, 1.0), [0.0, -0.25, 1.0 - 0.64 / 4])


def test_two_spheres_blended_by_a_smooth_union(tmp_path):
    """Two spheres of radius 2.5 mm, centres 6 mm apart: the smooth union (k = 3) bridges
    their 1 mm gap at the midpoint, where the sharp union leaves it empty."""
    design = _load(tmp_path, """
        a = pv.Sphere(pv.Vec3(-3, 0, 0), 2.5, materials.id("red"))
        b = pv.Sphere(pv.Vec3(3, 0, 0), 2.5, materials.id("blue"))
        viz.Render(pv.Union(3.0, False, [a, b]), materials)
        """)
    # at the midpoint both distances are 0.5: smin = 0.5 - 1^2 * 3 / 4
    assert design.sdf(np.array([0.0]), np.array([0.0]), np.array([0.0]))[0] == pytest.approx(-0.25)
    assert design.sdf(np.array([-3.0]), np.array([0.0]), np.array([0.0]))[0] == pytest.approx(-2.5)
    section = design.section(0.0)
    assert section.is_valid and len(section.geoms) == 1  # one bridged body
    far = design.section(2.2)  # near the tops the gap (3.6 mm) is wider than k: two bodies
    assert len(far.geoms) == 2
    f = design.fractions(np.array([-3.0, 3.0]), np.zeros(2), np.zeros(2))
    assert np.allclose(f, [[1, 0], [0, 1]])


@pytest.mark.parametrize("boolean", ["pv.Difference(1.0, box, ball)", "pv.Intersection(1.0, False, [box, ball])"])
def test_smooth_difference_and_intersection_only_round_away_material(tmp_path, boolean):
    design = _load(tmp_path, f"""
        box = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(10, 10, 10), materials.id("red"))
        ball = pv.Sphere(pv.Vec3(0, 0, 0), 6.5, materials.id("red"))
        viz.Render({boolean}, materials)
        """)
    rng = np.random.default_rng(1)
    p = rng.uniform(-6, 6, (4000, 3))
    box, ball = np.max(np.abs(p) - 5, axis=1), np.linalg.norm(p, axis=1) - 6.5
    sharp = np.maximum(box, -ball) if "Difference" in boolean else np.maximum(box, ball)
    smooth = design.sdf(*p.T)
    inside = box <= 0  # the box's own distance is exact inside (outside it is Euclidean to its edges)
    assert np.all(smooth[inside] >= sharp[inside] - 1e-12)  # smax >= max: the region only shrinks
    near = np.abs(box - (-ball if "Difference" in boolean else ball)) < 0.5
    assert np.all(smooth[near & inside] > sharp[near & inside])
