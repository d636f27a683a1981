"""The Vector pass of a rendered frame: a box moving over a still floor, then the camera
moving over both (orthographic, from above: a metre is 32 / 6 pixels)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from addon.core.scene.model import Instance, LightKind, Material, MotionSpan
from addon.core.settings import Settings
from tests.core.builders import floor_scene, light, pixel_centres, quad, translation

PIXELS_PER_METRE = 32 / 6


def moving_box_scene():
    box = Instance(quad(1.0, 1.0, z=0.5), translation(0.3, 0.0, 0.0),
                   [Material("red", (0.8, 0.1, 0.1))],
                   motion=(translation(0.0, -0.3, 0.0), translation(0.6, 0.3, 0.0)))
    scene = floor_scene([light(LightKind.SUN, np.eye(4), power=3.0)], extra=[box], size=32)
    scene.motion = MotionSpan()
    return scene


def test_a_moving_box_has_vectors_and_the_still_floor_none(renderer):
    frame, _ = renderer.render(moving_box_scene(), Settings(antialiasing=3, bounces=0),
                               passes=frozenset({"Vector"}))
    vectors = frame.passes["Vector"]
    x, y = pixel_centres(32)
    inside = (np.abs(x - 0.3) < 0.8) & (np.abs(y) < 0.8)
    outside = ~((np.abs(x - 0.3) < 1.2) & (np.abs(y) < 1.2))
    # previous - now: (-0.3, -0.3) m; now - next: (-0.3, -0.3) m
    np.testing.assert_allclose(vectors[inside], np.full((inside.sum(), 4), -0.3 *
                                                        PIXELS_PER_METRE), atol=1e-3)
    assert np.all(vectors[outside] == 0.0)


def test_a_deforming_mesh_moves_with_its_vertices(renderer):
    """A quad whose corners stretch it along x (each x doubles by the next time and halves
    back before: Mesh.deform) in an instance turned 90° about z that moves by +0.2 m in y
    by each time: a point at x_w = -y (local), y_w = x gets vectors from both."""
    quad_mesh = quad(1.0, 1.0, z=0.5)
    local = quad_mesh.positions.astype(np.float64)
    stretch = np.zeros((2, len(local), 3), np.float32)
    stretch[0, :, 0] = -0.5 * local[:, 0]  # before: x / 2
    stretch[1, :, 0] = local[:, 0]  # after: 2 x
    turn = np.array([[0, -1, 0, 0], [1, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], float)
    sheet = Instance(replace(quad_mesh, deform=stretch), turn, [Material("red")],
                     motion=(translation(0, -0.2, 0) @ turn, translation(0, 0.2, 0) @ turn))
    scene = floor_scene([light(LightKind.SUN, np.eye(4), power=3.0)], extra=[sheet], size=32)
    scene.motion = MotionSpan()
    frame, _ = renderer.render(scene, Settings(antialiasing=3, bounces=0),
                               passes=frozenset({"Vector"}))
    vectors = frame.passes["Vector"] / PIXELS_PER_METRE
    x, y = pixel_centres(32)
    inside = (np.abs(x) < 0.8) & (np.abs(y) < 0.8)
    # world y = local x: before at y/2 - 0.2, after at 2y + 0.2
    expected = np.stack([np.zeros_like(y), -0.5 * y - 0.2, np.zeros_like(y), -y - 0.2], -1)
    np.testing.assert_allclose(vectors[inside], expected[inside], atol=1e-3)
    assert np.all(vectors[~((np.abs(x) < 2.2) & (np.abs(y) < 2.2))] == 0.0)


def test_a_moving_camera_moves_everything(renderer):
    scene = moving_box_scene()
    scene.instances[1].motion = None
    camera = scene.camera
    scene.camera = replace(camera, motion_views=(camera.view_matrix @ translation(0.5, 0, 0),
                                                 camera.view_matrix @ translation(-0.5, 0, 0)))
    frame, _ = renderer.render(scene, Settings(antialiasing=3, bounces=0),
                               passes=frozenset({"Vector"}))
    # the camera at x - 0.5 before and x + 0.5 after: the world moves +0.5 m, then -0.5 m
    expected = np.array([0.5, 0.0, 0.5, 0.0]) * PIXELS_PER_METRE
    np.testing.assert_allclose(frame.passes["Vector"].reshape(-1, 4),
                               np.broadcast_to(expected, (32 * 32, 4)), atol=1e-3)


def test_motion_blur_hands_out_only_the_passes_asked_for(renderer):
    """Motion blur reads Depth and Vector (the planner adds them): they are returned only
    when asked for."""
    scene = moving_box_scene()
    scene.motion = MotionSpan(-0.25, 0.25, blur=True)
    settings = Settings(antialiasing=2, bounces=0)
    frame, stats = renderer.render(scene, settings, passes=frozenset({"Combined"}))
    assert set(frame.passes) == {"Combined"} and stats.counts["motion-blurred pixels"] > 0
    frame, _ = renderer.render(scene, settings, passes=frozenset({"Depth"}))
    assert set(frame.passes) == {"Combined", "Depth"}
