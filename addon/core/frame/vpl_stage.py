"""The frame's virtual point lights: traced light paths, incrementally updated ones, or
first bounces from reflective shadow maps; kept while nothing they depend on changes."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..gpu.gl import GLUnavailableError
from ..gpu.raytrace import Cutouts, RayTracer
from ..gpu.rsm import render_rsm, rsm_hits, rsm_light_samples
from ..gpu.scene_buffers import SceneBuffers
from ..scene.geometry import WorldGeometry
from ..settings import Settings
from ..transport.guidance import (
    USEFUL_SHARE,
    camera_points,
    candidate_paths,
    contributions,
    guide,
    refined_contributions,
)
from ..transport.lights import LightSamples
from ..transport.sequences import scrambled_halton
from ..transport.vpl import VPLs, generate_vpls, propagate
from .gpu_session import GpuSession
from .planner import Bounds, reaches_bounds
from .result import Stats
from .reuse import KeptProducts, content_key, settings_key
from .state import FrameState, RenderError, Stage

VPL_FIELDS = ("vpl_count", "bounces", "seed", "termination", "vpl_source", "rsm_resolution",
              "incremental", "incremental_budget", "vpl_guidance", "guidance_candidates")
"""Settings VPL generation reads (with the lights, the world, the geometry version and, with
camera guidance, the camera)."""
GUIDE_POINTS = 64  # camera points a candidate VPL's contribution is estimated at
MORE_GUIDE_POINTS = 448
"""Further camera points for the candidates that light none of the first GUIDE_POINTS (on
Sponza two VPLs the 64 points missed made the worst seed's brightest patch; six seeds: mean
error 36.5 → 33.0 %, docs/measurements.md)."""
DECISION_PATHS = 128
"""Light paths of the probe that decides whether guidance is worth it (the share of their VPLs
that lights a camera point, against USEFUL_SHARE): a few ms, where deciding from the candidates
(4 × vpl_count paths then) cost 0.4 s on the Cornell box, which then skips them."""
INCREMENTAL_FIELDS = ("vpl_count", "bounces", "seed", "termination")
"""Settings whose change makes Incremental Instant Radiosity start afresh."""


def may_guide(settings: Settings) -> bool:
    """Whether camera guidance may choose the frame's VPLs (when few light the view)."""
    return settings.vpl_guidance == "camera" and settings.vpl_source == "paths" \
        and not settings.incremental


def has_triangles(kept: KeptProducts) -> bool:
    """Whether the ray tracer holds this frame's triangles already."""
    return kept.has("bvh", _triangles_key(kept))


def _triangles_key(kept: KeptProducts) -> tuple:
    """The BVH's key: the triangle positions' version."""
    return (kept.versions.shape,)


def _cutouts(geometry: WorldGeometry) -> Cutouts | None:
    """The geometry's cutout triangles for the ray tracer, or None without any."""
    triangles, texels = geometry.cutout_rows()
    if len(triangles) == 0:
        return None
    uv = np.zeros((len(triangles), 3, 2), np.float32) if geometry.uv is None else \
        geometry.uv.reshape(-1, 3, 2)[triangles]
    return Cutouts(triangles, uv, texels, geometry.textures)


