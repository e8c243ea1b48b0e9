import pyvcad as pv
import pyvcad_metamaterials as mm

# Earlier builder style
root = mm.gyroid(cell=10.0, thickness=1.2, size=30.0)
