"""The planner leaves out only work whose result the frame does not show, and says why."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from addon.core.frame.planner import needed_pull_push_levels, reaches_bounds, visible_bounds
from addon.core.scene.model import Instance, LightKind, Material, Scene
from addon.core.settings import Settings
from tests.core.builders import (
    floor_scene,
    icosphere,
    inside_sphere_camera,
    light,
    quad,
    rotation_x,
    top_down_camera,
    translation,
)

DIRECT = Settings(bounces=0, antialiasing=1, light_samples=4, shadow_resolution=256,
                  sample_shadow_resolution=64, world_samples=16,
                  direct_shadows="shadow_maps")  # counts shadow maps


def relative_rmse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(((a - b) ** 2).mean() / max((b**2).mean(), 1e-30)))


def skipped_with(stats, words: str) -> list[str]:
    return [k for k, v in stats.skipped.items() if words in f"{k} {v}"]


def lights_out_of_view():
    """A point light that lights the floor, and three that cannot: a spot pointing up, an area
    light facing up and a spot whose cone misses the part of the floor the camera sees."""
    up = translation(0, 0, 2) @ rotation_x(np.pi)
    return [light(LightKind.POINT, translation(0, 0, 2), power=50.0),
            light(LightKind.SPOT, up, power=50.0, spot_size=np.radians(60)),
            light(LightKind.AREA, up, power=50.0, size_x=0.5),
            light(LightKind.SPOT, translation(40, 0, 2), power=50.0, spot_size=np.radians(30))]


def test_lights_that_cannot_reach_the_view_get_no_shadow_maps(renderer):
    scene = floor_scene(lights_out_of_view())
    planned, stats = renderer.render(scene, DIRECT)
    full, full_stats = renderer.render(scene, replace(DIRECT, planner=False))
    # 1 + 1 + 4 area samples + 1 remote spot, plus 16 world samples the black world needs not
    assert full_stats.counts["light_samples"] == 7 + 16
    assert stats.counts["light_samples"] == 1
    assert skipped_with(stats, "6 of 7 light samples") and skipped_with(stats, "black world")
    assert stats.counts["shadow_maps"] == 6 < full_stats.counts["shadow_maps"]
    np.testing.assert_allclose(planned.passes["Combined"], full.passes["Combined"],
                               rtol=1e-5, atol=1e-7)
    assert planned.passes["Combined"][..., :3].max() > 0.1


def test_zero_power_lights_and_a_black_world_are_reported(renderer):
    scene = floor_scene([light(LightKind.POINT, translation(0, 0, 2), power=0.0),
                         light(LightKind.POINT, translation(1, 0, 2), power=20.0)])
    scene.lights[0].name = "dark"
    _, stats = renderer.render(scene, DIRECT)
    assert stats.skipped["light 'dark'"] == "zero power"
    assert stats.skipped["world light"] == "black world"
    assert stats.skipped["texture lookups"] == "no material has an image texture"
    assert "ran: " in stats.summary() and "skipped: " in stats.summary()


def wall(x: float) -> Instance:
    """A 2 m high, 4 m wide wall in the plane x = ``x`` standing on the floor, normal +x."""
    facing_x = np.array([[0, 0, 1, 0], [0, 1, 0, 0], [-1, 0, 0, 0], [0, 0, 0, 1.0]])
    return Instance(quad(1, 2), translation(x, 0, 1) @ facing_x, [Material("wall")])


def test_vpls_facing_away_from_the_view_are_left_out_and_change_nothing(renderer):
    """A wall at x = 4, out of view, lit from behind (+x): its VPLs face away from every
    visible surface. Exact visibility and no interleaving: the kept VPLs' sum is the image."""
    scene = floor_scene([light(LightKind.POINT, translation(4.5, 0, 1), power=200.0),
                         light(LightKind.POINT, translation(0, 0, 2), power=50.0)],
                        extra=[wall(4)])
    settings = replace(DIRECT, bounces=1, vpl_count=256, visibility="exact", interleave=1)
    planned, stats = renderer.render(scene, settings)
    full, full_stats = renderer.render(scene, replace(settings, planner=False))
    assert full_stats.counts["vpls"] == stats.counts["vpls"]
    assert skipped_with(stats, "VPLs cannot light any surface in view")
    np.testing.assert_allclose(planned.passes["DiffInd"], full.passes["DiffInd"], rtol=1e-4,
                               atol=1e-6)
    assert planned.passes["DiffInd"].max() > 0


