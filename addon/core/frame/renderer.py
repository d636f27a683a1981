"""The renderer: one frame is the stages below, run in order over a FrameState."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import moderngl
import numpy as np

from ..blas_threads import single_threaded_blas
from ..gpu.blur import GeometryAwareBlur
from ..gpu.gl import make_current, shared_context
from ..gpu.ism import ImperfectShadowMaps
from ..gpu.raytrace import RayTracer
from ..scene.model import Scene
from ..settings import Settings
from ..transport.incremental import IncrementalVPLs
from ..transport.vpl import VPLs
from . import panorama
from .automatic import ChooseParameters
from .budget import render_budget
from .denoise import Denoise, PlanDenoise
from .depth_of_field import DepthOfField, PlanDepthOfField
from .gpu_session import GpuSession
from .image import RenderImage
from .light_groups import PASS_PREFIX, group_scene, has_emitters, requested_groups
from .motion_blur import MotionBlur
from .progressive import PassReport, merge_stats, render_passes
from .result import MATTE, Frame, Stats
from .reuse import KeptProducts
from .shadow_catcher import SHADOW_CATCHER_PASS, alone_bounces, catchers_alone, composite
from .stages import (
    CheckInput,
    DropBorrowed,
    FlattenGeometry,
    PlanFrame,
    PlanGather,
    PlanLightPasses,
    SampleLights,
    Sanitize,
)
from .state import (
    CancelCallback,
    FrameState,
    ProgressCallback,
    RenderCancelled,
    RenderError,
    Stage,
    labelled,
)
from .vpl_stage import MakeVPLs

__all__ = ["RenderCancelled", "RenderError", "Renderer"]

PANORAMA_NOT_AUTOMATIC = ("automatic parameters are not applied to a panoramic camera: "
                          "rendered with the settings as set")


PANORAMA_STILL = ("a panoramic camera's motion is not blurred within a pass, and its Vector "
                  "pass is empty: with motion blur, each pass renders one moment of the "
                  "shutter (more passes, a smoother blur)")


def _without_automatic(scene: Scene, settings: Settings) -> tuple[Scene, Settings]:
    """A panorama's scene and settings with the automatic mode off (it would choose for each
    face alike), and a warning where it was on."""
    if settings.auto_parameters == "off":
        return scene, settings
    return (replace(scene, warnings=[*scene.warnings, PANORAMA_NOT_AUTOMATIC]),
            replace(settings, auto_parameters="off"))


class Renderer:
    """Renders Scenes with one OpenGL context. Create once, call render() per frame; what
    frames reuse from each other is kept in ``kept``. ``share_programs_of``: a renderer on
    the same context whose compiled programs this one uses too (and must outlive it)."""

    def __init__(self, ctx: moderngl.Context | None = None,
                 share_programs_of: Renderer | None = None) -> None:
        programs = share_programs_of.gpu.programs if share_programs_of else None
        self.gpu = GpuSession(ctx or shared_context(), programs)
        self.kept = KeptProducts()
        self._automatic = ChooseParameters(self.gpu, self.kept, self.render)
        self._last_pass = (-1, 0)  # the index of the last pass rendered and its last path + 1
        self._helpers: dict[str, Renderer] = {}  # renderers of parts of scenes (their
        # shadow catchers, their light groups) alone, each with its own reuse, by _helper
        self.stages: list[Stage] = [
            CheckInput(self.gpu), FlattenGeometry(self.kept), PlanFrame(self.kept), SampleLights(),
            self._automatic, PlanGather(), MakeVPLs(self.gpu, self.kept),
            PlanLightPasses(self.gpu, self.kept), PlanDenoise(), PlanDepthOfField(),
            RenderImage(self.gpu, self.kept), Denoise(), MotionBlur(), DepthOfField(),
            DropBorrowed(), Sanitize(),
        ]

    def render(self, scene: Scene, settings: Settings, progress: ProgressCallback | None = None,
               cancelled: CancelCallback | None = None, passes: frozenset[str] | None = None,
               pass_index: int = 0) -> tuple[Frame, Stats]:
        """Render one pass of ``scene`` (``pass_index`` of a progressive render): the Combined
        pass and ``passes`` (all by default, and all when the planner is off, but those of
        result.ON_DEMAND_PASSES only where asked for; OIDN adds its guides, the Denoising
        Data passes). Raises RenderError or RenderCancelled."""
        last_index, paths_end = self._last_pass
        first_path = paths_end if pass_index and last_index == pass_index - 1 else \
            pass_index * settings.vpl_count  # passes of N paths before it elsewhere (viewport)
        report = progress or (lambda _f, _m: None)
        check = cancelled or (lambda: False)
        render = self._view_renderer(scene)
        make_current(self.gpu.ctx)  # Blender 5's compositor makes its own current here
        image, stats, used = render(scene, settings, report, check, passes, pass_index,
                                    first_path)
        self._last_pass = (pass_index, first_path + used.vpl_count)
        if MATTE in image.passes:
            self._composite_catchers(image, stats, scene, used, report, check,
                                     passes is not None and SHADOW_CATCHER_PASS in passes,
                                     pass_index, first_path)
        for group in requested_groups(passes):
            self._light_group(image, stats, scene, used, group, report, check, pass_index)
        return image, stats

    def _light_group(self, image: Frame, stats: Stats, scene: Scene, settings: Settings,
                     group: str, progress: ProgressCallback, cancelled: CancelCallback,
                     pass_index: int) -> None:
        """The light group's pass (light_groups.py): a frame of the scene lit by the group's
        emitters alone, with the settings the scene's frame used, by a renderer of its own;
        black where nothing in the group emits."""
        name = PASS_PREFIX + group
        alone = group_scene(scene, group)
        if not has_emitters(alone):
            image.passes[name] = np.zeros((image.height, image.width, 3), np.float32)
            return
        with stats.timed(f"light group '{group}'"):
            frame, group_stats = self._helper("light groups").render(
                alone, replace(settings, auto_parameters="off"),
                labelled(progress, f"Light group '{group}'"), cancelled,
                frozenset({"Combined"}), pass_index)
        image.passes[name] = frame.passes["Combined"][..., :3]
        stats.warnings.extend(f"light group '{group}': {w}" for w in group_stats.warnings
                              if f"light group '{group}': {w}" not in stats.warnings)

    def _helper(self, job: str) -> Renderer:
        """The renderer of ``job`` (a part of scenes rendered alone), made on first use on
        this renderer's context with its programs."""
        if job not in self._helpers:
            self._helpers[job] = Renderer(self.gpu.ctx, share_programs_of=self)
        return self._helpers[job]

    def _composite_catchers(self, image: Frame, stats: Stats, scene: Scene, settings: Settings,
                            progress: ProgressCallback, cancelled: CancelCallback,
                            as_matte: bool, pass_index: int, first_path: int) -> None:
        """Shadow catchers as Cycles composites them (shadow_catcher.py): the catchers alone
        rendered with the settings the scene's frame used (no bounces where they lie in one
        plane), by a renderer of their own (its reuse between frames is theirs)."""
        render = self._helper("shadow catchers")._view_renderer(scene)

        with stats.timed("shadow catchers alone"):
            bounces = alone_bounces(scene, settings.bounces)
            alone, alone_stats, _ = render(catchers_alone(scene),
                                           replace(settings, auto_parameters="off",
                                                   bounces=bounces),
                                           labelled(progress, "Shadow catchers alone"),
                                           cancelled, frozenset({"Combined"}),
                                           pass_index, first_path)
        composite(image.passes, alone.passes, scene.film_transparent, as_matte)
        stats.warnings.extend(w for w in alone_stats.warnings if w not in stats.warnings)

    def _view_renderer(self, scene: Scene) -> Callable[..., tuple[Frame, Stats, Settings]]:
        """How this renderer renders the scene's view: ``_render_panorama`` for a panoramic
        camera, else ``_render_view``."""
        panoramic = scene.camera is not None and scene.camera.panorama is not None
        return self._render_panorama if panoramic else self._render_view

    def _render_view(self, scene: Scene, settings: Settings, progress: ProgressCallback,
                     cancelled: CancelCallback, passes: frozenset[str] | None, pass_index: int,
                     first_path: int) -> tuple[Frame, Stats, Settings]:
        """One view through the stages: its frame, stats and the settings it used (the
        automatic mode's choice)."""
        frame = FrameState(scene, settings, passes, Stats(warnings=list(scene.warnings)),
                           progress, cancelled, pass_index=pass_index, first_path=first_path)
        with single_threaded_blas():  # no spinning BLAS thread takes a core from the driver
            for stage in self.stages:
                frame.check_cancelled()  # Esc in Blender: also between the long stages
                stage.run(frame)
        return Frame(frame.camera.width, frame.camera.height, frame.output), frame.stats, \
            frame.settings

    def _render_panorama(self, scene: Scene, settings: Settings, progress: ProgressCallback,
                         cancelled: CancelCallback, passes: frozenset[str] | None,
                         pass_index: int, first_path: int) -> tuple[Frame, Stats, Settings]:
        """A panoramic camera's frame from the cube faces its image looks through
        (panorama.py), each with the same light paths; camera guidance is off, since it would
        keep other VPLs for each face (seams)."""
        scene, settings = _without_automatic(scene, settings)
        if scene.motion is not None:
            scene = replace(scene, motion=None, warnings=[*scene.warnings, PANORAMA_STILL])
        camera = scene.camera
        rays = panorama.pixel_directions(camera.panorama, camera.width, camera.height)
        needed = panorama.needed_faces(rays)
        if not needed:
            raise RenderError("the panoramic camera sees nothing: its lens covers no angle")
        size = panorama.face_size(camera.panorama, camera.width, camera.height)
        views = panorama.face_cameras(camera, size, needed)
        face_settings = replace(settings, vpl_guidance="off")
        faces, total, used = {}, Stats(), face_settings
        for n, (k, view) in enumerate(zip(needed, views, strict=True)):
            def face_progress(fraction: float, message: str, n: int = n) -> None:
                progress((n + fraction) / len(needed), f"View {n + 1}/{len(needed)} | {message}")

            frame, stats, used = self._render_view(replace(scene, camera=view), face_settings,
                                                    face_progress, cancelled, passes,
                                                    pass_index, first_path)
            faces[k] = frame.passes
            merge_stats(total, stats)
        total.counts["views"] = len(needed)
        total.notes.append(f"panorama from {len(needed)} views of {views[0].width} px")
        image = panorama.resample(faces, size, rays)
        return Frame(camera.width, camera.height, image), total, used

    def render_progressive(self, scene: Scene, settings: Settings,
                           progress: ProgressCallback | None = None,
                           cancelled: CancelCallback | None = None,
                           passes: frozenset[str] | None = None,
                           on_pass: Callable[[PassReport], None] | None = None,
                           scene_at: Callable[[int], Scene] | None = None
                           ) -> tuple[Frame, Stats]:
        """A final render: ``settings.passes`` passes averaged (see progressive.py), or in the
        automatic mode 'time' passes until the budget is spent (budget.py), with ``on_pass``
        called after each; ``scene_at`` gives pass k's scene where passes see the scene at
        different times (motion blur), else every pass renders ``scene``."""
        settings.validate()
        if scene.camera is not None and scene.camera.panorama is not None:
            scene, settings = _without_automatic(scene, settings)

        def one_pass(scene: Scene, settings: Settings, index: int,
                     progress: ProgressCallback, cancelled: CancelCallback
                     ) -> tuple[Frame, Stats]:
            if scene_at is not None:
                scene = scene_at(index)
            return self.render(scene, settings, progress, cancelled, passes, index)

        if settings.auto_parameters == "time":
            return render_budget(one_pass, self._automatic, scene, settings, progress,
                                 cancelled, on_pass)
        return render_passes(one_pass, scene, settings, progress, cancelled, on_pass)

    def release(self) -> None:
        """Release every GPU object (the context stays the caller's)."""
        make_current(self.gpu.ctx)
        for helper in self._helpers.values():  # first: they share this renderer's programs
            helper.release()
        self._helpers.clear()
        self.gpu.release()
        self.forget_frames()

    def forget_frames(self) -> None:
        """Drop everything reused between frames; the next frame starts afresh."""
        self.kept.forget(anchors=True)
        for helper in self._helpers.values():
            helper.forget_frames()

    @property
    def ctx(self) -> moderngl.Context:
        return self.gpu.ctx

    @property
    def cost_cache(self) -> Path | None:
        """Where the automatic mode's measured cost model is kept (None: measure each time)."""
        return self._automatic.cost_cache

    @cost_cache.setter
    def cost_cache(self, path: Path | None) -> None:
        self._automatic.cost_cache = path

    @property
    def incremental(self) -> IncrementalVPLs:
        """Incremental Instant Radiosity's state (its anchors and last frame's statistics)."""
        return self.kept.incremental

    @property
    def last_vpls(self) -> VPLs | None:
        """The VPLs of the last frame that had indirect light (None before)."""
        return self.kept.latest("vpls")

    @property
    def has_ism(self) -> bool:
        """Whether imperfect shadow maps were rendered (their atlas can be read)."""
        helper = self.gpu.ism_if_made
        return helper is not None and helper.atlas is not None

    @property
    def ism(self) -> ImperfectShadowMaps:
        return self.gpu.ism

    @property
    def blur(self) -> GeometryAwareBlur:
        return self.gpu.blur

    @property
    def tracer(self) -> RayTracer:
        return self.gpu.tracer
