"""The renderer: g-buffer, shadow maps and direct light for one frame, in image tiles and
light batches, composed into Blender's passes."""

from __future__ import annotations

import pickle
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import moderngl
import numpy as np

from ..gpu.blur import GeometryAwareBlur
from ..gpu.gl import GLUnavailableError, ProgramCache, shared_context
from ..gpu.ism import ImperfectShadowMaps, atlas_grid
from ..gpu.raytrace import RayTracer
from ..gpu.rsm import render_rsm, rsm_hits, rsm_light_samples
from ..gpu.scene_buffers import SceneBuffers
from ..gpu.shadow_atlas import draw_tiles, near_far, tile_table
from ..gpu.texture_array import upload as upload_textures
from ..scene.environment import background
from ..scene.geometry import WorldGeometry, bounding_sphere, flatten_instances, light_shapes
from ..scene.model import Camera, Scene
from ..settings import Settings
from ..transport.incremental import IncrementalVPLs
from ..transport.lights import KIND_COSINE, KIND_DIRECTIONAL, LightSamples, build_light_samples
from ..transport.sequences import scrambled_halton
from ..transport.vpl import VPLs, generate_vpls, propagate
from . import autotune
from .ism_reuse import ReusedISMAtlas
from .planner import Bounds, plan_frame, plan_gather, reaches_bounds, visible_bounds
from .result import PASS_CHANNELS, Frame, Stats

BACKGROUND_DEPTH = 1e10  # Blender's Z pass value where no surface is hit
MAX_TILE = 1024  # supersampled pixels per image tile edge
ATLAS_TEXELS = 1 << 25  # texels per shadow atlas batch (128 MiB of float32)
MAX_BATCH = 8192  # samples or tiles per batch (rows of a table texture)
MAX_FRAME_SAMPLES = 1 << 27  # supersampled pixels per frame: the passes alone take 80 B each
TEXTURE_UNITS = 0, 1  # the g-buffer's array texture and its table of sizes
ISM_BIAS_TEXELS = 1.0  # measured best against exact visibility (see core/ism.py)
ISM_POINT_SUBSETS = 512  # stratified point sets sampled on the CPU (~0.4 µs a point); VPL k uses
# set k % 512, moved within its triangles by a per-VPL random shift beyond the first 512
SURFACE_VERTICES_BINDING = 4  # the position stream as direct_frag.glsl's storage buffer
PROBE_PATHS = 64  # light paths the automatic mode traces to learn how many VPLs a path leaves


class RenderError(RuntimeError):
    """The scene cannot be rendered; the message says why, for the user."""


class RenderCancelled(RuntimeError):
    """The user asked the render to stop."""


ProgressCallback = Callable[[float, str], None]
CancelCallback = Callable[[], bool]


@dataclass
class _LightPass:
    """One batch of light samples to gather, with its distance clamp and visibility mode."""

    name: str
    batch: _Batch
    min_distance: float
    visibility: str = "classic"  # "classic" (shadow-map atlas), "exact" or "ism"
    interleave: int = 1


@dataclass
class _Compensation:
    """Parameters of the bias-compensation pass."""

    clamp_distance: float
    samples: int
    seed: int
    max_generation: int


@dataclass
class _Batch:
    samples: LightSamples
    resolution: int
    first_tile: np.ndarray
    columns: int
    rows: int


