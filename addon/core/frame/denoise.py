"""Denoising: Blender's Denoising Data passes and Intel Open Image Denoise on the final image.

Three pieces, run at three points of the frame:

- ``PlanDenoise`` (a frame stage before the image) settles the denoiser the frame uses: OIDN
  needs the ``pyoidn`` module (a wheel bundled per platform); without it the frame falls back to
  the blur with one warning. ``denoiser = oidn`` turns the geometry-aware blur off.
- ``DenoisingData`` (a tile stage after compose) writes Cycles' Denoising Albedo, Normal and
  Depth passes from the tile's supersampled g-buffer, where the coverage of every supersample
  is still known. They are the guides OIDN reads here, and what the compositor's Denoise node
  reads on VPL GI renders as on Cycles' (Cycles' conventions: albedo = diffuse colour plus the
  emission and background radiance the camera sees, normal in camera space with +Z forward,
  depth = distance along the camera ray; 0 where nothing is hit).
- ``Denoise`` (a frame stage after the image) runs OIDN on the composed Combined pass
  (``oidn``, ``blur_oidn``), or on the indirect light DiffInd × DiffCol alone, adding the change
  to Combined and DiffInd (``oidn_indirect``: direct light and emission stay as rendered). It
  works after compose rather than as a tile stage on the indirect accumulator: OIDN's networks
  are trained on whole rendered images at output resolution with albedo and normal guides
  (per supersampled tile it would cost antialiasing² times more and see tile seams). Its time is
  the stage ``denoise`` in the stats.

Measured (tools/bench_denoise.py, README): at the sample scenes' settings OIDN leaves the
error against Cycles and the seed-to-seed noise where the blur leaves them. What remains is
bias and VPL-set noise spread over whole surfaces, which OIDN keeps as image content, so the
blur stays the default.
"""

from __future__ import annotations

from types import ModuleType
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from .compose import downsample
from .result import MATTE
from .state import FrameState, Stage

if TYPE_CHECKING:  # image.py runs DenoisingData among its tile stages
    from .image import FrameGpu, TileWork

DENOISING_PASSES = ("Denoising Normal", "Denoising Albedo", "Denoising Depth")
"""Cycles' Denoising Data passes, in the order Cycles registers them."""


class Mode(NamedTuple):
    """What a denoiser choice runs: the blur, and OIDN on the image or the indirect light."""

    blur: bool
    oidn: str | None  # "image", "indirect" or None


MODES = {
    "blur": Mode(True, None), "oidn": Mode(False, "image"), "blur_oidn": Mode(True, "image"),
    "oidn_indirect": Mode(False, "indirect"),
}
OIDN_DENOISERS = tuple(name for name, mode in MODES.items() if mode.oidn)
INDIRECT_PASSES = frozenset({"DiffInd", "DiffCol"})


def load_oidn() -> tuple[ModuleType | None, str]:
    """The ``pyoidn`` module, or None and why it cannot be used here."""
    try:
        import pyoidn
    except ImportError as exc:
        return None, f"no pyoidn module for this platform ({exc})"
    except Exception as exc:  # a wheel whose native library does not load
        return None, f"pyoidn does not load ({exc!r})"
    return pyoidn, ""


def frame_denoiser(frame: FrameState) -> str:
    """The denoiser this frame uses: the setting, or 'blur' where OIDN is unavailable."""
    denoiser = frame.settings.denoiser
    if denoiser in OIDN_DENOISERS and load_oidn()[0] is None:
        return "blur"
    return denoiser


class PlanDenoise(Stage):
    """Settle the frame's denoiser (one warning when OIDN is asked for but missing) and leave
    out the blur where OIDN replaces it."""

    name = "denoise plan"
    needs = ("light_passes",)

    def run(self, frame: FrameState) -> None:
        denoiser = frame.settings.denoiser
        if denoiser in OIDN_DENOISERS:
            module, reason = load_oidn()
            if module is None:
                frame.stats.warnings.append(
                    f"denoiser '{denoiser}': Open Image Denoise is unavailable, {reason}; "
                    f"the blur denoised the image instead")
                return
        mode = MODES[denoiser]
        if not mode.blur and frame.blur_radius:
            frame.blur_radius = 0
            frame.stats.skipped["blur"] = f"denoiser = {denoiser}"
        if mode.oidn:  # its guides, written by DenoisingData
            frame.plan.passes = frame.plan.passes | set(DENOISING_PASSES)
        if mode.oidn == "indirect":
            frame.plan.passes = frame.plan.passes | INDIRECT_PASSES


