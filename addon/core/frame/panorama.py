"""Panoramic cameras (Cycles' equirectangular and fisheye lenses) from six perspective views.

A rasteriser sees through a pinhole, so a panorama is rendered as the faces of a cube round
the camera (90° views with a guard band of GUARD_PIXELS, only the faces the image looks
through), each a frame of its own with the same VPLs, and every pixel of the panorama reads
its direction's face bilinearly. Directions follow Cycles (kernel/camera/projection.h) in its
panorama space, whose x is the camera's view (-Z), y its left (-X) and z its up (+Y).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..scene.model import Camera, Panorama
from .compose import BACKGROUND_DEPTH
from .id_passes import (
    CRYPTO_FAMILIES,
    INDEX_PASSES,
    family_of,
    family_passes,
    is_id_pass,
    joined_ranks,
    merge_ranks,
    split_ranks,
)

GUARD_PIXELS = 2  # beyond each face's 90°, so that bilinear reads never leave it
MAX_FACE_SIZE = 4096
FACE_DENSITY = 1.5  # face pixels per panorama pixel where the panorama is finest
# Each face: (the camera-local direction it looks along, its up), in Blender's camera axes.
FACES = ((np.array([0.0, 0.0, -1.0]), np.array([0.0, 1.0, 0.0])),   # front
         (np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0])),    # back
         (np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])),    # right
         (np.array([-1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])),   # left
         (np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])),    # up
         (np.array([0.0, -1.0, 0.0]), np.array([0.0, 0.0, -1.0])))  # down
SUBPIXELS = ((0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75))
KINDS = ("EQUIRECTANGULAR", "FISHEYE_EQUIDISTANT", "FISHEYE_EQUISOLID", "MIRRORBALL")
"""The panorama types rendered (the others: as a perspective camera, with a warning)."""


def _face_axes(k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Face ``k``'s right, up and forward in the camera's axes."""
    forward, up = FACES[k]
    return np.cross(forward, up), up, forward


def _from_cycles(d: np.ndarray) -> np.ndarray:
    """Cycles' panorama-space directions (..., 3) in Blender's camera axes."""
    return np.stack([-d[..., 1], d[..., 2], -d[..., 0]], axis=-1)


def _fisheye(u: np.ndarray, v: np.ndarray, theta: np.ndarray, inside: np.ndarray
             ) -> np.ndarray:
    """Cycles' fisheye direction at image-plane offsets (u, v) and angle theta from the view."""
    r = np.hypot(u, v)
    phi = np.arccos(np.clip(np.where(r > 0, u / np.maximum(r, 1e-30), 0.0), -1.0, 1.0))
    phi = np.where(v < 0, -phi, phi)
    d = np.stack([np.cos(theta), -np.cos(phi) * np.sin(theta), np.sin(phi) * np.sin(theta)],
                 axis=-1)
    return np.where(inside[..., None], d, 0.0)


