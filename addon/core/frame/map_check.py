"""A check of imperfect shadow maps against rays, made per frame where the maps may fail.

Each imperfect shadow map holds a fixed number of surface points (``ism_points``); where a
scene has more triangles than that, thin occluders between a VPL and what the camera sees
(pillars, arches, a wall's edge) can get too few points to stop its light, and the maps let
through light that rays find blocked. On the Sibenik cathedral (75k triangles, lit through
its windows) the maps let through 2.7 times the one-bounce light of ray-traced visibility.
The check draws (VPL, camera point) pairs by their unshadowed light, renders the maps of
the VPLs drawn, and compares the light the maps let through with what rays
let through, summed over the same pairs: their ratio estimates the maps' error in the
frame's indirect light. Outside [1 / (1 + limit), 1 + limit] the frame traces its VPLs'
visibility instead (stages.PlanLightPasses)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..scene.textures import LUMINANCE
from ..transport.guidance import CameraPoints, camera_points
from ..transport.lights import KIND_DIRECTIONAL, LightSamples
from ..transport.ray_caster import RayCaster
from .gpu_session import GpuSession
from .ism_maps import prepare_points, pull_push_levels
from .progressive import maps_undersample
from .reuse import KeptProducts
from .state import FrameState
from .vpl_stage import upload_triangles

CHECK_VPLS = 128
"""VPL draws (by their unshadowed light on the camera points) whose maps the check renders."""
CHECK_POINTS = 512
"""Camera rays whose first hits the pairs are drawn with."""
PAIRS_PER_VPL = 32
"""Points drawn per VPL drawn, by its unshadowed light on each."""
CHUNK_VPLS = 256
"""VPLs whose light on every camera point is summed at a time."""
MIN_LIT_PAIRS = 32
"""Pairs that the maps or the rays must find lit for the check to judge (fewer: no
verdict; the ratio's relative noise is then below about one over its square root)."""


@dataclass(frozen=True)
class MapCheck:
    """What rays let through of the unshadowed light of ``pairs`` drawn pairs
    (``ray_share``), and the light the maps let through over the rays' (``ratio``; None where
    it was not measured: the rays' share alone keeps it within the limit)."""

    pairs: int
    ray_share: float
    ratio: float | None = None

    def off_by_more_than(self, limit: float) -> bool:
        """Whether the maps' light is off from the rays' by more than the share ``limit``
        (either way)."""
        return self.ratio is not None and limit > 0 \
            and not 1.0 / (1.0 + limit) <= self.ratio <= 1.0 + limit


def unshadowed_pair_light(vpls: LightSamples, points: CameraPoints,
                          min_distance: float) -> np.ndarray:
    """The light (luminance) each VPL sends to each point without shadows, (n, s): intensity
    × both cosines / distance² (clamped below ``min_distance``) × the point's albedo."""
    offset = points.position[None, :, :] - vpls.position[:, None, :]
    squared = np.maximum((offset * offset).sum(axis=2), 1e-30)
    inverse = 1.0 / np.sqrt(squared)
    leaving = np.maximum(np.einsum("nsc,nc->ns", offset, vpls.axis) * inverse, 0.0)
    arriving = np.maximum(-np.einsum("nsc,sc->ns", offset, points.normal) * inverse, 0.0)
    weight = vpls.intensity @ LUMINANCE
    return (weight[:, None] * leaving * arriving / np.maximum(squared, min_distance**2)
            * (points.albedo @ LUMINANCE)[None, :])


def ray_visibility(tracer: RayCaster, start: np.ndarray, normal: np.ndarray,
                   end: np.ndarray, epsilon: float) -> np.ndarray:
    """What rays from VPLs at ``start`` (offset along ``normal``) to points ``end`` let
    through (m,): the clear surfaces' mean transmittance, 0 where a surface blocks."""
    origin = start + normal * epsilon
    towards = end - origin
    distance = np.linalg.norm(towards, axis=1)
    towards /= np.maximum(distance, 1e-30)[:, None]
    hits = tracer.intersect(origin, towards, 0.0, distance * (1 - 1e-4) - epsilon, diffuse=True)
    return np.where(hits.triangle >= 0, 0.0, hits.transmittance.mean(axis=1))


MapsVisibility = Callable[[LightSamples, np.ndarray, np.ndarray, np.ndarray], np.ndarray]
"""Renders the maps of VPLs (LightSamples) and reads them: what they let through from VPL
``vpl[q]`` to point ``world[q]`` of geometric normal ``normal[q]`` (Q,)."""


def check_maps(vpls: LightSamples, points: CameraPoints, tracer: RayCaster, epsilon: float,
               min_distance: float, limit: float, seed: int, maps_visibility: MapsVisibility
               ) -> MapCheck | None:
    """Compare the maps of ``vpls`` (read by ``maps_visibility``) with rays at pairs with
    ``points`` drawn by their unshadowed light: CHECK_VPLS VPLs by their light on all the
    points, then PAIRS_PER_VPL points by each one's light on it, so that the pairs follow the
    light of all pairs with the maps of few VPLs. Where rays let through more than
    1 / (1 + ``limit``) of it, no map can let through more than that much over the rays and
    the maps are not rendered. None where too few pairs are lit."""
    rng = np.random.default_rng(seed)
    totals = np.concatenate([
        unshadowed_pair_light(vpls.subset(np.arange(start, min(start + CHUNK_VPLS, len(vpls)))),
                              points, min_distance).sum(axis=1)
        for start in range(0, len(vpls), CHUNK_VPLS)])
    total = totals.sum()
    if not np.isfinite(total) or total <= 0:
        return None
    chosen, drawn = np.unique(rng.choice(len(vpls), CHECK_VPLS, p=totals / total),
                              return_inverse=True)
    subset = vpls.subset(chosen)
    light = unshadowed_pair_light(subset, points, min_distance)
    vpl = np.repeat(drawn, PAIRS_PER_VPL)
    point = np.concatenate([rng.choice(len(points), PAIRS_PER_VPL, p=light[k] / light[k].sum())
                            for k in drawn])
    by_rays = ray_visibility(tracer, subset.position[vpl], subset.axis[vpl],
                             points.position[point], epsilon)
    lit_by_rays = float(by_rays.sum())
    if lit_by_rays * (1.0 + limit) >= len(vpl):
        return MapCheck(len(vpl), lit_by_rays / len(vpl))
    lit_by_maps = float(maps_visibility(subset, vpl, points.position[point],
                                        points.normal[point]).sum())
    if max(lit_by_maps, lit_by_rays) < MIN_LIT_PAIRS:
        return None
    return MapCheck(len(vpl), lit_by_rays / len(vpl), lit_by_maps / max(lit_by_rays, 1.0))


def frame_traces_vpls(frame: FrameState, gpu: GpuSession, kept: KeptProducts,
                      min_distance: float) -> bool:
    """Whether a frame set to read imperfect shadow maps should trace its VPLs' visibility:
    where the maps undersample its triangles (progressive.maps_undersample) and ``check_maps``
    finds them off by more than ``map_error_limit`` (VPL distances clamped below
    ``min_distance``, as the gather clamps them); not with VPL reuse (the viewport keeps its
    maps between frames) and not below OpenGL 4.3. The verdict goes into the stats."""
    settings, stats, geometry = frame.settings, frame.stats, frame.geometry
    limit = settings.map_error_limit
    if limit <= 0 or settings.incremental or frame.vpl_samples is None \
            or len(frame.vpl_samples) == 0 or gpu.ctx.version_code < 430 \
            or not maps_undersample(settings, geometry.vertex_count // 3):
        return False
    sphere = (frame.centre, frame.radius)

    def maps_visibility(subset: LightSamples, vpl: np.ndarray, world: np.ndarray,
                        normal: np.ndarray) -> np.ndarray:
        ism = gpu.ism
        prepare_points(ism, kept, geometry, settings, frame.user_seed, stats)
        kept.ism_atlas.forget()  # these maps overwrite the atlas a frame may keep
        ism.render(geometry.positions.reshape(-1, 3, 3), subset.position, subset.axis,
                   settings.ism_resolution, pull_push_levels(settings),
                   subset.kind == KIND_DIRECTIONAL, sphere)
        return ism.visibility(vpl, world, normal)

    with stats.timed("map check"):
        tracer = upload_triangles(gpu, kept, geometry, stats)
        points = camera_points(frame.camera, geometry, tracer, CHECK_POINTS, settings.seed + 5)
        check = check_maps(frame.vpl_samples, points, tracer, 1e-5 * frame.radius,
                           min_distance, limit, settings.seed, maps_visibility)
    if check is None:
        stats.skipped["map check's verdict"] = "too few pairs of VPLs and camera points lit"
        return False
    if check.ratio is None:
        stats.skipped["map check's maps"] = (
            f"rays let through {check.ray_share:.0%} of the pairs' unshadowed light: maps "
            f"cannot exceed it by more than map_error_limit {limit:g}")
        return False
    stats.counts["map_light_vs_rays_pct"] = round(100 * check.ratio)
    if not check.off_by_more_than(limit):
        return False
    stats.skipped["imperfect shadow maps"] = (
        f"they let through {check.ratio:.2f}× the light rays do at {check.pairs} pairs of "
        f"VPLs and camera points (map_error_limit {limit:g}): VPL visibility ray traced")
    return True
