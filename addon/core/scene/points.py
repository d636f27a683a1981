"""Point clouds as triangles: Cycles renders each point as a sphere of its radius; VPL GI as
an icosahedron (an octahedron where a cloud has over ``DETAILED_POINTS`` points) with the
sphere's normals at its corners, whose area is the sphere's: by Cauchy's formula the same
mean silhouette, so a cloud blocks and reflects as much light as Cycles' spheres."""

from __future__ import annotations

import math

import numpy as np

from .model import Mesh
from .vectors import triangle_areas

DETAILED_POINTS = 65536


def _icosahedron() -> tuple[np.ndarray, np.ndarray]:
    golden = (1.0 + math.sqrt(5.0)) / 2.0
    corners = np.array([(x, y, 0.0) for x in (-1, 1) for y in (-golden, golden)]
                       + [(0.0, x, y) for x in (-1, 1) for y in (-golden, golden)]
                       + [(y, 0.0, x) for x in (-1, 1) for y in (-golden, golden)])
    corners /= np.linalg.norm(corners, axis=1, keepdims=True)
    edge = np.min([np.linalg.norm(corners[0] - c) for c in corners[1:]])
    faces = [(a, b, c) for a in range(12) for b in range(a + 1, 12) for c in range(b + 1, 12)
             if all(abs(np.linalg.norm(corners[i] - corners[j]) - edge) < 1e-9
                    for i, j in ((a, b), (b, c), (a, c)))]
    return corners, _outward(corners, np.array(faces))


def _octahedron() -> tuple[np.ndarray, np.ndarray]:
    corners = np.concatenate([np.eye(3), -np.eye(3)])
    faces = np.array([(a, b, c) for a in (0, 3) for b in (1, 4) for c in (2, 5)])
    return corners, _outward(corners, faces)


def _outward(corners: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Faces wound counter-clockwise seen from outside."""
    a, b, c = (corners[faces[:, i]] for i in range(3))
    flip = np.einsum("ij,ij->i", np.cross(b - a, c - a), a + b + c) < 0
    faces[flip] = faces[flip][:, [0, 2, 1]]
    return faces


SOLIDS = {"detailed": _icosahedron(), "coarse": _octahedron()}


def sphere_mesh(name: str, centres: np.ndarray, radii: np.ndarray, slots: np.ndarray
                ) -> tuple[Mesh, int]:
    """The spheres of points at ``centres`` (P, 3) of ``radii`` (P,) and material ``slots``
    (P,); and how many points were left out for a position or radius that is not finite
    (points of radius 0 make no triangles)."""
    centres = np.asarray(centres, np.float64).reshape(-1, 3)
    radii = np.maximum(np.asarray(radii, np.float64).reshape(-1), 0.0)
    finite = np.isfinite(centres).all(axis=1) & np.isfinite(radii)
    keep = finite & (radii > 0)
    corners, faces = SOLIDS["detailed" if keep.sum() <= DETAILED_POINTS else "coarse"]
    area = triangle_areas(corners[faces]).sum()
    scale = math.sqrt(4.0 * math.pi / area)  # the solid's area made the sphere's
    centres, radii = centres[keep], radii[keep]
    positions = centres[:, None] + (scale * radii)[:, None, None] * corners[None]
    index = (np.arange(len(centres))[:, None, None] * len(corners) + faces[None]).ravel()
    normals = np.broadcast_to(corners, positions.shape).reshape(-1, 3)
    mesh = Mesh(name, positions.reshape(-1, 3).astype(np.float32), normals.astype(np.float32),
                np.repeat(np.asarray(slots, np.int32)[keep], len(faces)),
                None, index.astype(np.int32), index.astype(np.int32))
    return mesh, int((~finite).sum())
