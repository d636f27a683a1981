"""The render region (Render Region, Ctrl+B in the camera view), as Blender composes it: the
region's pixels in the full image (the rest empty), or the region alone with Crop to Render
Region. VPL GI renders only the region (core/scene/render_region.py), or with depth of field
the full image cropped; either way the region's pixels are the full render's, but for the
image-space stages (blur, bias compensation) within a few pixels of the region's edge."""

from __future__ import annotations

from pathlib import Path

import bpy
import numpy as np
import pytest

from tests.blender.rendering import open_scene, render_linear

SIZE = 96  # the scene's image: 96 × 96
BORDER = (0.25, 0.75, 0.2, 0.6)  # min x, max x, min y, max y
REGION = (slice(19, 57), slice(24, 72))  # its pixels (rows from the bottom, columns)


def _region_renders(scene: bpy.types.Scene, tmp_path: Path) -> tuple[np.ndarray, ...]:
    """The full image, the region in it and the region cropped."""
    render = scene.render
    full = render_linear(scene, "VPL_GI", tmp_path / "full.exr")
    render.use_border = True
    render.border_min_x, render.border_max_x, render.border_min_y, render.border_max_y = BORDER
    render.use_crop_to_border = False
    placed = render_linear(scene, "VPL_GI", tmp_path / "placed.exr")
    render.use_crop_to_border = True
    cropped = render_linear(scene, "VPL_GI", tmp_path / "cropped.exr")
    return full, placed, cropped


@pytest.mark.parametrize("focus", [False, True], ids=["pinhole", "depth of field"])
def test_a_render_region_renders_the_full_images_pixels(blender, tmp_path, focus):
    scene = open_scene("cornell_box", SIZE)
    if focus:  # the full image renders and is cropped: the blur reaches across the edge
        scene.camera.data.dof.use_dof, scene.camera.data.dof.aperture_fstop = True, 2.8
    full, placed, cropped = _region_renders(scene, tmp_path)
    region = full[REGION]
    assert placed.shape == full.shape and cropped.shape == region.shape
    outside = np.ones(full.shape[:2], bool)
    outside[REGION] = False
    assert not placed[outside].any()  # Blender leaves the rest of the image empty
    assert np.array_equal(placed[REGION], cropped)
    inner = (slice(6, -6), slice(6, -6))  # past the image-space stages' reach of the edge
    off = np.abs(cropped - region)
    print(f"region vs the full image's: {off.mean() / region.mean():.4f} of the mean off, "
          f"{off[inner].mean() / region[inner].mean():.4f} inside")
    assert off.mean() < 0.01 * region.mean() and off[inner].mean() < 0.003 * region[inner].mean()
