"""The 2D domains light paths start from (directions of point and spot lights, the unit disc
of area lights, the sun's disc across the scene), and the Voronoi geometry on them that
Incremental Instant Radiosity uses to keep anchors evenly spread (see ``incremental.py``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, Delaunay, QhullError, cKDTree

from ..scene.model import Light, LightKind
from ..scene.vectors import unit
from .lights import area_light_points, light_problem, spot_mask, spot_parameters

QUADRATURE_PER_ANCHOR = 32
"""Quadrature points per anchor for the Voronoi cell integrals (measured on 1000 even anchors
of a sun's disc: cell measures spread 8.1 % against 7.1 % at 128, in a quarter of the time)."""
MAX_QUADRATURE = 1 << 18
CANDIDATES_PER_ANCHOR = 8  # uniform candidate points per anchor for the best spot
GOLDEN_ANGLE = np.pi * (3.0 - np.sqrt(5.0))


@dataclass
class LightDomain:
    """The 2D domain a light's paths start from, in the light's current pose.

    ``kind`` is "sphere" (unit 3-vectors: directions in the light's frame, restricted to a cap
    of half-angle acos(cos_half) around -Z for spots), "disc" (2-vectors in the unit disc: the
    Nusselt projection of directions around -Z; area lights) or "parallel" (2-vectors in the
    unit disc: ray origins across the scene's bounding sphere; suns). ``density`` is the RGB
    flux per unit of the domain's measure (W/sr for spheres, W per unit disc area otherwise)."""

    kind: str
    light: Light
    origin: np.ndarray  # (3,) light position (sphere, disc) or scene centre (parallel)
    frame: np.ndarray  # (3, 3) orthonormal columns: the light's x, y, z axes
    flux: np.ndarray  # (3,) RGB scale of ``density``
    cos_half: float = -1.0
    smooth: float = 0.0
    radius: float = 1.0  # parallel: the disc radius (the scene's bounding radius)

    @property
    def dimensions(self) -> int:
        return 3 if self.kind == "sphere" else 2

    @property
    def measure(self) -> float:
        if self.kind == "sphere":
            return 2 * np.pi * (1 - self.cos_half)
        return np.pi

    def contains(self, coords: np.ndarray) -> np.ndarray:
        if self.kind == "sphere":
            return -coords[:, 2] >= self.cos_half
        return (coords**2).sum(axis=1) <= 1.0 + 1e-9

    def density(self, coords: np.ndarray) -> np.ndarray:
        """(n, 3) flux per unit measure at domain points."""
        weight = np.ones(len(coords))
        if self.kind == "sphere" and self.cos_half > -1:
            weight = spot_mask(-coords[:, 2], self.cos_half, self.smooth) \
                if self.smooth > 0 else weight
        profile = self.light.profile
        if profile is not None and self.kind == "sphere":
            weight = weight * profile.towards(coords)
        elif profile is not None and self.kind == "disc":
            z = -np.sqrt(np.maximum(0.0, 1 - (coords**2).sum(axis=1)))
            weight = weight * profile.towards(np.hstack([coords, z[:, None]]))
        return weight[:, None] * self.flux[None]

    def uniform_points(self, count: int, rotation: float = 0.0) -> np.ndarray:
        """``count`` deterministic, evenly spread points of the domain (Fibonacci lattices:
        area-uniform on the cap and on the disc), turned by ``rotation`` radians."""
        i = np.arange(count) + 0.5
        phi = GOLDEN_ANGLE * i + rotation
        if self.kind == "sphere":
            cos_t = 1 - (1 - self.cos_half) * i / count  # angle from -Z
            sin_t = np.sqrt(np.maximum(0.0, 1 - cos_t**2))
            return np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), -cos_t], axis=1)
        r = np.sqrt(i / count)
        return np.stack([r * np.cos(phi), r * np.sin(phi)], axis=1)

    def shape_points(self, offsets: np.ndarray) -> np.ndarray:
        """World start points of paths with the given [0,1)² offsets on the light's shape."""
        n = len(offsets)
        if self.kind != "disc":
            return np.repeat(self.origin[None], n, 0)
        return area_light_points(self.light, offsets)

    def rays(self, coords: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World origins and unit directions of paths leaving domain points."""
        n = len(coords)
        if self.kind == "sphere":
            return self.shape_points(offsets), unit(coords @ self.frame.T)
        if self.kind == "disc":
            z = -np.sqrt(np.maximum(0.0, 1 - (coords**2).sum(axis=1)))
            local = np.hstack([coords, z[:, None]])
            return self.shape_points(offsets), unit(local @ self.frame.T)
        travel = -self.frame[:, 2]
        origin = self.origin - 1.01 * self.radius * travel + self.radius * (
            coords[:, :1] * self.frame[:, 0] + coords[:, 1:] * self.frame[:, 1])
        return origin, np.repeat(travel[None], n, 0)

    def project(self, points: np.ndarray, offsets: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Domain points of world points (the reprojection), the world origin of each path
        towards them, and whether the point lies in front of the light (inside the domain)."""
        if self.kind == "parallel":
            d = points - self.origin
            coords = np.stack([d @ self.frame[:, 0], d @ self.frame[:, 1]], axis=1) / self.radius
            origin, _ = self.rays(coords, offsets)
            return coords, origin, self.contains(coords)
        origin = self.shape_points(offsets)
        local = unit(points - origin) @ self.frame
        if self.kind == "sphere":
            return local, origin, self.contains(local)
        return local[:, :2], origin, local[:, 2] < 0


def light_domain(light: Light, centre: np.ndarray, radius: float) -> LightDomain | None:
    """The domain of a light with power, or None (no power, or left out: ``light_problem``)."""
    if light.power == 0 or light_problem(light) is not None:
        return None
    frame = light.frame
    color = np.asarray(light.color, np.float64) * light.power
    position = light.matrix[:3, 3].astype(np.float64)
    if light.kind in (LightKind.POINT, LightKind.SPOT):
        cos_half, smooth = spot_parameters(light)
        return LightDomain("sphere", light, position, frame, color / (4 * np.pi),
                           cos_half=max(-1.0, cos_half), smooth=smooth)
    if light.kind is LightKind.AREA:
        return LightDomain("disc", light, position, frame, color / np.pi)
    return LightDomain("parallel", light, np.asarray(centre, np.float64), frame,
                       color * radius**2, radius=radius)


def shortest_edge(coords: np.ndarray) -> tuple[int, int] | None:
    """The ends of the shortest Delaunay edge of points on the disc (2D) or the sphere (3D),
    or None for fewer than 2 points. The closest pair of a point set is always an edge of its
    Delaunay triangulation (on the sphere: of the convex hull of the unit vectors), so a k-d
    tree finds it without triangulating, including for sets Qhull refuses (coincident or
    collinear points, fewer than 3 or 4)."""
    if len(coords) < 2:
        return None
    distance, index = cKDTree(coords).query(coords, k=2)
    a = int(np.argmin(distance[:, 1]))
    b = int(index[a, 1]) if index[a, 1] != a else int(index[a, 0])
    return a, b


def voronoi_vertices(coords: np.ndarray) -> np.ndarray:
    """Circumcentres of the Delaunay triangles (disc) or hull facets (sphere): the vertices of
    the Voronoi diagram, where the largest empty circles are centred (empty when degenerate)."""
    dims = coords.shape[1]
    try:
        if dims == 3:
            hull = ConvexHull(coords)
            return unit(hull.equations[:, :3])
        tri = Delaunay(coords)
    except (QhullError, ValueError):
        return np.zeros((0, dims))
    a, b, c = (coords[tri.simplices[:, k]] for k in range(3))
    ab, ac = b - a, c - a
    d = 2 * (ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0])
    ok = np.abs(d) > 1e-12
    ab2, ac2 = (ab**2).sum(axis=1), (ac**2).sum(axis=1)
    ux = (ac[:, 1] * ab2 - ab[:, 1] * ac2)[ok] / d[ok]
    uy = (ab[:, 0] * ac2 - ac[:, 0] * ab2)[ok] / d[ok]
    return a[ok] + np.stack([ux, uy], axis=1)


