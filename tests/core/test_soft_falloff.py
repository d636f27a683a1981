"""Cycles' Soft Falloff of point and spot lights (on by default in Blender): the light of a
sphere of radius r dims by d² / (d² + r²) at distance d from its centre, in direct light
and at the first hits of its light paths (transport/lights.py soft_falloff)."""

from __future__ import annotations

import numpy as np
import pytest

from addon.core.frame.reuse import settings_key
from addon.core.frame.vpl_stage import INCREMENTAL_FIELDS
from addon.core.scene.geometry import bounding_sphere, flatten_instances
from addon.core.scene.model import LightKind
from addon.core.settings import Settings
from addon.core.transport.incremental import IncrementalVPLs
from addon.core.transport.vpl import generate_vpls
from tests.core.builders import floor_scene, light, pixel_centres, translation

HEIGHT, RADIUS = 1.0, 0.6


def lamp(soft_falloff: bool):
    return light(LightKind.POINT, translation(0, 0, HEIGHT), power=100.0, radius=RADIUS,
                 soft_falloff=soft_falloff)


def test_direct_light_dims_by_the_distance_to_the_centre(renderer):
    """The same light samples with and without Soft Falloff: per pixel, their ratio is
    d² / (d² + r²) (0.74 under the lamp, 0.98 at the image's corners)."""
    settings = Settings(bounces=0, antialiasing=1)
    images = [renderer.render(floor_scene([lamp(soft)]), settings)[0].passes["DiffDir"][..., 0]
              for soft in (True, False)]
    x, y = pixel_centres()
    distance2 = x**2 + y**2 + HEIGHT**2
    np.testing.assert_allclose(images[0] / images[1], distance2 / (distance2 + RADIUS**2),
                               rtol=1e-4)


@pytest.mark.parametrize("incremental", [False, True])
def test_light_paths_first_hits_dim_by_the_distance_to_the_centre(renderer, incremental):
    """The same light paths with and without Soft Falloff (plain, or Incremental Instant
    Radiosity's anchors): each first-bounce VPL's intensity keeps d² / (d² + r²) of its
    light."""
    renderer.forget_frames()  # the tracer is given other triangles than the frames' here
    settings = Settings(bounces=1, vpl_count=256, seed=3, incremental=incremental)
    vpls = []
    for soft in (True, False):
        scene = floor_scene([lamp(soft)])
        geometry = flatten_instances(scene, [])
        centre, radius = bounding_sphere(geometry.positions)
        renderer.tracer.upload(geometry.positions.reshape(-1, 3, 3))
        if incremental:
            vpls.append(IncrementalVPLs().update(
                scene, geometry, settings, renderer.tracer, centre, radius, shape_version=0,
                key=settings_key(settings, INCREMENTAL_FIELDS)))
        else:
            vpls.append(generate_vpls(scene, geometry, settings, renderer.tracer, centre,
                                      radius))
    renderer.forget_frames()
    soft, sphere = vpls
    np.testing.assert_allclose(soft.position, sphere.position)
    distance2 = ((soft.position - [0.0, 0.0, HEIGHT]) ** 2).sum(axis=1)
    assert len(soft) > 100 and distance2.min() < 1.1 * HEIGHT**2
    np.testing.assert_allclose(soft.intensity, sphere.intensity
                               * (distance2 / (distance2 + RADIUS**2))[:, None], rtol=1e-5)
