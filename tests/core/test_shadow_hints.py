"""Adaptive shadow rays (frame/shadow_hints.py): ray-traced direct light traced once per pixel
first, and at every supersample only where the pixels around disagree."""

from __future__ import annotations

import moderngl
import numpy as np
from scipy import ndimage

from addon.core.frame import gather as gather_module
from addon.core.gpu.gl import ProgramCache
from addon.core.scene.model import Instance, LightKind, Material, Mesh, Scene, World
from addon.core.settings import Settings
from devtools import metrics
from tests.core.builders import (
    floor_scene,
    inside_sphere_camera,
    light,
    quad,
    rotation_x,
    translation,
)


def blocked_scene(lights):
    blocker = Instance(quad(0.4, 0.4, z=1.0), np.eye(4), [Material("blocker")])
    return floor_scene(lights, extra=[blocker])


def render_both(renderer, scene, **settings):
    common = {"bounces": 0, "antialiasing": 3, "direct_shadows": "ray_traced", **settings}
    every, _ = renderer.render(scene, Settings(adaptive_shadows=False, **common))
    adaptive, stats = renderer.render(scene, Settings(adaptive_shadows=True, **common))
    return every.passes["DiffDir"], adaptive.passes["DiffDir"], stats


def test_hard_shadow_edges_are_antialiased_over_each_supersample(renderer):
    """Three point lights (one bit each). Where no edge is within 2 pixels the image is bit
    for bit the one with a ray per supersample; at the shadow edges on the floor each
    supersample traces 4 rays over its cell, so those pixels come closer to the edges' true
    coverage (antialiasing 8, a ray per supersample) than one ray per supersample does."""
    lights = [light(LightKind.POINT, translation(x, 0.5, 2.0), power=50.0) for x in (-1, 0, 1)]
    scene = blocked_scene(lights)
    every, adaptive, stats = render_both(renderer, scene)
    fine, _ = renderer.render(scene, Settings(bounces=0, antialiasing=8, adaptive_shadows=False,
                                              direct_shadows="ray_traced"))
    converged = fine.passes["DiffDir"]
    assert "shadow hints" in stats.timings
    lum = every[..., 0]
    span = ndimage.maximum_filter(lum, 5) - ndimage.minimum_filter(lum, 5)
    flat = span <= 1e-6 * lum.max()  # no edge within 2 pixels
    np.testing.assert_array_equal(adaptive[flat], every[flat])
    blocker = ndimage.binary_dilation(fine.passes["Depth"][..., 0] < 4.5, iterations=2)
    edges = ~flat & ~blocker  # shadow edges on the floor, away from the blocker's outline
    assert edges.sum() > 50

    def edge_error(image):
        return float(np.sqrt(((image - converged)[edges] ** 2).mean()))

    print(f"floor's edge pixels, RMS error against antialiasing 8: {edge_error(adaptive):.4f} "
          f"(a ray per supersample: {edge_error(every):.4f})")
    assert edge_error(adaptive) < 0.7 * edge_error(every)
    assert abs(metrics.mean_relative_energy(adaptive, converged)) < 0.005


def test_a_sun_with_an_angle_keeps_its_penumbra(renderer):
    """Interleaved sun samples (each supersample traces one): the pixels' hints hold one
    sample each, so penumbrae, where they disagree, keep their rays, and there each
    supersample's four edge rays take four of the sun's samples (SPREAD_EDGE_RAYS). Against
    the same 16 samples each taken 4 times a pixel (antialiasing 8), the penumbra comes closer
    than with one ray a supersample, and no light is lost where 3×3 pixels agree by chance."""
    sun = light(LightKind.SUN, rotation_x(0.5), power=3.0, sun_angle=0.3)
    scene = blocked_scene([sun])
    every, adaptive, stats = render_both(renderer, scene, light_samples=16)
    fine, _ = renderer.render(scene, Settings(bounces=0, antialiasing=8, adaptive_shadows=False,
                                              direct_shadows="ray_traced", light_samples=16))
    converged = fine.passes["DiffDir"]
    assert "shadow hints" in stats.timings
    assert abs(metrics.mean_relative_energy(adaptive, converged)) < 0.002
    error = {name: metrics.relative_rmse(image, converged)
             for name, image in (("adaptive", adaptive), ("every", every))}
    assert error["adaptive"] < 0.8 * error["every"], error  # measured 1.29 % and 1.81 %


