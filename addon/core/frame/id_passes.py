"""The ID passes compositing keys on: Object and Material Index, and Cryptomatte's object,
material and asset layers, from the triangle each supersample sees (the g-buffer's
geometric.w holds its index + 1).

Cryptomatte as Blender and Cycles write it: each name's MurmurHash3 (seed 0) as a float
(its exponent kept off 0 and 255), and per pixel the ids of the most covering names with
their share of the pixel, largest first, two (id, coverage) pairs to a pass
(CryptoObject00, 01, ...); the manifest and layer names go into the render result's
metadata (``metadata``)."""

from __future__ import annotations

import json
import struct
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING

import numpy as np

from ..scene.geometry import WorldGeometry
from ..scene.model import DEFAULT_MATERIAL, Material, Scene
from .compose import central
from .result import AOV_COLOR, aov_of

if TYPE_CHECKING:  # image.py runs IdPasses among its tile stages
    from .image import FrameGpu, TileWork
    from .state import FrameState

INDEX_PASSES = ("IndexOB", "IndexMA")
CRYPTO_FAMILIES = ("CryptoObject", "CryptoMaterial", "CryptoAsset")
CYCLES_DEFAULT_SURFACE = "default_surface"  # Cycles' name for an empty slot's material
MAX_TRIANGLES = 2 ** 24 - 1  # triangle index + 1 is exact in the g-buffer's float32


def murmur3_32(data: bytes, seed: int = 0) -> int:
    """MurmurHash3's x86 32-bit hash of ``data`` (Cryptomatte's name hash)."""
    c1, c2, mask = 0xCC9E2D51, 0x1B873593, 0xFFFFFFFF
    h = seed & mask
    whole = len(data) // 4 * 4
    for (k,) in struct.iter_unpack("<I", data[:whole]):
        k = (k * c1) & mask
        k = ((k << 15) | (k >> 17)) & mask
        h ^= (k * c2) & mask
        h = ((h << 13) | (h >> 19)) & mask
        h = (h * 5 + 0xE6546B64) & mask
    tail = data[whole:]
    if tail:
        k = int.from_bytes(tail, "little")
        k = (k * c1) & mask
        k = ((k << 15) | (k >> 17)) & mask
        h ^= (k * c2) & mask
    h ^= len(data)
    h ^= h >> 16
    h = (h * 0x85EBCA6B) & mask
    h ^= h >> 13
    h = (h * 0xC2B2AE35) & mask
    return h ^ (h >> 16)


def name_hash(name: str) -> int:
    """A name's Cryptomatte hash (of its UTF-8 bytes)."""
    return murmur3_32(name.encode("utf-8"))


def hash_to_float(value: int) -> float:
    """The hash as Cryptomatte stores it in a float pass: its bits, with the exponent clamped
    to [1, 254] (never 0, a denormal, Inf or NaN)."""
    exponent = min(max((value >> 23) & 0xFF, 1), 254)
    bits = (value & 0x807FFFFF) | (exponent << 23)
    return float(np.array(bits, np.uint32).view(np.float32))


