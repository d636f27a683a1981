"""The add-on registered once for all in-process Blender tests, and unregistered at the end
(a bpy process with a registered RenderEngine hangs at exit otherwise)."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def blender():
    import bpy

    import addon

    addon.register()
    try:
        yield bpy
    finally:
        addon.unregister()
        bpy.ops.wm.read_factory_settings(use_empty=True)
