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
    """Edge in texels of each cube face / directional shadow map of point, spot and sun lights."""
    sample_shadow_resolution: int = 256
    """Edge in texels of shadow maps of area-light, emission and world samples."""
    shadow_bias: float = 1.5
    """Receiver offset along its normal, in shadow-map texels (scale independent)."""
    antialiasing: int = 2
    """Supersampling factor per axis (1 = one sample per pixel)."""
    seed: int = 0
    """Seed of every stochastic choice; a render is deterministic for (scene, settings)."""

    _RANGES: ClassVar[dict[str, tuple[float, float]]] = {
        "light_samples": (1, 1024),
        "emission_samples": (1, 4096),
        "world_samples": (1, 1024),
        "shadow_resolution": (16, 8192),
        "sample_shadow_resolution": (16, 4096),
        "shadow_bias": (0.0, 64.0),
        "antialiasing": (1, 8),
        "seed": (0, 2**31 - 1),
    }

    def validate(self) -> Settings:
        """Return self, or raise SettingsError naming the first setting out of range."""
        for f in fields(self):
            low, high = self._RANGES[f.name]
            value = getattr(self, f.name)
            if not isinstance(value, int | float) or not (low <= value <= high):
                raise SettingsError(f"{f.name} = {value!r} is outside the supported range "
                                    f"[{low}, {high}]")
        return self
