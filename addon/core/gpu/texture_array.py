"""The frame's image textures as one array texture for the g-buffer and the ray tracer (see
``scene/textures.py`` for how they are sampled): packed on shelves into pages, each image
unresampled in a rectangle of its own, 8-bit images as such (16 bytes a texel for float
images, 4 for 8-bit ones)."""

from __future__ import annotations

import math
from weakref import WeakKeyDictionary

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


_CODES: WeakKeyDictionary[Texture, np.ndarray] = WeakKeyDictionary()


def byte_codes(texture: Texture) -> np.ndarray | None:
    """An 8-bit texture's (h, w, 4) byte codes (its values × 255, rounded; kept while the
    texture lives, as the passes of a render upload it again), None for a float one."""
    if not texture.eight_bit:
        return None
    if texture not in _CODES:
        codes = np.rint(np.clip(np.nan_to_num(texture.pixels), 0.0, 1.0) * np.float32(255.0))
        _CODES[texture] = codes.astype(np.uint8)
    return _CODES[texture]


def upload(ctx: moderngl.Context, textures: list[Texture]
           ) -> tuple[moderngl.TextureArray, moderngl.Texture]:
    """The textures packed into the pages of one RGBA32UI array texture (``pack``): a float
    image's texel as its four float32 bit patterns, an 8-bit image's four texels in one
    (RGBA8 each: a quarter of the memory); and a (layers × 2) table: per texture its width,
    height, sRGB flag and sampling mode (``textures.mode_code``; row 0) and where it lies, x,
    y, page and 1 for an 8-bit image (row 1). ValueError for an image larger than the GPU's
    textures."""
    codes = [byte_codes(t) for t in textures]
    sizes = [(t.pixels.shape[1], t.pixels.shape[0]) for t in textures]
    spans = [(-(-w // 4) if c is not None else w, h) for (w, h), c in zip(sizes, codes,
                                                                          strict=True)]
    limit = int(ctx.info["GL_MAX_TEXTURE_SIZE"])
    for (w, h), (span, _) in zip(sizes, spans, strict=True):
        if span > limit or h > limit:  # an 8-bit image's texels take a quarter of the width
            raise ValueError(f"an image of {w}×{h} pixels is larger than this GPU's textures "
                             f"({limit}×{limit}; 8-bit images up to {4 * limit} wide)")
    places, (width, height, pages) = pack(spans, limit)
    words = np.zeros((pages, height, width, 4), np.uint32)
    table = np.zeros((2, len(textures), 4), np.float32)
    for k, (texture, (x, y, page)) in enumerate(zip(textures, places, strict=True)):
        (w, h), (span, _) = sizes[k], spans[k]
        if codes[k] is None:
            words[page, y:y + h, x:x + w] = np.ascontiguousarray(texture.pixels,
                                                                 np.float32).view(np.uint32)
        else:  # RGBA8 texels, four to a word: texel i in word i % 4 of texel i // 4
            padded = np.zeros((h, 4 * span, 4), np.uint8)
            padded[:, :w] = codes[k]
            words[page, y:y + h, x:x + span] = padded.view(np.uint32).reshape(h, span, 4)
        table[0, k] = (w, h, float(texture.srgb), mode_code(texture))
        table[1, k] = (x, y, page, float(codes[k] is not None))
    array = ctx.texture_array((width, height, pages), 4, words.tobytes(), dtype="u4")
    array.filter = moderngl.NEAREST, moderngl.NEAREST
    table_texture = ctx.texture((len(textures), 2), 4, table.tobytes(), dtype="f4")
    table_texture.filter = moderngl.NEAREST, moderngl.NEAREST
    return array, table_texture
