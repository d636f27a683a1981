"""Progressive final renders: passes with their own VPLs, averaged, converging to the
unclamped answer; stopped by a time limit, a noise threshold or the user."""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
import pytest

from addon.core.frame.progressive import (
    EXACT_PASS_COST,
    Accumulator,
    expected_pass_seconds,
    pass_camera,
    pass_settings,
    ray_traced_from,
)
from addon.core.frame.renderer import RenderCancelled
from addon.core.frame.result import Frame
from addon.core.scene.model import Instance, Material, Scene, World
from addon.core.settings import Settings, SettingsError
from tests.core.builders import inside_sphere_camera, quad, top_down_camera, translation
from tests.core.test_instant_radiosity import sphere_scene

ALBEDO = 0.5
# a large clamp (a third of the sphere's radius) makes the first pass's bias plain to see
BASE = Settings(antialiasing=1, bounces=1, vpl_count=16, visibility="exact", interleave=1,
                clamp_distance=0.3)


def closed_sphere():
    scene = sphere_scene(ALBEDO)
    scene.camera = inside_sphere_camera(12)
    return scene


def ratio_error(frame: Frame) -> float:
    """Relative RMS error of DiffInd / DiffDir against ρ (the closed sphere's exact ratio for
    one bounce: indirect irradiance is uniform)."""
    ratio = frame.passes["DiffInd"][..., 0] / frame.passes["DiffDir"][..., 0]
    return float(np.sqrt(np.mean((ratio / ALBEDO - 1) ** 2)))


def test_one_pass_is_the_plain_render(renderer) -> None:
    renderer.forget_frames()
    plain, _ = renderer.render(closed_sphere(), BASE)
    renderer.forget_frames()
    progressive, stats = renderer.render_progressive(closed_sphere(), BASE)
    for name, image in plain.passes.items():
        np.testing.assert_array_equal(progressive.passes[name], image, err_msg=name)
    assert stats.counts["passes"] == 1


def test_passes_converge_to_the_unclamped_answer(renderer) -> None:
    errors = {}
    for passes in (1, 4, 16):
        frame, stats = renderer.render_progressive(closed_sphere(), replace(BASE, passes=passes))
        errors[passes] = ratio_error(frame)
        assert stats.counts["passes"] == passes
    assert errors[16] < errors[4] < errors[1]
    assert errors[16] < 0.5 * errors[1], errors


def test_each_pass_has_its_own_seed_and_a_shrinking_clamp() -> None:
    seeds = {pass_settings(BASE, k).seed for k in range(64)}
    assert len(seeds) == 64
    assert pass_settings(BASE, 63).clamp_distance == pytest.approx(BASE.clamp_distance / 2)
    assert pass_settings(BASE, 0) is BASE


def test_the_clamp_schedule_makes_hot_spots_and_clamped_energy_vanish() -> None:
    """Pass k's hot spots add about (clamp / c_k)² to the squared error of the average of K
    passes, weighted 1 / K²; the energy the last clamp removes goes as c_K². Both fall by more
    than half from 4 to 64 passes (with c_k = clamp / √(k + 1) the hot spots' term kept 0.81 of
    its 4-pass value; with a fixed clamp the energy term stays)."""
    def hot_spots(passes: int) -> float:
        return sum((BASE.clamp_distance / pass_settings(BASE, k).clamp_distance) ** 2
                   for k in range(passes)) / passes**2

    def clamped_energy(passes: int) -> float:
        return (pass_settings(BASE, passes - 1).clamp_distance / BASE.clamp_distance) ** 2

    assert hot_spots(64) < 0.5 * hot_spots(4)
    assert clamped_energy(64) < 0.5 * clamped_energy(4)


def test_the_average_is_shown_after_every_pass(renderer) -> None:
    shown = []
    renderer.render_progressive(closed_sphere(), replace(BASE, passes=3),
                                on_pass=lambda r: shown.append((r.index, r.frame)))
    assert [index for index, _ in shown] == [1, 2, 3]
    assert all(np.isfinite(f.passes["Combined"]).all() for _, f in shown)