def test_pull_push_stops_where_the_point_density_needs_no_more_levels(renderer):
    """A closed sphere lit from inside: 3 levels fill 128² maps of 8192 points; the 4 more
    levels of the full pipeline leave the indirect light unchanged (within 1 %; measured:
    bit for bit, as every hole is filled by level 3)."""
    sphere = Instance(icosphere(1.0, 3), np.eye(4), [Material("in", (0.8,) * 3)])
    scene = Scene([sphere], [light(LightKind.POINT, translation(0.2, 0.1, 0.3), power=10.0)],
                  camera=inside_sphere_camera(32))
    settings = replace(DIRECT, bounces=2, vpl_count=128, interleave=1)
    planned, stats = renderer.render(scene, settings)
    full, _ = renderer.render(scene, replace(settings, planner=False))
    assert needed_pull_push_levels(settings) == 3
    assert skipped_with(stats, "pull-push levels 4–7")
    error = relative_rmse(planned.passes["DiffInd"], full.passes["DiffInd"])
    assert error < 0.01, error


def test_needed_pull_push_levels_follow_the_point_density():
    base = Settings()
    assert needed_pull_push_levels(replace(base, ism_resolution=512, ism_points=1024)) == 7
    assert needed_pull_push_levels(replace(base, ism_resolution=32, ism_points=65536)) == 2
    assert needed_pull_push_levels(replace(base, pull_push_levels=1)) == 1  # never more


def test_passes_not_asked_for_are_left_out(renderer):
    scene = floor_scene([light(LightKind.POINT, translation(0, 0, 2), power=50.0)],
                        extra=[wall(2)])
    settings = replace(DIRECT, bounces=1, vpl_count=64)
    some, stats = renderer.render(scene, settings, passes=frozenset({"DiffDir"}))
    every, _ = renderer.render(scene, settings)
    assert np.array_equal(some.passes["Combined"], every.passes["Combined"])
    assert np.array_equal(some.passes["DiffDir"], every.passes["DiffDir"])
    assert set(some.passes) == {"Combined", "DiffDir"} and every.passes["DiffInd"].any()
    assert skipped_with(stats, "Depth, DiffCol, DiffInd, Emit, Env, GlossCol, GlossDir, "
                               "GlossInd, IndexMA, IndexOB, Mist, Normal, Position")
    assert "AO" not in every.passes  # rays of its own: only where asked for
    assert skipped_with(stats, "passes AO, CryptoAsset, CryptoMaterial, CryptoObject, Denoising")


def test_a_camera_that_sees_no_surface_runs_no_light_work(renderer):
    scene = floor_scene([light(LightKind.POINT, translation(0, 0, 2), power=50.0)])
    camera = top_down_camera(32)
    camera.view_matrix = camera.view_matrix @ translation(100, 0, 0)  # looks beside the floor
    scene.camera = camera
    frame, stats = renderer.render(scene, replace(DIRECT, bounces=2))
    assert stats.skipped["indirect light"] == "the camera sees no surface"
    assert stats.counts["light_samples"] == 0 and stats.counts["vpls"] == 0
    assert not frame.passes["Combined"][..., :3].any()  # the black world


@pytest.mark.parametrize("spot_degrees, x, reaches", [(30, 0, True), (30, 40, False),
                                                      (179, 40, True)])
def test_spot_cones_are_tested_against_the_visible_box(spot_degrees, x, reaches):
    from addon.core.scene.geometry import flatten_instances
    from addon.core.transport.lights import build_light_samples

    scene = floor_scene([light(LightKind.SPOT, translation(x, 0, 2), power=1.0,
                               spot_size=np.radians(spot_degrees))])
    geometry = flatten_instances(scene, [])
    samples = build_light_samples(scene, geometry, DIRECT, [])
    positions = geometry.positions
    bounds = visible_bounds(scene.camera, (positions.min(axis=0), positions.max(axis=0)))
    assert reaches_bounds(samples, bounds).tolist() == [reaches]


@pytest.mark.parametrize("planner", [True, False])
def test_scenes_without_surfaces_or_bounces_render_with_and_without_the_planner(renderer,
                                                                                 planner):
    empty = Scene([], [light(LightKind.POINT, translation(0, 0, 2), power=50.0)],
                  camera=top_down_camera(16))
    for scene, settings in ((empty, replace(DIRECT, bounces=2)),
                            (floor_scene(lights_out_of_view()), DIRECT)):
        frame, stats = renderer.render(scene, replace(settings, planner=planner))
        assert stats.skipped["indirect light"] in ("no surfaces", "bounces = 0")
        assert stats.counts["vpls"] == 0 and np.isfinite(frame.passes["Combined"]).all()
