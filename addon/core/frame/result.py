"""What a render returns: named float32 passes and the statistics of how they were made."""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

PASS_CHANNELS = {
    "Combined": 4, "Depth": 1, "Normal": 3, "DiffDir": 3, "DiffInd": 3, "DiffCol": 3,
    "GlossDir": 3, "GlossInd": 3, "GlossCol": 3, "Emit": 3, "Mist": 1, "Position": 3,
    "Denoising Normal": 3, "Denoising Albedo": 3, "Denoising Depth": 1, "IndexOB": 1,
    "IndexMA": 1, "Vector": 4, "AO": 3, "Env": 3, "Shadow Catcher": 3,
    **{f"{family}{k:02d}": 4 for family in ("CryptoObject", "CryptoMaterial", "CryptoAsset")
       for k in range(3)},
}
"""Blender's pass names (4.x's) and channel counts, in the order the engine registers them;
Cryptomatte's at Blender's default of 6 levels (``pass_channels`` knows the others)."""


ON_DEMAND_PASSES = frozenset({"AO"})
"""Passes that trace rays of their own: rendered where asked for by name, never as part of
"every pass" (a render's default, or with the planner off)."""


MATTE = "_Matte"
BACKDROP = "_Backdrop"
INTERNAL_PASSES = {MATTE: 4, BACKDROP: 3}
"""Passes a frame of a scene with shadow catchers makes for their compositing, never handed
out (shadow_catcher.py): Combined with the catchers as holes, and the background each pixel
sees."""

AOV_VALUE, AOV_COLOR = "AOV value:", "AOV color:"
"""Prefixes of a Shader AOV's pass (its name follows): one channel, or RGBA."""

PASS_FILL = {"Shadow Catcher": 1.0}
"""What a pass holds where nothing writes it (others: 0): no catcher, no shadow."""


def pass_channels(name: str) -> int:
    """The channel count of a pass (PASS_CHANNELS, INTERNAL_PASSES, a value AOV's 1; 4 for
    each Cryptomatte pass and a colour AOV)."""
    if name.startswith(AOV_VALUE):
        return 1
    return PASS_CHANNELS.get(name) or INTERNAL_PASSES.get(name, 4)


def aov_of(name: str) -> tuple[str, bool] | None:
    """A Shader AOV pass's AOV name and whether it is a colour; None for another pass."""
    for prefix, color in ((AOV_VALUE, False), (AOV_COLOR, True)):
        if name.startswith(prefix):
            return name[len(prefix):], color
    return None


@dataclass
class Frame:
    """The render passes asked for (Combined always), each (height, width, channels) float32,
    row 0 at the bottom (as Blender and OpenGL store images)."""

    width: int
    height: int
    passes: dict[str, np.ndarray]


@dataclass
class Stats:
    """Wall time of each stage, counts of the work done, and warnings for the user."""

    timings: dict[str, float] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    skipped: dict[str, str] = field(default_factory=dict)  # stage -> why it was not needed
    notes: list[str] = field(default_factory=list)  # choices made for the user, not problems

    @contextmanager
    def timed(self, stage: str) -> Iterator[None]:
        start = time.perf_counter()
        try:
            yield
        finally:
            self.timings[stage] = self.timings.get(stage, 0.0) + time.perf_counter() - start

    def summary(self) -> str:
        """One line for Blender's stats bar and the CLI: counts, every stage that ran with its
        time, and every stage left out with the reason."""
        counts = ", ".join(f"{k} {v}" for k, v in self.counts.items())
        times = ", ".join(f"{k} {v * 1000:.0f} ms" for k, v in self.timings.items())
        skipped = ", ".join(f"{k} ({v})" for k, v in self.skipped.items())
        return f"{counts} | ran: {times}" + (f" | skipped: {skipped}" if skipped else "")
