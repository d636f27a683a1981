"""Blender side of the interactive viewport: depsgraph updates and the region's view in, the
session's latest frame out as a texture. The frame logic is in core/viewport.py; this module
only translates and draws (Blender's ``gpu`` module exists only with a window)."""

from __future__ import annotations

import contextlib
import threading
import weakref
from dataclasses import replace

import bpy
import numpy as np

from . import bake
from .core.frame.renderer import Renderer
from .core.gpu.gl import create_context
from .core.scene.model import Camera
from .core.settings import SettingsError
from .core.viewport_session import Changes, Update, ViewportSession, classify, view_camera
from .export import ExportCache, camera_aperture, export_scene
from .preferences import chosen_device

_sessions: weakref.WeakSet[ViewportSession] = weakref.WeakSet()
_states: weakref.WeakSet[ViewportState] = weakref.WeakSet()


def depsgraph_updates(depsgraph: bpy.types.Depsgraph) -> list[Update]:
    """The depsgraph's updates as plain records."""
    updates = []
    for u in depsgraph.updates:
        datablock = u.id
        object_type = datablock.type if isinstance(datablock, bpy.types.Object) else ""
        updates.append(Update(datablock.id_type, datablock.name, object_type,
                              u.is_updated_geometry, u.is_updated_transform,
                              u.is_updated_shading))
    return updates


def region_camera(context: bpy.types.Context) -> Camera:
    """The camera of the 3D viewport being drawn (its own view, or the scene camera's when
    looking through it: Blender's region matrices cover both, and then, as in Cycles' viewport,
    the camera's depth of field)."""
    region, view = context.region, context.region_data
    camera = view_camera(np.array(view.view_matrix), np.array(view.window_matrix),
                         region.width, region.height, view.is_perspective)
    scene_camera = context.scene.camera
    if view.view_perspective == "CAMERA" and scene_camera is not None \
            and scene_camera.type == "CAMERA" and scene_camera.data.type != "PANO":
        camera.aperture = camera_aperture(scene_camera)  # (a panorama: drawn in perspective)
    return camera


def _same_camera(a: Camera | None, b: Camera) -> bool:
    return a is not None and (a.width, a.height) == (b.width, b.height) and \
        np.array_equal(a.view_matrix, b.view_matrix) and \
        np.array_equal(a.projection_matrix, b.projection_matrix) and a.aperture == b.aperture


class ViewportState:
    """One viewport's session, export cache, redraw timer and texture."""

    def __init__(self, engine: bpy.types.RenderEngine) -> None:
        self.new_frame = threading.Event()
        device = chosen_device()
        self.session = ViewportSession(on_frame=self.new_frame.set,
                                       renderer_factory=lambda: Renderer(create_context(device)))
        _sessions.add(self.session)
        self.cache = ExportCache()
        self.exported = False
        self.display = ""
        self._texture = None
        self._drawn = -1
        engine_ref = self._engine = weakref.ref(engine)
        session = self.session
        _states.add(self)

        def poll() -> float | None:
            engine = engine_ref()
            if engine is None or not session.alive:
                return None
            if self.new_frame.is_set():
                self.new_frame.clear()
                try:
                    engine.tag_redraw()
                except ReferenceError:  # Blender freed the engine
                    session.close()
                    return None
            return 0.05 if not session.idle else 0.25
        self._poll = poll
        bpy.app.timers.register(poll, first_interval=0.05)

    def update(self, context: bpy.types.Context, depsgraph: bpy.types.Depsgraph) -> None:
        """Classify the depsgraph's changes and hand the session what they touch."""
        changes = classify(depsgraph_updates(depsgraph)) if self.exported \
            else Changes(settings=True)
        props = depsgraph.scene.vpl_gi
        if props.viewport_display != self.display:
            changes.display, self.display = True, props.viewport_display
        try:
            settings = props.to_settings()
        except SettingsError as exc:
            self.session.status = f"VPL GI | Error: {exc}"
            return
        for name in changes.geometry:
            self.cache.forget(name)
        scene = export_scene(depsgraph, self.cache) if changes.needs_export or not \
            self.exported else None
        self.exported = True
        if scene is not None and self.cache.unbaked:  # its frames are shown until the bake's
            settings = replace(settings, viewport_passes=1)  # export: no idle passes first
            session = self.session
            bake.bake_soon(self._baked, ready=lambda: session.idle or not session.alive)
        self.session.edit(changes, scene=scene, camera=region_camera(context), settings=settings,
                          display=self.display)

    def _baked(self) -> None:
        """New bakes: export again at the next update (until then the viewport colour)."""
        self.exported = False
        engine = self._engine()
        if engine is not None:
            with contextlib.suppress(ReferenceError):  # Blender freed the engine
                engine.tag_update()

    def draw(self, engine: bpy.types.RenderEngine, context: bpy.types.Context) -> None:
        """Hand over a moved view, then draw the latest frame (display colour management by
        Blender's display-space shader) and show the session's status."""
        import gpu
        from gpu_extras.presets import draw_texture_2d

        camera = region_camera(context)
        if not _same_camera(self.session.camera, camera):
            self.session.edit(Changes(camera=True), camera=camera)
        frame = self.session.latest()
        engine.update_stats("", self.session.status)
        if frame is None:
            return
        if frame.number != self._drawn:
            h, w = frame.image.shape[:2]
            pixels = np.ascontiguousarray(frame.image, np.float32).ravel()
            self._texture = gpu.types.GPUTexture((w, h), format="RGBA16F", data=gpu.types.Buffer(
                "FLOAT", pixels.size, pixels))
            self._drawn = frame.number
        gpu.state.blend_set("ALPHA_PREMULT")
        engine.bind_display_space_shader(context.scene)
        draw_texture_2d(self._texture, (0, 0), context.region.width, context.region.height)
        engine.unbind_display_space_shader()
        gpu.state.blend_set("NONE")

    def close(self) -> None:
        """Stop the session and its redraw timer (a registered timer keeps a bpy process from
        exiting)."""
        self.session.close()
        if bpy.app.timers.is_registered(self._poll):
            bpy.app.timers.unregister(self._poll)
        self._texture = None


def close_all() -> None:
    """Stop every viewport session and its timer (add-on disabled, file closed)."""
    for state in list(_states):
        state.close()
    for session in list(_sessions):
        session.close()


@bpy.app.handlers.persistent
def _on_load_pre(*_args) -> None:
    close_all()


def register() -> None:
    bpy.app.handlers.load_pre.append(_on_load_pre)


def unregister() -> None:
    if _on_load_pre in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.remove(_on_load_pre)
    close_all()
