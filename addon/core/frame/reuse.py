"""What frames reuse from earlier frames, in one owner.

Each kept product (the VPLs, the ray tracer's BVH, the ISM atlas, shadow atlases) is keyed by
the settings fields its stage declares and the scene versions it reads, so that a setting a
stage reads cannot be left out of its key by hand."""

from __future__ import annotations

import pickle
from collections.abc import Iterable

import numpy as np

from ..scene.geometry import WorldGeometry
from ..scene.textures import mode_code
from ..settings import Settings
from ..transport.incremental import IncrementalVPLs
from .ism_reuse import ReusedISMAtlas


def settings_key(settings: Settings, fields: Iterable[str]) -> tuple:
    """The values of ``fields`` of ``settings``, for a product's key."""
    return tuple(getattr(settings, name) for name in fields)


def content_key(*parts: object) -> bytes:
    """Scene data (lights, the world, the camera) as comparable bytes, for a product's key."""
    return pickle.dumps(parts)


def _texture_state(geometry: WorldGeometry) -> tuple[np.ndarray, ...]:
    """What VPLs read from textures: UVs, texture attributes, sampling modes and pixels (none
    untextured)."""
    if not geometry.has_textures:
        return ()
    modes = np.array([mode_code(t) for t in geometry.textures])
    return geometry.uv, geometry.texture, modes, *(t.pixels for t in geometry.textures)


class SceneVersions:
    """Versions of the frame's geometry: ``shape`` changes when triangle positions, clear
    triangles, the triangles that cast no shadow or diffuse bounces pass, or cutouts do (the
    BVH and shadow maps read them), ``geometry`` when those, materials, textures or light
    linking's sets do (VPLs read all)."""

    def __init__(self) -> None:
        self.shape = 0
        self.geometry = 0
        self._arrays: tuple[np.ndarray, ...] = ()
        self._shape_length = 0

    def note(self, geometry: WorldGeometry) -> None:
        """Compare this frame's geometry with the last one's and bump the versions."""
        blockers = np.zeros(0) if geometry.blocker_set is None else geometry.blocker_set
        shape = (geometry.positions, geometry.clear_triangles, geometry.clear_transmission,
                 geometry.shadowless, geometry.diffuse_hidden, *geometry.cutout_state(),
                 blockers)
        linking = tuple(np.zeros(0) if a is None else a
                        for a in (geometry.receiver_set, geometry.emission_receivers,
                                  geometry.emission_blockers))
        arrays = (*shape, geometry.albedo, geometry.emission, geometry.materials,
                  geometry.triangle_material, *_texture_state(geometry), *linking)
        before = self._arrays
        same = [k < len(before) and a.shape == before[k].shape and np.array_equal(a, before[k])
                for k, a in enumerate(arrays)]
        if not all(same[:len(shape)]) or len(shape) != self._shape_length:
            self._shape_length = len(shape)
            self.shape += 1
        if not all(same) or len(before) != len(arrays):
            self._arrays = tuple(a.copy() for a in arrays)
            self.geometry += 1

    def forget(self) -> None:
        """Treat the next frame's geometry as new."""
        self._arrays = ()


class KeptProducts:
    """Products kept from earlier frames, and the scene versions their keys use."""

    def __init__(self) -> None:
        self.versions = SceneVersions()
        self.incremental = IncrementalVPLs()
        """Incremental Instant Radiosity's anchors (kept by ``forget(anchors=False)``)."""
        self.ism_atlas = ReusedISMAtlas()
        self.shadow_atlases: dict[tuple, list] = {}
        """GPU objects of the last frame's shadow atlases, by their key (see shadow_maps)."""
        self._products: dict[str, tuple[tuple, object]] = {}

    def get(self, name: str, key: tuple) -> object | None:
        """The product kept under ``name`` if it was made for ``key``, else None."""
        kept = self._products.get(name)
        return kept[1] if kept is not None and kept[0] == key else None

    def has(self, name: str, key: tuple) -> bool:
        kept = self._products.get(name)
        return kept is not None and kept[0] == key

    def keep(self, name: str, key: tuple, product: object = True) -> None:
        self._products[name] = (key, product)

    def latest(self, name: str) -> object | None:
        """The product last kept under ``name``, whatever its key."""
        kept = self._products.get(name)
        return kept[1] if kept is not None else None

    def keep_shadow_atlases(self, used: dict[tuple, list]) -> None:
        """Keep the shadow atlases a frame used; release the others."""
        for key, objects in self.shadow_atlases.items():
            if key not in used:
                for obj in objects:
                    obj.release()
        self.shadow_atlases = used

    def forget(self, anchors: bool = True) -> None:
        """Drop every kept product; with ``anchors``, Incremental Instant Radiosity's anchors
        and the last frame's geometry too (the next frame starts afresh)."""
        self._products.clear()
        self.ism_atlas.forget()
        self.keep_shadow_atlases({})
        if anchors:
            self.incremental = IncrementalVPLs()
            self.versions.forget()