def _plan_batches(samples: LightSamples, max_texture: int) -> list[_Batch]:
    """Group samples by shadow resolution and cut the groups so each atlas fits the budget."""
    batches: list[_Batch] = []
    tiles = samples.tiles_per_sample
    shadowless = np.flatnonzero(tiles == 0)
    for start in range(0, len(shadowless), MAX_BATCH):
        chunk = shadowless[start:start + MAX_BATCH]
        batches.append(_Batch(samples.subset(chunk), 1, np.zeros(len(chunk), int), 1, 1))
    for resolution in np.unique(samples.resolution[tiles > 0]):
        res = int(resolution)
        index = np.flatnonzero((tiles > 0) & (samples.resolution == res))
        per_edge = max(1, max_texture // res)
        capacity = min(per_edge * per_edge, max(6, ATLAS_TEXELS // (res * res)), MAX_BATCH)
        start = 0
        while start < len(index):
            used, stop = 0, start
            while stop < len(index) and used + tiles[index[stop]] <= capacity:
                used += tiles[index[stop]]
                stop += 1
            chunk = index[start:stop]
            first = np.concatenate([[0], np.cumsum(tiles[chunk])[:-1]])
            columns = min(used, per_edge)
            batches.append(_Batch(samples.subset(chunk), res, first, columns,
                                  -(-used // columns)))
            start = stop
    return batches


def _vpl_inputs(scene: Scene, settings: Settings) -> bytes:
    """Everything besides geometry that VPL generation reads, as comparable bytes."""
    relevant = (settings.vpl_count, settings.bounces, settings.seed, settings.termination,
                settings.vpl_source, settings.rsm_resolution, settings.incremental,
                settings.incremental_budget)
    return pickle.dumps((scene.lights, scene.world, relevant))


def _blur_radius(settings: Settings) -> int:
    """The blur radius, rounded up to a multiple of K/2 (0 without interleaving)."""
    k = settings.interleave
    if k == 1:
        return 0
    step = k // 2
    return -(-settings.blur_radius // step) * step


def _samples_per_draw(exact: bool, compensation: _Compensation | None) -> int:
    """Light samples one full-screen draw may loop over. Software OpenGL (Mesa llvmpipe) stops
    a shader invocation's loops after 65535 iterations in all; a ray's BVH traversal takes a
    few hundred, so ray-traced passes are split into draws of few samples."""
    rays_per_sample = 1 if exact else 0
    if compensation is not None:
        rays_per_sample = compensation.samples * (1 + rays_per_sample)
    return 4096 if rays_per_sample == 0 else max(1, 48 // rays_per_sample)


def _ism_tiles_per_atlas(resolution: int) -> int:
    """Imperfect shadow maps of ``resolution``² that one atlas holds."""
    return max(1, min(MAX_BATCH, ATLAS_TEXELS // (resolution * resolution)))


def _plan_ism_batches(samples: LightSamples, resolution: int) -> list[_Batch]:
    """VPLs in groups whose imperfect shadow maps fit one atlas (tile k = VPL k)."""
    size = _ism_tiles_per_atlas(resolution)
    batches = []
    for start in range(0, len(samples), size):
        index = np.arange(start, min(start + size, len(samples)))
        columns, rows = atlas_grid(len(index))
        batch_samples = samples.subset(index)
        batch_samples.resolution = np.full(len(index), resolution)
        batches.append(_Batch(batch_samples, resolution, np.arange(len(index)), columns, rows))
    return batches


def _tile_projection(projection: np.ndarray, x0: int, x1: int, y0: int, y1: int,
                     width: int, height: int) -> np.ndarray:
    """Projection whose clip volume covers only pixels [x0, x1) × [y0, y1) of the image."""
    hx, hy = (x1 - x0) / width, (y1 - y0) / height
    cx, cy = (x0 + x1) / width - 1.0, (y0 + y1) / height - 1.0
    crop = np.array([[1 / hx, 0, 0, -cx / hx], [0, 1 / hy, 0, -cy / hy], [0, 0, 1, 0],
                     [0, 0, 0, 1]])
    return crop @ projection


def _set_uniforms(program: moderngl.Program, **values: object) -> None:
    """Set the uniforms the compiler kept (unused ones are optimised away)."""
    for name, value in values.items():
        if name in program:
            program[name].value = value


def _downsample(image: np.ndarray, factor: int) -> np.ndarray:
    if factor == 1:
        return image
    h, w, c = image.shape
    return image.reshape(h // factor, factor, w // factor, factor, c).mean(axis=(1, 3))


def _texture_state(geometry: WorldGeometry) -> tuple[np.ndarray, ...]:
    """What VPLs read from textures: UVs, texture attributes and pixels (none untextured)."""
    if not geometry.has_textures:
        return ()
    return geometry.uv, geometry.texture, *(t.pixels for t in geometry.textures)


class Renderer:
    """Renders Scenes with one standalone OpenGL context. Create once, call render() per frame."""

    def __init__(self, ctx: moderngl.Context | None = None) -> None:
        self.ctx = ctx or shared_context()
        self.programs = ProgramCache(self.ctx)
        self.max_texture = int(self.ctx.info["GL_MAX_TEXTURE_SIZE"])
        self._helpers: dict[type, RayTracer | ImperfectShadowMaps | GeometryAwareBlur] = {}
        self.incremental = IncrementalVPLs()
        self._geometry: tuple[np.ndarray, ...] | None = None  # last frame's, to spot changes
        self._geometry_version = 0
        self._shape_version = 0
        self._traced_version = -1  # shape version the ray tracer holds
        self._vpl_cache: tuple[tuple, VPLs] | None = None  # (inputs, VPLs) of the last frame
        self._ism_atlas = ReusedISMAtlas()
        self._kept_atlases: dict[tuple, list] = {}  # shadow atlases of the last frame
        self.cost_cache: Path | None = autotune.default_cost_cache()
        """Where the automatic mode's measured cost model is kept (None: measure each time)."""

    def release(self) -> None:
        for helper in self._helpers.values():
            helper.release()
        self._helpers.clear()
        self.programs.release()
        self.forget_frames()

    def forget_frames(self) -> None:
        """Drop what is reused between frames (VPLs, uploaded geometry, ISM atlas)."""
        self.incremental = IncrementalVPLs()
        self._geometry, self._vpl_cache = None, None
        self._ism_atlas.forget()
        self._keep_atlases(None)
        self._traced_version = -1

    def _keep_atlases(self, kept: _KeptAtlases | None) -> None:
        """Keep the shadow atlases the last frame used; release the others."""
        now = kept.used if kept is not None else {}
        for key, objects in self._kept_atlases.items():
            if key not in now:
                for obj in objects:
                    obj.release()
        self._kept_atlases = now

    @property
    def last_vpls(self) -> VPLs | None:
        """The VPLs of the last frame that had indirect light (None before)."""
        return self._vpl_cache[1] if self._vpl_cache is not None else None

    @property
    def has_ism(self) -> bool:
        """Whether imperfect shadow maps were rendered (their atlas can be read)."""
        helper = self._helpers.get(ImperfectShadowMaps)
        return helper is not None and helper.atlas is not None

    def _note_geometry(self, geometry: WorldGeometry) -> None:
        """Bump the shape version when triangle positions differ from the last frame's (the
        ray tracer's BVH and the imperfect shadow maps depend on them), and the geometry
        version when positions, materials or textures do (VPLs depend on all)."""
        arrays = (geometry.positions, geometry.albedo, geometry.emission, *_texture_state(geometry))
        before = self._geometry or ()
        same = [k < len(before) and a.shape == before[k].shape and np.array_equal(a, before[k])
                for k, a in enumerate(arrays)]
        if not same[0]:
            self._shape_version += 1
        if not all(same) or len(before) != len(arrays):
            self._geometry = tuple(a.copy() for a in arrays)
            self._geometry_version += 1

    # -- one frame ------------------------------------------------------------------------
    def render(self, scene: Scene, settings: Settings, progress: ProgressCallback | None = None,
               cancelled: CancelCallback | None = None, passes: frozenset[str] | None = None
               ) -> tuple[Frame, Stats]:
        """Render ``scene``: the Combined pass and ``passes`` (all by default; the others come
        back zero when the planner is on). Raises RenderError or RenderCancelled."""
        settings.validate()
        camera = scene.camera
        if camera is None:
            raise RenderError("the scene has no camera")
        if camera.width < 1 or camera.height < 1:
            raise RenderError(f"resolution {camera.width}×{camera.height} is empty")
        samples_per_frame = camera.width * camera.height * settings.antialiasing**2
        if samples_per_frame > MAX_FRAME_SAMPLES:
            raise RenderError(f"{camera.width}×{camera.height} pixels at antialiasing "
                              f"{settings.antialiasing} is {samples_per_frame:,} samples; the "
                              f"limit is {MAX_FRAME_SAMPLES:,} (lower the resolution or the "
                              f"antialiasing)")
        stats = Stats(warnings=list(scene.warnings))
        report = progress or (lambda _f, _m: None)
        check = cancelled or (lambda: False)

        with stats.timed("geometry"):
            geometry = flatten_instances(scene, stats.warnings)
            shapes = light_shapes(scene)
            centre, radius = bounding_sphere(geometry.positions)
            self._note_geometry(geometry)
        with stats.timed("planning"):
            plan = plan_frame(scene, geometry, settings, passes)
            stats.skipped.update(plan.skipped)
            if not settings.planner:
                self._forget_reuse()
            in_view = visible_bounds(camera, geometry.positions) if plan.cull_to_view else None
            if plan.cull_to_view and in_view is None and plan.indirect:
                plan.indirect = False
                stats.skipped["indirect light"] = "the camera sees no surface"
        with stats.timed("light samples"):
            samples = build_light_samples(scene, geometry, settings, stats.warnings,
                                          plan.sample_dark)
            if plan.cull_to_view:
                samples = self._cull(samples, in_view, "light samples", stats)
        if settings.auto_parameters != "off" and plan.indirect:
            settings = self._automatic(scene, settings, geometry, samples, stats, report,
                                       (centre, radius, in_view))
        levels, skipped = plan_gather(plan, settings)
        stats.skipped.update(skipped)
        settings = replace(settings, pull_push_levels=levels)
        vpls = self._virtual_point_lights(scene, geometry, settings, centre, radius, stats,
                                          plan.indirect)
        keys = vpls.key
        vpl_samples = vpls.as_light_samples(settings.vpl_shadow_resolution)
        if plan.cull_to_view and len(vpls):
            reach = reaches_bounds(vpl_samples, in_view)
            keys = keys[reach] if keys is not None else None
            vpl_samples = self._cull(vpl_samples, in_view, "VPLs", stats, reach)
        mode = settings.visibility
        if mode == "exact":
            vpl_samples.casts_shadow[:] = False
        vpl_batches = (_plan_ism_batches(vpl_samples, settings.ism_resolution) if mode == "ism"
                       else _plan_batches(vpl_samples, self.max_texture))
        soft_ism = settings.soft_light_ism and samples.kind.size > 0
        if soft_ism and self.ctx.version_code < 430:
            stats.warnings.append("soft lights use triangle shadow maps: imperfect shadow maps "
                                  "need OpenGL 4.3")
            soft_ism = False
        as_ism = samples.soft & samples.casts_shadow & np.isin(
            samples.kind, (KIND_COSINE, KIND_DIRECTIONAL)) if soft_ism \
            else np.zeros(len(samples), bool)
        direct_ism = _plan_ism_batches(samples.subset(np.flatnonzero(as_ism)),
                                       settings.ism_resolution)
        work = [_LightPass("direct light", b, radius * 1e-6)
                for b in _plan_batches(samples.subset(np.flatnonzero(~as_ism)),
                                       self.max_texture)]
        work += [_LightPass("direct light", b, radius * 1e-6, visibility="ism")
                 for b in direct_ism]
        clamp = max(settings.clamp_distance * radius, radius * 1e-6)
        work += [_LightPass("indirect light", b, clamp, visibility=mode,
                            interleave=settings.interleave) for b in vpl_batches]
        blur_radius = _blur_radius(settings) if len(vpl_samples) else 0
        compensation = None
        if settings.bias_compensation and len(vpls) and settings.clamp_distance > 0:
            compensation = _Compensation(settings.clamp_distance * radius, settings.bias_samples,
                                         settings.seed, settings.bounces - 1)
        ism_batches = [p.batch for p in work if p.visibility == "ism"]
        keyed = vpl_batches[0] if mode == "ism" and len(vpl_batches) == 1 else None
        ism = self._ism_renderer(geometry, settings, ism_batches, centre, radius, stats, keyed,
                                 keys) if ism_batches else None
        stats.counts.update(triangles=geometry.vertex_count // 3, light_samples=len(samples),
                            vpls=len(vpls), shadow_maps=int(sum(
                                p.batch.samples.tiles_per_sample.sum() for p in work
                                if p.visibility == "classic")))

        aa = settings.antialiasing
        width, height = camera.width * aa, camera.height * aa
        tiles = [(x, min(x + MAX_TILE, width), y, min(y + MAX_TILE, height))
                 for y in range(0, height, MAX_TILE) for x in range(0, width, MAX_TILE)]
        output = {name: np.zeros((camera.height, camera.width, c), np.float32)
                  for name, c in PASS_CHANNELS.items()}
        kept = _KeptAtlases(self._kept_atlases, self._shape_version) if len(tiles) == 1 \
            else None
        resources = _FrameResources(self.ctx, geometry, shapes, self.programs, kept)
        if mode == "exact" or compensation is not None:
            self.tracer.bind()
        try:
            steps, done = len(tiles) * max(1, len(work)), 0
            keep_atlas = len(work) == 1
            for (x0, x1, y0, y1) in tiles:
                with stats.timed("g-buffer"):
                    gbuffer = resources.gbuffer(camera, x0, x1, y0, y1, width, height)
                direct = resources.accumulator(x1 - x0, y1 - y0)
                indirect = resources.accumulator(x1 - x0, y1 - y0)
                for light_pass in work:
                    if check():
                        raise RenderCancelled("render cancelled")
                    with stats.timed(f"{light_pass.name} maps"):
                        if light_pass.visibility == "ism":
                            atlas = ism(light_pass.batch)
                        else:
                            atlas = resources.atlas(light_pass.batch, centre, radius,
                                                    reuse=keep_atlas)
                        self.ctx.finish()
                    with stats.timed(light_pass.name):
                        target = indirect if light_pass.name == "indirect light" else direct
                        resources.shade(light_pass, atlas, target, centre, radius,
                                        settings.shadow_bias)
                        self.ctx.finish()
                    if compensation is not None:
                        with stats.timed("bias compensation"):
                            resources.shade(light_pass, atlas, indirect, centre, radius,
                                            settings.shadow_bias, compensation)
                            self.ctx.finish()
                    done += 1
                    report(done / steps, f"{light_pass.name} {done}/{steps}")
                if blur_radius:
                    with stats.timed("blur"):
                        indirect_light = resources.blurred(self.blur, indirect, blur_radius)
                else:
                    indirect_light = resources.read_accumulator(indirect)
                with stats.timed("compose"):
                    self._compose(output, gbuffer, resources.read_accumulator(direct),
                                  indirect_light, scene, aa, x0, y0, plan.passes)
        finally:
            resources.release()
            self._keep_atlases(kept)
        if resources.kept_hits:
            stats.skipped["shadow maps"] = (f"{resources.kept_hits} atlas(es) of unchanged "
                                            f"lights and triangles kept from the last frame")
        self._sanitize(output, stats)
        return Frame(camera.width, camera.height, output), stats

    def _automatic(self, scene: Scene, settings: Settings, geometry: WorldGeometry,
                   samples: LightSamples, stats: Stats, report: ProgressCallback,
                   bounds: tuple[np.ndarray, float, Bounds | None]) -> Settings:
        """Settings with the parameters the automatic mode chooses for this frame."""
        name = str(self.ctx.info["GL_RENDERER"])

        def measure() -> autotune.CostModel:
            report(0.0, "Measuring this machine's cost model (once)")
            with stats.timed("cost model calibration"):
                model = autotune.calibrate(self._calibration_frame, name,
                                           Settings(antialiasing=1))
            self._forget_reuse()
            return model

        cost = autotune.cached_cost_model(self.cost_cache, name, measure)
        camera = scene.camera
        with stats.timed("automatic parameters"):
            work = autotune.Workload(
                pixels=camera.width * camera.height * settings.antialiasing**2,
                triangles=geometry.vertex_count // 3,
                shadow_tiles=int(samples.tiles_per_sample.sum()),
                vpls_per_path=self._vpls_per_path(scene, geometry, settings, stats, *bounds),
                bounces=settings.bounces, max_subsets=ISM_POINT_SUBSETS,
                pooled=self._ism_pool(geometry))
        choice = autotune.choose(settings, work, cost, autotune.load_error_model())
        stats.notes.append(f"automatic parameters ({settings.auto_parameters}): "
                           f"{choice.describe()}")
        stats.counts.update(auto_vpl_count=choice.settings.vpl_count)
        return choice.settings

    def _ism_pool(self, geometry: WorldGeometry) -> tuple[int, int]:
        """(points per VPL, subsets) of the ISM point pool sampled for these triangles."""
        helper = self._helpers.get(ImperfectShadowMaps)
        key = getattr(helper, "pool_key", None)
        if key is None or key[0] != geometry.vertex_count // 3:
            return 0, 0
        return key[2], key[1]

    def _vpls_per_path(self, scene: Scene, geometry: WorldGeometry, settings: Settings,
                       stats: Stats, centre: np.ndarray, radius: float,
                       in_view: Bounds | None) -> float:
        """VPLs that can light the view per light path, from a probe of PROBE_PATHS paths."""
        probe = replace(settings, vpl_count=PROBE_PATHS, incremental=False)
        try:
            tracer = self.tracer
        except GLUnavailableError:
            return float(settings.bounces)
        self._upload_triangles(tracer, geometry, stats)
        vpls = generate_vpls(scene, geometry, probe, tracer, centre, radius)
        samples = vpls.as_light_samples(settings.vpl_shadow_resolution)
        in_view_count = int(reaches_bounds(samples, in_view).sum()) if in_view is not None \
            else len(vpls)
        return max(in_view_count, 1) / PROBE_PATHS

    def _calibration_frame(self, settings: Settings) -> dict[str, float | int]:
        """Stage timings and counts of one frame of the calibration scene."""
        self._forget_reuse()
        scene = autotune.calibration_scene()
        _, stats = self.render(scene, settings)
        camera = scene.camera
        return {**stats.timings, "vpls": stats.counts["vpls"],
                "pixels": camera.width * camera.height * settings.antialiasing**2,
                "triangles": stats.counts["triangles"],
                "shadow_tiles": stats.counts["shadow_maps"]}

    def _forget_reuse(self) -> None:
        """Drop what the planner would reuse from the last frame (VPLs, BVH, ISM and shadow
        atlases); Incremental Instant Radiosity keeps its anchors."""
        self._vpl_cache = None
        self._traced_version = -1
        self._ism_atlas.forget()
        self._keep_atlases(None)

    @staticmethod
    def _cull(samples: LightSamples, in_view: Bounds | None, what: str, stats: Stats,
              reach: np.ndarray | None = None) -> LightSamples:
        """The samples that can light a surface in view; the others are counted as skipped."""
        reach = reaches_bounds(samples, in_view) if reach is None else reach
        left_out = len(samples) - int(reach.sum())
        if left_out:
            stats.skipped[f"{left_out} of {len(samples)} {what}"] = (
                "cannot light any surface in view")
            return samples.subset(np.flatnonzero(reach))
        return samples

    def _virtual_point_lights(self, scene: Scene, geometry: WorldGeometry, settings: Settings,
                              centre: np.ndarray, radius: float, stats: Stats, needed: bool
                              ) -> VPLs:
        """Trace light paths for the indirect light (none when the plan needs none)."""
        if not needed:
            return VPLs.empty()
        inputs = (self._geometry_version, _vpl_inputs(scene, settings))
        if self._vpl_cache is not None and self._vpl_cache[0] == inputs:
            stats.skipped["vpl generation"] = "lights, world, geometry and settings unchanged"
            stats.skipped["ray tracing setup"] = "no rays to trace: the VPLs are reused"
            return self._vpl_cache[1]
        try:
            tracer = self.tracer
        except GLUnavailableError as exc:
            stats.warnings.append(f"indirect light skipped: {exc}")
            return VPLs.empty()
        self._upload_triangles(tracer, geometry, stats)
        if settings.vpl_source == "rsm":
            with stats.timed("vpl generation (rsm)"):
                vpls = self._rsm_vpls(scene, geometry, settings, centre, radius, stats)
        elif settings.incremental:
            with stats.timed("vpl generation (incremental)"):
                vpls = self.incremental.update(scene, geometry, settings, tracer, centre, radius,
                                               self._shape_version)
            s = self.incremental.stats
            stats.counts.update(vpls_new=s.new_vpls, vpls_reused=s.reused_vpls,
                                anchors_invalid=s.invalid, anchors_created=s.created,
                                anchors_redistributed=s.redistributed)
        else:
            with stats.timed("vpl generation"):
                vpls = generate_vpls(scene, geometry, settings, tracer, centre, radius)
        self._vpl_cache = (inputs, vpls)
        return vpls

    def _upload_triangles(self, tracer: RayTracer, geometry: WorldGeometry,
                          stats: Stats) -> None:
        """Give the ray tracer this frame's triangles (its BVH), unless it has them."""
        if self._traced_version == self._shape_version:
            if "ray tracing setup" not in stats.timings:  # not done earlier in this frame
                stats.skipped["ray tracing setup"] = "triangle positions unchanged"
            return
        with stats.timed("ray tracing setup"):
            try:
                tracer.upload(geometry.positions.reshape(-1, 3, 3))
            except ValueError as exc:  # the scene exceeds the GPU's storage-buffer limit
                raise RenderError(f"indirect light: {exc}") from None
        self._traced_version = self._shape_version

    def _rsm_vpls(self, scene: Scene, geometry: WorldGeometry, settings: Settings,
                  centre: np.ndarray, radius: float, stats: Stats) -> VPLs:
        """VPLs whose first bounce comes from the lights' reflective shadow maps."""
        if np.any(scene.world.radiance > 0) or np.any(geometry.emission > 0):
            stats.warnings.append("reflective shadow maps cover lights only: the world and "
                                  "emissive surfaces add no indirect light with vpl_source rsm")
        samples = rsm_light_samples(scene, settings)
        if len(samples) == 0:
            return VPLs.empty()
        buffers = SceneBuffers(self.ctx, geometry)
        try:
            table, position, normal, albedo = render_rsm(self.ctx, self.programs, buffers,
                                                        samples, centre, radius)
        finally:
            buffers.release()
        first = rsm_hits(table, position, normal, albedo, samples, radius, settings.vpl_count,
                         settings.seed)
        directions = scrambled_halton(settings.vpl_count, 2 * max(0, settings.bounces - 1),
                                      settings.seed)
        return propagate(first, settings.vpl_count, directions, settings, self.tracer, geometry,
                         radius)

    def _ism_renderer(self, geometry: WorldGeometry, settings: Settings,
                      batches: list[_Batch], centre: np.ndarray, radius: float, stats: Stats,
                      keyed_batch: _Batch | None, keys: np.ndarray | None):
        """A function rendering one batch's imperfect shadow maps (points sampled once per
        scene and VPL count, reused while the triangle count and settings repeat). With a
        single batch the atlas is kept between frames: ``keys`` identify the VPLs of
        ``keyed_batch``, and only maps of VPLs with new keys are rendered."""
        ism = self.ism
        triangles = geometry.positions.reshape(-1, 3, 3)
        most = max(len(b.samples) for b in batches)  # rounded up to a power of two, so that
        subsets = min(ISM_POINT_SUBSETS, 1 << max(0, most - 1).bit_length())  # counts that
        # vary a little from frame to frame (Incremental Instant Radiosity) keep the pool
        start = time.perf_counter()
        try:
            sampled = ism.prepare(triangles, subsets, settings.ism_points, settings.seed)
        except ValueError as exc:  # the point pool exceeds the GPU's storage-buffer limit
            raise RenderError(f"imperfect shadow maps: {exc} (lower ism_points)") from None
        if sampled:
            stats.timings["ism points"] = time.perf_counter() - start
        else:
            stats.skipped["ism points"] = "triangle count and point settings unchanged"
        levels = min(settings.pull_push_levels, int(np.log2(settings.ism_resolution)))
        stats.counts["isms"] = sum(len(b.samples) for b in batches)
        if geometry.vertex_count == 0:
            return lambda batch: ism.render(triangles, np.zeros((0, 3)), np.zeros((0, 3)),
                                            settings.ism_resolution, levels)
        cache: dict[int, moderngl.Texture] = {}
        settings_key = (self._shape_version, settings.ism_points, settings.ism_resolution,
                        levels, settings.seed)
        max_tiles = _ism_tiles_per_atlas(settings.ism_resolution)

        def render(batch: _Batch) -> moderngl.Texture:
            if id(batch) in cache:
                return cache[id(batch)]
            s = batch.samples
            if len(batches) > 1:  # several atlases per frame: nothing is kept between frames
                self._ism_atlas.forget()
                texture = ism.render(triangles, s.position, s.axis, settings.ism_resolution,
                                     levels, s.kind == KIND_DIRECTIONAL, (centre, radius))
                rendered = len(s)
            else:
                use = self._ism_atlas.render(ism, triangles, s,
                                             keys if batch is keyed_batch else None,
                                             settings_key, settings.ism_resolution, levels,
                                             (centre, radius), max_tiles)
                texture, rendered = use.texture, use.rendered
                batch.first_tile, batch.columns, batch.rows = use.tiles, use.columns, use.rows
                cache[id(batch)] = texture
            stats.counts["isms_rendered"] = stats.counts.get("isms_rendered", 0) + rendered
            if rendered == 0:
                stats.skipped["ism"] = "VPLs and geometry unchanged since the last frame"
                return texture
            for stage, seconds in ism.timings.items():
                stats.timings[f"ism {stage}"] = stats.timings.get(f"ism {stage}", 0) + seconds
            return texture
        return render

    def _helper(self, cls):
        """This context's GPU helper of a class (ray tracer, ISMs, blur), made on first use;
        the ray tracer and ISMs raise GLUnavailableError without OpenGL 4.3."""
        if cls not in self._helpers:
            self._helpers[cls] = cls(self.ctx, self.programs)
        return self._helpers[cls]

    @property
    def ism(self) -> ImperfectShadowMaps:
        return self._helper(ImperfectShadowMaps)

    @property
    def blur(self) -> GeometryAwareBlur:
        return self._helper(GeometryAwareBlur)

    @property
    def tracer(self) -> RayTracer:
        return self._helper(RayTracer)

    @staticmethod
    def _compose(output: dict[str, np.ndarray], gbuffer: dict[str, np.ndarray],
                 direct: np.ndarray, indirect: np.ndarray, scene: Scene, aa: int, x0: int,
                 y0: int, passes: frozenset[str]) -> None:
        """Turn one supersampled tile's buffers into Blender's ``passes`` at output
        resolution."""
        covered = gbuffer["normal"][..., 3:4]
        albedo, emission = gbuffer["albedo"][..., :3], gbuffer["emission"][..., :3]
        diff_dir, diff_ind = direct[..., :3], indirect[..., :3]
        combined = np.concatenate([(diff_dir + diff_ind) * albedo + emission, covered], axis=-1)
        if not scene.film_transparent:
            combined[..., 3:] += 1.0 - covered
            combined[..., :3] += (1.0 - covered) * background(
                scene.world, scene.camera, aa, x0, y0, covered.shape[1], covered.shape[0])
        h, w = covered.shape[0] // aa, covered.shape[1] // aa
        region = (slice(y0 // aa, y0 // aa + h), slice(x0 // aa, x0 // aa + w))
        images = {"Combined": lambda: combined, "DiffDir": lambda: diff_dir,
                  "DiffInd": lambda: diff_ind, "DiffCol": lambda: albedo,
                  "Emit": lambda: emission, "Normal": lambda: gbuffer["normal"][..., :3]}
        for name, image in images.items():
            if name in passes:
                output[name][region] = _downsample(image(), aa)
        if "Depth" in passes:
            depth = np.where(covered > 0, gbuffer["position"][..., 3:4], BACKGROUND_DEPTH)
            output["Depth"][region] = depth.reshape(h, aa, w, aa, 1).min(axis=(1, 3))

    @staticmethod
    def _sanitize(output: dict[str, np.ndarray], stats: Stats) -> None:
        """Never hand out NaN or Inf: replace them and say how many there were."""
        for name, image in output.items():
            bad = ~np.isfinite(image)
            if bad.any():
                stats.warnings.append(f"{int(bad.sum())} non-finite values in {name} set to 0")
                image[bad] = 0.0


class _KeptAtlases:
    """Shadow atlases kept between frames (single-tile frames: the viewport, small renders):
    an atlas whose samples and triangle positions repeat is not rendered again."""

    def __init__(self, previous: dict[tuple, list], shape_version: int) -> None:
        self.previous = previous
        self.shape_version = shape_version
        self.used: dict[tuple, list] = {}
        self.texels = 0

    def key(self, batch: _Batch, centre: np.ndarray, radius: float) -> tuple:
        s = batch.samples
        return (self.shape_version, batch.resolution, batch.columns, batch.rows,
                s.position.tobytes(), s.axis.tobytes(), s.kind.tobytes(),
                s.casts_shadow.tobytes(), batch.first_tile.tobytes(), tuple(centre), radius)

    def room_for(self, batch: _Batch) -> bool:
        """Whether the atlas fits the budget of kept atlases (twice one batch's)."""
        texels = batch.columns * batch.rows * batch.resolution**2
        return self.texels + texels <= 2 * ATLAS_TEXELS

    def keep(self, key: tuple, objects: list, batch: _Batch) -> None:
        self.used[key] = objects
        self.texels += batch.columns * batch.rows * batch.resolution**2


class _FrameResources:
    """GPU objects of one frame: vertex buffers, g-buffer, shadow atlas and accumulator."""

    def __init__(self, ctx: moderngl.Context, geometry: WorldGeometry, shapes: WorldGeometry,
                 programs: ProgramCache, kept: _KeptAtlases | None = None) -> None:
        self.ctx = ctx
        self.kept = kept
        self.programs = programs
        self._objects: list = []
        self._tile_objects: list = []
        self._atlas_objects: list = []
        self.scene = self._buffers(geometry)
        self.shapes = self._buffers(shapes)
        self.textures = None  # the texture path: (array texture, size table)
        if geometry.has_textures:
            self.textures = tuple(self._own(t) for t in upload_textures(ctx, geometry.textures))
        self._atlas: tuple[moderngl.Texture, _Batch] | None = None
        self.kept_hits = 0  # atlases taken from an earlier frame
        self._light_table: moderngl.Texture | None = None

    def _own(self, obj):
        self._objects.append(obj)
        return obj

    def _buffers(self, geometry: WorldGeometry) -> SceneBuffers | None:
        if geometry.vertex_count == 0:
            return None
        try:
            return self._own(SceneBuffers(self.ctx, geometry))
        except ValueError as exc:  # more triangles or materials than the GPU's textures hold
            self.release()
            raise RenderError(f"the scene is too large for this GPU: {exc}") from None

    def release(self) -> None:
        self._release_tile()
        for obj in self._atlas_objects + self._objects:
            obj.release()
        self._objects.clear()

    def _tile(self, obj):
        self._tile_objects.append(obj)
        return obj

    def _release_tile(self) -> None:
        for obj in self._tile_objects:
            obj.release()
        self._tile_objects.clear()

    # -- g-buffer -------------------------------------------------------------------------
    def gbuffer(self, camera: Camera, x0: int, x1: int, y0: int, y1: int, width: int,
                height: int) -> dict[str, np.ndarray]:
        self._release_tile()
        size = (x1 - x0, y1 - y0)
        names = ("position", "normal", "geometric", "albedo", "emission")
        textures = [self._tile(self.ctx.texture(size, 4, dtype="f4")) for _ in names]
        fbo = self._tile(self.ctx.framebuffer(textures, self._tile(
            self.ctx.depth_renderbuffer(size))))
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.BLEND | moderngl.CULL_FACE)
        projection = _tile_projection(camera.projection_matrix, x0, x1, y0, y1, width, height)
        view_projection = projection @ camera.view_matrix
        camera_to_world = np.linalg.inv(camera.view_matrix)
        uniforms = {
            "u_view_projection": tuple(view_projection.T.astype("f4").ravel()),
            "u_view": tuple(camera.view_matrix.T.astype("f4").ravel()),
            "u_camera_position": tuple(camera_to_world[:3, 3]),
            "u_camera_forward": tuple(-camera_to_world[:3, 2] /
                                      np.linalg.norm(camera_to_world[:3, 2])),
            "u_orthographic": camera.is_orthographic,
        }
        scene_defines = {"TEXTURED": 1} if self.textures else None
        for buffers, defines in ((self.scene, scene_defines), (self.shapes, {"ONE_SIDED": 1})):
            if buffers is None:
                continue
            program = self.programs.get("gbuffer_vert.glsl", "gbuffer_frag.glsl", defines)
            _set_uniforms(program, **uniforms)
            streams = buffers.streams()
            if defines is scene_defines and self.textures:
                array, sizes = self.textures
                streams.append((buffers.uv, "2f", "in_uv"))
                array.use(TEXTURE_UNITS[0])
                sizes.use(TEXTURE_UNITS[1])
                _set_uniforms(program, u_textures=TEXTURE_UNITS[0],
                              u_texture_sizes=TEXTURE_UNITS[1])
            buffers.bind_materials(program)
            vao = self._tile(self.ctx.vertex_array(program, streams, skip_errors=True))
            vao.render(moderngl.TRIANGLES, vertices=buffers.vertex_count)
        self.ctx.disable(moderngl.DEPTH_TEST)
        self._gbuffer_textures = dict(zip(names, textures, strict=True))
        return {name: np.frombuffer(tex.read(), dtype=np.float32).reshape(size[1], size[0], 4)
                for name, tex in self._gbuffer_textures.items()}

    def accumulator(self, width: int, height: int) -> moderngl.Framebuffer:
        texture = self._tile(self.ctx.texture((width, height), 4, dtype="f4"))
        fbo = self._tile(self.ctx.framebuffer([texture]))
        fbo.clear(0.0, 0.0, 0.0, 0.0)
        return fbo

    # -- shadows --------------------------------------------------------------------------
    def atlas(self, batch: _Batch, centre: np.ndarray, radius: float, reuse: bool
              ) -> moderngl.Texture:
        """Render the batch's shadow maps into one atlas of tiles (cube faces or directional),
        or return the kept atlas of the same samples and triangles."""
        if reuse and self._atlas is not None and self._atlas[1] is batch:
            return self._atlas[0]
        key = self.kept.key(batch, centre, radius) if self.kept is not None else None
        if key is not None and key in self.kept.previous:
            objects = self.kept.previous[key]
            self.kept.keep(key, objects, batch)
            self.kept_hits += 1
            return objects[0]
        for obj in self._atlas_objects:
            obj.release()
        self._atlas_objects.clear()
        keeping = key is not None and self.kept.room_for(batch)
        objects: list = []
        keep = objects.append if keeping else self._atlas_objects.append
        res = batch.resolution
        size = (batch.columns * res, batch.rows * res)
        texture = self.ctx.texture(size, 1, dtype="f4")
        depth = self.ctx.depth_renderbuffer(size)
        fbo = self.ctx.framebuffer([texture], depth)
        for obj in (texture, depth, fbo):
            keep(obj)
        if keeping:
            self.kept.keep(key, objects, batch)
        fbo.use()
        fbo.clear(3.0e38, 0.0, 0.0, 0.0, depth=1.0)
        self._atlas = (texture, batch)
        s = batch.samples
        if self.scene is None or not s.casts_shadow.any():
            return texture
        table = tile_table(s, batch.first_tile, batch.columns, centre, radius)
        tiles = table.texture(self.ctx)
        keep(tiles)
        tiles.use(0)
        program = self.programs.get("shadow_vert.glsl", "shadow_frag.glsl")
        vao = self.ctx.vertex_array(program, self.scene.streams(normals=False))
        keep(vao)
        _set_uniforms(program, u_tiles=0, u_atlas_tiles=(batch.columns, batch.rows),
                      u_scene_centre=tuple(centre), u_scene_radius=radius)
        draw_tiles(self.ctx, vao, self.scene.vertex_count, len(table.rows))
        return texture

    # -- shading --------------------------------------------------------------------------
    def shade(self, light_pass: _LightPass, atlas: moderngl.Texture,
              accumulator: moderngl.Framebuffer, centre: np.ndarray, radius: float,
              bias: float, compensation: _Compensation | None = None) -> None:
        """Add one batch's light to the accumulator (additive blending); with
        ``compensation``, add the light its distance clamp removed instead."""
        batch = light_pass.batch
        s = batch.samples
        near, far = near_far(s, centre, radius)
        table = s.table(batch.first_tile, near, far)
        light_table = self.ctx.texture((table.shape[1], len(s)), 4, table.tobytes(), dtype="f4")
        textures = self._gbuffer_textures
        for unit, name in enumerate(("position", "normal", "geometric")):
            textures[name].use(unit)
        light_table.use(3)
        atlas.use(4)
        defines: dict[str, object] = {
            "exact": {"EXACT_VISIBILITY": 1}, "ism": {"ISM_VISIBILITY": 1},
        }.get(light_pass.visibility, {})
        uniforms: dict[str, object] = {}
        if compensation is not None:
            defines.update(BIAS_COMPENSATION=1, SURFACE_VERTICES_BINDING=SURFACE_VERTICES_BINDING)
            uniforms.update(u_clamp_distance=compensation.clamp_distance,
                            u_bias_samples=compensation.samples, u_seed=compensation.seed,
                            u_max_generation=compensation.max_generation)
        needs_430 = light_pass.visibility == "exact" or compensation is not None
        program = self.programs.get("fullscreen_vert.glsl", "direct_frag.glsl", defines,
                                    version=430 if needs_430 else 410)
        _set_uniforms(program, u_position=0, u_normal=1, u_geometric=2, u_light_table=3,
                      u_shadow_atlas=4, u_atlas_columns=batch.columns,
                      u_interleave=light_pass.interleave, u_ism_bias=ISM_BIAS_TEXELS,
                      u_scene_centre=tuple(centre), u_scene_radius=radius, u_shadow_bias=bias,
                      u_min_distance2=light_pass.min_distance**2, u_ray_offset=1e-4 * radius,
                      **uniforms)
        if compensation is not None:  # the surfaces rays reach: positions and materials
            self.scene.positions.bind_to_storage_buffer(SURFACE_VERTICES_BINDING)
            self.scene.bind_materials(program)
        accumulator.use()
        self.ctx.enable(moderngl.BLEND)
        self.ctx.blend_func = moderngl.ONE, moderngl.ONE
        vao = self.ctx.vertex_array(program, [])
        chunk = _samples_per_draw(light_pass.visibility == "exact", compensation)
        for first in range(0, len(s), chunk):
            _set_uniforms(program, u_first=first, u_count=min(chunk, len(s) - first))
            vao.render(moderngl.TRIANGLES, vertices=3)
        self.ctx.disable(moderngl.BLEND)
        vao.release()
        light_table.release()

    def blurred(self, blur: GeometryAwareBlur, accumulator: moderngl.Framebuffer,
                radius: int) -> np.ndarray:
        """The accumulator after the geometry-aware blur, as (h, w, 4) float32."""
        textures = self._gbuffer_textures
        result = blur.apply(accumulator.color_attachments[0], textures["position"],
                            textures["normal"], radius)
        w, h = result.size
        image = np.frombuffer(result.read(), dtype=np.float32).reshape(h, w, 4)
        result.release()
        return image

    def read_accumulator(self, accumulator: moderngl.Framebuffer) -> np.ndarray:
        w, h = accumulator.size
        return np.frombuffer(accumulator.read(components=4, dtype="f4"),
                             dtype=np.float32).reshape(h, w, 4)
