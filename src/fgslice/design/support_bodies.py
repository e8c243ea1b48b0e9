"""Support enforcers and blockers drawn in the design, as bodies of their own material.

OpenVCAD marks support with its ``support`` material (``default_materials.id("support")``:
the volume that is support, as its support analyzer writes it); PrusaSlicer users draw
support enforcers and blockers as modifier volumes. A design says both with materials:

* a body made only of ``support`` is an **enforcer**: support goes there, and under it
  down to what it stands on, whether the part overhangs there or not;
* a body made only of ``support_blocker`` is a **blocker**: no support there.

Neither is printed as part of the part, nor counts for its placement on the bed. A body
is a child of the design's top-level union (unions nested in it included) whose
primitives all name that material (or an fgrade of that material alone); elsewhere in
the tree the names are ordinary materials. Design frame, mm.
"""

from __future__ import annotations

from dataclasses import dataclass

from fgslice.design import nodes
from fgslice.errors import DesignError

SUPPORT = "support"
BLOCKER = "support_blocker"


@dataclass(frozen=True)
class SupportBodies:
    """A design split into the part and its support bodies (None where there are none)."""

    part: nodes.NodeDesign
    enforcers: nodes.NodeDesign | None = None
    blockers: nodes.NodeDesign | None = None


def _only_material(node: nodes.Node) -> str | None:
    """The one material every primitive of ``node``'s subtree is made of (lower case), or None."""
    found: set[str] = set()
    for child, _, overridden in nodes.walk(node):
        if overridden:
            continue
        if isinstance(child, nodes.Fgrade):
            found.update(name.lower() for name in child.materials)
        elif isinstance(child, nodes.Primitive):
            if child.material is None:
                return None
            found.add(child.material.lower())
    return found.pop() if len(found) == 1 else None


def _top_children(root: nodes.Node) -> list[nodes.Node]:
    """The bodies of the top-level union (nested unions opened), or ``[root]``."""
    if type(root) is not nodes.Union:
        return [root]
    return [leaf for child in root.children for leaf in _top_children(child)]


def split_support_bodies(design) -> SupportBodies:
    """``design`` without its support bodies, and those bodies (see the module); a design
    that is not a node tree, or has none, comes back as the part alone.

    Raises:
        DesignError: the design holds support bodies only (nothing to print).
    """
    root = getattr(design, "root", None)
    if not isinstance(design, nodes.NodeDesign) or root is None:
        return SupportBodies(design)
    bodies: dict[str | None, list[nodes.Node]] = {SUPPORT: [], BLOCKER: [], None: []}
    for body in _top_children(root):
        material = _only_material(body)
        bodies[material if material in (SUPPORT, BLOCKER) else None].append(body)
    if not bodies[SUPPORT] and not bodies[BLOCKER]:
        return SupportBodies(design)
    if not bodies[None]:
        raise DesignError("the design holds only support bodies ('support' / 'support_blocker'): nothing to print",
                          hint="union the support bodies with the part they hold", **root.where.error_kwargs())

    def tree(children: list[nodes.Node]) -> nodes.NodeDesign | None:
        if not children:
            return None
        node = children[0] if len(children) == 1 else nodes.Union(children, root.where)
        return nodes.NodeDesign(node, design.library, hint_bounds=design.hint_bounds, voxel_size=design.voxel_size,
                                section_spacing=design.section_spacing, source=design.source)

    return SupportBodies(tree(bodies[None]), tree(bodies[SUPPORT]), tree(bodies[BLOCKER]))
