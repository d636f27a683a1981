"""Incremental Instant Radiosity (Laine et al. 2007; the seed's "Incremental Instant Radiosity"
and "How To Reuse VPLs"): VPLs that survive from frame to frame while lights move.

Each light keeps *anchors*: points of its 2D emission domain (``LightDomain``) with the surface
point their path first hit. Every frame, per light:

1. Invalid anchors are deleted: their hit is now behind the light (outside a spot's cone, behind
   an area light or the surface faces away) or hidden from it (a ray from the light is blocked).
   Anchors whose path missed the scene keep their domain point and are traced again.
2. The survivors are reprojected into the domain from the light's new pose.
3. Missing anchors are created at once (so illumination never lags behind the light), greedily
   at the point farthest from all others: the largest empty circle, whose centre is a vertex of
   the Voronoi diagram (a circumcentre of the Delaunay triangulation; on the sphere, of the
   convex hull of the unit vectors), or a point of a dense uniform candidate set (which covers
   the domain's border). Then up to ``incremental_budget`` anchors move: the worst ones (an
   end of the shortest Delaunay edge) to the best spots, while that widens the closest spacing
   (all moves chosen and traced in one batch).
4. Each anchor's path carries the light's flux through its Voronoi cell (the integral of the
   light's flux density over the cell, by a deterministic uniform quadrature of the domain), so
   an uneven set still integrates the light exactly.

Domains: point and spot lights use unit directions in the light's frame (the whole sphere, or
the spot's cone cap); area lights the unit disc of the Nusselt analog (uniform on the disc =
cosine-distributed directions), each anchor with its own fixed point on the light's shape;
suns a disc across the scene's bounding sphere, perpendicular to the light (parallel rays; the
sun's angular size is ignored for the VPLs). World and emissive surfaces do not move with
lights: their paths are the same seeded paths every frame (traced again only when geometry
changes).

Continuing bounces are traced from each anchor's hit with the direction samples of the path's
rank (a fixed random permutation of its slot), so a surviving anchor keeps its whole path and
each VPL keeps its identity (``VPLs.key``) while its geometry holds still: shadow maps are
needed only for VPLs with new keys.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from ..scene.geometry import WorldGeometry
from ..scene.model import NO_BOUNCE_LIMIT, Scene
from ..scene.vectors import unit
from ..settings import Settings
from .light_domains import (
    LightDomain,
    cell_integrals,
    farthest_points,
    light_domain,
    shortest_edge,
)
from .lights import soft_falloff_radius
from .ray_caster import RayCaster
from .sequences import scrambled_halton
from .vpl import (
    START_DIMENSIONS,
    SurfaceHits,
    VPLs,
    environment_emitters,
    light_emitter,
    light_hits,
    lit_hits,
    propagate,
    start_paths,
    trace_hits,
)

FAR_SIDE = 128  # added to the key of a VPL on the far side of a translucent surface
GENERATION_STRIDE = 2 * FAR_SIDE  # VPL key = path id * stride + generation (bounces <= 64)


@dataclass
class _Anchors:
    """One light's anchors: domain points, shape offsets and the surface their path hit."""

    coords: np.ndarray
    offsets: np.ndarray
    hit: np.ndarray  # (n,) bool
    position: np.ndarray
    normal: np.ndarray
    albedo: np.ndarray
    triangle: np.ndarray  # (n,) int, the triangle hit (-1 for a miss)
    slot: np.ndarray  # (n,) int, global path slot
    path_id: np.ndarray  # (n,) int, unique id of the path (new id = new VPLs)
    transmittance: np.ndarray  # (n, 3) light the clear surfaces on the path let through

    @classmethod
    def empty(cls, dimensions: int) -> _Anchors:
        return cls(np.zeros((0, dimensions)), np.zeros((0, 2)), np.zeros(0, bool),
                   np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, int),
                   np.zeros(0, int), np.zeros(0, int), np.zeros((0, 3)))

    def __len__(self) -> int:
        return len(self.slot)

    def keep(self, mask: np.ndarray) -> _Anchors:
        return _Anchors(*(getattr(self, f)[mask] for f in self.__dataclass_fields__))

    def append(self, other: _Anchors) -> _Anchors:
        return _Anchors(*(np.concatenate([getattr(self, f), getattr(other, f)])
                          for f in self.__dataclass_fields__))


@dataclass
class IncrementalStats:
    """What one update did: anchors kept, deleted as invalid, moved by the budget, created."""

    kept: int = 0
    invalid: int = 0
    redistributed: int = 0
    created: int = 0
    reset: str = ""  # why everything was regenerated, '' when nothing was
    new_vpls: int = 0
    reused_vpls: int = 0


