"""The helper of OpenVCAD's conformal-mesh examples that the guide imports, rebuilt from
its description: ``disk_surface(radius, rings, segments, height)`` is a round patch of
``rings`` rings of ``segments`` vertices around a centre vertex, at ``z = height(x, y)``,
triangles ordered so that the patch faces +Z."""

import math

import pyvcad as pv


def disk_surface(radius, rings, segments, height):
    vertices = [pv.Vec3(0.0, 0.0, height(0.0, 0.0))]
    for ring in range(1, rings + 1):
        r = radius * ring / rings
        for k in range(segments):
            x, y = r * math.cos(2 * math.pi * k / segments), r * math.sin(2 * math.pi * k / segments)
            vertices.append(pv.Vec3(x, y, height(x, y)))
    triangles = [(0, 1 + k, 1 + (k + 1) % segments) for k in range(segments)]
    for ring in range(1, rings):
        inner, outer = 1 + (ring - 1) * segments, 1 + ring * segments
        for k in range(segments):
            a, b = inner + k, inner + (k + 1) % segments
            c, d = outer + k, outer + (k + 1) % segments
            triangles += [(a, c, d), (a, d, b)]
    return pv.TriangleMeshSurface(vertices, triangles)
