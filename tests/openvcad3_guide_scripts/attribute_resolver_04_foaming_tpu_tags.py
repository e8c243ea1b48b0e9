import pyvcad as pv
import pyvcad_rendering as viz
import pyvcad_attribute_resolver as resolver

# "Built-in Modules and Tags": a shore-hardness design resolved for foaming TPU
design = pv.RectPrism(pv.Vec3(0.0, 0.0, 0.0), pv.Vec3(100.0, 30.0, 10.0))
design.set_attribute(pv.DefaultAttributes.SHORE_HARDNESS, pv.FloatAttribute("77 + 0.3 * x"))

resolver.clear_conversions()
resolver.register_foaming_conversions()
root = resolver.adapt(design, ["temperature", "flow_rate"], tags=["foaming_tpu"])
viz.Render(root)