@dataclass
class _LightState:
    anchors: _Anchors
    target: int = 0


@dataclass
class IncrementalVPLs:
    """VPLs reused between frames (create one per render session; ``update`` per frame)."""

    lights: dict[str, _LightState] = field(default_factory=dict)
    stats: IncrementalStats = field(default_factory=IncrementalStats)
    _key: tuple | None = None
    _shape_version: int | None = None  # the caller's version of last frame's positions
    _next_id: int = 0
    _frame: int = 0
    _previous_keys: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    _environment_slots: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    _environment_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    def update(self, scene: Scene, geometry: WorldGeometry, settings: Settings,
               tracer: RayCaster, centre: np.ndarray, radius: float,
               shape_version: int, key: tuple) -> VPLs:
        """This frame's VPLs, reusing last frame's where they are still valid.
        ``shape_version`` is the caller's version of the triangle positions: a new value means
        surfaces moved, and every path is traced again; a new ``key`` (the settings the paths
        depend on) starts afresh."""
        self.stats = IncrementalStats()
        self._frame += 1
        same_geometry = shape_version == self._shape_version
        if key != self._key:
            self.lights.clear()
            self.stats.reset = "settings changed" if self._key else "first frame"
        elif not same_geometry:
            self.stats.reset = "geometry changed"
        self._key = key
        self._shape_version = shape_version
        n = settings.vpl_count
        domains = {light.name: d for light in scene.surface_lights if light.max_bounces > 0
                   and (d := light_domain(light, centre, radius)) is not None}
        environment = environment_emitters(scene, geometry, centre, radius)
        targets = _allocate(n, [light_emitter(d.light, centre, radius).power
                                for d in domains.values()]
                            + [sum(e.power for e in environment)])
        for name in list(self.lights):
            if name not in domains:
                del self.lights[name]
        epsilon = 1e-5 * radius
        for (name, domain), target in zip(domains.items(), targets, strict=False):
            state = self.lights.setdefault(name, _LightState(_Anchors.empty(domain.dimensions)))
            if state.anchors.coords.shape[1] != domain.dimensions:
                state.anchors = _Anchors.empty(domain.dimensions)
            state.target = target
            state.anchors = self._validate(state.anchors, domain, tracer, geometry, epsilon,
                                           retrace_all=not same_geometry)
            while len(state.anchors) > target:
                state.anchors = self._delete_worst(state.anchors)
        free = np.setdiff1d(np.arange(n), np.concatenate(
            [s.anchors.slot for s in self.lights.values()] + [np.zeros(0, int)]))
        hits: list[tuple[SurfaceHits, np.ndarray]] = []
        limit = np.full(n, NO_BOUNCE_LIMIT)  # per rank: its emitter's Max Bounces
        permutation = np.random.default_rng(settings.seed).permutation(n)
        for name, domain in domains.items():
            state = self.lights[name]
            missing = state.target - len(state.anchors)
            slots, free = free[:missing], free[missing:]
            state.anchors = self._create(state.anchors, domain, slots, tracer, geometry,
                                         epsilon, settings.seed)
            state.anchors = self._redistribute(state.anchors, domain, tracer, geometry, epsilon,
                                               settings)
            hits.append(self._anchor_hits(state.anchors, domain, permutation, geometry))
            limit[hits[-1][0].rank] = domain.light.max_bounces
        if environment and len(free):
            found, ids, bounces = self._environment_hits(environment, free, n, permutation,
                                                         tracer, geometry, epsilon,
                                                         settings.seed)
            hits.append((found, ids))
            limit[found.rank] = bounces
        self.stats.kept = sum(len(s.anchors) for s in self.lights.values()) \
            - self.stats.created - self.stats.redistributed
        if not hits or settings.bounces == 0 or geometry.vertex_count == 0:
            return VPLs.empty()
        first = SurfaceHits(*(np.concatenate([getattr(h, f) for h, _ in hits])
                              for f in SurfaceHits.__dataclass_fields__
                              if f not in ("incoming", "base")))
        directions = scrambled_halton(n, 2 * max(0, settings.bounces - 1), settings.seed)
        vpls = propagate(first, n, directions, settings, tracer, geometry,
                         radius).within_bounce_limits(limit)
        path_of_rank = np.zeros(n, np.int64)
        path_of_rank[first.rank] = np.concatenate([ids for _, ids in hits])
        vpls.key = path_of_rank[vpls.rank] * GENERATION_STRIDE + vpls.generation
        if vpls.far_side is not None:
            vpls.key += FAR_SIDE * vpls.far_side
        reused = np.isin(vpls.key, self._previous_keys)
        self.stats.reused_vpls, self.stats.new_vpls = int(reused.sum()), int((~reused).sum())
        self._previous_keys = vpls.key.copy()
        return vpls

    # -- steps ------------------------------------------------------------------------------
    def _ids(self, count: int) -> np.ndarray:
        ids = np.arange(self._next_id, self._next_id + count)
        self._next_id += count
        return ids

    def _validate(self, anchors: _Anchors, domain: LightDomain, tracer: RayCaster,
                  geometry: WorldGeometry, epsilon: float, retrace_all: bool) -> _Anchors:
        """Drop anchors whose hit the light no longer reaches; trace missed (and, after a
        geometry change, all) paths again from their domain points."""
        if len(anchors) == 0:
            return anchors
        if not retrace_all:  # materials may have changed: read the albedo again
            anchors.albedo[anchors.hit] = geometry.albedo_at(anchors.triangle[anchors.hit],
                                                             anchors.position[anchors.hit])
        coords, origin, in_front = domain.project(anchors.position, anchors.offsets)
        towards = anchors.position - origin
        distance = np.linalg.norm(towards, axis=1)
        faces = (towards * anchors.normal).sum(axis=1) < 0
        check = anchors.hit & in_front & faces & (not retrace_all)
        visible = np.zeros(len(anchors), bool)
        if check.any():
            rows = np.flatnonzero(check)
            ray, reach, _, _ = light_hits(tracer, geometry, origin[rows], unit(towards[rows]),
                                          epsilon, domain.light.blockers, every_surface=False)
            visible[rows[ray]] = reach >= distance[rows[ray]] * (1 - 1e-4) - 2 * epsilon
        valid = check & visible
        retrace = ~anchors.hit | retrace_all
        self.stats.invalid += int((anchors.hit & ~valid & ~retrace).sum())
        anchors.coords = np.where(valid[:, None], coords, anchors.coords)
        kept = anchors.keep(valid | retrace)
        again = ~kept.hit | retrace_all
        if again.any():
            kept = kept.keep(~again).append(self._trace(domain, kept.coords[again],
                                                        kept.offsets[again], kept.slot[again],
                                                        tracer, geometry, epsilon))
        return kept

    def _trace(self, domain: LightDomain, coords: np.ndarray, offsets: np.ndarray,
               slots: np.ndarray, tracer: RayCaster, geometry: WorldGeometry,
               epsilon: float) -> _Anchors:
        """New anchors: paths from domain points traced to their first hit (misses kept)."""
        n = len(coords)
        origin, direction = domain.rays(coords, offsets)
        # unit flux: what the hits get is their path's transmittance
        found = trace_hits(tracer, geometry, origin, direction, np.ones((n, 3)),
                           np.arange(n), epsilon, from_light=True,
                           soft_radius=soft_falloff_radius(domain.light),
                           blockers=domain.light.blockers, every_surface=False)
        hit = np.zeros(n, bool)
        hit[found.rank] = True
        position, normal, albedo = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
        position[found.rank], normal[found.rank] = found.position, found.normal
        albedo[found.rank] = found.albedo
        triangle = np.full(n, -1)
        triangle[found.rank] = found.triangle
        transmittance = np.zeros((n, 3))
        transmittance[found.rank] = found.flux
        return _Anchors(coords, offsets, hit, position, normal, albedo, triangle, slots,
                        self._ids(n), transmittance)

    def _create(self, anchors: _Anchors, domain: LightDomain, slots: np.ndarray,
                tracer: RayCaster, geometry: WorldGeometry, epsilon: float,
                seed: int) -> _Anchors:
        if len(slots) == 0:
            return anchors
        coords, _ = farthest_points(domain, anchors.coords, len(slots), self._frame * 0.61803)
        rng = np.random.default_rng((seed, self._frame, len(anchors)))
        offsets = rng.uniform(size=(len(slots), 2))
        self.stats.created += len(slots)
        return anchors.append(self._trace(domain, coords, offsets, slots, tracer, geometry,
                                          epsilon))

    def _delete_worst(self, anchors: _Anchors) -> _Anchors:
        """The anchors without the worst one (see _worst)."""
        return anchors.keep(np.arange(len(anchors)) != _worst(anchors.coords)[0])

    def _redistribute(self, anchors: _Anchors, domain: LightDomain, tracer: RayCaster,
                      geometry: WorldGeometry, epsilon: float, settings: Settings) -> _Anchors:
        """Up to ``incremental_budget`` anchors move from the most crowded places to the
        emptiest: the worst anchors are taken out one after another, as many best spots are
        chosen greedily among the rest (one triangulation, where a move at a time took one
        each: 8 moves cost 0.13 s on the interior's sun), and the i-th move is made while its
        spot is farther from its neighbours than the i-th shortest edge was long (the
        anchors of the moves not made are put back). The moved paths are traced together."""
        edges: list[float] = []
        taken: list[_Anchors] = []
        remaining = anchors
        for _ in range(settings.incremental_budget):
            if len(remaining) < domain.dimensions + 2:
                break
            worst, edge = _worst(remaining.coords)
            edges.append(edge)
            mask = np.arange(len(remaining)) == worst
            taken.append(remaining.keep(mask))
            remaining = remaining.keep(~mask)
        if not edges:
            return anchors
        spots, gaps = farthest_points(domain, remaining.coords, len(edges),
                                      self._frame * 0.61803)
        moves = next((i for i, (gap, edge) in enumerate(zip(gaps, edges, strict=True))
                      if gap <= edge * 1.05), len(edges))
        for kept in taken[moves:]:
            remaining = remaining.append(kept)
        if moves == 0:
            return remaining
        slots = np.concatenate([t.slot for t in taken[:moves]])
        offsets = np.array([np.random.default_rng((settings.seed, self._frame, int(slot)))
                            .uniform(size=2) for slot in slots])
        self.stats.redistributed += moves
        return remaining.append(self._trace(domain, spots[:moves], offsets, slots, tracer,
                                            geometry, epsilon))

    def _anchor_hits(self, anchors: _Anchors, domain: LightDomain, permutation: np.ndarray,
                     geometry: WorldGeometry) -> tuple[SurfaceHits, np.ndarray]:
        """Surface hits of the anchors whose path met a surface its light lights (light
        linking), carrying their cell's flux, and their path ids."""
        _, flux = cell_integrals(domain, anchors.coords)
        hit = anchors.hit.copy()
        lit = lit_hits(anchors.triangle[hit], domain.light.receivers, geometry)
        if lit is not None:
            hit[hit] = lit
        return SurfaceHits(anchors.position[hit], anchors.normal[hit], anchors.albedo[hit],
                           flux[hit] * anchors.transmittance[hit],
                           permutation[anchors.slot[hit]],
                           anchors.triangle[hit]), anchors.path_id[hit]

    def _environment_hits(self, emitters: list, slots: np.ndarray, count: int,
                          permutation: np.ndarray, tracer: RayCaster, geometry: WorldGeometry,
                          epsilon: float, seed: int
                          ) -> tuple[SurfaceHits, np.ndarray, np.ndarray]:
        """First hits of the world's and emissive surfaces' paths: the same seeded path for a
        slot every frame (ids change only with the geometry or the slot set), and each hit's
        emitter's Max Bounces."""
        u = scrambled_halton(count, START_DIMENSIONS, seed + 7)[slots]
        paths = start_paths(emitters, u)
        found = trace_hits(tracer, geometry, paths.origin, paths.direction, paths.flux,
                           np.arange(len(slots)), epsilon, from_light=True,
                           blockers=paths.blockers)
        if self.stats.reset or not np.array_equal(slots, self._environment_slots):
            self._environment_slots, self._environment_ids = slots, self._ids(len(slots))
        found = found.kept(lit_hits(found.triangle, paths.receivers[found.rank], geometry))
        return (SurfaceHits(found.position, found.normal, found.albedo, found.flux,
                            permutation[slots[found.rank]], found.triangle),
                self._environment_ids[found.rank], paths.max_bounces[found.rank])


