"""Points on a scene's surfaces for imperfect shadow maps: the triangles' area CDF that the GPU
draws them from (``gpu_shaders/ism_points_lib.glsl``), and the points as read back, stored as
triangle index + barycentrics so that they follow moved or deformed triangles."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .vectors import triangle_areas


@dataclass
class SurfacePoints:
    """Points on triangles: ``triangle`` (n,) int32 and ``barycentric`` (n, 2) float32, the
    weights of vertices 1 and 2."""

    triangle: np.ndarray
    barycentric: np.ndarray

    def __len__(self) -> int:
        return len(self.triangle)


def area_cdf(triangles: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray | None:
    """(T,) float32 cumulative area / total area of (T, 3, 3) triangles, each area times its
    ``weight`` (T,) where given, the last exactly 1 (zero-area and non-finite triangles add
    nothing); None when there is no area."""
    areas = triangle_areas(triangles)
    cumulative = np.cumsum(areas if weights is None else areas * weights)
    if len(cumulative) == 0 or not cumulative[-1] > 0:
        return None
    cdf = (cumulative / cumulative[-1]).astype(np.float32)
    cdf[-1] = 1.0
    return cdf


def cdf_guide(cdf: np.ndarray) -> np.ndarray:
    """(T + 1,) uint32 guide table of a (T,) CDF: entry g is the first triangle whose CDF
    exceeds g / T, so a search for x needs only the triangles between the entries around
    x · T (the cutpoint method: a few steps on average, not log2 T)."""
    cells = np.arange(len(cdf) + 1, dtype=np.float64) / len(cdf)
    return np.searchsorted(cdf.astype(np.float64), cells, side="right").astype(np.uint32)