def test_antialiasing_one_and_the_setting_off_trace_every_ray(renderer):
    lights = [light(LightKind.POINT, translation(0, 0.5, 2.0), power=50.0)]
    _, stats = renderer.render(blocked_scene(lights), Settings(bounces=0, antialiasing=1))
    assert "shadow hints" not in stats.timings
    _, stats = renderer.render(blocked_scene(lights), Settings(bounces=0,
                                                               adaptive_shadows=False))
    assert "shadow hints" not in stats.timings


class _OneDraw:
    """The hinted gather as one draw of the full shader (gather.py's _HintedDraws splits it)."""

    def __init__(self, _ctx: object, programs: ProgramCache, defines: dict[str, object],
                 *_args: object) -> None:
        self.hints_only = programs.get("fullscreen_vert.glsl", "gather_frag.glsl", defines,
                                       version=430)  # the full shader: its uniforms set twice

    def render(self, vao: moderngl.VertexArray) -> None:
        vao.render(moderngl.TRIANGLES, vertices=3)


def test_splitting_off_the_supersamples_that_need_rays_changes_no_pixel(renderer, monkeypatch):
    """The hints-only draw and the draw with rays where it left supersamples give the image
    of one draw of the shader with rays, bit for bit: hard edges (bits per light) and a sun's
    interleaved angle samples."""
    lights = [light(LightKind.POINT, translation(x, 0.5, 2.0), power=50.0) for x in (-1, 1)]
    lights.append(light(LightKind.SUN, rotation_x(0.5), power=3.0, sun_angle=0.3))
    scene = blocked_scene(lights)
    settings = Settings(bounces=0, antialiasing=3, light_samples=16)
    split, stats = renderer.render(scene, settings)
    assert "shadow hints" in stats.timings
    monkeypatch.setattr(gather_module, "_HintedDraws", _OneDraw)
    whole, _ = renderer.render(scene, settings)
    for name, image in whole.passes.items():
        np.testing.assert_array_equal(split.passes[name], image, err_msg=name)


def room_with_a_window() -> list[Instance]:
    """A 4 × 3 × 5 m room round the origin's camera (inside_sphere_camera, looking down -Z),
    its left wall open by a 1.2 × 1.5 m window."""
    rectangles = [((-2, -1.5, -4), (4, 0, 0), (0, 3, 0)), ((-2, -1.5, 1), (4, 0, 0), (0, 3, 0)),
                  ((-2, -1.5, -4), (4, 0, 0), (0, 0, 5)), ((-2, 1.5, -4), (4, 0, 0), (0, 0, 5)),
                  ((2, -1.5, -4), (0, 3, 0), (0, 0, 5)), ((-2, -1.5, -4), (0, 1.2, 0), (0, 0, 5)),
                  ((-2, 0.9, -4), (0, 0.6, 0), (0, 0, 5)), ((-2, -0.3, -4), (0, 1.2, 0), (0, 0, 1)),
                  ((-2, -0.3, -1.5), (0, 1.2, 0), (0, 0, 2.5))]  # corner, two edges
    corners = np.array([[o, np.add(o, u), np.add(o, u) + v, o, np.add(o, u) + v, np.add(o, v)]
                        for o, u, v in rectangles], np.float32)
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 5] - corners[:, 0])
    inward = np.sign(np.einsum("ij,ij->i", normals, [0, 0, -1.5] - corners.mean(axis=1)))
    normals *= (inward / np.linalg.norm(normals, axis=1))[:, None]
    mesh = Mesh("room", corners.reshape(-1, 3), np.repeat(normals, 6, axis=0).astype(np.float32),
                np.zeros(2 * len(rectangles), np.int32))
    return [Instance(mesh, np.eye(4), [Material("wall", (0.7, 0.7, 0.7))])]


def test_world_light_through_a_window_is_not_taken_from_the_pixels_around(renderer):
    """The world's samples are interleaved, a different direction at each supersample: the
    pixels around, which traced other directions, cannot stand for them (a room's sky light
    through a small window was 60–94 % dark away from its sun patch). With adaptive shadows
    every world sample keeps its ray (measured: the image the same to the bit; when the
    neighbours stood for them, relRMSE 19.6 %)."""
    scene = Scene(room_with_a_window(), [], World((1.0, 1.0, 1.0)), inside_sphere_camera(64))
    every, adaptive, stats = render_both(renderer, scene)
    assert "shadow hints" not in stats.timings
    assert metrics.relative_rmse(adaptive, every) < 0.002
