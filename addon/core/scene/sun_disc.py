"""Sun discs in environment maps, taken out as sun lights: a map texel or a few hold a sun's
light, which world samples shadowed by scene-wide maps blur and leak, where a sun light of
the disc's size is ray traced (exact shadow edges) and starts light paths of its own.

A patch of an equirectangular map (Blender's layout, core/scene/environment.py) around its
brightest texel holds a disc where texels over SUN_CONTRAST times the patch's median form a
peak clear of the patch's edge that carries at least SUN_SHARE of the map's light. The light
gets the texels' irradiance (radiance × solid angle, summed), their brightness-weighted mean
direction and the angular diameter of a disc of their solid angle; the texels get the rest of
the patch's median, so the map and the light together hold the light once."""

from __future__ import annotations

import numpy as np

from .environment import equirect_directions, mean_radiance
from .model import EnvironmentMap, Light, LightKind

SUN_CONTRAST = 100.0
"""A peak whose texels are this many times brighter than the median around it is a sun disc."""
SUN_SHARE = 0.01
"""The least share of the map's light (∫ radiance dω over the sphere, RGB summed) a disc must
hold to be taken out as a sun light."""
WINDOW_DEGREES = 4.0  # the window around a map's brightest texel searched for a disc …
WINDOW_TEXELS = 16  # … at least this many texels wide (a 0.53° sun: 12 texels of an 8k map)


def peak_window(radiance: np.ndarray, texels: int) -> tuple[slice, np.ndarray]:
    """The rows and (wrapping) columns of the ``texels`` × ``texels`` window of a map
    centred on its brightest texel, kept inside the map's rows."""
    height, width = radiance.shape[:2]
    row, column = np.unravel_index(np.argmax(radiance.sum(axis=2)), (height, width))
    first_row = int(np.clip(row - texels // 2, 0, height - texels))
    columns = (np.arange(texels) + int(column) - texels // 2) % width
    return slice(first_row, first_row + texels), columns


def window_ranges(rows: slice, columns: np.ndarray, shape: tuple[int, ...]
                  ) -> tuple[tuple[float, float], tuple[float, float]]:
    """A window's (u, v) ranges in the map, u continuing past 1 where its columns wrap."""
    height, width = shape[:2]
    first = int(columns[0])
    return ((first / width, (first + len(columns)) / width),
            (rows.start / height, rows.stop / height))


def _patch_directions(u_range: tuple[float, float], v_range: tuple[float, float],
                      shape: tuple[int, int], rotation: float
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Unit directions (h, w, 3) of a patch's texel centres and their solid angles (h, 1)."""
    height, width = shape
    u = u_range[0] + (np.arange(width) + 0.5) / width * (u_range[1] - u_range[0])
    v = v_range[0] + (np.arange(height) + 0.5) / height * (v_range[1] - v_range[0])
    directions = equirect_directions(u[None, :], v[:, None], rotation)
    texel = (2 * np.pi * (u_range[1] - u_range[0]) / width) * (np.pi * (v_range[1] - v_range[0])
                                                               / height)
    return directions, texel * np.sin(np.pi * v)[:, None]


def _sun_matrix(towards: np.ndarray) -> np.ndarray:
    """A sun light's matrix: its local +Z towards the sun (it shines along -Z)."""
    z = towards / np.linalg.norm(towards)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    matrix = np.eye(4)
    matrix[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
    return matrix


def take_out_sun(patch: np.ndarray, u_range: tuple[float, float],
                 v_range: tuple[float, float], map_power: float, name: str,
                 rotation: float = 0.0) -> Light | None:
    """The sun disc in a patch (h, w, 3) covering ``u_range`` × ``v_range`` of a map turned by
    ``rotation`` about Z, as a sun light, its texels set to the rest of the patch's median (in
    place); None where there is none: nothing SUN_CONTRAST times the patch's median, a peak
    on the patch's edge (not compact), or one under SUN_SHARE of ``map_power``."""
    brightness = patch.sum(axis=2)
    disc = brightness > SUN_CONTRAST * np.median(brightness)
    if not disc.any() or disc[[0, -1]].any() or disc[:, [0, -1]].any():
        return None
    directions, solid = _patch_directions(u_range, v_range, brightness.shape, rotation)
    solid = np.broadcast_to(solid, brightness.shape)
    irradiance = (patch[disc] * solid[disc][:, None]).sum(axis=0).astype(np.float64)
    if irradiance.sum() < SUN_SHARE * map_power:
        return None
    towards = (directions[disc] * (brightness * solid)[disc][:, None]).sum(axis=0)
    diameter = 2 * np.arccos(1 - solid[disc].sum() / (2 * np.pi))
    patch[disc] = np.median(patch[~disc], axis=0)
    strength = float(irradiance.max())
    return Light(name, LightKind.SUN, _sun_matrix(towards),
                 color=tuple(float(c) for c in irradiance / strength), power=strength,
                 sun_angle=float(diameter))


def map_power(env: EnvironmentMap) -> float:
    """∫ radiance dω over the sphere, RGB summed."""
    return float(mean_radiance(env).sum() * 4 * np.pi)


def take_out_map_sun(env: EnvironmentMap, name: str) -> Light | None:
    """The sun disc of an environment map (in the window of WINDOW_DEGREES, at least
    WINDOW_TEXELS, around its brightest texel) as a sun light, taken out of the map in
    place; None where it has none."""
    radiance = env.radiance
    texels = min(radiance.shape[0], max(WINDOW_TEXELS,
                                        round(radiance.shape[1] * WINDOW_DEGREES / 360)))
    rows, columns = peak_window(radiance, texels)
    u_range, v_range = window_ranges(rows, columns, radiance.shape)
    patch = radiance[rows, columns]
    sun = take_out_sun(patch, u_range, v_range, map_power(env), name, env.rotation)
    if sun is not None:
        radiance[rows, columns] = patch
    return sun
