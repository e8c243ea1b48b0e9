"""Attributes computed from other attributes: conflict resolution in overlaps and converters.

Both are pass-through nodes (geometry and materials are their child's) that the attribute
evaluation (:class:`fgslice.design.attributes.AttributeFields`) asks for the names they
produce:

* :class:`ResolveConflicts` over a union or intersection: where two or more children
  holding the attribute contain a point, their values are combined by a
  :class:`Reducer` (average, per-channel min / max, the child of least / greatest
  magnitude, or a pairwise function reduced in child order); elsewhere the union's rule
  (first child containing the point, else the nearest) decides. A group of names
  (the channels of one vector attribute) is resolved together.
* :class:`ConvertAttributes`: output attributes as a function of input attributes of the
  child at each point; where an input is undefined the child's own output (else the
  enclosing one) stays.
* :class:`AverageFractions` does for materials what an average resolver does for
  attributes: inside two or more children, the mean of their normalized fractions.

Values are float64 arrays over 1-D points of the node's frame; NaN means undefined.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from fgslice.design import nodes


class AttributeCarrier(nodes.Node):
    """A node that adds attributes over ``_body`` (its child, or its children's union)
    and keeps the body's geometry, as an fgrade does, and materials, as a transform does."""

    sdf = nodes.MaterialNode.sdf
    _bounds = nodes.MaterialNode._bounds
    _sections = nodes.MaterialNode._sections
    coordinate_free = nodes.Affine.coordinate_free
    can_be_void = nodes.Affine.can_be_void

    def raw(self, x, y, z, columns):
        return self._body.raw(x, y, z, columns)


class AttributeOperator(AttributeCarrier):
    """A node producing the attributes ``outputs`` over its child, which keeps its
    geometry and materials."""

    kind = "attribute_operator"
    outputs: tuple[str, ...] = ()

    def __init__(self, child: nodes.Node, where: nodes.Where = nodes.NOWHERE) -> None:
        super().__init__((child,), where)
        self._body = child

    def evaluate(self, fields, name: str, x, y, z, ctx: np.ndarray) -> np.ndarray:
        """Attribute ``name`` (one of :attr:`outputs`) at 1-D points; ``fields``: the
        evaluating :class:`~fgslice.design.attributes.AttributeFields`; ``ctx``: the
        enclosing value."""
        raise NotImplementedError


@dataclass(frozen=True)
class Reducer:
    """How values of overlapping children combine.

    ``mode``: ``"average"``, ``"min"``, ``"max"`` (per channel), ``"min_magnitude"``,
    ``"max_magnitude"`` (the whole vector of the child of least / greatest Euclidean
    norm), or ``"pairwise"``: ``functions[c](left, right)`` per channel ``c``, reduced
    left to right in child order (vectorized callables on arrays).
    """

    mode: str
    functions: tuple[Callable, ...] = ()

    def reduce(self, values: np.ndarray, present: np.ndarray) -> np.ndarray:
        """Combine ``values`` ``(children, points, channels)`` over the children where
        ``present`` ``(children, points)``; points with no child present give NaN."""
        masked = np.where(present[..., None], values, np.nan)
        if self.mode in ("average", "min", "max"):
            reduce = {"average": np.nanmean, "min": np.nanmin, "max": np.nanmax}[self.mode]
            out = np.full(values.shape[1:], np.nan)
            some = present.any(axis=0)
            out[some] = reduce(masked[:, some], axis=0)
            return out
        if self.mode in ("min_magnitude", "max_magnitude"):
            norm = np.sqrt(np.nansum(masked * masked, axis=2))
            norm = np.where(present, norm, np.inf if self.mode == "min_magnitude" else -np.inf)
            pick = np.argmin(norm, axis=0) if self.mode == "min_magnitude" else np.argmax(norm, axis=0)
            return np.take_along_axis(masked, pick[None, :, None], axis=0)[0]
        out = np.full(values.shape[1:], np.nan)
        for child in range(values.shape[0]):
            here = present[child]
            fresh = here & np.isnan(out[:, 0])
            out[fresh] = values[child, fresh]
            both = here & ~fresh
            if both.any():
                for c, function in enumerate(self.functions):
                    out[both, c] = np.asarray(function(out[both, c], values[child, both, c]), dtype=float)
        return out


class ResolveConflicts(AttributeOperator):
    """The attributes ``names`` (channels of one attribute) of a union or intersection
    ``child``, combined by ``reducer`` where several of its children hold them."""

    kind = "resolve_conflicts"

    def __init__(self, names: Sequence[str], reducer: Reducer, child: nodes.Node,
                 where: nodes.Where = nodes.NOWHERE) -> None:
        super().__init__(child, where)
        self.outputs = tuple(names)
        self.reducer = reducer

    def evaluate(self, fields, name, x, y, z, ctx):
        body = self._body
        out = fields._values(body, name, x, y, z, ctx)
        kids = [c for c in body.children if any(n in fields._below[id(c)] for n in self.outputs)]
        if len(kids) < 2:
            return out
        nan = np.full(len(x), np.nan)
        values = np.stack([np.stack([fields._values(kid, n, x, y, z, nan) for n in self.outputs], axis=1)
                           for kid in kids])
        inside = np.stack([np.broadcast_to(kid.sdf(x, y, z), np.shape(x)) <= 0 for kid in kids])
        present = inside & np.isfinite(values).all(axis=2)
        several = np.flatnonzero(present.sum(axis=0) >= 2)
        if several.size:
            resolved = self.reducer.reduce(values[:, several], present[:, several])
            out = out.copy()
            out[several] = resolved[:, self.outputs.index(name)]
        return out


class ConvertAttributes(AttributeOperator):
    """Attributes ``outputs`` computed by ``function`` from the child's attributes
    ``inputs`` at each point: ``function(list of input arrays) -> list of output arrays``."""

    kind = "convert_attributes"

    def __init__(self, inputs: Sequence[str], outputs: Sequence[str], function: Callable, child: nodes.Node,
                 where: nodes.Where = nodes.NOWHERE) -> None:
        super().__init__(child, where)
        self.inputs = tuple(inputs)
        self.outputs = tuple(outputs)
        self.function = function

    def evaluate(self, fields, name, x, y, z, ctx):
        nan = np.full(len(x), np.nan)
        inputs = [fields._values(self._body, n, x, y, z, nan) for n in self.inputs]
        converted = np.asarray(self.function(inputs)[self.outputs.index(name)], dtype=float)
        converted = np.broadcast_to(converted, np.shape(x))
        known = np.isfinite(converted) & np.all([np.isfinite(v) for v in inputs], axis=0)
        if known.all():
            return np.array(converted)
        return np.where(known, converted, fields._values(self._body, name, x, y, z, ctx))


class AverageFractions(nodes.MaterialNode):
    """The materials of a union or intersection ``child``, averaged (normalized
    fractions, equal weights) where two or more of its children contain a point."""

    kind = "average_fractions"
    coordinate_free = False

    def __init__(self, child: nodes.Node, where: nodes.Where = nodes.NOWHERE) -> None:
        super().__init__((child,), where)

    def raw(self, x, y, z, columns):
        body = self._body
        out = np.array(body.raw(x, y, z, columns), dtype=float)
        kids = body.children
        if len(kids) < 2:
            return out
        inside = np.stack([np.broadcast_to(kid.sdf(x, y, z), np.shape(x)) <= 0 for kid in kids])
        several = np.flatnonzero(inside.sum(axis=0) >= 2)
        if several.size:
            xs, ys, zs = x[several], y[several], z[several]
            total = np.zeros((several.size, columns.k))
            for kid, mask in zip(kids, inside[:, several]):
                if mask.any():
                    total[mask] += nodes.normalized(kid.raw(xs[mask], ys[mask], zs[mask], columns))
            out[several] = total / inside[:, several].sum(axis=0)[:, None]
        return out
