"""Shadow catchers (Object Properties > Visibility > Mask > Shadow Catcher) composited as
Cycles does (its film/read.h): the catcher's light with the other objects over its light
without them is the Shadow Catcher pass, and the rest of the image is the matte.

A frame of a scene with catchers renders twice: the scene itself, whose compose also writes
MATTE (Combined with the catchers' supersamples as holes) and, with an opaque film, BACKDROP
(the background each pixel sees); and the catchers alone (every other object left out, as
Cycles' split path ignores them), which writes the same. Per pixel, a render's catcher light
is Combined − MATTE over the catchers' coverage (the alphas' difference), and the ratio of the
two renders' is the Shadow Catcher pass (1 where no catcher is). Combined becomes:

- with the Shadow Catcher pass asked for, the matte (Cycles: catchers are holes);
- else Cycles' approximation: the matte over the shadow, alpha 1 − mean(ratio) on the
  catchers (transparent film), or the backdrop dimmed by it (opaque film)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..scene.geometry import WorldGeometry, transform_points
from ..scene.model import Scene
from .result import BACKDROP, MATTE

SHADOW_CATCHER_PASS = "Shadow Catcher"
MIN_COVERAGE = 1e-4  # a pixel's catcher coverage below this has no catcher light to divide
PLANE_TOLERANCE = 1e-5  # of the points' extent: float32 rounding of flat geometry
PLANE_PROBE = 1024  # points tested first, spread over the list (most meshes fail there)


def has_shadow_catchers(scene: Scene) -> bool:
    """Whether some instance is a shadow catcher."""
    return any(inst.shadow_catcher for inst in scene.instances)


def catcher_triangles(scene: Scene, geometry: WorldGeometry) -> np.ndarray | None:
    """Per triangle of ``geometry`` (flattened from ``scene``): whether it is a catcher's
    (T,) bool; None where none is."""
    owners = geometry.triangle_instance
    if owners is None or not has_shadow_catchers(scene):
        return None
    flags = np.array([inst.shadow_catcher for inst in scene.instances], bool)
    return flags[owners] if len(owners) else np.zeros(0, bool)


def catchers_alone(scene: Scene) -> Scene:
    """The scene with only its shadow catchers (its lights and world kept)."""
    return replace(scene, instances=[i for i in scene.instances if i.shadow_catcher],
                   warnings=[])


def in_one_plane(points: np.ndarray) -> bool:
    """Whether the points (V, 3) all lie in one plane, to PLANE_TOLERANCE of their extent
    (PLANE_PROBE of them tested first); False for fewer than 3 or no extent."""
    if len(points) < 3:
        return False
    step = max(1, len(points) // PLANE_PROBE)
    for chosen in (points[::step], points):
        offsets = chosen.astype(np.float64) - chosen.mean(axis=0, dtype=np.float64)
        extent = float(np.abs(offsets).max())
        if not 0.0 < extent < np.inf:
            return False
        normal = np.linalg.svd(offsets.T @ offsets)[2][-1]  # the direction of least spread
        if np.abs(offsets @ normal).max() > PLANE_TOLERANCE * extent:
            return False
    return True


def alone_bounces(scene: Scene, bounces: int) -> int:
    """The bounces the catchers-alone render needs: none where they all lie in one plane (a
    ground plane, the usual catcher, cannot light itself), else ``bounces``."""
    points = [transform_points(i.matrix, i.mesh.positions) for i in scene.instances
              if i.shadow_catcher]
    return 0 if points and in_one_plane(np.concatenate(points)) else bounces


def _catcher_light(passes: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """A render's catcher light per unit of coverage (h, w, 3) and its coverage (h, w, 1)."""
    combined, matte = passes["Combined"], passes[MATTE]
    coverage = np.clip(combined[..., 3:4] - matte[..., 3:4], 0.0, 1.0)
    light = (combined[..., :3] - matte[..., :3]) / np.maximum(coverage, MIN_COVERAGE)
    return light, coverage


def shadow_ratio(full: dict[str, np.ndarray], alone: dict[str, np.ndarray]) -> np.ndarray:
    """Per pixel and colour, the catchers' light with the other objects over their light
    without them (h, w, 3); 1 where no catcher is seen or it gets no light alone (Cycles'
    safe_divide_shadow_catcher)."""
    return _ratio(_catcher_light(full), _catcher_light(alone))


def _ratio(full: tuple[np.ndarray, np.ndarray], alone: tuple[np.ndarray, np.ndarray]
           ) -> np.ndarray:
    """shadow_ratio of the two renders' (catcher light, coverage)."""
    (lit, coverage), (unshadowed, alone_coverage) = full, alone
    valid = (coverage >= MIN_COVERAGE) & (alone_coverage >= MIN_COVERAGE) & (unshadowed != 0)
    with np.errstate(over="ignore"):
        ratio = np.where(valid, lit / np.where(valid, unshadowed, 1.0), 1.0)
    return np.where(np.isfinite(ratio), np.maximum(ratio, 0.0), 1.0).astype(np.float32)


def composite(full: dict[str, np.ndarray], alone: dict[str, np.ndarray],
              transparent: bool, as_matte: bool) -> None:
    """Turn ``full`` (the scene's render, with MATTE and, opaque, BACKDROP) into Cycles' output
    with shadow catchers, given ``alone`` (the catchers-alone render): its Combined (see the
    module) and, where present, its Shadow Catcher pass; the hidden passes are dropped.
    ``as_matte``: the Shadow Catcher pass was asked for (Combined is the matte)."""
    caught = _catcher_light(full)
    ratio, coverage = _ratio(caught, _catcher_light(alone)), caught[1]
    combined, matte = full["Combined"], full.pop(MATTE)
    backdrop = full.pop(BACKDROP, None)
    if SHADOW_CATCHER_PASS in full:
        alpha = np.clip(combined[..., 3:4], 0.0, 1.0)  # alpha-over on white, as Cycles
        full[SHADOW_CATCHER_PASS] = ((1.0 - alpha) + alpha * ratio).astype(np.float32)
    if as_matte:
        full["Combined"] = matte
        return
    shadow = np.clip(ratio.mean(axis=-1, keepdims=True), 0.0, 1.0)
    if transparent or backdrop is None:
        alpha = np.clip(matte[..., 3:4], 0.0, 1.0)
        full["Combined"] = np.concatenate(
            [matte[..., :3], alpha + (1.0 - alpha) * (1.0 - shadow)], axis=-1).astype(np.float32)
    else:
        rgb = matte[..., :3] + backdrop * coverage * shadow
        full["Combined"] = np.concatenate([rgb, np.ones_like(shadow)], axis=-1).astype(np.float32)
