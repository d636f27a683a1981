"""Point clouds as spheres: each point a closed solid of the sphere's area around it, with
outward normals, its material slot, the coarser solid for large clouds, and points that are
not finite left out and counted."""

from __future__ import annotations

import math

import numpy as np
import pytest

from addon.core.scene.points import DETAILED_POINTS, sphere_mesh
from addon.core.scene.vectors import triangle_areas


def _areas(mesh) -> np.ndarray:
    return triangle_areas(mesh.corner_positions())


@pytest.mark.parametrize("count, faces", [(3, 20), (DETAILED_POINTS + 1, 8)])
def test_spheres_of_the_points_area_closed_and_outward(count, faces):
    ordinal = np.arange(count)
    centres = np.stack([ordinal % 256, ordinal // 256, np.zeros(count)], 1) * 0.3
    radii = np.full(count, 0.1)
    mesh, dropped = sphere_mesh("p", centres, radii, np.arange(count) % 2)
    assert dropped == 0 and mesh.triangle_count == faces * count
    areas = _areas(mesh).reshape(count, faces).sum(axis=1)
    assert areas == pytest.approx(np.full(count, 4 * math.pi * 0.01), rel=1e-4)
    corners = mesh.corner_positions().reshape(count, faces, 3, 3).astype(np.float64)
    facing = np.cross(corners[..., 1, :] - corners[..., 0, :],
                      corners[..., 2, :] - corners[..., 0, :])
    outward = corners.mean(axis=2) - centres[:, None]
    assert (np.einsum("pfi,pfi->pf", facing, outward) > 0).all()
    # closed: every edge shared by two faces, in opposite directions
    first = mesh.position_index.reshape(-1, 3)[:faces]
    edges = {(int(face[k]), int(face[(k + 1) % 3])) for face in first for k in range(3)}
    assert all((b, a) in edges for a, b in edges)
    assert mesh.material_slots.reshape(count, faces)[:, 0].tolist() == \
        (np.arange(count) % 2).tolist()


def test_bad_points_are_left_out_and_counted():
    centres = np.array([[0.0, 0.0, 0.0], [np.nan, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0, 0]])
    mesh, dropped = sphere_mesh("p", centres, np.array([0.1, 0.1, np.inf, 0.0]),
                                np.zeros(4, np.int32))
    assert dropped == 2  # the NaN position and the infinite radius; radius 0: no triangles
    assert mesh.triangle_count == 20 and np.isfinite(mesh.positions).all()
