"""Render regions (scene/render_region.py): their pixels as Blender truncates them, and a
camera that sees in each of the region's pixels what the full image's camera sees there.
The renders are checked in tests/blender/test_render_region.py."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from addon.core.scene.model import Aperture, Camera, Panorama
from addon.core.scene.render_region import Region, cropped, region_camera, region_of


def _perspective(width: int, height: int) -> Camera:
    """A 50° camera at (0.3, -0.2, 4) looking down -Z."""
    near, far, f = 0.1, 100.0, 1.0 / math.tan(math.radians(25.0))
    projection = np.array([[f * height / width, 0, 0, 0], [0, f, 0, 0],
                           [0, 0, -(far + near) / (far - near), -2 * far * near / (far - near)],
                           [0, 0, -1, 0]])
    view = np.eye(4)
    view[:3, 3] = (-0.3, 0.2, -4.0)
    return Camera(view, projection, width, height)


def _pixels(camera: Camera, points: np.ndarray) -> np.ndarray:
    """Where world ``points`` (n, 3) land in the camera's image, in pixels from the bottom
    left."""
    clip = np.c_[points, np.ones(len(points))] @ (camera.projection_matrix
                                                  @ camera.view_matrix).T
    ndc = clip[:, :2] / clip[:, 3:]
    return (ndc + 1.0) / 2.0 * np.array([camera.width, camera.height])


def test_the_regions_pixels_are_truncated_as_blender_does():
    assert region_of(160, 90, (0.25, 0.75, 0.2, 0.6)) == Region(40, 18, 120, 54)
    assert region_of(160, 90, (0.0, 1.0, 0.0, 1.0)) is None  # the whole image
    assert region_of(160, 90, (0.5, 0.503, 0.2, 0.6)) is None  # no pixel
    assert region_of(160, 90, (-1.0, 2.0, 0.5, 0.7)) == Region(0, 45, 160, 62)  # 62.99…


def test_the_region_camera_sees_what_the_full_image_sees_in_its_pixels():
    full = _perspective(160, 90)
    region = Region(40, 18, 120, 54)
    camera = region_camera(full, region)
    assert (camera.width, camera.height) == (80, 36)
    points = np.random.default_rng(0).uniform([-2, -2, -1], [2, 2, 1], (200, 3))
    np.testing.assert_allclose(_pixels(camera, points) + np.array(region[:2]),
                               _pixels(full, points), atol=1e-9)
    assert camera.view_matrix is full.view_matrix


def test_depth_of_field_and_panoramas_render_the_full_image_cropped():
    full = _perspective(160, 90)
    region = Region(40, 18, 120, 54)
    assert region_camera(replace(full, aperture=Aperture(0.02, 4.0)), region) is None
    assert region_camera(replace(full, panorama=Panorama("EQUIRECTANGULAR")), region) is None
    image = np.arange(90 * 160, dtype=np.float32).reshape(90, 160, 1)
    part = cropped({"Combined": image}, region)["Combined"]
    assert part.shape == (36, 80, 1) and part[0, 0, 0] == image[18, 40, 0]
