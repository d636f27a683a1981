"""Area-light spread (Cycles' soft-box grid): the attenuation, and light paths that start
only inside the spread cone with the light's full power."""

from __future__ import annotations

import numpy as np

from addon.core.scene.model import LightKind
from addon.core.transport import vpl
from addon.core.transport.lights import spread_attenuation, spread_parameters
from addon.core.transport.sequences import scrambled_halton
from tests.core.builders import light, translation


def test_spread_keeps_the_power_of_a_lambertian_emitter():
    """∫ cos θ · attenuation dω over the hemisphere is π for every spread (as for 180°), and
    nothing leaves outside the cone."""
    steps = 200000
    theta = (np.arange(steps) + 0.5) / steps * np.pi / 2
    for degrees in (180, 120, 30, 5):
        lamp = light(LightKind.AREA, np.eye(4), spread=np.radians(degrees))
        factor = spread_attenuation(np.cos(theta), *spread_parameters(lamp))
        integral = (np.cos(theta) * factor * 2 * np.pi * np.sin(theta)).sum() * np.pi / 2 / steps
        assert abs(integral / np.pi - 1) < 1e-3
        if degrees < 180:
            assert (factor[theta > np.radians(degrees) / 2] == 0).all()


def test_area_light_paths_start_inside_the_spread_cone_with_full_power():
    lamp = light(LightKind.AREA, translation(0, 0, 2), power=50.0, spread=np.radians(30))
    emitter = vpl.light_emitter(lamp, np.zeros(3), 3.0)
    paths = vpl.start_paths([emitter], scrambled_halton(8192, vpl.START_DIMENSIONS, 0))
    cos = paths.direction @ np.array([0.0, 0.0, -1.0])
    assert cos.min() > np.cos(np.radians(15)) - 1e-9
    np.testing.assert_allclose(paths.flux.sum(axis=0), [50.0] * 3, rtol=0.01)
