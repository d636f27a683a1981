"""The frame's image textures as one float32 RGBA array texture for the g-buffer (see
``scene/textures.py`` for the packing)."""

from __future__ import annotations

import moderngl
import numpy as np

from ..scene.model import Texture
from ..scene.textures import mode_code


def upload(ctx: moderngl.Context, textures: list[Texture]
           ) -> tuple[moderngl.TextureArray, moderngl.Texture]:
    """The textures as one float32 RGBA array texture (one layer each, in the lower-left
    corner), and a (layers × 1) table of each layer's width, height, sRGB flag and sampling
    mode (``textures.mode_code``)."""
    width = max(t.pixels.shape[1] for t in textures)
    height = max(t.pixels.shape[0] for t in textures)
    layers = np.zeros((len(textures), height, width, 4), np.float32)
    table = np.zeros((len(textures), 4), np.float32)
    for k, texture in enumerate(textures):
        h, w = texture.pixels.shape[:2]
        layers[k, :h, :w] = texture.pixels
        table[k] = (w, h, float(texture.srgb), mode_code(texture))
    array = ctx.texture_array((width, height, len(textures)), 4, layers.tobytes(), dtype="f4")
    array.filter = moderngl.NEAREST, moderngl.NEAREST
    sizes = ctx.texture((len(textures), 1), 4, table.tobytes(), dtype="f4")
    sizes.filter = moderngl.NEAREST, moderngl.NEAREST
    return array, sizes
