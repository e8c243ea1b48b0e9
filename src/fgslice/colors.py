"""Display colors of material mixtures, shared by previews, the viewer and fidelity metrics.

A mixture's color is the volume-weighted mix of its materials' colors in linear-light
sRGB: each material's sRGB (0-1) is decoded to linear light, the linear values are
mixed by the fractions, and the result is encoded back to sRGB. Alpha mixes linearly.
Fractions are used as given (callers clamp and normalize them).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fgslice.design.base import Material


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """sRGB (0-1) to linear light (IEC 61966-2-1 transfer function)."""
    c = np.asarray(c, dtype=float)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c: np.ndarray) -> np.ndarray:
    """Linear light (0-1) to sRGB (0-1), clipped to [0, 1]."""
    c = np.clip(np.asarray(c, dtype=float), 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * c ** (1 / 2.4) - 0.055)


def mix_linear(fractions: np.ndarray, rgb: np.ndarray) -> np.ndarray:
    """Linear-light RGB ``(..., 3)`` of mixtures ``(..., k)`` of materials whose sRGB (0-1) is ``rgb`` ``(k, 3)``."""
    return np.asarray(fractions, dtype=float) @ srgb_to_linear(np.asarray(rgb, dtype=float)[:, :3])


def mix_rgba(fractions: np.ndarray, rgba: np.ndarray) -> np.ndarray:
    """Display RGBA ``(..., 4)`` in [0, 1] of mixtures ``(..., k)`` of materials ``rgba`` ``(k, 4)``.

    RGB mixes in linear light (:func:`mix_linear`), alpha linearly.
    """
    rgba = np.asarray(rgba, dtype=float)
    rgb = linear_to_srgb(mix_linear(fractions, rgba[:, :3]))
    alpha = np.clip(np.asarray(fractions, dtype=float) @ rgba[:, 3], 0.0, 1.0)
    return np.concatenate([rgb, alpha[..., None]], axis=-1)


def materials_rgba(materials: Sequence[Material]) -> np.ndarray:
    """``(k, 4)`` RGBA (0-1) of ``materials``."""
    return np.array([m.rgba for m in materials], dtype=float).reshape(-1, 4)
