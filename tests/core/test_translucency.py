"""Translucent surfaces (Material.translucency, Cycles' Translucent BSDF): the share t of the
diffuse light a surface lets through leaves its other side, directly lit or from VPLs, and
light paths cross to the far side with it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from addon.core.scene.model import Instance, LightKind, Material, Scene, World
from addon.core.settings import Settings
from tests.core.builders import (
    floor_scene,
    light,
    quad,
    rotation_x,
    top_down_camera,
    traced_vpls,
    translation,
)

SUN_STRENGTH = 3.0
CENTRE = (slice(24, 40), slice(24, 40))  # the middle of the 64² top-down view


def sun(from_below: bool = False):
    """A sun straight down (or straight up: it lights the floor's underside)."""
    return light(LightKind.SUN, rotation_x(np.pi if from_below else 0.0), power=SUN_STRENGTH)


def leaf_floor(translucency: float, from_below: bool) -> Scene:
    """The floor alone, translucent by ``translucency``, in a sun from above or below."""
    floor = Instance(quad(5, 5), np.eye(4), [Material("leaf", (0.8,) * 3,
                                                        translucency=(translucency,) * 3)])
    return Scene([floor], [sun(from_below)], World(), top_down_camera())


@pytest.mark.parametrize("visibility", ["ism", "classic", "exact"])
@pytest.mark.parametrize("translucency", [0.0, 0.3, 1.0])
def test_direct_light_leaves_a_translucent_surface_on_both_sides(renderer, visibility,
                                                                 translucency):
    """Sunlit from the camera's side the floor shows (1 − t) of its light, from the far side
    t of it, in every visibility mode (the far side's shadows by rays where shadow hints
    would serve the near side's)."""
    settings = Settings(bounces=0, antialiasing=1, visibility=visibility)
    light_seen = {}
    for from_below in (False, True):
        frame, _ = renderer.render(leaf_floor(translucency, from_below), settings)
        light_seen[from_below] = frame.passes["DiffDir"][CENTRE].mean(axis=(0, 1))
    open_sun = SUN_STRENGTH / math.pi  # DiffDir: irradiance / pi
    np.testing.assert_allclose(light_seen[False], (1 - translucency) * open_sun, rtol=1e-3,
                               atol=1e-4)
    np.testing.assert_allclose(light_seen[True], translucency * open_sun, rtol=1e-3, atol=1e-4)


def square_view_factor(half: float, height: float) -> float:
    """The view factor from a point to a square of half-width ``half`` centred ``height``
    above it, parallel (four rectangles meeting over the point)."""
    a = half / height
    root = math.sqrt(1 + a * a)
    return 4 * (2 * a / root * math.atan(a / root)) / (2 * math.pi)


def canopy(translucency: float) -> Scene:
    """A grey floor under a sunlit translucent canopy (2 m square, 0.5 m up, unseen by the
    camera)."""
    leaf = Material("leaf", (0.6,) * 3, translucency=(translucency,) * 3)
    panel = Instance(quad(1, 1), translation(0, 0, 0.5), [leaf], visible_to_camera=False)
    return floor_scene([sun()], extra=[panel])


@pytest.mark.parametrize("visibility", ["ism", "exact"])
def test_light_let_through_a_canopy_lights_the_floor_under_it(renderer, visibility):
    """One bounce: the floor under the canopy gets the light its far side lets through, ρ t
    S F / π in DiffInd (F the view factor of the canopy from the floor's centre), and none
    when it lets none through."""
    settings = Settings(bounces=1, antialiasing=1, vpl_count=4096, visibility=visibility,
                        seed=3)
    under = (slice(30, 34), slice(30, 34))
    light_under = {}
    for t in (0.0, 1.0):
        frame, _ = renderer.render(canopy(t), settings)
        light_under[t] = frame.passes["DiffInd"][under].mean()
        assert frame.passes["DiffDir"][under].max() < 1e-4  # the canopy's shadow
    expected = 0.6 * SUN_STRENGTH / math.pi * square_view_factor(1.0, 0.5)
    assert light_under[1.0] == pytest.approx(expected, rel=0.06), (light_under, expected)
    assert light_under[0.0] < 0.02 * expected


@pytest.mark.parametrize("incremental", [False, True])
def test_light_paths_leave_far_side_vpls_with_the_light_let_through(renderer, incremental):
    """At the canopy (t = 0.25) each path's VPL splits: (1 − t) of its light on the lit side,
    t on the far side around the reversed normal, marked far_side, with keys of their own in
    Incremental Instant Radiosity."""
    settings = Settings(bounces=1, vpl_count=2048, incremental=incremental, seed=5)
    vpls = traced_vpls(renderer, canopy(0.25), settings)
    at_canopy = np.abs(vpls.position[:, 2] - 0.5) < 1e-3
    far = vpls.far_side
    assert far is not None and far[at_canopy].any() and not far[~at_canopy].any()
    near = at_canopy & ~far
    np.testing.assert_allclose(vpls.normal[near], [[0, 0, 1]] * int(near.sum()), atol=1e-6)
    np.testing.assert_allclose(vpls.normal[far], [[0, 0, -1]] * int(far.sum()), atol=1e-6)
    assert vpls.intensity[far].sum() == pytest.approx(vpls.intensity[near].sum() / 3, rel=1e-6)
    if incremental:
        assert len(np.unique(vpls.key)) == len(vpls)


def test_paths_cross_a_translucent_canopy_with_the_light_it_lets_through(renderer):
    """Two bounces: the floor under the canopy gets second-bounce VPLs from paths that crossed
    it, carrying ρ t of the light on average (their flux weighted by the chance to cross)."""
    settings = Settings(bounces=2, vpl_count=8192, seed=7, termination="roulette")
    counts = {}
    for t in (0.0, 1.0):
        vpls = traced_vpls(renderer, canopy(t), settings)
        second = vpls.generation == 2
        under = second & (np.abs(vpls.position[:, :2]).max(axis=1) < 1) \
            & (vpls.position[:, 2] < 0.25)
        counts[t] = vpls.intensity[under].sum()
    assert counts[0.0] < 0.05 * counts[1.0]


@pytest.mark.parametrize("incremental", [False, True])
def test_a_layered_translucent_leaf_lights_its_far_side(renderer, incremental):
    """A translucent leaf that is also glossy, rough and coated (a Principled BSDF mixed with a
    Translucent BSDF): every pixel finite, its far side lit by t of the sun with light paths
    crossing it, in final renders and Incremental Instant Radiosity."""
    leaf = Material("leaf", (0.5, 0.7, 0.3), roughness=0.4, specular_ior_level=0.5,
                    diffuse_roughness=0.6, coat_weight=0.3, translucency=(0.4, 0.4, 0.4))
    floor = Instance(quad(5, 5), np.eye(4), [leaf])
    scene = Scene([floor], [sun(from_below=True)], World(), top_down_camera())
    settings = Settings(bounces=2, antialiasing=1, vpl_count=256, incremental=incremental)
    frame, _ = renderer.render(scene, settings)
    assert all(np.isfinite(p).all() for p in frame.passes.values())
    assert frame.passes["DiffDir"][CENTRE].mean() == pytest.approx(
        0.4 * SUN_STRENGTH / math.pi, rel=0.05)
