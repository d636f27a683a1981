"""Motion blur: the finished passes smeared along each pixel's motion over the shutter, by
McGuire et al.'s reconstruction filter ("A Reconstruction Filter for Plausible Motion
Blur", I3D 2012), as EEVEE blurs its frames.

The frame is rendered at the shutter's middle; the Vector pass at the shutter's opening and
closing (Scene.motion) gives each pixel its half-exposure motion v. Pixels are gathered along
the strongest motion around them (the largest v of the 3 × 3 tiles of MAX_RADIUS pixels about
them), each sample weighted by whether it lies in front (its own blur reaches the pixel),
behind (the pixel's blur reaches it) or both (two blurs over each other), so a moving object
smears over a still background and a still object in front of a moving one stays sharp."""

from __future__ import annotations

import numpy as np

from ..scene.model import MotionSpan
from ..transport.sequences import radical_inverse
from .compose import BACKGROUND_DEPTH
from .depth_of_field import BLURRED_PASSES
from .state import FrameState, Stage

MAX_RADIUS = 32  # pixels: the longest half-exposure motion drawn, and the tiles' size
SAMPLES = 15  # per pixel, along the tile's motion
SOFT_DEPTH = 0.01  # relative depth over which "in front" fades to "behind"
MIN_MOTION = 0.5  # pixels: slower pixels are not blurred


def pass_span(span: MotionSpan, index: int, passes: int) -> MotionSpan:
    """The part of the shutter pass ``index`` of ``passes`` renders: a 1/passes share of it
    about its van der Corput point turned by half the shutter (the strata's middles, the
    first one at the shutter's middle, which the data passes come from, in an order that
    spreads any first passes over the shutter), blurred over that share alone; one pass
    blurs the whole."""
    if passes <= 1 or not span.blur:
        return span
    length = span.after - span.before
    point = min((radical_inverse(index, 2) + 0.5) % 1.0 + 0.5 / passes, 1.0 - 0.5 / passes)
    middle = span.before + length * point  # within the shutter past ``passes`` passes too
    return MotionSpan(-0.5 * length / passes, 0.5 * length / passes, blur=True,
                      centre=span.centre + middle)


def half_exposure(vectors: np.ndarray) -> np.ndarray:
    """Each pixel's half-exposure motion (h, w, 2) in pixels from the Vector pass at the
    shutter's opening and closing (x, y: opening - now; z, w: now - closing), clamped to
    MAX_RADIUS."""
    opening, closing = vectors[..., :2], -vectors[..., 2:4]
    v = 0.5 * (closing - opening)
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(length > MAX_RADIUS, v * (MAX_RADIUS / np.maximum(length, 1e-30)), v)


