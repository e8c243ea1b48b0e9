"""A copy of an OpenVCAD-Public checkout's examples with its Git LFS meshes replaced.

A checkout made without ``git lfs pull`` holds, for every mesh, a pointer file (``version
https://git-lfs.github.com/spec/v1``, ``oid``, ``size``). :func:`examples_with_standins`
copies the examples folder and writes in place of each mesh pointer a generated mesh of
about the same size in bytes: an ellipsoid 40 x 20 x 10 mm (icosphere, as many
subdivisions as the byte size suggests) centred at the origin; the 3DBenchy, when
``shared/data/meshes/3DBenchy.stl`` beside a folder above this one, or ``$BENCHY``, is at hand, is the real one.
CAD files (.step, .iges) get solids built with Open CASCADE when the CAD extra is
installed (``cad_standins.py``), else stay pointers; other pointers are left as they are.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import trimesh
from cad_standins import CAD_SUFFIXES, write_standin

LFS_HEADER = b"version https://git-lfs.github.com/spec/v1"
BYTES_PER_TRIANGLE = {".stl": 50, ".3mf": 15, ".obj": 40, ".off": 30}
"""About how many bytes a triangle takes in each format (a 3MF is zipped XML)."""
BENCHY = Path(os.environ.get("BENCHY") or next(
    (p / "shared" / "data" / "meshes" / "3DBenchy.stl" for p in Path(__file__).resolve().parents
     if (p / "shared" / "data" / "meshes" / "3DBenchy.stl").is_file()), "3DBenchy.stl"))


def lfs_size(path: Path) -> int | None:
    """The size in bytes a Git LFS pointer file announces, None for any other file."""
    data = path.read_bytes()[:400]
    if not data.startswith(LFS_HEADER):
        return None
    for line in data.decode("ascii", "replace").splitlines():
        if line.startswith("size "):
            return int(line.split()[1])
    return 0


def standin_mesh(size_bytes: int, suffix: str) -> trimesh.Trimesh:
    """An ellipsoid of about ``size_bytes / BYTES_PER_TRIANGLE[suffix]`` triangles (at least 80)."""
    triangles = max(80, size_bytes // BYTES_PER_TRIANGLE[suffix])
    subdivisions = int(np.clip(round(np.log(triangles / 20) / np.log(4)), 1, 6))
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions)
    sphere.apply_scale((20.0, 10.0, 5.0))
    return sphere


def examples_with_standins(checkout: Path, target: Path) -> Path:
    """Copy ``checkout/examples`` to ``target/examples`` with stand-ins for its LFS meshes;
    returns the copied examples folder."""
    source = Path(checkout) / "examples"
    if not source.is_dir():
        raise SystemExit(f"{checkout} has no examples/ folder (give the root of an OpenVCAD-Public checkout)")
    examples = Path(target) / "examples"
    shutil.copytree(source, examples)
    for path in examples.rglob("*"):
        suffix = path.suffix.lower()
        if path.is_file() and suffix in CAD_SUFFIXES and lfs_size(path) is not None:
            write_standin(path)
        if not path.is_file() or suffix not in BYTES_PER_TRIANGLE:
            continue
        size = lfs_size(path)
        if size is None:
            continue
        if path.stem.lower() == "3dbenchy" and BENCHY.is_file():
            trimesh.load(BENCHY).export(path)
        else:
            standin_mesh(size, suffix).export(path, file_type=suffix.lstrip("."))
    return examples
