"""Turn the scene's lights, world and emissive surfaces into light samples: point-like emitters
the shaders evaluate with one shadow map each (the seed's "area lights as many point lights").

Units follow Cycles (each factor was checked against Cycles renders):
- point/spot of power P: intensity P / (4 pi) W/sr in every direction (spot: masked);
- sun of strength S: irradiance S W/m² on a surface facing it;
- area light of power P: a one-sided Lambertian emitter of total flux P, peak intensity P / pi
  (radiance P / (pi A)); its samples' unshadowed sum is replaced by the exact irradiance of its
  outline (AreaShapes);
- world of radiance L: irradiance pi L on an unoccluded surface;
- emission of radiance L: a two-sided Lambertian emitter of peak intensity L·A per triangle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene.environment import EnvironmentSampler
from ..scene.geometry import WorldGeometry, area_light_outline, transform_points
from ..scene.model import EVERY_RECEIVER_SET, Light, LightKind, Scene
from ..scene.vectors import unit
from ..settings import Settings
from .light_profiles import LightProfiles

KIND_OMNI, KIND_COSINE, KIND_COSINE2, KIND_DIRECTIONAL = 0, 1, 2, 3
NO_SPOT = -2.0
MIN_SPREAD = np.radians(1.0)  # narrower area-light spreads (collimated light) are widened
GLOSSY_LOBE_TEXELS = 5  # a VPL's glossy emission: its lobe, towards its light, its coat
ROUGH_TEXELS = 2  # then its rough diffuse lobe (VPLs.glossy; lights_lib.glsl's VPL_ROUGH)


def directional_emission(glossy: np.ndarray) -> np.ndarray:
    """Per VPL of the ``glossy`` texels (n, 7, 4) (VPLs.glossy): whether it emits through a
    glossy lobe or a rough diffuse one (the light table's texel 4 w flag)."""
    return (glossy[:, 0, 3] > 0) | (glossy[:, GLOSSY_LOBE_TEXELS, 3] > 0)


@dataclass
class LightSamples:
    """Parallel arrays, one row per sample."""

    position: np.ndarray  # (n, 3)
    axis: np.ndarray  # (n, 3) direction of travel (spot/sun/world) or emitter normal
    kind: np.ndarray  # (n,) int
    intensity: np.ndarray  # (n, 3) W/sr, or W/m² for directional samples
    spot_cos: np.ndarray  # (n,) cosine of half cone angle, NO_SPOT without a mask
    spot_smooth: np.ndarray  # (n,) 1 / ((1 - spot_cos) * blend), 0 for a hard edge
    casts_shadow: np.ndarray  # (n,) bool
    resolution: np.ndarray  # (n,) int shadow-map edge in texels
    generation: np.ndarray  # (n,) int bounces the light has made (0 = emitted light)
    soft: np.ndarray  # (n,) bool one of many samples of a soft light (area, sphere, sun angle,
    # world, emission) rather than a light of its own
    spread: np.ndarray  # (n, 2) area-light spread: tan(half angle), normalisation; 0 = none
    glossy: np.ndarray | None = None  # (n, 7, 4) VPLs' glossy and rough diffuse emission
    # (VPLs.glossy); None when no sample has one (the table then has no glossy texels)
    broad: np.ndarray | None = None  # (n,) bool a sample of light from everywhere (the
    # world), whose light varies smoothly over surfaces, diffuse and glossy; None: none is
    shape: np.ndarray | None = None  # (n,) int the sample's area light in ``shapes``, -1 for
    # none; None: no sample has one
    shapes: AreaShapes | None = None  # the area lights' outlines (per light, not per sample)
    soft_radius: np.ndarray | None = None  # (n,) the radius of its light's Soft Falloff
    # (soft_falloff_radius), 0 for none; None: no sample has one
    profile: np.ndarray | None = None  # (n,) int the sample's light in ``profiles``, -1 for
    # none; None: no sample has one
    profiles: LightProfiles | None = None  # the IES-profiled lights (per light, not sample)
    receivers: np.ndarray | None = None  # (n,) uint64 light linking: the receiver sets
    # (Instance.receiver_set) the sample's emitter lights; None: every sample lights all
    blockers: np.ndarray | None = None  # (n,) uint64 shadow linking: the blocker sets
    # (Instance.blocker_set) that cast the sample's shadows; None: every object casts all

    def __len__(self) -> int:
        return len(self.kind)

    @property
    def of_world(self) -> np.ndarray:
        """(n,) bool: the samples of the world (``broad``; none where it is None)."""
        return self.broad if self.broad is not None else np.zeros(len(self), bool)

    @property
    def tiles_per_sample(self) -> np.ndarray:
        """Atlas tiles each sample's shadow map needs (6 cube faces, 1 directional map)."""
        tiles = np.where(self.kind == KIND_DIRECTIONAL, 1, 6)
        return np.where(self.casts_shadow, tiles, 0)

    def table(self, first_tile: np.ndarray, near: np.ndarray, far: np.ndarray) -> np.ndarray:
        """The (n, 5, 4) float32 table the shaders read (see lights_lib.glsl); (n, 10, 4) with
        glossy emission (texel 4's w flags the samples that have it), (n, 12, 4) where a
        VPL is at a rough diffuse surface."""
        n = len(self)
        flagged = directional_emission(self.glossy) if self.glossy is not None else None
        width = 5
        if flagged is not None and flagged.any():
            rough = bool(np.any(self.glossy[:, GLOSSY_LOBE_TEXELS, 3] > 0))
            width += GLOSSY_LOBE_TEXELS + ROUGH_TEXELS * rough
        t = np.zeros((n, width, 4), dtype=np.float32)
        t[:, 0, :3], t[:, 0, 3] = self.position, self.kind
        if self.profile is not None:  # kind + 4 (profiled light + 1): lights_lib.glsl
            t[:, 0, 3] += 4 * (np.maximum(self.profile, -1) + 1)
        t[:, 1, :3], t[:, 1, 3] = self.axis, self.spot_cos
        t[:, 2, :3], t[:, 2, 3] = self.intensity, self.spot_smooth
        t[:, 3, 0] = np.where(self.casts_shadow, first_tile, -1)
        t[:, 3, 1], t[:, 3, 2], t[:, 3, 3] = self.resolution, near, far
        t[:, 4, 0] = self.generation
        t[:, 4, 1:3] = self.spread
        if self.soft_radius is not None:  # texel 4's z holds it where there is no spread
            t[:, 4, 2] = np.where(self.spread[:, 0] > 0, t[:, 4, 2], self.soft_radius)
        if self.shape is not None:  # negative: -(shape + 1); the glossy flag is positive
            t[:, 4, 3] = np.where(self.shape >= 0, -(self.shape + 1), 0)
        if width > 5:
            t[:, 4, 3] = np.where(flagged, 1.0, t[:, 4, 3])
            t[:, 5:] = self.glossy[:, :width - 5]
        return t

    def subset(self, index: np.ndarray) -> LightSamples:
        per_light = ("shapes", "profiles")
        return LightSamples(**{f: getattr(self, f) if f in per_light else
                               None if getattr(self, f) is None else getattr(self, f)[index]
                               for f in self.__dataclass_fields__})

    @property
    def linked(self) -> bool:
        """Whether some sample lights only some receiver sets (light linking)."""
        return self.receivers is not None \
            and bool(np.any(self.receivers != np.uint64(EVERY_RECEIVER_SET)))

    @property
    def shadow_linked(self) -> bool:
        """Whether some sample's shadows are cast by some blocker sets only (shadow
        linking)."""
        return self.blockers is not None \
            and bool(np.any(self.blockers != np.uint64(EVERY_RECEIVER_SET)))

    @property
    def has_profiles(self) -> bool:
        """Whether some sample's light has an IES profile (the shaders then look it up)."""
        return self.profiles is not None and self.profile is not None \
            and bool(np.any(self.profile >= 0))


@dataclass(frozen=True)
class AreaShapes:
    """Outlines of area lights for the ratio estimator of their direct light (Heitz, Hill &
    McGuire 2018): the light's exact unshadowed irradiance (its outline's projected solid
    angle, clipped at the receiver's horizon, times its radiance) times the fraction of its
    samples' unshadowed point estimates that their shadows keep. Unshadowed light is then
    exact, also where a receiver's plane cuts the light, and the samples give only the
    fraction in shadow. ``texels`` (T, 4) float32, read by lights_lib.glsl: texel k of light k
    = (first outline texel, outline points, samples, outline area), then the outlines' world
    points."""

    texels: np.ndarray

    @staticmethod
    def build(outlines: list[np.ndarray], samples: list[int]) -> AreaShapes:
        """From each light's world outline (m, 3) (convex, in order) and sample count."""
        headers = np.zeros((len(outlines), 4))
        at = len(outlines)
        for k, (outline, count) in enumerate(zip(outlines, samples, strict=True)):
            edges = np.cross(outline, np.roll(outline, -1, axis=0)).sum(axis=0)
            headers[k] = at, len(outline), count, 0.5 * float(np.linalg.norm(edges))
            at += len(outline)
        points = np.concatenate(outlines)
        rows = np.hstack([points, np.zeros((len(points), 1))])
        return AreaShapes(np.concatenate([headers, rows]).astype(np.float32))


def fibonacci_sphere(n: int, rng: np.random.Generator) -> np.ndarray:
    """n stratified unit vectors (spherical Fibonacci lattice, randomly rotated)."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = np.pi * (1.0 + 5**0.5) * i + rng.uniform(0, 2 * np.pi)
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    points = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return points @ q.T


def stratified_square(n: int, rng: np.random.Generator) -> np.ndarray:
    """n points in [0,1)² from a jittered grid of ceil(sqrt(n))² cells (n cells used, spread)."""
    side = int(np.ceil(np.sqrt(n)))
    cells = rng.permutation(side * side)[:n]
    jitter = rng.uniform(size=(n, 2))
    return (np.stack([cells % side, cells // side], axis=1) + jitter) / side


def fibonacci_square(n: int, rng: np.random.Generator) -> np.ndarray:
    """n points of the Fibonacci lattice in [0,1)², randomly shifted (Cranley-Patterson): the
    spherical Fibonacci lattice once mapped to the sphere by solid angle."""
    i = np.arange(n)
    shift = rng.uniform(size=2)
    return np.stack([(i + shift[0]) / n, (i * (5**0.5 - 1) / 2 + shift[1]) % 1.0], axis=1)


def concentric_disk(u: np.ndarray) -> np.ndarray:
    """Shirley-Chiu map of [0,1)² to the unit disk, preserving stratification."""
    a, b = 2 * u[:, 0] - 1, 2 * u[:, 1] - 1
    use_a = np.abs(a) > np.abs(b)
    safe_a = np.where(a == 0, 1, a)
    safe_b = np.where(b == 0, 1, b)
    r = np.where(use_a, a, b)
    phi = np.where(use_a, np.pi / 4 * (b / safe_a), np.pi / 2 - np.pi / 4 * (a / safe_b))
    return np.stack([r * np.cos(phi), r * np.sin(phi)], axis=1)


class _Builder:
    def __init__(self) -> None:
        self.rows: list[dict] = []
        self.outlines: list[np.ndarray] = []  # of the area lights whose samples have a shape
        self.profiled: list[Light] = []  # the lights with an IES profile, in index order

    def new_shape(self, outline: np.ndarray) -> int:
        """The index of a new area-light shape (its samples are added with it)."""
        self.outlines.append(outline)
        return len(self.outlines) - 1

    def new_profile(self, light: Light) -> int:
        """The index of a light with an IES profile (its samples are added with it), -1 for a
        light without one."""
        if light.profile is None:
            return -1
        self.profiled.append(light)
        return len(self.profiled) - 1

    def add(self, *, position, axis, kind, intensity, shadow, resolution,
            spot_cos=NO_SPOT, spot_smooth=0.0, soft=False, spread=(0.0, 0.0),
            broad=False, shape=-1, soft_radius=0.0, profile=-1,
            receivers=EVERY_RECEIVER_SET, blockers=EVERY_RECEIVER_SET) -> None:
        position = np.atleast_2d(position)
        n = len(position)
        self.rows.append({
            "position": position,
            "axis": np.broadcast_to(axis, (n, 3)),
            "kind": np.full(n, kind),
            "intensity": np.broadcast_to(intensity, (n, 3)),
            "spot_cos": np.full(n, spot_cos),
            "spot_smooth": np.full(n, spot_smooth),
            "casts_shadow": np.full(n, shadow),
            "resolution": np.full(n, resolution),
            "generation": np.zeros(n, dtype=int),
            "soft": np.full(n, soft),
            "spread": np.broadcast_to(spread, (n, 2)),
            "broad": np.full(n, broad),
            "shape": np.full(n, shape),
            "soft_radius": np.full(n, soft_radius),
            "profile": np.full(n, profile),
            "receivers": np.broadcast_to(np.asarray(receivers, np.uint64), (n,)),
            "blockers": np.broadcast_to(np.asarray(blockers, np.uint64), (n,)),
        })

    def link(self, first_row: int, light: Light) -> None:
        """The light's receiver and blocker sets on the samples added from row ``first_row``
        on (light and shadow linking)."""
        for row in self.rows[first_row:]:
            row["receivers"] = np.full(len(row["kind"]), light.receivers, np.uint64)
            row["blockers"] = np.full(len(row["kind"]), light.blockers, np.uint64)

    def build(self) -> LightSamples:
        if not self.rows:
            return LightSamples(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, int),
                                np.zeros((0, 3)), np.zeros(0), np.zeros(0), np.zeros(0, bool),
                                np.zeros(0, int), np.zeros(0, int), np.zeros(0, bool),
                                np.zeros((0, 2)))
        keys = self.rows[0].keys()
        samples = LightSamples(**{k: np.concatenate([r[k] for r in self.rows]) for k in keys})
        if self.profiled:
            samples.profiles = LightProfiles.build(self.profiled)
        if not samples.linked:
            samples.receivers = None
        if not samples.shadow_linked:
            samples.blockers = None
        if self.outlines:
            samples.shapes = AreaShapes.build(self.outlines, list(np.bincount(
                samples.shape[samples.shape >= 0], minlength=len(self.outlines))))
        return samples


def area_light_points(light: Light, u: np.ndarray) -> np.ndarray:
    """World points of an area light's shape (disc/ellipse or square/rectangle) at the
    offsets ``u`` (n, 2) in [0, 1)²."""
    on_shape = 0.5 * concentric_disk(u) if light.is_round else u - 0.5
    local = np.hstack([on_shape * light.area_size, np.zeros((len(u), 1))])
    return transform_points(light.matrix, local)


def spot_mask(cos_to_axis: np.ndarray, spot_cos: float, spot_smooth: float) -> np.ndarray:
    """Cycles' spot mask (as spot_mask in lights_lib.glsl): a smoothstep of the cosine past the
    cone edge scaled by spot_smooth, a hard edge when it is 0; 1 without a cone (NO_SPOT)."""
    cos_to_axis = np.asarray(cos_to_axis, dtype=np.float64)
    if spot_cos <= -1:
        return np.ones_like(cos_to_axis)
    if spot_smooth <= 0:
        return (cos_to_axis > spot_cos).astype(np.float64)
    x = np.clip((cos_to_axis - spot_cos) * spot_smooth, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def spread_parameters(light: Light) -> tuple[float, float]:
    """Cycles' area-light spread: tan of the half angle and the normalisation that keeps the
    light's power (1 / (tan a - a), or its Taylor form 3 / a³ below a = 0.05); (0, 0) for a
    spread of 180° (no attenuation). Spreads below MIN_SPREAD are rendered as MIN_SPREAD."""
    if light.kind is not LightKind.AREA or light.spread >= np.pi:
        return 0.0, 0.0
    half = 0.5 * max(light.spread, MIN_SPREAD)
    norm = 1.0 / (np.tan(half) - half) if half > 0.05 else 3.0 / half**3
    return float(np.tan(half)), float(norm)


def spread_attenuation(cos_to_axis: np.ndarray, tan_half: float, norm: float) -> np.ndarray:
    """Cycles' soft-box spread factor of radiance (as in lights_lib.glsl): a grid of slats
    passes max((tan a - tan θ) norm, 0) of the light at θ from the normal; 1 without spread."""
    cos_to_axis = np.asarray(cos_to_axis, dtype=np.float64)
    if tan_half <= 0:
        return np.ones_like(cos_to_axis)
    sin = np.sqrt(np.maximum(0.0, 1 - cos_to_axis**2))
    tan = np.divide(sin, cos_to_axis, out=np.full_like(sin, np.inf), where=cos_to_axis > 0)
    return np.maximum((tan_half - tan) * norm, 0.0)


def soft_falloff_radius(light: Light) -> float:
    """The radius of a point or spot light's Soft Falloff, 0 where it has none. Cycles then
    takes the light for a disc of that radius facing the receiver (not a sphere): its light
    at distance d from the centre is the sphere's × d² / (d² + r²) (``soft_falloff``), exact
    on the disc's axis."""
    if light.kind in (LightKind.POINT, LightKind.SPOT) and light.soft_falloff:
        return max(light.radius, 0.0)
    return 0.0


def soft_falloff(distance2: np.ndarray, radius: float | np.ndarray) -> np.ndarray:
    """What Soft Falloff of ``radius`` leaves of a light at squared distance ``distance2``
    from its centre: d² / (d² + r²) (1 for a radius of 0)."""
    r2 = np.square(radius)
    return np.divide(distance2, distance2 + r2, out=np.ones_like(distance2 * r2),
                     where=r2 > 0)


def spot_parameters(light: Light) -> tuple[float, float]:
    if light.kind is not LightKind.SPOT:
        return NO_SPOT, 0.0
    cos_half = float(np.cos(min(light.spot_size, np.pi) / 2))
    blend = float(np.clip(light.spot_blend, 0.0, 1.0))
    smooth = 1.0 / ((1.0 - cos_half) * blend) if blend > 0 and cos_half < 1 else 0.0
    return cos_half, smooth


def _add_light(b: _Builder, light: Light, s: Settings, rng: np.random.Generator) -> None:
    color = np.asarray(light.color, dtype=np.float64) * light.power
    m = light.matrix
    position, travel = m[:3, 3], unit(-m[:3, 2])
    profile = b.new_profile(light) if light.kind is not LightKind.SUN else -1
    if light.kind in (LightKind.POINT, LightKind.SPOT):
        spot_cos, spot_smooth = spot_parameters(light)
        if light.radius <= 0:
            b.add(position=position, axis=travel, kind=KIND_OMNI, intensity=color / (4 * np.pi),
                  shadow=light.cast_shadow, resolution=s.shadow_resolution,
                  spot_cos=spot_cos, spot_smooth=spot_smooth, profile=profile)
            return
        # A sphere of uniform radiance: one-sided cosine emitters on its surface.
        n = s.light_samples
        normals = fibonacci_sphere(n, rng)
        b.add(position=position + light.radius * normals, axis=normals, kind=KIND_COSINE,
              intensity=color / (np.pi * n), shadow=light.cast_shadow,
              resolution=s.sample_shadow_resolution, soft=True, spot_cos=spot_cos,
              spot_smooth=spot_smooth, soft_radius=soft_falloff_radius(light), profile=profile)
    elif light.kind is LightKind.SUN:
        half = 0.5 * min(light.sun_angle, np.pi)
        if half <= 0:
            b.add(position=position, axis=travel, kind=KIND_DIRECTIONAL, intensity=color,
                  shadow=light.cast_shadow, resolution=s.shadow_resolution)
            return
        n = s.light_samples
        u = fibonacci_square(n, rng)
        cos_t = 1.0 - u[:, 0] * (1.0 - np.cos(half))
        sin_t, phi = np.sqrt(np.maximum(0.0, 1 - cos_t**2)), 2 * np.pi * u[:, 1]
        local = np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), -cos_t], axis=1)
        b.add(position=np.repeat(position[None], n, 0), axis=unit(local @ m[:3, :3].T),
              kind=KIND_DIRECTIONAL, intensity=color / n, shadow=light.cast_shadow,
              resolution=s.shadow_resolution, soft=True)  # each map spans the whole scene
    elif light.kind is LightKind.AREA:
        n = s.light_samples
        u = stratified_square(n, rng)
        spread = spread_parameters(light)
        shape = -1
        if spread == (0.0, 0.0) and min(light.area_size) > 0 and profile < 0:  # Lambertian
            ring = area_light_outline(light)
            shape = b.new_shape(transform_points(m, np.hstack([ring, np.zeros((len(ring), 1))])))
        b.add(position=area_light_points(light, u), axis=travel, kind=KIND_COSINE,
              intensity=color / (np.pi * n), shadow=light.cast_shadow,
              resolution=s.sample_shadow_resolution, soft=True, spread=spread, shape=shape,
              profile=profile)


