"""Light linking in the renderer: an emitter lights the surfaces of the receiver sets its
``receivers`` bits name (Instance.receiver_set), directly and through their bounces, and no
others (the Blender side, and the comparison with Cycles: tests/blender/test_light_linking.py)."""

from __future__ import annotations

import numpy as np
import pytest

from addon.core.frame.gather import draws, mask_words
from addon.core.scene.geometry import flatten_instances
from addon.core.scene.model import EVERY_RECEIVER_SET, Instance, LightKind, Material, Scene, World
from addon.core.settings import Settings
from addon.core.transport.lights import build_light_samples
from tests.core.builders import (
    floor_scene,
    icosphere,
    inside_sphere_camera,
    light,
    quad,
    traced_vpls,
    translation,
)

ONLY_SET_1 = 1 << 1
LAMP = light(LightKind.POINT, translation(0, 0, 2), power=200.0, receivers=ONLY_SET_1)


def halves(right_set: int = 0) -> list[Instance]:
    """A floor of two halves: x < 0 in receiver set 1, x > 0 in ``right_set``."""
    grey = [Material("floor", (0.8, 0.8, 0.8))]
    return [Instance(quad(2.5, 5), translation(-2.5, 0, 0), grey, receiver_set=1),
            Instance(quad(2.5, 5), translation(2.5, 0, 0), grey, receiver_set=right_set)]


@pytest.mark.parametrize("shadows", ["hybrid", "ray_traced", "shadow_maps"])
def test_a_linked_light_lights_only_its_receivers(renderer, shadows):
    """Its direct light falls on the set-1 half only; unlinked, on both alike."""
    settings = Settings(bounces=0, antialiasing=1, direct_shadows=shadows)
    scene = Scene(halves(), [LAMP], World(), floor_scene([]).camera)
    frame, _ = renderer.render(scene, settings)
    direct = frame.passes["DiffDir"][..., 0]
    left, right = direct[16:48, 8:28], direct[16:48, 36:56]
    assert left.mean() > 0.05 and right.max() == 0.0
    scene.lights = [light(LightKind.POINT, translation(0, 0, 2), power=200.0)]
    frame, _ = renderer.render(scene, settings)
    direct = frame.passes["DiffDir"][..., 0]
    np.testing.assert_allclose(direct[16:48, 8:28], direct[16:48, 36:56][:, ::-1], rtol=0.02)


def test_an_emitters_light_bounces_only_from_its_receivers(renderer):
    """A red wall in set 1 over a floor in set 0, lit by a sun linked to set 1: the floor gets
    the wall's red bounce light and no sunlight; linked to set 0 only, the wall bounces none."""
    red = Instance(quad(5, 1), translation(0, 2, 1) @ _facing_minus_y(), [Material(
        "wall", (0.8, 0.1, 0.1))], receiver_set=1)
    floor = floor_scene([]).instances[0]
    sun = light(LightKind.SUN, _facing_minus_y(-0.6), power=3.0, receivers=ONLY_SET_1)
    settings = Settings(bounces=1, antialiasing=1, vpl_count=512)
    frame, _ = renderer.render(Scene([floor, red], [sun], World(), floor_scene([]).camera),
                               settings)
    floor_only = slice(0, 48)  # y < 1.6: the wall (y = 2) shows beyond
    assert frame.passes["DiffDir"][floor_only].max() == 0.0
    bounce = frame.passes["DiffInd"][8:40, 8:56]
    assert bounce[..., 0].mean() > 0.01 and bounce[..., 0].mean() > 3 * bounce[..., 1].mean()
    sun.receivers = 1 << 0
    frame, _ = renderer.render(Scene([floor, red], [sun], World(), floor_scene([]).camera),
                               settings)
    assert frame.passes["DiffDir"][floor_only].mean() > 0.1
    assert frame.passes["DiffInd"][floor_only].max() == 0.0


