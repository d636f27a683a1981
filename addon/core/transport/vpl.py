"""Virtual point lights by light tracing (Instant Radiosity, the seed's "Creating VPLs").

Light paths start on every emitter (lights, emissive surfaces, the world) from a scrambled
Halton sequence, reflect diffusely (cosine-distributed) and leave a VPL at every hit. A VPL
left at the k-th hit carries the light of k bounces and is used when ``bounces >= k``.

Weights (flux Φ is RGB):
- a path starts with Φ₀ = Φ_emitter / (N p_emitter) (emitters chosen by flux);
- at a hit y with albedo ρ(y) the VPL is a one-sided Lambertian emitter of peak intensity
  Φ ρ(y) / π (W/sr) around the normal facing the incoming path; at a glossy surface it also
  reflects Φ through its GGX lobe (a glossy point emitter, as Virtual Spherical Lights without
  the spread): Φ f_glossy(ω_in, ω) cos θ towards ω, the lobe evaluated at the receiver by
  the gather (lights_lib.glsl) from the VPL's ``glossy`` texels; at a rough diffuse surface
  its diffuse light leaves through the Oren–Nayar lobe of the direction it arrived from
  (retro-reflecting towards it) instead of a cosine, of the same power (``rough_lobes``);
- continuing, the flux becomes Φ ρ(y) / q, where q is the chance to continue: with
  fractional absorption q = n_k / n_(k-1), the share of the N index-ordered paths that go on
  (n_k = round(ρ̄^k N), ρ̄ the scene's average reflectance); with Russian roulette
  q = min(1, max(ρ(y))) per path. Both keep the estimator unbiased.

At a translucent surface (Material.translucency t) the diffuse reflectance ρ splits: the VPL
emits ρ (1 − t) on the side the light came from, and a second VPL on the far side ρ t
(the Translucent BSDF's light); a path continuing diffusely crosses to the far side with the
luminance share of ρ t, weighted by its chance.

A path continuing through the glossy lobe leaves its next VPL at the next hit, which carries
two or more bounces; the glossy emission at y is the single glossy bounce y → receiver, so no
path is counted twice. Its lobe's multiple-scattering compensation is taken at the incoming
cosine, so the emitted glossy power is exactly what the glossy continuation carries on.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene import principled
from ..scene.environment import EnvironmentSampler, lookup
from ..scene.geometry import WorldGeometry
from ..scene.model import EVERY_RECEIVER_SET, NO_BOUNCE_LIMIT, Light, LightKind, Scene, World
from ..scene.textures import LUMINANCE
from ..scene.vectors import triangle_areas, unit
from ..settings import Settings
from .light_profiles import profile_sampler, profile_towards
from .lights import (
    GLOSSY_LOBE_TEXELS,
    KIND_COSINE,
    NO_SPOT,
    ROUGH_TEXELS,
    LightSamples,
    area_light_points,
    concentric_disk,
    light_problem,
    soft_falloff,
    soft_falloff_radius,
    spot_mask,
    spot_parameters,
    spread_attenuation,
    spread_parameters,
)
from .ray_caster import RayCaster
from .sequences import scrambled_halton

START_DIMENSIONS = 5  # emitter choice, position (2), direction (2)
GLOSSY_TEXELS = GLOSSY_LOBE_TEXELS + ROUGH_TEXELS  # VPLs.glossy's (lights_lib.glsl's VPL_GLOSSY)
FLUX_TEXELS = [0, 1, 2, 4, 5, 6]  # those of them scaled by the flux


@dataclass
class VPLs:
    """Virtual point lights: one-sided cosine emitters."""

    position: np.ndarray  # (n, 3)
    normal: np.ndarray  # (n, 3) unit, facing the side the light arrived from
    intensity: np.ndarray  # (n, 3) peak radiant intensity, W/sr
    generation: np.ndarray  # (n,) int, the bounce a VPL's light has made (1 = first hit)
    rank: np.ndarray  # (n,) int, the rank of the light path that left it
    key: np.ndarray | None = None  # (n,) int64 identity kept while the VPL holds still
    # (Incremental Instant Radiosity); None when VPLs are made afresh every frame
    glossy: np.ndarray | None = None  # (n, GLOSSY_TEXELS, 4) directional emission: the
    # glossy lobe's texels scaled by the incident flux (Φ A, alpha), (Φ B, eta), (Φ C, 0),
    # (towards the light, the coat's eta), the clear coat's (Φ × its weight, its alpha)
    # (alpha 0: no glossy lobe), and a rough diffuse lobe's (Φ c, σ), (Φ c m (1 − E(μ)), 0)
    # (WorldGeometry.rough_lobes; σ 0: smooth); all zero for a Lambertian VPL; None when no
    # VPL emits directionally
    far_side: np.ndarray | None = None  # (n,) bool: on the far side of a translucent surface
    # from its light (its own key in Incremental IR); None where none is

    def __len__(self) -> int:
        return len(self.generation)

    @classmethod
    def empty(cls) -> VPLs:
        return cls(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, int),
                   np.zeros(0, int))

    def as_light_samples(self, shadow_resolution: int) -> LightSamples:
        n = len(self)
        return LightSamples(self.position, self.normal, np.full(n, KIND_COSINE), self.intensity,
                            np.full(n, NO_SPOT), np.zeros(n), np.ones(n, bool),
                            np.full(n, shadow_resolution), self.generation, np.zeros(n, bool),
                            np.zeros((n, 2)), self.glossy)

    def within_bounce_limits(self, limit: np.ndarray) -> VPLs:
        """The VPLs whose generation is within their path's limit (``limit`` per rank: its
        emitter's Max Bounces), with their keys."""
        keep = self.generation <= limit[self.rank]
        if keep.all():
            return self
        kept = self.scaled(keep, 1.0)
        kept.key = None if self.key is None else self.key[keep]
        return kept

    def scaled(self, keep: np.ndarray | slice, factor: np.ndarray | float) -> VPLs:
        """The VPLs ``keep``, their light (diffuse and glossy) times ``factor`` (per VPL or
        one); without keys."""
        factor = np.broadcast_to(np.asarray(factor, float), self.generation[keep].shape)
        glossy = None
        if self.glossy is not None:
            glossy = self.glossy[keep].copy()
            glossy[:, FLUX_TEXELS, :3] *= factor[:, None, None]
        return VPLs(self.position[keep], self.normal[keep],
                    self.intensity[keep] * factor[:, None], self.generation[keep],
                    self.rank[keep], glossy=glossy,
                    far_side=None if self.far_side is None else self.far_side[keep])

    @classmethod
    def concatenate(cls, parts: list[VPLs]) -> VPLs:
        """One set of the VPLs of ``parts`` (without keys)."""
        glossy = None
        if any(p.glossy is not None for p in parts):
            glossy = np.concatenate([p.glossy if p.glossy is not None
                                     else np.zeros((len(p), GLOSSY_TEXELS, 4)) for p in parts])
        far_side = None
        if any(p.far_side is not None for p in parts):
            far_side = np.concatenate([p.far_side if p.far_side is not None
                                       else np.zeros(len(p), bool) for p in parts])
        return cls(*(np.concatenate([getattr(p, f) for p in parts])
                     for f in ("position", "normal", "intensity", "generation", "rank")),
                   glossy=glossy, far_side=far_side)