def _add_world(b: _Builder, scene: Scene, s: Settings, rng: np.random.Generator) -> None:
    """World samples: directions of a spherical Fibonacci lattice for a constant colour, or
    a Fibonacci lattice importance-sampled into the environment map (radiance / (n pdf)
    each: unbiased)."""
    radiance = scene.world.radiance
    n = s.world_samples
    env = scene.world.environment
    if env is None:
        sky, intensity = fibonacci_sphere(n, rng), radiance * 4 * np.pi / n
    else:
        sky, ratio = EnvironmentSampler(env).sample(fibonacci_square(n, rng))
        intensity = ratio / n
    b.add(position=np.zeros((n, 3)), axis=-sky, kind=KIND_DIRECTIONAL, intensity=intensity,
          shadow=True, resolution=s.sample_shadow_resolution, soft=True, broad=True)


def _add_emission(b: _Builder, geometry: WorldGeometry, s: Settings,
                  rng: np.random.Generator) -> None:
    emission = geometry.light_emission
    emitting = np.flatnonzero(emission.max(axis=1) > 0)
    if len(emitting) == 0:
        return
    tri = geometry.positions.reshape(-1, 3, 3)[emitting].astype(np.float64)
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    power = area * emission[emitting].mean(axis=1)
    if power.sum() <= 0:
        return
    n = s.emission_samples
    cdf = np.cumsum(power) / power.sum()
    pick = np.minimum(np.searchsorted(cdf, (np.arange(n) + rng.uniform()) / n), len(cdf) - 1)
    u = rng.uniform(size=(n, 2))
    flip = u.sum(axis=1) > 1
    u[flip] = 1 - u[flip]
    t = tri[pick]
    points = t[:, 0] + u[:, :1] * (t[:, 1] - t[:, 0]) + u[:, 1:] * (t[:, 2] - t[:, 0])
    probability = power[pick] / power.sum()
    intensity = emission[emitting][pick] * (area[pick] / (n * probability))[:, None]
    receivers, blockers = geometry.emission_receivers, geometry.emission_blockers
    b.add(position=points, axis=unit(cross[pick]), kind=KIND_COSINE2,
          intensity=intensity, shadow=True, resolution=s.sample_shadow_resolution, soft=True,
          receivers=EVERY_RECEIVER_SET if receivers is None else receivers[emitting][pick],
          blockers=EVERY_RECEIVER_SET if blockers is None else blockers[emitting][pick])


