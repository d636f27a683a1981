"""Bad input gives clear errors or warnings and finite images, never NaN, hangs or crashes."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from addon.core.frame.renderer import RenderCancelled, RenderError
from addon.core.scene.model import Instance, LightKind, Material, Mesh, Scene, World
from addon.core.settings import Settings, SettingsError
from tests.core.builders import floor_scene, light, quad, top_down_camera, translation


def assert_finite(frame) -> None:
    for name, image in frame.passes.items():
        assert np.isfinite(image).all(), name


def test_scene_without_camera_is_refused(renderer):
    scene = floor_scene([])
    scene.camera = None
    with pytest.raises(RenderError, match="no camera"):
        renderer.render(scene, Settings(bounces=0))


@pytest.mark.parametrize("name, value", [("light_samples", 0), ("shadow_resolution", 10**6),
                                         ("antialiasing", 0), ("shadow_bias", float("nan"))])
def test_settings_out_of_range_name_the_setting(name, value):
    with pytest.raises(SettingsError, match=name):
        Settings(**{name: value}).validate()


def test_nan_vertices_are_left_out_with_a_warning(renderer):
    broken = quad(0.5, 0.5, z=1.0)
    broken.positions[0] = np.nan
    scene = floor_scene([light(LightKind.POINT, translation(0, 0, 2), power=10.0)],
                        extra=[Instance(broken, np.eye(4), [Material("m")])])
    frame, stats = renderer.render(scene, Settings(bounces=0, antialiasing=1))
    assert_finite(frame)
    assert any("NaN/Inf positions" in w for w in stats.warnings)
    assert frame.passes["DiffDir"].max() > 0


def test_nan_light_is_left_out_with_a_warning(renderer):
    bad = light(LightKind.POINT, translation(0, 0, np.nan), power=10.0)
    good = light(LightKind.POINT, translation(0, 0, 2), power=10.0)
    frame, stats = renderer.render(floor_scene([bad, good]), Settings(bounces=0, antialiasing=1))
    assert_finite(frame)
    assert any("NaN/Inf" in w for w in stats.warnings)


def test_zero_size_area_light_still_lights_and_warns(renderer):
    area = light(LightKind.AREA, translation(0, 0, 2), power=50.0, size_x=0.0)
    frame, stats = renderer.render(floor_scene([area]), Settings(bounces=0, antialiasing=1))
    assert_finite(frame)
    assert frame.passes["DiffDir"].max() > 0
    assert any("zero or negative size" in w for w in stats.warnings)


def test_degenerate_and_empty_meshes_render(renderer):
    needle = Mesh("needle", np.zeros((3, 3), np.float32), np.zeros((3, 3), np.float32),
                  np.zeros(1, np.int32))
    empty = Mesh("empty", np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32),
                 np.zeros(0, np.int32))
    scene = floor_scene([light(LightKind.POINT, translation(0, 0, 2), power=10.0)],
                        extra=[Instance(needle, np.eye(4), []), Instance(empty, np.eye(4), [])])
    frame, _ = renderer.render(scene, Settings(bounces=0, antialiasing=1))
    assert_finite(frame)


def test_scene_with_nothing_shows_the_world(renderer):
    scene = Scene([], [], World((0.1, 0.2, 0.3), 1.0), floor_scene([]).camera)
    frame, _ = renderer.render(scene, Settings(bounces=0, antialiasing=1))
    np.testing.assert_allclose(frame.passes["Combined"][0, 0], [0.1, 0.2, 0.3, 1.0], rtol=1e-6)
    assert np.all(frame.passes["Depth"] == 1e10)


@pytest.mark.parametrize("power", [1e-8, 1e12])
def test_extreme_powers_scale_linearly(renderer, power):
    reference, _ = renderer.render(
        floor_scene([light(LightKind.POINT, translation(0, 0, 2), power=1.0)]),
        Settings(bounces=0, antialiasing=1))
    frame, _ = renderer.render(
        floor_scene([light(LightKind.POINT, translation(0, 0, 2), power=power)]),
        Settings(bounces=0, antialiasing=1))
    assert_finite(frame)
    np.testing.assert_allclose(frame.passes["DiffDir"], reference.passes["DiffDir"] * power,
                               rtol=1e-5)


def test_cancel_stops_the_render(renderer):
    with pytest.raises(RenderCancelled):
        renderer.render(floor_scene([light(LightKind.POINT, translation(0, 0, 2))]),
                        Settings(bounces=0),
                        cancelled=lambda: True)


@pytest.mark.parametrize("change, reason", [
    ({"bounces": 0}, "bounces = 0"),
    ({"albedo": 0.0}, "every albedo is 0"),
    ({"power": 0.0}, "nothing emits light"),
])
def test_indirect_light_is_left_out_when_the_scene_does_not_need_it(renderer, change, reason):
    power = change.get("power", 10.0)
    scene = floor_scene([light(LightKind.POINT, translation(0, 0, 2), power=power)],
                        albedo=change.get("albedo", 0.8))
    frame, stats = renderer.render(scene, Settings(antialiasing=1,
                                                   bounces=change.get("bounces", 2)))
    assert stats.skipped["indirect light"] == reason
    assert stats.counts["vpls"] == 0 and np.all(frame.passes["DiffInd"] == 0)
    assert "skipped: indirect light" in stats.summary()


def test_a_view_narrower_than_float32_resolves_has_no_nan_rows(renderer):
    """An orthographic view 10 µm wide, a metre and a half from the origin, of a floor under
    an area light (shadow-mapped, supersampled): neighbouring supersamples' positions are
    equal in float32 there, so the geometric normal taken from their differences was NaN
    (whole rows of pixels, zeroed into dark rows with a warning). The floor is lit evenly."""
    area = light(LightKind.AREA, translation(1, 1, 2), power=50.0, size_x=0.5)
    scene = floor_scene([area], size=32)
    scene.camera = replace(top_down_camera(32, extent=1e-5),
                           view_matrix=translation(-1.0, -1.0, -5.0))
    frame, stats = renderer.render(scene, Settings(bounces=0))
    assert not any("non-finite" in w for w in stats.warnings)
    direct = frame.passes["DiffDir"][..., :3]
    assert direct.min() > 0.99 * direct.max() > 0
