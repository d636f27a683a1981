"""numpy's BLAS on one thread while a frame renders.

OpenBLAS's worker threads spin for a while after each call that woke them, and where the GPU
driver runs on the CPU (llvmpipe) a spinning thread takes a core from it: on 2 cores the time
mode's ray probe took 42 instead of 27 ms, in streaks of up to a quarter of a second after the
numpy work before it, so the mode priced Sponza's rays at 4.9 instead of 3.1 times the
calibration room's and chose half the light paths (docs/measurements.md, *The ray probe and
numpy's threads*). A frame's BLAS products are small (points times 3×3 or 4×4 matrices), which
one thread computes as fast."""

from __future__ import annotations

from contextlib import AbstractContextManager
from functools import cache

from threadpoolctl import ThreadpoolController


@cache
def _controller() -> ThreadpoolController:
    return ThreadpoolController()


def single_threaded_blas() -> AbstractContextManager:
    """A context in which the BLAS libraries the process has loaded use one thread (their
    settings restored on leaving it)."""
    return _controller().limit(limits=1, user_api="blas")
