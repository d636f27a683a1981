"""The frame's stages before and after the image: input checks, geometry, planning, light
samples, gather settings, light passes with their visibility, and the final NaN check."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..scene.bounds import robust_bounds
from ..scene.geometry import bounding_sphere, flatten_instances, light_shapes
from ..settings import Settings
from ..transport.guidance import camera_points
from ..transport.lights import KIND_COSINE, KIND_DIRECTIONAL, LightSamples, build_light_samples
from ..transport.view_probe import reaches_view
from .ambient_occlusion import needs_ambient_occlusion
from .batches import shadow_map_batches
from .compose import sanitize
from .gather import RAY_OFFSET, Compensation, LightPass
from .gpu_session import GpuSession
from .ism_maps import ImperfectShadowMapFrame
from .map_check import frame_traces_vpls
from .near_field import NearField
from .planner import plan_frame, plan_gather, visible_bounds
from .progressive import pass_camera, pass_settings
from .reuse import KeptProducts
from .scene_size import SceneLimits, check_scene_size, physical_memory
from .state import FrameState, RenderError, Stage
from .visibility import (
    VISIBILITY,
    ImperfectVisibility,
    RayTracedVisibility,
    ShadowMapVisibility,
)
from .vpl_stage import cull, has_triangles, upload_triangles

MAX_FRAME_SAMPLES = 1 << 27  # supersampled pixels per frame: the passes alone take 80 B each


class CheckInput(Stage):
    """Settings in range, a camera with a non-empty image of a size the GPU can hold, and a
    scene whose flattened triangles fit the machine (before they are flattened)."""

    name = "check input"
    makes = ("camera",)

    def __init__(self, gpu: GpuSession) -> None:
        self.gpu = gpu

    def run(self, frame: FrameState) -> None:
        frame.settings.validate()
        check_scene_size(frame.scene, frame.settings, SceneLimits(
            self.gpu.max_storage, self.gpu.max_texture, physical_memory()))
        frame.user_seed = frame.settings.seed
        frame.settings = pass_settings(frame.settings, frame.pass_index)
        camera = frame.scene.camera
        if camera is None:
            raise RenderError("the scene has no camera")
        if camera.width < 1 or camera.height < 1:
            raise RenderError(f"resolution {camera.width}×{camera.height} is empty")
        aa = frame.settings.antialiasing
        samples = camera.width * camera.height * aa**2
        if samples > MAX_FRAME_SAMPLES:
            raise RenderError(f"{camera.width}×{camera.height} pixels at antialiasing {aa} is "
                              f"{samples:,} samples; the limit is {MAX_FRAME_SAMPLES:,} (lower "
                              f"the resolution or the antialiasing)")
        frame.camera = pass_camera(camera, frame.pass_index, aa)


class FlattenGeometry(Stage):
    """Every instance's triangles in world space, the lights' visible outlines, the bounding
    sphere (far outliers left out, with a warning), and the versions of what changed since the
    last frame."""

    name = "geometry"
    needs = ("camera",)
    makes = ("geometry", "shapes", "centre")

    def __init__(self, kept: KeptProducts) -> None:
        self.kept = kept

    def run(self, frame: FrameState) -> None:
        with frame.stats.timed(self.name):
            frame.geometry = flatten_instances(frame.scene, frame.stats.warnings,
                                               frame.stats.notes)
            frame.shapes = light_shapes(frame.scene)
            self.kept.versions.note(frame.geometry)
            positions = frame.geometry.positions
            key = (self.kept.versions.shape,)
            bounds = self.kept.get("scene bounds", key)
            if bounds is None:  # the triangles moved (a camera edit keeps them)
                box = (positions.min(axis=0), positions.max(axis=0)) if len(positions) else None
                bounds = (bounding_sphere(positions, box), box)
                self.kept.keep("scene bounds", key, bounds)
            sphere, frame.box = bounds
            frame.centre, frame.radius, outliers = robust_bounds(
                positions, frame.camera, frame.scene.instances, sphere)
            if outliers:
                frame.stats.warnings.append(outliers)


class PlanFrame(Stage):
    """What the frame needs (the planner), and the bounds of the surfaces in view."""

    name = "planning"
    needs = ("camera", "geometry")
    makes = ("plan",)

    def __init__(self, kept: KeptProducts) -> None:
        self.kept = kept

    def run(self, frame: FrameState) -> None:
        stats = frame.stats
        with stats.timed(self.name):
            plan = plan_frame(frame.scene, frame.geometry, frame.settings, frame.passes)
            stats.skipped.update(plan.skipped)
            if not frame.settings.planner:
                self.kept.forget(anchors=False)
            in_view = visible_bounds(frame.camera, frame.box) \
                if plan.cull_to_view else None
            if plan.cull_to_view and in_view is None and plan.indirect:
                plan.indirect = False
                stats.skipped["indirect light"] = "the camera sees no surface"
        frame.plan, frame.in_view = plan, in_view


class SampleLights(Stage):
    """Point samples of every light, emissive surface and the world, culled to the view."""

    name = "light samples"
    needs = ("geometry", "plan")
    makes = ("light_samples",)

    def run(self, frame: FrameState) -> None:
        with frame.stats.timed(self.name):
            samples = build_light_samples(frame.scene, frame.geometry, frame.settings,
                                          frame.stats.warnings, frame.plan.sample_dark)
            if frame.plan.cull_to_view:
                samples = cull(samples, frame.in_view, "light samples", frame.stats)
        frame.light_samples = samples


class PlanGather(Stage):
    """The pull-push levels the frame's final settings need."""

    name = "gather plan"
    needs = ("plan",)

    def run(self, frame: FrameState) -> None:
        uses_ism = VISIBILITY[frame.settings.visibility].uses_ism
        levels, skipped = plan_gather(frame.plan, frame.settings, uses_ism)
        frame.stats.skipped.update(skipped)
        frame.settings = replace(frame.settings, pull_push_levels=levels)


