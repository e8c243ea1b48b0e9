import pyvcad as pv
import pyvcad_rendering as viz
import pyvcad_attribute_resolver as resolver

# "J750 Modulus and Toughness Inverse Design": a custom table, registered, then used
resolver.generate_j750_modulus_toughness_lookup_table(
    output_path="j750_modulus_toughness_custom.json",
    table_size=192,
    max_liquid_volume=0.25,
    fail_threshold=0.05,
)
resolver.register_j750_modulus_toughness_conversions(
    lookup_table_path="j750_modulus_toughness_custom.json",
)

design = pv.RectPrism(pv.Vec3(0.0, 0.0, 0.0), pv.Vec3(100.0, 30.0, 10.0))
design.set_attribute(pv.DefaultAttributes.MODULUS, pv.FloatAttribute("10 ** (0.5 + x / 100)"))
design.set_attribute(pv.DefaultAttributes.TOUGHNESS, pv.FloatAttribute(2.0))
root = resolver.adapt(design, ["volume_fractions"], tags=["j750_modulus_toughness"])
viz.Render(root)