def cell_integrals(domain: LightDomain, coords: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The measure of each point's Voronoi cell within the domain and the light's flux through
    it (n, 3), by a deterministic uniform quadrature of the domain (exact in the sums: the
    measures add up to the domain's measure)."""
    n = len(coords)
    if n == 0:
        return np.zeros(0), np.zeros((0, 3))
    count = int(min(MAX_QUADRATURE, max(4096, QUADRATURE_PER_ANCHOR * n)))
    quadrature = domain.uniform_points(count)
    _, owner = cKDTree(coords).query(quadrature, workers=-1)
    weight = domain.measure / count
    measure = np.bincount(owner, minlength=n) * weight
    density = domain.density(quadrature)
    flux = np.stack([np.bincount(owner, density[:, c], minlength=n) for c in range(3)],
                    axis=1) * weight
    return measure, flux


def farthest_points(domain: LightDomain, coords: np.ndarray, count: int,
                    rotation: float) -> tuple[np.ndarray, np.ndarray]:
    """``count`` new domain points, each in turn the candidate farthest from every point so far
    (greedy largest empty circle over the Voronoi vertices and a uniform candidate set), and
    each one's distance from the points before it (its empty circle's radius)."""
    candidates = domain.uniform_points(
        max(256, CANDIDATES_PER_ANCHOR * (len(coords) + count)), rotation)
    vertices = voronoi_vertices(coords) if len(coords) >= domain.dimensions + 1 else None
    if vertices is not None and len(vertices):
        candidates = np.concatenate([vertices[domain.contains(vertices)], candidates])
    nearest = (cKDTree(coords).query(candidates, workers=-1)[0] if len(coords)
               else np.full(len(candidates), np.inf))
    chosen, gaps = [], []
    for _ in range(count):
        best = int(np.argmax(nearest))
        chosen.append(candidates[best])
        gaps.append(nearest[best])
        nearest = np.minimum(nearest, np.linalg.norm(candidates - candidates[best], axis=1))
    return np.array(chosen).reshape(-1, domain.dimensions), np.array(gaps)