def light_problem(light: Light) -> str | None:
    """Why a light is left out (the message follows its name), or None when it is used."""
    values = [light.power, *light.color, light.radius, light.spot_size, light.spot_blend,
              light.sun_angle, light.size_x, light.size_y]
    if not np.isfinite(light.matrix).all() or not all(np.isfinite(values)):
        return "has NaN/Inf settings or transform and was left out"
    if abs(np.linalg.det(light.matrix[:3, :3])) < 1e-300:
        return "has a zero-scale transform and was left out"
    if light.power < 0:
        return f"has negative power ({light.power:g} W): rendered as 0 W"
    return None


def build_light_samples(scene: Scene, geometry: WorldGeometry, settings: Settings,
                        warnings: list[str], include_dark: bool = False) -> LightSamples:
    """All direct-light samples of the scene, deterministic for ``settings.seed``; lights of
    zero power and a black world have none unless ``include_dark``."""
    rng = np.random.default_rng(settings.seed)
    b = _Builder()
    for light in scene.surface_lights:
        problem = light_problem(light)
        if problem:
            warnings.append(f"light '{light.name}' {problem}")
            continue
        if light.kind is LightKind.AREA and light.spread < MIN_SPREAD:
            warnings.append(f"area light '{light.name}': spread below 1° is rendered as 1°")
        if light.kind is LightKind.AREA and min(light.area_size) <= 0:
            warnings.append(f"area light '{light.name}' has zero or negative size: lit as a "
                            f"point emitter of the same power")
        if include_dark or (light.power != 0 and any(c != 0 for c in light.color)):
            first_row = len(b.rows)
            _add_light(b, light, settings, rng)
            b.link(first_row, light)
    if include_dark or np.any(scene.world.radiance > 0):
        _add_world(b, scene, settings, rng)
    _add_emission(b, geometry, settings, rng)
    return b.build()
