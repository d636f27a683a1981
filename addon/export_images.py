"""Image Texture nodes -> core Texture: pixels read with foreach_get, one warning per problem.

Supported: an Image Texture's Color output linked (directly or through reroutes) to a colour
input, its Vector input unlinked (the active render UV map) or linked to a UV Map node or a
Texture Coordinate node's UV output; every interpolation (Smart is Cubic, as Cycles' SVM
samples it) and extension, Flat projection. Pixels of byte images are in the image's colour
space: sRGB ones are decoded by the renderer after interpolation, as Cycles does; float
images are linear already. As Cycles, the Color output of a byte image with Straight alpha in
a colour (not data) space is associated — multiplied by alpha — unless the node's Alpha output
is linked; float images' pixels are associated as Blender stores them.
"""

from __future__ import annotations

import bpy
import numpy as np

from .blender_read import rgb
from .core.scene.model import COVERAGE_ALPHA, COVERAGE_LUMINANCE, EXTENSIONS, Texture
from .core.scene.textures import associate_bytes, missing_texture

RAW_SPACES = {"Non-Color", "Linear Rec.709", "Linear"}
UNREAD_SOURCES = {"SEQUENCE": "an image sequence", "MOVIE": "a movie"}
"""Image sources whose frames Blender's Python API does not choose: their pixels are the
frame Blender has loaded, if any."""
INTERPOLATION = {"Closest": "Closest", "Linear": "Linear", "Cubic": "Cubic", "Smart": "Cubic"}


class UnsupportedLink(Exception):
    """A colour input linked to something other than a supported Image Texture."""


def linked_node(socket):
    """The node a linked input comes from, through any Reroute nodes."""
    node = socket.links[0].from_node
    while node.type == "REROUTE" and node.inputs[0].is_linked:
        node = node.inputs[0].links[0].from_node
    return node


def _check_vector(node) -> None:
    socket = node.inputs.get("Vector")
    if socket is None or not socket.is_linked:
        return
    link = socket.links[0]
    source = linked_node(socket)
    if source.type == "UVMAP" or (source.type == "TEX_COORD" and link.from_socket.name == "UV"):
        return
    raise UnsupportedLink(f"input 'Vector' of '{node.bl_label}' is linked to "
                          f"'{source.bl_label}'")


def read_pixels(image: bpy.types.Image, warnings: list[str]) -> np.ndarray | None:
    """The image's pixels as (h, w, 4) float32, rows bottom-up, in its stored values (byte
    images: sRGB-encoded when their colour space is sRGB), or None when Blender cannot read
    it. NaN/Inf values (float images) are read as 0, with one warning per image."""
    width, height = image.size
    channels = image.channels
    try:
        count = len(image.pixels)
    except RuntimeError:
        return None
    if width * height == 0 or count != width * height * channels or channels not in (1, 3, 4):
        return None
    flat = np.empty(count, dtype=np.float32)
    image.pixels.foreach_get(flat)
    bad = ~np.isfinite(flat)
    if bad.any():
        flat[bad] = 0.0
        message = (f"image '{image.name}': {int(bad.sum())} NaN/Inf values read as 0 (as if "
                   f"black there)")
        if message not in warnings:
            warnings.append(message)
    pixels = flat.reshape(height, width, channels)
    if channels == 4:
        return pixels
    rgba = np.ones((height, width, 4), np.float32)
    rgba[..., :3] = pixels
    return rgba


