"""Light samples that light no point the camera sees: rays from camera points to each sample
(a few points first, then all of them for the samples none of the few reaches), so that a
frame renders no shadow map for light the view cannot receive, such as the world's directions
that a room's walls block (the interior sample scene: 49 of its 64)."""

from __future__ import annotations

import numpy as np

from .guidance import CameraPoints
from .lights import KIND_COSINE, KIND_DIRECTIONAL, LightSamples
from .ray_caster import RayCaster

FIRST_POINTS = 256  # camera points every sample is tested from first
MAX_RAYS = 1 << 20  # rays of the second round (fewer points where there are many samples)


def reaches_view(samples: LightSamples, points: CameraPoints, tracer: RayCaster,
                 offset: float) -> np.ndarray:
    """(n,) bool: whether a ray from some camera point (moved ``offset`` off its surface)
    reaches each sample unblocked: towards a directional sample's light, to a point sample in
    front of its emitting side (either side of an emissive triangle's). True, untested, for
    samples that cast no shadow (they reach through anything) and for an area light's samples
    (its exact unshadowed light is scaled by the share of its samples a draw holds, so they
    are kept together)."""
    reached = ~samples.casts_shadow.astype(bool)
    if samples.shape is not None:
        reached |= samples.shape >= 0
    for first in (FIRST_POINTS, len(points)):
        todo = np.flatnonzero(~reached)
        if len(todo) == 0 or len(points) == 0:
            break
        count = min(first, max(1, MAX_RAYS // len(todo)), len(points))
        chosen = np.linspace(0, len(points) - 1, count).astype(int)  # spread over the image
        origin = points.position[chosen] + points.normal[chosen] * offset
        lit = _unblocked(samples, todo, origin, tracer)
        reached[todo[lit.any(axis=1)]] = True
    return reached


def _unblocked(samples: LightSamples, todo: np.ndarray, origin: np.ndarray,
               tracer: RayCaster) -> np.ndarray:
    """(len(todo), points) bool: the rays from each origin to each sample in ``todo``."""
    kind = samples.kind[todo][:, None]  # (m, 1) against (m, points)
    position, axis = samples.position[todo][:, None], samples.axis[todo][:, None]
    directional = kind == KIND_DIRECTIONAL
    to_light = np.where(directional[..., None], -axis, position - origin[None])
    distance = np.linalg.norm(to_light, axis=-1)
    direction = to_light / np.maximum(distance, 1e-30)[..., None]
    t_max = np.where(directional, np.inf, distance * (1.0 - 1e-4))
    # a one-sided emitter (KIND_COSINE) facing away; emissive triangles (KIND_COSINE2) emit
    # from both sides
    behind = (kind == KIND_COSINE) & ((direction * axis).sum(axis=-1) >= 0.0)
    shape = direction.shape[:2]
    blocked = tracer.occluded(np.broadcast_to(origin[None], (*shape, 3)).reshape(-1, 3),
                              direction.reshape(-1, 3), t_max.reshape(-1), shadow=True)
    return ~blocked.reshape(shape) & ~behind
