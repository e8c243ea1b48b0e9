"""The .vcad design language: grammar, parser and the builder of the node tree.

A file holds one node. A node is ``name(arguments)`` followed by ``{ children }`` for
operators, or an optional ``;`` for primitives. Arguments are numbers (``5``, ``.5``,
``5.``, ``-40``, ``1e1``), double-quoted strings (raw text, may span lines, no escapes),
vectors ``(a, b, c)`` and lists ``["a", "b"]``. Names are case-insensitive; ``//`` and
``/* */`` are comments. See ``docs/language.md`` for every primitive and operator.
"""

from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass
from pathlib import Path

import lark
import numpy as np

from fgslice.design import nodes
from fgslice.design.blend import Blend
from fgslice.design.lark_cache import cached_lark
from fgslice.design.materials import MaterialLibrary, builtin_library, load_library
from fgslice.design.statement_runs import PLACEHOLDER, StatementRun, find_runs
from fgslice.errors import DesignError, DesignSyntaxError, MeshError, did_you_mean

GRAMMAR = r"""
start: node*
node: NAME "(" [arg ("," arg)*] ")" (block | ";")?
block: "{" node* "}"
?arg: NUMBER -> number
    | STRING -> string
    | "(" arg ("," arg)* ")" -> vector
    | "[" [arg ("," arg)*] "]" -> list

NAME: /[A-Za-z_][A-Za-z_0-9]*/
NUMBER: /[+-]?([0-9]+(\.[0-9]*)?|\.[0-9]+)([eE][+-]?[0-9]+)?/
STRING: /"[^"]*"/
COMMENT: /\/\/[^\n]*/ | /\/\*(.|\n)*?\*\//
%ignore COMMENT
%ignore /\s+/
"""

_TOKEN_NAMES = {
    "LPAR": "'('",
    "RPAR": "')'",
    "LBRACE": "'{'",
    "RBRACE": "'}'",
    "LSQB": "'['",
    "RSQB": "']'",
    "COMMA": "','",
    "SEMICOLON": "';'",
    "NAME": "a name",
    "NUMBER": "a number",
    "STRING": "a string",
}


@functools.cache
def _parser() -> lark.Lark:
    return cached_lark(GRAMMAR, propagate_positions=True, maybe_placeholders=True)


@dataclass
class Arg:
    """One parsed argument: ``kind`` is number, string, vector or list."""

    kind: str
    value: object
    where: nodes.Where


_KIND_WORDS = {"number": "a number", "string": "a string", "vector": "a vector (a, b, c)", "list": "a list [...]"}