def test_passes_continue_one_light_path_sequence(renderer, monkeypatch) -> None:
    """Pass k traces the user's seed's light paths from where the passes before it ended (K
    passes: one stratified set of K·N paths), whatever seed its other choices take."""
    from addon.core.frame import vpl_stage

    traced = []

    def recording(*args, **kwargs):
        sequence = args[6] if len(args) > 6 else kwargs["sequence"]
        traced.append((sequence.seed, sequence.first, args[2].vpl_count))
        return generate(*args, **kwargs)

    generate = vpl_stage.generate_vpls
    monkeypatch.setattr(vpl_stage, "generate_vpls", recording)
    renderer.forget_frames()
    renderer.render_progressive(closed_sphere(), replace(BASE, passes=3, seed=7,
                                                         vpl_guidance="off"))
    assert traced == [(7, 0, 16), (7, 16, 16), (7, 32, 16)]


def test_time_limit_and_noise_threshold_stop_early(renderer) -> None:
    _, stats = renderer.render_progressive(closed_sphere(),
                                           replace(BASE, passes=50, time_limit=1e-3))
    assert stats.counts["passes"] == 1
    _, stats = renderer.render_progressive(closed_sphere(),
                                           replace(BASE, passes=50, noise_threshold=0.5))
    assert stats.counts["passes"] == 4  # the first estimate (4 passes) is already below 50 %


def test_cancelling_during_a_pass_raises(renderer) -> None:
    calls = []

    def cancelled() -> bool:
        calls.append(1)
        return len(calls) > 3

    with pytest.raises(RenderCancelled):
        renderer.render_progressive(closed_sphere(), replace(BASE, passes=50),
                                    cancelled=cancelled)


def test_noise_estimate_matches_the_noise_of_the_average() -> None:
    rng = np.random.default_rng(1)
    truth = np.full((64, 64, 4), 2.0, np.float32)
    accumulator = Accumulator()
    for _ in range(16):
        noisy = truth + rng.normal(0, 0.4, truth.shape).astype(np.float32)
        accumulator.add(Frame(64, 64, {"Combined": noisy}))
    average = accumulator.average().passes["Combined"][..., :3]
    actual = float(np.sqrt(np.mean((average - 2.0) ** 2))) / 2.0
    assert accumulator.noise() == pytest.approx(actual, rel=0.1)


def test_passes_of_unequal_size_are_averaged_by_their_weights() -> None:
    """Passes whose noise variance is 1 / weight (the time mode's passes of different light
    path counts) are averaged by weight: less noise than the plain mean, and the estimate
    still matches it."""
    rng = np.random.default_rng(2)
    truth = np.full((64, 64, 4), 2.0, np.float32)
    weights = [512, 181, 512, 181, 724, 181]
    weighted, plain = Accumulator(), Accumulator()
    for w in weights:
        noisy = truth + rng.normal(0, 8.0 / np.sqrt(w), truth.shape).astype(np.float32)
        weighted.add(Frame(64, 64, {"Combined": noisy}), weight=w)
        plain.add(Frame(64, 64, {"Combined": noisy}))

    def error(accumulator: Accumulator) -> float:
        average = accumulator.average().passes["Combined"][..., :3]
        return float(np.sqrt(np.mean((average - 2.0) ** 2))) / 2.0

    expected = 8.0 / np.sqrt(sum(weights)) / 2.0  # the inverse-variance average's
    assert error(weighted) == pytest.approx(expected, rel=0.05)
    assert error(plain) > 1.1 * error(weighted)
    assert weighted.noise() == pytest.approx(error(weighted), rel=0.1)


@pytest.mark.parametrize(("name", "value"), [("passes", 0), ("passes", -1),
                                             ("time_limit", float("nan")),
                                             ("time_limit", -1.0), ("noise_threshold", 2.0)])
def test_bad_pass_settings_are_refused_before_work_starts(renderer, name, value) -> None:
    with pytest.raises(SettingsError, match=name):
        renderer.render_progressive(closed_sphere(), replace(BASE, **{name: value}))