def directions(panorama: Panorama, width: int, height: int,
               offset: tuple[float, float] = (0.5, 0.5)) -> np.ndarray:
    """The viewing direction (height, width, 3) through each pixel's point ``offset`` (in
    pixels from its lower left corner) in the camera's axes, rows from the image's bottom;
    zero where the lens sees nothing (outside a fisheye's circle)."""
    u = ((np.arange(width) + offset[0]) / width)[None, :].repeat(height, axis=0)
    v = ((np.arange(height) + offset[1]) / height)[:, None].repeat(width, axis=1)
    p = panorama
    if p.kind == "EQUIRECTANGULAR":
        phi = (p.longitude_min - p.longitude_max) * u - p.longitude_min
        theta = (p.latitude_min - p.latitude_max) * v - p.latitude_min + math.pi / 2
        d = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)],
                     axis=-1)
    elif p.kind == "FISHEYE_EQUIDISTANT":
        x, y = 2.0 * (u - 0.5), 2.0 * (v - 0.5)
        r = np.hypot(x, y)
        d = _fisheye(x, y, r * p.fisheye_fov * 0.5, r <= 1.0)
    elif p.kind == "FISHEYE_EQUISOLID":
        x, y = (u - 0.5) * p.sensor_width, (v - 0.5) * p.sensor_height
        r = np.hypot(x, y)
        inside = r <= 2.0 * p.fisheye_lens * math.sin(p.fisheye_fov * 0.25)
        theta = 2.0 * np.arcsin(np.clip(r / (2.0 * p.fisheye_lens), -1.0, 1.0))
        d = _fisheye(x, y, theta, inside)
    else:  # MIRRORBALL: the reflection of a view along -y off a unit ball
        x, z = 2.0 * u - 1.0, 2.0 * v - 1.0
        inside = x * x + z * z <= 1.0
        n = np.stack([x, -np.sqrt(np.maximum(1.0 - x * x - z * z, 0.0)), z], axis=-1)
        incoming = np.array([0.0, -1.0, 0.0])
        d = n * (2.0 * (n @ incoming))[..., None] - incoming
        local = _from_cycles(np.where(inside[..., None], d, 0.0))
        # Cycles' ball image has the view at its centre and the camera's right on its right:
        # the reflection above with the view and the right swapped (measured against Cycles).
        return np.stack([-local[..., 2], local[..., 1], -local[..., 0]], axis=-1)
    return _from_cycles(d)


def face_size(panorama: Panorama, width: int, height: int) -> int:
    """Face pixels across 90° for the panorama's finest pixels: 2 × its pixels per radian
    (a face's centre has size / 2 per radian)."""
    p = panorama
    if p.kind == "EQUIRECTANGULAR":
        per_radian = max(width / max(p.longitude_max - p.longitude_min, 1e-6),
                         height / max(p.latitude_max - p.latitude_min, 1e-6))
    elif p.kind == "FISHEYE_EQUIDISTANT":
        per_radian = max(width, height) / max(p.fisheye_fov, 1e-6)
    elif p.kind == "FISHEYE_EQUISOLID":
        per_radian = p.fisheye_lens * max(width / p.sensor_width, height / p.sensor_height)
    else:
        per_radian = max(width, height) / 2.0  # the ball's rim packs more: its centre's rate
    return int(min(max(math.ceil(2.0 * FACE_DENSITY * per_radian), 8), MAX_FACE_SIZE))


def face_cameras(camera: Camera, size: int, needed: list[int]) -> list[Camera]:
    """The perspective cameras of the faces ``needed`` (size × size plus the guard band), at
    the panorama camera's place, with its near and far planes."""
    inner = size + 2 * GUARD_PIXELS
    tan_half = inner / size
    p = camera.projection_matrix
    near, far = p[2, 3] / (p[2, 2] - 1.0), p[2, 3] / (p[2, 2] + 1.0)
    projection = np.zeros((4, 4))
    projection[0, 0] = projection[1, 1] = 1.0 / tan_half
    projection[2, 2] = (far + near) / (near - far)
    projection[2, 3] = 2.0 * far * near / (near - far)
    projection[3, 2] = -1.0
    cameras = []
    for k in needed:
        right, up, forward = _face_axes(k)
        rotation = np.eye(4)
        rotation[:3, :3] = np.stack([right, up, -forward])  # face axes from the camera's
        cameras.append(replace(camera, view_matrix=rotation @ camera.view_matrix,
                               projection_matrix=projection, width=inner, height=inner,
                               panorama=None, aperture=None))
    return cameras


def _face_of(d: np.ndarray) -> np.ndarray:
    """The index into FACES each direction (..., 3) looks through."""
    axis = np.abs(d).argmax(axis=-1)
    positive = np.take_along_axis(d, axis[..., None], axis=-1)[..., 0] > 0
    # FACES order: -z, +z, +x, -x, +y, -y
    table = np.array([[3, 2], [5, 4], [0, 1]])
    return table[axis, positive.astype(int)]