class DenoisingData:
    """A tile stage (image.py's TileStage interface): Denoising Albedo, Normal and Depth of one
    tile, where the view layer asks for them or OIDN needs them as guides."""

    name = "denoising data"

    def run(self, frame: FrameState, data: FrameGpu, work: TileWork) -> None:
        wanted = frame.plan.passes.intersection(DENOISING_PASSES)
        if not wanted:
            return
        with frame.stats.timed(self.name):
            write_denoising_data(frame, work, wanted)


def write_denoising_data(frame: FrameState, work: TileWork, wanted: set[str]) -> None:
    """Write the ``wanted`` Denoising Data passes of one supersampled tile into the output."""
    images, camera = work.gbuffer.images, frame.camera
    aa, tile = frame.settings.antialiasing, work.tile
    covered = images["normal"][..., 3:4]
    h, w = covered.shape[0] // aa, covered.shape[1] // aa
    region = (slice(tile.y0 // aa, tile.y0 // aa + h), slice(tile.x0 // aa, tile.x0 // aa + w))
    output = frame.output
    if "Denoising Albedo" in wanted:
        albedo = (images["albedo"][..., :3] + images["emission"][..., :3]) * covered
        if work.background is not None:  # composed before: the same background
            albedo = albedo + (1.0 - covered) * work.background
        output["Denoising Albedo"][region] = downsample(albedo, aa)
    if "Denoising Normal" in wanted:
        # Cycles' camera space: +X right, +Y up, +Z forward (Blender's camera looks along -Z).
        rotation = np.diag([1.0, 1.0, -1.0]) @ camera.view_matrix[:3, :3]
        normal = images["normal"][..., :3] @ rotation.T.astype(np.float32) * covered
        output["Denoising Normal"][region] = downsample(normal, aa)
    if "Denoising Depth" in wanted:
        position = images["position"]
        if camera.is_orthographic:
            depth = position[..., 3:4]
        else:
            depth = np.linalg.norm(position[..., :3] - camera.position.astype(np.float32),
                                   axis=-1, keepdims=True)
        output["Denoising Depth"][region] = downsample(depth * covered, aa)


class Denoise(Stage):
    """Open Image Denoise on the Combined pass, guided by Denoising Albedo and Normal."""

    name = "denoise"
    needs = ("output",)

    def run(self, frame: FrameState) -> None:
        denoiser = frame_denoiser(frame)
        if denoiser not in OIDN_DENOISERS:
            return
        module, _ = load_oidn()
        output = frame.output
        guides = output["Denoising Albedo"], output["Denoising Normal"]
        indirect = MODES[denoiser].oidn == "indirect"
        with frame.stats.timed(self.name):
            try:
                # With indirect: the indirect light leaving the surfaces, DiffInd × DiffCol
                # (exact where the albedo is uniform within a pixel); direct light and emission
                # stay as they are.
                before = output["DiffInd"] * output["DiffCol"] if indirect \
                    else output["Combined"][..., :3]
                after = denoise_image(module, before, *guides)
            except (RuntimeError, ValueError, TypeError, OSError) as exc:
                frame.stats.warnings.append(f"Open Image Denoise failed ({exc}); the image is "
                                            f"not denoised")
                return
        if MATTE in output:  # the shadow catchers' matte takes the change off their pixels
            combined = output["Combined"]
            catcher = np.clip(combined[..., 3:4] - output[MATTE][..., 3:4], 0.0, 1.0)
            output[MATTE][..., :3] += (after - before) * (1.0 - catcher)
        if indirect:
            output["Combined"][..., :3] += after - before
            albedo = output["DiffCol"]
            lit = albedo > 0
            output["DiffInd"][lit] = after[lit] / albedo[lit]
        else:
            output["Combined"][..., :3] = after


def denoise_image(oidn: ModuleType, color: np.ndarray, albedo: np.ndarray,
                  normal: np.ndarray) -> np.ndarray:
    """OIDN's ray-tracing filter on an HDR (h, w, 3) image with noise-free guides. Inputs
    are made finite and in range first; a non-finite output pixel keeps its input value."""
    color = np.nan_to_num(color, nan=0.0, posinf=0.0, neginf=0.0).clip(0.0, None)
    albedo = np.nan_to_num(albedo, nan=0.0, posinf=1.0, neginf=0.0).clip(0.0, 1.0)
    normal = np.nan_to_num(normal, nan=0.0, posinf=0.0, neginf=0.0).clip(-1.0, 1.0)
    result = oidn.denoise(np.ascontiguousarray(color, np.float32),
                          np.ascontiguousarray(albedo, np.float32),
                          np.ascontiguousarray(normal, np.float32),
                          hdr=True, clean_aux=True, quality="high")
    return np.where(np.isfinite(result), result, color).astype(np.float32)
