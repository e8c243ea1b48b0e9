import pyvcad as pv
import pyvcad_metamaterials as mm
import pyvcad_rendering as viz

# every named cell of the catalog on a map of its own, side by side (the guide's galleries)
parts = []
for row, names in enumerate((mm.TPMS_NAMES, mm.LATTICE_NAMES)):
    for column, name in enumerate(names):
        x, y = column * 12.0, row * 12.0
        cell_map = mm.rectangular_cell_map((pv.Vec3(x, y, 0.0), pv.Vec3(x + 10.0, y + 10.0, 5.0)), cell_size=5.0)
        if row == 0:
            parts.append(mm.tpms(cell_map, name, wall_thickness=0.8))
        else:
            parts.append(mm.graph_lattice(cell_map, name, beam_radius=0.5))
viz.Render(pv.Union(False, parts))
