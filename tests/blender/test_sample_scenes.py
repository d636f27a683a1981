"""The committed sample scenes are what the build script makes."""

from __future__ import annotations

import numpy as np
import pytest

from sample_scenes import build_scenes
from tests.blender.rendering import SAMPLE_SCENES


def scene_summary(bpy) -> dict[str, tuple]:
    """Object name -> (type, rounded world matrix, data name) of the open file."""
    return {o.name: (o.type, tuple(np.round(np.array(o.matrix_world), 5).ravel()),
                     o.data.name if o.data else None) for o in bpy.data.objects}


@pytest.mark.parametrize("name", list(build_scenes.SCENES))
def test_committed_scene_matches_the_build_script(blender, tmp_path, name):
    bpy = blender
    rebuilt = build_scenes.build_scene(name, tmp_path)
    bpy.ops.wm.open_mainfile(filepath=str(rebuilt), load_ui=False)
    fresh = scene_summary(bpy)
    bpy.ops.wm.open_mainfile(filepath=str(SAMPLE_SCENES / f"{name}.blend"), load_ui=False)
    assert scene_summary(bpy) == fresh
    assert bpy.context.scene.render.engine == "VPL_GI"
    assert bpy.context.scene.camera is not None
