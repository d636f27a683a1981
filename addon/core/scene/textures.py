"""Image textures on the CPU: sRGB decoding, mean colours, bilinear sampling for light paths,
and the frame's set of distinct textures (their GPU packing is in ``gpu/texture_array.py``).

Packing: one ``sampler2DArray`` whose layers are as large as the largest image; each image
lies unresampled in its layer's lower-left corner and the shader interpolates it itself
(``texelFetch``, Repeat), so there is no precision loss, at the cost of memory when sizes
differ (layers × largest width × largest height × 16 bytes, float32 RGBA). Interpolation is
done on the stored values and sRGB images are decoded afterwards, as Cycles does.
"""

from __future__ import annotations

from weakref import WeakKeyDictionary

import numpy as np

from .model import Material, Texture

MISSING_COLOR = (1.0, 0.0, 1.0)  # Blender's colour for an image it cannot read
NO_TEXTURE = -1.0


def missing_texture(name: str) -> Texture:
    """The 1×1 magenta image Cycles shows in place of a missing or unreadable one."""
    return Texture(name, np.array([[[*MISSING_COLOR, 1.0]]], np.float32))


def decode_srgb(values: np.ndarray) -> np.ndarray:
    """sRGB-encoded values to linear (the IEC 61966-2-1 curve, as Blender's sRGB space)."""
    v = np.asarray(values, dtype=np.float64)
    return np.where(v <= 0.04045, v / 12.92, ((np.maximum(v, 0.04045) + 0.055) / 1.055) ** 2.4)


_MEANS: WeakKeyDictionary[Texture, np.ndarray] = WeakKeyDictionary()


def mean_color(texture: Texture) -> np.ndarray:
    """The average linear colour (3,) of a texture's texels (computed once per texture)."""
    if texture not in _MEANS:
        rgb = texture.pixels[..., :3].reshape(-1, 3)
        if texture.srgb:  # byte images hold k/255: decode through a table of the 256 codes
            codes = np.clip(np.rint(rgb * 255), 0, 255).astype(np.uint8)
            rgb = decode_srgb(np.arange(256) / 255)[codes]
        _MEANS[texture] = rgb.mean(axis=0, dtype=np.float64)
    return _MEANS[texture]


def sample(texture: Texture, uv: np.ndarray) -> np.ndarray:
    """Linear RGB (n, 3) at UVs (n, 2): bilinear between texel centres, Repeat extension."""
    pixels = texture.pixels
    h, w = pixels.shape[:2]
    x = np.asarray(uv[:, 0], np.float64) * w - 0.5
    y = np.asarray(uv[:, 1], np.float64) * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    x0, y0 = x0.astype(np.int64) % w, y0.astype(np.int64) % h
    x1, y1 = (x0 + 1) % w, (y0 + 1) % h
    rgb = pixels[..., :3]
    value = ((1 - fy) * ((1 - fx) * rgb[y0, x0] + fx * rgb[y0, x1])
             + fy * ((1 - fx) * rgb[y1, x0] + fx * rgb[y1, x1]))
    return decode_srgb(value) if texture.srgb else value


class TextureSet:
    """The distinct textures of a frame, each with its layer of the array texture."""

    def __init__(self) -> None:
        self.textures: list[Texture] = []
        self._layers: dict[int, int] = {}

    def layer(self, texture: Texture | None) -> float:
        """The texture's layer (added on first use), or NO_TEXTURE for None."""
        if texture is None:
            return NO_TEXTURE
        key = id(texture)
        if key not in self._layers:
            self._layers[key] = len(self.textures)
            self.textures.append(texture)
        return float(self._layers[key])

    def columns(self, material: Material) -> tuple[float, float, float]:
        """A material's texture attribute: albedo layer, emission layer, and the
        emission strength the emission texture is multiplied by."""
        scale = float(np.max(material.emission)) if material.emission_texture else 0.0
        return (self.layer(material.base_color_texture),
                self.layer(material.emission_texture), scale)
