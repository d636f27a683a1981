"""Vector helpers shared by the scene, light transport and GPU layers."""

from __future__ import annotations

import numpy as np


def unit(v: np.ndarray) -> np.ndarray:
    """Each vector of ``v`` (..., 3) scaled to length 1; zero vectors stay zero."""
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, n, out=np.zeros_like(v), where=n > 0)


def triangle_areas(triangles: np.ndarray) -> np.ndarray:
    """Areas (float64) of (T, 3, 3) triangles; 0 where a coordinate is not finite."""
    tris = np.asarray(triangles, np.float64).reshape(-1, 3, 3)
    with np.errstate(invalid="ignore", over="ignore"):
        area = 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]),
                                    axis=1)
    return np.where(np.isfinite(area), area, 0.0)
