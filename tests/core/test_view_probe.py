"""Shadow-mapped light samples that light no point the camera sees are left out
(transport/view_probe.py, frame/stages.py): which samples a ray from camera points reaches,
and a frame without the left-out samples' maps against one with them."""

from __future__ import annotations

import numpy as np

from addon.core.frame import stages
from addon.core.scene.model import Instance, Material, World
from addon.core.settings import Settings
from addon.core.transport.guidance import CameraPoints
from addon.core.transport.lights import (
    KIND_COSINE,
    KIND_COSINE2,
    KIND_DIRECTIONAL,
    KIND_OMNI,
    LightSamples,
)
from addon.core.transport.view_probe import reaches_view
from tests.core.builders import floor_scene, quad, translation


def samples(rows: list[tuple[int, tuple, tuple, bool]]) -> LightSamples:
    """Light samples of (kind, position, axis, casts shadow) rows."""
    n = len(rows)
    axis = np.array([r[2] for r in rows], float)
    return LightSamples(
        position=np.array([r[1] for r in rows], float),
        axis=axis / np.linalg.norm(axis, axis=1, keepdims=True),
        kind=np.array([r[0] for r in rows]),
        intensity=np.ones((n, 3)), spot_cos=np.full(n, -2.0), spot_smooth=np.zeros(n),
        casts_shadow=np.array([r[3] for r in rows]), resolution=np.full(n, 256),
        generation=np.zeros(n, int), soft=np.ones(n, bool), spread=np.zeros((n, 2)))


def test_a_ray_from_some_camera_point_decides(tracer):
    """Floor points under a roof (z = 1, x up to 2): light from above is blocked, light from
    low in +x comes in under the roof's edge, light from below the floor never arrives; a point
    light under the roof reaches them, one above it does not, unless it casts no shadow or is
    an area light's sample (kept with the others of its light); a one-sided emitter under the
    roof facing up lights nothing below it, one facing down does, and an emissive triangle's
    sample (two-sided) does either way."""
    floor = quad(5, 5).positions
    roof = quad(3.5, 5, z=1.0).positions + np.array([-1.5, 0.0, 0.0], np.float32)
    tracer.upload(np.concatenate([floor, roof]).reshape(-1, 3, 3))
    x, y = np.meshgrid(np.linspace(0.5, 1.5, 8), np.linspace(-1, 1, 8))
    position = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    up = np.tile([0.0, 0.0, 1.0], (len(position), 1))
    points = CameraPoints(position, up, np.full_like(position, 0.5))
    low = (-np.cos(np.radians(20)), 0.0, -np.sin(np.radians(20)))  # travelling towards -x
    rows = [(KIND_DIRECTIONAL, (0, 0, 0), (0, 0, -1), True),  # from straight above
            (KIND_DIRECTIONAL, (0, 0, 0), low, True),  # low, from +x
            (KIND_DIRECTIONAL, (0, 0, 0), (0, 0, 1), True),  # from below the floor
            (KIND_OMNI, (1, 0, 0.5), (0, 0, 1), True),  # under the roof
            (KIND_OMNI, (1, 0, 3.0), (0, 0, 1), True),  # above it
            (KIND_OMNI, (1, 0, 3.0), (0, 0, 1), False),  # above it, no shadow
            (KIND_COSINE, (1, 0, 0.5), (0, 0, 1), True),  # facing up, away from the floor
            (KIND_COSINE, (1, 0, 0.5), (0, 0, -1), True),  # facing the floor
            (KIND_COSINE2, (1, 0, 0.5), (0, 0, 1), True)]  # emissive, its normal up
    reached = reaches_view(samples(rows), points, tracer, 1e-4)
    np.testing.assert_array_equal(reached,
                                  [False, True, False, True, False, True, False, True, True])
    of_area_lights = samples(rows)
    of_area_lights.shape = np.array([-1, -1, -1, -1, 0, -1, -1, -1, -1])  # an area light's
    reached = reaches_view(of_area_lights, points, tracer, 1e-4)
    np.testing.assert_array_equal(reached,
                                  [False, True, False, True, True, True, False, True, True])


def room_with_a_window_scene():
    """A floor under a roof with an opening: the world lights the floor through it, from a few
    of its directions only."""
    roof = [Instance(quad(5, 2, z=1.0), translation(0, y, 0), [Material("roof")])
            for y in (-3.0, 3.0)]  # a 2 m gap along x between y = -1 and 1
    return floor_scene([], extra=roof, world=World((1.0, 1.0, 1.0)))


def test_a_frame_without_the_unreaching_samples_maps_matches_one_with_them(renderer,
                                                                           monkeypatch):
    """Bit for bit, without interleaving (with it, the world's samples move to other cells of
    the pattern: measured 0.9 % energy, all of it at the image border, where the blur removes
    the pattern only in part)."""
    scene = room_with_a_window_scene()
    settings = Settings(bounces=1, world_samples=64, interleave=1)  # VPLs build the tracer
    probed, stats = renderer.render(scene, settings)
    skipped = [k for k in stats.skipped if k.endswith("shadow-mapped light samples")]
    assert skipped, stats.skipped
    assert "view probe" in stats.timings
    assert 16 <= int(skipped[0].split()[0]) < 64  # the roof blocks much of the sky, not all
    monkeypatch.setattr(stages, "PROBE_MIN_SAMPLES", 10**9)
    full, stats = renderer.render(scene, settings)
    assert not any(k.endswith("shadow-mapped light samples") for k in stats.skipped)
    assert full.passes["Combined"][..., :3].mean() > 0.01
    for name, image in full.passes.items():
        np.testing.assert_array_equal(probed.passes[name], image, err_msg=name)
