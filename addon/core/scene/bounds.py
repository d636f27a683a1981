"""The scene's bounding sphere, robust to far outliers: the clamp distance, shadow-map depth
ranges, imperfect-shadow-map depths and ray offsets are relative to it, so one object at
x = 1e30 (or 1e4 m from a 1 m scene) must not set it.

The bounds come from what can reach the camera's view: the *core* is the box around the
camera, the vertex nearest to it and every vertex inside its view frustum; geometry farther
than OUTLIER_FACTOR times the core's size from the core is an outlier. Outliers are still
rendered, but left out of the sphere, with one warning naming their objects. A scene without
outliers gets exactly ``bounding_sphere`` of all its vertices."""

from __future__ import annotations

import numpy as np

from .geometry import bounding_sphere
from .model import Camera, Instance

OUTLIER_FACTOR = 100.0
"""Geometry beyond this many core sizes from the core does not set the bounds. Light from
there reaches the view with a share of the order of 1 / OUTLIER_FACTOR² (1e-4) or less."""
NAMED_OUTLIERS = 3  # objects named in the warning
SAMPLE_STRIDE = 64
"""Every this many-th vertex is tested for the quick answer that a scene has no outliers."""


def _in_view(camera: Camera, points: np.ndarray) -> np.ndarray:
    """Which points (n, 3) lie inside the camera's view frustum (near and far clip
    included)."""
    clip_matrix = camera.projection_matrix @ camera.view_matrix
    clip = points.astype(np.float64) @ clip_matrix[:, :3].T + clip_matrix[:, 3]
    w = clip[:, 3:]
    with np.errstate(invalid="ignore"):
        return (w[:, 0] > 0) & np.all(np.abs(clip[:, :3]) <= w, axis=1)


def view_core(camera: Camera, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Corners (lo, hi) of the box around the camera's position, the vertex nearest to it and
    the vertices (n, 3), n > 0, in its view."""
    eye = camera.position
    points = positions.astype(np.float64)
    nearest = points[np.argmin(((points - eye) ** 2).sum(axis=1))]
    seen = points[_in_view(camera, positions)]
    core = np.vstack([eye, nearest, seen])
    return core.min(axis=0), core.max(axis=0)


def _surely_inside(positions: np.ndarray, sphere: tuple[np.ndarray, float], camera: Camera
                   ) -> bool:
    """Whether every vertex surely lies within OUTLIER_FACTOR core sizes of the core, from
    every SAMPLE_STRIDE-th vertex (a few ms where the whole test takes 0.1 s for 200k
    vertices): the camera and the sampled vertices in view lie in the core, so the box around
    them, grown by OUTLIER_FACTOR times its size, lies inside the core's grown box. False when
    that does not settle it."""
    sample = positions[::SAMPLE_STRIDE]
    seen = sample[_in_view(camera, sample)].astype(np.float64)
    if len(seen) == 0:
        return False
    eye = camera.position
    lo, hi = np.minimum(seen.min(axis=0), eye), np.maximum(seen.max(axis=0), eye)
    reach = OUTLIER_FACTOR * float(np.linalg.norm(hi - lo))
    centre, radius = sphere
    return bool(np.all(centre - radius >= lo - reach) and np.all(centre + radius <= hi + reach))


def robust_bounds(positions: np.ndarray, camera: Camera | None, instances: list[Instance],
                  sphere: tuple[np.ndarray, float] | None = None
                  ) -> tuple[np.ndarray, float, str | None]:
    """Centre and radius of the scene's bounding sphere, without far outliers, and the warning
    that names the outlying objects (None without outliers: then the sphere is
    ``bounding_sphere(positions)``, or ``sphere`` where the caller has it). ``positions``: the
    flattened triangles' (finite) vertices; ``instances``: the scene's, to name the
    outliers."""
    sphere = sphere if sphere is not None else bounding_sphere(positions)
    if len(positions) == 0 or camera is None or not np.isfinite(camera.view_matrix).all() \
            or abs(np.linalg.det(camera.view_matrix)) < 1e-300 \
            or _surely_inside(positions, sphere, camera):
        return (*sphere, None)
    lo, hi = view_core(camera, positions)
    reach = OUTLIER_FACTOR * max(float(np.linalg.norm(hi - lo)), 1e-30)
    lo, hi = lo - reach, hi + reach
    if np.all(positions.min(axis=0) >= lo) and np.all(positions.max(axis=0) <= hi):
        return (*sphere, None)
    inside = np.all((positions >= lo) & (positions <= hi), axis=1)
    centre, radius = bounding_sphere(positions[inside])
    names = sorted({inst.mesh.name for inst in instances if _reaches_out(inst, lo, hi)})
    listed = ", ".join(f"'{name}'" for name in names[:NAMED_OUTLIERS])
    more = f" and {len(names) - NAMED_OUTLIERS} more" if len(names) > NAMED_OUTLIERS else ""
    warning = (f"far outliers {listed}{more}: over {OUTLIER_FACTOR:g} times the size of the "
               f"camera's view away from it; rendered, but left out of the scene's bounds "
               f"(which the clamp distance, shadow-map depths and ray offsets scale with)")
    return centre, radius, warning


def _reaches_out(instance: Instance, lo: np.ndarray, hi: np.ndarray) -> bool:
    """Whether some vertex of the instance lies outside the box (lo, hi)."""
    points = instance.mesh.positions.astype(np.float64) @ instance.matrix[:3, :3].T \
        + instance.matrix[:3, 3]
    with np.errstate(invalid="ignore"):
        return bool(np.any((points < lo) | (points > hi)))
