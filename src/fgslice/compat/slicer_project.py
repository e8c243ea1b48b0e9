"""What OpenVCAD's slicer-project compilers say about the machine, as fgslice uses it.

``PrusaSlicerProjectCompiler(root, voxel_size, output_file_path, num_regions=12, ...)`` and
``FullSpectrumSlicerProjectCompiler(root, voxel_size, output_file_path, filaments=None,
...)`` sample a design's attributes into piecewise-constant regions for PrusaSlicer or
OrcaSlicer. fgslice grades every attribute continuously, so the arguments that shape
those regions (``num_regions``, ``max_palette_size``, ``voxel_size``, recipes,
``region_overlap_mm``, profiles, the output path) are accepted and not used. Two say what
the machine holds, and fgslice uses them:

* the loaded filaments' colours, ``color_mix_filaments`` (Prusa) or ``filaments``
  (FullSpectrum), ``[{"slot": 1, "color_hex": "#rrggbb"}, ...]`` (slot: 1-based, the
  entry's position when absent): they become the setting ``filament_colors`` in slot
  order, which prints a ``COLOR_RGB`` attribute as their nearest mixture. Without them a
  design whose colour decides the mixture takes the compiler's documented default CMYKW
  set (:data:`DEFAULT_FILAMENTS`). A ``filament_colors`` given in a profile or with
  ``--set`` wins over both;
* ``volume_fraction_materials = {"red": 1, "blue": 2}``: the 1-based slot (channel, tool)
  of each material of the design's ``VOLUME_FRACTIONS``
  (:func:`fgslice.design.material_slots.slotted`).

:class:`SlicerProject` holds them as plain data; :func:`applied` gives a loaded design its
slots and remembers its project (:func:`project_of`), :func:`machine_settings` applies the
colours to a slice's settings and :func:`notes` says what ``check`` reports.
"""

from __future__ import annotations

import re
import weakref
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from fgslice.design.nodes import NOWHERE, Where
from fgslice.errors import DesignError, did_you_mean

PRUSA = "PrusaSlicerProjectCompiler"
FULL_SPECTRUM = "FullSpectrumSlicerProjectCompiler"

PARAMETERS = {
    PRUSA: ("root", "voxel_size", "output_file_path", "num_regions", "printer_profile_path", "filament_profile_path",
            "enable_color_mix", "color_mix_filaments", "total_physical_extruders", "color_mix_recipe_preset",
            "max_palette_size", "min_component_percent", "max_recipe_components", "direct_physical_delta_e",
            "region_overlap_mm", "volume_fraction_materials", "material_defs_path"),
    FULL_SPECTRUM: ("root", "voxel_size", "output_file_path", "filaments", "max_palette_size", "min_component_percent",
                    "max_recipe_components", "direct_physical_delta_e", "region_overlap_mm",
                    "base_project_settings_path", "orca_machine_profile_path", "orca_process_profile_path",
                    "orca_default_filament_profile_path", "orca_profile_search_paths", "volume_fraction_materials",
                    "material_defs_path"),
}
"""Each compiler's parameters in OpenVCAD's documented order (positional arguments bind so)."""

FILAMENTS = {PRUSA: "color_mix_filaments", FULL_SPECTRUM: "filaments"}
"""The argument naming the loaded filaments."""

DEFAULT_FILAMENTS = {
    PRUSA: ("#0082ad", "#d10f4f", "#efd00b", "#3d3e3d", "#e6eaef"),
    FULL_SPECTRUM: ("#00ffff", "#ff00ff", "#ffff00", "#000000", "#ffffff"),
}
"""The CMYKW filaments a compiler assumes for ``COLOR_RGB`` without a filament list:
Prusa's documented ColorMix defaults; FullSpectrum's CMYKW as its guide lists it."""

REGIONS = {PRUSA: ("num_regions", 12), FULL_SPECTRUM: ("max_palette_size", 32)}
"""The argument counting a compiler's stepwise regions, and its default."""