def near_field_rays(settings: Settings) -> int:
    """Rays per supersample of the bias compensation from the image (0: none, or ``full``)."""
    on = settings.bias_compensation == "image" and settings.clamp_distance > 0
    return settings.bias_samples if on else 0


def indirect_per_pixel(settings: Settings, glossy: bool) -> bool:
    """Whether VPLs are gathered once per pixel (the pixel-centre g-buffer) rather than per
    supersample: with antialiasing only, and with ``auto`` where no material is ``glossy``."""
    chosen = settings.indirect_resolution
    return settings.antialiasing > 1 and (chosen == "pixel" or (chosen == "auto" and not glossy))


def indirect_interleave(settings: Settings, glossy: bool) -> int:
    """The indirect light's interleaving pattern: ``interleave`` supersamples, or, gathered per
    pixel, ``pixel_interleave`` pixels."""
    if not indirect_per_pixel(settings, glossy):
        return settings.interleave
    return pixel_interleave(settings.interleave, settings.antialiasing)


def pixel_interleave(interleave: int, antialiasing: int) -> int:
    """The pattern of VPLs gathered once per pixel: the power of two at or above interleave /
    antialiasing pixels, so that it covers at least the part of the image that ``interleave``
    supersamples do (8 supersamples at antialiasing 3: 4 pixels); ``interleave`` itself at
    antialiasing 1."""
    return 1 << max(0, math.ceil(math.log2(interleave / antialiasing)))


PROBE_POINTS = 4096  # camera points that test whether shadow-mapped samples reach the view
PROBE_MIN_SAMPLES = 8  # fewer samples are mapped without the test (it costs more than it saves)


