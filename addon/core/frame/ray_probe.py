"""The ray probe: what a short ray from a surface the camera sees costs in this scene, for the
automatic mode's prediction of the bias compensation (a ray of the clamp distance per
supersample), whose cost per ray differs between scenes far more than the rasterised stages'
do: at 640×360 the interior's took 1.3-1.5 and Sponza's 2.9 times the Cornell box's, and the
probe measured 1.1-1.2 and 2.9 times (docs/measurements.md, *The time mode's prediction*)."""

from __future__ import annotations

import time

import numpy as np

from ..scene.geometry import WorldGeometry
from ..scene.model import Camera
from ..scene.vectors import unit
from ..transport.guidance import camera_points
from ..transport.ray_caster import RayCaster

PROBE_POINTS = 4096  # camera points the probe's rays start from
RAYS_PER_POINT = 8
PROBE_REPEATS = 2  # the least of these measurements counts (the first may wait on a driver)
RAY_OFFSET = 1e-4  # × the scene's radius along the normal, off the surface


def ray_probe_seconds(camera: Camera, geometry: WorldGeometry, tracer: RayCaster,
                      radius: float, length: float, seed: int = 0) -> float:
    """Seconds the tracer takes for RAYS_PER_POINT random rays into the hemisphere of each of
    PROBE_POINTS points the camera sees, ``length`` long (the least of PROBE_REPEATS runs;
    0 where the camera sees nothing). ``tracer`` must hold ``geometry``'s triangles."""
    points = camera_points(camera, geometry, tracer, PROBE_POINTS, seed)
    if len(points) == 0:
        return 0.0
    normal = np.repeat(points.normal, RAYS_PER_POINT, axis=0)
    origin = np.repeat(points.position, RAYS_PER_POINT, axis=0) + normal * RAY_OFFSET * radius
    direction = unit(np.random.default_rng(seed).normal(size=normal.shape))
    direction *= np.where((direction * normal).sum(axis=1) < 0.0, -1.0, 1.0)[:, None]
    seconds = []
    for _ in range(PROBE_REPEATS):
        began = time.perf_counter()
        tracer.intersect(origin, direction, 0.0, length)
        seconds.append(time.perf_counter() - began)
    return min(seconds)
