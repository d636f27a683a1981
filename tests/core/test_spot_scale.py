"""Spot lights under a non-uniform scale (transport/spot_scale.py): the stretched cone's profile
against Cycles' spot attenuation written out from its kernel's formula, and the round cone
the light's paths start in. The render against Cycles is in
tests/blender/test_light_strength.py (an elliptical spot: relRMSE 3.8 %, the round one 113 %)."""

from __future__ import annotations

import numpy as np

from addon.core.scene.model import LightKind
from addon.core.transport.light_profiles import profile_towards
from addon.core.transport.lights import spot_mask, spot_parameters
from addon.core.transport.spot_scale import stretch_spot
from tests.core.builders import light

SCALE = np.array([1.8, 0.8, 1.2])


def _turned_matrix(scale: np.ndarray) -> np.ndarray:
    """A light 2 m up, turned 30° about Z and 15° about X, scaled by ``scale``."""
    a, b = np.radians(30.0), np.radians(15.0)
    about_z = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    about_x = np.array([[1, 0, 0], [0, np.cos(b), -np.sin(b)], [0, np.sin(b), np.cos(b)]])
    matrix = np.eye(4)
    matrix[:3, :3] = about_z @ about_x @ np.diag(scale)
    matrix[:3, 3] = (0.0, 0.0, 2.0)
    return matrix


def _cycles_attenuation(matrix: np.ndarray, size: float, blend: float,
                        directions: np.ndarray) -> np.ndarray:
    """Cycles' spot attenuation towards world ``directions``: their components along the
    light's unit x and y axes and its direction of travel (-Z), each over that axis' length,
    normalised; smoothstep of the cosine past the half angle over (1 - cos) × blend."""
    columns = matrix[:3, :3]
    lengths = np.linalg.norm(columns, axis=0)
    axes = columns / lengths
    scaled = np.stack([directions @ axes[:, 0] / lengths[0], directions @ axes[:, 1] / lengths[1],
                       directions @ -axes[:, 2] / lengths[2]], 1)
    cosine = scaled[:, 2] / np.linalg.norm(scaled, axis=1)
    cos_half = np.cos(size / 2)
    x = np.clip((cosine - cos_half) / ((1 - cos_half) * blend), 0.0, 1.0)
    return x * x * (3 - 2 * x)


def _directions(count: int, seed: int) -> np.ndarray:
    d = np.random.default_rng(seed).normal(size=(count, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def test_a_stretched_cone_is_cycles_attenuation():
    """Towards the lit ones of 20,000 random directions the stretched spot's light (its
    round cone's hard mask times its profile) is Cycles' attenuation within 0.002 on
    average and 0.03 at worst (measured: under 0.0001 and 0.017; the profile's table is
    0.125° by 1°); the same spot unstretched differs by far more."""
    size, blend = np.radians(50.0), 0.3
    matrix = _turned_matrix(SCALE)
    spot = light(LightKind.SPOT, matrix, spot_size=size, spot_blend=blend)
    stretched = stretch_spot(spot)
    directions = _directions(20000, 0)
    cos_half, smooth = spot_parameters(stretched)
    frame = stretched.frame
    ours = spot_mask(directions @ -frame[:, 2], cos_half, smooth) \
        * profile_towards(stretched, directions)
    cycles = _cycles_attenuation(matrix, size, blend, directions)
    lit = (cycles > 0) | (ours > 0)
    assert cycles.max() == 1.0 and lit.sum() > 500
    difference = np.abs(ours - cycles)[lit]
    assert difference.mean() < 0.002 and difference.max() < 0.03
    round_cos, round_smooth = spot_parameters(spot)
    unstretched = spot_mask(directions @ -frame[:, 2], round_cos, round_smooth)
    assert np.abs(unstretched - cycles)[lit].mean() > 10 * difference.mean()


def test_the_round_cone_holds_the_stretched_one():
    """Every direction the stretched cone lights lies inside the round cone its paths start
    in, which is as wide as the cone's longest axis (1.8 / 1.2 times its half angle's
    tangent)."""
    size = np.radians(50.0)
    matrix = _turned_matrix(SCALE)
    stretched = stretch_spot(light(LightKind.SPOT, matrix, spot_size=size, spot_blend=0.0))
    expected = 2 * np.arctan(np.tan(size / 2) * 1.8 / 1.2)
    assert np.isclose(stretched.spot_size, expected) and stretched.spot_blend == 0.0
    directions = _directions(20000, 1)
    lit = _cycles_attenuation(matrix, size, 1e-9, directions) > 0
    cos_to_axis = directions @ -stretched.frame[:, 2]
    assert lit.any() and np.all(cos_to_axis[lit] >= np.cos(stretched.spot_size / 2) - 1e-9)


def test_uniform_scales_and_other_lights_are_left_alone():
    """A spot scaled alike on every axis, or a point light scaled unevenly, is the light
    itself: no profile, its own cone."""
    spot = light(LightKind.SPOT, _turned_matrix(np.array([2.0, 2.0, 2.0])))
    assert stretch_spot(spot) is spot
    point = light(LightKind.POINT, _turned_matrix(SCALE))
    assert stretch_spot(point) is point
