"""The Vector pass: each pixel's motion, in pixels, from where its surface is at the previous
frame to where it is now (x, y) and from now to the next frame (z, w), both as Blender's
Vector Blur node reads them (measured against Cycles: a surface moving right by 6 pixels a
frame reads (-6, 0, -6, 0)). Surfaces move with their instance's matrices at the two times
(Instance.motion) and, on a deforming mesh, with its vertices (WorldGeometry.deform: the
point's barycentric share of its triangle's corners' displacements, in its instance's space
at each time), the view with the camera's (Camera.motion_views); the background is at
infinity, so only the camera's turning moves it."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..scene.environment import camera_directions
from ..scene.geometry import WorldGeometry
from ..scene.model import Camera, Scene
from .compose import central
from .id_passes import IdTables

if TYPE_CHECKING:  # image.py runs MotionVectors among its tile stages
    from .image import FrameGpu, TileWork
    from .state import FrameState

MIN_W = 1e-6  # a point this close to the camera's plane (or behind it) at a time: no vector


def _pixels(view_projection: np.ndarray, points: np.ndarray, camera: Camera
            ) -> tuple[np.ndarray, np.ndarray]:
    """Pixel coordinates (n, 2) of homogeneous world ``points`` (n, 4), and where they are
    in front of the camera."""
    clip = points @ view_projection.T
    w = clip[:, 3]
    ahead = w > MIN_W
    safe = np.where(ahead, w, 1.0)[:, None]
    size = np.array([camera.width, camera.height], np.float64)
    return (clip[:, :2] / safe * 0.5 + 0.5) * size, ahead


@dataclass(frozen=True)
class InstanceMotion:
    """Per instance + 1 (entry 0: none), made once a frame: whether it moves, the maps from
    its world placement now to those at the two times (identity where it does not move),
    (2, I + 1, 4, 4), and, where some mesh deforms, its linear map (object to world) at the
    two times, (2, I + 1, 3, 3)."""

    moves: np.ndarray
    deltas: np.ndarray
    linear: np.ndarray | None

    @classmethod
    def of(cls, scene: Scene, deforming: bool) -> InstanceMotion:
        count = len(scene.instances)
        moves = np.zeros(count + 1, bool)
        deltas = np.broadcast_to(np.eye(4), (2, count + 1, 4, 4)).copy()
        for index, instance in enumerate(scene.instances):
            if instance.motion is None:
                continue
            with np.errstate(all="ignore"):
                try:
                    inverse = np.linalg.inv(instance.matrix)
                except np.linalg.LinAlgError:
                    continue
                for k in (0, 1):
                    deltas[k, index + 1] = instance.motion[k] @ inverse
            if np.isfinite(deltas[:, index + 1]).all() and not (
                    np.allclose(deltas[0, index + 1], np.eye(4), atol=1e-12)
                    and np.allclose(deltas[1, index + 1], np.eye(4), atol=1e-12)):
                moves[index + 1] = True
            else:
                deltas[:, index + 1] = np.eye(4)
        linear = None
        if deforming:
            linear = np.broadcast_to(np.eye(3), (2, count + 1, 3, 3)).copy()
            linear[:, 1:] = np.nan_to_num(np.array(
                [[inst.matrix if inst.motion is None else inst.motion[k]
                  for inst in scene.instances] for k in (0, 1)],
                np.float64).reshape(2, count, 4, 4)[..., :3, :3])
        return cls(moves, deltas, linear)


def _displacements(points: np.ndarray, triangles: np.ndarray, geometry: WorldGeometry
                   ) -> np.ndarray:
    """How far world ``points`` (n, 3) on ``triangles`` (n,) of a deforming mesh move by the
    two times, in their instance's space: their barycentric share of the corners'
    (WorldGeometry.deform), (2, n, 3)."""
    corners = geometry.positions.reshape(-1, 3, 3)[triangles].astype(np.float64)
    a, e1, e2 = corners[:, 0], corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    p = points - a
    d11, d12, d22 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
    p1, p2 = (p * e1).sum(1), (p * e2).sum(1)
    with np.errstate(all="ignore"):
        det = d11 * d22 - d12 * d12
        u = np.nan_to_num((d22 * p1 - d12 * p2) / det)
        v = np.nan_to_num((d11 * p2 - d12 * p1) / det)
    weights = np.stack([1.0 - u - v, u, v], axis=1)
    moved = geometry.deform.reshape(2, -1, 3, 3)[:, triangles].astype(np.float64)
    return np.einsum("nc,kncj->knj", weights, moved)


def motion_vectors(position: np.ndarray, codes: np.ndarray, geometry: WorldGeometry,
                   motion: InstanceMotion, camera: Camera, x0: int, y0: int) -> np.ndarray:
    """The Vector pass (h, w, 4) of pixels [x0, x0 + w) × [y0, y0 + h) whose surfaces are at
    world ``position`` (h, w, 3) on triangles ``codes`` (IdTables.triangles: 0 none), which
    move as ``motion`` (of the frame's instances) says. Only
    moving pixels are projected: those of moving instances and deforming triangles, or all
    where the camera moves."""
    h, w = codes.shape
    projection = camera.projection_matrix
    views = camera.motion_views or (camera.view_matrix, camera.view_matrix)
    camera_moves = not all(np.array_equal(v, camera.view_matrix) for v in views)
    codes = codes.ravel()
    seen = codes > 0
    instance = np.zeros(h * w, np.int64)
    owners = geometry.triangle_instance
    moves, deltas, linear = motion.moves, motion.deltas, motion.linear
    warps = np.zeros(h * w, bool)  # on a deforming mesh's moving triangles
    if owners is not None and len(owners) and seen.any():
        instance[seen] = np.take(owners, codes[seen] - 1, mode="clip") + 1
        if geometry.deforming is not None:
            warps[seen] = np.take(geometry.deforming, codes[seen] - 1, mode="clip")
    pixels = np.arange(h * w) if camera_moves else np.flatnonzero(moves[instance] | warps)
    vectors = np.zeros((h * w, 4), np.float32)
    if pixels.size == 0:
        return vectors.reshape(h, w, 4)
    points = np.ones((pixels.size, 4))
    points[:, :3] = position.reshape(-1, 3)[pixels]
    background = ~seen[pixels]
    if background.any():  # at infinity, in the pixel's direction
        directions = camera_directions(camera, 1, x0, y0, w, h).reshape(-1, 3)
        points[background, :3], points[background, 3] = directions[pixels[background]], 0.0
    current, ahead = _pixels(projection @ camera.view_matrix, points, camera)
    ends = []
    owner = instance[pixels]
    moving = np.flatnonzero(moves[owner])
    warped = np.flatnonzero(warps[pixels])
    if warped.size:
        displaced = _displacements(points[warped, :3], codes[pixels[warped]] - 1, geometry)
    for k, view in enumerate(views):
        moved = points.copy()
        moved[moving] = np.einsum("nij,nj->ni", deltas[k][owner[moving]], points[moving])
        if warped.size:
            moved[warped, :3] += np.einsum("nij,nj->ni", linear[k][owner[warped]],
                                           displaced[k])
        ends.append(_pixels(projection @ view, moved, camera))
    (previous, ahead_before), (following, ahead_after) = ends
    vectors[pixels, :2] = np.where((ahead & ahead_before)[:, None], previous - current, 0.0)
    vectors[pixels, 2:] = np.where((ahead & ahead_after)[:, None], current - following, 0.0)
    return np.nan_to_num(vectors, nan=0.0, posinf=0.0, neginf=0.0).reshape(h, w, 4)


class MotionVectors:
    """A tile stage (image.py's TileStage interface): the Vector pass of one tile, from each
    pixel's centre supersample (as Cycles' data passes come from a pixel's first sample)."""

    name = "motion vectors"

    def run(self, frame: FrameState, data: FrameGpu, work: TileWork) -> None:
        if "Vector" not in frame.output or frame.scene.motion is None:
            return  # nothing moves (or a panorama's face: its views are not the camera's)
        with frame.stats.timed(self.name):
            if frame.id_tables is None:
                frame.id_tables = IdTables(frame.scene, frame.geometry)
            if frame.instance_motion is None:
                frame.instance_motion = InstanceMotion.of(
                    frame.scene, frame.geometry.deforming is not None)
            aa, tile, images = frame.settings.antialiasing, work.tile, work.gbuffer.images
            codes = frame.id_tables.triangles(central(images["geometric"], aa))
            position = central(images["position"][..., :3], aa)
            vectors = motion_vectors(position, codes, frame.geometry, frame.instance_motion,
                                     frame.camera, tile.x0 // aa, tile.y0 // aa)
            h, w = vectors.shape[:2]
            frame.output["Vector"][tile.y0 // aa:tile.y0 // aa + h,
                                   tile.x0 // aa:tile.x0 // aa + w] = vectors