def _largest(v: np.ndarray, tile: int) -> np.ndarray:
    """The longest motion of each tile × tile block (the image padded with zeros), then the
    longest among each block's 3 × 3 neighbours: (th, tw, 2)."""
    h, w = v.shape[:2]
    th, tw = -(-h // tile), -(-w // tile)
    padded = np.zeros((th * tile, tw * tile, 2), v.dtype)
    padded[:h, :w] = v
    blocks = padded.reshape(th, tile, tw, tile, 2).transpose(0, 2, 1, 3, 4).reshape(th, tw, -1, 2)
    pick = np.argmax(np.einsum("abnc,abnc->abn", blocks, blocks), axis=-1)
    tiles = np.take_along_axis(blocks, pick[..., None, None], axis=2)[:, :, 0]
    ring = np.pad(tiles, ((1, 1), (1, 1), (0, 0)))
    around = np.stack([ring[i:i + th, j:j + tw] for i in range(3) for j in range(3)], axis=2)
    pick = np.argmax(np.einsum("abnc,abnc->abn", around, around), axis=-1)
    return np.take_along_axis(around, pick[..., None, None], axis=2)[:, :, 0]


def _cone(distance: np.ndarray, speed: np.ndarray) -> np.ndarray:
    return np.clip(1.0 - distance / np.maximum(speed, 1e-6), 0.0, 1.0)


def _cylinder(distance: np.ndarray, speed: np.ndarray) -> np.ndarray:
    edge = np.clip((distance - 0.95 * speed) / np.maximum(0.1 * speed, 1e-6), 0.0, 1.0)
    return 1.0 - edge * edge * (3.0 - 2.0 * edge)  # 1 - smoothstep(0.95 s, 1.05 s, d)


def blur(images: dict[str, np.ndarray], vectors: np.ndarray, depth: np.ndarray,
         seed: int = 0) -> int:
    """Blur ``images`` (each (h, w, c)) in place along the motion of ``vectors`` (the Vector
    pass at the shutter's times), in front of and behind by ``depth`` (h, w, 1); returns how
    many pixels were blurred. Samples are jittered per pixel by ``seed``'s pattern."""
    h, w = depth.shape[:2]
    v = half_exposure(vectors).astype(np.float32)
    speed = np.maximum(np.linalg.norm(v, axis=-1), 0.5)
    neighbour = np.repeat(np.repeat(_largest(v, MAX_RADIUS), MAX_RADIUS, 0), MAX_RADIUS, 1)
    neighbour = neighbour[:h, :w]
    rows, cols = np.nonzero(np.linalg.norm(neighbour, axis=-1) > MIN_MOTION)
    if rows.size == 0:
        return 0
    z = np.where(depth[..., 0] >= BACKGROUND_DEPTH, np.inf, depth[..., 0])
    direction = neighbour[rows, cols]
    jitter = np.random.default_rng(seed).random(rows.size, np.float32) - 0.5
    z_here, speed_here = z[rows, cols], speed[rows, cols]
    weight = 1.0 / speed_here
    sums = {name: image[rows, cols] * weight[:, None] for name, image in images.items()}
    for k in range(SAMPLES):
        t = -1.0 + 2.0 * (k + 0.5 + jitter) / SAMPLES
        y = np.clip(np.rint(rows + direction[:, 1] * t), 0, h - 1).astype(np.int64)
        x = np.clip(np.rint(cols + direction[:, 0] * t), 0, w - 1).astype(np.int64)
        distance = np.hypot(y - rows, x - cols)
        z_there, speed_there = z[y, x], speed[y, x]
        with np.errstate(invalid="ignore"):
            front = np.clip(1.0 - (z_there - z_here) / (SOFT_DEPTH * z_here), 0.0, 1.0)
            back = np.clip(1.0 - (z_here - z_there) / (SOFT_DEPTH * z_there), 0.0, 1.0)
        front = np.nan_to_num(front, nan=1.0)  # both at infinity: the same depth
        back = np.nan_to_num(back, nan=1.0)
        alpha = (front * _cone(distance, speed_there) + back * _cone(distance, speed_here)
                 + 2.0 * _cylinder(distance, speed_there) * _cylinder(distance, speed_here))
        weight = weight + alpha
        for name, image in images.items():
            sums[name] += image[y, x] * alpha[:, None]
    for name, image in images.items():
        image[rows, cols] = sums[name] / weight[:, None]
    return int(rows.size)


class MotionBlur(Stage):
    """The shutter's motion blur over the finished passes (after denoising, before depth of
    field)."""

    name = "motion blur"
    needs = ("output",)

    def run(self, frame: FrameState) -> None:
        motion = frame.scene.motion
        if motion is None or not motion.blur or "Vector" not in frame.output:
            return
        frame.report(1.0, "Motion blur")
        with frame.stats.timed(self.name):
            images = {n: frame.output[n] for n in BLURRED_PASSES if n in frame.output}
            blurred = blur(images, frame.output["Vector"], frame.output["Depth"],
                           seed=frame.pass_index)
            frame.stats.counts["motion-blurred pixels"] = blurred
