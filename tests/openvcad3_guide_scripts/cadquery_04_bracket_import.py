import pyvcad as pv
import pyvcad_rendering as viz

# bracket_import.py: the bundled bracket file next to the script
cad_format = "step"  # Change to "iges" to load the alternate file.
model_path = f"bracket.{cad_format}"
root = pv.CAD(str(model_path), use_fast_mode=True)
root.set_attribute(
    pv.DefaultAttributes.MODULUS,
    pv.FloatAttribute("900.0 + 1700.0 * clamp(z / 32.0, 0, 1)"),
)

viz.Render(root)
