"""Shared fixtures: paths to the project's examples and to the shared test meshes; a
comparison of layer plans step by step."""

from pathlib import Path

import numpy as np
import pytest

from fgslice.planning.plan import SetState

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
SHARED_DATA = ROOT.parent / "shared" / "data"


@pytest.fixture
def benchy_path() -> Path:
    """The 3DBenchy mesh from the shared test data; skips when the folder is absent."""
    path = SHARED_DATA / "meshes" / "3DBenchy.stl"
    if not path.exists():
        pytest.skip(f"shared test data not found at {path}")
    return path


def same_steps(a, b):
    """Assert that plans ``a`` and ``b`` have the same steps: state changes, and paths with
    the same points and attributes."""
    assert len(a.steps) == len(b.steps)
    for x, y in zip(a.steps, b.steps):
        assert type(x) is type(y)
        if isinstance(x, SetState):
            assert x == y
        else:
            assert np.array_equal(x.points, y.points) and x.points.shape == y.points.shape
            assert (x.role, x.color, x.width, x.height, x.closed, x.group) == (
                y.role, y.color, y.width, y.height, y.closed, y.group)
