"""Shared fixtures: paths to the project's examples and to the shared test meshes."""

from pathlib import Path

import pytest

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
