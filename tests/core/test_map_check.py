"""The check of imperfect shadow maps against rays (core/frame/map_check.py): VPLs under a
ceiling light a floor through a comb of thin slats, which maps of few points miss; and, in a
frame, the switch to ray-traced visibility where the check finds the maps off."""

from __future__ import annotations

import numpy as np
import pytest

from addon.core.frame.map_check import check_maps
from addon.core.gpu.ism import ImperfectShadowMaps
from addon.core.scene.model import Instance, LightKind, Material
from addon.core.settings import Settings
from addon.core.transport.guidance import CameraPoints
from addon.core.transport.vpl import VPLs
from tests.core.builders import floor_scene, light, quad, translation
from tests.core.test_ism import quad as flat_quad

SLATS = 20  # 0.1 wide, 0.1 apart: half the light blocked


def comb() -> np.ndarray:
    """A 4 × 4 floor at z = 0 and SLATS slats across it at z = 0.5."""
    slats = [flat_quad(-2.0 + 0.2 * k, -1.9 + 0.2 * k, -2.0, 2.0, 0.5) for k in range(SLATS)]
    return np.concatenate([flat_quad(-2.0, 2.0, -2.0, 2.0, 0.0), *slats])


def ceiling_vpls(n: int = 32) -> VPLs:
    rng = np.random.default_rng(4)
    position = np.column_stack([rng.uniform(-1.5, 1.5, (n, 2)), np.full(n, 0.999)])
    return VPLs(position, np.tile([0.0, 0.0, -1.0], (n, 1)), np.ones((n, 3)),
                np.ones(n, int), np.arange(n))


def floor_points(side: int = 24) -> CameraPoints:
    g = np.linspace(-1.5, 1.5, side)
    x, y = (a.ravel() for a in np.meshgrid(g, g))
    n = len(x)
    return CameraPoints(np.column_stack([x, y, np.zeros(n)]), np.tile([0.0, 0.0, 1.0], (n, 1)),
                        np.full((n, 3), 0.5))


@pytest.fixture
def maps(programs):
    m = ImperfectShadowMaps(programs.ctx, programs)
    yield m
    m.release()


def check(maps, tracer, triangles: np.ndarray, points_per_map: int, rendered: list | None = None):
    """check_maps with maps of ``points_per_map`` points (each render appended to
    ``rendered``)."""
    maps.prepare(triangles, points_per_map, seed=5)
    tracer.upload(triangles)

    def maps_visibility(subset, vpl, world, normal):
        (rendered if rendered is not None else []).append(len(subset))
        maps.render(triangles, subset.position, subset.axis, 128, 7)
        return maps.visibility(vpl, world, normal)
    return check_maps(ceiling_vpls().as_light_samples(8), floor_points(), tracer, 3e-5, 1e-3,
                      0.25, 1, maps_visibility)


def test_maps_of_few_points_are_found_to_let_light_through_the_slats(maps, tracer):
    """Rays find the comb blocking about half the light the floor would get; maps of 64
    points a map hardly see the slats (the check measures them off by more than 25 %), maps
    of 16384 points do (within it)."""
    sparse = check(maps, tracer, comb(), 64)
    dense = check(maps, tracer, comb(), 16384)
    print(f"rays' share {sparse.ray_share:.3f}; maps over rays: 64 points {sparse.ratio:.3f}, "
          f"16384 points {dense.ratio:.3f}")
    assert 0.4 < sparse.ray_share < 0.6
    assert sparse.ratio > 1.3 and sparse.off_by_more_than(0.25)
    assert dense.ratio == pytest.approx(1.0, abs=0.15) and not dense.off_by_more_than(0.25)


def test_rays_alone_settle_an_open_floor(maps, tracer):
    """Without the comb rays let through all the pairs' light: no map can let through more,
    so the maps are not rendered (no ratio) and the verdict is 'within the limit'."""
    rendered: list[int] = []
    open_floor = check(maps, tracer, flat_quad(-2.0, 2.0, -2.0, 2.0, 0.0), 64, rendered)
    assert open_floor.ray_share == 1.0 and open_floor.ratio is None and not rendered
    assert not open_floor.off_by_more_than(0.25)


def slatted_floor() -> object:
    """The floor scene's floor under 40 slats 0.15 wide and 0.2 apart at z = 0.5 and a ceiling
    at z = 1 (neither seen by the camera), lit by a point light between them: the ceiling's
    VPLs light the floor through the slats (more triangles than the frame's maps have
    points)."""
    ceiling = Instance(quad(5, 5, 1.0, flip=True), np.eye(4), [Material("ceiling")],
                       visible_to_camera=False)
    slats = [Instance(quad(0.075, 5, 0.5), translation(-4.0 + 0.2 * k, 0, 0),
                      [Material("slat")], visible_to_camera=False) for k in range(40)]
    bulb = light(LightKind.POINT, translation(0, 0, 0.9), power=50.0)
    return floor_scene([bulb], extra=[ceiling, *slats])


def test_a_frame_whose_maps_leak_traces_its_vpls(renderer):
    """With 64 points a map, the slatted floor's maps let the ceiling's light through the slats:
    the frame traces its VPLs' visibility instead (as visibility = exact renders it), and says
    so; with the check off it reads the leaking maps, brighter."""
    settings = Settings(bounces=1, antialiasing=1, vpl_count=256, ism_points=64)
    checked, stats = renderer.render(slatted_floor(), settings)
    unchecked, _ = renderer.render(slatted_floor(), Settings(**{**settings.__dict__,
                                                               "map_error_limit": 0.0}))
    traced, _ = renderer.render(slatted_floor(), Settings(**{**settings.__dict__,
                                                            "visibility": "exact"}))
    light = {name: frame.passes["DiffInd"][..., 0].mean()
             for name, frame in (("checked", checked), ("unchecked", unchecked),
                                 ("traced", traced))}
    print(light, stats.counts.get("map_light_vs_rays_pct"))
    assert "imperfect shadow maps" in stats.skipped
    assert stats.counts["map_light_vs_rays_pct"] > 125
    assert light["checked"] == pytest.approx(light["traced"], rel=0.02)
    assert light["unchecked"] > 1.2 * light["traced"]