def _facing_minus_y(tilt: float = 0.0) -> np.ndarray:
    """A rotation about x turning +Z to -Y (a wall facing -y), ``tilt`` further (a sun
    turned by -0.6 travels towards +y and down)."""
    angle = np.pi / 2 + tilt
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1]], float)


def closed_halves() -> Scene:
    """A closed sphere whose upper half (z > 0) is in receiver set 1, the lower in set 0,
    with a linked point light at its centre."""
    sphere = icosphere(2.0, 3)
    tri = sphere.positions.reshape(-1, 3, 3)
    upper = tri.mean(axis=1)[:, 2] > 0
    parts = []
    for keep, receiver_set in ((upper, 1), (~upper, 0)):
        mesh = type(sphere)("half", np.ascontiguousarray(tri[keep].reshape(-1, 3)),
                            np.ascontiguousarray(sphere.normals.reshape(-1, 3, 3)[keep]
                                                 .reshape(-1, 3)),
                            np.zeros(int(keep.sum()), np.int32))
        parts.append(Instance(mesh, np.eye(4), [Material("wall", (0.5,) * 3)],
                              receiver_set=receiver_set))
    return Scene(parts, [light(LightKind.POINT, np.eye(4), power=100.0, receivers=ONLY_SET_1)],
                 World(), inside_sphere_camera())


@pytest.mark.parametrize("incremental", [False, True])
def test_light_paths_leave_first_bounce_vpls_only_on_receivers(renderer, incremental):
    """Every path hits the sphere; those that hit the unlinked half end there: the first
    bounce keeps about half the light's power, all on the upper half."""
    vpls = traced_vpls(renderer, closed_halves(),
                       Settings(vpl_count=512, bounces=2, incremental=incremental))
    first = vpls.generation == 1
    assert (vpls.position[first, 2] > -1e-6).all()
    assert (vpls.position[~first, 2] < 0).any()  # their light bounces on everywhere
    flux = float((vpls.intensity[first, 0] * np.pi / 0.5).sum())
    assert flux == pytest.approx(50.0, rel=0.1)


def test_samples_carry_their_emitters_receivers():
    """A light's samples carry its receivers, an emissive object's samples its own; none
    without light linking."""
    glow = Material("glow", (0.0, 0.0, 0.0), emission=(1.0, 1.0, 1.0))
    panel = Instance(quad(1, 1), translation(0, 0, 1), [glow], emission_receivers=1 << 3)
    scene = Scene([*halves(), panel], [LAMP], World(), floor_scene([]).camera)
    geometry = flatten_instances(scene, [])
    assert set(np.unique(geometry.receiver_set)) == {0, 1}
    samples = build_light_samples(scene, geometry, Settings(), [])
    lamp = samples.kind != 2  # KIND_COSINE2: the emission's
    assert (samples.receivers[lamp] == ONLY_SET_1).all()
    assert (samples.receivers[~lamp] == 1 << 3).all() and (~lamp).any()
    plain = floor_scene([light(LightKind.POINT, translation(0, 0, 2))])
    plain_geometry = flatten_instances(plain, [])
    assert plain_geometry.receiver_set is None and plain_geometry.emission_receivers is None
    assert build_light_samples(plain, plain_geometry, Settings(), []).receivers is None


def test_draws_hold_one_emitters_receivers_each():
    receivers = np.array([EVERY_RECEIVER_SET] * 3 + [2] * 5 + [1 << 40] * 2, np.uint64)
    assert draws(10, 4, None, receivers) == [(0, 3), (3, 4), (7, 1), (8, 2)]
    assert draws(10, 4, np.array([0] * 5 + [1] * 5), receivers) == \
        [(0, 3), (3, 2), (5, 3), (8, 2)]
    assert mask_words(int(receivers[9])) == (0, 1 << 8)
    assert mask_words(EVERY_RECEIVER_SET) == (0xFFFFFFFF, 0xFFFFFFFF)