class _Builder:
    """Turns a lark parse tree into nodes, checking names, arguments and materials."""

    def __init__(self, text: str, file: str | None, library: MaterialLibrary, runs: list[StatementRun] = ()) -> None:
        self.lines = text.splitlines()
        self.file = file
        self.library = library
        self.base_dir = Path(file).resolve().parent if file else None
        self.hint_bounds = None
        self.voxel_size = None
        self.runs = runs
        self._line_starts = np.flatnonzero(np.frombuffer(text.encode("utf-32-le"), dtype=np.uint32) == 10) + 1 if runs else None

    def where(self, line: int, column: int) -> nodes.Where:
        source = self.lines[line - 1] if 0 < line <= len(self.lines) else None
        return nodes.Where(self.file, line, column, source)

    def where_at(self, offset: int) -> nodes.Where:
        """The location of character ``offset`` of the text (lines and columns from 1)."""
        line = int(np.searchsorted(self._line_starts, offset, side="right"))
        return self.where(line + 1, offset - (int(self._line_starts[line - 1]) if line else 0) + 1)

    # ------------------------------------------------------------------ arguments

    def arg(self, tree) -> Arg:
        if isinstance(tree, lark.Token):
            where = self.where(tree.line, tree.column)
            if tree.type == "NUMBER":
                value = float(tree)
                if not math.isfinite(value):
                    shown = tree if len(tree) <= 24 else tree[:20] + "..."
                    raise DesignSyntaxError(f"number too large: '{shown}'", hint="numbers must be below about 1.8e308",
                                            **where.error_kwargs())
                return Arg("number", value, where)
            inner = self.where(tree.line, tree.column + 1)
            return Arg("string", str(tree)[1:-1], inner)
        where = self.where(tree.meta.line, tree.meta.column)
        items = [self.arg(c) for c in tree.children if c is not None]
        if tree.data == "number":
            return self.arg(tree.children[0])
        if tree.data == "string":
            return self.arg(tree.children[0])
        return Arg(tree.data, items, where)

    # ---------------------------------------------------------------------- nodes

    def build(self, tree: lark.Tree, top: bool = False) -> nodes.Node:
        name_token = tree.children[0]
        name = str(name_token).lower()
        where = self.where(name_token.line, name_token.column)
        tail = tree.children[-1]
        block = tail if isinstance(tail, lark.Tree) and tail.data == "block" else None
        raw_args = tree.children[1:-1] if block is not None else tree.children[1:]
        args = [self.arg(a) for a in raw_args if a is not None]
        if name in _PRIMITIVES:
            if block is not None:
                raise DesignError(f"{name} is a primitive and takes no {{ }} block", **where.error_kwargs())
            return _PRIMITIVES[name](self, args, where)
        if name in _OPERATORS:
            children = []
            for c in block.children if block is not None else ():
                if str(c.children[0]) == PLACEHOLDER:
                    children += self.run_nodes(self.runs[int(c.children[1].children[0])], together=name in ("union", "root"))
                else:
                    children.append(self.build(c))
            if not children:
                raise DesignError(
                    f"{name} has no children",
                    hint=f"write {name}(...) {{ child; ... }} with at least one node inside",
                    **where.error_kwargs(),
                )
            return _OPERATORS[name](self, args, children, where, top)
        raise DesignError(
            f"unknown primitive or operator '{name_token}'",
            hint=did_you_mean(name, list(_PRIMITIVES) + list(_OPERATORS))
            or "known: " + ", ".join(list(_PRIMITIVES) + list(_OPERATORS)),
            **where.error_kwargs(),
        )

    def run_nodes(self, run: StatementRun, together: bool) -> list[nodes.Node]:
        """The nodes of a run of simple statements (:mod:`fgslice.design.statement_runs`):
        with ``together`` (the children of a union), :class:`~fgslice.design.copies.Copies`
        per stretch of one primitive kind and material when every number is in range;
        otherwise one ``translate`` and its primitive per statement, as parsed."""
        from fgslice.design.copies import Copies

        names = np.array(run.names)
        given = ~np.isnan(run.sizes)
        usable = (
            together
            and np.isfinite(run.offsets).all()
            and bool(np.all(np.isfinite(run.sizes) & (run.sizes > 0) | ~given))
        )
        materials = {}
        if usable:
            for i, material in enumerate(run.materials):
                if material is not None and material not in materials:
                    where = self.where_at(run.arguments(i)[2][-1][2])
                    materials[material] = self.library.get(material, **where.error_kwargs()).name
        if not usable:
            return [self._statement(run, i) for i in range(run.count)]
        shape = np.select([names == "sphere", names == "cylinder"], ["sphere", "cylinder"], "box")
        material = np.array([materials.get(m) or "" for m in run.materials], dtype=object)
        change = np.flatnonzero((shape[1:] != shape[:-1]) | (material[1:] != material[:-1])) + 1
        out = []
        for start, end in zip(np.r_[0, change], np.r_[change, run.count]):
            kind = str(shape[start])
            sizes = run.sizes[start:end]
            if kind == "box":
                sizes = np.where(np.isnan(sizes), sizes[:, :1], sizes)  # a cube's size on every axis
            elif kind == "sphere":
                sizes = sizes[:, :1]
            else:
                sizes = sizes[:, :2]
            out.append(Copies(kind, run.offsets[start:end], sizes, material[start] or None,
                              self.where_at(run.matches[start].start(4))))
        return out

    def _statement(self, run: StatementRun, i: int) -> nodes.Node:
        """Statement ``i`` of ``run`` built as the parser's path builds it."""
        numbers, (name, name_at), given = run.arguments(i)

        def arg(kind, text, offset):
            if kind == "number":
                return self.arg(lark.Token("NUMBER", text, line=(w := self.where_at(offset)).line, column=w.column))
            w = self.where_at(offset)
            return Arg("string", text, w)

        offset = [arg(*a) for a in numbers]
        primitive = _PRIMITIVES[name.lower()](self, [arg(*a) for a in given], self.where_at(name_at))
        return _OPERATORS["translate"](self, offset, [primitive], self.where_at(run.matches[i].start()), False)

    def field(self, arg: Arg) -> nodes.Field:
        """The compiled expression of string ``arg``, its errors showing the file's lines."""
        first = arg.where.line - 1
        return nodes.Field(arg.value, arg.where, file_lines=self.lines[first : first + arg.value.count("\n") + 1])

    def material(self, arg: Arg | None) -> str | None:
        if arg is None:
            return None
        return self.library.get(arg.value, **arg.where.error_kwargs()).name


