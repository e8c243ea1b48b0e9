"""The browser viewer: a local web page showing a G-code file's toolpaths in 3D.

:class:`ViewerServer` reads the G-code once (:func:`fgslice.machine.gcode_reader.read_gcode`)
and serves, on 127.0.0.1 only, the page (``preview/assets/``: HTML, JS, CSS and a
vendored three.js, so it works offline) and the data the page draws:

``/data/meta.json``
    layer count and tops z (mm), the index of each layer's first extrusion and travel
    segment, the roles, the machine states (label, display color, tool), the tools,
    the bounding box (mm) and the statistics from the file's comments.
``/data/extrusions.bin``, ``/data/travels.bin``
    little-endian Float32 ``(S, 2, 3)``: start and end xyz (mm) of every segment,
    sorted by layer (stable, so printing order within a layer), so that a layer range
    is one contiguous draw range.
``/data/states.bin``
    little-endian Uint16 (Uint32 if a file has 65536 states or more, see
    ``meta["state_bytes"]``): machine state of each extrusion segment.
``/data/roles.bin``
    Uint8: 1 + the ``;TYPE:`` role of each extrusion segment (0: none).

A segment is an extrusion when it moves and has positive E, a travel when it moves
without; moves before the first layer change belong to layer 0. Display colors of
states are the design's materials (``; materials = a,b`` header comment, looked up in
the built-in library) mixed by the state's composition in linear sRGB, as
:mod:`fgslice.analysis.fidelity` mixes them: the palette center of the ``;STATE:``
color when the header gives ``; colors = N``, else the normalized ``M165``/``M163``
mix, else the tool's material.
"""

from __future__ import annotations

import colorsys
import errno
import json
import os
import re
import threading
import webbrowser
from collections.abc import Callable
from dataclasses import dataclass
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from pathlib import Path
from urllib.parse import urlsplit

import numpy as np

from fgslice.colors import linear_to_srgb, mix_linear
from fgslice.design.materials import builtin_library
from fgslice.errors import FgsliceError
from fgslice.machine.gcode_header import GcodeHeader, read_footer, read_header
from fgslice.machine.gcode_reader import GcodeProgram, MachineState, read_gcode
from fgslice.slicing.palette import LETTERS
from fgslice.slicing.states import header_palette

HOST = "127.0.0.1"

ROLE_COLORS = {
    "External perimeter": (255, 125, 56),
    "Perimeter": (255, 230, 77),
    "Overhang perimeter": (0, 0, 255),
    "Internal infill": (176, 48, 41),
    "Solid infill": (150, 84, 204),
    "Top solid infill": (240, 64, 64),
    "Bottom solid infill": (107, 79, 187),
    "Bridge infill": (77, 128, 186),
    "Gap fill": (255, 255, 255),
    "Skirt/Brim": (0, 135, 110),
    "Skirt": (0, 135, 110),
    "Wipe tower": (179, 227, 171),
    "Support material": (0, 255, 0),
    "Support material interface": (0, 128, 0),
    "Custom": (94, 209, 148),
}
"""Display colors (sRGB 0-255) of PrusaSlicer's ``;TYPE:`` names, after its defaults."""

_MIME = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8",
         ".css": "text/css; charset=utf-8", "": "text/plain; charset=utf-8"}
_HEADER_STATS = ("materials", "colors", "dialect", "profile_name", "strategy", "layer_height", "bead_width")


class ViewerError(FgsliceError):
    """The viewer cannot serve (address in use, port not allowed)."""


@dataclass(frozen=True)
class ViewerData:
    """What the page fetches: ``meta`` (JSON-able) and binary ``buffers`` by route name."""

    meta: dict
    buffers: dict[str, bytes]


def categorical_colors(n: int) -> list[tuple[int, int, int]]:
    """``n`` distinct sRGB colors (0-255): hues spaced by the golden angle."""
    hues = (np.arange(n) * 0.618033988749895) % 1.0
    return [tuple(int(round(255 * c)) for c in colorsys.hsv_to_rgb(h, 0.65, 0.95)) for h in hues]


