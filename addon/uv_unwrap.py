"""UV maps for bakes: whether a mesh's own UV map can hold a bake, and a new one from xatlas
when it cannot. Plain numpy arrays in and out (no Blender types)."""

from __future__ import annotations

import numpy as np
import xatlas

PADDING = 2  # texels between xatlas charts, so bilinear lookups do not mix two charts
AREA_SLACK = 1e-3  # rounding allowed in the non-overlap test of a UV map's area sum
COLLAPSED_SHARE = 0.01  # of the surface a UV map may map to no area and still hold a bake


def unsuitable(corner_uvs: np.ndarray | None, corner_positions: np.ndarray | None = None
               ) -> str | None:
    """Why a UV map (per triangle corner, (T*3, 2)) cannot hold a bake, or None if it can.

    A bake needs each surface point to own its texel: coordinates inside [0, 1] whose
    triangles' areas sum to at most the unit square (tiled, mirrored or stacked islands
    usually fail that) and that share no texel centre of a coarse grid (``shared_texels``:
    the overlaps the sum misses); with ``corner_positions`` (T*3, 3), no more than
    COLLAPSED_SHARE of the surface on triangles of no area in UV (a text object's faces)."""
    if corner_uvs is None or len(corner_uvs) == 0:
        return "it has no UV map"
    if not np.isfinite(corner_uvs).all():
        return "its UV map has NaN/Inf coordinates"
    if corner_uvs.min() < -AREA_SLACK or corner_uvs.max() > 1 + AREA_SLACK:
        return "its UV map reaches outside the unit square"
    a, b, c = (corner_uvs.reshape(-1, 3, 2)[:, i].astype(np.float64) for i in range(3))
    areas = 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) -
                         (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    area = areas.sum()
    if corner_positions is not None:
        p = corner_positions.reshape(-1, 3, 3).astype(np.float64)
        surface = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
        collapsed = surface[areas <= 1e-12].sum() / max(surface.sum(), 1e-300)
        if collapsed > COLLAPSED_SHARE:
            return f"its UV map collapses {100 * collapsed:.0f} % of the surface to lines " \
                   f"or points"
    if area > 1 + AREA_SLACK:
        return f"its UV map's triangles overlap (their areas sum to {area:.2f} of the square)"
    shared = shared_texels(corner_uvs)
    if shared:
        return f"its UV map's triangles overlap ({shared} of a {OVERLAP_GRID}² grid's texels " \
               f"lie in two or more)"
    return None


OVERLAP_GRID = 128  # texels per side of the grid the overlap test rasterises UVs into
OVERLAP_WORK = 1 << 21  # texel tests at most (182 MiB, 0.19 s measured; then the first triangles)


def shared_texels(corner_uvs: np.ndarray) -> int:
    """How many texel centres of an OVERLAP_GRID² grid lie strictly inside two or more of
    the UV triangles (T*3, 2): overlaps the area sum does not find (mirrored halves, a front
    and back face on one island, whose areas fit in the square together)."""
    tri = corner_uvs.reshape(-1, 3, 2).astype(np.float64) * OVERLAP_GRID - 0.5
    lo = np.ceil(tri.min(axis=1)).astype(np.int64).clip(0, OVERLAP_GRID - 1)
    hi = np.floor(tri.max(axis=1)).astype(np.int64).clip(0, OVERLAP_GRID - 1)
    span = np.maximum(hi - lo + 1, 0)
    count = span[:, 0] * span[:, 1]
    if count.sum() > OVERLAP_WORK:  # the first triangles only: the test stays cheap
        keep = np.cumsum(count) <= OVERLAP_WORK
        tri, lo, span, count = tri[keep], lo[keep], span[keep], count[keep]
    owner = np.repeat(np.arange(len(tri)), count)
    local = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    x = lo[owner, 0] + local % np.maximum(span[owner, 0], 1)
    y = lo[owner, 1] + local // np.maximum(span[owner, 0], 1)
    a, b, c = (tri[owner, i] for i in range(3))

    def edge(p: np.ndarray, q: np.ndarray) -> np.ndarray:
        return (q[:, 0] - p[:, 0]) * (y - p[:, 1]) - (q[:, 1] - p[:, 1]) * (x - p[:, 0])

    e0, e1, e2 = edge(a, b), edge(b, c), edge(c, a)
    eps = 1e-9
    inside = ((e0 > eps) & (e1 > eps) & (e2 > eps)) | ((e0 < -eps) & (e1 < -eps) & (e2 < -eps))
    covered = np.bincount(y[inside] * OVERLAP_GRID + x[inside], minlength=OVERLAP_GRID ** 2)
    return int((covered > 1).sum())


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
