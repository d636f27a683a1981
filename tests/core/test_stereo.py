"""Stereo views (scene/stereo.py): an eye's camera, its shift, and the camera's own view left
alone. The eyes against Cycles' are in tests/blender/test_stereo.py."""

from __future__ import annotations

import numpy as np

from addon.core.scene.model import Camera
from addon.core.scene.stereo import StereoView, in_view, shift_scale, stereo_view


def _camera(orthographic: bool) -> Camera:
    projection = np.diag([1.0, 1.5, -1.0, 0.0 if not orthographic else 1.0])
    if not orthographic:
        projection[3, 2], projection[2, 3] = -1.0, -0.2
    placed = np.eye(4)
    placed[:3, 3] = (1.0, 2.0, 3.0)
    view = np.linalg.inv(placed)
    return Camera(view, projection, 64, 48, is_orthographic=orthographic,
                  motion_views=(view, view))


def test_an_eye_moves_the_view_and_shifts_the_image():
    """The left eye 0.15 m along the camera's x axis: a point seen at the camera's centre is
    seen 0.15 m to the right in the eye's view; a shift of 0.05 more than the camera's moves
    a perspective frustum's skew and an orthographic image's offset by 0.1 of clip space."""
    for orthographic in (False, True):
        camera = _camera(orthographic)
        placed = np.linalg.inv(camera.view_matrix)
        eye_placed = placed.copy()
        eye_placed[:3, 3] += placed[:3, 0] * -0.15
        view = stereo_view("left", placed, eye_placed, 0.05, 1.0)
        eye = in_view(camera, view)
        centre = placed @ np.array([0.0, 0.0, -2.0, 1.0])
        np.testing.assert_allclose((eye.view_matrix @ centre)[:3], [0.15, 0.0, -2.0],
                                   atol=1e-12)
        np.testing.assert_allclose(eye.motion_views[0], eye.view_matrix, atol=1e-12)
        moved = eye.projection_matrix - camera.projection_matrix
        expected = np.zeros((4, 4))
        expected[(0, 3) if orthographic else (0, 2)] = -0.1 if orthographic else 0.1
        np.testing.assert_allclose(moved, expected, atol=1e-12)


def test_the_cameras_own_view_is_the_camera():
    camera = _camera(False)
    assert in_view(camera, StereoView()) is camera


def test_the_shift_is_in_units_of_the_fitted_side():
    assert shift_scale("AUTO", 64, 48) == 1.0 and shift_scale("HORIZONTAL", 48, 64) == 1.0
    assert shift_scale("AUTO", 48, 64) == 64 / 48 and shift_scale("VERTICAL", 64, 48) == 0.75