def mix_colors(fractions: np.ndarray, rgb: np.ndarray) -> np.ndarray:
    """sRGB colors (0-255 uint8, ``(..., 3)``) of compositions ``(..., k)`` of materials
    whose sRGB colors (0-1) are ``rgb`` ``(k, 3)``, mixed linearly in linear sRGB."""
    return np.round(255 * linear_to_srgb(mix_linear(fractions, rgb))).astype(np.uint8)


def _material_colors(header: GcodeHeader) -> tuple[list[str], np.ndarray | None]:
    """Material names of the ``materials`` header comment and their sRGB colors (0-1),
    gray for names the built-in library does not know; None without the comment."""
    names = list(header.materials)
    if not names:
        return [], None
    library = builtin_library()
    known = {n.lower() for n in library.names}
    rgb = [library.get(n).rgba[:3] if n.lower() in known else (0.5, 0.5, 0.5) for n in names]
    return names, np.array(rgb, dtype=float)


def _palette_centers(header: GcodeHeader, n_materials: int) -> np.ndarray | None:
    """Palette centers ``(N, k)`` from the ``colors`` header comment, or None."""
    if header.colors is None or n_materials < 1:
        return None
    try:
        return header_palette(n_materials, header.colors, header.palette, header.settings.get("temperature_levels")).centers
    except FgsliceError:
        return None


def _composition(state: MachineState, centers: np.ndarray | None, k: int) -> np.ndarray | None:
    """The composition ``(k,)`` a state prints, or None if the file does not say."""
    if centers is not None and state.color is not None and 0 <= state.color < len(centers):
        return centers[state.color]
    mix = state.mix_fractions(k)
    if mix is not None:
        return mix
    if 0 <= state.tool < k:
        return np.eye(k)[state.tool]
    return None


def _state_label(state: MachineState, palette_labels: dict[int, str], fractions: np.ndarray | None,
                 varying: set[str]) -> str:
    """Short text for a state: palette color, composition, and the tool, temperature and
    flow when they are among the ``varying`` fields of the file's states."""
    parts = []
    if state.color is not None:
        parts.append(f"color {state.color}")
    if state.color in palette_labels:
        parts.append(palette_labels[state.color])
    elif fractions is not None:
        parts.append(" / ".join(f"{LETTERS[i]} {100 * f:.4g}%" for i, f in enumerate(fractions)))
    if "tool" in varying:
        parts.append(f"T{state.tool}")
    if "temperature" in varying and state.temperature is not None:
        parts.append(f"{state.temperature:g} degC")
    if "flow" in varying:
        parts.append(f"flow {state.flow:g}%")
    return ", ".join(parts) or "default"


def _states_meta(program: GcodeProgram, header: GcodeHeader) -> list[dict]:
    """Label, display color (sRGB 0-255) and tool of every machine state."""
    names, rgb = _material_colors(header)
    k = len(names)
    centers = _palette_centers(header, k)
    fractions = [_composition(s, centers, k) if rgb is not None else None for s in program.states]
    known = [i for i, f in enumerate(fractions) if f is not None]
    colors = categorical_colors(len(program.states))
    if known:
        for i, color in zip(known, mix_colors(np.array([fractions[i] for i in known]), rgb).tolist()):
            colors[i] = tuple(color)
    varying = {name for name in ("tool", "temperature", "flow")
               if len({getattr(s, name) for s in program.states} - {None}) > 1}
    return [{"label": _state_label(s, header.labels, f, varying), "color": c, "tool": s.tool}
            for s, f, c in zip(program.states, fractions, colors)]


def _sorted_segments(mask: np.ndarray, layer: np.ndarray, start: np.ndarray, end: np.ndarray,
                     n_layers: int) -> tuple[np.ndarray, np.ndarray, bytes]:
    """Moves selected by ``mask`` sorted stably by layer: their indices, the index of each
    layer's first segment (``n_layers + 1`` offsets) and Float32 ``(S, 2, 3)`` positions."""
    index = np.flatnonzero(mask)
    index = index[np.argsort(layer[index], kind="stable")]
    offsets = np.searchsorted(layer[index], np.arange(n_layers + 1))
    positions = np.stack([start[index], end[index]], axis=1).astype("<f4")
    return index, offsets, positions.tobytes()