def upload_triangles(gpu: GpuSession, kept: KeptProducts, geometry: WorldGeometry,
                     stats: Stats) -> RayTracer:
    """The ray tracer with this frame's triangles (its BVH built unless it has them)."""
    tracer = gpu.tracer
    if has_triangles(kept):
        if "ray tracing setup" not in stats.timings:  # not done earlier in this frame
            stats.skipped["ray tracing setup"] = "triangle positions unchanged"
        return tracer
    with stats.timed("ray tracing setup"):
        try:
            tracer.upload(geometry.positions.reshape(-1, 3, 3), instanced=geometry.instanced,
                          clear=geometry.clear_triangles,
                          transmission=geometry.clear_transmission,
                          shadowless=geometry.shadowless, cutouts=_cutouts(geometry),
                          diffuse_hidden=geometry.diffuse_hidden,
                          blocker_set=geometry.blocker_set)
        except ValueError as exc:  # the scene exceeds the GPU's storage-buffer limit
            raise RenderError(f"ray tracing: {exc}") from None
    kept.keep("bvh", _triangles_key(kept))
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
    needs = ("camera", "geometry", "centre", "plan")
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
        guided = may_guide(settings)
        key = (kept.versions.geometry, content_key(scene.lights, scene.world, scene.portals),
               *settings_key(settings, VPL_FIELDS),
               content_key(frame.camera) if guided else None)
        reused = kept.get("vpls", key)
        if reused is not None:
            stats.skipped["vpl generation"] = "lights, world, geometry and settings unchanged"
            stats.skipped["ray tracing setup"] = "no rays to trace: the VPLs are reused"
            return reused
        try:
            tracer = upload_triangles(self.gpu, kept, frame.geometry, stats)
        except GLUnavailableError as exc:  # a frame without its indirect light is wrong
            raise RenderError(str(exc)) from None
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
        elif guided:
            with stats.timed("vpl generation (camera-driven)"):
                vpls = self._guided_vpls(frame, tracer)
        else:
            with stats.timed("vpl generation"):
                vpls = generate_vpls(scene, geometry, settings, tracer, centre, radius,
                                     frame.path_sequence)
        kept.keep("vpls", key, vpls)
        return vpls

    def _guided_vpls(self, frame: FrameState, tracer: RayTracer) -> VPLs:
        """Candidates from guidance_candidates × vpl_count light paths, kept by their
        contribution to camera points, when a probe of DECISION_PATHS paths finds under
        USEFUL_SHARE of its VPLs lighting the view (else the plain light paths). As many VPLs
        are kept as vpl_count paths leave. All the candidates are traced, not only as many as
        the kept count needs (4 × vpl_count paths, more where few light the view, until stop
        48): the rare paths that light the view (Sponza's bay behind the camera) then come
        many times lighter, and Sponza's error over seeds 0-15 fell from 37.2 to 30.7 % (RMS;
        its worst seed 68.8 → 38.4 %) for about 80 ms (docs/measurements.md)."""
        settings, stats, epsilon = frame.settings, frame.stats, 1e-5 * frame.radius

        def candidates(paths: int, stream: int) -> VPLs:  # stream: the candidates' own seed
            stream_settings = replace(settings, vpl_count=paths,
                                      seed=(settings.seed + stream * 7919) % 2**31)
            return generate_vpls(frame.scene, frame.geometry, stream_settings, tracer,
                                 frame.centre, frame.radius)

        points = camera_points(frame.camera, frame.geometry, tracer, GUIDE_POINTS, settings.seed)
        paths = candidate_paths(settings.vpl_count, settings.guidance_candidates)
        probe = candidates(min(DECISION_PATHS, paths), 2)
        share = float(np.mean(contributions(probe, points, tracer, epsilon) > 0)) \
            if len(probe) else 1.0
        if share >= USEFUL_SHARE:
            stats.skipped["vpl guidance"] = (f"{share:.0%} of the light paths' VPLs light the "
                                             "view: selecting among them would add noise")
            return generate_vpls(frame.scene, frame.geometry, settings, tracer, frame.centre,
                                 frame.radius, frame.path_sequence)
        more = camera_points(frame.camera, frame.geometry, tracer, MORE_GUIDE_POINTS,
                             settings.seed + 1)
        traced = candidates(paths, 0)
        contribution = refined_contributions(traced, points, more, tracer, epsilon)
        wanted = len(traced) * settings.vpl_count / paths  # VPLs of vpl_count paths
        guidance = guide(traced, contribution, wanted, settings.seed + 3)
        stats.counts.update(vpl_candidates=guidance.candidates,
                            candidates_in_view_pct=round(100 * guidance.candidate_share),
                            vpls_in_view_pct=round(100 * guidance.kept_share))
        return guidance.vpls

    def _rsm_vpls(self, frame: FrameState, tracer: RayTracer) -> VPLs:
        """VPLs whose first bounce comes from the lights' reflective shadow maps."""
        scene, geometry, settings = frame.scene, frame.geometry, frame.settings
        if np.any(scene.world.radiance > 0) or np.any(geometry.emission > 0):
            frame.stats.warnings.append(
                "reflective shadow maps cover lights only: the world and emissive surfaces "
                "add no indirect light with vpl_source rsm")
        limited = [light.name for light in scene.lights
                   if 0 < light.max_bounces < settings.bounces]
        if limited:
            frame.stats.warnings.append(
                f"reflective shadow maps do not limit a light's bounces: Max Bounces of "
                f"{', '.join(repr(name) for name in limited)} not applied with vpl_source rsm")
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
