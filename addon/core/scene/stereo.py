"""Stereoscopy (Output Properties > Stereoscopy): each view (eye) is the scene camera moved
as Blender moves it for that view (its interocular distance, convergence mode and distance)
with its own horizontal shift (off-axis convergence), rendered as a camera of its own."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .model import Camera


@dataclass(frozen=True)
class StereoView:
    """A view's name (empty: the only one) and how it differs from the camera: ``eye``
    maps the camera's view space to the view's (identity for the camera's own), and its
    image is shifted by ``shift`` of its width in clip space."""

    name: str = ""
    eye: np.ndarray | None = None
    shift: float = 0.0


def stereo_view(name: str, camera_matrix: np.ndarray, view_matrix: np.ndarray,
                shift: float, scale: float) -> StereoView:
    """The view ``name`` of a camera placed at ``camera_matrix`` (its object's world matrix)
    that Blender places at ``view_matrix`` for it (RenderEngine.camera_model_matrix) and
    shifts by ``shift`` more than the camera's own Shift X, times ``scale`` (shift_scale)."""
    eye = np.linalg.inv(np.asarray(view_matrix, np.float64)) @ np.asarray(camera_matrix,
                                                                           np.float64)
    return StereoView(name, eye, 2.0 * shift * scale)


def shift_scale(sensor_fit: str, width: float, height: float) -> float:
    """A camera's Shift X in units of its image's width: 1 where the sensor fits the width
    (Horizontal, or Auto for a wide image), height / width where it fits the height
    (``width`` and ``height`` with the pixel aspect applied), as Blender's view plane has it."""
    horizontal = width >= height if sensor_fit == "AUTO" else sensor_fit == "HORIZONTAL"
    return 1.0 if horizontal else height / width


def in_view(camera: Camera, view: StereoView) -> Camera:
    """``camera`` as ``view`` sees: its view matrices (and those at motion blur's times)
    moved by the eye, its projection shifted (perspective: the frustum's skew; orthographic:
    its offset)."""
    if view.eye is None:
        return camera
    projection = np.array(camera.projection_matrix, np.float64)
    if camera.is_orthographic:
        projection[0, 3] -= view.shift
    else:
        projection[0, 2] += view.shift
    motion = None if camera.motion_views is None else \
        tuple(view.eye @ np.asarray(m, np.float64) for m in camera.motion_views)
    return replace(camera, view_matrix=view.eye @ np.asarray(camera.view_matrix, np.float64),
                   projection_matrix=projection, motion_views=motion)
