"""What light transport needs of a ray tracer (the GPU's, ``gpu/raytrace.py``, is one)."""

from __future__ import annotations

from typing import Protocol

import numpy as np


class RayHits(Protocol):
    """Closest hits of a batch of rays."""

    distance: np.ndarray  # (R,) inf where missed
    triangle: np.ndarray  # (R,) triangle index, -1 where missed
    barycentric: np.ndarray  # (R, 2) weights of vertices 1 and 2
    transmittance: np.ndarray  # (R, 3) light let through by clear surfaces before the hit


class RayCaster(Protocol):
    """Closest-hit and any-hit queries against the frame's triangles."""

    def intersect(self, origins: np.ndarray, directions: np.ndarray,
                  t_min: float | np.ndarray = 0.0, t_max: float | np.ndarray = np.inf,
                  shadow: bool = False, diffuse: bool = False) -> RayHits:
        """Closest hit of each ray (R, 3) with ``t_min < t < t_max``; ``shadow``: a light's
        rays (Cycles' shadow rays), which objects with Shadow visibility off let through;
        ``diffuse``: diffuse bounces, which objects with Diffuse visibility off let through."""
        ...

    def occluded(self, origins: np.ndarray, directions: np.ndarray, t_max: float | np.ndarray,
                 t_min: float | np.ndarray = 0.0, shadow: bool = False,
                 diffuse: bool = False) -> np.ndarray:
        """Whether each ray (R, 3) hits anything opaque with ``t_min < t < t_max``."""
        ...
