"""Equirectangular environment maps: Blender's mapping, lookups, importance sampling and the
background seen by camera rays.

Blender's equirectangular convention (rows bottom-up): a direction d looks up
u = 0.5 - atan2(d.y, d.x) / 2π, v = 0.5 + asin(d.z) / π, so the image centre faces +X and its
top row looks up. The map is piecewise constant for sampling: pixel (i, j) covers the solid
angle Ω_i = (2π / w)(sin φ_(i+1) - sin φ_i) between its elevations φ.
"""

from __future__ import annotations

import numpy as np

from .model import Camera, EnvironmentMap, World


def _row_elevations(height: int) -> np.ndarray:
    """sin(elevation) at the h + 1 row edges, bottom (-1) to top (+1)."""
    return -np.cos(np.pi * np.arange(height + 1) / height)


def pixel_solid_angles(height: int, width: int) -> np.ndarray:
    """(h,) solid angle of one pixel of each row; they sum to 4π over the image."""
    return np.diff(_row_elevations(height)) * (2 * np.pi / width)


def mean_radiance(env: EnvironmentMap) -> np.ndarray:
    """(3,) radiance averaged over the sphere (by solid angle)."""
    h, w, _ = env.radiance.shape
    weight = pixel_solid_angles(h, w)
    rows = env.radiance.astype(np.float64).sum(axis=1)
    return (weight @ rows) / (4 * np.pi)


