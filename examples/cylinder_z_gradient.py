# examples/cylinder_z_gradient.vcad written as an OpenVCAD Python script: a cylinder
# (r 15 mm, h 70 mm) graded blue -> yellow along its height. fgslice runs it unchanged:
#   fgslice slice examples/cylinder_z_gradient.py
import pyvcad as pv
import pyvcad_rendering as viz

materials = pv.default_materials

# Centred at z = 35, so z runs from 0 to 70 in the grade's frame and z/70 stays in [0, 1].
# The material id 1 is OpenVCAD's default: the cylinder takes the grade's fractions.
cylinder = pv.Cylinder(pv.Vec3(0, 0, 35), 15, 70, 1)

root = pv.FGrade(["z/70", "1 - z/70"], [materials.id("blue"), materials.id("yellow")], True)
root.set_child(cylinder)

viz.Render(root, materials)
