"""OpenVCAD 3's ``PNGLoader``: PNG images as colour volumes to attach as ``COLOR_RGB(A)``.

* ``PNGLoader.FromImage(path, voxel_size, depth_mm, mode, center=False)``: one image
  repeated along Z over ``depth_mm``;
* ``PNGLoader.FromStack(folder, voxel_size, mode, center=False)``: the folder's PNG files,
  in name order, as slices from the bottom up, ``voxel_size.z`` apart;
* ``as_rgb_volume()`` / ``as_rgba_volume()``: the :class:`ColorVolume`, whose
  ``bounding_box()`` gives its corners and which ``Vec3Attribute(volume)`` /
  ``Vec4Attribute(volume)`` take as their channels.

Units and conventions: each pixel is ``voxel_size.x`` by ``voxel_size.y`` mm, column 0 at
the least X and row 0 (the top of the image) at the greatest Y; the volume's least corner
is at the origin, or its centre is with ``center=True``. Channels are the PNG's values
scaled to 0-1 (read by matplotlib); ``COLOR_RGB`` drops an alpha channel, ``COLOR_RGBA``
keeps it or makes the volume opaque (1) when the image has none; a grey image gives its
grey to red, green and blue. A channel at a point is interpolated trilinearly between the
voxel centres and held at the edge value beyond them.
"""

from __future__ import annotations

import enum
from pathlib import Path

import numpy as np
from scipy.ndimage import map_coordinates

from fgslice.compat import context
from fgslice.errors import DesignError

__all__ = ["PNGLoader", "PNGColorMode", "ColorVolume"]


class PNGColorMode(enum.Enum):
    """``pyvcad.PNGColorMode``: the channels a PNG volume gives."""

    COLOR_RGB = 3
    COLOR_RGBA = 4


def _read(path: Path) -> np.ndarray:
    """The image as ``(rows, columns, 4)`` RGBA in 0-1 (opaque when it has no alpha)."""
    from matplotlib import image

    try:
        pixels = np.asarray(image.imread(path, format="png"), dtype=float)
    except (OSError, ValueError, SyntaxError) as error:
        raise DesignError(f"PNGLoader: cannot read '{path}' as a PNG image: {error}",
                          hint="give the path of a PNG file (relative paths: the script's folder)") from None
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    if pixels.shape[2] in (1, 2):
        pixels = np.concatenate([np.repeat(pixels[:, :, :1], 3, axis=2), pixels[:, :, 1:]], axis=2)
    if pixels.shape[2] == 3:
        pixels = np.concatenate([pixels, np.ones(pixels.shape[:2] + (1,))], axis=2)
    return pixels


def _path(owner: str, path) -> Path:
    if not isinstance(path, (str, Path)):
        raise DesignError(f"{owner}: the path must be a file or folder name, got {path!r}")
    path = Path(path)
    run = context.current()
    if not path.is_absolute() and run is not None and (run.path.resolve().parent / path).exists():
        path = run.path.resolve().parent / path
    if not path.exists():
        raise DesignError(f"{owner}: '{path}' not found", hint="relative paths are looked up in the script's folder")
    return path


def _voxel(owner: str, voxel_size) -> np.ndarray:
    from fgslice.compat.pyvcad import _vec3

    size = np.array(_vec3(owner, "voxel_size", voxel_size))
    if not np.all(size > 0):
        raise DesignError(f"{owner}: voxel_size must be positive on every axis, got {tuple(size)}")
    return size


def _mode(owner: str, mode) -> PNGColorMode:
    if not isinstance(mode, PNGColorMode):
        raise DesignError(f"{owner}: mode must be a pyvcad.PNGColorMode, got {mode!r}")
    return mode


