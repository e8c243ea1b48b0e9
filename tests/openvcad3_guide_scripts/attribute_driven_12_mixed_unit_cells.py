import pyvcad as pv
import pyvcad_metamaterials as mm
import pyvcad_rendering as viz

# "Mix unit cells with a scalar control" on a six-cell map
cell_map = mm.rectangular_cell_map(
    (pv.Vec3(-24.0, -8.0, -8.0), pv.Vec3(24.0, 8.0, 8.0)),
    cells=(6, 2, 2),
)

weight = mm.ramp(
    2.5,
    3.5,
    axis="u",
    coordinates=cell_map.logical_position,
)
mixed_cell = pv.ImplicitUnitCell.mixed(
    pv.ImplicitUnitCell.standard("gyroid"),
    pv.ImplicitUnitCell.standard("schwarz_d"),
    weight,
)
root = mm.tpms(cell_map, mixed_cell, wall_thickness=1.2)
viz.Render(root)