def blur_radius(interleave: int, radius: int) -> int:
    """The blur radius, rounded up to a multiple of K/2 (0 without interleaving)."""
    if interleave == 1:
        return 0
    step = interleave // 2
    return -(-radius // step) * step


class PlanLightPasses(Stage):
    """Light samples and VPLs in batches, each with its visibility mode; the bias
    compensation, the blur, and the frame's imperfect shadow maps."""

    name = "visibility"
    needs = ("geometry", "centre", "light_samples", "vpls", "vpl_samples")
    makes = ("light_passes",)

    def __init__(self, gpu: GpuSession, kept: KeptProducts) -> None:
        self.gpu, self.kept = gpu, kept

    def run(self, frame: FrameState) -> None:
        settings, stats, radius = frame.settings, frame.stats, frame.radius
        clamp = max(settings.clamp_distance * radius, radius * 1e-6)
        mode = VISIBILITY[settings.visibility]()
        if mode.uses_ism and frame_traces_vpls(frame, self.gpu, self.kept, clamp):
            mode = RayTracedVisibility()
        vpl_samples = mode.prepare(frame.vpl_samples)
        vpl_batches = mode.batches(vpl_samples, settings, self.gpu.max_texture)
        passes = self._direct_passes(frame)
        pattern = indirect_interleave(settings, frame.geometry.has_specular)
        passes += [LightPass("indirect light", b, clamp, mode, pattern) for b in vpl_batches]
        frame.blur_radius = blur_radius(settings.interleave, settings.blur_radius) \
            if any(p.interleave > 1 and (p.indirect or p.blurred) for p in passes) else 0
        if len(frame.vpls) and settings.clamp_distance \
                and settings.bias_compensation == "full":
            frame.compensation = Compensation(settings.clamp_distance * radius,
                                              settings.bias_samples, settings.seed,
                                              settings.bounces - 1)
        elif len(frame.vpls) and near_field_rays(settings):
            frame.near_field = NearField(settings.clamp_distance * radius,
                                         settings.bias_samples, settings.seed,
                                         settings.bounces > 1)
        frame.traces_rays = frame.compensation is not None or frame.near_field is not None \
            or any(p.visibility.rays_per_sample for p in passes) \
            or needs_ambient_occlusion(frame, self.gpu.ctx.version_code)
        if frame.traces_rays:
            upload_triangles(self.gpu, self.kept, frame.geometry, stats)
        batches = [p.batch for p in passes if p.visibility.uses_ism]
        if batches:
            keyed = vpl_batches[0] if mode.uses_ism and len(vpl_batches) == 1 else None
            frame.ism_maps = ImperfectShadowMapFrame(
                self.gpu.ism, self.kept, frame.geometry, settings, batches,
                (frame.centre, radius), stats, keyed, frame.vpl_keys, frame.user_seed)
        stats.counts.update(
            triangles=frame.geometry.vertex_count // 3, light_samples=len(frame.light_samples),
            vpls=len(frame.vpls), shadow_maps=int(sum(
                p.batch.samples.tiles_per_sample.sum() for p in passes
                if type(p.visibility) is ShadowMapVisibility)))
        frame.light_passes = passes


    def _direct_passes(self, frame: FrameState) -> list[LightPass]:
        """The light samples' passes: ray traced (all samples, or with ``hybrid`` those of
        lights with hard shadows and of suns with an angle), the others with shadow maps
        (imperfect ones for soft lights with soft_light_ism). The world's samples are
        interleaved like VPLs (its light varies smoothly; the blur removes the pattern); a
        sun's angle samples are interleaved without the blur (each supersample traces one of
        them: Cycles' one light sample per path, sharp where the penumbra is); the shadow-mapped
        samples of other soft lights are spread over each pixel's supersamples (each pixel
        takes each sample once: ``_split_world``); hard lights go to every supersample."""
        settings, stats, samples = frame.settings, frame.stats, frame.light_samples
        near = frame.radius * 1e-6
        sun_disc = self._sun_disc(samples)
        traced = {"ray_traced": np.ones(len(samples), bool),
                  "hybrid": ~samples.soft | sun_disc,
                  "shadow_maps": np.zeros(len(samples), bool)}[settings.direct_shadows]
        if traced.any() and self.gpu.ctx.version_code < 430:
            stats.warnings.append("direct shadows use shadow maps: ray tracing needs OpenGL 4.3")
            traced[:] = False
        ray_traced = RayTracedVisibility()
        passes = [LightPass("direct light", b, near, ray_traced, k, blurred)
                  for chosen, k, blurred in self._split_world(samples, traced & ~sun_disc,
                                                              settings.interleave, 1)
                  for b in ray_traced.batches(chosen, settings, 0)]
        sun_samples = samples.subset(np.flatnonzero(traced & sun_disc))
        if len(sun_samples):  # the smallest pattern that gives each supersample one sample
            k = next((k for k in (1, 2, 4) if k * k >= len(sun_samples)), 8)
            passes += [LightPass("direct light", b, near, ray_traced, k, spread=True)
                       for b in ray_traced.batches(sun_samples, settings, 0)]
        mapped = self._reaching_view(frame, samples.subset(np.flatnonzero(~traced)))
        soft_ism = settings.soft_light_ism and mapped.kind.size > 0
        if soft_ism and self.gpu.ctx.version_code < 430:
            stats.warnings.append("soft lights use triangle shadow maps: imperfect shadow maps "
                                  "need OpenGL 4.3")
            soft_ism = False
        as_ism = mapped.soft & mapped.casts_shadow & np.isin(
            mapped.kind, (KIND_COSINE, KIND_DIRECTIONAL)) if soft_ism \
            else np.zeros(len(mapped), bool)
        imperfect, triangles = ImperfectVisibility(), ShadowMapVisibility()
        aa = settings.antialiasing
        passes += [LightPass("direct light", b, near, triangles, k, blurred)
                   for chosen, k, blurred in self._split_world(mapped, ~as_ism,
                                                               settings.interleave, aa)
                   for b in shadow_map_batches(chosen, self.gpu.max_texture)]
        return passes + [LightPass("direct light", b, near, imperfect, k, blurred)
                         for chosen, k, blurred in self._split_world(mapped, as_ism,
                                                                     settings.interleave, aa)
                         for b in imperfect.batches(chosen, settings, 0)]

    def _reaching_view(self, frame: FrameState, samples: LightSamples) -> LightSamples:
        """The shadow-mapped samples that a ray from some point the camera sees reaches
        (transport/view_probe.py), where the frame has the ray tracer anyway; the others are
        counted as skipped. Not with incremental reuse (the viewport's first frames)."""
        settings, stats = frame.settings, frame.stats
        if len(samples) < PROBE_MIN_SAMPLES or not frame.plan.cull_to_view \
                or settings.incremental or not has_triangles(self.kept):
            return samples
        with stats.timed("view probe"):
            points = camera_points(frame.camera, frame.geometry, self.gpu.tracer, PROBE_POINTS,
                                   settings.seed)
            reached = reaches_view(samples, points, self.gpu.tracer, RAY_OFFSET * frame.radius)
        left_out = len(samples) - int(reached.sum())
        if not left_out or len(points) == 0:
            return samples
        stats.skipped[f"{left_out} of {len(samples)} shadow-mapped light samples"] = (
            f"no ray from {len(points)} points the camera sees reaches them")
        return samples.subset(np.flatnonzero(reached))

    @staticmethod
    def _sun_disc(samples: LightSamples) -> np.ndarray:
        """The angle samples of suns (directional, soft, not the world's)."""
        return samples.soft & (samples.kind == KIND_DIRECTIONAL) & ~samples.of_world

    @staticmethod
    def _split_world(samples: LightSamples, chosen: np.ndarray, interleave: int,
                     antialiasing: int) -> list[tuple[LightSamples, int, bool]]:
        """The ``chosen`` world samples, interleaved and blurred; the other ``chosen`` samples
        of soft lights in a pattern of ``antialiasing`` supersamples, so that each pixel's
        supersamples take each sample once (antialiasing² times less work, the pixel's sum
        unchanged but for where each sample is taken inside the pixel); the samples of hard
        lights, which every supersample takes (a hard shadow's edge is antialiased by them).
        Neither of the last two is blurred: shadows, spots and glossy highlights can be
        sharp. With ``antialiasing`` 1 (and for ray-traced samples) the last two are one
        batch, as before soft lights were spread."""
        world, soft = samples.of_world, samples.soft & ~samples.of_world
        others = ((~world, 1, False),) if antialiasing == 1 else \
            ((soft, antialiasing, False), (~world & ~soft, 1, False))
        return [(samples.subset(np.flatnonzero(chosen & subset)), k, blurred)
                for subset, k, blurred in ((world, interleave, interleave > 1), *others)]


class DropBorrowed(Stage):
    """The passes only the frame's own stages read (FramePlan.borrowed: depth of field's and
    motion blur's Depth and Vector) are not handed out."""

    name = "drop borrowed passes"
    needs = ("output",)

    def run(self, frame: FrameState) -> None:
        for name in frame.plan.borrowed:
            frame.output.pop(name, None)


class Sanitize(Stage):
    """No NaN or Inf leaves the renderer (each replaced by 0, with a warning)."""

    name = "sanitize"
    needs = ("output",)

    def run(self, frame: FrameState) -> None:
        sanitize(frame.output, frame.stats)
