import pyvcad_metamaterials as mm

report = mm.properties.characterize_graph_cell(
    "octet",
    cell_size=16.0,
    beam_radius=0.8,
)

print(report.node_count)
print(report.strut_count)
print(report.degree_histogram)
print(report.mean_aspect_ratio)
print(report.mean_slenderness_ratio)
