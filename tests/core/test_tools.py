"""Every developer tool (tools/*.py) imports and has a main(): a tool whose imports went stale
when code moved in addon/ (bench_raytrace.py imported build_bvh from gpu/raytrace.py long after
it moved to gpu/bvh.py) fails here, not when someone next measures with it."""

from __future__ import annotations

import importlib
from pathlib import Path

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
