"""The Blender side of the viewport with stand-ins for what background mode lacks (a 3D view
region and Blender's ``gpu`` module): view_update hands the exported scene to the session,
view_draw hands over a moved view and draws the latest frame between the display-space shader's
bind and unbind."""

from __future__ import annotations

import sys
from pathlib import Path
from types import ModuleType, SimpleNamespace

import numpy as np

SAMPLE = Path(__file__).resolve().parents[2] / "sample_scenes" / "light_point.blend"


class FakeEngine:
    """What ViewportState uses of a RenderEngine, recording the calls."""

    def __init__(self, calls: list) -> None:
        self.calls = calls

    def tag_redraw(self) -> None:
        self.calls.append("redraw")

    def update_stats(self, _stats: str, info: str) -> None:
        self.calls.append(("stats", info))

    def bind_display_space_shader(self, _scene) -> None:
        self.calls.append("bind")

    def unbind_display_space_shader(self) -> None:
        self.calls.append("unbind")


def fake_gpu(calls: list) -> tuple[ModuleType, ModuleType]:
    gpu = ModuleType("gpu")
    gpu.types = SimpleNamespace(
        Buffer=lambda kind, size, data: (kind, size, np.asarray(data)),
        GPUTexture=lambda size, format, data: ("texture", tuple(size), format, data[1]))
    gpu.state = SimpleNamespace(blend_set=lambda mode: calls.append(("blend", mode)))
    presets = ModuleType("gpu_extras.presets")
    presets.draw_texture_2d = lambda texture, position, width, height: calls.append(
        ("draw", texture, position, width, height))
    return gpu, presets


def viewport_context(scene, depsgraph, width: int, height: int,
                     perspective: bool) -> SimpleNamespace:
    """A stand-in for a 3D view's context looking through the scene's camera."""
    camera = scene.camera.evaluated_get(depsgraph)
    region_data = SimpleNamespace(
        view_matrix=np.array(camera.matrix_world.inverted()),
        window_matrix=np.array(camera.calc_matrix_camera(depsgraph, x=width, y=height)),
        is_perspective=perspective, view_perspective="CAMERA")
    return SimpleNamespace(region=SimpleNamespace(width=width, height=height),
                           region_data=region_data, scene=scene)


def test_view_update_and_view_draw(blender, monkeypatch):
    from addon.viewport import ViewportState, region_camera

    calls: list = []
    gpu, presets = fake_gpu(calls)
    monkeypatch.setitem(sys.modules, "gpu", gpu)
    monkeypatch.setitem(sys.modules, "gpu_extras", ModuleType("gpu_extras"))
    monkeypatch.setitem(sys.modules, "gpu_extras.presets", presets)
    blender.ops.wm.open_mainfile(filepath=str(SAMPLE), load_ui=False)
    scene = blender.context.scene
    scene.vpl_gi.vpl_count = 64
    depsgraph = blender.context.evaluated_depsgraph_get()
    context = viewport_context(scene, depsgraph, 80, 60, perspective=True)
    region_data = context.region_data
    engine = FakeEngine(calls)
    state = ViewportState(engine)
    try:
        state.update(context, depsgraph)
        assert state.session.wait_idle(300) and state.session.error is None
        state.draw(engine, context)
        draws = [c for c in calls if isinstance(c, tuple) and c[0] == "draw"]
        assert draws == [("draw", ("texture", (80, 60), "RGBA16F", 80 * 60 * 4), (0, 0), 80, 60)]
        names = [c if isinstance(c, str) else c[0] for c in calls]
        assert names.index("bind") < names.index("draw") < names.index("unbind")
        assert any(c[0] == "stats" and c[1].startswith("VPL GI") for c in calls
                   if isinstance(c, tuple))

        region_data.view_matrix = region_data.view_matrix.copy()
        region_data.view_matrix[0, 3] += 0.1  # the user pans the view
        state.draw(engine, context)
        assert state.session.records[-1].kind == "camera"
        assert state.session.wait_idle(300)
        assert "vpl generation" in state.session.records[-1].skipped

        scene.camera.data.dof.use_dof = True  # seen through the camera: Cycles' viewport blurs
        assert region_camera(context).aperture.focus_distance == \
            scene.camera.data.dof.focus_distance
        state.draw(engine, context)
        assert state.session.records[-1].kind == "camera"
        assert state.session.wait_idle(300) and state.session.error is None
        assert "depth of field" in state.session.records[-1].ran
        region_data.view_perspective = "PERSP"  # the user's own view: in focus
        assert region_camera(context).aperture is None
    finally:
        state.close()
    assert not state.session.alive
    assert not blender.app.timers.is_registered(state._poll)  # it would keep bpy from exiting
