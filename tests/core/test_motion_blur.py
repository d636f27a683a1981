"""Motion blur's reconstruction filter and the shutter's split over passes."""

from __future__ import annotations

import numpy as np
import pytest

from addon.core.frame.compose import BACKGROUND_DEPTH
from addon.core.frame.motion_blur import blur, half_exposure, pass_span
from addon.core.scene.model import MotionSpan


def test_passes_split_the_shutter_into_strata():
    span = MotionSpan(-0.25, 0.25, blur=True, centre=0.1)
    parts = [pass_span(span, k, 4) for k in range(4)]
    assert sorted(round(p.centre - 0.1, 9) for p in parts) == [-0.1875, -0.0625, 0.0625, 0.1875]
    assert parts[1].centre < 0.1 < parts[0].centre < parts[2].centre  # the first passes
    assert parts[0].centre - 0.1 == pytest.approx(0.0625)  # spread out, from the middle
    assert all(p.after - p.before == pytest.approx(0.125) and p.blur for p in parts)
    assert pass_span(span, 3, 1) == span
    late = [pass_span(span, k, 4).centre - 0.1 for k in range(4, 64)]  # a budget's passes
    assert all(-0.1875 - 1e-12 <= t <= 0.1875 + 1e-12 for t in late)


def test_half_exposure_is_half_the_motion_over_the_shutter_and_clamped():
    vectors = np.array([[[-3.0, 1.0, -3.0, 1.0], [-100.0, 0.0, -100.0, 0.0]]], np.float32)
    v = half_exposure(vectors)
    np.testing.assert_allclose(v[0, 0], [3.0, -1.0])
    np.testing.assert_allclose(v[0, 1], [32.0, 0.0])


def scene_of_a_moving_square(speed: float):
    """A bright square 8 pixels wide, 2 m away, moving right by ``speed`` pixels over the
    shutter, over a dark wall 10 m away."""
    h, w = 32, 64
    image = np.full((h, w, 4), 0.1, np.float32)
    depth = np.full((h, w, 1), 10.0, np.float32)
    vectors = np.zeros((h, w, 4), np.float32)
    image[12:20, 28:36, :3], depth[12:20, 28:36] = 1.0, 2.0
    vectors[12:20, 28:36] = [-speed / 2, 0.0, -speed / 2, 0.0]
    return image, depth, vectors


def test_a_moving_square_smears_over_a_still_wall_along_its_motion():
    image, depth, vectors = scene_of_a_moving_square(16.0)
    before = image.copy()
    blurred = blur({"Combined": image}, vectors, depth)
    assert blurred > 0
    row = image[16, :, 0]
    assert row[22] > 0.15 and row[41] > 0.15  # its trail reaches 6 pixels past each side
    assert row[12] == pytest.approx(0.1) and row[52] == pytest.approx(0.1)  # not 16 past
    np.testing.assert_allclose(image[4:8], before[4:8])  # nothing moves above it
    assert image[16, 28:36, 0].max() < 1.0  # the square itself is smeared too
    # The filter is not energy-exact: a square moving twice its width keeps its middle too
    # bright (it cannot see the wall behind itself), +24 % of its light here. Passes that
    # each see part of the shutter (test_motion.py) take that error away.
    gain = (image[..., 0].sum() - before[..., 0].sum()) / (before[..., 0] - 0.1).sum()
    assert 0.0 < gain < 0.3


def test_a_still_frame_is_left_alone_and_the_background_is_at_infinity():
    image, depth, vectors = scene_of_a_moving_square(0.0)
    depth[:4] = BACKGROUND_DEPTH
    before = image.copy()
    assert blur({"Combined": image}, vectors, depth) == 0
    np.testing.assert_array_equal(image, before)
