"""Slicing: layer outlines, the palette, and per-color faces."""
