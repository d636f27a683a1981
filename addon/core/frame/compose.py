"""Blender's passes from a tile's supersampled buffers, and the final check for NaN."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from functools import cache

import numpy as np

from ..scene.model import Camera, Mist
from .result import Stats

BACKGROUND_DEPTH = 1e10  # Blender's Z pass value where no surface is hit
COMPOSED_PASSES = frozenset({"DiffDir", "DiffInd", "DiffCol", "Emit", "Normal", "GlossDir",
                             "GlossInd", "GlossCol", "Depth", "Mist", "Position", "Env"})
"""The passes ``compose`` writes from the supersamples read back."""
SEEN_THROUGH = frozenset({"DiffCol", "GlossCol", "Emit", "Env"})
"""The passes clear surfaces in front dim, as Cycles writes them (measured, 4.5: through a
tinted Transparent BSDF the colour passes and Emit carry the tint, the light passes, which
are light over colour, do not)."""


def downsample(image: np.ndarray, factor: int) -> np.ndarray:
    """Mean of each factor × factor block of an (h, w, c) image (float32: rows added, then
    columns, as whole lines; several times faster than a mean over two strided axes)."""
    if factor == 1:
        return image
    h, w, c = image.shape
    lines = image.reshape(h // factor, factor, w * c)
    rows = lines[:, 0].astype(np.float32)  # a copy
    for k in range(1, factor):
        rows += lines[:, k]
    blocks = rows.reshape(h // factor, w // factor, factor, c)
    result = blocks[:, :, 0].copy()
    for k in range(1, factor):
        result += blocks[:, :, k]
    result *= np.float32(1.0 / (factor * factor))
    return result


def _glossy(gbuffer: Mapping[str, np.ndarray], direct: np.ndarray, indirect: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """GlossCol and the glossy radiance, direct and indirect (zeros without glossy layers)."""
    if direct.shape[-1] == 4:
        zero = np.zeros_like(direct[..., :3])
        return zero, zero, zero
    color = np.stack([gbuffer["lobe_c"][..., 3], gbuffer["albedo"][..., 3],
                      gbuffer["emission"][..., 3]], axis=-1)
    return color, direct[..., 4:7], indirect[..., 4:7]


def _per_colour(radiance: np.ndarray, color: np.ndarray) -> np.ndarray:
    """Blender's light pass: radiance / colour where the colour is not 0."""
    safe = np.where(color > 0, color, 1.0)
    return np.where(color > 0, radiance / safe, 0.0)


def central(image: np.ndarray, factor: int) -> np.ndarray:
    """The supersample at each factor × factor block's centre of an (h, w, c) image (for an
    even factor, the one above and right of it): one sample, as Cycles writes its data
    passes, not a mean of two surfaces at an edge."""
    return image[factor // 2::factor, factor // 2::factor]


def mist(position: np.ndarray, covered: np.ndarray, camera: Camera, settings: Mist
         ) -> np.ndarray:
    """Cycles' Mist pass per supersample (h, w, 1): the distance from the camera (along the
    view, orthographic) from ``settings.start`` over ``settings.depth``, clamped to [0, 1]
    and raised to the falloff; 1 where no surface is (``covered`` 0)."""
    offset = position[..., :3] - camera.position
    distance = offset @ camera.forward if camera.is_orthographic \
        else np.linalg.norm(offset, axis=-1)
    value = np.clip((distance - settings.start) / max(settings.depth, 1e-12), 0.0, 1.0)
    value = value ** settings.falloff
    return np.where(covered > 0, value[..., None], 1.0).astype(np.float32)


def compose(output: dict[str, np.ndarray], gbuffer: Mapping[str, np.ndarray],
            read_light: Callable[[], tuple[np.ndarray, np.ndarray]], aa: int, x0: int, y0: int,
            passes: frozenset[str], read_transmittance: Callable[[], np.ndarray] | None = None,
            holdouts: bool = False, view: tuple[Camera, Mist] | None = None,
            read_background: Callable[[], np.ndarray] | None = None) -> None:
    """Write one supersampled tile's ``passes`` (of COMPOSED_PASSES; Combined is composed on
    the GPU, gpu/combined.py) into ``output`` at output resolution. ``read_light`` returns
    the direct and indirect light, (h, w, 4) diffuse or (h, w, 8) with glossy radiance in
    channels 4-6; it is called once, and only where a light pass or GlossCol is asked for (the
    others come from the g-buffer alone). ``read_transmittance``: what clear surfaces in
    front let through to each supersample (h, w, 4), which dims SEEN_THROUGH; with
    ``holdouts``, the supersamples of holdouts (the g-buffer's geometric.w) get nothing, as
    the background does (Cycles writes no pass there). Depth and Position are the pixel
    centre's (Cycles writes both from a pixel's first sample, measured at its centre:
    ``central``). ``view``: the pass's camera and the
    mist settings, for the Mist pass. ``read_background``: what the camera sees where no
    surface is, per supersample (h, w, 3), for the Environment pass (Env), which Cycles
    writes whether the film is transparent or not."""
    covered = gbuffer["normal"][..., 3:4]
    seen_surface = None  # with holdouts: the supersamples whose passes are written
    if holdouts:
        seen_surface = (covered > 0) & (gbuffer["geometric"][..., 3:4] >= -0.5)
        covered = covered * seen_surface
    seen = read_transmittance()[..., :3] if read_transmittance is not None \
        and passes & SEEN_THROUGH else None
    h, w = covered.shape[0] // aa, covered.shape[1] // aa
    region = (slice(y0 // aa, y0 // aa + h), slice(x0 // aa, x0 // aa + w))
    light = cache(read_light)
    glossy = cache(lambda: _glossy(gbuffer, *light()))
    images = {"DiffDir": lambda: light()[0][..., :3],
              "DiffInd": lambda: light()[1][..., :3],
              "DiffCol": lambda: gbuffer["albedo"][..., :3],
              "Emit": lambda: gbuffer["emission"][..., :3],
              "Normal": lambda: gbuffer["normal"][..., :3],
              "GlossDir": lambda: _per_colour(glossy()[1], glossy()[0]),
              "GlossInd": lambda: _per_colour(glossy()[2], glossy()[0]),
              "GlossCol": lambda: glossy()[0]}
    for name, image in images.items():
        if name in passes:
            values = image()
            if seen is not None and name in SEEN_THROUGH:
                values = values * seen
            if seen_surface is not None:
                values = values * seen_surface
            output[name][region] = downsample(values, aa)
    if "Env" in passes and read_background is not None:  # none on holdouts: covered
        environment = (1.0 - gbuffer["normal"][..., 3:4]) * read_background()[..., :3]
        output["Env"][region] = downsample(environment if seen is None
                                           else environment * seen, aa)
    if "Mist" in passes and view is not None:  # the background's (and holdouts') is 1
        output["Mist"][region] = downsample(mist(gbuffer["position"], covered, *view), aa)
    if "Position" in passes:
        output["Position"][region] = central(gbuffer["position"][..., :3] * covered, aa)
    if "Depth" in passes:
        depth = np.where(covered > 0, gbuffer["position"][..., 3:4], BACKGROUND_DEPTH)
        output["Depth"][region] = central(depth, aa)


def sanitize(output: dict[str, np.ndarray], stats: Stats) -> None:
    """Never hand out NaN or Inf: replace them and say how many there were."""
    for name, image in output.items():
        bad = ~np.isfinite(image)
        if bad.any():
            stats.warnings.append(f"{int(bad.sum())} non-finite values in {name} set to 0")
            image[bad] = 0.0