def _format_mm(value: float) -> str:
    return f"{value:,.1f} mm"


def build_viewer_data(program: GcodeProgram, header: GcodeHeader, footer: dict[str, str], name: str) -> ViewerData:
    """The page's data from a read program, its header and its footer ``; key = value`` comments."""
    moved = np.any(program.end != program.start, axis=1)
    extruding = moved & (program.e > 0)
    layer = np.maximum(program.layer, 0)
    n_layers = max(len(program.layer_z), int(layer.max()) + 1)
    ext, ext_offsets, ext_positions = _sorted_segments(extruding, layer, program.start, program.end, n_layers)
    trv, trv_offsets, trv_positions = _sorted_segments(moved & ~extruding, layer, program.start, program.end, n_layers)
    states = _states_meta(program, header)
    state_type = "<u2" if len(states) < 2**16 else "<u4"
    roles = [{"name": "(none)", "color": (160, 160, 160)}]
    unknown = iter(categorical_colors(len(program.roles)))
    roles += [{"name": r, "color": ROLE_COLORS.get(r) or next(unknown)} for r in program.roles]
    tool_ids = sorted({s["tool"] for s in states})
    tools = [{"tool": t, "color": c} for t, c in zip(tool_ids, categorical_colors(len(tool_ids)))]
    points = np.concatenate([program.start[ext], program.end[ext]]) if len(ext) else np.zeros((1, 3))
    lo, hi = points.min(axis=0), points.max(axis=0)
    travel_mm = float(np.linalg.norm(program.end[trv] - program.start[trv], axis=1).sum())
    stats = [["layers", str(n_layers)], ["extrusion segments", f"{len(ext):,}"], ["travel segments", f"{len(trv):,}"],
             ["travel", _format_mm(travel_mm)],
             ["size", " x ".join(f"{v:.1f}" for v in hi - lo) + " mm"]]
    if program.faults:
        stats.append(["unreadable words", f"{len(program.faults)} (see fgslice verify)"])
    stats += [[key, header.settings[key]] for key in _HEADER_STATS if header.settings.get(key)]
    stats += [[key, value] for key, value in footer.items()]
    bed = [float(header.settings[k]) if re.fullmatch(r"\d+(\.\d*)?", header.settings.get(k, "")) else None
           for k in ("bed_x", "bed_y")]
    meta = {
        "name": name,
        "layer_count": n_layers,
        "layer_z": [float(z) for z in program.layer_z],
        "extrusion_count": int(len(ext)),
        "travel_count": int(len(trv)),
        "extrusion_offsets": ext_offsets.tolist(),
        "travel_offsets": trv_offsets.tolist(),
        "state_bytes": np.dtype(state_type).itemsize,
        "states": states,
        "roles": roles,
        "tools": tools,
        "bbox": [lo.tolist(), hi.tolist()],
        "bed": bed if None not in bed else None,
        "stats": stats,
    }
    buffers = {
        "extrusions.bin": ext_positions,
        "travels.bin": trv_positions,
        "states.bin": program.state[ext].astype(state_type).tobytes(),
        "roles.bin": np.clip(program.role[ext] + 1, 0, 255).astype(np.uint8).tobytes(),
    }
    return ViewerData(meta, buffers)


def load_viewer_data(gcode_path: str | os.PathLike) -> ViewerData:
    """Read a G-code file and build the page's data (GcodeError if it is not G-code or a
    header value fgslice interprets is malformed)."""
    program = read_gcode(Path(gcode_path)).split_arcs()  # arcs as the straight pieces the firmware prints
    return build_viewer_data(program, read_header(gcode_path), read_footer(gcode_path), Path(gcode_path).name)


def _asset_routes() -> dict[str, tuple[str, bytes]]:
    """``/`` and ``/assets/<name>`` for every file of ``preview/assets``."""
    folder = resources.files("fgslice.preview").joinpath("assets")
    routes = {}
    for item in folder.iterdir():
        if item.is_file():
            routes[f"/assets/{item.name}"] = (_MIME.get(Path(item.name).suffix, _MIME[""]), item.read_bytes())
    routes["/"] = routes.pop("/assets/index.html")
    return routes


