"""The frame's image textures as one float32 RGBA array texture for the g-buffer and the ray
tracer (see ``scene/textures.py`` for how they are sampled): packed on shelves into pages,
each image unresampled in a rectangle of its own."""

from __future__ import annotations

import math

import moderngl
import numpy as np

from ..scene.model import Texture
from ..scene.textures import mode_code


def pack(sizes: list[tuple[int, int]], limit: int
         ) -> tuple[list[tuple[int, int, int]], tuple[int, int, int]]:
    """Rectangles of ``sizes`` (width, height) on shelves, tallest first, in pages at most
    ``limit`` texels on a side: each rectangle's (x, y, page) and the pages' (width, height,
    count). The page width is the widest image or the side of a square of their total area
    (a power of two), whichever is larger; ValueError for an image larger than ``limit``."""
    for w, h in sizes:
        if w > limit or h > limit:
            raise ValueError(f"an image of {w}×{h} pixels is larger than this GPU's textures "
                             f"({limit}×{limit})")
    area = sum(w * h for w, h in sizes)
    side = 1 << max(0, math.ceil(math.log2(max(1.0, math.sqrt(area)))))
    width = min(limit, max(max(w for w, _ in sizes), side))
    places: list[tuple[int, int, int]] = [(0, 0, 0)] * len(sizes)
    page = x = y = shelf = height = 0
    for k in sorted(range(len(sizes)), key=lambda k: -sizes[k][1]):
        w, h = sizes[k]
        if x + w > width:  # the next shelf
            x, y, shelf = 0, y + shelf, 0
        if y + h > limit:  # the next page
            page, x, y, shelf = page + 1, 0, 0, 0
        places[k] = (x, y, page)
        x, shelf = x + w, max(shelf, h)
        height = max(height, y + shelf)
    return places, (width, height, page + 1)


def upload(ctx: moderngl.Context, textures: list[Texture]
           ) -> tuple[moderngl.TextureArray, moderngl.Texture]:
    """The textures packed into the pages of one float32 RGBA array texture (``pack``), and a
    (layers × 2) table: per texture its width, height, sRGB flag and sampling mode
    (``textures.mode_code``; row 0) and where it lies, x, y and page (row 1). ValueError for
    an image larger than the GPU's textures."""
    sizes = [(t.pixels.shape[1], t.pixels.shape[0]) for t in textures]
    places, (width, height, pages) = pack(sizes, int(ctx.info["GL_MAX_TEXTURE_SIZE"]))
    layers = np.zeros((pages, height, width, 4), np.float32)
    table = np.zeros((2, len(textures), 4), np.float32)
    for k, (texture, (x, y, page)) in enumerate(zip(textures, places, strict=True)):
        w, h = sizes[k]
        layers[page, y:y + h, x:x + w] = texture.pixels
        table[0, k] = (w, h, float(texture.srgb), mode_code(texture))
        table[1, k, :3] = (x, y, page)
    array = ctx.texture_array((width, height, pages), 4, layers.tobytes(), dtype="f4")
    array.filter = moderngl.NEAREST, moderngl.NEAREST
    table_texture = ctx.texture((len(textures), 2), 4, table.tobytes(), dtype="f4")
    table_texture.filter = moderngl.NEAREST, moderngl.NEAREST
    return array, table_texture
