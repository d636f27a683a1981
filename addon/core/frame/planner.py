"""Before each frame, decide which work the scene needs and say why the rest is left out.

The planner never changes what a frame shows: every decision leaves out work whose result is
exactly zero (a light that cannot reach any surface the camera sees, a black world, a bounce
count of 0) or is already at hand (the stages the renderer reuses between frames report
themselves). ``Settings.planner = False`` turns every decision off, for comparison (the
``tools/bench_planner.py`` benchmark)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..scene.geometry import WorldGeometry
from ..scene.model import Camera, Scene
from ..settings import Settings
from ..transport.lights import KIND_COSINE, KIND_DIRECTIONAL, NO_SPOT, LightSamples
from .id_passes import family_of
from .result import BACKDROP, INTERNAL_PASSES, MATTE, ON_DEMAND_PASSES, PASS_CHANNELS, aov_of
from .shadow_catcher import has_shadow_catchers

Bounds = tuple[np.ndarray, np.ndarray]  # (lo, hi) corners of an axis-aligned box

PULL_PUSH_MARGIN = 2
"""Pull-push levels beyond the one whose texels are as large as the mean gap between splatted
points: footprints cover most gaps; two more levels fill what they leave (on the Cornell box
the further levels change the image by 0.28 % relative RMSE, against 5.7 % between two seeds:
tools/bench_planner.py)."""


@dataclass
class FramePlan:
    """What one frame runs; ``skipped`` names each stage left out, with the reason."""

    indirect: bool = True
    sample_dark: bool = False  # sample zero-power lights and a black world anyway
    cull_to_view: bool = True  # leave out light samples and VPLs the camera cannot see lit
    passes: frozenset[str] = frozenset(PASS_CHANNELS)
    borrowed: frozenset[str] = frozenset()  # passes only the frame's own stages read (depth
    # of field's and motion blur's): dropped before the frame is returned (DropBorrowed)
    skipped: dict[str, str] = field(default_factory=dict)


def no_indirect_reason(scene: Scene, geometry: WorldGeometry, settings: Settings) -> str:
    """Why the scene needs no indirect light, or '' when it does."""
    if settings.bounces == 0:
        return "bounces = 0"
    if geometry.vertex_count == 0:
        return "no surfaces"
    if not settings.planner:
        return ""
    if not np.any(geometry.albedo > 0):
        return "every albedo is 0"
    lit = any(light.power != 0 and any(c != 0 for c in light.color)
              for light in scene.surface_lights)
    if not lit and not np.any(scene.world.radiance > 0) and not np.any(geometry.emission > 0):
        return "nothing emits light"
    return ""


def needed_pull_push_levels(settings: Settings) -> int:
    """Pull-push levels the ISM point density needs: holes between splats of ``ism_points``
    points spread over a hemisphere map of ``ism_resolution``² texels are about
    resolution / sqrt(points / 2) texels wide; levels beyond that, plus a margin, only spread
    coarse depths into directions where nothing was seen."""
    gap = settings.ism_resolution / math.sqrt(settings.ism_points / 2)
    needed = max(0, math.ceil(math.log2(max(gap, 1.0)))) + PULL_PUSH_MARGIN
    return min(settings.pull_push_levels, needed)


def plan_gather(plan: FramePlan, settings: Settings, uses_ism: bool
                ) -> tuple[int, dict[str, str]]:
    """For the frame's final VPL settings (after any automatic choice): the pull-push levels
    its imperfect shadow maps need (``uses_ism``: the visibility mode renders them), and the
    skipped entries for the other levels and the blur."""
    if not settings.planner or not plan.indirect:
        return settings.pull_push_levels, {}
    skipped = {"blur": "interleaving off"} if settings.interleave == 1 else {}
    if not uses_ism and not settings.soft_light_ism:
        return settings.pull_push_levels, skipped
    levels = needed_pull_push_levels(settings)
    if levels < settings.pull_push_levels:
        skipped[f"pull-push levels {levels + 1}–{settings.pull_push_levels}"] = (
            f"{settings.ism_points} points fill {settings.ism_resolution}² maps by level "
            f"{levels}")
    return levels, skipped


def plan_frame(scene: Scene, geometry: WorldGeometry, settings: Settings,
               passes: frozenset[str] | None = None) -> FramePlan:
    """The stages this frame needs, from the scene, the settings and the requested passes."""
    every = frozenset(PASS_CHANNELS) - ON_DEMAND_PASSES
    if passes is None:
        wanted = every
    elif not settings.planner:  # every pass, and those on demand (and AOVs) where asked for
        wanted = every | (frozenset(passes) & ON_DEMAND_PASSES) \
            | frozenset(p for p in passes if aov_of(p) is not None)
    else:
        wanted = frozenset(passes) | {"Combined"}
    read: set[str] = set()
    if scene.camera is not None and scene.camera.defocused:
        read |= {"Depth"}  # depth of field blurs by it (depth_of_field.py)
    if scene.motion is not None and scene.motion.blur:
        read |= {"Depth", "Vector"}  # motion blur smears by them (motion_blur.py)
    if has_shadow_catchers(scene):  # their compositing's (shadow_catcher.py)
        read |= {MATTE} if scene.film_transparent else {MATTE, BACKDROP}
    asked = wanted if passes is None else frozenset(passes)
    plan = FramePlan(passes=wanted | read,
                     borrowed=frozenset(read - asked - set(INTERNAL_PASSES)))
    reason = no_indirect_reason(scene, geometry, settings)  # off: bounces = 0, no surfaces
    if reason:
        plan.indirect = False
        plan.skipped["indirect light"] = reason
    if not settings.planner:
        plan.sample_dark, plan.cull_to_view = True, False
        return plan
    for light in scene.lights:
        if not light.visible_to_diffuse:
            plan.skipped[f"light '{light.name}'"] = "not visible to diffuse rays"
        elif light.power == 0 or not any(c != 0 for c in light.color):
            plan.skipped[f"light '{light.name}'"] = "zero power"
    if not np.any(scene.world.radiance > 0):
        plan.skipped["world light"] = "black world"
    if not np.any(geometry.emission > 0):
        plan.skipped["emission light"] = "no emissive surface"
    if not geometry.has_textures:
        plan.skipped["texture lookups"] = "no material has an image texture"
    if plan.indirect and settings.bias_compensation == "off":
        plan.skipped["bias compensation"] = "off"
    elif plan.indirect and settings.clamp_distance == 0:
        plan.skipped["bias compensation"] = "no distance clamp"
    unused = sorted({family_of(name) or name for name in set(PASS_CHANNELS) - wanted})
    if unused:
        plan.skipped["passes " + ", ".join(unused)] = "not enabled in the view layer"
    return plan


def visible_bounds(camera: Camera, box: Bounds | None) -> Bounds | None:
    """A box holding every surface point the camera can see: the scene's bounding box ``box``
    (None without triangles) cut by the box around the camera's view frustum. None when the
    two do not overlap."""
    if box is None:
        return None
    lo, hi = box[0].astype(np.float64), box[1].astype(np.float64)
    clip_to_world = np.linalg.inv(camera.projection_matrix @ camera.view_matrix)
    corners = np.array([[x, y, z, 1.0] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    world = corners @ clip_to_world.T
    if np.all(world[:, 3] > 0) and np.isfinite(world).all():
        frustum = world[:, :3] / world[:, 3:]
        lo, hi = np.maximum(lo, frustum.min(axis=0)), np.minimum(hi, frustum.max(axis=0))
    if np.any(lo > hi):
        return None
    return lo, hi


def reaches_bounds(samples: LightSamples, bounds: Bounds | None) -> np.ndarray:
    """Per sample, whether its light can fall on some point of ``bounds`` (conservative: a
    False is certain). One-sided emitters (area-light samples, VPLs) and spots of cones up
    to 180° light only the side their axis faces; spot cones light only inside their outer
    edge (tested against the box's bounding sphere)."""
    n = len(samples)
    if bounds is None:
        return np.zeros(n, bool)
    lo, hi = bounds
    reach = np.any(samples.intensity > 0, axis=1)
    if samples.glossy is not None:
        reach |= samples.glossy[:, 0, 3] > 0
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])
    spot = (samples.spot_cos > NO_SPOT) & (samples.kind != KIND_DIRECTIONAL)
    one_sided = (samples.kind == KIND_COSINE) | (spot & (samples.spot_cos >= 0))
    if one_sided.any():
        offsets = corners[None] - samples.position[one_sided, None]
        ahead = np.einsum("nkc,nc->nk", offsets, samples.axis[one_sided])
        reach[one_sided] &= ahead.max(axis=1) > 0
    if spot.any():
        centre, radius = 0.5 * (lo + hi), 0.5 * float(np.linalg.norm(hi - lo))
        to_centre = centre - samples.position[spot]
        distance = np.linalg.norm(to_centre, axis=1)
        outside = distance > radius
        cos_angle = np.einsum("nc,nc->n", to_centre, samples.axis[spot]) / np.maximum(
            distance, 1e-30)
        angle = np.arccos(np.clip(cos_angle, -1.0, 1.0))
        spread = np.arcsin(np.clip(radius / np.maximum(distance, 1e-30), 0.0, 1.0))
        cone = np.arccos(np.clip(samples.spot_cos[spot], -1.0, 1.0))
        reach[spot] &= ~outside | (angle - spread < cone)
    return reach
