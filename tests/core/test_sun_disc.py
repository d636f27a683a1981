"""Sun discs taken out of environment maps as sun lights: the light's direction, size and
irradiance against the disc painted into a map, turned maps, the map's light kept once, maps
without a disc left alone, and the disc still seen by the camera."""

from __future__ import annotations

import math

import numpy as np
import pytest

from addon.core.scene import environment
from addon.core.scene.environment import pixel_solid_angles
from addon.core.scene.model import EnvironmentMap, LightKind, World
from addon.core.scene.sun_disc import map_power, take_out_map_sun
from tests.core.builders import inside_sphere_camera
from tests.core.test_environment import pixel_directions

ELEVATION, AZIMUTH = math.radians(30), math.radians(70)
RADIUS = math.radians(0.5)  # the disc's angular radius: about 6 texels wide at 2048
SUN_RADIANCE = 2.0e4


def towards(elevation: float, azimuth: float) -> np.ndarray:
    return np.array([math.cos(elevation) * math.cos(azimuth),
                     math.cos(elevation) * math.sin(azimuth), math.sin(elevation)])


def sky_map(rotation: float = 0.0, sun: float = SUN_RADIANCE, width: int = 2048
            ) -> EnvironmentMap:
    """A sky of radiance 1 above, 0.2 below, and a disc of ``sun`` at ELEVATION, AZIMUTH."""
    d = pixel_directions(width // 2, width, rotation)
    radiance = np.where(d[..., 2:3] > 0, 1.0, 0.2) * np.ones(3)
    inside = d @ towards(ELEVATION, AZIMUTH) > math.cos(RADIUS)
    radiance[inside] = sun * np.array([1.0, 0.9, 0.7])
    return EnvironmentMap(radiance.astype(np.float32), rotation)


@pytest.mark.parametrize("rotation", [0.0, 1.3])
def test_the_disc_becomes_a_sun_light_of_its_direction_size_and_irradiance(rotation):
    env = sky_map(rotation)
    before = map_power(env)
    height, width = env.radiance.shape[:2]
    solid = np.broadcast_to(pixel_solid_angles(height, width)[:, None], (height, width))
    painted = float(solid[env.radiance[..., 0] > 1.0].sum()) * SUN_RADIANCE  # its irradiance
    sun = take_out_map_sun(env, "Sky sun disc")
    assert sun is not None and sun.kind is LightKind.SUN and sun.name == "Sky sun disc"
    axis = sun.matrix[:3, 2]
    assert np.degrees(np.arccos(np.clip(axis @ towards(ELEVATION, AZIMUTH), -1, 1))) < 0.05
    assert sun.sun_angle == pytest.approx(2 * RADIUS, rel=0.05)
    assert sun.power == pytest.approx(painted, rel=1e-4)
    np.testing.assert_allclose(sun.color, [1.0, 0.9, 0.7], rtol=1e-4)
    # the map keeps the sky (1 where the disc was), and map + light hold the light once
    assert float(env.radiance.max()) == pytest.approx(1.0)
    light = sun.power * np.asarray(sun.color).sum()
    assert map_power(env) + light == pytest.approx(before, rel=1e-3)


def test_maps_without_a_disc_are_left_alone():
    """A sky without a sun; a peak under 100 times the sky around it; a disc holding under
    1 % of the map's light; a bright band wider than the window searched."""
    cases = [sky_map(sun=1.0), sky_map(sun=50.0), sky_map(sun=150.0)]
    band = sky_map(sun=1.0)
    band.radiance[600:700] = 5.0e3  # 18° of sky, every column
    for env in [*cases, band]:
        before = env.radiance.copy()
        assert take_out_map_sun(env, "none") is None
        np.testing.assert_array_equal(env.radiance, before)


def test_camera_rays_still_see_the_disc_taken_out():
    """The background of a camera looking at the sun shows the disc's radiance inside its
    angle (as the map did before the disc became a light) and the sky outside it."""
    env = sky_map()
    sun = take_out_map_sun(env, "Sky sun disc")
    forward = towards(ELEVATION, AZIMUTH)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    camera_to_world = np.eye(4)
    camera_to_world[:3, :3] = np.stack([right, np.cross(right, forward), -forward], axis=1)
    camera = inside_sphere_camera(512)  # 90°: a pixel is about 0.18°, the disc 1°
    camera.view_matrix = np.linalg.inv(camera_to_world)
    world = World((1.0, 1.0, 1.0), 1.0, env, sun)
    seen = environment.background(world, camera, 1, 0, 0, 512, 512)
    np.testing.assert_allclose(seen[256, 256], SUN_RADIANCE * np.array([1.0, 0.9, 0.7]),
                               rtol=0.02)
    np.testing.assert_allclose(seen[256, 300], [1.0, 1.0, 1.0], rtol=1e-3)  # 8° off
    without = environment.background(World((1.0, 1.0, 1.0), 1.0, env), camera, 1, 0, 0, 512, 512)
    np.testing.assert_allclose(without[256, 256], [1.0, 1.0, 1.0], rtol=1e-3)
