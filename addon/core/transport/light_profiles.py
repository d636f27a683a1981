"""Lights' IES profiles for the shaders (lights_lib.glsl's ``light_profile``): each profile
sampled on an even grid of its angles, looked up bilinearly, and each light's frame, which
turns a world direction into the profile's angles."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..scene.ies import IesProfile
from ..scene.model import Light

V_SAMPLES = 181  # vertical angles 0-180°, 1° apart
H_SAMPLES = 181  # horizontal angles 0-360°, 2° apart


@dataclass(frozen=True)
class LightProfiles:
    """``frames`` (k, 3, 4) float32, one per profiled light: texels 0-2 hold the rows of its
    world-to-light rotation, texel 0's w the first row of its profile in ``grid``.
    ``grid`` (rows, V_SAMPLES) float32: each profile's H_SAMPLES rows of ``IesProfile.grid``
    (lights with the same profile share them). ``lights``: the profiled lights."""

    frames: np.ndarray
    grid: np.ndarray
    lights: tuple[Light, ...]

    @staticmethod
    def build(lights: list[Light]) -> LightProfiles:
        """For lights that all have a profile, in the order their samples name them."""
        first_row: dict[bytes, int] = {}
        blocks: list[np.ndarray] = []
        frames = np.zeros((len(lights), 3, 4), np.float32)
        for k, light in enumerate(lights):
            profile: IesProfile = light.profile
            if profile.key not in first_row:
                first_row[profile.key] = H_SAMPLES * len(blocks)
                blocks.append(_grid(profile))
            frames[k, :, :3] = light.frame.T
            frames[k, 0, 3] = first_row[profile.key]
        return LightProfiles(frames, np.concatenate(blocks).astype(np.float32), tuple(lights))


@lru_cache(maxsize=64)
def _grid(profile: IesProfile) -> np.ndarray:
    """The shaders' grid of a profile (made once per profile, not per frame)."""
    return profile.grid(V_SAMPLES, H_SAMPLES)


@lru_cache(maxsize=64)
def profile_sampler(profile: IesProfile) -> ProfileSampler:
    """The path sampler of a profile (its table made once per profile, not per frame)."""
    return ProfileSampler(profile)


def profile_towards(light: Light, directions: np.ndarray) -> np.ndarray:
    """(n,) what a light's profile multiplies its light by towards world ``directions``
    (n, 3) (unit, away from the light); 1 without a profile."""
    if light.profile is None:
        return np.ones(len(directions))
    return light.profile.towards(np.asarray(directions, np.float64) @ light.frame)


class ProfileSampler:
    """Directions of a point light's paths drawn in proportion to its IES profile: a table of
    cells even in cos(vertical angle) and horizontal angle (equal solid angles), each drawn
    with the largest of the profile at its centre and corners (so no lit direction is left
    out) plus 1 % of the profile's mean, uniformly within it."""

    CELLS = 64, 128  # cos(vertical angle), horizontal angle

    def __init__(self, profile: IesProfile) -> None:
        self.profile = profile
        nz, nh = self.CELLS
        z = np.linspace(-1.0, 1.0, 2 * nz + 1)  # cos v: corners at even, centres at odd
        h = np.linspace(0.0, 2 * np.pi, 2 * nh + 1)
        values = profile.at_angles(h[None, :], np.arccos(z)[:, None])
        corners = [values[dz:2 * nz + dz:2, dh:2 * nh + dh:2] for dz in (0, 1, 2)
                   for dh in (0, 1, 2)]
        weight = np.max(corners, axis=0) + 0.01 * profile.mean
        self.cdf = np.cumsum(weight.ravel()) / weight.sum()
        self.pdf = weight.ravel() / weight.sum() * (nz * nh) / (4 * np.pi)  # per steradian

    def sample(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unit directions (n, 3) in the light's frame for ``u`` (n, 3) in [0, 1), and each
        one's profile over 4π times its density: what a path carries of the light's colour
        × power (1 everywhere for a uniform profile drawn uniformly)."""
        nz, nh = self.CELLS
        cell = np.minimum(np.searchsorted(self.cdf, u[:, 0], side="right"), nz * nh - 1)
        row, column = np.divmod(cell, nh)
        cos_v = -1.0 + 2.0 * (row + u[:, 1]) / nz
        h = 2 * np.pi * (column + u[:, 2]) / nh
        local = IesProfile.direction(h, cos_v)
        weight = self.profile.at_angles(h, np.arccos(cos_v)) / (4 * np.pi * self.pdf[cell])
        return local, weight
