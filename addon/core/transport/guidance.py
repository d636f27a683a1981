"""Camera-driven VPLs (Georgiev & Slusallek 2010, "Simple and robust iterative importance
sampling of virtual point lights"): light paths are traced for several times the VPLs wanted,
each candidate VPL's contribution to a few points the camera sees is estimated (unclamped
geometry term, visibility by ray), and each is kept with probability p = min(1, Φ / τ) (at
least a floor, :func:`least_acceptance`), its intensity divided by p. τ is chosen so that about
as many VPLs are kept as the candidates' share would give: the same VPL count, spent where the
camera looks. The draw runs along a space-filling curve through the candidates' positions, so
the kept ones are spread over the scene like the candidates.
The estimator stays unbiased: every VPL keeps p > 0 and its expected weight is one."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene.geometry import WorldGeometry
from ..scene.model import Camera
from ..scene.vectors import unit
from .ray_caster import RayCaster
from .vpl import LUMINANCE, VPLs

MIN_ACCEPTANCE = 0.05
"""The least chance a candidate is kept, where few candidates light no sampled camera point:
VPLs that light none may still light the image between the points."""
UNLIT_SHARE = 0.2
"""Where many candidates light no camera point, their least chance is lowered so that they
take about this share of the VPLs kept (what MIN_ACCEPTANCE gave Sponza's 4 candidate paths
per kept path), and the rest go to the candidates that light the view."""
USEFUL_SHARE = 0.25
"""Guidance is used only when fewer than this share of a probe's candidates light the view: the
plain light paths are stratified, and selecting among them adds variance that only a large
gain repays (measured on a wall bleeding onto a floor, 56 % useful: guided 1-4 % noise across
seeds against 0.2-0.9 % plain; on the interior sample scene 7 % are useful)."""
CONTRIBUTION_ROWS = 256
"""VPLs whose pairs with the camera points :func:`contributions` forms at a time."""
HIDDEN_LAYERS = 8
"""Objects the camera does not see that a camera ray passes before it finds what it sees."""


@dataclass
class CameraPoints:
    """Surface points the camera sees, each with its normal (towards the camera) and albedo."""

    position: np.ndarray  # (s, 3)
    normal: np.ndarray  # (s, 3)
    albedo: np.ndarray  # (s, 3)

    def __len__(self) -> int:
        return len(self.position)


@dataclass
class Guidance:
    """The kept VPLs, and the shares of candidates and of kept VPLs that light camera points."""

    vpls: VPLs
    candidates: int
    candidate_share: float
    kept_share: float


def _first_seen(origin: np.ndarray, direction: np.ndarray, geometry: WorldGeometry,
                tracer: RayCaster) -> tuple[np.ndarray, np.ndarray]:
    """Distance and triangle (-1: none) of the first surface each camera ray sees: rays go
    on through objects the camera does not see (up to HIDDEN_LAYERS of them) and see nothing
    where they meet a holdout (its light is not in the image)."""
    hits = tracer.intersect(origin, direction, 0.0, np.inf)
    distance, triangle = hits.distance.copy(), hits.triangle.copy()
    hidden = geometry.camera_hidden
    for _ in range(HIDDEN_LAYERS):
        again = np.flatnonzero(triangle >= 0)
        again = again[hidden[triangle[again]]]
        if len(again) == 0:
            break
        beyond = tracer.intersect(origin[again], direction[again], distance[again], np.inf)
        distance[again], triangle[again] = beyond.distance, beyond.triangle
    seen = np.flatnonzero(triangle >= 0)
    triangle[seen[hidden[triangle[seen]] | geometry.holdout[triangle[seen]]]] = -1
    return distance, triangle


def camera_points(camera: Camera, geometry: WorldGeometry, tracer: RayCaster, count: int,
                  seed: int) -> CameraPoints:
    """The first surfaces hit by ``count`` camera rays through jittered cells of a grid over
    the image."""
    side = max(1, int(np.ceil(np.sqrt(count))))
    rng = np.random.default_rng(seed)
    cells = (np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2)
             + rng.random((side * side, 2))) / side
    origin, direction = camera.rays(cells * 2.0 - 1.0)
    distance, triangle = _first_seen(origin, direction, geometry, tracer)
    hit = np.flatnonzero(triangle >= 0)
    triangle = triangle[hit]
    position = origin[hit] + direction[hit] * distance[hit, None].astype(np.float64)
    t = geometry.positions.reshape(-1, 3, 3)[triangle].astype(np.float64)
    normal = unit(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]))
    normal *= np.where((normal * direction[hit]).sum(axis=1) > 0, -1.0, 1.0)[:, None]
    return CameraPoints(position, normal, geometry.albedo_at(triangle, position))


def contributions(vpls: VPLs, points: CameraPoints, tracer: RayCaster, epsilon: float
                  ) -> np.ndarray:
    """Each VPL's estimated radiance (luminance) summed over the camera points: intensity ×
    both cosines / distance² × albedo / π, where a ray finds the pair mutually visible. The
    (VPL, point) pairs are formed CONTRIBUTION_ROWS VPLs at a time and only pairs that face
    each other are measured further: most candidates of an interior face away from every
    point, and whole (VPL, point) matrices cost their allocation more than their arithmetic
    (the interior's 6000 × 448: 0.27 s against 0.04 s)."""
    if len(vpls) == 0 or len(points) == 0:
        return np.zeros(len(vpls))
    centre = points.position.mean(axis=0)  # centred: the products lose little to cancellation
    x, p = vpls.position - centre, points.position - centre
    x_squared, p_squared = (x * x).sum(axis=1), (p * p).sum(axis=1)
    x_along_normal = (x * vpls.normal).sum(axis=1)
    p_along_normal = (p * points.normal).sum(axis=1)
    vpl_weight = vpls.intensity @ LUMINANCE
    point_weight = (points.albedo @ LUMINANCE) / np.pi
    found = []  # (vpl, point, value, distance) of the pairs that face each other
    for start in range(0, len(x), CONTRIBUTION_ROWS):
        rows = slice(start, start + CONTRIBUTION_ROWS)
        cosines = vpls.normal[rows] @ p.T - x_along_normal[rows, None]  # offset · n_vpl
        along_point = x[rows] @ points.normal.T - p_along_normal[None]  # -offset · n
        np.maximum(cosines, 0.0, out=cosines)
        cosines *= np.maximum(along_point, 0.0)
        vpl, point = np.nonzero(cosines > 0)
        squared = x_squared[rows][vpl] + p_squared[point] \
            - 2.0 * (x[rows][vpl] * p[point]).sum(axis=1)
        distance = np.maximum(np.sqrt(np.maximum(squared, 0.0)), epsilon)
        value = cosines[vpl, point] / distance**4 * vpl_weight[rows][vpl] * point_weight[point]
        lit = value > 0
        found.append((vpl[lit] + start, point[lit], value[lit], distance[lit]))
    vpl, point, value, distance = (np.concatenate(column) for column in zip(*found, strict=True))
    if len(vpl):
        towards = (p[point] - x[vpl]) / distance[:, None]
        origin = vpls.position[vpl] + vpls.normal[vpl] * epsilon
        hits = tracer.intersect(origin, towards, 0.0, distance * (1 - 1e-4) - epsilon,
                                diffuse=True)
        value[hits.triangle >= 0] = 0.0
    return np.bincount(vpl, weights=value, minlength=len(vpls))


def refined_contributions(vpls: VPLs, points: CameraPoints, more_points: CameraPoints,
                          tracer: RayCaster, epsilon: float) -> np.ndarray:
    """``contributions`` at ``points``; those that light none of them estimated again at
    ``more_points`` (scaled to as many points as ``points``). A VPL that lights the view
    between the few points would otherwise be kept at the least chance and weighted by its
    inverse (twentyfold or more): on Sponza two such VPLs made the brightest blotch of a
    seed."""
    value = contributions(vpls, points, tracer, epsilon)
    unlit = np.flatnonzero(value == 0)
    if len(unlit) and len(more_points):
        again = contributions(vpls.scaled(unlit, 1.0), more_points, tracer, epsilon)
        value[unlit] = again * (len(points) / len(more_points))
    return value


def least_acceptance(contribution: np.ndarray, kept: float) -> float:
    """The least chance of a candidate: MIN_ACCEPTANCE, or lower where the candidates that
    light no camera point would otherwise take more than UNLIT_SHARE of the ``kept``, or more
    than the ones that light a point leave."""
    unlit = int(np.count_nonzero(contribution <= 0))
    if unlit == 0:
        return MIN_ACCEPTANCE
    share = max(UNLIT_SHARE * kept, kept - (len(contribution) - unlit))
    return min(MIN_ACCEPTANCE, share / unlit)


def acceptance(contribution: np.ndarray, kept: float) -> np.ndarray:
    """Chances min(1, Φ / τ), at least :func:`least_acceptance`, with τ set so that they add
    up to about ``kept`` (all ones when there are no more candidates than that; all kept /
    n where none lights a camera point, as without guidance: keeping every candidate made
    a view that sees almost nothing, a 170° lens, take 16 times the VPLs)."""
    n = len(contribution)
    if n <= kept:
        return np.ones(n)
    if not np.any(contribution > 0):
        return np.full(n, kept / n)
    least = least_acceptance(contribution, kept)
    low, high = 1e-30, float(contribution.max()) * n
    for _ in range(100):  # bisection on log τ: the expected count falls as τ grows
        tau = np.sqrt(low * high)
        expected = np.clip(contribution / tau, least, 1.0).sum()
        low, high = (tau, high) if expected > kept else (low, tau)
        if high / low < 1 + 1e-6:
            break
    return np.clip(contribution / np.sqrt(low * high), least, 1.0)


def systematic(chance: np.ndarray, offset: float) -> np.ndarray:
    """Which candidates are kept: candidate i when a point of the grid offset + k falls in its
    stretch of the running sum of chances, so each is kept with its own chance exactly, and
    the number kept varies by less than one from the sum (far less variance than independent
    draws)."""
    edges = np.concatenate([[0.0], np.cumsum(chance)]) + offset
    return np.floor(edges[1:]) > np.floor(edges[:-1])


def morton_order(position: np.ndarray, bits: int = 10) -> np.ndarray:
    """Indices that put ``position`` ((n, 3)) in Z order (Morton codes of ``bits`` bits per
    axis over their bounding box): near points come near each other. Systematic selection
    along the light paths' own order kept strided subsets of the Halton sequence instead, whose
    base-2 digits repeat with the stride (tests/core/test_guidance.py's wall bleeding onto a
    floor, seeds 0-5: guided 4.9-12.1 % error along the paths' order, unguided 5.8-12.0 %,
    guided along this order 1.6-3.5 %)."""
    if len(position) == 0:
        return np.zeros(0, int)
    low, high = position.min(axis=0), position.max(axis=0)
    scale = ((1 << bits) - 1) / np.maximum(high - low, 1e-30)
    cell = np.clip(((position - low) * scale).astype(np.int64), 0, (1 << bits) - 1)
    code = np.zeros(len(position), np.int64)
    for bit in range(bits):
        for axis in range(3):
            code |= ((cell[:, axis] >> bit) & 1) << (3 * bit + axis)
    return np.argsort(code, kind="stable")


def guide(candidates: VPLs, contribution: np.ndarray, wanted: float, seed: int) -> Guidance:
    """Keep about ``wanted`` of the candidate VPLs by their contribution to the camera points,
    reweighted so that the estimate stays unbiased."""
    chance = acceptance(contribution, wanted)
    order = morton_order(candidates.position)
    keep = np.zeros(len(chance), bool)
    keep[order] = systematic(chance[order], np.random.default_rng(seed).random())
    chosen = candidates.scaled(keep, 1.0 / chance[keep])
    lights = contribution > 0
    return Guidance(chosen, len(candidates), float(lights.mean()) if len(lights) else 0.0,
                    float(lights[keep].mean()) if keep.any() else 0.0)


def candidate_paths(vpl_count: int, oversampling: float) -> int:
    """Light paths to trace for candidates (at most 2¹⁶, the setting's own limit)."""
    return int(min(vpl_count * oversampling, 1 << 16))
