"""Image textures on the CPU: sRGB decoding, mean colours, sampling for light paths as Cycles
samples (``intern/cycles/kernel/device/cpu/image.h``), and the frame's set of distinct textures
(their GPU packing is in ``gpu/texture_array.py``; ``gpu_shaders/textures_lib.glsl`` samples
them the same way).

Sampling: Closest takes the texel under the point; Linear blends the 2×2 texels around it
(texel centres at half-integers); Cubic is Cycles' uniform cubic B-spline over 4×4 texels (a
smoothing spline: it does not pass through the texel values). Extension: Repeat wraps, Extend
clamps to the edge texel, Mirror reflects (the edge texel repeated), Clip reads transparent
black outside the image (so Linear and Cubic fade to black across the edge).

Packing (``gpu/texture_array.py``): the images lie unresampled on shelves in the pages of one
``usampler2DArray``, each in a rectangle of its own (float images as float32 RGBA, 16 bytes a
texel; 8-bit images as RGBA8, 4 bytes), and the shader interpolates them itself
(``texelFetch`` within the rectangle), so there is no precision loss and no texel of a
neighbour is read. Interpolation is done on the stored
values and sRGB images are decoded afterwards, as Cycles does.
"""

from __future__ import annotations

from weakref import WeakKeyDictionary

import numpy as np

from .model import (
    COVERAGE_INVERTED,
    COVERAGE_LUMINANCE,
    EXTENSIONS,
    INTERPOLATIONS,
    Material,
    Texture,
)

MISSING_COLOR = (1.0, 0.0, 1.0)  # Blender's colour for an image it cannot read
NO_TEXTURE = -1.0


def missing_texture(name: str) -> Texture:
    """The 1×1 magenta image Cycles shows in place of a missing or unreadable one."""
    return Texture(name, np.array([[[*MISSING_COLOR, 1.0]]], np.float32))


def decode_srgb(values: np.ndarray) -> np.ndarray:
    """sRGB-encoded values to linear (the IEC 61966-2-1 curve, as Blender's sRGB space)."""
    v = np.asarray(values, dtype=np.float64)
    return np.where(v <= 0.04045, v / 12.92, ((np.maximum(v, 0.04045) + 0.055) / 1.055) ** 2.4)


def associate_bytes(pixels: np.ndarray) -> np.ndarray:
    """8-bit RGBA pixels (values k/255) with colour multiplied by alpha as Cycles loads byte
    images whose alpha it associates: integer byte arithmetic, c·a/255 rounded down."""
    codes = np.rint(np.clip(pixels, 0, 1) * 255).astype(np.int32)
    out = pixels.copy()
    out[..., :3] = (codes[..., :3] * codes[..., 3:]) // 255 / 255
    return out


_SRGB_TABLE = decode_srgb(np.arange(256) / 255)  # every byte code, decoded
_MEANS: WeakKeyDictionary[Texture, np.ndarray] = WeakKeyDictionary()


def mean_color(texture: Texture) -> np.ndarray:
    """The average linear colour (3,) of a texture's texels (computed once per texture)."""
    if texture not in _MEANS:
        rgb = texture.pixels[..., :3].reshape(-1, 3)
        if texture.srgb:  # byte images hold k/255: decode through a table of the 256 codes
            rgb = _SRGB_TABLE[np.clip(np.rint(rgb * 255), 0, 255).astype(np.uint8)]
        _MEANS[texture] = rgb.mean(axis=0, dtype=np.float64)
    return _MEANS[texture]


def mode_code(texture: Texture) -> int:
    """The texture's interpolation and extension as one number for the GPU's table:
    interpolation index + 4 × extension index (INTERPOLATIONS, EXTENSIONS)."""
    return INTERPOLATIONS.index(texture.interpolation) + 4 * EXTENSIONS.index(texture.extension)


def _cubic_weights(t: np.ndarray) -> list[np.ndarray]:
    """Uniform cubic B-spline weights of the four texels around fraction t (they sum to 1)."""
    s = 1 - t
    return [s ** 3 / 6, (3 * t ** 3 - 6 * t ** 2 + 4) / 6, (3 * s ** 3 - 6 * s ** 2 + 4) / 6,
            t ** 3 / 6]


