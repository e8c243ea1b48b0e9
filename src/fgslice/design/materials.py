"""Material libraries: names of base materials and their display colors.

A library file is JSON::

    {"scale": 255,
     "materials": [{"name": "blue", "r": 30, "g": 80, "b": 200, "a": 255}, ...]}

Color channels are on the scale named by ``"scale"`` (``1`` or ``255``). Without
``"scale"`` the whole file is read on the 0-255 scale when any channel value in it is
greater than 1, else on the 0-1 scale. ``"a"`` is optional (opaque). Names are matched
case-insensitively. A user library extends the built-in one (``materials.json`` beside
this module) and overrides built-in entries of the same name.
"""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

from fgslice.design.base import Material
from fgslice.errors import DesignError, did_you_mean

_CHANNELS = ("r", "g", "b", "a")


class MaterialLibrary:
    """Named materials, looked up case-insensitively."""

    def __init__(self, materials: list[Material]) -> None:
        self._by_name = {m.name.lower(): m for m in materials}

    @property
    def names(self) -> list[str]:
        """All material names, in library order."""
        return [m.name for m in self._by_name.values()]

    def extended(self, other: MaterialLibrary) -> MaterialLibrary:
        """A new library: this one plus ``other``, whose entries win on equal names."""
        merged = dict(self._by_name)
        merged.update(other._by_name)
        return MaterialLibrary(list(merged.values()))

    def get(
        self,
        name: str,
        *,
        file: str | None = None,
        line: int | None = None,
        column: int | None = None,
        source_line: str | None = None,
    ) -> Material:
        """The material called ``name``; DesignError with a did-you-mean hint otherwise."""
        found = self._by_name.get(name.lower())
        if found is None:
            hint = did_you_mean(name, self.names) or (
                "known materials: " + ", ".join(self.names) + "; add others with a materials file"
            )
            raise DesignError(
                f"unknown material '{name}'",
                file=file,
                line=line,
                column=column,
                hint=hint,
                source_line=source_line,
            )
        return found


def _parse_library(data: object, source: str) -> MaterialLibrary:
    """Validate decoded JSON ``data`` into a library; ``source`` names it in errors."""
    hint = 'expected {"materials": [{"name": "blue", "r": 0, "g": 0, "b": 255, "a": 255}, ...]}'
    if not isinstance(data, dict) or not isinstance(data.get("materials"), list):
        raise DesignError("a materials file must hold an object with a 'materials' list", file=source, hint=hint)
    entries = data["materials"]
    for i, entry in enumerate(entries):
        if not isinstance(entry, dict) or not isinstance(entry.get("name"), str) or not entry["name"].strip():
            raise DesignError(f"material #{i + 1} has no 'name' string", file=source, hint=hint)
        for key in _CHANNELS:
            value = entry.get(key, None)
            if key == "a" and value is None:
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 <= value <= 255:
                raise DesignError(
                    f"material '{entry['name']}': channel '{key}' must be a number in [0, 255] or [0, 1]",
                    file=source,
                    hint=hint,
                )
    scale = data.get("scale")
    if scale is None:
        scale = 255 if any(entry.get(k, 0) > 1 for entry in entries for k in _CHANNELS) else 1
    if scale not in (1, 255):
        raise DesignError("'scale' must be 1 or 255", file=source, hint=hint)
    if scale == 1 and any(entry.get(k, 1) > 1 for entry in entries for k in _CHANNELS):
        raise DesignError("'scale' is 1 but a channel value exceeds 1", file=source, hint=hint)
    materials = [
        Material(
            entry["name"].strip(),
            tuple(float(entry.get(k, scale)) / scale for k in _CHANNELS),
        )
        for entry in entries
    ]
    return MaterialLibrary(materials)


def builtin_library() -> MaterialLibrary:
    """The library shipped with fgslice (red, green, blue, yellow, cyan, magenta, ...)."""
    text = resources.files("fgslice.design").joinpath("materials.json").read_text(encoding="utf-8")
    return _parse_library(json.loads(text), "materials.json")


def load_library(path: str | Path) -> MaterialLibrary:
    """The built-in library extended by the JSON file at ``path`` (DesignError if unusable)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise DesignError(f"materials file not found: {path}", file=path) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DesignError(f"cannot read materials file: {exc}", file=path) from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise DesignError(
            f"materials file is not valid JSON: {exc.msg}", file=path, line=exc.lineno, column=exc.colno
        ) from None
    except RecursionError:
        raise DesignError("materials file nests arrays or objects too deeply to read", file=path,
                          hint="a material library is a list of objects, two levels deep") from None
    return builtin_library().extended(_parse_library(data, str(path)))
