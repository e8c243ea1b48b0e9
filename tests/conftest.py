"""Shared fixtures: paths to the project's examples and to the shared test meshes, a local
Dask cluster; a comparison of layer plans step by step."""

import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from fgslice.planning.plan import SetState

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"


def _shared_data() -> Path:
    """The shared test data: ``$FGSLICE_SHARED_DATA``, else the first ``shared/data``
    folder beside the repository or beside one of its parent folders (CI puts ``shared/``
    beside the clone; a checkout in a subfolder finds it further up)."""
    if os.environ.get("FGSLICE_SHARED_DATA"):
        return Path(os.environ["FGSLICE_SHARED_DATA"])
    for folder in ROOT.parents:
        if (folder / "shared" / "data").is_dir():
            return folder / "shared" / "data"
    return ROOT.parent / "shared" / "data"


SHARED_DATA = _shared_data()


@pytest.fixture
def benchy_path() -> Path:
    """The 3DBenchy mesh from the shared test data; skips when the folder is absent."""
    path = SHARED_DATA / "meshes" / "3DBenchy.stl"
    if not path.exists():
        pytest.skip(f"shared test data not found at {path}")
    return path


@pytest.fixture(scope="session")
def dask_scheduler() -> Iterator[str]:
    """The address of a local Dask cluster of two worker processes, shared by the tests of
    one test process (skips when dask.distributed is not installed). The scheduler's HTTP
    server (health routes; the dashboard is off) listens on a free loopback port, not on
    8787 of every interface, which the clusters of parallel test processes would all ask for."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=40,
        scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
    ) as local:
        yield local.scheduler_address


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