def _plural(n: int) -> str:
    return f"{n} argument" + ("" if n == 1 else "s")


def _match(name: str, signature: str, args: list[Arg], patterns, where: nodes.Where, material: bool = False):
    """The values of ``args`` for the first pattern they fit, plus the optional material.

    ``patterns``: tuples of kinds ("number", "string", "vector3", "list"). With
    ``material``, a trailing string argument may follow any pattern.
    """
    candidates = []
    for pattern in patterns:
        candidates.append((pattern, args, None))
        if material and len(args) == len(pattern) + 1:
            candidates.append((pattern, args[:-1], args[-1]))
    mismatch = None
    for pattern, given, mat in candidates:
        if len(given) != len(pattern):
            continue
        problem = _first_mismatch(pattern, given)
        if problem is None and (mat is None or mat.kind == "string"):
            return [_value(a) for a in given], mat
        if problem is None:
            problem = (len(given), mat, "string")
        mismatch = mismatch or problem
    if mismatch is not None:
        index, arg, wanted = mismatch
        word = "a vector of 3 numbers" if wanted == "vector3" else _KIND_WORDS.get(wanted, wanted)
        got = _KIND_WORDS[arg.kind]
        if arg.kind == "vector":
            got = f"a vector of {len(arg.value)} items"
        raise DesignError(
            f"{name} takes {signature}: argument {index + 1} must be {word}, got {got}",
            **arg.where.error_kwargs(),
        )
    raise DesignError(f"{name} takes {signature}, got {_plural(len(args))}", **where.error_kwargs())


def _first_mismatch(pattern, args):
    for i, (kind, arg) in enumerate(zip(pattern, args)):
        if kind == "vector3":
            if arg.kind != "vector" or len(arg.value) != 3 or any(v.kind != "number" for v in arg.value):
                return i, arg, kind
        elif kind == "list":
            if arg.kind != "list" or any(v.kind != "string" for v in arg.value):
                return i, arg, "list of strings"
        elif arg.kind != kind:
            return i, arg, kind
    return None


def _value(arg: Arg):
    if arg.kind == "vector":
        return tuple(v.value for v in arg.value)
    if arg.kind == "list":
        return list(arg.value)
    return arg.value


def _positive(name: str, what: str, value: float, where: nodes.Where) -> float:
    if not value > 0:
        raise DesignError(f"{name}: {what} must be positive, got {value:g}", **where.error_kwargs())
    return value


# -------------------------------------------------------------------- primitives


def _sphere(b: _Builder, args, where):
    (r,), mat = _match("sphere", "(r[, material])", args, [("number",)], where, material=True)
    return nodes.Sphere(_positive("sphere", "r", r, where), b.material(mat), where)


def _cube(b: _Builder, args, where):
    (s,), mat = _match("cube", "(size[, material])", args, [("number",)], where, material=True)
    return nodes.Box([_positive("cube", "size", s, where)] * 3, b.material(mat), where)


def _rectprism(b: _Builder, args, where):
    values, mat = _match(
        "rectprism",
        "((sx, sy, sz)[, material]) or (sx, sy, sz[, material])",
        args,
        [("vector3",), ("number", "number", "number")],
        where,
        material=True,
    )
    size = values[0] if len(values) == 1 else values
    size = [_positive("rectprism", axis, v, where) for axis, v in zip(("sx", "sy", "sz"), size)]
    return nodes.Box(size, b.material(mat), where)


def _cylinder(b: _Builder, args, where):
    (r, h), mat = _match("cylinder", "(r, h[, material])", args, [("number", "number")], where, material=True)
    return nodes.Cylinder(_positive("cylinder", "r", r, where), _positive("cylinder", "h", h, where), b.material(mat), where)


def _strut(b: _Builder, args, where):
    (a, c, r), mat = _match(
        "strut", "((x0, y0, z0), (x1, y1, z1), r[, material])", args, [("vector3", "vector3", "number")], where, True
    )
    return nodes.Strut(a, c, _positive("strut", "r", r, where), b.material(mat), where)


