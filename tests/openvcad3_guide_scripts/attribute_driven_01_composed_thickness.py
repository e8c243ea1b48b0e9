import pyvcad as pv
import pyvcad_metamaterials as mm
import pyvcad_rendering as viz

# "Compose scalar attributes": the composed control grades a gyroid's wall across X
cell_map = mm.rectangular_cell_map(
    (pv.Vec3(-24.0, -8.0, -8.0), pv.Vec3(24.0, 8.0, 8.0)),
    cells=(6, 2, 2),
)

x_position = pv.FloatAttribute("x")
position_01 = x_position.normalize(-24.0, 24.0)
curved_position = position_01 ** 2
thickness = curved_position.map_range(0.0, 1.0, 0.55, 1.65)
bounded_thickness = thickness.clamp(0.55, 1.65)

combined = pv.DerivedFloatAttribute(
    "base + gain * signal",
    {
        "base": 0.4,
        "gain": 0.8,
        "signal": position_01,
    },
)

root = mm.gyroid(cell_map, wall_thickness=bounded_thickness)
root.set_attribute("combined", combined)
viz.Render(root)
