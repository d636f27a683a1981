"""Spot lights under a non-uniform scale, as Cycles renders them: their cone stretched into an
elliptical one (Cycles' spot attenuation divides a direction's components along the light's
axes by the axes' scales before the cone test). VPL GI renders the stretched cone as an IES
profile of the light's mask (times the light's own profile, if any) within the round cone
around it, so the shaders, light paths and guidance read it as they read any profile."""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache

import numpy as np

from ..scene.ies import IesProfile
from ..scene.model import Light, LightKind
from .lights import spot_mask, spot_parameters

STRETCH_TOLERANCE = 1e-4  # relative difference of the axes' scales that stretches the cone
V_STEPS, H_STEPS = 721, 361  # the mask's table: 0.125° vertical over [0°, 90°], 1° horizontal


def axis_scales(matrix: np.ndarray) -> np.ndarray:
    """(3,) lengths of a light's x, y and z axes in the world (its matrix's columns)."""
    return np.linalg.norm(np.asarray(matrix, np.float64)[:3, :3], axis=0)


def stretch_spot(light: Light) -> Light:
    """``light`` as VPL GI renders it: a spot whose axes' scales differ gets its stretched
    cone as a profile, its own cone replaced by the round one around the stretched cone,
    with a hard edge (blend 0), where its paths start; any other light is returned
    unchanged."""
    if light.kind is not LightKind.SPOT:
        return light
    scales = axis_scales(light.matrix)
    if not np.all(np.isfinite(scales)) or scales.min() <= 0 \
            or scales.max() <= scales.min() * (1.0 + STRETCH_TOLERANCE):
        return light
    ratios = (float(scales[0] / scales[2]), float(scales[1] / scales[2]))
    size = float(np.clip(light.spot_size, 0.0, np.pi))
    profile = _stretched_mask(ratios, *spot_parameters(light), light.profile)
    around = 2.0 * float(np.arctan(np.tan(size / 2) * max(ratios))) if size < np.pi else np.pi
    return replace(light, profile=profile, spot_size=around, spot_blend=0.0)


def stretched_mask(local: np.ndarray, ratios: tuple[float, float], spot_cos: float,
                   spot_smooth: float) -> np.ndarray:
    """(n,) Cycles' spot mask towards unit directions ``local`` (n, 3) in the light's frame
    (it shines along -Z) for x and y axes ``ratios`` times as long as its z axis: the
    direction's components divided by them, normalised, its cosine to the axis masked as the
    round spot of ``spot_cos`` and ``spot_smooth`` (lights.spot_parameters) masks it."""
    local = np.asarray(local, np.float64)
    scaled = np.stack([local[..., 0] / ratios[0], local[..., 1] / ratios[1], -local[..., 2]],
                      -1)
    length = np.linalg.norm(scaled, axis=-1)
    cosine = np.divide(scaled[..., 2], length, out=np.zeros_like(length), where=length > 0)
    return spot_mask(cosine, spot_cos, spot_smooth)


@lru_cache(maxsize=64)
def _stretched_mask(ratios: tuple[float, float], spot_cos: float, spot_smooth: float,
                    profile: IesProfile | None) -> IesProfile:
    """The profile of a stretched cone (times ``profile``), made once for the same light
    (so what is cached per profile is too)."""
    v = np.linspace(0.0, np.pi / 2, V_STEPS)
    h = np.linspace(0.0, 2 * np.pi, H_STEPS)
    hh, vv = np.meshgrid(h, v, indexing="ij")
    local = IesProfile.direction(hh, np.cos(vv))
    intensity = stretched_mask(local, ratios, spot_cos, spot_smooth)
    if profile is not None:
        intensity = intensity * profile.at_angles(hh, vv)
    return IesProfile(h, v, intensity)
