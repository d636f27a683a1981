"""Render settings of the engine, validated in one place with messages a user can act on."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import ClassVar


class SettingsError(ValueError):
    """A setting is outside the range the engine supports."""


@dataclass(frozen=True)
class Settings:
    """All user-facing parameters of one render. Ranges are checked by :meth:`validate`."""

    light_samples: int = 16
    """Point samples per area light, per sphere light (radius > 0) and per sun with an angle."""
    emission_samples: int = 64
    """Point samples spread over all emissive surfaces (by emitted power)."""
    world_samples: int = 64
    """Directions the world colour is sampled in, each with its own shadow map."""
    shadow_resolution: int = 1024
    """Edge in texels of each cube face / directional shadow map of point, spot and sun lights
    (each of a sun's angle samples too: its map spans the whole scene)."""
    sample_shadow_resolution: int = 256
    """Edge in texels of shadow maps of area-light, sphere-light, emission and world samples."""
    shadow_bias: float = 1.5
    """Receiver offset along its normal, in shadow-map texels (scale independent)."""
    antialiasing: int = 2
    """Supersampling factor per axis (1 = one sample per pixel)."""
    seed: int = 0
    """Seed of every stochastic choice; a render is deterministic for (scene, settings)."""
    bounces: int = 4
    """Diffuse bounces, as Cycles counts them: 0 = direct light only."""
    vpl_count: int = 1024
    """Light paths started per frame; each leaves a VPL at every bounce it survives."""
    vpl_source: str = "paths"
    """Where VPLs come from: 'paths' (light tracing, every bounce) or 'rsm' (reflective
    shadow maps of the lights, importance-sampled by reflected flux; one bounce only)."""
    rsm_resolution: int = 128
    """Texels per edge of each reflective-shadow-map face (vpl_source = 'rsm')."""
    termination: str = "fractional"
    """How light paths end: 'fractional' absorption by the average reflectance (the seed's
    scheme: N paths start, ρ̄N continue, ...) or per-path 'roulette'."""
    visibility: str = "ism"
    """VPL visibility: 'ism' (imperfect shadow maps: point-splatted paraboloid maps, the fast
    default), 'classic' (a triangle cube shadow map per VPL) or 'exact' (ray traced)."""
    vpl_shadow_resolution: int = 256
    """Texels per cube-face edge of each VPL's shadow map (classic visibility)."""
    clamp_distance: float = 0.05
    """VPL distances below this fraction of the scene's radius are clamped (0 = no clamp):
    bounds the 1/d² singularity of the geometry term."""
    bias_compensation: bool = False
    """Restore the energy the clamp removes (Kollig & Keller 2004: ray traced)."""
    bias_samples: int = 16
    """Rays per pixel for bias compensation."""
    interleave: int = 4
    """Interleaved sampling of VPLs: each pixel of a K×K pattern gathers every K²-th VPL
    (1 = off; 2, 4, 8)."""
    blur_radius: int = 4
    """Radius in (supersampled) pixels of the geometry-aware blur that removes the interleaving
    pattern; rounded up to a multiple of K/2 so the pattern cancels exactly on flat surfaces."""
    soft_light_ism: bool = False
    """Shadows of the samples of area lights, sphere lights, suns with an angle and the world
    from imperfect shadow maps instead of triangle shadow maps (the seed's extension to direct
    light: soft shadows and natural illumination from many point lights)."""
    ism_points: int = 8192
    """Surface points splatted into each VPL's imperfect shadow map."""
    ism_resolution: int = 128
    """Texels per edge of each imperfect shadow map (paraboloid, one per VPL)."""
    incremental: bool = False
    """Incremental Instant Radiosity: reuse last frame's VPLs (and their shadow maps) where the
    lights still reach them; only invalid ones and a few redistributed ones are new. For
    animations rendered in order in one process and the viewport; off, every frame is made
    afresh (the same image whichever machine renders the frame)."""
    incremental_budget: int = 8
    """VPLs per light moved per frame from the most crowded place to the emptiest one
    (beyond replacing invalid VPLs, which always happens at once)."""
    pull_push_levels: int = 7
    """Pull-push levels that fill the holes between splatted points (capped at
    log2(ism_resolution), which fills every hole)."""
    auto_parameters: str = "off"
    """Choose vpl_count, ism_points, ism_resolution, interleave and blur_radius automatically:
    'off', 'time' (least predicted error within time_budget) or 'error' (least predicted
    time within target_error), from a cost model measured once on this machine."""
    time_budget: float = 2.0
    """Seconds per frame the automatic mode 'time' aims at."""
    target_error: float = 0.1
    """Relative RMSE against a converged image that the automatic mode 'error' aims at."""
    planner: bool = True
    """Leave out work the frame does not need (lights that cannot reach the view, a black
    world, pull-push levels the point density does not need, passes not asked for, work kept
    from the last frame). Off runs every stage: for comparisons only."""

    _RANGES: ClassVar[dict[str, tuple[float, float]]] = {
        "light_samples": (1, 1024),
        "emission_samples": (1, 4096),
        "world_samples": (1, 1024),
        "shadow_resolution": (16, 8192),
        "sample_shadow_resolution": (16, 4096),
        "shadow_bias": (0.0, 64.0),
        "antialiasing": (1, 8),
        "seed": (0, 2**31 - 1),
        "bounces": (0, 64),
        "vpl_count": (1, 1 << 16),
        "vpl_shadow_resolution": (16, 2048),
        "clamp_distance": (0.0, 1.0),
        "bias_samples": (1, 1024),
        "blur_radius": (1, 32),
        "ism_points": (16, 1 << 16),
        "pull_push_levels": (0, 12),
        "incremental_budget": (0, 1024),
        "time_budget": (0.01, 86400.0),
        "target_error": (0.001, 10.0),
    }
    _CHOICES: ClassVar[dict[str, tuple[str, ...]]] = {
        "termination": ("fractional", "roulette"),
        "visibility": ("ism", "classic", "exact"),
        "ism_resolution": (32, 64, 128, 256, 512),
        "interleave": (1, 2, 4, 8),
        "vpl_source": ("paths", "rsm"),
        "rsm_resolution": (32, 64, 128, 256, 512),
        "auto_parameters": ("off", "time", "error"),
    }

    def validate(self) -> Settings:
        """Return self, or raise SettingsError naming the first setting out of range."""
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in self._CHOICES:
                if value not in self._CHOICES[f.name]:
                    raise SettingsError(f"{f.name} = {value!r} is not one of "
                                        f"{', '.join(self._CHOICES[f.name])}")
            elif isinstance(value, bool) or f.name not in self._RANGES:
                if not isinstance(value, bool):
                    raise SettingsError(f"{f.name} = {value!r} must be true or false")
            else:
                low, high = self._RANGES[f.name]
                if not isinstance(value, int | float) or not (low <= value <= high):
                    raise SettingsError(f"{f.name} = {value!r} is outside the supported range "
                                        f"[{low}, {high}]")
        return self
