"""Depth of field (frame/depth_of_field.py): the circle of confusion of Cycles' thin lens, the
aperture's shape, and the layered blur: exact convolution at one depth, nothing blurred in
focus, no background bled onto a sharp foreground, a blurred foreground covering in part."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from addon.core.frame.compose import BACKGROUND_DEPTH
from addon.core.frame.depth_of_field import (
    Defocus,
    aperture_kernel,
    aperture_problem,
    circle_of_confusion,
    defocus_frame,
)
from addon.core.scene.model import Aperture, Camera

DISC = Aperture(radius=0.02, focus_distance=4.0)


def perspective(width: int, height: int, aperture: Aperture | None = DISC,
                orthographic: bool = False) -> Camera:
    """A camera of 50 mm on a 36 mm sensor (P00 = 100 / 36)."""
    projection = np.eye(4)
    projection[0, 0] = 100.0 / 36.0
    projection[1, 1] = projection[0, 0] * width / height
    return Camera(np.eye(4), projection, width, height, is_orthographic=orthographic,
                  aperture=aperture)


def test_circle_of_confusion_is_the_thin_lens_of_cycles():
    camera = perspective(320, 180)
    depth = np.array([[2.0, 4.0, 8.0, BACKGROUND_DEPTH]])
    scale = 0.02 * (100.0 / 36.0) * 160.0  # radius × P00 × width / 2
    expected = scale * (1.0 / 4.0 - 1.0 / np.array([2.0, 4.0, 8.0, np.inf]))
    assert circle_of_confusion(depth, camera) == pytest.approx(expected[None, :], rel=1e-5)
    ortho = perspective(320, 180, orthographic=True)
    assert circle_of_confusion(depth, ortho) == pytest.approx(
        scale * np.array([[2.0 / 4.0 - 1.0, 0.0, 1.0, 0.0]]), rel=1e-5)


@pytest.mark.parametrize("aperture", [DISC, Aperture(0.02, 4.0, blades=5, rotation=0.3),
                                      Aperture(0.02, 4.0, ratio=2.0)])
def test_the_kernel_is_the_aperture_s_shape_and_mirrored_in_front_of_the_focus(aperture):
    radius = 12.0
    kernel = aperture_kernel(radius, aperture, 1.0)
    assert kernel.sum() == pytest.approx(1.0, abs=1e-5)
    n = aperture.blades
    area = n / 2 * math.sin(2 * math.pi / n) if n >= 3 else math.pi  # of the unit shape
    covered = (kernel > 0.5 * kernel.max()).sum()
    assert covered == pytest.approx(area * radius ** 2 / aperture.ratio, rel=0.06)
    mirrored = aperture_kernel(-radius, aperture, 1.0)
    assert mirrored == pytest.approx(kernel[::-1, ::-1], abs=1e-7)
    if n >= 3:  # a pentagon is not its own mirror image
        assert not np.allclose(mirrored, kernel, atol=1e-4)


def test_one_depth_is_a_convolution_with_the_aperture_and_keeps_the_light():
    rng = np.random.default_rng(3)
    image = rng.random((90, 120, 3)).astype(np.float32)
    coc = np.full((90, 120), 4.0, np.float32)
    blurred = Defocus(coc, DISC, 1.0).apply(image)
    kernel = aperture_kernel(float(coc.mean()), DISC, 1.0)
    expected = signal.fftconvolve(image, kernel[:, :, None], mode="same", axes=(0, 1))
    inner = (slice(10, -10), slice(10, -10))
    assert blurred[inner] == pytest.approx(expected[inner], abs=1e-4)
    assert blurred.mean() == pytest.approx(image.mean(), rel=2e-3)
    assert blurred.std() < 0.5 * image.std()


def test_in_focus_pixels_stay_sharp_and_a_blurred_background_does_not_bleed_onto_them():
    image = np.zeros((64, 64, 3), np.float32)
    image[:, 32:] = 1.0  # a bright background on the right half
    coc = np.full((64, 64), 10.0, np.float32)
    coc[20:44, 8:30] = 0.0  # a dark object in focus, left of the bright half
    image[20:44, 8:30] = 0.1
    out = Defocus(coc, DISC, 1.0).apply(image)
    assert out[20:44, 8:30] == pytest.approx(0.1, abs=1e-6)
    assert out[32, 40, 0] > 0.9 and out[32, 31, 0] > 0.3  # the background itself blurs


def test_a_blurred_foreground_covers_a_sharp_background_in_part():
    image = np.ones((80, 80, 3), np.float32)
    coc = np.zeros((80, 80), np.float32)
    image[:, :40] = 0.0  # a dark foreground on the left, 8 px out of focus
    coc[:, :40] = -8.0
    out = Defocus(coc, DISC, 1.0).apply(image)
    profile = out[40, :, 0]
    assert profile[40] == pytest.approx(0.5, abs=0.08)  # half the disc over the edge
    assert profile[49] == pytest.approx(1.0, abs=1e-3)  # past the radius: the background
    assert profile[31] == pytest.approx(0.0, abs=1e-3)
    assert np.all(np.diff(profile[30:52]) >= -1e-6)


def test_a_frame_is_defocused_in_place_with_the_border_extended_and_data_passes_sharp():
    camera = perspective(96, 54)
    depth = np.full((54, 96, 1), 16.0, np.float32)
    combined = np.ones((54, 96, 4), np.float32)
    normal = np.zeros((54, 96, 3), np.float32)
    output = {"Combined": combined, "Depth": depth, "Normal": normal}
    notes: list[str] = []
    defocus_frame(output, camera, notes)
    assert output["Combined"] == pytest.approx(1.0, abs=1e-5)  # no dark border
    assert output["Normal"] is normal and notes == []
    huge = perspective(96, 54, Aperture(radius=50.0, focus_distance=4.0))
    output = {"Combined": combined.copy(), "Depth": depth}
    defocus_frame(output, huge, notes)
    assert np.isfinite(output["Combined"]).all() and "48 px wide" in notes[0]


@pytest.mark.parametrize("aperture, why", [
    (Aperture(0.02, 0.0), "its focus distance is 0"),
    (Aperture(float("nan"), 4.0), "its aperture or focus distance is not a finite number"),
    (Aperture(0.02, 4.0, ratio=0.0), "its aperture ratio is 0"),
])
def test_an_aperture_that_cannot_be_rendered_says_why(aperture, why):
    assert aperture_problem(aperture) == why
    assert aperture_problem(DISC) is None


def test_the_blur_stops_between_slices_when_asked():
    coc = np.linspace(-20, 20, 64, dtype=np.float32)[None, :].repeat(32, axis=0)
    lens = Defocus(coc, DISC, 1.0)
    calls = []

    def stop() -> None:
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        lens.apply(np.ones((32, 64, 3), np.float32), stop)
    assert len(calls) == 3 < len(lens.slices)
