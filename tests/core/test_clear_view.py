"""Clear surfaces on the GPU: what the camera sees through a pane is dimmed by its colour and
Fresnel loss at the view angle, once per surface crossed, background included; so is the
light shadow maps let through (their atlases' clear layers)."""

from __future__ import annotations

import numpy as np
import pytest

from addon.core.gpu.clear_view import clear_vertices
from addon.core.scene.model import AreaShape, Instance, LightKind, Material, Scene, World
from addon.core.settings import Settings
from tests.core.builders import floor_scene, light, quad, rotation_x, top_down_camera, translation

SIZE = 64
EXTENT = 6.0  # metres across the top-down view: 64 / 6 pixels a metre, x = -3 at column 0
FRESNEL_1_5 = 0.04  # ((1.5 - 1) / (1.5 + 1))², one face met at normal incidence


def columns(x0: float, x1: float) -> slice:
    """The pixel columns well inside x0 < x < x1 (one pixel clear of each edge)."""
    scale = SIZE / EXTENT
    return slice(int(np.ceil((x0 + 3) * scale)) + 1, int(np.floor((x1 + 3) * scale)) - 1)


def test_degenerate_clear_triangles_are_left_out_and_normals_are_unit():
    triangles = np.array([[[0, 0, 0], [2, 0, 0], [0, 3, 0]], [[0, 0, 0], [1, 1, 1], [2, 2, 2]]],
                         np.float32)
    rows = clear_vertices(triangles, [[0.5, 0.6, 0.7, 1.5], [1, 1, 1, 0]])
    assert rows.shape == (3, 10)
    np.testing.assert_allclose(rows[:, 3:6], [[0, 0, 1]] * 3)
    np.testing.assert_allclose(rows[:, 6:], [[0.5, 0.6, 0.7, 1.5]] * 3)


def test_what_the_camera_sees_through_panes_is_dimmed_by_each(renderer):
    """An emissive strip under a tinted glass pane and, over part of it, a red Transparent
    pane; the world colour beside the strip is seen through both too."""
    emission, world = np.array([2.0, 1.0, 0.5]), np.array([0.3, 0.4, 0.5])
    tint_glass, tint_red = np.array([0.5, 0.8, 1.0]), np.array([1.0, 0.5, 0.5])
    strip = Instance(quad(2, 3), np.eye(4), [Material("lamp", (0, 0, 0), tuple(emission))])
    glass = Instance(quad(1.5, 3, 1.0), translation(-1.5, 0, 0),
                     [Material("glass", (0, 0, 0), transmission=tuple(tint_glass),
                               transmission_ior=1.5)])
    red = Instance(quad(0.75, 3, 2.0), translation(-2.25, 0, 0),
                   [Material("red", (0, 0, 0), transmission=tuple(tint_red))])
    scene = Scene([strip, glass, red], [], World(tuple(world)), top_down_camera(SIZE, EXTENT))
    frame, _ = renderer.render(scene, Settings(bounces=0, antialiasing=2))
    image = frame.passes["Combined"][..., :3]

    glass_loss = tint_glass * (1 - FRESNEL_1_5)
    expected = [((0, 2), emission), ((2, 3), world), ((-1.5, 0), emission * glass_loss),
                ((-2, -1.5), emission * glass_loss * tint_red),
                ((-3, -2), world * glass_loss * tint_red)]
    for (x0, x1), colour in expected:
        seen = image[:, columns(x0, x1)]
        np.testing.assert_allclose(seen, np.broadcast_to(colour, seen.shape), rtol=1e-4,
                                   err_msg=f"{x0} < x < {x1}")


@pytest.mark.parametrize("kind, shadows", [(LightKind.AREA, "hybrid"),
                                           (LightKind.AREA, "ray_traced"),
                                           (LightKind.POINT, "shadow_maps"),
                                           (LightKind.SUN, "shadow_maps")])
def test_shadow_mapped_light_through_a_tinted_pane_is_tinted(renderer, kind, shadows):
    """A pane of red Transparent BSDF between a light and the whole floor: the light is the
    same as without it, times the pane's colour (the area light's samples are shadow-mapped
    in the default hybrid mode, the point light's cube maps and the sun's directional map
    with shadow_maps; ray traced, the area light's per-channel shadowed share keeps the tint,
    which its sum over r, g, b greyed: 0.58 of the light in each channel)."""
    tint = np.array([1.0, 0.6, 0.2])  # in 8 bits a channel (the ray tracer's) exactly
    lamp = {LightKind.AREA: light(LightKind.AREA, translation(0, 0, 2), power=80.0,
                                  area_shape=AreaShape.SQUARE, size_x=0.5),
            LightKind.POINT: light(LightKind.POINT, translation(0, 0, 2), power=80.0),
            LightKind.SUN: light(LightKind.SUN, rotation_x(0.3), power=3.0)}[kind]
    pane = Instance(quad(8, 8, 1.0), np.eye(4),
                    [Material("red", (0, 0, 0), transmission=tuple(tint))])
    settings = Settings(bounces=0, antialiasing=1, direct_shadows=shadows, light_samples=16)
    open_frame, _ = renderer.render(floor_scene([lamp]), settings)
    glazed, stats = renderer.render(floor_scene([lamp], extra=[pane]), settings)
    assert (stats.counts["shadow_maps"] > 0) == (shadows != "ray_traced")
    np.testing.assert_allclose(glazed.passes["DiffDir"][..., :3],
                               open_frame.passes["DiffDir"][..., :3] * tint, rtol=1e-5,
                               atol=1e-6)


def test_blender_s_pass_algebra_holds_through_a_pane(renderer):
    """Seen through a tinted pane, Combined = (DiffDir + DiffInd) × DiffCol + Emit still holds:
    DiffCol and Emit carry the pane's colour and the light passes do not, as Cycles writes
    them (compose.SEEN_THROUGH; the sun's light through the pane is tinted by it once)."""
    tint = np.array([1.0, 0.6, 0.2])
    sun = light(LightKind.SUN, rotation_x(0.3), power=3.0)
    floor = Instance(quad(5, 5), np.eye(4), [Material("floor", (0.8, 0.8, 0.8), (0.1, 0.1, 0.1))])
    pane = Instance(quad(8, 8, 2.5), np.eye(4),
                    [Material("tint", (0, 0, 0), transmission=tuple(tint))])
    scene = Scene([floor, pane], [sun], World(), top_down_camera())
    frame, _ = renderer.render(scene, Settings(bounces=1, antialiasing=2, vpl_count=64))
    p = frame.passes
    np.testing.assert_allclose(p["DiffCol"], np.broadcast_to(0.8 * tint, p["DiffCol"].shape),
                               rtol=1e-5)
    np.testing.assert_allclose(p["Emit"], np.broadcast_to(0.1 * tint, p["Emit"].shape),
                               rtol=1e-5)
    rebuilt = (p["DiffDir"] + p["DiffInd"]) * p["DiffCol"] + p["Emit"]
    np.testing.assert_allclose(p["Combined"][..., :3], rebuilt, rtol=1e-4, atol=1e-6)