def map_coordinates(env: EnvironmentMap, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(u, v) in [0, 1) × [0, 1] of unit world directions (n, 3)."""
    phi = np.arctan2(directions[:, 1], directions[:, 0]) + env.rotation
    u = (0.5 - phi / (2 * np.pi)) % 1.0
    v = 0.5 + np.arcsin(np.clip(directions[:, 2], -1.0, 1.0)) / np.pi
    return u, v


def equirect_directions(u: np.ndarray, v: np.ndarray, rotation: float = 0.0) -> np.ndarray:
    """Unit world directions (..., 3) at map coordinates ``u``, ``v`` (broadcast together) of
    a map turned by ``rotation``: the inverse of map_coordinates."""
    azimuth = 2 * np.pi * (0.5 - np.asarray(u)) - rotation
    elevation = np.pi * (np.asarray(v) - 0.5)
    return np.stack(np.broadcast_arrays(np.cos(elevation) * np.cos(azimuth),
                                        np.cos(elevation) * np.sin(azimuth),
                                        np.sin(elevation)), -1)


def lookup(env: EnvironmentMap, directions: np.ndarray) -> np.ndarray:
    """(n, 3) bilinearly interpolated radiance (Blender's default Linear interpolation)."""
    h, w, _ = env.radiance.shape
    u, v = map_coordinates(env, directions)
    x, y = u * w - 0.5, np.clip(v * h - 0.5, 0.0, h - 1.0)
    x0, y0 = np.floor(x).astype(np.int64), np.minimum(np.floor(y).astype(np.int64), h - 2)
    y0 = np.maximum(y0, 0)
    fx, fy = (x - x0)[:, None], np.clip(y - y0, 0.0, 1.0)[:, None]
    x0, x1 = x0 % w, (x0 + 1) % w
    y1 = np.minimum(y0 + 1, h - 1)
    m = env.radiance
    return ((m[y0, x0] * (1 - fx) + m[y0, x1] * fx) * (1 - fy)
            + (m[y1, x0] * (1 - fx) + m[y1, x1] * fx) * fy)


class EnvironmentSampler:
    """Piecewise-constant importance sampling of a map by the mean of its RGB channels:
    a marginal CDF over rows (weighted by each pixel's solid angle) and conditional CDFs over
    columns. The density per solid angle is exactly weight(pixel) / Σ weight·Ω."""

    def __init__(self, env: EnvironmentMap) -> None:
        self.env = env
        h, w, _ = env.radiance.shape
        self.edges = _row_elevations(h)
        self.solid_angle = pixel_solid_angles(h, w)
        weight = np.maximum(env.radiance.astype(np.float64).mean(axis=2), 0.0)
        mass = weight * self.solid_angle[:, None]
        self.total = float(mass.sum())
        row_mass = mass.sum(axis=1)
        self.row_probability = row_mass / self.total if self.total > 0 else np.full(h, 1 / h)
        self.row_cdf = np.cumsum(self.row_probability)
        safe = np.where(row_mass > 0, row_mass, 1.0)[:, None]
        column = np.where(row_mass[:, None] > 0, mass / safe, 1.0 / w)
        self.column_probability = column
        # Rows offset by 2 make one increasing array, searched for all samples at once.
        self.column_cdf = (np.cumsum(column, axis=1) + 2 * np.arange(h)[:, None]).ravel()
        self.weight = weight

    def sample(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Directions (n, 3) for points u (n, 2) in [0, 1)² (their stratification carries over
        to the sphere) and the radiance there over its density per solid angle (n, 3)."""
        h, w, _ = self.env.radiance.shape
        below = np.nextafter(1.0, 0.0)
        row = np.minimum(np.searchsorted(self.row_cdf, u[:, 0], side="right"), h - 1)
        p_row = self.row_probability[row]
        f_row = np.clip((u[:, 0] - (self.row_cdf[row] - p_row)) / np.maximum(p_row, 1e-300),
                        0.0, below)
        flat = np.searchsorted(self.column_cdf, 2 * row + u[:, 1], side="right")
        col = np.clip(flat - row * w, 0, w - 1)
        p_col = self.column_probability[row, col]
        low = self.column_cdf[row * w + col] - 2 * row - p_col
        f_col = np.clip((u[:, 1] - low) / np.maximum(p_col, 1e-300), 0.0, below)
        z = self.edges[row] + f_row * (self.edges[row + 1] - self.edges[row])
        phi = 2 * np.pi * (0.5 - (col + f_col) / w) - self.env.rotation
        r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
        directions = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
        radiance = self.env.radiance[row, col].astype(np.float64)
        weight = self.weight[row, col][:, None]
        ratio = np.divide(radiance * self.total, weight, out=np.zeros_like(radiance),
                          where=weight > 0)
        return directions, ratio


def camera_directions(camera: Camera, aa: int, x0: int, y0: int, width: int, height: int
                      ) -> np.ndarray:
    """(height, width, 3) unit directions of the camera rays through the centres of the
    supersampled pixels [x0, x0 + width) × [y0, y0 + height) (rows bottom-up, as OpenGL)."""
    full_w, full_h = camera.width * aa, camera.height * aa
    x = 2 * (x0 + np.arange(width) + 0.5) / full_w - 1
    y = 2 * (y0 + np.arange(height) + 0.5) / full_h - 1
    gx, gy = np.meshgrid(x, y)
    return camera.rays(np.stack([gx, gy], axis=-1))[1]


def background(world: World, camera: Camera, aa: int, x0: int, y0: int, width: int,
               height: int) -> np.ndarray:
    """Radiance seen by the camera rays of a supersampled tile that miss every surface:
    (height, width, 3) float32 from the environment map and the sun disc taken out of it (its
    light's irradiance over its solid angle), or from what the world shows the camera instead
    (``World.background``), or the world colour (3,)."""
    shown = world.environment if world.background is None else world.background
    if shown is None:
        return world.radiance.astype(np.float32)
    d = camera_directions(camera, aa, x0, y0, width, height).reshape(-1, 3)
    radiance = lookup(shown, d)
    sun = world.visible_sun
    if sun is not None:
        half = sun.sun_angle / 2
        inside = d @ sun.matrix[:3, 2] > np.cos(half)
        disc = np.asarray(sun.color) * sun.power / (2 * np.pi * (1 - np.cos(half)))
        radiance[inside] = disc
    return radiance.reshape(height, width, 3).astype(np.float32)