@dataclass
class _Paths:
    """A batch of rays leaving emitters: origins, unit directions and carried flux, the
    Soft Falloff radius of a path's light (at its origin; 0 for none), the receiver sets
    its emitter lights (light linking: Light.receivers) and the blocker sets that cast its
    shadows (shadow linking: Light.blockers), per path or one for all."""

    origin: np.ndarray
    direction: np.ndarray
    flux: np.ndarray
    soft_radius: float | np.ndarray = 0.0
    receivers: int | np.ndarray = EVERY_RECEIVER_SET
    blockers: int | np.ndarray = EVERY_RECEIVER_SET
    max_bounces: int | np.ndarray = NO_BOUNCE_LIMIT  # its emitter's (Light.max_bounces)


def _frame(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal tangents (n, 3) around unit normals (Duff et al. 2017)."""
    sign = np.where(normal[:, 2] >= 0, 1.0, -1.0)
    a = -1.0 / (sign + normal[:, 2])
    b = normal[:, 0] * normal[:, 1] * a
    t = np.stack([1 + sign * normal[:, 0] ** 2 * a, sign * b, -sign * normal[:, 0]], axis=1)
    s = np.stack([b, sign + normal[:, 1] ** 2 * a, -normal[:, 1]], axis=1)
    return t, s


def cosine_directions(normal: np.ndarray, u: np.ndarray, sin_max: float = 1.0) -> np.ndarray:
    """Cosine-distributed unit directions around unit normals (Malley: disk -> hemisphere),
    within the cone sin θ < sin_max (half angle below 90°) when given."""
    disk = concentric_disk(u) * sin_max
    z = np.sqrt(np.maximum(0.0, 1.0 - (disk**2).sum(axis=1)))
    t, s = _frame(normal)
    return unit(disk[:, :1] * t + disk[:, 1:] * s + z[:, None] * normal)


def uniform_sphere(u: np.ndarray) -> np.ndarray:
    z = 1 - 2 * u[:, 0]
    r = np.sqrt(np.maximum(0.0, 1 - z * z))
    phi = 2 * np.pi * u[:, 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def average_reflectance(geometry: WorldGeometry) -> float:
    """Area-weighted mean albedo luminance of all surfaces (ρ̄ of fractional absorption)."""
    if geometry.vertex_count == 0:
        return 0.0
    area = triangle_areas(geometry.positions)
    albedo = geometry.albedo @ LUMINANCE
    return float((area * albedo).sum() / max(area.sum(), 1e-300))


class _Emitter:
    """One source of light paths: its flux (for allocation), a sampler of start rays, the
    receiver sets it lights and the blocker sets that cast its shadows (light and shadow
    linking; its paths' own where they carry them), and how often its light may bounce
    (Cycles' Max Bounces of a light or the world)."""

    def __init__(self, flux: np.ndarray, sample) -> None:
        self.flux = np.asarray(flux, dtype=np.float64)
        self.power = float(self.flux @ LUMINANCE)
        self.sample = sample  # (u (n, 5) in [0,1)) -> (_Paths with flux per unit path)
        self.receivers = EVERY_RECEIVER_SET
        self.blockers = EVERY_RECEIVER_SET
        self.max_bounces = NO_BOUNCE_LIMIT


def light_emitter(light: Light, centre: np.ndarray, radius: float) -> _Emitter | None:
    """A light's emitter of light paths (None for one that emits none)."""
    emitter = _light_emitter(light, centre, radius)
    if emitter is not None:  # a light that casts no shadow: nothing blocks its paths' start
        emitter.receivers = light.receivers
        emitter.blockers = light.blockers if light.cast_shadow else 0
        emitter.max_bounces = light.max_bounces
    return emitter


PASS_LIMIT = 16  # objects a light path passes (shadow linking) before its first hit, at most


def light_hits(tracer: RayCaster, geometry: WorldGeometry, origin: np.ndarray,
               direction: np.ndarray, t_min: float, blockers: int | np.ndarray,
               every_surface: bool = True
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Where light leaving its emitter arrives (Cycles' shadow rays): each ray's first hit,
    or every surface up to the first that casts a shadow of it, since the others let it
    through yet receive it (``every_surface``; else that surface alone): objects whose
    Shadow visibility is off, those not in the emitter's ``blockers`` (per ray or one:
    shadow linking) and, for blockers 0 (a light that casts no shadow), every surface.
    Surfaces met from behind are passed without light where they are shadowless or the
    light is (a bulb round its lamp, the inside of a closed object: no ray from outside
    reaches them, and light left there would leak through imperfect shadow maps). As (ray,
    distance, triangle, light let through by clear surfaces on the way (·, 3)), one entry per
    ray and hit; a miss has distance inf and triangle -1."""
    shadowless = geometry.shadowless if every_surface and geometry.shadowless.any() else None
    stop_at_shadowless = shadowless is not None
    hits = tracer.intersect(origin, direction, t_min, np.inf, shadow=not stop_at_shadowless)
    current = (np.arange(len(origin)), hits.distance.copy(), hits.triangle.copy(),
               hits.transmittance.astype(np.float64))
    blockers = np.broadcast_to(np.asarray(blockers, np.uint64), current[0].shape)
    unblocked = blockers == np.uint64(0)
    linked = bool(np.any(blockers != np.uint64(EVERY_RECEIVER_SET))) and (
        geometry.blocker_set is not None or bool(unblocked.any()))
    if not linked and shadowless is None:
        return current
    found = []
    for _ in range(PASS_LIMIT):
        ray, distance, triangle, through = current
        hit = np.flatnonzero(triangle >= 0)
        passes = np.zeros(len(hit), bool)
        if linked:
            sets = geometry.blocker_set
            bit = np.zeros(len(hit), np.uint64) if sets is None \
                else sets[triangle[hit]].astype(np.uint64)
            passes |= ((blockers[ray[hit]] >> bit) & np.uint64(1)) == 0
        if shadowless is not None:
            passes |= shadowless[triangle[hit]]
        passing = hit[passes]
        if len(passing) == 0:
            break
        stays = np.ones(len(ray), bool)
        stays[passing] = every_surface
        unlit_behind = unblocked[ray[passing]]
        if shadowless is not None:
            unlit_behind = unlit_behind | shadowless[triangle[passing]]
        if unlit_behind.any():
            behind = _back_facing(geometry, triangle[passing], direction[ray[passing]])
            stays[passing] &= ~(unlit_behind & behind)
        found.append(tuple(a[stays] for a in current))
        rays = ray[passing]
        again = tracer.intersect(origin[rays], direction[rays], distance[passing], np.inf,
                                 shadow=not stop_at_shadowless)
        current = (rays, again.distance, again.triangle,
                   through[passing] * again.transmittance)
    found.append(current)
    return tuple(np.concatenate(parts) for parts in zip(*found, strict=True))


def _back_facing(geometry: WorldGeometry, triangle: np.ndarray, direction: np.ndarray
                 ) -> np.ndarray:
    """Whether rays along ``direction`` (m, 3) meet ``triangle`` (m,) from behind (against
    its winding's normal)."""
    t = geometry.positions.reshape(-1, 3, 3)[triangle].astype(np.float64)
    normal = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    return (normal * direction).sum(axis=1) > 0


def lit_hits(triangle: np.ndarray, receivers: int | np.ndarray, geometry: WorldGeometry
             ) -> np.ndarray | None:
    """Light linking: whether each path's first hit, on ``triangle``, is lit by its emitter
    of ``receivers`` (per hit or one), or None where every hit is (Cycles: an emitter's
    light reaches no surface of an unlinked object, so none of it bounces on from there)."""
    receivers = np.asarray(receivers, np.uint64)
    if not np.any(receivers != np.uint64(EVERY_RECEIVER_SET)):
        return None
    sets = geometry.receiver_set
    bit = np.zeros(len(triangle), np.uint64) if sets is None \
        else sets[triangle].astype(np.uint64)
    return ((receivers >> bit) & np.uint64(1)).astype(bool)


def _light_emitter(light: Light, centre: np.ndarray, radius: float) -> _Emitter | None:
    color = np.asarray(light.color, dtype=np.float64) * light.power
    m = light.matrix
    position, travel = m[:3, 3], unit(-m[:3, 2][None])[0]
    if light.kind in (LightKind.POINT, LightKind.SPOT):
        intensity = color / (4 * np.pi)
        if light.kind is LightKind.POINT and light.profile is not None:
            sampler = profile_sampler(light.profile)

            def sample_profile(u: np.ndarray) -> _Paths:
                local, weight = sampler.sample(u[:, [0, 3, 4]])
                return _Paths(np.repeat(position[None], len(u), 0), local @ light.frame.T,
                              color * weight[:, None], soft_falloff_radius(light))
            return _Emitter(color * light.profile.mean, sample_profile)
        if light.kind is LightKind.POINT:
            def sample(u: np.ndarray) -> _Paths:
                n = len(u)
                return _Paths(np.repeat(position[None], n, 0), uniform_sphere(u[:, 3:5]),
                              np.repeat(color[None], n, 0), soft_falloff_radius(light))
            return _Emitter(color, sample)
        cos_half, smooth = spot_parameters(light)
        solid_angle = 2 * np.pi * (1 - cos_half)

        def sample_spot(u: np.ndarray) -> _Paths:
            n = len(u)
            cos_t = 1 - u[:, 3] * (1 - cos_half)
            sin_t = np.sqrt(np.maximum(0.0, 1 - cos_t**2))
            phi = 2 * np.pi * u[:, 4]
            t, s = _frame(np.repeat(travel[None], n, 0))
            d = (sin_t * np.cos(phi))[:, None] * t + (sin_t * np.sin(phi))[:, None] * s \
                + cos_t[:, None] * travel
            mask = spot_mask(cos_t, cos_half, smooth) if smooth > 0 else np.ones(n)
            return _Paths(np.repeat(position[None], n, 0), unit(d),
                          intensity * solid_angle * mask[:, None], soft_falloff_radius(light))
        return _profiled(light, _Emitter(intensity * solid_angle, sample_spot))
    if light.kind is LightKind.SUN:
        flux = color * np.pi * radius**2
        return _Emitter(flux, _parallel_sampler(
            lambda u: (np.repeat(travel[None], len(u), 0), np.repeat(flux[None], len(u), 0)),
            centre, radius))
    # Area light: position on the shape, cosine-distributed direction around -Z (within the
    # spread cone, carrying the spread factor over the cone's cosine-weighted share sin² a).
    tan_half, norm = spread_parameters(light)
    sin_max = float(np.sin(np.arctan(tan_half))) if tan_half > 0 else 1.0

    def sample_area(u: np.ndarray) -> _Paths:
        n = len(u)
        origin = area_light_points(light, u[:, 1:3])
        direction = cosine_directions(np.repeat(travel[None], n, 0), u[:, 3:5], sin_max)
        weight = sin_max**2 * spread_attenuation(direction @ travel, tan_half, norm)
        return _Paths(origin, direction, color * weight[:, None])
    return _profiled(light, _Emitter(color, sample_area))


def _profiled(light: Light, emitter: _Emitter) -> _Emitter:
    """A spot or area light's emitter with its IES profile (itself without one): each path's
    flux × the profile towards its direction, the emitter's flux × the profile's mean over
    its paths (a fixed set of 4096)."""
    if light.profile is None:
        return emitter

    def sample(u: np.ndarray) -> _Paths:
        paths = emitter.sample(u)
        paths.flux = paths.flux * profile_towards(light, paths.direction)[:, None]
        return paths
    plain = emitter.sample(np.random.default_rng(0).random((4096, 5)))
    weight = plain.flux @ LUMINANCE
    mean = (weight * profile_towards(light, plain.direction)).sum() / max(weight.sum(), 1e-300)
    return _Emitter(emitter.flux * float(mean), sample)


def _parallel_sampler(travel_and_flux, centre: np.ndarray, radius: float):
    """Parallel rays through a disk covering the scene's bounding sphere; ``travel_and_flux``
    maps u (n, 5) to the directions of travel and the flux per path."""
    def sample(u: np.ndarray) -> _Paths:
        travel, flux = travel_and_flux(u)
        t, s = _frame(travel)
        disk = concentric_disk(u[:, 1:3]) * radius
        origin = centre - 1.01 * radius * travel + disk[:, :1] * t + disk[:, 1:] * s
        return _Paths(origin, travel, flux)
    return sample


def _world_emitter(scene: Scene, centre: np.ndarray, radius: float) -> _Emitter | None:
    """Parallel rays from every direction: uniform for a constant colour, importance-sampled
    from the environment map otherwise (flux L / pdf × π R² per path); through the light
    portals instead where the scene has any."""
    radiance = scene.world.radiance
    if not np.any(radiance > 0):
        return None
    if scene.portals:
        return _portal_emitter(scene.world, scene.portals)
    disk = np.pi * radius**2
    flux = radiance * 4 * np.pi * disk
    env = scene.world.environment
    if env is None:
        def uniform(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            return -uniform_sphere(u[:, 3:5]), np.repeat(flux[None], len(u), 0)
        return _Emitter(flux, _parallel_sampler(uniform, centre, radius))
    sampler = EnvironmentSampler(env)

    def importance(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        sky, ratio = sampler.sample(u[:, 3:5])
        return -sky, ratio * disk
    return _Emitter(flux, _parallel_sampler(importance, centre, radius))


def _portal_emitter(world: World, portals: list[Light]) -> _Emitter | None:
    """World light entering through Cycles' light portals (area lights marked Portal, facing
    into the room along their -Z): a path starts on a portal chosen by area, travels
    cosine-distributed into the room and carries L_world(-d) π A (A: all portals' area), the
    flux through the openings; light entering elsewhere is not traced (as portals mean)."""
    areas = np.array([portal.world_area for portal in portals])
    total = float(areas.sum())
    if total <= 0:
        return None
    cdf = np.cumsum(areas) / total
    inward = [unit(-portal.matrix[:3, 2][None])[0] for portal in portals]

    def sample(u: np.ndarray) -> _Paths:
        pick = np.minimum(np.searchsorted(cdf, u[:, 0], side="right"), len(portals) - 1)
        origin, direction = np.zeros((len(u), 3)), np.zeros((len(u), 3))
        for index, portal in enumerate(portals):
            rows = np.flatnonzero(pick == index)
            origin[rows] = area_light_points(portal, u[rows, 1:3])
            direction[rows] = cosine_directions(np.repeat(inward[index][None], len(rows), 0),
                                                u[rows, 3:5])
        radiance = np.repeat(world.radiance[None], len(u), 0) if world.environment is None \
            else lookup(world.environment, -direction)
        return _Paths(origin, direction, radiance * np.pi * total)
    return _Emitter(world.radiance * np.pi * total, sample)


def _emission_emitter(geometry: WorldGeometry) -> _Emitter | None:
    """Emissive triangles, two-sided Lambertian (flux 2 π L A each), or one-sided outwards
    (π L A) on a closed object, whose inner side's light stays inside it."""
    emission = geometry.light_emission.astype(np.float64)
    emitting = np.flatnonzero(emission.max(axis=1) > 0)
    if len(emitting) == 0:
        return None
    tri = geometry.positions.reshape(-1, 3, 3)[emitting].astype(np.float64)
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    outward = geometry.emission_sides[emitting]
    flux = np.where(outward == 0, 2.0, 1.0)[:, None] * np.pi * emission[emitting] \
        * area[:, None]
    power = flux @ LUMINANCE
    if power.sum() <= 0:
        return None
    cdf = np.cumsum(power) / power.sum()
    normal = unit(cross)
    linked, shadow_linked = geometry.emission_receivers, geometry.emission_blockers
    receivers = None if linked is None else linked[emitting]
    blockers = None if shadow_linked is None else shadow_linked[emitting]

    def sample(u: np.ndarray) -> _Paths:
        pick = np.minimum(np.searchsorted(cdf, u[:, 0], side="right"), len(cdf) - 1)
        a, b = u[:, 1], u[:, 2]
        flip = a + b > 1
        a, b = np.where(flip, 1 - a, a), np.where(flip, 1 - b, b)
        t = tri[pick]
        origin = t[:, 0] + a[:, None] * (t[:, 1] - t[:, 0]) + b[:, None] * (t[:, 2] - t[:, 0])
        side = np.where(outward[pick] != 0, outward[pick], np.where(u[:, 4] < 0.5, 1.0, -1.0))
        v = np.stack([u[:, 3], (u[:, 4] * 2) % 1.0], axis=1)
        direction = cosine_directions(normal[pick] * side[:, None], v)
        probability = power[pick] / power.sum()
        return _Paths(origin, direction, flux[pick] / probability[:, None],
                      receivers=EVERY_RECEIVER_SET if receivers is None else receivers[pick],
                      blockers=EVERY_RECEIVER_SET if blockers is None else blockers[pick])
    return _Emitter(flux.sum(axis=0), sample)


def _emitters(scene: Scene, geometry: WorldGeometry, centre: np.ndarray, radius: float
              ) -> list[_Emitter]:
    found = [light_emitter(light, centre, radius) for light in scene.surface_lights
             if light.power != 0 and light.max_bounces > 0 and light_problem(light) is None]
    return [e for e in found if e is not None and e.power > 0] + environment_emitters(
        scene, geometry, centre, radius)


def environment_emitters(scene: Scene, geometry: WorldGeometry, centre: np.ndarray,
                         radius: float) -> list[_Emitter]:
    """The emitters that are not lights: the world and the emissive surfaces (with power and
    bounces allowed)."""
    world = _world_emitter(scene, centre, radius)
    if world is not None:
        world.max_bounces = scene.world.max_bounces
    found = [world, _emission_emitter(geometry)]
    return [e for e in found if e is not None and e.power > 0 and e.max_bounces > 0]


def start_paths(emitters: list[_Emitter], u: np.ndarray) -> _Paths:
    """Choose an emitter per path by flux (first dimension, remapped), then sample it."""
    power = np.array([e.power for e in emitters])
    probability = power / power.sum()
    cdf = np.cumsum(probability)
    choice = np.minimum(np.searchsorted(cdf, u[:, 0], side="right"), len(emitters) - 1)
    low = cdf[choice] - probability[choice]
    u = u.copy()
    u[:, 0] = np.clip((u[:, 0] - low) / probability[choice], 0, np.nextafter(1, 0))
    n = len(u)
    origin, direction, flux = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
    soft_radius = np.zeros(n)
    receivers = np.full(n, EVERY_RECEIVER_SET, np.uint64)
    blockers = np.full(n, EVERY_RECEIVER_SET, np.uint64)
    max_bounces = np.full(n, NO_BOUNCE_LIMIT)
    for index, emitter in enumerate(emitters):
        rows = np.flatnonzero(choice == index)
        if len(rows):
            paths = emitter.sample(u[rows])
            origin[rows], direction[rows] = paths.origin, paths.direction
            flux[rows] = paths.flux / (n * probability[index])
            soft_radius[rows] = paths.soft_radius
            receivers[rows] = paths.receivers if np.ndim(paths.receivers) \
                else emitter.receivers
            blockers[rows] = paths.blockers if np.ndim(paths.blockers) else emitter.blockers
            max_bounces[rows] = emitter.max_bounces
    return _Paths(origin, direction, flux, soft_radius, receivers, blockers, max_bounces)


@dataclass
class SurfaceHits:
    """Where light paths met surfaces: the incident flux there, and each path's rank (paths
    continue by rank under fractional absorption, so ranks must not depend on the path)."""

    position: np.ndarray  # (m, 3)
    normal: np.ndarray  # (m, 3) facing the side the light came from
    albedo: np.ndarray  # (m, 3)
    flux: np.ndarray  # (m, 3) incident flux carried by the path
    rank: np.ndarray  # (m,) int in [0, n)
    triangle: np.ndarray | None = None  # (m,) int, the triangle hit (where known)
    incoming: np.ndarray | None = None  # (m, 3) direction of travel (where known)
    base: np.ndarray | None = None  # (m, 3) base colour, WorldGeometry.base_at (where known)

    def kept(self, keep: np.ndarray | None) -> SurfaceHits:
        """The hits ``keep`` (a boolean mask; None keeps all)."""
        if keep is None:
            return self
        return SurfaceHits(*(None if value is None else value[keep] for value in (
            self.position, self.normal, self.albedo, self.flux, self.rank, self.triangle,
            self.incoming, self.base)))


def trace_hits(tracer: RayCaster, geometry: WorldGeometry, origin: np.ndarray,
           direction: np.ndarray, flux: np.ndarray, rank: np.ndarray, epsilon: float,
           from_light: bool = False, soft_radius: float | np.ndarray = 0.0,
           blockers: int | np.ndarray = EVERY_RECEIVER_SET, every_surface: bool = True
           ) -> SurfaceHits:
    """The surfaces the rays hit (misses dropped), normals turned towards the ray, the flux
    dimmed by the clear surfaces crossed on the way; the base colour is looked up once per hit
    (the path albedo and the lobes derive from it). Rays ``from_light`` are its light's direct
    path (Cycles' shadow rays): objects whose Shadow visibility is off let them through, and
    those whose Diffuse visibility is off end them (no diffuse bounce sees their light); the
    others are diffuse bounces, which the latter let through. Shadow linking: light passes the
    objects that cast no shadow of its emitter (``blockers``, per ray or one), which still
    receive it (``light_hits``: a hit each, ``every_surface``). A light's Soft Falloff of
    ``soft_radius`` (per ray, or one for all) dims its light at the hits
    (``soft_falloff``)."""
    if from_light:
        ray, distance, triangle, through = light_hits(tracer, geometry, origin, direction,
                                                      epsilon, blockers, every_surface)
    else:
        hits = tracer.intersect(origin, direction, epsilon, np.inf, diffuse=True)
        ray, distance, triangle, through = (np.arange(len(origin)), hits.distance,
                                            hits.triangle, hits.transmittance)
    hit = triangle >= 0
    if from_light and geometry.diffuse_hidden.any():
        hit[hit] = ~geometry.diffuse_hidden[triangle[hit]]
    tri, ray = triangle[hit], ray[hit]
    position = origin[ray] + direction[ray] * distance[hit, None].astype(np.float64)
    t = geometry.positions.reshape(-1, 3, 3)[tri].astype(np.float64)
    normal = unit(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]))
    normal *= np.where((normal * direction[ray]).sum(axis=1) > 0, -1.0, 1.0)[:, None]
    base = geometry.base_at(tri, position)
    kept = through[hit]
    if np.any(soft_radius):
        kept = kept * soft_falloff(np.square(distance[hit].astype(np.float64)),
                                   np.broadcast_to(soft_radius, origin.shape[:1])[ray])[:, None]
    return SurfaceHits(position, normal, geometry.path_albedo(tri, base),
                       flux[ray] * kept, rank[ray], tri, direction[ray], base)


def _lobes(hits: SurfaceHits, geometry: WorldGeometry
           ) -> tuple[np.ndarray, np.ndarray | None, tuple[np.ndarray, ...], np.ndarray | None]:
    """What a VPL at the hits emits diffusely (reflectance (m, 3)), the glossy albedo (m, 3)
    of the paths' glossy continuation and its lobes (roughness (m,), the coat's share of it
    (m,) and the coat's roughness (m,)), and the VPLs' directional emission (VPLs.glossy: the
    glossy lobes, the coats' included, and the rough diffuse ones) (both None where no
    material is glossy or rough or the incoming direction or base colour is not known: the
    path albedo is then all diffuse)."""
    if hits.incoming is None or hits.triangle is None or hits.base is None \
            or not (geometry.has_specular or geometry.has_rough_diffuse):
        return hits.albedo, None, (np.zeros(len(hits.rank)),) * 3, None
    mu = np.clip(-(hits.incoming * hits.normal).sum(axis=1), 0.0, 1.0)
    diffuse, gloss, *lobes = geometry.reflectance_split(hits.triangle, hits.base, mu)
    emission = np.zeros((len(mu), GLOSSY_TEXELS, 4))
    emission[:, :3] = geometry.lobe_texels(hits.triangle, hits.base, mu)
    emission[:, 3, :3] = -hits.incoming
    weight, rough, eta = geometry.coats(hits.triangle).T
    emission[:, 3, 3], emission[:, 4, :3], emission[:, 4, 3] = eta, weight[:, None], rough**2
    no_lobe = emission[:, 0, 3] <= 0
    emission[no_lobe, :3] = emission[no_lobe, 4] = 0.0
    emission[:, GLOSSY_LOBE_TEXELS:] = geometry.rough_lobes(hits.triangle, hits.base, mu)
    emission[:, FLUX_TEXELS, :3] *= hits.flux[:, None, :]
    return diffuse, gloss, tuple(lobes), emission


def propagate(first: SurfaceHits, count: int, directions: np.ndarray, settings: Settings,
              tracer: RayCaster, geometry: WorldGeometry, radius: float) -> VPLs:
    """VPLs at the first hits of ``count`` paths and at every further hit up to
    ``settings.bounces``; ``directions`` (count, 2 (bounces - 1)) are the unit-square samples
    of the cosine-distributed reflections, per rank."""
    rho_bar = float(np.clip(average_reflectance(geometry), 1e-3, 1.0))
    roulette = np.random.default_rng(settings.seed + 1).uniform(size=(count, settings.bounces))
    lobe_choice = np.random.default_rng(settings.seed + 2).uniform(size=(count, settings.bounces))
    side_choice = np.random.default_rng(settings.seed + 3).uniform(size=(count, settings.bounces)) \
        if geometry.has_translucency else None
    epsilon = 1e-5 * radius
    hits, survivors = first, count
    out: list[VPLs] = []
    for generation in range(1, settings.bounces + 1):
        diffuse, gloss, (rough, coat_share, coat_rough), emission = _lobes(hits, geometry)
        through = None if side_choice is None or hits.triangle is None \
            else diffuse * geometry.translucency(hits.triangle)
        reflected = diffuse if through is None else diffuse - through
        if through is not None and emission is not None:  # the rough lobe reflects (1 − t)
            emission[:, GLOSSY_LOBE_TEXELS:, :3] *= (reflected / np.maximum(diffuse, 1e-30)
                                                      )[:, None]
        out.append(VPLs(hits.position, hits.normal, hits.flux * reflected / np.pi,
                        np.full(len(hits.rank), generation), hits.rank, glossy=emission))
        if through is not None:
            out.append(_far_side_vpls(hits, through, generation, emission is not None))
        if generation == settings.bounces or len(hits.rank) == 0:
            break
        if settings.termination == "fractional":
            continuing = max(1, round(count * rho_bar**generation))
            keep = hits.rank < continuing
            weight = np.full(len(hits.rank), survivors / continuing)
            survivors = continuing
        else:
            q = np.minimum(1.0, hits.albedo.max(axis=1))
            keep = roulette[hits.rank, generation] < q
            weight = 1.0 / np.maximum(q, 1e-12)
        k = 2 * (generation - 1)
        samples = directions[hits.rank, k:k + 2]
        direction = cosine_directions(hits.normal, samples)
        side = hits.normal.copy()  # the side the path leaves by
        carried = diffuse  # what a diffuse continuation keeps (per unit chance)
        if through is not None:  # through to the far side, by the luminance share
            p_through = np.clip(through @ LUMINANCE / np.maximum(diffuse @ LUMINANCE, 1e-30),
                                0.0, 1.0)
            crossing = side_choice[hits.rank, generation] < p_through
            direction[crossing] *= -1.0
            side[crossing] *= -1.0
            carried = np.where(crossing[:, None], through / np.maximum(p_through, 1e-12)[:, None],
                               reflected / np.maximum(1.0 - p_through, 1e-12)[:, None])
        flux = hits.flux * carried * weight[:, None]
        if gloss is not None:  # a diffuse or a glossy reflection, by their luminance
            total = np.maximum((diffuse + gloss) @ LUMINANCE, 1e-30)
            p_gloss = np.clip(gloss @ LUMINANCE / total, 0.0, 1.0)
            choice = lobe_choice[hits.rank, generation]
            glossy = choice < p_gloss
            if glossy.any():  # the coat's lobe or the one below, by their shares
                on_coat = choice[glossy] < p_gloss[glossy] * coat_share[glossy]
                direction[glossy] = principled.sample_reflection(
                    hits.normal[glossy], hits.incoming[glossy],
                    np.where(on_coat, coat_rough[glossy], rough[glossy]), samples[glossy])
                side[glossy] = hits.normal[glossy]
            lobe = np.where(glossy[:, None], gloss / np.maximum(p_gloss, 1e-12)[:, None],
                            carried / np.maximum(1.0 - p_gloss, 1e-12)[:, None])
            flux = hits.flux * lobe * weight[:, None]
        keep &= np.any(flux > 0, axis=1)
        hits = trace_hits(tracer, geometry, (hits.position + side * epsilon)[keep],
                          direction[keep], flux[keep], hits.rank[keep], epsilon)
    if not out:
        return VPLs.empty()
    return VPLs.concatenate(out)


def _far_side_vpls(hits: SurfaceHits, through: np.ndarray, generation: int,
                   directional: bool) -> VPLs:
    """The VPLs on the far side of the translucent surfaces among ``hits``: Lambertian
    emitters of the light let through (``through`` per unit incident flux, (m, 3)) around the
    reversed normal; with ``directional``, their (zero) directional emission."""
    far = np.flatnonzero(np.any(through > 0, axis=1))
    return VPLs(hits.position[far], -hits.normal[far], hits.flux[far] * through[far] / np.pi,
                np.full(len(far), generation), hits.rank[far],
                glossy=np.zeros((len(far), GLOSSY_TEXELS, 4)) if directional else None,
                far_side=np.ones(len(far), bool))


@dataclass(frozen=True)
class PathSequence:
    """Which light paths of the scrambled Halton sequence a frame traces: those from index
    ``first`` of the sequence scrambled by ``seed``. The passes of a render continue one
    sequence, so that K passes of N paths trace its first K·N paths, stratified as one set,
    not K independent sets of N."""

    seed: int
    first: int = 0


def generate_vpls(scene: Scene, geometry: WorldGeometry, settings: Settings, tracer: RayCaster,
                  centre: np.ndarray, radius: float, sequence: PathSequence | None = None
                  ) -> VPLs:
    """Trace ``settings.vpl_count`` light paths for up to ``settings.bounces`` hits each (or
    their emitter's Max Bounces), from ``sequence`` (default: from the start of
    ``settings.seed``'s)."""
    emitters = _emitters(scene, geometry, centre, radius)
    if settings.bounces == 0 or not emitters or geometry.vertex_count == 0:
        return VPLs.empty()
    n = settings.vpl_count
    sequence = sequence or PathSequence(settings.seed)
    u = scrambled_halton(n, START_DIMENSIONS + 2 * max(0, settings.bounces - 1), sequence.seed,
                         sequence.first)
    paths = start_paths(emitters, u[:, :START_DIMENSIONS])
    alive = np.flatnonzero(np.any(paths.flux != 0, axis=1))
    first = trace_hits(tracer, geometry, paths.origin[alive], paths.direction[alive],
                       paths.flux[alive], alive, 1e-5 * radius, from_light=True,
                       soft_radius=paths.soft_radius[alive], blockers=paths.blockers[alive])
    first = first.kept(lit_hits(first.triangle, paths.receivers[first.rank], geometry))
    vpls = propagate(first, n, u[:, START_DIMENSIONS:], settings, tracer, geometry, radius)
    return vpls.within_bounce_limits(paths.max_bounces)
