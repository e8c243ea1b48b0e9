"""Thumbnails embedded in G-code, in PrusaSlicer's format (read by printers and hosts).

A block is::

    ; thumbnail begin 16x16 1234
    ; iVBORw0KGgo...            (base64 of the PNG, lines of at most 78 characters)
    ; thumbnail end

where 1234 is the length of the base64 text. Rendering the pictures is done elsewhere;
this module only embeds PNG bytes.
"""

from __future__ import annotations

import base64

LINE_CHARS = 78
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def thumbnail_block(png_bytes: bytes, width: int, height: int) -> str:
    """The comment block embedding ``png_bytes`` (a ``width`` x ``height`` pixel PNG).

    Raises:
        ValueError: ``png_bytes`` is not a PNG or the size is not positive.
    """
    if not png_bytes.startswith(PNG_SIGNATURE):
        raise ValueError("thumbnail data is not a PNG image")
    if width <= 0 or height <= 0:
        raise ValueError(f"thumbnail size must be positive, got {width}x{height}")
    text = base64.b64encode(png_bytes).decode("ascii")
    lines = [f"; {text[i:i + LINE_CHARS]}" for i in range(0, len(text), LINE_CHARS)]
    return "\n".join([f"; thumbnail begin {width}x{height} {len(text)}", *lines, "; thumbnail end"]) + "\n"
