"""The ray probe the automatic mode scales its bias compensation prediction by."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from addon.core.frame.ray_probe import ray_probe_seconds, visibility_probe_seconds
from addon.core.scene.geometry import bounding_sphere, flatten_instances
from tests.core.builders import floor_scene, rotation_x


def test_the_probe_times_rays_from_what_the_camera_sees_and_none_where_it_sees_nothing(tracer):
    scene = floor_scene([])
    geometry = flatten_instances(scene, [])
    _, radius = bounding_sphere(geometry.positions)
    tracer.upload(geometry.positions.reshape(-1, 3, 3))
    assert ray_probe_seconds(scene.camera, geometry, tracer, radius, 0.1 * radius) > 0.0
    up = replace(scene.camera, view_matrix=rotation_x(np.pi) @ scene.camera.view_matrix)
    assert ray_probe_seconds(up, geometry, tracer, radius, 0.1 * radius) == 0.0


def test_the_visibility_probe_times_rays_to_the_targets_and_none_without_them(tracer):
    scene = floor_scene([])
    geometry = flatten_instances(scene, [])
    _, radius = bounding_sphere(geometry.positions)
    tracer.upload(geometry.positions.reshape(-1, 3, 3))
    above = np.array([[0.0, 0.0, 2.0], [1.0, -1.0, 1.0]])
    assert visibility_probe_seconds(scene.camera, geometry, tracer, radius, above) > 0.0
    assert visibility_probe_seconds(scene.camera, geometry, tracer, radius,
                                    np.zeros((0, 3))) == 0.0
    up = replace(scene.camera, view_matrix=rotation_x(np.pi) @ scene.camera.view_matrix)
    assert visibility_probe_seconds(up, geometry, tracer, radius, above) == 0.0
