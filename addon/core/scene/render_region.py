"""The render region (Output Properties > Format > Render Region, Ctrl+B in the camera view):
the pixels of the image Blender asks an engine for, and a camera that renders only them."""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np

from .model import Camera


class Region(NamedTuple):
    """Pixel bounds of the region in the full image (x from the left, y from the bottom, the
    maxima exclusive), as Blender computes them."""

    x_min: int
    y_min: int
    x_max: int
    y_max: int

    @property
    def width(self) -> int:
        return self.x_max - self.x_min

    @property
    def height(self) -> int:
        return self.y_max - self.y_min


def region_of(width: int, height: int, border: tuple[float, float, float, float]
              ) -> Region | None:
    """The region of a ``width`` × ``height`` image that ``border`` (min x, max x, min y,
    max y as fractions of the image) covers, truncated to pixels as Blender truncates them;
    None where it is the whole image or has no pixels (Blender then renders the image)."""
    min_x, max_x, min_y, max_y = (float(np.clip(b, 0.0, 1.0)) for b in border)
    region = Region(int(min_x * width), int(min_y * height), int(max_x * width),
                    int(max_y * height))
    if region.width < 1 or region.height < 1 or region == Region(0, 0, width, height):
        return None
    return region


def region_camera(camera: Camera, region: Region) -> Camera | None:
    """``camera`` rendering only ``region`` of its image: its projection followed by the map
    of the region's part of clip space onto all of it, so each pixel sees what it sees in
    the full image. None for a panoramic camera (its faces are not one projection) and with
    depth of field (its blur reaches across the region's edge): those render the full image,
    cropped."""
    if camera.panorama is not None or camera.defocused:
        return None
    centre_x = (region.x_min + region.x_max) / camera.width - 1.0
    centre_y = (region.y_min + region.y_max) / camera.height - 1.0
    half_x, half_y = region.width / camera.width, region.height / camera.height
    to_region = np.array([[1.0 / half_x, 0.0, 0.0, -centre_x / half_x],
                          [0.0, 1.0 / half_y, 0.0, -centre_y / half_y],
                          [0.0, 0.0, 1.0, 0.0],
                          [0.0, 0.0, 0.0, 1.0]])
    projection = to_region @ np.asarray(camera.projection_matrix, np.float64)
    return replace(camera, projection_matrix=projection, width=region.width,
                   height=region.height)


def cropped(passes: dict[str, np.ndarray], region: Region) -> dict[str, np.ndarray]:
    """The region's pixels of full-image passes (rows bottom-up)."""
    return {name: image[region.y_min:region.y_max, region.x_min:region.x_max]
            for name, image in passes.items()}
