"""Camera-driven VPLs: the same VPL count spent on what the camera sees, unbiased."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np

from addon.core.scene.geometry import flatten_instances
from addon.core.scene.model import Instance, LightKind, Material
from addon.core.scene.vectors import unit
from addon.core.settings import Settings
from addon.core.transport.guidance import (
    MIN_ACCEPTANCE,
    UNLIT_SHARE,
    CameraPoints,
    acceptance,
    camera_points,
    contributions,
    guide,
    least_acceptance,
    refined_contributions,
    systematic,
)
from addon.core.transport.vpl import LUMINANCE, VPLs
from devtools import metrics
from tests.core.builders import (
    floor_scene,
    light,
    quad,
    rotation_x,
    top_down_camera,
    translation,
)

BASE = Settings(antialiasing=1, bounces=1, vpl_count=256, visibility="exact", interleave=1,
                clamp_distance=0.02)


def mostly_wasted_scene():
    """A lit wall beside the floor the camera sees, and a second light that only lights the
    back of a far wall turned away from everything: most VPLs light nothing in view."""
    near_wall = Instance(quad(5, 2), translation(0, 4, 2) @ rotation_x(np.pi / 2),
                         [Material("near", (0.8, 0.3, 0.3))])
    far_wall = Instance(quad(5, 5), translation(0, -30, 5) @ rotation_x(np.pi / 2),
                        [Material("far", (0.8, 0.8, 0.8))])
    lights = [light(LightKind.POINT, translation(0, 2, 1), power=100),
              light(LightKind.POINT, translation(0, -33, 5), power=300)]
    return floor_scene(lights, extra=[near_wall, far_wall], size=24)


def test_guided_vpls_light_the_view_with_less_error_and_the_same_energy(renderer) -> None:
    reference, _ = renderer.render_progressive(
        mostly_wasted_scene(), replace(BASE, vpl_guidance="off", vpl_count=2048, passes=16))
    truth = reference.passes["DiffInd"]
    error, energy, stats = {}, {}, {}
    for guidance in ("off", "camera"):
        frame, stats[guidance] = renderer.render_progressive(
            mostly_wasted_scene(), replace(BASE, vpl_guidance=guidance, passes=4))
        image = frame.passes["DiffInd"]
        error[guidance] = metrics.relative_rmse(image, truth)
        energy[guidance] = metrics.mean_relative_energy(image, truth)
    guided = stats["camera"].counts
    assert guided["vpls_in_view_pct"] >= 70 > guided["candidates_in_view_pct"] + 40, guided
    assert error["camera"] < 0.75 * error["off"], error
    assert abs(energy["camera"]) < 0.05, energy


class BlockingTracer:
    """A stand-in ray caster: the rays whose index is in ``blocked`` hit something."""

    def __init__(self, blocked: set[int] = frozenset()) -> None:
        self.blocked = blocked

    def intersect(self, origin, direction, t_min, t_max, shadow=False, diffuse=False):
        hit = np.array([i in self.blocked for i in range(len(origin))])
        return SimpleNamespace(triangle=np.where(hit, 0, -1), distance=np.where(hit, 1.0, np.inf))


def test_contributions_follow_the_point_to_point_formula_far_from_the_origin() -> None:
    """Intensity × both cosines / distance² × albedo / π summed over the points, zero for
    pairs facing away or whose ray is blocked; computed from products of positions, so it is
    checked 1e4 from the origin, where cancellation would show."""
    rng = np.random.default_rng(4)
    far = np.array([1e4, -2e4, 5e3])
    vpls = VPLs(far + rng.normal(size=(30, 3)), unit(rng.normal(size=(30, 3))), rng.random((30, 3)),
                np.ones(30, int), np.arange(30))
    points = CameraPoints(far + rng.normal(size=(40, 3)), unit(rng.normal(size=(40, 3))),
                          rng.random((40, 3)))
    expected = np.zeros((30, 40))
    for i in range(30):
        for j in range(40):
            offset = points.position[j] - vpls.position[i]
            distance = np.linalg.norm(offset)
            cos_vpl = max(0.0, offset @ vpls.normal[i] / distance)
            cos_point = max(0.0, -offset @ points.normal[j] / distance)
            expected[i, j] = (vpls.intensity[i] @ LUMINANCE) * cos_vpl * cos_point \
                / distance**2 * (points.albedo[j] @ LUMINANCE) / np.pi
    assert np.allclose(contributions(vpls, points, BlockingTracer(), 1e-9),
                       expected.sum(axis=1), rtol=1e-9, atol=0)
    pairs = np.argwhere(expected > 0)  # the rays, in the order the caster gets them
    blocked = {0, 5, len(pairs) - 1}
    for k in blocked:
        expected[tuple(pairs[k])] = 0.0
    assert np.allclose(contributions(vpls, points, BlockingTracer(blocked), 1e-9),
                       expected.sum(axis=1), rtol=1e-9, atol=0)


def test_candidates_the_first_points_miss_are_estimated_at_more_points() -> None:
    """A VPL that lights none of the first points but lights the view between them gets the
    further points' estimate (scaled to the first points' count), not zero (which would keep
    it at MIN_ACCEPTANCE and weight it twentyfold); one that lights the first points keeps
    their estimate."""
    up, down = np.array([[0.0, 0.0, 1.0]]), np.array([[0.0, 0.0, -1.0]])
    vpls = VPLs(np.array([[0.0, 0.0, 1.0], [5.0, 0.0, 1.0]]), np.array([down[0], [1, 0, 0]]),
                np.ones((2, 3)), np.ones(2, int), np.arange(2))
    first = CameraPoints(np.array([[0.0, 0.0, 0.0], [0.0, 0.5, 0.0]]), np.repeat(up, 2, 0),
                         np.full((2, 3), 0.5))  # under the first VPL, behind the second
    more = CameraPoints(np.array([[7.0, 0.0, 0.0], [7.0, 1.0, 0.0], [0.0, 0.0, 0.0],
                                  [3.0, 0.0, 0.0]]), np.repeat(up, 4, 0), np.full((4, 3), 0.5))
    value = refined_contributions(vpls, first, more, BlockingTracer(), 1e-6)
    assert value[0] == contributions(vpls, first, BlockingTracer(), 1e-6)[0] > 0
    only_second = VPLs(vpls.position[1:], vpls.normal[1:], vpls.intensity[1:],
                       vpls.generation[1:], vpls.rank[1:])
    assert contributions(only_second, first, BlockingTracer(), 1e-6)[0] == 0
    again = contributions(only_second, more, BlockingTracer(), 1e-6)[0]
    assert value[1] == again * 2 / 4 > 0


def test_acceptance_spends_the_budget_on_contribution() -> None:
    contribution = np.r_[np.zeros(90), np.linspace(1, 2, 100)]
    chance = acceptance(contribution, 120.0)  # at most 100 + 0.05 × 90 = 104.5 are possible
    assert np.all(chance == np.r_[np.full(90, MIN_ACCEPTANCE), np.ones(100)])
    chance = acceptance(contribution, 100.0)
    assert abs(chance.sum() - 100) < 0.01
    assert np.all(chance[:90] == MIN_ACCEPTANCE) and np.all(chance[90:] > MIN_ACCEPTANCE)
    assert np.all(np.diff(chance[90:]) >= 0)  # more contribution, more chance
    assert np.all(acceptance(contribution, 2000.0) == 1.0)  # fewer candidates than wanted


def test_where_no_candidate_lights_the_view_as_many_are_kept_as_without_guidance() -> None:
    """A view that sees almost nothing (a 170° lens on the Cornell box: its few camera points
    miss the box) gives no candidate a contribution; each is kept with the same chance, so
    about ``kept`` remain, each weighted by n / kept. Keeping every one (before stop 67) gave
    16 times the VPLs: 17 s for a 48² frame."""
    chance = acceptance(np.zeros(16000), 1000.0)
    assert np.all(chance == 1000.0 / 16000)


def test_candidates_that_light_no_camera_point_take_a_bounded_share() -> None:
    """Where many candidates light no camera point (Sponza: 8700 of 10,400) the least chance
    falls so that they take UNLIT_SHARE of the VPLs kept; where those that light a point are
    too few for the rest, the others fill it (up to MIN_ACCEPTANCE each)."""
    many_unlit = np.r_[np.zeros(8000), np.linspace(1, 2, 2000)]
    chance = acceptance(many_unlit, 600.0)
    assert least_acceptance(many_unlit, 600.0) == chance[0] < MIN_ACCEPTANCE
    assert abs(chance[:8000].sum() - UNLIT_SHARE * 600) < 1e-6
    assert abs(chance.sum() - 600) < 0.01
    few_lit = np.r_[np.zeros(8000), np.linspace(1, 2, 300)]
    chance = acceptance(few_lit, 600.0)
    assert np.all(chance[8000:] == 1.0) and abs(chance[:8000].sum() - 300) < 1e-6
    assert least_acceptance(np.r_[np.zeros(100), np.ones(900)], 600.0) == MIN_ACCEPTANCE


def test_the_draw_spreads_the_kept_candidates_over_the_scene() -> None:
    """Candidates in light-path order alternate between two halves of the scene, as a Halton
    dimension's base-2 digit does; a systematic draw of half of them along that order keeps
    one half of the scene only, along the Morton order both halves alike, each kept VPL
    weighted by 1/chance."""
    n = 256
    index = np.arange(n)
    position = np.stack([np.where(index % 2 == 0, 0.25, 0.75), index / n, np.zeros(n)], axis=1)
    normal = np.tile([0.0, 0.0, 1.0], (n, 1))
    candidates = VPLs(position, normal, np.ones((n, 3)), np.ones(n, int), index)
    along_paths = systematic(np.full(n, 0.5), 0.3)
    assert len(set(index[along_paths] % 2)) == 1  # the failure the order avoids
    for seed in range(4):
        kept = guide(candidates, np.ones(n), n / 2, seed).vpls
        left = int(np.sum(kept.position[:, 0] < 0.5))
        assert len(kept) == n // 2 and abs(left - n // 4) <= 2, (seed, left)
        assert np.allclose(kept.intensity, 2.0)


def test_the_decision_costs_a_small_probe_not_a_round_of_candidates(renderer, monkeypatch):
    """Whether guidance pays is decided from DECISION_PATHS light paths: where most VPLs light
    the view the frame traces only those and its plain paths (no guidance_candidates ×
    vpl_count candidates), and where few do the candidates follow."""
    from addon.core.frame import vpl_stage

    traced: list[int] = []
    plain = vpl_stage.generate_vpls

    def counting(scene, geometry, settings, *args):
        traced.append(settings.vpl_count)
        return plain(scene, geometry, settings, *args)

    monkeypatch.setattr(vpl_stage, "generate_vpls", counting)
    from tests.core.test_progressive import closed_sphere

    settings = replace(BASE, vpl_count=512)
    renderer.forget_frames()
    _, stats = renderer.render(closed_sphere(), settings)  # every VPL lights the view
    assert "vpl guidance" in stats.skipped
    assert traced == [vpl_stage.DECISION_PATHS, 512]
    traced.clear()
    renderer.forget_frames()
    _, stats = renderer.render(mostly_wasted_scene(), settings)
    assert "vpl guidance" not in stats.skipped and stats.counts["vpls_in_view_pct"] >= 50
    assert traced == [vpl_stage.DECISION_PATHS, settings.guidance_candidates * 512]


def test_camera_points_go_through_hidden_objects_and_stop_at_holdouts(tracer) -> None:
    """Over the floor's left half a panel the camera does not see, over its right half a
    holdout: the points guiding VPLs lie on the floor on the left and nowhere on the right
    (the camera sees a hole there, whatever lights it)."""
    panel = Instance(quad(1.5, 3, 1.0), translation(-1.5, 0, 0), [Material("panel")],
                     visible_to_camera=False)
    hole = Instance(quad(1.5, 3, 1.0), translation(1.5, 0, 0), [Material("hole")], holdout=True)
    scene = floor_scene([], extra=[panel, hole])
    geometry = flatten_instances(scene, [])
    tracer.upload(geometry.positions.reshape(-1, 3, 3))
    points = camera_points(top_down_camera(), geometry, tracer, 256, 0)
    x, z = points.position[:, 0], points.position[:, 2]
    assert np.all(x < 0.0) and np.abs(z).max() < 1e-5
    assert 100 < len(x) < 156  # the left half of 256 rays


def test_camera_points_under_a_clip_range_float32_cannot_hold(tracer) -> None:
    """A perspective camera 5 m above the floor with Clip Start 0.1 mm and Clip End 100 km, its
    projection rounded to float32 as Blender computes it: the far plane lies at infinity
    (−(f + n)/(f − n) rounds to −1), so rays made towards it were NaN and guidance found no
    camera point (the Cornell box: 16 times the VPLs, 12 times the time, before stop 66)."""
    near, far = 1e-4, 1e5
    projection = np.array([[1, 0, 0, 0], [0, 1, 0, 0],
                           [0, 0, -(far + near) / (far - near), -2 * far * near / (far - near)],
                           [0, 0, -1, 0]], np.float32).astype(np.float64)
    assert projection[2, 2] == -1.0
    camera = replace(top_down_camera(), projection_matrix=projection, is_orthographic=False)
    geometry = flatten_instances(floor_scene([]), [])
    tracer.upload(geometry.positions.reshape(-1, 3, 3))
    points = camera_points(camera, geometry, tracer, 256, 0)
    assert len(points.position) == 256  # every ray of the 90° view meets the 10 m floor
    assert np.isfinite(points.position).all() and np.abs(points.position[:, 2]).max() < 1e-5
