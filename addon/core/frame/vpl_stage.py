"""The frame's virtual point lights: traced light paths, incrementally updated ones, or
first bounces from reflective shadow maps; kept while nothing they depend on changes."""

from __future__ import annotations

import numpy as np

from ..gpu.gl import GLUnavailableError
from ..gpu.raytrace import RayTracer
from ..gpu.rsm import render_rsm, rsm_hits, rsm_light_samples
from ..gpu.scene_buffers import SceneBuffers
from ..scene.geometry import WorldGeometry
from ..transport.lights import LightSamples
from ..transport.sequences import scrambled_halton
from ..transport.vpl import VPLs, generate_vpls, propagate
from .gpu_session import GpuSession
from .planner import Bounds, reaches_bounds
from .result import Stats
from .reuse import KeptProducts, lights_key, settings_key
from .state import FrameState, RenderError, Stage

VPL_FIELDS = ("vpl_count", "bounces", "seed", "termination", "vpl_source", "rsm_resolution",
              "incremental", "incremental_budget")
"""Settings VPL generation reads (with the lights, the world and the geometry version)."""
INCREMENTAL_FIELDS = ("vpl_count", "bounces", "seed", "termination")
"""Settings whose change makes Incremental Instant Radiosity start afresh."""


def upload_triangles(gpu: GpuSession, kept: KeptProducts, geometry: WorldGeometry,
                     stats: Stats) -> RayTracer:
    """The ray tracer with this frame's triangles (its BVH built unless it has them)."""
    tracer = gpu.tracer
    key = (kept.versions.shape,)
    if kept.has("bvh", key):
        if "ray tracing setup" not in stats.timings:  # not done earlier in this frame
            stats.skipped["ray tracing setup"] = "triangle positions unchanged"
        return tracer
    with stats.timed("ray tracing setup"):
        try:
            tracer.upload(geometry.positions.reshape(-1, 3, 3))
        except ValueError as exc:  # the scene exceeds the GPU's storage-buffer limit
            raise RenderError(f"indirect light: {exc}") from None
    kept.keep("bvh", key)
    return tracer


def cull(samples: LightSamples, in_view: Bounds | None, what: str, stats: Stats,
         reach: np.ndarray | None = None) -> LightSamples:
    """The samples that can light a surface in view; the others are counted as skipped."""
    reach = reaches_bounds(samples, in_view) if reach is None else reach
    left_out = len(samples) - int(reach.sum())
    if left_out:
        stats.skipped[f"{left_out} of {len(samples)} {what}"] = (
            "cannot light any surface in view")
        return samples.subset(np.flatnonzero(reach))
    return samples


class MakeVPLs(Stage):
    """Light paths' VPLs, reused while their inputs repeat, culled to those that can light
    the view."""

    name = "vpl generation"
    needs = ("geometry", "centre", "plan")
    makes = ("vpls", "vpl_samples")  # and vpl_keys where the VPLs have identities

    def __init__(self, gpu: GpuSession, kept: KeptProducts) -> None:
        self.gpu, self.kept = gpu, kept

    def run(self, frame: FrameState) -> None:
        vpls = self._vpls(frame) if frame.plan.indirect else VPLs.empty()
        keys = vpls.key
        samples = vpls.as_light_samples(frame.settings.vpl_shadow_resolution)
        if frame.plan.cull_to_view and len(vpls):
            reach = reaches_bounds(samples, frame.in_view)
            keys = keys[reach] if keys is not None else None
            samples = cull(samples, frame.in_view, "VPLs", frame.stats, reach)
        frame.vpls, frame.vpl_keys, frame.vpl_samples = vpls, keys, samples

    def _vpls(self, frame: FrameState) -> VPLs:
        scene, settings, stats, kept = frame.scene, frame.settings, frame.stats, self.kept
        key = (kept.versions.geometry, lights_key(scene.lights, scene.world),
               *settings_key(settings, VPL_FIELDS))
        reused = kept.get("vpls", key)
        if reused is not None:
            stats.skipped["vpl generation"] = "lights, world, geometry and settings unchanged"
            stats.skipped["ray tracing setup"] = "no rays to trace: the VPLs are reused"
            return reused
        try:
            tracer = upload_triangles(self.gpu, kept, frame.geometry, stats)
        except GLUnavailableError as exc:
            stats.warnings.append(f"indirect light skipped: {exc}")
            return VPLs.empty()
        geometry, centre, radius = frame.geometry, frame.centre, frame.radius
        if settings.vpl_source == "rsm":
            with stats.timed("vpl generation (rsm)"):
                vpls = self._rsm_vpls(frame, tracer)
        elif settings.incremental:
            with stats.timed("vpl generation (incremental)"):
                vpls = kept.incremental.update(scene, geometry, settings, tracer, centre, radius,
                                               kept.versions.shape,
                                               settings_key(settings, INCREMENTAL_FIELDS))
            s = kept.incremental.stats
            stats.counts.update(vpls_new=s.new_vpls, vpls_reused=s.reused_vpls,
                                anchors_invalid=s.invalid, anchors_created=s.created,
                                anchors_redistributed=s.redistributed)
        else:
            with stats.timed("vpl generation"):
                vpls = generate_vpls(scene, geometry, settings, tracer, centre, radius)
        kept.keep("vpls", key, vpls)
        return vpls

    def _rsm_vpls(self, frame: FrameState, tracer: RayTracer) -> VPLs:
        """VPLs whose first bounce comes from the lights' reflective shadow maps."""
        scene, geometry, settings = frame.scene, frame.geometry, frame.settings
        if np.any(scene.world.radiance > 0) or np.any(geometry.emission > 0):
            frame.stats.warnings.append(
                "reflective shadow maps cover lights only: the world and emissive surfaces "
                "add no indirect light with vpl_source rsm")
        samples = rsm_light_samples(scene, settings)
        if len(samples) == 0:
            return VPLs.empty()
        buffers = SceneBuffers(self.gpu.ctx, geometry)
        try:
            table, position, normal, albedo = render_rsm(self.gpu.ctx, self.gpu.programs,
                                                        buffers, samples, frame.centre,
                                                        frame.radius)
        finally:
            buffers.release()
        first = rsm_hits(table, position, normal, albedo, samples, frame.radius,
                         settings.vpl_count, settings.seed)
        directions = scrambled_halton(settings.vpl_count, 2 * max(0, settings.bounces - 1),
                                      settings.seed)
        return propagate(first, settings.vpl_count, directions, settings, tracer, geometry,
                         frame.radius)