def crypto_pass_names(family: str, levels: int) -> list[str]:
    """The passes of a Cryptomatte ``family`` (CRYPTO_FAMILIES) of ``levels`` ranks, as
    Blender registers them: two ranks each, ``family`` + 00, 01, ..."""
    return [f"{family}{k:02d}" for k in range((max(levels, 1) + 1) // 2)]


def family_of(name: str) -> str | None:
    """The Cryptomatte family a pass name belongs to, or None."""
    for family in CRYPTO_FAMILIES:
        if name.startswith(family) and name[len(family):].isdigit():
            return family
    return None


def family_passes(passes: Mapping[str, np.ndarray] | frozenset[str], family: str) -> list[str]:
    """The family's pass names among ``passes``, in order."""
    return sorted(name for name in passes if family_of(name) == family)


def _material_name(material: Material) -> str:
    return CYCLES_DEFAULT_SURFACE if material.name == DEFAULT_MATERIAL.name else material.name


def cryptomatte_names(scene: Scene, geometry: WorldGeometry, family: str) -> list[str]:
    """Per instance (CryptoObject, CryptoAsset) or per material row (CryptoMaterial): the name
    the family keys on ("" for none)."""
    if family == "CryptoMaterial":
        return [_material_name(m) for m in geometry.row_materials]
    if family == "CryptoAsset":
        return [inst.identity.asset for inst in scene.instances]
    return [inst.identity.name for inst in scene.instances]


def scene_names(scene: Scene, family: str) -> set[str]:
    """Every name of ``family`` in the scene (its manifest's)."""
    if family == "CryptoMaterial":
        return {_material_name(m) for inst in scene.instances
                for m in inst.materials or [DEFAULT_MATERIAL]}
    return {inst.identity.asset if family == "CryptoAsset" else inst.identity.name
            for inst in scene.instances} - {""}


def _float_ids(names: list[str]) -> np.ndarray:
    """Each name's float id (0 for "": no id)."""
    found: dict[str, float] = {}
    for name in dict.fromkeys(names):
        found[name] = hash_to_float(name_hash(name)) if name else 0.0
    return np.array([found[n] for n in names] or [0.0], np.float32)


class IdTables:
    """The frame's lookups from a triangle to the ID passes' values."""

    def __init__(self, scene: Scene, geometry: WorldGeometry) -> None:
        self.scene, self.geometry = scene, geometry
        self._per_triangle: dict[str, np.ndarray] = {}

    def triangles(self, geometric: np.ndarray) -> np.ndarray:
        """Each supersample's triangle + 1 (int32; 0 where none: the background, a holdout,
        a light's shape), from the g-buffer's geometric layer (h, w, 4)."""
        code = np.maximum(geometric[..., 3], 0.0).astype(np.int32)
        return np.minimum(code, self.geometry.triangle_count, out=code)

    def values(self, kind: str, triangles: np.ndarray) -> np.ndarray:
        """At ``triangles`` (``triangles``' codes), the pass index (IndexOB, IndexMA) or the
        Cryptomatte float id (a family of CRYPTO_FAMILIES); 0 where none, float32."""
        if kind not in self._per_triangle:
            self._per_triangle[kind] = self._lookup(kind)
        return np.take(self._per_triangle[kind], triangles)

    def aov(self, name: str, triangles: np.ndarray) -> np.ndarray:
        """At ``triangles`` (``triangles``' codes), the Shader AOV ``name``'s colour, value
        and 1 (..., 5) float32 where each one's material writes it; 0 where none does."""
        key = AOV_COLOR + name
        if key not in self._per_triangle:
            rows = [(*dict(m.aovs)[name], 1.0) if name in dict(m.aovs) else (0.0,) * 5
                    for m in self.geometry.row_materials] or [(0.0,) * 5]
            owners = self._owners(self.geometry.triangle_material)
            table = np.take(np.asarray(rows, np.float32), owners, axis=0, mode="clip")
            self._per_triangle[key] = np.concatenate([np.zeros((1, 5), np.float32), table])
        return np.take(self._per_triangle[key], triangles, axis=0)

    def _owners(self, owners: np.ndarray | None) -> np.ndarray:
        """Each triangle's owner (its material row or instance), 0 for all where the
        geometry has none per triangle (light shapes)."""
        if owners is None or len(owners) != self.geometry.triangle_count:
            return np.zeros(self.geometry.triangle_count, np.int32)
        return owners

    def _lookup(self, kind: str) -> np.ndarray:
        """The kind's value per triangle code (entry 0: none)."""
        geometry = self.geometry
        owners = self._owners(geometry.triangle_material if kind in ("IndexMA", "CryptoMaterial")
                              else geometry.triangle_instance)
        if kind == "IndexOB":
            table = np.array([i.identity.pass_index for i in self.scene.instances] or [0],
                             np.float32)
        elif kind == "IndexMA":
            table = np.array([m.pass_index for m in geometry.row_materials] or [0],
                             np.float32)
        else:
            table = _float_ids(cryptomatte_names(self.scene, geometry, kind))
        return np.concatenate([[0.0], np.take(table, owners, mode="clip")]).astype(np.float32)


def merge_ranks(ids: np.ndarray, weights: np.ndarray, levels: int
                ) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel, the ``levels`` ids of largest total weight among (h, w, n) ``ids`` (0: no
    id) and their weights, summed over equal ids, largest first; (h, w, levels) each. Pixels
    of one id (most, inside objects) are ranked without sorting."""
    uniform = ids.max(axis=-1) == ids.min(axis=-1)
    return _ranks(ids[..., 0], uniform, weights.sum(axis=-1),
                  lambda mixed: (ids[mixed], weights[mixed]), levels)


def supersample_ranks(ids: np.ndarray, aa: int, levels: int
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The ranks (``merge_ranks``) of each pixel's aa × aa supersample ids (h·aa, w·aa), each
    supersample weighing 1 / aa²; pixels whose supersamples agree (most) are compared as
    whole strided images, without gathering their supersamples."""
    views = [ids[i::aa, j::aa] for i in range(aa) for j in range(aa)]
    lead = views[0]
    uniform = np.ones(lead.shape, bool)
    for view in views[1:]:
        uniform &= view == lead

    def gathered(mixed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        blocks = np.stack([view[mixed] for view in views], axis=-1)
        return blocks, np.full(blocks.shape, 1.0 / (aa * aa), np.float32)

    return _ranks(lead, uniform, np.float32(1.0), gathered, levels)


def _ranks(lead: np.ndarray, uniform: np.ndarray, lead_weight: np.ndarray | np.float32,
           gather: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]], levels: int
           ) -> tuple[np.ndarray, np.ndarray]:
    """Ranks (h, w, levels) of ids and weights: where ``uniform``, the pixel's one id
    ``lead`` (none where 0) of ``lead_weight``; elsewhere the sorted ranks of the pixels'
    (m, n) ids and weights ``gather`` returns for that mask."""
    out_ids = np.zeros((*lead.shape, levels), np.float32)
    out_weights = np.zeros((*lead.shape, levels), np.float32)
    out_ids[..., 0] = np.where(uniform, lead, 0.0)
    out_weights[..., 0] = np.where(uniform & (lead != 0), lead_weight, 0.0)
    mixed = ~uniform
    if mixed.any():
        out_ids[mixed], out_weights[mixed] = _sorted_ranks(*gather(mixed), levels)
    return out_ids, out_weights


def _sorted_ranks(ids: np.ndarray, weights: np.ndarray, levels: int
                  ) -> tuple[np.ndarray, np.ndarray]:
    """``merge_ranks`` of (m, n) rows, by sorting each row's ids."""
    m, n = ids.shape
    order = np.argsort(ids, axis=-1)
    ids = np.take_along_axis(ids, order, axis=-1)
    weights = np.take_along_axis(weights, order, axis=-1)
    starts = np.ones(ids.shape, bool)
    starts[:, 1:] = ids[:, 1:] != ids[:, :-1]
    run = np.cumsum(starts, axis=-1) - 1 + n * np.arange(m)[:, None]
    totals = np.bincount(run.ravel(), weights.ravel().astype(np.float64), m * n)
    run_ids = np.zeros(m * n, np.float32)
    run_ids[run[starts]] = ids[starts]
    totals = np.where(run_ids != 0, totals, 0.0).reshape(m, n)
    run_ids = run_ids.reshape(m, n)
    if n < levels:
        pad = ((0, 0), (0, levels - n))
        totals, run_ids = np.pad(totals, pad), np.pad(run_ids, pad)
    best = np.argsort(-totals, axis=-1, kind="stable")[:, :levels]
    return (np.take_along_axis(run_ids, best, axis=-1),
            np.take_along_axis(totals, best, axis=-1).astype(np.float32))


def split_ranks(images: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """A family's passes (each (h, w, 4): id, coverage, id, coverage) as ids and weights."""
    stacked = np.concatenate(images, axis=-1)
    return stacked[..., 0::2], stacked[..., 1::2]


def joined_ranks(ids: np.ndarray, weights: np.ndarray) -> list[np.ndarray]:
    """Ids and weights (h, w, 2k) as the family's k passes (``split_ranks`` inverted)."""
    pairs = np.stack([ids, weights], axis=-1).reshape(*ids.shape[:2], -1)
    return [np.ascontiguousarray(pairs[..., 4 * k:4 * k + 4], np.float32)
            for k in range(pairs.shape[-1] // 4)]


def write_tile(output: dict[str, np.ndarray], tables: IdTables, geometric: np.ndarray,
               aa: int, x0: int, y0: int) -> None:
    """The ID passes in ``output`` of one supersampled tile whose g-buffer geometric layer is
    ``geometric`` (h·aa, w·aa, 4) at supersample (x0, y0): the index passes at each pixel's
    centre (one sample, as Cycles writes them from a pixel's first sample), Cryptomatte over
    all its supersamples, and the Shader AOVs averaged over them (a colour's alpha: the
    share of them whose material writes it, as Cycles')."""
    triangles = tables.triangles(geometric)
    h, w = triangles.shape[0] // aa, triangles.shape[1] // aa
    region = (slice(y0 // aa, y0 // aa + h), slice(x0 // aa, x0 // aa + w))
    centres = central(triangles[..., None], aa)
    for name in INDEX_PASSES:
        if name in output:
            output[name][region] = tables.values(name, centres)
    for name in output:
        aov = aov_of(name)
        if aov is not None:
            values = tables.aov(aov[0], triangles)  # (h·aa, w·aa, 5): colour, value, written
            values = values[..., (0, 1, 2, 4)] if aov[1] else values[..., 3:4]
            output[name][region] = values.reshape(h, aa, w, aa, -1).mean(axis=(1, 3))
    for family in CRYPTO_FAMILIES:
        names = family_passes(output, family)
        if names:
            ids, weights = supersample_ranks(tables.values(family, triangles), aa,
                                             2 * len(names))
            for name, image in zip(names, joined_ranks(ids, weights), strict=True):
                output[name][region] = image


def metadata(scene: Scene, families: list[str], layer: str) -> dict[str, str]:
    """The render result's Cryptomatte metadata for the view layer ``layer``: per family its
    layer name, hash, conversion and manifest (name -> hex hash), under the key prefix
    "cryptomatte/" + the layer name's hash's first 7 hex digits."""
    fields = {}
    for family in families:
        name = f"{layer}.{family}"
        prefix = f"cryptomatte/{name_hash(name):08x}"[:19] + "/"
        names = sorted(scene_names(scene, family))
        fields[prefix + "name"] = name
        fields[prefix + "hash"] = "MurmurHash3_32"
        fields[prefix + "conversion"] = "uint32_to_float32"
        fields[prefix + "manifest"] = json.dumps({n: f"{name_hash(n):08x}" for n in names},
                                                 separators=(",", ":"), ensure_ascii=False)
    return fields


def is_id_pass(name: str) -> bool:
    """Whether a pass holds ids (an index pass, a Cryptomatte pass): never blended."""
    return name in INDEX_PASSES or family_of(name) is not None


def wants_ids(passes: Mapping[str, np.ndarray] | frozenset[str]) -> bool:
    """Whether any ID pass (or Shader AOV, looked up the same way) is among ``passes``."""
    return any(is_id_pass(name) or aov_of(name) is not None for name in passes)


class IdPasses:
    """A tile stage (image.py's TileStage interface): the ID passes of one tile, where the
    view layer asks for them."""

    name = "ID passes"

    def run(self, frame: FrameState, data: FrameGpu, work: TileWork) -> None:
        if not wants_ids(frame.output):
            return
        geometry = frame.geometry
        if geometry.triangle_count > MAX_TRIANGLES:
            warning = (f"the ID passes are left empty: {geometry.triangle_count:,} triangles, "
                       f"more than their {MAX_TRIANGLES:,}")
            if warning not in frame.stats.warnings:
                frame.stats.warnings.append(warning)
            return
        with frame.stats.timed(self.name):
            if frame.id_tables is None:
                frame.id_tables = IdTables(frame.scene, geometry)
            write_tile(frame.output, frame.id_tables, work.gbuffer.images["geometric"],
                       frame.settings.antialiasing, work.tile.x0, work.tile.y0)
