"""Radiance .hdr files of linear RGB, for test and measurement worlds: Blender's own writer
stores a generated float image display-encoded (sRGB: 59000 became 102.5 in the file)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def write_hdr(path: Path, rgb: np.ndarray) -> None:
    """A Radiance .hdr of linear RGB (h, w, 3), rows bottom-up as Blender stores images, in
    flat RGBE scanlines."""
    brightest = rgb.max(axis=2)
    mantissa, exponent = np.frexp(brightest)
    scale = np.divide(mantissa * 256.0, brightest, out=np.zeros_like(brightest),
                      where=brightest > 1e-32)
    rgbe = np.concatenate([rgb * scale[..., None], (exponent + 128)[..., None]], axis=-1)
    rgbe[brightest <= 1e-32] = 0
    height, width = brightest.shape
    header = f"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {height} +X {width}\n".encode()
    Path(path).write_bytes(header + np.clip(rgbe[::-1], 0, 255).astype(np.uint8).tobytes())
