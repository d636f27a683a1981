"""The "VPL GI" RenderEngine: final renders (F12, background, command line) and pass setup."""

from __future__ import annotations

import traceback
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import bpy
import numpy as np

from . import ENGINE_ID, bake
from .core.frame.id_passes import metadata
from .core.frame.motion_blur import pass_span
from .core.frame.progressive import PassReport
from .core.frame.renderer import RenderCancelled, Renderer, RenderError
from .core.frame.result import Frame, Stats, aov_of
from .core.frame.state import labelled
from .core.gpu.gl import GLUnavailableError, shared_context
from .core.scene.model import Camera, MotionSpan, Scene
from .core.scene.render_region import Region, cropped, region_camera, region_of
from .core.scene.stereo import StereoView, in_view, shift_scale, stereo_view
from .core.settings import SettingsError
from .export import export_scene
from .export_motion import motion_span, sample_motion
from .layer_passes import (
    OPTIONAL_PASSES,
    aov_passes,
    blender_pass_name,
    cryptomatte_families,
    cryptomatte_passes,
    layer_passes,
    light_group_passes,
    toggled,
)
from .preferences import chosen_device
from .viewport import ViewportState


def render_region(scene: bpy.types.Scene, camera: Camera) -> Region | None:
    """The scene's render region (Render Region on, a part of the image) in pixels of the
    camera's image, or None."""
    render = scene.render
    if not render.use_border:
        return None
    return region_of(camera.width, camera.height, (render.border_min_x, render.border_max_x,
                                                   render.border_min_y, render.border_max_y))


@dataclass
class RenderMonitor:
    """Lets a host (the command line) follow and stop renders the engine runs."""

    progress_listeners: list[Callable[[float, str], None]] = field(default_factory=list)
    cancel_requested: bool = False
    last_error: str | None = None
    last_stats: Stats | None = None
    last_warnings: list[str] = field(default_factory=list)


monitor = RenderMonitor()
_renderer: Renderer | None = None


def shared_renderer() -> Renderer:
    """One Renderer (and GL context) per Blender process, created on first render."""
    global _renderer
    if _renderer is None:
        _renderer = Renderer(shared_context(chosen_device()))
    return _renderer


def release_renderer() -> None:
    global _renderer
    if _renderer is not None:
        _renderer.release()
        _renderer = None