@dataclass(frozen=True)
class SlicerProject:
    """One slicer-project compiler call, as fgslice uses it.

    Attributes:
        compiler: the compiler's class name.
        regions: the region-count arguments given (``{"num_regions": 12}``), or the
            default one when none was.
        filament_colors: the given filaments' ``#rrggbb`` colours in slot order (empty
            when none were given).
        slots: ``volume_fraction_materials``: material name to 1-based slot (empty: the
            design's order).
        where: the script's line of the call.
    """

    compiler: str
    regions: dict[str, object]
    filament_colors: tuple[str, ...] = ()
    slots: dict[str, int] = field(default_factory=dict)
    where: Where = NOWHERE

    def default_colors(self) -> tuple[str, ...]:
        """The compiler's default filaments for a colour attribute."""
        return DEFAULT_FILAMENTS[self.compiler]


def parse(compiler: str, args: Sequence, kwargs: Mapping, where: Where) -> SlicerProject:
    """The :class:`SlicerProject` of ``compiler(*args, **kwargs)`` called at ``where``.

    Raises:
        DesignError: an argument OpenVCAD does not document for the compiler, too many
            positional arguments, or filaments / slots that are not as documented.
    """
    names = PARAMETERS[compiler]
    if len(args) > len(names):
        raise DesignError(f"pyvcad_compilers.{compiler} takes at most {len(names)} arguments, got {len(args)}",
                          **where.error_kwargs())
    given = dict(zip(names, args))
    for key, value in kwargs.items():
        if key not in names:
            raise DesignError(f"pyvcad_compilers.{compiler} has no argument '{key}'",
                              hint=did_you_mean(key, names) or f"its arguments: {', '.join(names)}",
                              **where.error_kwargs())
        if key in given:
            raise DesignError(f"pyvcad_compilers.{compiler}: '{key}' is given twice", **where.error_kwargs())
        given[key] = value
    counts = {k: given[k] for k in ("num_regions", "max_palette_size") if given.get(k) is not None}
    if not counts:
        key, default = REGIONS[compiler]
        counts = {key: default}
    filaments = given.get(FILAMENTS[compiler])
    colors = _filament_colors(FILAMENTS[compiler], filaments, where) if filaments else ()
    slots = given.get("volume_fraction_materials") or {}
    return SlicerProject(compiler, counts, colors, _slots(slots, where), where)


def _filament_colors(argument: str, filaments, where: Where) -> tuple[str, ...]:
    """The ``#rrggbb`` colours of OpenVCAD's filament dictionaries, in slot order."""
    if not isinstance(filaments, (list, tuple)) or not all(isinstance(f, Mapping) for f in filaments):
        raise DesignError(f"{argument} takes a list of dictionaries such as {{'slot': 1, 'color_hex': '#00ffff'}}, "
                          f"got {filaments!r}", **where.error_kwargs())
    by_slot = {}
    for position, entry in enumerate(filaments, start=1):
        slot, color = entry.get("slot", position), entry.get("color_hex")
        if not isinstance(color, str) or not re.fullmatch(r"#?[0-9a-fA-F]{6}", color.strip()):
            raise DesignError(f"{argument}: slot {slot} has color_hex {color!r}, not a '#rrggbb' colour",
                              **where.error_kwargs())
        if not isinstance(slot, int) or isinstance(slot, bool) or slot in by_slot:
            raise DesignError(f"{argument}: slot {slot!r} is not a slot number of its own",
                              hint="number the filaments' slots 1, 2, ...", **where.error_kwargs())
        by_slot[slot] = "#" + color.strip().lstrip("#").lower()
    if sorted(by_slot) != list(range(1, len(by_slot) + 1)):
        raise DesignError(f"{argument} fills slots {', '.join(map(str, sorted(by_slot)))}: fgslice takes one "
                          "filament colour per channel, 1, 2, ... n",
                          hint="number the slots from 1 without gaps, in the order the filaments are loaded",
                          **where.error_kwargs())
    return tuple(by_slot[slot] for slot in sorted(by_slot))


