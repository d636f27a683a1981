"""Points on a scene's surfaces for imperfect shadow maps: subsets uniform by area, each
stratified on its own, stored as triangle index + barycentrics so that they follow moved or
deformed triangles (see ``gpu/ism.py``)."""

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


def spread_order(count: int) -> np.ndarray:
    """0 .. count-1 ordered by the base-2 radical inverse (bit reversal): every prefix of the
    order is spread evenly over the range."""
    index = np.arange(count, dtype=np.int64)
    bits = max(1, (count - 1).bit_length())
    reversed_bits = np.zeros(count, np.int64)
    for bit in range(bits):
        reversed_bits |= (index >> bit & 1) << (bits - 1 - bit)
    return np.argsort(reversed_bits, kind="stable")


R2 = np.array([0.7548776662466927, 0.5698402909980532])  # Roberts' 2D Kronecker sequence


def _stratified_barycentrics(group: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Barycentrics (n, 2) for points in runs of equal ``group`` (one triangle of one subset):
    the j-th point of a run takes the j-th point of a randomly shifted R2 sequence, folded from
    the unit square into the triangle, so that a subset's points on a large triangle are spread
    evenly, not clumped."""
    start = np.flatnonzero(np.r_[True, group[1:] != group[:-1]])
    run = np.repeat(np.arange(len(start)), np.diff(np.r_[start, len(group)]))
    rank = np.arange(len(group)) - start[run]
    uv = np.mod(rng.random((len(start), 2))[run] + rank[:, None] * R2, 1.0)
    return np.where(uv.sum(axis=1, keepdims=True) > 1, 1 - uv, uv).astype(np.float32)


def sample_surface_points(triangles: np.ndarray, count: int, seed: int,
                          subsets: int = 1) -> SurfacePoints:
    """``subsets`` runs of ``count`` points, each uniform by area and stratified on its own:
    systematic sampling of the area CDF with a random offset per run (each triangle gets the
    floor or the ceiling of its expected share of every run), and a run's points on one
    triangle spread by a shifted R2 sequence. Within a run the strata come in
    ``spread_order``, so any prefix of a run is an even subset of the scene (level of detail).
    Zero-area triangles get no points; a scene without area gives none."""
    area = triangle_areas(triangles)
    cumulative = np.cumsum(area)
    if count <= 0 or subsets <= 0 or len(area) == 0 or cumulative[-1] <= 0:
        return SurfacePoints(np.zeros(0, np.int32), np.zeros((0, 2), np.float32))
    rng = np.random.default_rng(seed)
    strata = (np.arange(count) + rng.random((subsets, 1))) * (cumulative[-1] / count)
    strata = np.minimum(strata, np.nextafter(cumulative[-1], 0))  # rounding: stay below the end
    triangle = np.searchsorted(cumulative, strata, side="right").astype(np.int32)
    group = triangle + np.arange(subsets, dtype=np.int64)[:, None] * len(area)
    uv = _stratified_barycentrics(group.ravel(), rng).reshape(subsets, count, 2)
    order = spread_order(count)
    return SurfacePoints(triangle[:, order].ravel(), uv[:, order].reshape(-1, 2))