class VPLGIRenderEngine(bpy.types.RenderEngine):
    """Global illumination with virtual point lights: final renders and the Rendered
    viewport."""

    bl_idname = ENGINE_ID
    bl_label = "VPL GI"
    bl_use_preview = False
    bl_use_eevee_viewport = True  # Material Preview shading uses EEVEE; Rendered uses ours
    bl_use_shading_nodes_custom = False

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._viewport: ViewportState | None = None
        self._region: Region | None = None  # the final render's render region, if any
        self._layer = ""  # the view layer the final render renders
        self._view = StereoView()  # the view (stereoscopy's eye) it renders

    def __del__(self) -> None:
        viewport = getattr(self, "_viewport", None)
        if viewport is not None:
            viewport.close()

    def view_update(self, context: bpy.types.Context, depsgraph: bpy.types.Depsgraph) -> None:
        """Scene edits in a Rendered viewport: hand what changed to its session."""
        if self._viewport is None:
            self._viewport = ViewportState(self)
        self._viewport.update(context, depsgraph)

    def view_draw(self, context: bpy.types.Context, depsgraph: bpy.types.Depsgraph) -> None:
        """Draw the session's latest frame; never waits for rendering."""
        if self._viewport is None:
            self.view_update(context, depsgraph)
        self._viewport.draw(self, context)

    def render(self, depsgraph: bpy.types.Depsgraph) -> None:
        monitor.last_error, monitor.last_stats, monitor.last_warnings = None, None, []
        try:
            self._render(depsgraph)
        except RenderCancelled:
            self.update_stats("", "Cancelled")
        except (RenderError, SettingsError, GLUnavailableError) as exc:
            self._fail(str(exc))
        except Exception as exc:  # never let an engine bug take Blender down
            traceback.print_exc()
            self._fail(f"internal error: {exc!r} (details in the console)")

    def _export_at(self, depsgraph: bpy.types.Depsgraph, span: MotionSpan | None) -> Scene:
        """The scene at ``span``'s rendered time with its motion (export_motion.py), and the
        render back at its frame; without a span, the frame's scene. Each export reads its
        meshes afresh: a deforming mesh differs at each time."""
        if span is None:
            return export_scene(depsgraph, cancelled=self._cancelled)
        scene = depsgraph.scene
        frame, subframe = scene.frame_current, scene.frame_subframe
        motion = sample_motion(self, depsgraph, span)
        try:
            return export_scene(depsgraph, motion=motion, cancelled=self._cancelled)
        finally:
            if span.centre:  # rendered at its part of the shutter
                self.frame_set(frame, subframe)

    def _cancelled(self) -> bool:
        """Whether Esc in Blender or the command line's host asked the render to stop."""
        return monitor.cancel_requested or self.test_break()

    def _fail(self, message: str) -> None:
        monitor.last_error = message
        self.report({"ERROR"}, f"VPL GI: {message}")
        self.error_set(f"VPL GI: {message}")

    def _render(self, depsgraph: bpy.types.Depsgraph) -> None:
        scene = depsgraph.scene
        settings = scene.vpl_gi.to_settings()
        self.update_stats("", "VPL GI | Exporting scene")
        passes = layer_passes(depsgraph.view_layer)
        span = motion_span(depsgraph.scene, "Vector" in passes)
        first = None if span is None else pass_span(span, 0, settings.passes)
        exported = self._export_at(depsgraph, first)
        if exported.camera is None:
            raise RenderError("the scene has no active camera")
        self._layer = depsgraph.view_layer.name  # this render's; Blender renders each in turn
        self._region = render_region(scene, exported.camera)
        scene_at = None
        if first is not span:  # motion blur's shutter split over the passes
            def scene_at(index: int) -> Scene:
                """Pass ``index`` sees its own part of the shutter (motion_blur.pass_span)."""
                return exported if index == 0 else \
                    self._export_at(depsgraph, pass_span(span, index, settings.passes))

        def progress(fraction: float, message: str) -> None:
            self.update_progress(fraction)
            self.update_stats("", f"VPL GI | {message}")
            for listener in monitor.progress_listeners:
                listener(fraction, message)

        full_result = self.get_result()  # Cryptomatte's manifests, as Cycles stamps them
        for key, value in metadata(exported, cryptomatte_families(depsgraph.view_layer),
                                   depsgraph.view_layer.name).items():
            full_result.stamp_data_add_field(key, value)

        def show(report: PassReport) -> None:
            """Each pass's average in the render window (Esc keeps the passes shown)."""
            self._write_result(report.frame)
            timed = settings.auto_parameters == "time"  # passes until the budget is spent
            if settings.passes > 1 or timed:
                noise = "" if report.noise is None else f", noise {report.noise * 100:.1f} %"
                planned = f" ({settings.time_budget:g} s budget)" if timed \
                    else f"/{settings.passes}"
                self.update_stats("", f"VPL GI | Pass {report.index}{planned}{noise}")

        warnings: list[str] = []
        views = self._views(depsgraph, exported.camera, warnings)
        for view in views:
            self._view = view
            view_scene_at = None if scene_at is None else \
                (lambda index: self._in_view(scene_at(index)))
            view_progress = progress if len(views) == 1 else \
                labelled(progress, f"view '{view.name}'")
            _, stats = shared_renderer().render_progressive(
                self._in_view(exported), settings, view_progress, self._cancelled, passes,
                on_pass=show, scene_at=view_scene_at)
            warnings.extend(w for w in stats.warnings if w not in warnings)
        stats.warnings[:] = warnings
        bake.report(stats, exported.notes)
        monitor.last_stats, monitor.last_warnings = stats, list(stats.warnings)
        for note in stats.notes:
            self.report({"INFO"}, f"VPL GI: {note}")
        for warning in stats.warnings:
            self.report({"WARNING"}, f"VPL GI: {warning}")
        self.update_stats("", f"VPL GI | {stats.summary()}")

    def _views(self, depsgraph: bpy.types.Depsgraph, camera: Camera,
               warnings: list[str]) -> list[StereoView]:
        """The views the render result has (stereoscopy's eyes, each made active in turn by
        the caller), or the camera's own view without stereoscopy."""
        names = [view.name for view in self.get_result().views]
        if not depsgraph.scene.render.use_multiview or len(names) < 2:
            return [StereoView()]
        obj = depsgraph.scene.camera.evaluated_get(depsgraph)
        if camera.panorama is not None:
            warnings.append(f"camera '{obj.name}': its stereo views are the eyes' offset "
                            f"views, not Cycles' spherical stereo")
        render = depsgraph.scene.render
        views = []
        for name in names:
            self.active_view_set(name)
            views.append(stereo_view(
                name, np.array(obj.matrix_world), np.array(self.camera_model_matrix(obj)),
                self.camera_shift_x(obj) - obj.data.shift_x,
                shift_scale(obj.data.sensor_fit, camera.width * render.pixel_aspect_x,
                            camera.height * render.pixel_aspect_y)))
        return views

    def _in_view(self, scene: Scene) -> Scene:
        """The scene seen from the view being rendered (stereoscopy's eye)."""
        return self._in_region(replace(scene, camera=in_view(scene.camera, self._view)))

    def _in_region(self, scene: Scene) -> Scene:
        """The scene with a camera that renders only the render region, where there is one
        and the camera allows it (else the full image renders and is cropped)."""
        if self._region is None:
            return scene
        camera = region_camera(scene.camera, self._region)
        return scene if camera is None else replace(scene, camera=camera)

    def _write_result(self, frame: Frame) -> None:
        region = self._region
        if region is None:
            result = self.begin_result(0, 0, frame.width, frame.height, layer=self._layer,
                                       view=self._view.name)
            passes = frame.passes
        else:  # Blender's result is the region's (its coordinates are the region's)
            result = self.begin_result(0, 0, region.width, region.height, layer=self._layer,
                                       view=self._view.name)
            full = frame.width != region.width or frame.height != region.height
            passes = cropped(frame.passes, region) if full else frame.passes
        layer = result.layers[0]
        ours = {blender_pass_name(name): data for name, data in passes.items()}
        for render_pass in layer.passes:
            data = ours.get(render_pass.name)
            if data is not None and data.shape[2] == render_pass.channels:
                render_pass.rect.foreach_set(np.ascontiguousarray(data, np.float32).ravel())
        self.end_result(result)

    def update_render_passes(self, scene: bpy.types.Scene | None = None,
                             renderlayer: bpy.types.ViewLayer | None = None) -> None:
        """Declare the passes this engine fills, under the running Blender's own names."""
        self.register_pass(scene, renderlayer, "Combined", 4, "RGBA", "COLOR")
        for name, (channels, ids, kind, toggle) in OPTIONAL_PASSES.items():
            if toggled(renderlayer, toggle):
                self.register_pass(scene, renderlayer, blender_pass_name(name), channels, ids,
                                   kind)
        for name in cryptomatte_passes(renderlayer):
            self.register_pass(scene, renderlayer, name, 4, "RGBA", "COLOR")
        for name in light_group_passes(renderlayer):
            self.register_pass(scene, renderlayer, name, 3, "RGB", "COLOR")
        for name in aov_passes(renderlayer):
            color = aov_of(name)[1]
            self.register_pass(scene, renderlayer, blender_pass_name(name), 4 if color else 1,
                               "RGBA" if color else "X", "COLOR" if color else "VALUE")


def register() -> None:
    bpy.utils.register_class(VPLGIRenderEngine)


def unregister() -> None:
    release_renderer()
    bpy.utils.unregister_class(VPLGIRenderEngine)