def _slots(mapping, where: Where) -> dict[str, int]:
    if not isinstance(mapping, Mapping) or not all(
            isinstance(k, str) and isinstance(v, int) and not isinstance(v, bool) for k, v in mapping.items()):
        raise DesignError(f"volume_fraction_materials takes material names and slot numbers, such as "
                          f"{{'red': 1, 'blue': 2}}, got {mapping!r}", **where.error_kwargs())
    return dict(mapping)


def applied(design, project: SlicerProject):
    """``design`` with ``project``'s material slots, remembered as compiled by it
    (:func:`project_of`).

    Raises:
        DesignError: the slots name a material the design lacks or leave gaps, at the
            compiler's line.
    """
    if project.slots:
        from fgslice.compat import context
        from fgslice.design.material_slots import slotted

        try:
            design = slotted(design, project.slots)
        except DesignError as error:
            raise context.locate(error, project.where) from None
    remember(design, project)
    return design


def design_colors(project: SlicerProject, design) -> tuple[str, ...]:
    """The filament colours ``project`` gives ``design``: the given ones, else the
    compiler's defaults when the design's colour decides the mixture, else none."""
    if project.filament_colors:
        return project.filament_colors
    from fgslice.design.attributes import attribute_fields
    from fgslice.design.color_mix import color_channels, colors_drive_mixture

    fields = attribute_fields(design)
    if fields is not None and color_channels(fields.names) and colors_drive_mixture(design):
        return project.default_colors()
    return ()


def machine_settings(project: SlicerProject | None, design, settings):
    """``settings`` with ``filament_colors`` from ``project`` (for ``design``) when the
    settings name none; an explicit ``filament_colors`` wins."""
    if project is None or settings.filament_colors:
        return settings
    import msgspec

    colors = design_colors(project, design)
    return msgspec.structs.replace(settings, filament_colors=",".join(colors)) if colors else settings


def notes(project: SlicerProject | None, design, settings) -> list[str]:
    """What ``fgslice check`` says about the compiler call: its regions are not used;
    where the filament colours come from."""
    if project is None:
        return []
    at = f" (line {project.where.line})" if project.where.line is not None else ""
    counts = ", ".join(f"{k}={v}" for k, v in project.regions.items())
    out = [f"{project.compiler}{at}: its stepwise regions ({counts}) are not used: fgslice grades every attribute "
           "continuously"]
    from fgslice.design.material_slots import MaterialSlots

    root = getattr(design, "root", None)
    if isinstance(root, MaterialSlots):
        kept = {name.lower() for name in root.materials}
        for name in root.inner.index:
            if name not in kept:
                out.append(f"material '{name}' has no slot in volume_fraction_materials: it is left out and the "
                           "other materials' fractions are normalized without it")
    colors = design_colors(project, design)
    if colors:
        source = FILAMENTS[project.compiler] if project.filament_colors else f"{project.compiler}'s default filaments"
        if settings.filament_colors and settings.filament_colors != ",".join(colors):
            out.append(f"filament colours {settings.filament_colors} from the profile or --set, not {source}")
        elif project.filament_colors:
            out.append(f"filament colours {','.join(colors)} from {source}")
        else:
            out.append(f"filament colours {','.join(colors)} from {source} (set filament_colors to the ones "
                       "loaded if they differ)")
    return out


_PROJECTS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def remember(design, project: SlicerProject) -> None:
    """Note that ``design`` was compiled by ``project`` (its script's compiler call)."""
    _PROJECTS[design] = project


def project_of(design) -> SlicerProject | None:
    """The slicer project ``design`` was loaded with, or None."""
    return _PROJECTS.get(design)
