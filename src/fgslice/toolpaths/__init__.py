"""Toolpaths: walls, skins, infill, the two strategies, zippers."""
