import os
import shutil

import pyvcad as pv
import pyvcad_attribute_resolver as resolver
import pyvcad_compilers as pvc
import pyvcad_rendering as viz

materials = pv.j750_materials

bar_length = 100.0
bar_width = 30.0
bar_height = 10.0

# Use the overlap between the two target models so the same design-intent field
# can be compiled without clamping on either backend.
shore_min = 62.0
shore_max = 92.0
shore_span = shore_max - shore_min
shore_expr = (
    f"max(min(({shore_span:.8f} * (x + {bar_length / 2.0:.8f}) / {bar_length:.8f}) + "
    f"{shore_min:.8f}, {shore_max:.8f}), {shore_min:.8f})"
)


def make_shore_hardness_bar():
    bar = pv.RectPrism(pv.Vec3(0.0, 0.0, 0.0), pv.Vec3(bar_length, bar_width, bar_height))
    bar.set_attribute(
        pv.DefaultAttributes.SHORE_HARDNESS,
        pv.FloatAttribute(shore_expr),
    )
    return bar


# Target 1: foaming TPU on filament hardware -> temperature + flow_rate
resolver.clear_conversions()
resolver.register_tpu_conversions()
slicer_root = resolver.adapt(
    make_shore_hardness_bar(),
    ["temperature", "flow_rate"],
    tags=["foaming_tpu"],
)

# Target 2: J750 inkjet hardware -> volume fractions
resolver.clear_conversions()
resolver.register_j750_shore_hardness_conversions(
    material_defs=materials,
    agilus_material="Agilus30Mgn",
    vero_material="VeroYellow",
)
inkjet_root = resolver.adapt(
    make_shore_hardness_bar(),
    ["volume_fractions"],
    tags=["j750_shore_hardness"],
)

root = slicer_root
viz.Render(root)

_here = os.path.dirname(os.path.abspath(__file__))
output_dir = os.path.join(_here, "output")
os.makedirs(output_dir, exist_ok=True)

profiles_dir = os.path.normpath(
    os.path.join(_here, "..", "applications", "foaming_filaments", "profiles")
)
printer_profile_path = os.path.join(profiles_dir, "prusa_mk4s_profile.ini")
filament_profile_path = os.path.join(profiles_dir, "ColorFabb_VarioShore_TPU.ini")

slicer_output_path = os.path.join(output_dir, "cross_compilation_shore_hardness_tpu.3mf")
slicer_compiler = pvc.PrusaSlicerProjectCompiler(
    slicer_root,
    pv.Vec3(0.25, 0.25, 0.25),
    slicer_output_path,
    10,
    printer_profile_path,
    filament_profile_path,
)
slicer_compiler.compile()

inkjet_output_dir = os.path.join(output_dir, "cross_compilation_shore_hardness_j750_slices")
if os.path.isdir(inkjet_output_dir):
    shutil.rmtree(inkjet_output_dir)
os.makedirs(inkjet_output_dir, exist_ok=True)

inkjet_compiler = pvc.MaterialInkjetCompiler(
    inkjet_root,
    pv.Vec3(0.15, 0.15, 0.15),
    inkjet_output_dir,
    "slice_",
    materials,
    0.0,
)
inkjet_compiler.compile()
