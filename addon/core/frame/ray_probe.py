"""The ray probes: what a short ray from a surface the camera sees costs in this scene, for the
automatic mode's prediction of the bias compensation (a ray of the clamp distance per
supersample), whose cost per ray differs between scenes far more than the rasterised stages'
do: at 640×360 the interior's took 1.3-1.5 and Sponza's 2.9 times the Cornell box's, and the
probe measured 1.1-1.2 and 2.9 times (docs/measurements.md, *The time mode's prediction*);
and what a ray from such a surface to a VPL costs, for a pass that traces its VPLs'
visibility (the short rays' probe put the interior's and Sponza's traced passes at 1.3 and
1.6 times what they took)."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from ..scene.geometry import WorldGeometry
from ..scene.model import Camera
from ..scene.vectors import unit
from ..transport.guidance import camera_points
from ..transport.ray_caster import RayCaster

PROBE_POINTS = 4096  # camera points the probe's rays start from
VISIBILITY_POINTS = 1024  # those of the visibility probe (its long rays cost more)
RAYS_PER_POINT = 8
PROBE_REPEATS = 2  # the least of these measurements counts (the first may wait on a driver)
RAY_OFFSET = 1e-4  # × the scene's radius along the normal, off the surface


def ray_probe_seconds(camera: Camera, geometry: WorldGeometry, tracer: RayCaster,
                      radius: float, length: float, seed: int = 0) -> float:
    """Seconds the tracer takes for RAYS_PER_POINT random rays into the hemisphere of each of
    PROBE_POINTS points the camera sees, ``length`` long (the least of PROBE_REPEATS runs;
    0 where the camera sees nothing). ``tracer`` must hold ``geometry``'s triangles."""
    origin, normal = _ray_origins(camera, geometry, tracer, radius, PROBE_POINTS, seed)
    if len(origin) == 0:
        return 0.0
    direction = unit(np.random.default_rng(seed).normal(size=normal.shape))
    direction *= np.where((direction * normal).sum(axis=1) < 0.0, -1.0, 1.0)[:, None]
    return _least_seconds(lambda: tracer.intersect(origin, direction, 0.0, length))


def visibility_probe_seconds(camera: Camera, geometry: WorldGeometry, tracer: RayCaster,
                             radius: float, targets: np.ndarray, seed: int = 0) -> float:
    """Seconds the tracer takes for a shadow ray from each of VISIBILITY_POINTS points the
    camera sees to each of RAYS_PER_POINT of the ``targets`` (VPL positions, (n, 3)) drawn at
    random (the least of PROBE_REPEATS runs; 0 where the camera sees nothing or there is no
    target). Every pair is traced, facing or not: tracing only facing pairs, as the gather
    does, put the traced passes of the interior and Sponza below their time (the probe's VPLs,
    from unguided paths, face the view less than a frame's guided ones)."""
    targets = np.asarray(targets, np.float64).reshape(-1, 3)
    if len(targets) == 0:
        return 0.0
    origin, _ = _ray_origins(camera, geometry, tracer, radius, VISIBILITY_POINTS, seed)
    if len(origin) == 0:
        return 0.0
    offset = targets[np.random.default_rng(seed).integers(len(targets), size=len(origin))] \
        - origin
    distance = np.maximum(np.linalg.norm(offset, axis=1), 1e-12)
    direction = offset / distance[:, None]
    return _least_seconds(lambda: tracer.occluded(origin, direction, distance * (1.0 - 1e-4)))


def _ray_origins(camera: Camera, geometry: WorldGeometry, tracer: RayCaster, radius: float,
                 count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """RAYS_PER_POINT ray origins at each of ``count`` points the camera sees, lifted
    RAY_OFFSET × ``radius`` off the surface, and their normals ((m, 3) each; m = 0 where the
    camera sees nothing)."""
    points = camera_points(camera, geometry, tracer, count, seed)
    normal = np.repeat(points.normal, RAYS_PER_POINT, axis=0)
    origin = np.repeat(points.position, RAYS_PER_POINT, axis=0) + normal * RAY_OFFSET * radius
    return origin, normal


def _least_seconds(trace: Callable[[], object]) -> float:
    """The least of PROBE_REPEATS timings of ``trace`` (the first may wait on a driver)."""
    seconds = []
    for _ in range(PROBE_REPEATS):
        began = time.perf_counter()
        trace()
        seconds.append(time.perf_counter() - began)
    return min(seconds)