def needed_faces(rays: list[np.ndarray]) -> list[int]:
    """The faces any seen direction of ``rays`` looks through."""
    faces: set[int] = set()
    for d in rays:
        faces.update(int(k) for k in np.unique(_face_of(d[np.any(d != 0, axis=-1)])))
    return sorted(faces)


def pixel_directions(panorama: Panorama, width: int, height: int) -> list[np.ndarray]:
    """The directions of each pixel's SUBPIXELS (``directions``)."""
    return [directions(panorama, width, height, offset) for offset in SUBPIXELS]


def resample(faces: dict[int, dict[str, np.ndarray]], size: int, rays: list[np.ndarray]
             ) -> dict[str, np.ndarray]:
    """The panorama's passes from the faces': the mean over each pixel's subpixels of the
    faces read bilinearly in their directions (``pixel_directions``), as Cycles' one-pixel
    box filter averages its samples (a subpixel that sees nothing adds 0: a fisheye's rim);
    Depth the nearest, as the distance along the ray (Cycles' Z of a panorama); the index
    passes the first subpixel's nearest face pixel, Cryptomatte the merged ranks of each
    subpixel's nearest."""
    images = [_resample_at(faces, size, d) for d in rays]
    out = {}
    for name in images[0]:
        stack = [image[name] for image in images]
        if name in INDEX_PASSES:
            out[name] = stack[0]
        elif family_of(name) is None:
            out[name] = np.minimum.reduce(stack) if name == "Depth" \
                else (sum(stack) / len(stack)).astype(np.float32)
    for family in CRYPTO_FAMILIES:
        names = family_passes(images[0], family)
        if names:
            ranks = [split_ranks([image[n] for n in names]) for image in images]
            ids, weights = merge_ranks(np.concatenate([r[0] for r in ranks], axis=-1),
                                       np.concatenate([r[1] for r in ranks], axis=-1)
                                       / len(ranks), 2 * len(names))
            out.update(zip(names, joined_ranks(ids, weights), strict=True))
    return out


def _resample_at(faces: dict[int, dict[str, np.ndarray]], size: int, d: np.ndarray
                 ) -> dict[str, np.ndarray]:
    """The faces' passes read bilinearly in the directions ``d`` (h, w, 3); 0 (Depth
    BACKGROUND_DEPTH) where a direction is zero."""
    h, w = d.shape[:2]
    first = next(iter(faces.values()))
    out = {n: np.zeros((h, w, image.shape[2]), np.float32) for n, image in first.items()}
    if "Depth" in out:
        out["Depth"][:] = BACKGROUND_DEPTH
    face = _face_of(d)
    seen = np.any(d != 0, axis=-1)
    half = size / 2.0
    for k, passes in faces.items():
        rows, cols = np.nonzero(seen & (face == k))
        if rows.size == 0:
            continue
        right, up, forward = _face_axes(k)
        ray = d[rows, cols]
        along = ray @ forward
        x = (ray @ right) / along * half + half + GUARD_PIXELS - 0.5
        y = (ray @ up) / along * half + half + GUARD_PIXELS - 0.5
        x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
        tx, ty = (x - x0)[:, None], (y - y0)[:, None]
        for name, image in passes.items():
            if is_id_pass(name):
                out[name][rows, cols] = image[np.rint(y).astype(int), np.rint(x).astype(int)]
                continue
            value = (image[y0, x0] * (1 - tx) * (1 - ty) + image[y0, x0 + 1] * tx * (1 - ty)
                     + image[y0 + 1, x0] * (1 - tx) * ty + image[y0 + 1, x0 + 1] * tx * ty)
            if name == "Depth":
                nearest = np.minimum.reduce([image[y0, x0], image[y0, x0 + 1],
                                             image[y0 + 1, x0], image[y0 + 1, x0 + 1]])
                length = np.linalg.norm(ray, axis=1)[:, None]
                value = np.where(nearest >= BACKGROUND_DEPTH, BACKGROUND_DEPTH,
                                 value * length / along[:, None])
            out[name][rows, cols] = value
    return out
