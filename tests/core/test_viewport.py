"""The viewport session, headless: change classification, progressive frames, what each kind
of edit re-runs, display modes, cancellation and release."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from addon.core.frame.renderer import Renderer
from addon.core.scene.model import Instance, LightKind, Material
from addon.core.settings import Settings
from addon.core.viewport_session import (
    Changes,
    Update,
    ViewportSession,
    classify,
    display_image,
    quick_settings,
    refinement_levels,
)
from devtools import metrics
from tests.core.builders import floor_scene, icosphere, light, top_down_camera, translation

# shadow maps for direct light: the tests follow what edits keep (a ray-traced light keeps
# nothing and is traced again after every edit)
SETTINGS = Settings(vpl_count=128, bounces=2, ism_points=1024, interleave=1,
                    direct_shadows="shadow_maps", viewport_passes=1)


def scene(light_x: float = 0.0, ball_colour=(0.8, 0.2, 0.2)):
    ball = Instance(icosphere(0.5, 2), translation(0.5, 0.5, 0.5), [Material("ball",
                                                                          ball_colour)])
    return floor_scene([light(LightKind.POINT, translation(light_x, 0, 2), power=100.0)],
                       extra=[ball], size=192)


@pytest.mark.parametrize(("updates", "expected"), [
    ([Update("OBJECT", "Camera", "CAMERA", transform=True)], "camera"),
    ([Update("OBJECT", "Lamp", "LIGHT", transform=True), Update("SCENE", "Scene")],
     "lights+settings"),
    ([Update("LIGHT", "Lamp")], "lights"),
    ([Update("OBJECT", "Cube", "MESH", transform=True)], "transforms"),
    ([Update("OBJECT", "Cube", "MESH", geometry=True),
      Update("MESH", "Cube.001", geometry=True)], "geometry"),
    ([Update("MESH", "Cube.001", shading=True)], "materials"),
    ([Update("MATERIAL", "Red", shading=True),
      Update("OBJECT", "Wall", "MESH", shading=True)], "materials"),
    ([Update("OBJECT", "Wall", "MESH")], "transforms"),
    ([Update("WORLD", "World")], "world"),
    ([], "nothing"),
])
def test_depsgraph_updates_are_classified(updates, expected):
    changes = classify(updates)
    assert changes.describe() == expected
    assert changes.needs_export == (expected not in ("camera", "nothing"))
    if expected == "geometry":
        assert changes.geometry == {"Cube", "Cube.001"}


def test_levels_refine_to_full_resolution():
    """The first level has at most 64² pixels (Cycles' Start Resolution), or 1/8 of each
    edge, and each next one doubles the resolution."""
    assert refinement_levels(top_down_camera(800)) == [8, 4, 2, 1]
    assert refinement_levels(replace(top_down_camera(640), height=360)) == [8, 4, 2, 1]
    assert refinement_levels(top_down_camera(200)) == [4, 2, 1]
    assert refinement_levels(top_down_camera(128)) == [2, 1]
    assert refinement_levels(top_down_camera(50)) == [1]


@pytest.fixture
def session():
    s = ViewportSession()
    yield s
    s.close()
    assert not s.alive


def run(session: ViewportSession, changes: Changes, **kwargs):
    session.edit(changes, **kwargs)
    assert session.wait_idle(300), "the viewport did not finish"
    assert session.error is None, session.error
    return session.records[-1], session.latest()


def test_edits_rerun_only_what_they_change(session):
    first, frame = run(session, Changes(settings=True), scene=scene(), camera=scene().camera,
                       settings=SETTINGS)
    assert frame.level == frame.levels - 1 == 2 and frame.image.shape == (192, 192, 4)
    assert "vpl generation (incremental)" in first.ran and "ism splat" in first.ran
    assert np.isfinite(frame.image).all() and frame.image[..., :3].mean() > 0

    moved_view = top_down_camera(192, extent=5.0)
    camera_only, frame = run(session, Changes(camera=True), camera=moved_view)
    assert not any(k.startswith(("vpl", "ism", "ray tracing")) for k in camera_only.ran)
    assert {"vpl generation", "ism", "ray tracing setup", "shadow maps"} <= set(
        camera_only.skipped)
    assert camera_only.latency < first.latency

    light_move, frame = run(session, Changes(lights=True), scene=scene(light_x=0.05))
    assert "vpl generation (incremental)" in light_move.ran
    assert "ray tracing setup" in light_move.skipped
    assert light_move.counts["vpls_reused"] > light_move.counts["vpls_new"]
    assert light_move.counts["isms_rendered"] == light_move.counts["vpls_new"]

    recolour, _ = run(session, Changes(materials=True),
                      scene=scene(light_x=0.05, ball_colour=(0.2, 0.8, 0.2)))
    assert "ray tracing setup" in recolour.skipped  # triangle positions are unchanged
    assert recolour.counts["isms_rendered"] < recolour.counts["vpls"] // 2


def test_display_modes_split_the_combined_image(session):
    _, frame = run(session, Changes(settings=True), scene=scene(), camera=scene().camera,
                   settings=SETTINGS)
    combined = frame.image
    _, direct = run(session, Changes(display=True), display="direct")
    _, indirect = run(session, Changes(display=True), display="indirect")
    total = direct.image[..., :3] + indirect.image[..., :3]
    assert np.allclose(total, combined[..., :3], rtol=1e-4, atol=1e-6)
    _, dots = run(session, Changes(display=True), display="vpls")
    changed = np.any(dots.image != combined, axis=-1)
    assert changed.sum() > 100  # VPL dots painted
    _, atlas = run(session, Changes(display=True), display="ism")
    assert atlas.image.shape == combined.shape and 0 < atlas.image[..., 0].mean() < 1


def test_a_new_edit_cancels_the_frame_in_progress(session):
    slow = Settings(vpl_count=2048, bounces=3, visibility="exact", interleave=1)
    session.edit(Changes(settings=True), scene=scene(), camera=scene().camera, settings=slow)
    session.edit(Changes(settings=True), settings=SETTINGS)
    assert session.wait_idle(300)
    assert session.latest().edit == 2
    assert session.records[0].converged is None  # the first edit never finished


def test_close_releases_the_worker_and_its_gpu_objects():
    made: list[Renderer] = []

    def factory() -> Renderer:
        from addon.core.gpu.gl import create_context
        made.append(Renderer(create_context()))
        return made[-1]

    session = ViewportSession(renderer_factory=factory)
    run(session, Changes(settings=True), scene=scene(), camera=scene().camera,
        settings=SETTINGS)
    session.close()
    assert not session.alive
    assert made[0].gpu.helpers == () and made[0].last_vpls is None


def test_display_image_rejects_nothing_and_keeps_alpha():
    frame_passes = {name: np.ones((4, 4, c), np.float32) for name, c in
                    {"Combined": 4, "DiffDir": 3, "DiffInd": 3, "DiffCol": 3, "Emit": 3}.items()}
    from addon.core.frame.result import Frame
    frame = Frame(4, 4, frame_passes)
    for mode in ("combined", "direct", "indirect", "vpls", "ism"):
        image = display_image(frame, mode, top_down_camera(4))
        assert image.shape == (4, 4, 4) and np.all(image[..., 3] == 1)


def test_kept_shadow_maps_give_the_same_image(renderer):
    mapped = replace(SETTINGS, direct_shadows="shadow_maps")
    renderer.forget_frames()
    first, _ = renderer.render(scene(), mapped)
    again, stats = renderer.render(scene(), mapped)
    assert "shadow maps" in stats.skipped
    np.testing.assert_array_equal(first.passes["Combined"], again.passes["Combined"])
    _, moved = renderer.render(scene(light_x=0.3), mapped)
    assert "shadow maps" not in moved.skipped
    renderer.forget_frames()


def test_an_edit_that_regenerates_starts_with_fewer_paths(session):
    first, frame = run(session, Changes(settings=True), scene=scene(), camera=scene().camera,
                       settings=SETTINGS)
    assert Changes(settings=True).regenerates and not Changes(lights=True).regenerates
    assert first.counts["vpls"] < 0.75 * frame.stats.counts["vpls"]  # 64 paths, then 128
    light_move, _ = run(session, Changes(lights=True), scene=scene(light_x=0.05))
    assert light_move.counts["vpls_reused"] > 0  # full count from its first frame: reused


def test_edits_that_redraw_shadow_maps_start_with_fewer_light_samples(session):
    """A regenerating edit's or a light edit's first frame draws a quarter of an area light's
    samples (each a shadow map), the later levels all of them; an edit that keeps the maps
    keeps all samples."""
    lit = floor_scene([light(LightKind.AREA, translation(0, 0, 2), power=100.0, size_x=0.5)],
                      size=192)
    settings = replace(SETTINGS, light_samples=16)
    first, frame = run(session, Changes(settings=True), scene=lit, camera=lit.camera,
                       settings=settings)
    assert (first.counts["light_samples"], frame.stats.counts["light_samples"]) == (4, 16)
    assert np.isfinite(frame.image).all() and frame.image[..., :3].mean() > 0
    moved = floor_scene([light(LightKind.AREA, translation(0.05, 0, 2), power=100.0,
                               size_x=0.5)], size=192)
    light_move, frame = run(session, Changes(lights=True), scene=moved)
    assert (light_move.counts["light_samples"], frame.stats.counts["light_samples"]) == (4, 16)
    assert light_move.counts["vpls_reused"] > 0  # the VPLs do not read the light samples
    recolour, _ = run(session, Changes(materials=True), scene=moved)
    assert recolour.counts["light_samples"] == 16  # its shadow maps are kept: all samples


def test_idle_passes_converge_and_an_edit_starts_over(renderer):
    """While nothing changes the viewport adds passes with their own VPLs and shows their
    average: its error against a many-VPL reference falls; an edit starts at one pass again."""
    settings = replace(SETTINGS, vpl_count=64, viewport_passes=8)
    renderer.forget_frames()
    reference, _ = renderer.render_progressive(scene(), replace(
        settings, antialiasing=1, vpl_count=1024, passes=16))
    truth = reference.passes["DiffInd"] * reference.passes["DiffCol"]
    frames = []
    session = ViewportSession(on_frame=lambda: frames.append(session.latest()))
    try:
        run(session, Changes(settings=True), scene=scene(), camera=scene().camera,
            settings=settings, display="indirect")
        full = [f for f in frames if f.image.shape[:2] == truth.shape[:2]]
        assert [f.passes for f in full] == list(range(1, 9))
        error = [metrics.relative_rmse(f.image, truth) for f in full]
        assert error[-1] < 0.6 * error[0], error
        assert session.records[-1].passes == 8

        frames.clear()
        record, last = run(session, Changes(camera=True),
                           camera=top_down_camera(192, extent=5.0))
        assert frames[0].passes == 1 and frames[0].edit == last.edit == 2
        assert last.passes == record.passes == 8
    finally:
        session.close()


def test_the_idle_passes_renderer_compiles_no_program_the_edit_renderer_has(renderer):
    """The viewport's second renderer (idle passes), made as the session makes it, before
    the first has compiled anything, uses the first's programs, and releasing it leaves them
    to the first."""
    settings = replace(SETTINGS, antialiasing=1)
    edit = Renderer(renderer.ctx)
    idle = Renderer(renderer.ctx, share_programs_of=edit)
    try:
        programs = edit.gpu.programs
        assert idle.gpu.programs is programs
        edit.render(scene(), settings)
        compiled = len(programs)
        idle_frame, _ = idle.render(scene(), replace(settings, seed=1))
        assert np.isfinite(idle_frame.passes["Combined"]).all()
        assert len(programs) == compiled
        idle.release()
        again, _ = edit.render(scene(), settings)
        assert np.isfinite(again.passes["Combined"]).all()
        assert again.passes["Combined"][..., :3].mean() > 0
    finally:
        idle.release()
        edit.release()


def test_quick_settings_cut_only_what_the_edit_redraws():
    """A regenerating edit's first frame takes fewer paths, points, 64² maps and a quarter of
    every kind of direct-light sample; a light edit only the lights' samples (the world's
    and emission's shadow maps and the ISMs are kept); a camera edit nothing."""
    full = Settings(vpl_count=1024, ism_points=8192, ism_resolution=128, light_samples=16,
                    world_samples=64, emission_samples=64)
    moved = quick_settings(full, Changes(transforms=True))
    assert (moved.vpl_count, moved.ism_points, moved.ism_resolution) == (128, 2048, 64)
    assert (moved.light_samples, moved.world_samples, moved.emission_samples) == (4, 16, 16)
    lit = quick_settings(full, Changes(lights=True))
    assert lit == replace(full, light_samples=4)
    assert quick_settings(full, Changes(camera=True)) == full
    few = replace(full, light_samples=2, ism_resolution=32)
    assert quick_settings(few, Changes(settings=True)).light_samples == 2  # never more
    assert quick_settings(few, Changes(settings=True)).ism_resolution == 32


def test_idle_passes_trace_visibility_from_the_set_pass_as_final_renders_do(renderer,
                                                                             monkeypatch):
    """The floor and ball (322 triangles) with 256 points per ISM: idle passes from
    ``ray_traced_from_pass`` on render with ray-traced visibility; with 1024 points, none."""
    seen = []
    render = Renderer.render

    def recording(self, scene, settings, *args, pass_index: int = 0, **kwargs):
        seen.append((pass_index, settings.visibility))
        return render(self, scene, settings, *args, pass_index=pass_index, **kwargs)

    monkeypatch.setattr(Renderer, "render", recording)
    for points, expected in ((256, ["ism", "ism", "exact", "exact"]), (1024, ["ism"] * 4)):
        seen.clear()
        settings = replace(SETTINGS, ism_points=points, viewport_passes=4, ray_traced_from_pass=3)
        session = ViewportSession()
        try:
            run(session, Changes(settings=True), scene=scene(), camera=scene().camera,
                settings=settings, display="indirect")
        finally:
            session.close()
        full_size = [visibility for index, visibility in seen if index > 0]
        assert [v for i, v in seen if i == 0][-1] == "ism"
        assert full_size == expected[1:], seen
