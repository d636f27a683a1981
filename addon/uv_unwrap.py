"""UV maps for bakes: whether a mesh's own UV map can hold a bake, and a new one from xatlas
when it cannot. Plain numpy arrays in and out (no Blender types)."""

from __future__ import annotations

import numpy as np
import xatlas

PADDING = 2  # texels between xatlas charts, so bilinear lookups do not mix two charts
AREA_SLACK = 1e-3  # rounding allowed in the non-overlap test of a UV map's area sum


def unsuitable(corner_uvs: np.ndarray | None) -> str | None:
    """Why a UV map (per triangle corner, (T*3, 2)) cannot hold a bake, or None if it can.

    A bake needs each surface point to own its texel: coordinates inside [0, 1] whose
    triangles' areas sum to at most the unit square (a necessary test of non-overlap: tiled,
    mirrored or stacked islands fail it; overlaps that do not raise the sum are not found)."""
    if corner_uvs is None or len(corner_uvs) == 0:
        return "it has no UV map"
    if not np.isfinite(corner_uvs).all():
        return "its UV map has NaN/Inf coordinates"
    if corner_uvs.min() < -AREA_SLACK or corner_uvs.max() > 1 + AREA_SLACK:
        return "its UV map reaches outside the unit square"
    a, b, c = (corner_uvs.reshape(-1, 3, 2)[:, i].astype(np.float64) for i in range(3))
    area = 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) -
                        (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])).sum()
    if area > 1 + AREA_SLACK:
        return f"its UV map's triangles overlap (their areas sum to {area:.2f} of the square)"
    return None


def unwrap(positions: np.ndarray, triangles: np.ndarray, resolution: int) -> np.ndarray:
    """xatlas UVs per triangle corner, (T*3, 2) float32 in [0, 1], for triangles (T, 3)
    indexing positions (P, 3), packed for a ``resolution``² image with padding."""
    atlas = xatlas.Atlas()
    atlas.add_mesh(np.ascontiguousarray(positions, np.float32),
                   np.ascontiguousarray(triangles, np.uint32))
    pack = xatlas.PackOptions()
    pack.padding = PADDING
    pack.resolution = int(resolution)
    pack.bilinear = True
    atlas.generate(pack_options=pack)
    _, indices, uvs = atlas.get_mesh(0)
    return np.ascontiguousarray(uvs[indices.ravel()], np.float32)
