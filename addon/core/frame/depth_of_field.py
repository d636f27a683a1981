"""Depth of field: Cycles' thin lens as a blur of the finished image.

Cycles starts each camera ray at a point L of the aperture (a disc or a regular polygon of
radius R) and aims it at the pixel's point on the plane of focus, at depth s. A surface point
at depth z then lands at its pinhole position plus L (1/s - 1/z) (perspective; L (z/s - 1)
orthographic) in the image plane at distance 1: it spreads over the aperture's shape scaled
by its circle of confusion c = R (1/s - 1/z) (point-mirrored in front of the plane, c < 0),
in pixels × the projection's scale.

The image is cut into slices of depth by c (a ratio of SLICE_RATIO between edges, the slice
within FOCUS_RADIUS left sharp); each slice's premultiplied light and coverage are convolved
with its shape at its pixels' mean c (by FFT, on an image shrunk so that the shape spans about
DOWNSAMPLED_RADIUS pixels) and composited front to back over the nearer slices, then divided
by the coverage. So a blurred foreground covers what is behind it in part, an object in focus
is not blurred by what lies behind it, and where the pinhole image holds nothing behind an
object (its hidden background) its neighbours fill in.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import replace

import numpy as np
import scipy.fft
from scipy import signal

from ..scene.model import Aperture, Camera
from .compose import BACKGROUND_DEPTH, downsample
from .result import BACKDROP, MATTE
from .state import FrameState, Stage

FOCUS_RADIUS = 0.5  # pixels: a circle of confusion smaller than this is left sharp
SLICE_RATIO = 1.25  # between a slice's outer and inner circle of confusion
MIN_SLICE_WIDTH = 0.5  # pixels
DOWNSAMPLED_RADIUS = 6.0  # shapes wider than this are convolved on a shrunk image
MAX_RADIUS_SHARE = 0.5  # of the image's larger side: the widest circle of confusion drawn
HIDDEN_FILL_FROM = 0.05  # a slice's own coverage from which it fills what is hidden in full
KERNEL_SUBSAMPLES = 4  # per pixel and axis, where the aperture's outline is drawn
BLURRED_PASSES = ("Combined", "DiffDir", "DiffInd", "DiffCol", "GlossDir", "GlossInd",
                  "GlossCol", "Emit", "AO", "Env", MATTE, BACKDROP)
"""The passes depth of field blurs (with the shadow catchers' matte and backdrop, which
make Combined); data passes (Depth, Normal, the denoising guides) stay sharp for the
compositor."""


def circle_of_confusion(depth: np.ndarray, camera: Camera) -> np.ndarray:
    """Each pixel's signed circle of confusion in pixels across the image (behind the plane of
    focus positive, in front negative) from its view-space depth; the background (depth
    BACKGROUND_DEPTH) is at infinity (orthographic: not blurred)."""
    aperture = camera.aperture
    scale = aperture.radius * camera.projection_matrix[0, 0] * camera.width / 2.0
    z = depth.astype(np.float64)
    background = z >= BACKGROUND_DEPTH
    focus = aperture.focus_distance
    if camera.is_orthographic:
        c = scale * (z / focus - 1.0)
        c[background] = 0.0
    else:
        inverse = np.where(background, 0.0, 1.0 / np.maximum(z, 1e-12))
        c = scale * (1.0 / focus - inverse)
    return c.astype(np.float32)


def aperture_kernel(radius: float, aperture: Aperture, aspect: float) -> np.ndarray:
    """The aperture's shape for a signed circle of confusion of ``radius`` pixels (negative:
    mirrored through its centre), ``aspect`` pixels down the image per pixel across, as
    weights summing to 1 (rows from the image's bottom, as the passes are stored)."""
    rx = abs(radius) / aperture.ratio
    ry = abs(radius) * aspect
    half_x, half_y = math.ceil(rx + 0.5), math.ceil(ry + 0.5)
    n = KERNEL_SUBSAMPLES
    offsets = (np.arange(n) + 0.5) / n - 0.5
    xs = (np.arange(-half_x, half_x + 1)[:, None] + offsets[None, :]).ravel() / max(rx, 1e-9)
    ys = (np.arange(-half_y, half_y + 1)[:, None] + offsets[None, :]).ravel() / max(ry, 1e-9)
    x, y = np.meshgrid(xs, ys)
    if radius < 0:
        x, y = -x, -y
    if aperture.blades >= 3:
        inside = np.ones_like(x, dtype=bool)
        apothem = math.cos(math.pi / aperture.blades)
        for k in range(aperture.blades):
            angle = aperture.rotation + 2.0 * math.pi * k / aperture.blades
            inside &= x * math.cos(angle) + y * math.sin(angle) <= apothem
    else:
        inside = x * x + y * y <= 1.0
    cells = inside.reshape(2 * half_y + 1, n, 2 * half_x + 1, n).sum(axis=(1, 3))
    weights = cells.astype(np.float64)
    total = weights.sum()
    if total <= 0:  # narrower than a subsample: a point
        weights[half_y, half_x] = total = 1.0
    return (weights / total).astype(np.float32)


def slice_edges(largest: float) -> np.ndarray:
    """The circles of confusion between slices, from -largest to +largest (at least the
    focus slice's ±FOCUS_RADIUS)."""
    edges = [FOCUS_RADIUS]
    while edges[-1] < largest:
        edges.append(max(edges[-1] * SLICE_RATIO, edges[-1] + MIN_SLICE_WIDTH))
    positive = np.array(edges)
    return np.concatenate([-positive[::-1], positive])


def _blur(layer: np.ndarray, radius: float, aperture: Aperture, aspect: float) -> np.ndarray:
    """``layer`` (h, w, c) convolved with the aperture's shape of ``radius`` pixels, on an
    image shrunk by a whole factor where the shape is wider than DOWNSAMPLED_RADIUS."""
    factor = max(1, int(abs(radius) / DOWNSAMPLED_RADIUS))
    h, w = layer.shape[:2]
    if factor > 1:
        layer = downsample(np.pad(layer, ((0, -h % factor), (0, -w % factor), (0, 0))), factor)
    kernel = aperture_kernel(radius / factor, aperture, aspect)
    blurred = signal.fftconvolve(layer, kernel[:, :, None], mode="same", axes=(0, 1))
    if factor > 1:
        blurred = _upsampled(_upsampled(blurred, factor, h, 0), factor, w, 1)
    return np.maximum(blurred, 0.0).astype(np.float32)


def _upsampled(image: np.ndarray, factor: int, size: int, axis: int) -> np.ndarray:
    """``image`` grown ``factor`` times along ``axis`` to ``size`` pixels, linearly between
    the centres of its pixels (each the mean of factor pixels), the edges held."""
    position = (np.arange(size) + 0.5) / factor - 0.5
    below = np.clip(np.floor(position).astype(int), 0, image.shape[axis] - 1)
    above = np.minimum(below + 1, image.shape[axis] - 1)
    t = np.clip(position - below, 0.0, 1.0).astype(np.float32)
    shape = [1, 1, 1]
    shape[axis] = size
    t = t.reshape(shape)
    return np.take(image, below, axis=axis) * (1.0 - t) + np.take(image, above, axis=axis) * t


class Defocus:
    """One frame's slices of depth, applied to each pass alike (``apply``)."""

    def __init__(self, coc: np.ndarray, aperture: Aperture, aspect: float) -> None:
        self.aperture, self.aspect = aperture, aspect
        largest = float(np.abs(coc).max()) if coc.size else 0.0
        self.margin = self._reach(largest) + 1
        coc = np.pad(coc, self.margin, mode="edge")
        edges = slice_edges(largest)
        index = np.digitize(coc, edges)  # 0 .. len(edges); the focus slice is len(edges) // 2
        # each slice: its pixels and those in front of it (h, w, 2), where, and its radius
        self.slices: list[tuple[np.ndarray, tuple[slice, slice], float]] = []
        h, w = coc.shape
        for k in np.unique(index):  # front (most negative) to back
            members = index == k
            radius = float(coc[members].mean())
            if abs(radius) < FOCUS_RADIUS:
                radius = 0.0
            rows, cols = np.nonzero(members)
            pad = 0 if radius == 0.0 else \
                self._reach(radius) + 2 * max(1, int(abs(radius) / DOWNSAMPLED_RADIUS)) + 2
            region = (slice(max(rows.min() - pad, 0), min(rows.max() + pad + 1, h)),
                      slice(max(cols.min() - pad, 0), min(cols.max() + pad + 1, w)))
            nearer = index[region] < k
            self.slices.append((np.stack([members[region], nearer], axis=-1).astype(np.float32),
                                region, radius))

    def _reach(self, radius: float) -> int:
        """Pixels the aperture's shape of ``radius`` reaches from its centre, either way."""
        return math.ceil(abs(radius) * max(1.0 / self.aperture.ratio, self.aspect))

    def apply(self, image: np.ndarray, between: Callable[[], None] = lambda: None
              ) -> np.ndarray:
        """``image`` (h, w, c), premultiplied where it has alpha, seen through the lens (the
        image's border repeated outwards, to stand for what lies beyond it); ``between`` is
        called before each slice (it may raise to stop)."""
        m = self.margin
        image = np.pad(image, ((m, m), (m, m), (0, 0)), mode="edge")
        h, w, c = image.shape
        light = np.zeros((h, w, c), np.float32)
        coverage = np.zeros((h, w), np.float32)
        for masks, region, radius in self.slices:
            between()
            layer = np.concatenate([image[region] * masks[..., :1], masks], axis=2)
            if radius != 0.0:
                layer = _blur(layer, radius, self.aperture, self.aspect)
            own, hidden = layer[..., c], layer[..., c + 1]
            # The slice goes on behind what is in front of it, where its own pixels are near.
            alpha = np.minimum(own + hidden * np.minimum(own / HIDDEN_FILL_FROM, 1.0), 1.0)
            gain = np.where(own > 1e-6, alpha / np.maximum(own, 1e-6), 0.0)
            free = 1.0 - coverage[region]
            light[region] += (free * gain)[..., None] * layer[..., :c]
            coverage[region] += free * alpha
        seen = coverage > 1e-4
        result = image.astype(np.float32, copy=True)
        result[seen] = light[seen] / coverage[seen][:, None]
        return result[m:h - m, m:w - m]


def defocus_frame(output: dict[str, np.ndarray], camera: Camera, notes: list[str],
                  between: Callable[[], None] = lambda: None) -> None:
    """Blur BLURRED_PASSES of ``output`` in place by the camera's aperture, from its Depth;
    ``between`` is called before each slice of each pass (it may raise to stop)."""
    coc = circle_of_confusion(output["Depth"][..., 0], camera)
    limit = MAX_RADIUS_SHARE * max(camera.width, camera.height)
    widest = float(np.abs(coc).max()) if coc.size else 0.0
    if widest > limit:
        notes.append(f"depth of field: circles of confusion up to {widest:.0f} px drawn "
                     f"{limit:.0f} px wide (half the image)")
        coc = np.clip(coc, -limit, limit)
    projection = camera.projection_matrix
    aspect = (projection[1, 1] * camera.height) / (projection[0, 0] * camera.width)
    lens = Defocus(coc, camera.aperture, float(aspect))
    with scipy.fft.set_workers(os.cpu_count() or 1):  # the GPU is idle by now
        for name in BLURRED_PASSES:
            if name in output:
                output[name] = lens.apply(output[name], between)


def aperture_problem(aperture: Aperture) -> str | None:
    """Why an aperture cannot be rendered (None: it can)."""
    values = (aperture.radius, aperture.focus_distance, aperture.rotation, aperture.ratio)
    if not all(math.isfinite(v) for v in values):
        return "its aperture or focus distance is not a finite number"
    if aperture.focus_distance <= 0:
        return "its focus distance is 0"
    if aperture.ratio <= 0:
        return "its aperture ratio is 0"
    return None


class PlanDepthOfField(Stage):
    """One warning, and a camera in focus, where the aperture cannot be rendered (the planner
    asks for the Depth pass the blur reads; DropBorrowed drops it again when not asked for)."""

    name = "depth of field plan"
    needs = ("camera",)

    def run(self, frame: FrameState) -> None:
        if not frame.camera.defocused:
            return
        problem = aperture_problem(frame.camera.aperture)
        if problem is not None:
            frame.stats.warnings.append(f"depth of field is not rendered: {problem}")
            frame.camera = replace(frame.camera, aperture=None)


class DepthOfField(Stage):
    """The camera's depth of field over the finished passes (after denoising)."""

    name = "depth of field"
    needs = ("output",)

    def run(self, frame: FrameState) -> None:
        if not frame.camera.defocused or "Depth" not in frame.output:
            return
        frame.report(1.0, "Depth of field")
        with frame.stats.timed(self.name):
            defocus_frame(frame.output, frame.camera, frame.stats.notes, frame.check_cancelled)