class _Handler(BaseHTTPRequestHandler):
    """GET/HEAD of the fixed routes; other hosts than the bound address are refused."""

    server: _Server
    protocol_version = "HTTP/1.1"

    def _respond(self, body: bool) -> None:
        host = self.headers.get("Host", "")
        if host not in self.server.hosts:
            self.send_error(HTTPStatus.MISDIRECTED_REQUEST, "unknown host")
            return
        route = self.server.routes.get(urlsplit(self.path).path)
        if route is None:
            self.send_error(HTTPStatus.NOT_FOUND)
            return
        content_type, payload = route
        self.send_response(HTTPStatus.OK)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(payload)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.end_headers()
        if body:
            self.wfile.write(payload)

    def do_GET(self) -> None:  # noqa: N802 (http.server's naming)
        self._respond(True)

    def do_HEAD(self) -> None:  # noqa: N802
        self._respond(False)

    def log_message(self, format: str, *args) -> None:  # noqa: A002 (http.server's signature)
        """Quiet: the terminal shows only the address."""


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    routes: dict[str, tuple[str, bytes]]
    hosts: set[str]


class ViewerServer:
    """The viewer's HTTP server on 127.0.0.1: reads the file, then binds.

    Args:
        gcode_path: the G-code file to show.
        port: TCP port; None or 0 picks a free one.

    Raises:
        GcodeError: the file is not readable G-code (raised before anything listens).
        ViewerError: the port is in use, not allowed or out of range.
    """

    def __init__(self, gcode_path: str | os.PathLike, *, port: int | None = None) -> None:
        if port is not None and not 0 <= port <= 65535:
            raise ViewerError(f"port {port} is out of range", hint="use a port in 1..65535, or omit --port for a free one")
        data = load_viewer_data(gcode_path)
        try:
            self._server = _Server((HOST, port or 0), _Handler)
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                raise ViewerError(f"port {port} on {HOST} is already in use",
                                  hint="close the program using it, pick another with --port, "
                                  "or omit --port to use a free one") from None
            raise ViewerError(f"cannot listen on {HOST}:{port}: {exc.strerror}",
                              hint="ports below 1024 need privileges; omit --port to use a free one") from None
        self.port = self._server.server_address[1]
        routes = _asset_routes()
        routes["/data/meta.json"] = ("application/json", json.dumps(data.meta, separators=(",", ":")).encode())
        routes.update({f"/data/{k}": ("application/octet-stream", v) for k, v in data.buffers.items()})
        self._server.routes = routes
        self._server.hosts = {f"{HOST}:{self.port}", f"localhost:{self.port}"}
        self.data = data
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        """The page's address, ``http://127.0.0.1:<port>/``."""
        return f"http://{HOST}:{self.port}/"

    def serve_forever(self) -> None:
        """Serve in this thread until :meth:`stop` (from another thread) or an exception."""
        self._server.serve_forever(poll_interval=0.2)

    def start(self) -> ViewerServer:
        """Serve in a background thread; returns self."""
        self._thread = threading.Thread(target=self.serve_forever, name="fgslice-viewer", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop serving and release the port."""
        if self._thread is not None:
            self._server.shutdown()
            self._thread.join()
            self._thread = None
        self._server.server_close()

    def __enter__(self) -> ViewerServer:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()


def serve(gcode_path: str | os.PathLike, *, port: int | None = None, open_browser: bool = False,
          ready: Callable[[str], None] | None = None) -> None:
    """Show ``gcode_path`` in the browser viewer until Ctrl-C (``fgslice view``).

    Prints the address; ``ready(url)`` is called once the server listens;
    ``open_browser`` opens the page in the default browser.

    Raises:
        GcodeError: the file is not readable G-code.
        ViewerError: the port is in use, not allowed or out of range.
    """
    server = ViewerServer(gcode_path, port=port)
    print(f"fgslice viewer: {server.url}  (Ctrl-C to stop)", flush=True)
    if ready is not None:
        ready(server.url)
    if open_browser:
        webbrowser.open(server.url)
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