class ImageReader:
    """Textures of one export, one per image and sampling mode, and the warnings about them."""

    def __init__(self, warnings: list[str]) -> None:
        self.warnings = warnings
        self._pixels: dict[str, tuple[np.ndarray, bool, bool] | None] = {}
        self._associated: dict[str, np.ndarray] = {}
        self._textures: dict[tuple[str, bool, str, str], Texture] = {}

    def warn(self, message: str) -> None:
        """Add ``message`` to the export's warnings unless it is there already."""
        if message not in self.warnings:
            self.warnings.append(message)

    def color(self, node, name: str, default, material: str
              ) -> tuple[tuple[float, float, float], Texture | None]:
        """A colour input's constant value, or (1, 1, 1) and the texture linked to it."""
        socket = node.inputs.get(name)
        if socket is None or not socket.is_linked:
            value = default if socket is None else socket.default_value
            return rgb(value), None
        source = linked_node(socket)
        if source.type != "TEX_IMAGE" or socket.links[0].from_socket.name != "Color":
            raise UnsupportedLink(f"input '{name}' of '{node.bl_label}' is linked to "
                                  f"'{source.bl_label}'")
        _check_vector(source)
        return (1.0, 1.0, 1.0), self.texture(source, material)

    def coverage(self, node, name: str, material: str) -> tuple[float, Texture | None, int]:
        """A float input read as a cutout's coverage: its constant value (clipped to [0, 1])
        and no texture, or 1 and the Image Texture linked to it with the mode of the output
        it comes from (its Alpha, or its Color as a float: COVERAGE_LUMINANCE)."""
        socket = node.inputs[name]
        if not socket.is_linked:
            return float(np.clip(np.nan_to_num(socket.default_value, nan=1.0), 0, 1)), None, 0
        source = linked_node(socket)
        output = socket.links[0].from_socket.name
        if source.type != "TEX_IMAGE" or output not in ("Alpha", "Color"):
            raise UnsupportedLink(f"input '{name}' of '{node.bl_label}' is linked to "
                                  f"'{source.bl_label}'")
        _check_vector(source)
        mode = COVERAGE_ALPHA if output == "Alpha" else COVERAGE_LUMINANCE
        return 1.0, self.texture(source, material), mode

    def texture(self, node, material: str) -> Texture:
        """The node's image as a Texture with the node's interpolation and extension; magenta,
        with a warning, when it cannot be read; UnsupportedLink for a UDIM image of several
        tiles (Python reads its first tile only) or a projection other than Flat: the
        material is baked by Cycles instead."""
        image = node.image
        label = f"image '{image.name}'" if image is not None else "an image texture"
        if image is not None and image.source == "TILED" and len(image.tiles) > 1:
            raise UnsupportedLink(f"{label} is a UDIM image of {len(image.tiles)} tiles, "
                                  f"which VPL GI reads only through a bake")
        if node.projection != "FLAT":
            raise UnsupportedLink(f"{label}: its projection {node.projection.title()} is read "
                                  f"only through a bake")
        if image is None:
            self.warn(f"material '{material}': an image texture has no image: shown in "
                      f"magenta (1, 0, 1) as Cycles does")
            return missing_texture("(none)")
        key = image.name_full
        read = self._read(image, material)
        if read is None:
            return self._textures.setdefault((key, False, "", ""), missing_texture(image.name))
        pixels, srgb, translucent = read
        interpolation, extension = self._sampling(node, material, label)
        associate = (translucent and not image.is_float and image.alpha_mode == "STRAIGHT"
                     and not image.colorspace_settings.is_data
                     and not node.outputs["Alpha"].is_linked)
        mode = (key, associate, interpolation, extension)
        if mode not in self._textures:
            if associate:
                pixels = self._associated.setdefault(key, associate_bytes(pixels))
            self._textures[mode] = Texture(image.name, pixels, srgb, interpolation, extension,
                                           eight_bit=not image.is_float)
        return self._textures[mode]

    def _read(self, image, material: str) -> tuple[np.ndarray, bool, bool] | None:
        """The image's pixels, sRGB flag and whether some alpha is below 1 (read once per
        export), None when unreadable; the warnings about them, once per material."""
        key = image.name_full
        if key not in self._pixels:
            pixels = read_pixels(image, self.warnings)
            srgb = not image.is_float and image.colorspace_settings.name == "sRGB"
            self._pixels[key] = None if pixels is None else \
                (pixels, srgb, bool((pixels[..., 3] < 1).any()))
        space = image.colorspace_settings.name
        if self._pixels[key] is None and image.source in UNREAD_SOURCES:
            self.warn(f"material '{material}': image '{image.name}' is "
                      f"{UNREAD_SOURCES[image.source]}, which VPL GI does not read: shown in "
                      f"magenta (1, 0, 1)")
        elif image.source in UNREAD_SOURCES:
            self.warn(f"material '{material}': image '{image.name}' is "
                      f"{UNREAD_SOURCES[image.source]}: rendered with the frame Blender has "
                      f"loaded, which need not be the scene frame's")
        elif self._pixels[key] is None:
            self.warn(f"material '{material}': image '{image.name}' is missing or cannot be "
                      f"read ({image.filepath or 'no file'}): shown in magenta (1, 0, 1) as "
                      f"Cycles does")
        elif not image.is_float and space not in RAW_SPACES | {"sRGB"}:
            self.warn(f"material '{material}': image '{image.name}': colour space '{space}' "
                      f"is not supported (read as Non-Color)")
        return self._pixels[key]

    def _sampling(self, node, material: str, label: str) -> tuple[str, str]:
        """The node's interpolation (Smart as Cubic) and extension; Linear/Repeat, with a
        warning, for a value this add-on does not know (a newer Blender's)."""
        interpolation = INTERPOLATION.get(node.interpolation, "Linear")
        extension = node.extension if node.extension in EXTENSIONS else "REPEAT"
        if (interpolation, extension) != (INTERPOLATION.get(node.interpolation), node.extension):
            self.warn(f"material '{material}': {label}: interpolation "
                      f"{node.interpolation.title()}, extension {node.extension.title()} not "
                      f"supported (rendered as {interpolation}, {extension.title()})")
        return interpolation, extension