def test_passes_move_the_supersamples_so_edges_converge(renderer) -> None:
    """A strip's edge a third of the way into pixel column 8: one sample per pixel at its
    centre misses it, and passes whose samples move over the pixel cover a third of it."""
    size, extent = 16, 6.0
    pixel = extent / size
    edge = -extent / 2 + 8 * pixel + pixel / 3
    half = (edge + extent / 2) / 2
    strip = Instance(quad(half, extent), translation(edge - half, 0, 0),
                     [Material("strip", (0.5, 0.5, 0.5))])
    scene = Scene([strip], [], World(color=(1.0, 1.0, 1.0)), top_down_camera(size, extent),
                  film_transparent=True)
    settings = Settings(antialiasing=1, bounces=0, world_samples=4)
    one, _ = renderer.render_progressive(scene, settings)
    many, _ = renderer.render_progressive(scene, replace(settings, passes=32))
    assert np.all(one.passes["Combined"][:, 8, 3] == 0.0)
    np.testing.assert_allclose(many.passes["Combined"][:, 8, 3], 1 / 3, atol=0.04)
    np.testing.assert_array_equal(many.passes["Combined"][:, :8, 3], 1.0)


def test_pass_offsets_stay_within_a_supersample_and_centre_on_it() -> None:
    camera = top_down_camera(10)
    assert pass_camera(camera, 0, 2) is camera
    offsets = np.array([(pass_camera(camera, k, 2).projection_matrix
                         - camera.projection_matrix)[:2, 3] * 10 * 2 / 2 for k in range(1, 65)])
    assert np.all(np.abs(offsets) <= 0.5) and len(np.unique(offsets, axis=0)) == 64
    np.testing.assert_allclose(offsets.mean(axis=0), 0.0, atol=0.02)


ISM = replace(BASE, visibility="ism", ism_points=1024)  # the closed sphere: 1280 triangles


def test_passes_trace_visibility_from_the_set_pass_where_the_maps_undersample_the_scene(
        renderer) -> None:
    """From ``ray_traced_from_pass`` on a final render's passes are the passes the exact mode
    renders; with more ISM points than triangles, or 0, every pass reads the maps."""
    settings = replace(ISM, passes=3, ray_traced_from_pass=2)
    renderer.forget_frames()
    frame, stats = renderer.render_progressive(closed_sphere(), settings)
    assert "passes 2–3: VPL visibility ray traced (1024 ISM points for 1,280 triangles)" \
        in stats.notes
    renderer.forget_frames()
    one_by_one = [renderer.render(closed_sphere(), replace(settings, visibility=visibility),
                                  pass_index=index)[0].passes["Combined"].astype(np.float64)
                  for index, visibility in enumerate(["ism", "exact", "exact"])]
    np.testing.assert_allclose(frame.passes["Combined"], sum(one_by_one) / 3, rtol=1e-6,
                               atol=1e-7)
    assert ray_traced_from(replace(settings, ism_points=2048), 1280) is None
    assert ray_traced_from(replace(settings, ray_traced_from_pass=0), 1280) is None
    assert ray_traced_from(replace(settings, visibility="classic"), 1280) is None
    _, stats = renderer.render_progressive(closed_sphere(), replace(settings, ism_points=2048))
    assert stats.skipped["ray-traced visibility from pass 2"] == \
        "1,280 triangles: each ISM's 2048 points hold them"
    assert not any("ray traced" in note for note in stats.notes)


def test_a_time_limit_expects_the_first_ray_traced_pass_to_take_longer() -> None:
    assert expected_pass_seconds([1.0, 3.0], [], tracing=False) == 2.0
    assert expected_pass_seconds([1.0, 3.0], [], tracing=False, predicted=2.5) == 2.5
    assert expected_pass_seconds([1.0, 3.0], [], tracing=True) == 2.0 * EXACT_PASS_COST
    assert expected_pass_seconds([1.0, 3.0], [5.0, 6.0], tracing=True) == 5.5
    # a prediction of the first traced pass (the time mode's) replaces the rule of thumb
    assert expected_pass_seconds([1.0, 3.0], [], tracing=True, predicted=7.0) == 7.0
    # the caller's expectation wins over the passes so far (the time mode's traced passes,
    # chosen again from the first one's time, differ from it)
    assert expected_pass_seconds([1.0, 3.0], [5.0, 6.0], tracing=True, predicted=7.0) == 7.0
    assert expected_pass_seconds([], [5.0], tracing=True) == 5.0  # rays from the first pass


def test_rays_from_the_first_pass_render_every_pass_traced(renderer) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no mean of an empty list of mapped passes' times
        _, stats = renderer.render_progressive(closed_sphere(), replace(
            ISM, passes=2, ray_traced_from_pass=1, time_limit=1e5))
    assert "passes 1–2: VPL visibility ray traced (1024 ISM points for 1,280 triangles)" \
        in stats.notes