def _function(b: _Builder, args, where):
    (lo, hi, text), mat = _match(
        "function",
        '((x0, y0, z0), (x1, y1, z1), "expression"[, material])',
        args,
        [("vector3", "vector3", "string")],
        where,
        material=True,
    )
    if any(h <= l for l, h in zip(lo, hi)):
        raise DesignError(
            "function: the box's first corner must be below the second on every axis",
            **args[0].where.error_kwargs(),
        )
    field = b.field(args[2])
    return nodes.FunctionShape(lo, hi, field, b.material(mat), where)


def _mesh(b: _Builder, args, where):
    (name,), mat = _match("mesh", '("file"[, material])', args, [("string",)], where, material=True)
    path = resolve_mesh_path(name, b.base_dir, args[0].where)
    from fgslice.design.cad import is_cad_file, load_cad
    from fgslice.design.mesh import load_mesh

    try:
        geometry = load_cad(path) if is_cad_file(path) else load_mesh(path)
    except (MeshError, DesignError) as exc:  # a DesignError: a CAD file without the cad extra
        raise type(exc)(f"mesh '{name}': {exc.message}", hint=exc.hint, **args[0].where.error_kwargs()) from None
    return nodes.MeshShape(geometry, str(path), b.material(mat), where)


def resolve_mesh_path(name: str, base_dir: Path | None, where: nodes.Where = nodes.NOWHERE) -> Path:
    """A mesh file: absolute, else relative to ``base_dir`` (the design's folder), else to the
    cwd, else to a folder above ``base_dir`` (OpenVCAD's legacy designs name meshes from its
    resources root, e.g. ``examples/data/3d_models/gear.stl`` from a design three folders
    below it)."""
    path = Path(name)
    candidates = [path] if path.is_absolute() else ([base_dir / path] if base_dir else []) + [Path.cwd() / path]
    above = [] if path.is_absolute() or base_dir is None else [folder / path for folder in Path(base_dir).resolve().parents]
    for candidate in candidates + above:
        if candidate.is_file():
            return candidate
    raise MeshError(
        f"mesh file not found: '{name}'",
        hint="looked in " + ", ".join(str(c.parent.resolve()) for c in candidates)
             + (" and the folders above the design's" if above else "")
             + "; put the file there, or give its path (absolute, or relative to the design's folder)",
        **where.error_kwargs(),
    )


# --------------------------------------------------------------------- operators


def _boolean(cls):
    def make(b: _Builder, args, children, where, top):
        _match(cls.kind, "()", args, [()], where)
        return cls(children, where)

    return make


def _root(b: _Builder, args, children, where, top):
    lo, hi, voxel = _match(
        "root", "((minx, miny, minz), (maxx, maxy, maxz), (vx, vy, vz))", args, [("vector3",) * 3], where
    )[0]
    if top:
        b.hint_bounds, b.voxel_size = (lo, hi), voxel
    return nodes.Union(children, where)


def _vector_op(cls, name: str, allow_uniform: bool = False):
    signature = f"({name[0]}x, {name[0]}y, {name[0]}z) or (({name[0]}x, {name[0]}y, {name[0]}z))"
    if cls is nodes.Rotate:
        signature = "(pitch, yaw, roll) in degrees"
    patterns = [("number", "number", "number"), ("vector3",)] + ([("number",)] if allow_uniform else [])

    def make(b: _Builder, args, children, where, top):
        values = _match(name, signature, args, patterns, where)[0]
        vector = values[0] if len(values) == 1 and isinstance(values[0], tuple) else values
        if len(vector) == 1:
            vector = vector * 3
        if cls is nodes.Scale and any(v == 0 for v in vector):
            raise DesignError("scale: factors must be non-zero", **where.error_kwargs())
        return cls(vector, children, where)

    return make