def _worst(coords: np.ndarray) -> tuple[int, float]:
    """The worst anchor, the end of the shortest Delaunay edge that lies in the denser place
    (the one whose second neighbour is nearer), and that edge's length (the first anchor and
    0 without an edge)."""
    edge = shortest_edge(coords)
    if edge is None:
        return 0, 0.0
    tree = cKDTree(coords)
    second = [tree.query(coords[i], k=min(3, len(coords)))[0][-1] for i in edge]
    return edge[int(np.argmin(second))], float(np.linalg.norm(coords[edge[0]] - coords[edge[1]]))


def _allocate(total: int, powers: list[float]) -> list[int]:
    """Split ``total`` paths over emitters by power (largest remainders; every emitter with
    power gets at least one path while paths last)."""
    power = np.maximum(np.asarray(powers, np.float64), 0.0)
    if power.sum() <= 0:
        return [0] * len(power)
    share = total * power / power.sum()
    counts = np.floor(share).astype(int)
    counts[(power > 0) & (counts == 0)] = 1
    while counts.sum() > total:
        counts[int(np.argmax(counts))] -= 1
    order = np.argsort(-(share - np.floor(share)), kind="stable")
    for index in order[: total - counts.sum()]:
        counts[index] += 1
    return [int(c) for c in counts]

