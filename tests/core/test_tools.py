"""Every developer tool (tools/*.py) imports and has a main(): a tool whose imports went stale
when code moved in addon/ (bench_raytrace.py imported build_bvh from gpu/raytrace.py long after
it moved to gpu/bvh.py) fails here, not when someone next measures with it."""

from __future__ import annotations

import importlib
from pathlib import Path

import numpy as np
import pytest

TOOLS = Path(__file__).resolve().parents[2] / "tools"
NEEDS_BLENDER = frozenset({"error_tables"})
"""Tools that import bpy when imported (through devtools.report): tests/blender/test_report.py
imports them."""


@pytest.mark.parametrize("name", sorted(p.stem for p in TOOLS.glob("*.py")
                                        if p.stem not in NEEDS_BLENDER))
def test_the_tool_imports_and_has_a_main(name):
    module = importlib.import_module(f"tools.{name}")
    assert callable(getattr(module, "main", None))


def test_error_parts_splits_a_frames_error_into_noise_and_the_rest():
    """tools/error_parts.py: frames of a known bias plus independent noise split into both."""
    from devtools.metrics import unbiased_squared_error as squared_error
    from tools.error_parts import block_mean, split

    rng = np.random.default_rng(0)
    truth = np.zeros((64, 64, 3))
    frames = [truth + 0.3 + rng.normal(0.0, 0.2, truth.shape) for _ in range(8)]
    errors2 = [squared_error(frame, truth, truth) for frame in frames]
    noise2, rest2 = split(errors2, squared_error(np.mean(frames, axis=0), truth, truth))
    assert np.sqrt(noise2) == pytest.approx(0.2, rel=0.02)
    assert np.sqrt(rest2) == pytest.approx(0.3, rel=0.02)
    blocks = block_mean(np.arange(2 * 4 * 3, dtype=float).reshape(2, 4, 3), 2)
    assert blocks.shape == (1, 2, 3) and blocks[0, 0, 0] == (0 + 3 + 12 + 15) / 4
