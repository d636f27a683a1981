"""Panoramic cameras (frame/panorama.py): Cycles' lens directions in Blender's camera axes,
the cube faces a panorama needs, and reading the faces back in each pixel's direction."""

from __future__ import annotations

import math

import numpy as np
import pytest

from addon.core.frame.compose import BACKGROUND_DEPTH
from addon.core.frame.panorama import (
    FACES,
    GUARD_PIXELS,
    directions,
    face_cameras,
    face_size,
    needed_faces,
    pixel_directions,
    resample,
)
from addon.core.scene.model import Camera, Panorama

EQUIRECTANGULAR = Panorama("EQUIRECTANGULAR")


def unit(d: np.ndarray) -> np.ndarray:
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def test_an_equirectangular_image_looks_forward_at_its_centre_and_up_at_its_top():
    d = directions(EQUIRECTANGULAR, 4, 2, offset=(0.0, 0.0))  # pixel corners
    assert d[1, 2] == pytest.approx([0.0, 0.0, -1.0], abs=1e-9)  # u = v = 0.5: the view
    assert d[1, 3] == pytest.approx([1.0, 0.0, 0.0], abs=1e-9)  # u = 0.75: the camera's right
    assert d[1, 1] == pytest.approx([-1.0, 0.0, 0.0], abs=1e-9)
    top = directions(EQUIRECTANGULAR, 4, 2, offset=(0.5, 1.0))[1]  # v = 1
    assert top == pytest.approx(np.tile([0.0, 1.0, 0.0], (4, 1)), abs=1e-9)


@pytest.mark.parametrize("kind", ["FISHEYE_EQUIDISTANT", "FISHEYE_EQUISOLID", "MIRRORBALL"])
def test_a_round_lens_looks_forward_at_its_centre_and_sees_nothing_past_its_rim(kind):
    lens = Panorama(kind, fisheye_fov=math.radians(180), sensor_width=36.0, sensor_height=36.0)
    d = directions(lens, 65, 65)
    assert unit(d[32, 32]) == pytest.approx([0.0, 0.0, -1.0], abs=1e-9)
    assert unit(d[32, 48])[0] > 0.3  # right of the centre: the camera's right
    assert unit(d[48, 32])[1] > 0.3  # above it: up
    assert not d[0, 0].any()  # the image's corner is outside the circle


def test_the_faces_cover_what_the_lens_sees_and_turn_their_view_to_their_axis():
    rays = pixel_directions(EQUIRECTANGULAR, 64, 32)
    assert needed_faces(rays) == list(range(6))
    half = Panorama("EQUIRECTANGULAR", latitude_min=-0.3, latitude_max=0.3,
                    longitude_min=-0.6, longitude_max=0.6)
    assert needed_faces(pixel_directions(half, 64, 32)) == [0]
    camera = Camera(np.eye(4), _projection(0.1, 100.0), 64, 32, panorama=EQUIRECTANGULAR)
    size = face_size(EQUIRECTANGULAR, 64, 32)
    assert size == math.ceil(2 * 1.5 * 64 / (2 * math.pi))
    views = face_cameras(camera, size, list(range(6)))
    for (forward, _), view in zip(FACES, views, strict=True):
        assert view.view_matrix[:3, :3] @ forward == pytest.approx([0.0, 0.0, -1.0])
        assert view.width == view.height == size + 2 * GUARD_PIXELS
        assert view.panorama is None
        near, far = _near_far(view.projection_matrix)
        assert (near, far) == pytest.approx((0.1, 100.0))


def _projection(near: float, far: float) -> np.ndarray:
    p = np.zeros((4, 4))
    p[0, 0] = p[1, 1] = 1.0
    p[2, 2], p[2, 3], p[3, 2] = (far + near) / (near - far), 2 * far * near / (near - far), -1
    return p


def _near_far(p: np.ndarray) -> tuple[float, float]:
    return p[2, 3] / (p[2, 2] - 1.0), p[2, 3] / (p[2, 2] + 1.0)


def _face_passes(view: Camera, radius: float) -> dict[str, np.ndarray]:
    """A face's Combined (its pixels' world directions as colour) and Depth of a sphere of
    ``radius`` round the camera, as a render would give them."""
    n = view.width
    c = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    x, y = np.meshgrid(c, c)  # rows from the bottom
    tan_half = 1.0 / view.projection_matrix[0, 0]
    local = np.stack([x * tan_half, y * tan_half, -np.ones_like(x)], axis=-1)
    world = local @ view.view_matrix[:3, :3]  # face axes back to the camera's
    along = radius / np.linalg.norm(local, axis=-1, keepdims=True)  # depth of the sphere
    return {"Combined": unit(world).astype(np.float32),
            "Depth": along.astype(np.float32)}


def test_reading_the_faces_back_gives_each_pixel_its_direction_and_distance():
    camera = Camera(np.eye(4), _projection(0.1, 100.0), 96, 48, panorama=EQUIRECTANGULAR)
    rays = pixel_directions(EQUIRECTANGULAR, 96, 48)
    size = face_size(EQUIRECTANGULAR, 96, 48)
    faces = {k: _face_passes(view, 3.0)
             for k, view in zip(range(6), face_cameras(camera, size, list(range(6))),
                                strict=True)}
    out = resample(faces, size, rays)
    expected = np.mean([unit(d) for d in rays], axis=0)
    assert np.abs(out["Combined"] - expected).max() < 0.03
    assert out["Depth"] == pytest.approx(3.0, rel=0.02)  # the distance, not a face's depth


def test_pixels_outside_a_fisheye_s_circle_are_empty_and_its_rim_is_partly_covered():
    lens = Panorama("FISHEYE_EQUIDISTANT", fisheye_fov=math.pi)
    rays = pixel_directions(lens, 32, 32)
    needed = needed_faces(rays)
    assert 1 not in needed  # 180°: nothing behind
    size = face_size(lens, 32, 32)
    faces = {k: {"Combined": np.ones((size + 2 * GUARD_PIXELS,) * 2 + (4,), np.float32),
                 "Depth": np.full((size + 2 * GUARD_PIXELS,) * 2 + (1,), BACKGROUND_DEPTH,
                                  np.float32)}
             for k in needed}
    out = resample(faces, size, rays)["Combined"][..., 0]
    assert out[0, 0] == 0.0 and out[16, 16] == 1.0
    assert ((out > 0.0) & (out < 1.0)).any()  # the rim, in part
    assert abs(out.sum() - math.pi * 16 ** 2) < 0.02 * math.pi * 16 ** 2
