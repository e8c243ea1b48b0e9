"""Scalar fields sampled on a voxel grid (CT/MRI data), and the DICOM series reader.

:class:`ScalarVolume` holds values at voxel centres ``origin + index * spacing`` (mm,
axis-aligned) and interpolates them trilinearly; a point outside the centres takes the
value of the nearest face (the grid's values held flat), so a solid spanning the
volume's :meth:`ScalarVolume.bounds` (the voxels' outer faces) is defined everywhere.
It is a field as attribute nodes take them: ``volume(x, y, z, d=None)`` on arrays.

:func:`load_dicom_series` reads a folder of DICOM slices with pydicom: each slice's
stored values times ``RescaleSlope`` plus ``RescaleIntercept`` (Hounsfield units for
CT), placed by ``ImagePositionPatient`` and ``PixelSpacing`` in the patient frame (mm),
slices sorted along Z. Only axial series (``ImageOrientationPatient`` 1,0,0,0,1,0) with
evenly spaced slices of one size are read.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from fgslice.errors import DesignError


class ScalarVolume:
    """Values ``(nz, ny, nx)`` at the voxel centres ``origin + (i, j, k) * spacing``
    (``origin``, ``spacing``: x, y, z in mm; ``spacing`` > 0)."""

    def __init__(self, values: np.ndarray, origin, spacing, name: str = "volume") -> None:
        self.values = np.asarray(values, dtype=float)
        self.origin = np.asarray(origin, dtype=float)
        self.spacing = np.asarray(spacing, dtype=float)
        self.__name__ = name
        axes = [self.origin[a] + self.spacing[a] * np.arange(n) for a, n in zip((2, 1, 0), self.values.shape)]
        # one voxel along an axis: hold it flat (a second, equal plane one spacing on)
        padded, grid_axes = self.values, []
        for axis, centres in enumerate(axes):
            if len(centres) == 1:
                padded = np.concatenate([padded, padded], axis=axis)
                centres = np.array([centres[0], centres[0] + self.spacing[2 - axis]])
            grid_axes.append(centres)
        self._grid_axes = grid_axes
        self._interpolator = RegularGridInterpolator(grid_axes, padded, method="linear")

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The voxels' outer faces ``(lo, hi)`` (x, y, z, mm)."""
        shape = np.array(self.values.shape[::-1])
        return self.origin - self.spacing / 2, self.origin + self.spacing * (shape - 0.5)

    def __call__(self, x, y, z, d=None) -> np.ndarray:
        """Trilinear values at the points (mm), the grid's faces held beyond it."""
        x, y, z = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (x, y, z)))
        points = np.column_stack([np.clip(c.ravel(), a[0], a[-1]) for c, a in zip((z, y, x), self._grid_axes)])
        return self._interpolator(points).reshape(x.shape)


def load_dicom_series(folder: str | Path) -> ScalarVolume:
    """The DICOM slices in ``folder`` as one :class:`ScalarVolume` (see the module notes).

    Raises:
        DesignError: no folder, no DICOM slice with pixels in it, or slices that do not
            make one axial, evenly spaced volume.
    """
    import pydicom
    from pydicom.errors import InvalidDicomError

    folder = Path(folder)
    if not folder.is_dir():
        raise DesignError(f"DICOMLoader: '{folder}' is not a folder", hint="give the folder of the series' slices")
    slices = []
    for path in sorted(p for p in folder.iterdir() if p.is_file()):
        try:
            ds = pydicom.dcmread(path)
        except (InvalidDicomError, OSError):
            continue
        if "PixelData" in ds:
            slices.append((path, ds))
    if not slices:
        raise DesignError(f"DICOMLoader: no DICOM slice with pixel data in '{folder}'")
    for path, ds in slices:
        orientation = [float(v) for v in getattr(ds, "ImageOrientationPatient", (1, 0, 0, 0, 1, 0))]
        if not np.allclose(orientation, (1, 0, 0, 0, 1, 0), atol=1e-4):
            raise DesignError(f"DICOMLoader: '{path.name}' is not an axial slice (ImageOrientationPatient "
                              f"{orientation})", hint="fgslice reads axial series only")
    position = [[float(v) for v in getattr(ds, "ImagePositionPatient", (0, 0, i))] for i, (_, ds) in enumerate(slices)]
    order = np.argsort([p[2] for p in position], kind="stable")
    slices = [slices[i] for i in order]
    position = np.array([position[i] for i in order])
    shapes = {(int(ds.Rows), int(ds.Columns)) for _, ds in slices}
    if len(shapes) != 1:
        raise DesignError(f"DICOMLoader: the slices in '{folder}' differ in size ({sorted(shapes)})")
    first = slices[0][1]
    dy, dx = (float(v) for v in getattr(first, "PixelSpacing", (1.0, 1.0)))
    steps = np.diff(position[:, 2])
    if len(steps):
        if steps.min() <= 0 or not np.allclose(steps, steps[0], rtol=1e-3, atol=1e-4):
            raise DesignError(f"DICOMLoader: the slices in '{folder}' are not evenly spaced along Z "
                              f"(steps {steps.min():g} .. {steps.max():g} mm)")
        dz = float(steps[0])
    else:
        dz = float(getattr(first, "SliceThickness", 1.0) or 1.0)
    try:
        values = np.stack([ds.pixel_array.astype(float) * float(getattr(ds, "RescaleSlope", 1.0))
                           + float(getattr(ds, "RescaleIntercept", 0.0)) for _, ds in slices])
    except Exception as exc:  # pydicom raises several kinds for pixel data it cannot decode
        raise DesignError(f"DICOMLoader: cannot decode the pixel data in '{folder}': {exc}",
                          hint="give an uncompressed series (or install the decoder pydicom names)") from None
    if min(dx, dy, dz) <= 0:
        raise DesignError(f"DICOMLoader: the voxel spacing {dx:g} x {dy:g} x {dz:g} mm is not positive")
    return ScalarVolume(values, (position[0, 0], position[0, 1], position[0, 2]), (dx, dy, dz), name=folder.name)