class ColorVolume:
    """Colour channels on a voxel grid: ``grid`` is ``(x, y, z, channels)`` in 0-1,
    ``lo`` the least corner (mm) and ``voxel`` the voxel sizes (mm)."""

    def __init__(self, grid: np.ndarray, lo: np.ndarray, voxel: np.ndarray) -> None:
        self.grid, self.lo, self.voxel = grid, lo, voxel

    @property
    def channels(self) -> int:
        """3 (RGB) or 4 (RGBA)."""
        return self.grid.shape[3]

    def bounding_box(self):
        """``(min, max)`` corners of the volume, ``pyvcad.Vec3``."""
        from fgslice.compat.pyvcad import Vec3

        return Vec3(*self.lo), Vec3(*(self.lo + self.voxel * np.array(self.grid.shape[:3])))

    def field(self, channel: int):
        """Channel ``channel`` as a field ``f(x, y, z, d=None)`` (mm) -> values in 0-1."""
        values = np.ascontiguousarray(self.grid[..., channel])

        def sampled(x, y, z, d=None):
            shape = np.broadcast_shapes(np.shape(x), np.shape(y), np.shape(z))
            index = [(np.broadcast_to(c, shape).ravel() - self.lo[a]) / self.voxel[a] - 0.5
                     for a, c in enumerate((x, y, z))]
            return map_coordinates(values, index, order=1, mode="nearest").reshape(shape)

        sampled.__name__ = f"png {'rgba'[channel]}"
        return sampled

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        from fgslice.compat.pyvcad import _unsupported

        raise _unsupported("ColorVolume", name)


class PNGLoader:
    """A PNG image or stack with its voxel size and colour mode (see the module)."""

    def __init__(self, pixels: np.ndarray, voxel: np.ndarray, mode: PNGColorMode, center: bool) -> None:
        grid = np.transpose(pixels[:, ::-1, :, :], (2, 1, 0, 3))  # (slice, row, column) -> (x, y, z), row 0 on top
        self._grid = grid[..., : mode.value]
        self._voxel = voxel
        size = voxel * np.array(grid.shape[:3])
        self._lo = -size / 2 if center else np.zeros(3)

    @classmethod
    def FromImage(cls, path, voxel_size, depth_mm, mode, center: bool = False) -> PNGLoader:  # noqa: N802 (OpenVCAD's name)
        """One image repeated along Z to ``depth_mm`` (whole voxels, at least one)."""
        from fgslice.compat.pyvcad import _number

        owner = "PNGLoader.FromImage"
        voxel, mode = _voxel(owner, voxel_size), _mode(owner, mode)
        depth = _number(owner, "depth_mm", depth_mm)
        if depth <= 0:
            raise DesignError(f"{owner}: depth_mm must be positive, got {depth:g}")
        image = _read(_path(owner, path))
        slices = max(1, round(depth / voxel[2]))
        return cls(np.repeat(image[None], slices, axis=0), voxel, mode, bool(center))

    @classmethod
    def FromStack(cls, folder, voxel_size, mode, center: bool = False) -> PNGLoader:  # noqa: N802 (OpenVCAD's name)
        """The folder's PNG files in name order, the first at the bottom."""
        owner = "PNGLoader.FromStack"
        voxel, mode, folder = _voxel(owner, voxel_size), _mode(owner, mode), _path(owner, folder)
        files = sorted(p for p in folder.iterdir() if p.suffix.lower() == ".png") if folder.is_dir() else []
        if not files:
            raise DesignError(f"{owner}: '{folder}' is not a folder of PNG files")
        images = [_read(p) for p in files]
        if len({i.shape[:2] for i in images}) > 1:
            raise DesignError(f"{owner}: the images of '{folder}' differ in size", hint="every slice must have "
                              "the same width and height in pixels")
        return cls(np.stack(images), voxel, mode, bool(center))

    def as_rgb_volume(self) -> ColorVolume:
        """The red, green and blue channels."""
        return ColorVolume(self._grid[..., :3], self._lo, self._voxel)

    def as_rgba_volume(self) -> ColorVolume:
        """The four channels (a ``COLOR_RGB`` loader has no alpha to give)."""
        if self._grid.shape[3] < 4:
            raise DesignError("PNGLoader.as_rgba_volume: the loader was made with PNGColorMode.COLOR_RGB",
                              hint="load with PNGColorMode.COLOR_RGBA, or use as_rgb_volume()")
        return ColorVolume(self._grid, self._lo, self._voxel)

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        from fgslice.compat.pyvcad import _unsupported

        raise _unsupported("PNGLoader", name)