def _taps(coordinate: np.ndarray, size: int, interpolation: str
          ) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Texel indices (unwrapped) and weights along one axis for texture coordinates (n,)."""
    p = coordinate.astype(np.float32) * np.float32(size)  # float32, as Cycles
    if interpolation == "Closest":
        return [np.floor(p).astype(np.int64)], [np.ones(len(p))]
    p = p - np.float32(0.5)  # texel centres at half-integers
    base = np.floor(p)
    t = (p - base).astype(np.float64)
    i = base.astype(np.int64)
    if interpolation == "Linear":
        return [i, i + 1], [1 - t, t]
    return [i - 1, i, i + 1, i + 2], _cubic_weights(t)


def _wrap(i: np.ndarray, size: int, extension: str) -> tuple[np.ndarray, np.ndarray | None]:
    """Indices inside [0, size) for the extension, and for Clip the mask of those inside."""
    if extension == "REPEAT":
        return i % size, None
    if extension == "MIRROR":  # period 2·size, the edge texel repeated at each reflection
        m = i % (2 * size)
        return np.where(m < size, m, 2 * size - 1 - m), None
    inside = (i >= 0) & (i < size) if extension == "CLIP" else None
    return np.clip(i, 0, size - 1), inside


def _interpolate(texture: Texture, uv: np.ndarray) -> np.ndarray:
    """Stored RGBA values (n, 4) interpolated at UVs (n, 2), not decoded."""
    pixels = texture.pixels
    h, w = pixels.shape[:2]
    uv = np.nan_to_num(np.asarray(uv, np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    uv = np.clip(uv, -1e6, 1e6)  # keeps indices small; float32 holds no texel fraction there
    xs, wx = _taps(uv[:, 0], w, texture.interpolation)
    ys, wy = _taps(uv[:, 1], h, texture.interpolation)
    value = np.zeros((len(uv), 4))
    for y, weight_y in zip(ys, wy, strict=True):
        row, row_inside = _wrap(y, h, texture.extension)
        for x, weight_x in zip(xs, wx, strict=True):
            column, column_inside = _wrap(x, w, texture.extension)
            weight = weight_x * weight_y
            if row_inside is not None:
                weight = weight * (row_inside & column_inside)
            value += weight[:, None] * pixels[row, column]
    return value


def sample(texture: Texture, uv: np.ndarray) -> np.ndarray:
    """Linear RGB (n, 3) at UVs (n, 2), with the texture's interpolation and extension."""
    value = _interpolate(texture, uv)[:, :3]
    return decode_srgb(value) if texture.srgb else value


LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709: Blender's colour-to-float weights


def _coverage_of(rgb: np.ndarray, alpha: np.ndarray, mode: int) -> np.ndarray:
    value = rgb @ LUMINANCE if mode & COVERAGE_LUMINANCE else alpha
    value = 1.0 - value if mode & COVERAGE_INVERTED else value
    return np.nan_to_num(value, nan=0.0)  # as the shader and the export read NaN


def sample_coverage(texture: Texture, mode: int, uv: np.ndarray) -> np.ndarray:
    """A cutout texture's coverage (n,) in [0, 1] at UVs (n, 2) (Material.coverage_mode;
    the GPU twin is coverage_lib.glsl)."""
    value = _interpolate(texture, uv)
    rgb = decode_srgb(value[:, :3]) if texture.srgb else value[:, :3]
    return np.clip(_coverage_of(rgb, value[:, 3], mode), 0.0, 1.0)


def mean_coverage(texture: Texture, mode: int) -> float:
    """A cutout texture's coverage averaged over its texels."""
    rgb = texture.pixels[..., :3].reshape(-1, 3)
    if mode & COVERAGE_LUMINANCE and texture.srgb:  # byte codes, decoded through a table
        rgb = _SRGB_TABLE[np.clip(np.rint(rgb * 255), 0, 255).astype(np.uint8)]
    value = _coverage_of(rgb, texture.pixels[..., 3].ravel(), mode)
    return float(np.clip(value, 0.0, 1.0).mean(dtype=np.float64))


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

    def cutout(self, material: Material) -> tuple[float, float, float, float]:
        """A material's cutout texel (coverage_lib.glsl): coverage layer + 1 (0 for none),
        1 − its constant alpha, the coverage mode, 0."""
        alpha = float(np.clip(np.nan_to_num(material.alpha, nan=1.0), 0.0, 1.0))
        return (self.layer(material.coverage_texture) + 1.0, 1.0 - alpha,
                float(material.coverage_mode), 0.0)

    def normal(self, material: Material) -> tuple[float, float, float, float]:
        """A material's normal-map texel (gbuffer_frag.glsl): normal or bump map layer + 1
        (0 for none), its strength (finite, >= 0), for a bump map its filter width in pixels
        (> 0; 0 for a normal map), its distance (finite)."""
        strength = float(np.nan_to_num(material.normal_strength, nan=0.0, posinf=0.0))
        width = 0.0
        if material.bump_distance is not None:
            width = float(np.clip(np.nan_to_num(material.bump_filter_width, nan=1.0), 1e-3, 1e3))
        distance = float(np.nan_to_num(material.bump_distance or 0.0, posinf=0.0, neginf=0.0))
        return self.layer(material.normal_texture) + 1.0, max(strength, 0.0), width, distance

    def columns(self, material: Material) -> tuple[float, float, float]:
        """A material's texture attribute: albedo layer, emission layer, and the
        emission strength the emission texture is multiplied by."""
        scale = float(np.max(material.emission)) if material.emission_texture else 0.0
        return (self.layer(material.base_color_texture),
                self.layer(material.emission_texture), scale)
