"""The Principled Hair BSDF's parametrisations turned into the colour VPL GI renders hair
with: Direct Coloring's colour survives the round trip through absorption, more melanin
darkens, redness reddens, and a tint dyes."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from addon.core.scene.hair_fibre import (
    absorption_from_colour,
    colour_from_absorption,
    melanin_absorption,
)


@pytest.mark.parametrize("radial", [0.0, 0.3, 1.0])
def test_a_colour_survives_the_round_trip(radial):
    colour = (0.5, 0.3, 0.1)
    assert colour_from_absorption(absorption_from_colour(colour, radial), radial) == \
        pytest.approx(colour, rel=1e-9)


def test_melanin_darkens_and_redness_reddens():
    white = (1.0, 1.0, 1.0)
    colours = [np.array(colour_from_absorption(melanin_absorption(m, 0.0, white, 0.3), 0.3))
               for m in (0.0, 0.3, 0.6, 0.9)]
    assert colours[0] == pytest.approx(1.0)  # no melanin, no dye: white
    assert all((a > b).all() for a, b in itertools.pairwise(colours))  # darker
    assert all(c[0] > c[1] > c[2] for c in colours[1:])  # brown: red above green above blue
    brown = colours[1]
    red = np.array(colour_from_absorption(melanin_absorption(0.3, 1.0, white, 0.3), 0.3))
    assert red[0] / red[2] > brown[0] / brown[2]
    dyed = np.array(colour_from_absorption(melanin_absorption(0.0, 0.0, (0.2, 0.9, 0.2), 0.3),
                                           0.3))
    assert dyed == pytest.approx((0.2, 0.9, 0.2), rel=1e-9)


def test_bad_absorption_is_white_not_nan():
    assert colour_from_absorption((np.nan, -1.0, 0.0), 0.3) == (1.0, 1.0, 1.0)