def _blend(b: _Builder, args, children, where, top):
    values = _match(
        "blend", "(sx, sy, sz), ((sx, sy, sz)) or (s) in mm", args,
        [("number", "number", "number"), ("vector3",), ("number",)], where,
    )[0]
    size = values[0] if isinstance(values[0], tuple) else tuple(values) * (3 // len(values))
    if any(v < 0 for v in size) or not any(v > 0 for v in size):
        raise DesignError(
            f"blend: sizes must be >= 0 with at least one positive, got {', '.join(f'{v:g}' for v in size)}",
            **where.error_kwargs(),
        )
    return Blend(size, children, where)


def _fgrade(b: _Builder, args, children, where, top):
    _match(
        "fgrade",
        '(["expr", ...], ["material", ...][, "prob" | "thresh"])',
        args,
        [("list", "list"), ("list", "list", "string")],
        where,
    )
    exprs, mats = args[0].value, args[1].value
    if not exprs:
        raise DesignError("fgrade needs at least one expression", **args[0].where.error_kwargs())
    if len(exprs) != len(mats):
        raise DesignError(
            f"fgrade has {len(exprs)} expressions but {len(mats)} materials",
            hint="give one expression per material, in the same order",
            **args[1].where.error_kwargs(),
        )
    mode = "prob"
    if len(args) == 3:
        mode = args[2].value.strip().lower()
        if mode not in ("prob", "thresh"):
            raise DesignError(
                f"fgrade mode must be \"prob\" or \"thresh\", got \"{args[2].value}\"",
                hint=did_you_mean(mode, ["prob", "thresh"]),
                **args[2].where.error_kwargs(),
            )
    names = [b.material(m) for m in mats]
    seen: set[str] = set()
    for name, m in zip(names, mats):
        if name.lower() in seen:
            raise DesignError(f"material '{name}' appears twice in this fgrade", **m.where.error_kwargs())
        seen.add(name.lower())
    fields = [b.field(e) for e in exprs]
    return nodes.Fgrade(fields, names, children, mode, where)


def _attribute(b: _Builder, args, children, where, top):
    from fgslice.design.attributes import Attribute

    (name, value), _ = _match("attribute", '("name", "expr" | number)', args, [("string", "string"), ("string", "number")], where)
    source = value if args[1].kind == "string" else repr(float(value))
    return Attribute(name, nodes.Field(source, args[1].where), children, args[0].where)


_PRIMITIVES = {
    "sphere": _sphere,
    "cube": _cube,
    "rectprism": _rectprism,
    "cylinder": _cylinder,
    "mesh": _mesh,
    "function": _function,
    "strut": _strut,
}

_OPERATORS = {
    "root": _root,
    "union": _boolean(nodes.Union),
    "intersection": _boolean(nodes.Intersection),
    "difference": _boolean(nodes.Difference),
    "translate": _vector_op(nodes.Translate, "translate"),
    "rotate": _vector_op(nodes.Rotate, "rotate"),
    "scale": _vector_op(nodes.Scale, "scale", allow_uniform=True),
    "fgrade": _fgrade,
    "attribute": _attribute,
    "blend": _blend,
}


# ------------------------------------------------------------------------- entry


def _syntax_error(exc: lark.exceptions.LarkError, text: str, file: str | None) -> DesignSyntaxError:
    lines = text.splitlines()
    line = getattr(exc, "line", None)
    column = getattr(exc, "column", None)
    at_end = isinstance(exc, lark.exceptions.UnexpectedEOF) or (
        isinstance(exc, lark.exceptions.UnexpectedToken) and exc.token.type == "$END"
    )
    if line is None or line < 1 or at_end:
        line = max(len(lines), 1)
        column = len(lines[-1]) + 1 if lines else 1
    source = lines[line - 1] if 0 < line <= len(lines) else ""
    hint = None
    if isinstance(exc, lark.exceptions.UnexpectedCharacters):
        char = exc.char
        if char == '"':
            message = "unterminated string: a '\"' has no closing quote"
        elif text[exc.pos_in_stream : exc.pos_in_stream + 2] == "/*":
            message = "unterminated comment: '/*' has no closing '*/'"
        else:
            message = f"unexpected character {char!r}"
    elif isinstance(exc, lark.exceptions.UnexpectedToken) and exc.token.type != "$END":
        message = f"unexpected {exc.token.value!r}"
        expected = sorted({_TOKEN_NAMES.get(t, t) for t in exc.expected if t != "$END"})
        if expected:
            hint = "expected " + " or ".join(expected)
    else:
        message = "unexpected end of file"
        expected = sorted({_TOKEN_NAMES.get(t, t) for t in getattr(exc, "expected", ()) if t != "$END"})
        if expected:
            hint = "expected " + " or ".join(expected)
    return DesignSyntaxError(message, file=file, line=line, column=column, source_line=source, hint=hint)


def _check_depth(tree: lark.Tree, builder: _Builder) -> None:
    """Refuse trees nested deeper than :data:`nodes.MAX_DEPTH` before building them."""
    stack = [(c, 1) for c in tree.children]
    while stack:
        node, depth = stack.pop()
        if depth > nodes.MAX_DEPTH:
            token = node.children[0]
            raise DesignError(
                f"the design nests more than {nodes.MAX_DEPTH} levels deep",
                hint="flatten the tree: a union takes any number of children",
                **builder.where(token.line, token.column).error_kwargs(),
            )
        block = node.children[-1]
        if isinstance(block, lark.Tree) and block.data == "block":
            stack.extend((c, depth + 1) for c in block.children)


def _library(materials) -> MaterialLibrary:
    if materials is None:
        return builtin_library()
    if isinstance(materials, MaterialLibrary):
        return materials
    return load_library(materials)


MAX_DESIGN_CHARS = 5_000_000
"""Longest design text accepted (characters); larger files are refused before parsing."""

_STRINGS_AND_COMMENTS = re.compile(r'"[^"]*"|//[^\n]*|/\*.*?\*/', re.DOTALL)


def _check_size_and_nesting(text: str, file: str | None) -> None:
    """Refuse huge texts and blocks nested deeper than :data:`nodes.MAX_DEPTH` before the
    parser spends time on them (a linear scan of the braces outside strings and comments)."""
    if len(text) > MAX_DESIGN_CHARS:
        raise DesignSyntaxError(
            f"the design is {len(text):,} characters long; the limit is {MAX_DESIGN_CHARS:,}",
            file=file, hint="large geometry belongs in a mesh file: mesh(\"part.stl\")",
        )
    code = np.frombuffer(_STRINGS_AND_COMMENTS.sub(lambda m: " " * len(m.group(0)), text).encode("utf-32-le"), dtype=np.uint32)
    depth = np.cumsum((code == ord("{")).astype(np.int32) - (code == ord("}")))
    deepest = int(np.argmax(depth)) if len(depth) else 0
    if len(depth) and depth[deepest] > nodes.MAX_DEPTH:
        first = int(np.argmax(depth > nodes.MAX_DEPTH))
        line = text.count("\n", 0, first) + 1
        column = first - (text.rfind("\n", 0, first) + 1) + 1
        raise DesignError(
            f"the design nests more than {nodes.MAX_DEPTH} levels deep",
            file=file, line=line, column=column, source_line=text.splitlines()[line - 1],
            hint="flatten the tree: a union takes any number of children",
        )


def parse_design(
    text: str,
    *,
    file: str | Path | None = None,
    materials: MaterialLibrary | str | Path | None = None,
) -> nodes.NodeDesign:
    """Parse .vcad ``text`` into a design.

    Args:
        text: the design source.
        file: its path, for error locations and to resolve relative mesh paths.
        materials: a library, or a JSON materials file extending the built-in library.

    Raises:
        DesignSyntaxError, DesignError, MeshError: with file:line:column where known.
    """
    file = str(file) if file is not None else None
    library = _library(materials)
    if "\x00" in text:
        raise DesignSyntaxError("the design is not a text file (it contains NUL bytes)", file=file)
    _check_size_and_nesting(text, file)
    parsed, runs = find_runs(text)
    try:
        tree = _parser().parse(parsed)
    except lark.exceptions.LarkError as exc:
        raise _syntax_error(exc, text, file) from None
    if not tree.children:
        raise DesignError("the design is empty", file=file, hint="write one node, e.g. sphere(10);")
    builder = _Builder(text, file, library, runs)
    if len(tree.children) > 1:
        token = tree.children[1].children[0]
        raise DesignError(
            f"a design holds one node, found {len(tree.children)} at the top level",
            hint="wrap them in union() { ... }",
            **builder.where(token.line, token.column).error_kwargs(),
        )
    _check_depth(tree, builder)
    root = builder.build(tree.children[0], top=True)
    return nodes.NodeDesign(
        root, library, hint_bounds=builder.hint_bounds, voxel_size=builder.voxel_size, source=file
    )


def load_design(path: str | Path, materials_file: str | Path | None = None) -> nodes.NodeDesign:
    """Read and parse the .vcad file at ``path`` (see :func:`parse_design`)."""
    path = Path(path)
    return parse_design(read_design_text(path), file=path, materials=materials_file)


def read_design_text(path: Path, hint: str = "a .vcad design is UTF-8 text") -> str:
    """The text of the design file at ``path``; a clear error when it is missing,
    unreadable or not UTF-8 (``hint`` says what the file should be)."""
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise DesignError(f"design file not found: {path}", file=path) from None
    except OSError as exc:
        raise DesignError(f"cannot read design file: {exc.strerror}", file=path) from None
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise DesignSyntaxError(
            f"the design is not a text file (invalid UTF-8 at byte {exc.start})", file=path, hint=hint
        ) from None
