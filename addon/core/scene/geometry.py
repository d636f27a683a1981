"""World-space triangle data for the GPU: instances flattened into one vertex stream with a
material-table row per triangle, visible light shapes, and the scene's bounding sphere."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from . import oren_nayar, principled
from . import sheen as sheens
from . import textures as tex
from .closed_surfaces import outward_sides
from .model import (
    DEFAULT_MATERIAL,
    EVERY_RECEIVER_SET,
    Light,
    LightKind,
    Material,
    Mesh,
    Scene,
    Texture,
)

DISK_SEGMENTS = 48
MAX_SHAPE_RADIANCE = 1e30  # a near-zero-area light's shape radiance stays a finite float32
UNIT_TOLERANCE = 1e-5  # relative: unit normals and similarity maps, within float32 rounding


MATERIAL_COLUMNS = 44  # albedo, hidden, emission, holdout, texture attribute, shadowless,
# specular (with the coat and sheen), cutout, diffuse-hidden, normal map, translucency:
# eleven texels
HIDDEN = 3  # 1 in the rows of instances the camera does not see (gbuffer_frag.glsl)
HOLDOUT = 7  # 1 in the rows of holdout instances (gbuffer_frag.glsl, combined_frag.glsl)
SHADOWLESS = 11  # 1 in the rows of instances shadow rays pass (shadow_frag.glsl)
SPECULAR = 12  # first column of the specular texels (principled.specular_row)
COAT = SPECULAR + 8  # the coat's weight in them
SHEEN = SPECULAR + principled.SHEEN_COLUMN  # the sheen's colour in them
ROUGH_DIFFUSE = SPECULAR + principled.DIFFUSE_ROUGHNESS_COLUMN  # the diffuse roughness
CUTOUT = 32  # first column of the cutout texel (TextureSet.cutout, coverage_lib.glsl)
DIFFUSE_HIDDEN = 35  # 1 in the rows of instances diffuse bounces pass (cutout_lib.glsl)
NORMAL_MAP = 36  # first column of the normal-map texel (TextureSet.normal, gbuffer_frag.glsl)
TRANSLUCENCY = 40  # the translucency (Material.translucency) per channel (gather_frag.glsl)
NO_TEXTURE_ATTRIBUTE = (tex.NO_TEXTURE, tex.NO_TEXTURE, 0.0)
NO_MATERIAL = [DEFAULT_MATERIAL]  # the material list of an instance without slots
NO_LINKING = (0, EVERY_RECEIVER_SET, 0, EVERY_RECEIVER_SET)  # Instance.linking's defaults


@dataclass
class WorldGeometry:
    """Flattened triangles: 3 vertices per triangle (positions and normals, float32, each a
    vertex stream of its own as the GPU reads them), and a row of the material table per
    triangle.

    A material row holds the albedo (base colour), the emission, the texture attribute (albedo
    layer, emission layer — NO_TEXTURE for none — and the strength the emission texture is
    multiplied by) and the Principled BSDF's specular parameters (principled.specular_row),
    the cutout texel (TextureSet.cutout), the normal map's (TextureSet.normal) and the
    translucency, laid out as eleven RGBA texels (gpu_shaders/materials_lib.glsl). Textured
    materials have their textures' average colour as albedo and emission (the per-triangle
    values light sampling and path termination use); ``uv`` (per vertex) is set only when some
    material has a texture. ``albedo`` and ``albedo_at`` are what light paths keep at a
    bounce: the base colour, or for materials with a specular layer its cosine-weighted total
    reflectance."""

    positions: np.ndarray  # (V, 3) C-contiguous float32
    normals: np.ndarray  # (V, 3) C-contiguous float32
    triangle_material: np.ndarray  # (V/3,) int32 rows of ``materials``
    materials: np.ndarray  # (M, MATERIAL_COLUMNS) float32
    uv: np.ndarray | None = None  # (V, 2) float32, only with textures
    textures: list[Texture] = field(default_factory=list)
    instanced: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.int64))
    """Runs of one mesh's copies: rows (first triangle, instances, triangles each)."""
    clear_triangles: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 3), np.float32))
    """Triangles of clear materials, (C, 3, 3) world positions: not in the vertex streams; the
    ray tracer lets rays through them (Material.is_clear)."""
    clear_transmission: np.ndarray = field(default_factory=lambda: np.zeros((0, 4), np.float32))
    """Per clear triangle: the colour it lets through and the IOR of its Fresnel loss (0:
    none), (C, 4)."""
    triangle_instance: np.ndarray | None = None
    """Per triangle: its instance's index in ``Scene.instances`` (int32; None for geometry not
    made from instances: light shapes)."""
    row_materials: list[Material] = field(default_factory=list)
    """Per row of ``materials``: the material it was made from."""
    row_receiver_set: np.ndarray | None = None
    """Per row of ``materials``: its instances' light-linking receiver set (int32;
    Instance.receiver_set); None where every row is in set 0."""
    row_emission_receivers: np.ndarray | None = None
    """Per row of ``materials``: the receiver sets its emission lights (uint64;
    Instance.emission_receivers); None where every row's lights all."""
    row_blocker_set: np.ndarray | None = None
    """Per row of ``materials``: its instances' shadow-linking blocker set (int32;
    Instance.blocker_set); None where every row is in set 0."""
    row_emission_blockers: np.ndarray | None = None
    """Per row of ``materials``: the blocker sets that cast its emission's shadows (uint64;
    Instance.emission_blockers); None where every row's are all."""
    deform: np.ndarray | None = None
    """Per vertex: how far it moves (in its instance's object space) by Scene.motion's two
    times, (2, V, 3) float32 (Mesh.deform); None where no mesh deforms."""

    @classmethod
    def from_triangles(cls, positions: np.ndarray, normals: np.ndarray, albedo: np.ndarray,
                       emission: np.ndarray) -> WorldGeometry:
        """Untextured geometry from vertex positions and normals (V, 3) and each triangle's
        albedo and emission (V/3, 3), one material row per triangle."""
        count = len(positions) // 3
        materials = np.zeros((count, MATERIAL_COLUMNS), np.float32)
        materials[:, 0:3], materials[:, 4:7] = albedo, emission
        materials[:, 8:11] = NO_TEXTURE_ATTRIBUTE
        return cls(np.ascontiguousarray(positions, np.float32),
                   np.ascontiguousarray(normals, np.float32),
                   np.arange(count, dtype=np.int32), materials)

    @cached_property
    def albedo(self) -> np.ndarray:
        """Each triangle's reflectance for light paths, (T, 3) float32."""
        layered = np.flatnonzero(self._layered_rows)
        if len(layered) == 0:
            return self._per_triangle(0)
        table = self.materials[:, 0:3].copy()  # never a view: rows change below
        for row in layered:
            table[row] = self._path_albedo(table[row][None], row)[0]
        return np.take(table, self.triangle_material, axis=0)

    @property
    def _layered_rows(self) -> np.ndarray:
        """(M,) bool: material rows whose reflectance is not their base colour's (a glossy
        lobe, a coat, a sheen or a rough diffuse layer)."""
        return (self.materials[:, SPECULAR + 7] > 0) | (self.materials[:, ROUGH_DIFFUSE] != 0)

    def _path_albedo(self, base: np.ndarray, row: int) -> np.ndarray:
        params = self.materials[row, SPECULAR:CUTOUT]
        return np.clip(principled.path_albedo(base.astype(np.float64), params), 0.0, MAX_ALBEDO)

    def _per_triangle_row(self, rows: np.ndarray | None) -> np.ndarray | None:
        """A per-row array read at each triangle's row, or None where ``rows`` is."""
        return None if rows is None else rows[self.triangle_material]

    @cached_property
    def receiver_set(self) -> np.ndarray | None:
        """Each triangle's light-linking receiver set (T,) int32, or None: all in set 0."""
        return self._per_triangle_row(self.row_receiver_set)

    @cached_property
    def emission_receivers(self) -> np.ndarray | None:
        """The receiver sets each triangle's emission lights (T,) uint64, or None: all."""
        return self._per_triangle_row(self.row_emission_receivers)

    @cached_property
    def blocker_set(self) -> np.ndarray | None:
        """Each triangle's shadow-linking blocker set (T,) int32, or None: all in set 0."""
        return self._per_triangle_row(self.row_blocker_set)

    @cached_property
    def emission_blockers(self) -> np.ndarray | None:
        """The blocker sets that cast each triangle's emission's shadows (T,) uint64, or
        None: all."""
        return self._per_triangle_row(self.row_emission_blockers)

    @cached_property
    def deforming(self) -> np.ndarray | None:
        """Per triangle: whether a corner moves by the motion's times (``deform``), or None
        where no mesh deforms."""
        if self.deform is None:
            return None
        return np.any(self.deform.reshape(2, -1, 9) != 0, axis=(0, 2))

    @property
    def has_specular(self) -> bool:
        """Whether some material has a glossy lobe (the shaders' GLOSSY path)."""
        return bool(np.any(self.materials[:, SPECULAR + 7] > 0))

    @property
    def has_coat(self) -> bool:
        """Whether some material has a clear coat (the shaders' COAT path)."""
        return bool(np.any(self.materials[:, COAT] > 0))

    @property
    def has_rough_diffuse(self) -> bool:
        """Whether some material has a rough diffuse layer (the shaders' ROUGH_DIFFUSE
        path)."""
        return bool(np.any(self.materials[:, ROUGH_DIFFUSE] != 0))

    @property
    def has_sheen(self) -> bool:
        """Whether some material has a sheen (the shaders' SHEEN path)."""
        return bool(np.any(self.materials[:, SHEEN:SHEEN + 3] > 0))

    @property
    def has_translucency(self) -> bool:
        """Whether some material lets diffuse light through (the shaders' TRANSLUCENT
        path)."""
        return bool(np.any(self.materials[:, TRANSLUCENCY:TRANSLUCENCY + 3] > 0))

    def translucency(self, triangle: np.ndarray) -> np.ndarray:
        """The share of the diffuse light let through (m, 3) of triangles
        (Material.translucency)."""
        return self.materials[self.triangle_material[triangle],
                              TRANSLUCENCY:TRANSLUCENCY + 3].astype(np.float64)

    @cached_property
    def emission(self) -> np.ndarray:
        """Each triangle's emitted radiance, (T, 3) float32."""
        return self._per_triangle(4)

    @cached_property
    def emission_sides(self) -> np.ndarray:
        """Per triangle, the side its light leaves by: +1 / -1 (along / against its winding's
        normal) on an emissive object that is closed (``closed_surfaces.outward_sides``, by
        instance), 0 (both sides) elsewhere and for geometry not made from instances, (T,)
        int8; found once per geometry, as every set of light paths reads it."""
        sides = np.zeros(self.triangle_count, np.int8)
        emitting = np.flatnonzero(self.light_emission.max(axis=1) > 0)
        if len(emitting) and self.triangle_instance is not None:
            sides[emitting] = outward_sides(self.positions.reshape(-1, 3, 3)[emitting],
                                            self.triangle_instance[emitting])
        return sides

    @cached_property
    def light_emission(self) -> np.ndarray:
        """Each triangle's emitted radiance as a light of the other surfaces (T, 3): its
        emission times its mean coverage (a cutout emits from the part that is there) and
        what leaves through its clear coat and sheen (principled.emission_below_layers), none
        where diffuse bounces pass it (as Cycles' diffuse rays do not see it)."""
        emission = self.emission
        layered = (self.materials[:, COAT] > 0) | self.materials[:, SHEEN:SHEEN + 3].any(axis=1)
        covered = np.flatnonzero(layered & (self.materials[:, 4:7].max(axis=1) > 0))
        if len(covered):
            table = np.ones((len(self.materials), 3), np.float32)
            for row in covered:
                params = self.materials[row, SPECULAR:CUTOUT]
                table[row] = principled.emission_below_layers(principled.coat_of(params),
                                                              principled.sheen_of(params))
            emission = emission * table[self.triangle_material]
        if not (self.cutout.any() or self.diffuse_hidden.any()):
            return emission
        share = np.where(self.diffuse_hidden, 0.0, self.coverage)
        return (emission * share[:, None]).astype(np.float32)

    @property
    def texture(self) -> np.ndarray | None:
        """Each triangle's texture attribute (T, 3), or None without textures."""
        return self._per_triangle(8) if self.has_textures else None

    @cached_property
    def camera_hidden(self) -> np.ndarray:
        """(T,) bool: triangles of instances the camera does not see."""
        return self.materials[self.triangle_material, HIDDEN] > 0.5

    @cached_property
    def holdout(self) -> np.ndarray:
        """(T,) bool: triangles of holdout instances or materials (the camera sees a hole
        there)."""
        return self.materials[self.triangle_material, HOLDOUT] > 0.5

    @cached_property
    def cutout(self) -> np.ndarray:
        """(T,) bool: triangles of cutout materials (Material.is_cutout)."""
        rows = self.materials[:, CUTOUT:CUTOUT + 2]
        return ((rows[:, 0] > 0) | (rows[:, 1] > 0))[self.triangle_material]

    @cached_property
    def coverage(self) -> np.ndarray:
        """(T,) each triangle's mean coverage: 1, or a cutout's constant alpha times its
        texture's mean coverage."""
        table = 1.0 - self.materials[:, CUTOUT + 1].astype(np.float64)
        for row in np.flatnonzero(self.materials[:, CUTOUT] > 0):
            texture = self.textures[int(self.materials[row, CUTOUT]) - 1]
            table[row] *= tex.mean_coverage(texture, int(self.materials[row, CUTOUT + 2]))
        return table[self.triangle_material]

    def cutout_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """The cutout triangles (n,) and their cutout texels (n, 4) (TextureSet.cutout; the
        last column is DIFFUSE_HIDDEN's, which the texel does not use)."""
        triangles = np.flatnonzero(self.cutout)
        rows = self.materials[self.triangle_material[triangles], CUTOUT:CUTOUT + 4]
        return triangles, np.ascontiguousarray(rows, np.float32)

    def cutout_state(self) -> tuple[np.ndarray, ...]:
        """What decides which rays cutouts stop: their triangles, texels, UVs and textures'
        pixels (none without cutouts)."""
        triangles, rows = self.cutout_rows()
        if len(triangles) == 0:
            return ()
        layers = np.unique(rows[:, 0][rows[:, 0] > 0]).astype(int) - 1
        uv = () if self.uv is None else (self.uv.reshape(-1, 6)[triangles],)
        return (triangles, rows, *uv, *(self.textures[k].pixels for k in layers))

    @cached_property
    def diffuse_hidden(self) -> np.ndarray:
        """(T,) bool: triangles of instances diffuse bounces pass (Diffuse visibility off)."""
        return self.materials[self.triangle_material, DIFFUSE_HIDDEN] > 0.5

    @cached_property
    def shadowless(self) -> np.ndarray:
        """(T,) bool: triangles of instances that cast no shadow (shadow rays pass them)."""
        return self.materials[self.triangle_material, SHADOWLESS] > 0.5

    def _per_triangle(self, column: int) -> np.ndarray:
        rows = np.ascontiguousarray(self.materials[:, column:column + 3]).view("V12")[:, 0]
        return np.take(rows, self.triangle_material).view(np.float32).reshape(-1, 3)

    @property
    def vertex_count(self) -> int:
        return len(self.positions)

    @property
    def triangle_count(self) -> int:
        return len(self.triangle_material)

    @property
    def has_textures(self) -> bool:
        """Whether the g-buffer needs its texture path (some material has a texture)."""
        return bool(self.textures)

    def albedo_at(self, triangle: np.ndarray, position: np.ndarray) -> np.ndarray:
        """Reflectance for light paths (m, 3) at points on triangles (``path_albedo`` of the
        base colour there)."""
        return self.path_albedo(triangle, self.base_at(triangle, position))

    def path_albedo(self, triangle: np.ndarray, base: np.ndarray) -> np.ndarray:
        """Reflectance for light paths (m, 3) at points on triangles whose base colour is
        ``base`` (m, 3) (``base_at``'s): ``albedo``'s, per point."""
        if not self.has_textures or len(triangle) == 0:
            return self.albedo[triangle].astype(np.float64)
        albedo = base.copy()
        material = self.triangle_material[triangle]
        layered = self._layered_rows
        for row in np.unique(material):
            if layered[row]:
                group = np.flatnonzero(material == row)
                albedo[group] = self._path_albedo(albedo[group], row)
        return albedo

    def reflectance_split(self, triangle: np.ndarray, base: np.ndarray, mu: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                     np.ndarray]:
        """What a light path arriving at cosine ``mu`` (m,) keeps at points on triangles whose
        base colour is ``base`` (m, 3): the diffuse reflectance (m, 3) (base colour × the
        diffuse weight averaged over outgoing directions × the rough diffuse lobe's albedo
        factor at ``mu``, plus what the sheen reflects at ``mu``, which a VPL re-emits
        diffusely), the glossy albedo (m, 3) at ``mu`` (the
        coat's included), the lobe's roughness (m,), and the coat's share of the glossy
        albedo's luminance (m,) and roughness (m,)."""
        diffuse = base.copy()
        gloss, rough = np.zeros_like(diffuse), np.zeros(len(triangle))
        coat_share, coat_rough = np.zeros(len(triangle)), np.zeros(len(triangle))
        material = self.triangle_material[triangle]
        for row in np.unique(material):
            params = self.materials[row, SPECULAR:CUTOUT]
            sigma, multiscatter = principled.diffuse_roughness_of(params)
            group = np.flatnonzero(material == row)
            if sigma > 0:
                diffuse[group] *= oren_nayar.albedo_factor(base[group], sigma, mu[group],
                                                           multiscatter)
            if params[7] <= 0:
                continue
            specular = principled.specular_parameters(params)
            _, gloss[group] = principled.layer_weights(base[group], *specular, mu[group])
            sheen_reflected, keep = sheens.layer(specular[-1], mu[group])
            diffuse[group] = diffuse[group] * principled.diffuse_average(params) \
                + sheen_reflected
            rough[group] = params[0]
            coat = principled.coat_of(params)
            if coat.weight > 0:
                reflected = principled.coat_albedo(coat, mu[group]) * keep
                luminance = np.maximum(gloss[group] @ tex.LUMINANCE, 1e-30)
                coat_share[group] = reflected / luminance
                coat_rough[group] = coat.roughness
        return diffuse, gloss, rough, np.clip(coat_share, 0.0, 1.0), coat_rough

    def rough_lobes(self, triangle: np.ndarray, base: np.ndarray, mu: np.ndarray
                    ) -> np.ndarray:
        """The rough diffuse lobes (m, 2, 4) at points on triangles whose base colour is
        ``base`` (m, 3), for light arriving at cosine ``mu`` (m,), per unit incident flux:
        (c, σ) and (c m (1 − E(μ)), 0), c the diffuse layer's colour (the base colour times
        the diffuse weight ``reflectance_split`` averages); zero for smooth materials (what
        lights_lib.glsl's VPLs at rough surfaces emit beyond a Lambertian one)."""
        out = np.zeros((len(triangle), 2, 4))
        material = self.triangle_material[triangle]
        for row in np.unique(material):
            params = self.materials[row, SPECULAR:CUTOUT]
            sigma, multiscatter = principled.diffuse_roughness_of(params)
            if sigma <= 0:
                continue
            group = np.flatnonzero(material == row)
            colour = base[group] * (principled.diffuse_average(params) if params[7] > 0
                                    else 1.0)
            out[group, 0, :3], out[group, 0, 3] = colour, sigma
            out[group, 1, :3] = colour * oren_nayar.multiscatter_at(
                base[group], sigma, mu[group], multiscatter)
        return out

    def coats(self, triangle: np.ndarray) -> np.ndarray:
        """The clear coats (weight, roughness, IOR) (m, 3) of triangles (weight 0: none)."""
        return self.materials[self.triangle_material[triangle], COAT:COAT + 3].astype(
            np.float64)

    def lobe_texels(self, triangle: np.ndarray, base: np.ndarray,
                    mu: np.ndarray) -> np.ndarray:
        """The glossy lobes (m, 3, 4) at points on triangles whose base colour is ``base``
        (m, 3), for light arriving at cosine ``mu`` (m,) (principled.lobe_texels; zero for
        materials without one)."""
        out = np.zeros((len(triangle), principled.LOBE_TEXELS, 4))
        material = self.triangle_material[triangle]
        for row in np.unique(material):
            params = self.materials[row, SPECULAR:CUTOUT]
            if params[7] > 0:
                group = np.flatnonzero(material == row)
                out[group] = principled.lobe_texels(base[group], params, mu[group])
        return out

    def base_at(self, triangle: np.ndarray, position: np.ndarray) -> np.ndarray:
        """Base colour (m, 3) at points on triangles: the material's, or the texture sampled
        at the interpolated UV (with its interpolation and extension), capped like base
        colours."""
        albedo = np.clip(self.materials[self.triangle_material[triangle], 0:3].astype(np.float64),
                         0.0, MAX_ALBEDO)
        if not self.has_textures or len(triangle) == 0:
            return albedo
        layer = self.materials[self.triangle_material[triangle], 8].astype(int)
        rows = np.flatnonzero(layer >= 0)
        if len(rows) == 0:
            return albedo
        t = self.positions.reshape(-1, 3, 3)[triangle[rows]].astype(np.float64)
        e1, e2, d = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0], position[rows] - t[:, 0]
        d11, d12, d22 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
        p1, p2 = (d * e1).sum(1), (d * e2).sum(1)
        det = np.maximum(d11 * d22 - d12 * d12, 1e-300)
        b1, b2 = (d22 * p1 - d12 * p2) / det, (d11 * p2 - d12 * p1) / det
        uv = self.uv.reshape(-1, 3, 2)[triangle[rows]].astype(np.float64)
        at = uv[:, 0] + b1[:, None] * (uv[:, 1] - uv[:, 0]) + b2[:, None] * (uv[:, 2] - uv[:, 0])
        for k in np.unique(layer[rows]):
            group = layer[rows] == k
            albedo[rows[group]] = tex.sample(self.textures[k], at[group])
        return np.clip(albedo, 0.0, MAX_ALBEDO)


def empty_geometry() -> WorldGeometry:
    """Geometry without triangles (one material row of zeros, as the GPU needs a buffer)."""
    empty = np.zeros((0, 3), np.float32)
    return WorldGeometry(empty, empty, np.zeros(0, np.int32),
                         np.zeros((1, MATERIAL_COLUMNS), np.float32))


def transform_points(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Points (N, 3) through a 4×4 affine matrix."""
    return points @ matrix[:3, :3].T + matrix[:3, 3]


def _normal_matrices(linear: np.ndarray) -> np.ndarray:
    """Matrices that carry normals through (k, 3, 3) linear maps: the cofactor matrices (the
    inverse transposes times the determinant), signed so that mirroring keeps the side; they
    stay defined for singular maps. Normals are normalised afterwards."""
    c0, c1, c2 = linear[:, :, 0], linear[:, :, 1], linear[:, :, 2]
    cofactor = np.stack([np.cross(c1, c2), np.cross(c2, c0), np.cross(c0, c1)], axis=2)
    det = np.einsum("ki,ki->k", c0, cofactor[:, :, 0])
    return cofactor * np.where(det < 0, -1.0, 1.0)[:, None, None]


MAX_ALBEDO = 1.0  # a diffuse surface cannot reflect more than it receives
MAX_EMISSION = 1e30  # radiance a surface may emit: sums of its light stay below float32's max


def _albedo_table(materials: list[Material], warnings: list[str]) -> np.ndarray:
    """Base colours per material slot, capped to [0, MAX_ALBEDO] with one warning per material
    (Blender allows colours above 1; with them every bounce would add energy)."""
    table = np.array([m.base_color for m in materials], dtype=np.float64)
    _name_rows(materials, table, warnings, lambda row: not np.isfinite(row).all(),
               "base colour {} is not finite: rendered as 0 there",
               lambda row: tuple(row.tolist()))
    table = np.where(np.isfinite(table), table, 0.0)
    _name_rows(materials, table, warnings, lambda row: row.max() > MAX_ALBEDO or row.min() < 0,
               f"base colour {{}} capped to [0, {MAX_ALBEDO:g}] (energy would grow with every "
               f"bounce)", lambda row: tuple(np.round(row, 3)))
    return np.clip(table, 0.0, MAX_ALBEDO)


def _name_rows(materials: list[Material], rows: np.ndarray, warnings: list[str],
               bad: Callable[[np.ndarray], bool], text: str,
               shown: Callable[[np.ndarray], object]) -> None:
    """One warning per material whose row of ``rows`` is ``bad``: ``text`` with the row as
    ``shown``, after the material's name (each message once)."""
    for material, row in zip(materials, rows, strict=True):
        message = f"material '{material.name}': " + text.format(shown(row)) if bad(row) \
            else None
        if message is not None and message not in warnings:
            warnings.append(message)


def _material_rows(materials: list[Material], warnings: list[str],
                   textures: tex.TextureSet, clamped: set[str]) -> np.ndarray:
    """Material-table rows (n, MATERIAL_COLUMNS) of one material list: albedo (capped, see
    ``_albedo_table``), emission (finite, >= 0) and texture attribute; textures count with
    their average colour; names of glossy materials whose roughness is clamped go into
    ``clamped``."""
    albedo = _albedo_table(materials, warnings)
    emission = np.array([m.emission for m in materials], np.float64)
    _name_rows(materials, emission, warnings,
               lambda row: not (np.isfinite(row).all() and row.min() >= 0),
               "emission {} is negative or not finite: rendered as 0 there",
               lambda row: tuple(row.tolist()))
    emission = np.where(np.isfinite(emission), np.maximum(emission, 0), 0)
    _name_rows(materials, emission, warnings, lambda row: row.max() > MAX_EMISSION,
               f"emission {{}} capped to {MAX_EMISSION:g} (its light would overflow 32-bit "
               f"floats)", lambda row: tuple(row.tolist()))
    emission = np.minimum(emission, MAX_EMISSION)
    for row, material in enumerate(materials):
        if material.base_color_texture is not None:
            albedo[row] = np.clip(tex.mean_color(material.base_color_texture), 0, MAX_ALBEDO)
        if material.emission_texture is not None:
            emission[row] *= tex.mean_color(material.emission_texture)
    rows = np.zeros((len(materials), MATERIAL_COLUMNS), np.float32)
    rows[:, 0:3], rows[:, 4:7] = albedo, emission
    rows[:, 8:11] = [textures.columns(m) for m in materials]
    rows[:, CUTOUT:CUTOUT + 4] = [textures.cutout(m) for m in materials]
    rows[:, NORMAL_MAP:NORMAL_MAP + 4] = [textures.normal(m) for m in materials]
    translucency = np.array([m.translucency for m in materials], np.float64).reshape(-1, 3)
    rows[:, TRANSLUCENCY:TRANSLUCENCY + 3] = np.clip(np.nan_to_num(translucency), 0.0, 1.0)
    for row, m in enumerate(materials):
        values = np.array([m.roughness, m.metallic, m.ior, m.specular_ior_level,
                           *m.specular_tint, m.coat_weight, m.coat_roughness, m.coat_ior,
                           *m.coat_tint, m.sheen_weight, m.sheen_roughness, *m.sheen_tint,
                           m.diffuse_roughness],
                          np.float64)
        if not np.isfinite(values).all():
            message = f"material '{m.name}': specular values are not finite: rendered diffuse"
            if message not in warnings:
                warnings.append(message)
            continue
        rows[row, SPECULAR:CUTOUT] = principled.specular_row(
            m.roughness, m.metallic, m.ior, m.specular_ior_level, m.specular_tint,
            principled.Coat(m.coat_weight, m.coat_roughness, m.coat_ior, m.coat_tint),
            principled.Sheen(tuple(max(m.sheen_weight, 0.0) * np.asarray(m.sheen_tint)),
                             m.sheen_roughness, m.sheen_layered, m.sheen_dims_cast_light),
            m.diffuse_roughness, m.diffuse_multiscatter)
        base_lobe = rows[row, SPECULAR + 7] > 0 \
            and (rows[row, SPECULAR + 2] != 1.0 or rows[row, SPECULAR + 1] > 0)
        if (base_lobe and m.roughness < principled.MIN_ROUGHNESS) \
                or (rows[row, COAT] > 0 and m.coat_roughness < principled.MIN_ROUGHNESS):
            clamped.add(m.name)
    return rows


def _transmission_row(material: Material) -> tuple[float, ...]:
    """The colour a clear material lets through (finite, in [0, 1]) and its Fresnel IOR."""
    colour = np.clip(np.nan_to_num(np.asarray(material.transmission, float)), 0.0, 1.0)
    ior = float(material.transmission_ior)
    return (*colour, ior if np.isfinite(ior) and ior > 0 else 0.0)


class _MaterialTable:
    """The frame's material table: one block of rows per distinct material list (one row per
    slot), shared by every instance with that list."""

    def __init__(self, warnings: list[str]) -> None:
        self.warnings = warnings
        self.textures = tex.TextureSet()
        self.clamped: set[str] = set()
        self.clear: list[bool] = []  # per row: a clear material (Material.is_clear)
        self.transmission: list[tuple[float, ...]] = []  # per row: colour and Fresnel IOR
        self.clear_names: set[str] = set()
        self.materials: list[Material] = []  # per row
        self.linking_rows: list[tuple[int, int, int, int]] = []  # per row: Instance's
        # receiver_set, emission_receivers, blocker_set, emission_blockers
        self.blocks: list[np.ndarray] = []
        self._first: dict[tuple[int, ...], int] = {}
        self.row_count = 0

    def block(self, materials: list[Material], flags: tuple[bool, bool, bool, bool],
              linking: tuple[int, int, int, int] = NO_LINKING) -> tuple[int, int]:
        """The first row and row count of a material list's block (added on first use) for
        instances of ``flags`` (Instance.flags): the rows of instances the camera does not see
        are marked (column HIDDEN; and of materials it sees through), those of holdouts
        (HOLDOUT) and those that cast no shadow (SHADOWLESS; and of materials shadow rays pass)
        and those diffuse bounces pass (DIFFUSE_HIDDEN). ``linking``: the
        instances' receiver set, emission receivers, blocker set and emission blockers
        (Instance.linking)."""
        key = (*(id(m) for m in materials), *flags, *linking)
        if key not in self._first:
            self._first[key] = self.row_count
            rows = _material_rows(materials, self.warnings, self.textures, self.clamped)
            visible_to_camera, holdout, casts_shadow, visible_to_diffuse = flags
            rows[:, HIDDEN] = [0.0 if visible_to_camera and not m.camera_sees_through
                               else 1.0 for m in materials]
            rows[:, HOLDOUT] = [1.0 if holdout or m.holdout else 0.0 for m in materials]
            rows[:, SHADOWLESS] = [0.0 if casts_shadow and not m.shadow_rays_pass else 1.0
                                   for m in materials]
            rows[:, DIFFUSE_HIDDEN] = 0.0 if visible_to_diffuse else 1.0
            self.blocks.append(rows)
            self.materials.extend(materials)
            self.linking_rows.extend([linking] * len(materials))
            self.clear.extend(m.is_clear for m in materials)
            self.transmission.extend(_transmission_row(m) for m in materials)
            self.clear_names.update(m.name for m in materials if m.is_clear)
            self.row_count += len(materials)
        return self._first[key], len(materials)

    def rows(self) -> np.ndarray:
        """All rows, (M, MATERIAL_COLUMNS) float32 (one row of zeros when empty)."""
        if not self.blocks:
            return np.zeros((1, MATERIAL_COLUMNS), np.float32)
        return np.concatenate(self.blocks)

    def linking(self) -> dict[str, np.ndarray | None]:
        """WorldGeometry's row_* linking fields: per row the receiver set, the emission's
        receivers, the blocker set and the emission's blockers, each None where all rows
        have the default (no light or shadow linking)."""
        columns = list(zip(*self.linking_rows, strict=True)) or [()] * 4
        found = {}
        for name, column, default in zip(
                ("row_receiver_set", "row_emission_receivers", "row_blocker_set",
                 "row_emission_blockers"), columns, NO_LINKING, strict=True):
            values = np.array(column, np.int32 if name.endswith("_set") else np.uint64)
            found[name] = values if (values != values.dtype.type(default)).any() else None
        return found


def _apply(rows: np.ndarray, maps: np.ndarray) -> np.ndarray:
    """(R, n) rows through (k, 3, n) maps in float32 (n = 4: affine maps of points given
    without their homogeneous 1), as a C-contiguous (k, R, 3)."""
    rows = np.asarray(rows, np.float32)
    if maps.shape[2] == 4:
        rows = np.concatenate([rows, np.ones((len(rows), 1), np.float32)], axis=1)
    return np.matmul(rows[None], np.ascontiguousarray(maps.transpose(0, 2, 1), np.float32))


def _unit_rows(rows: np.ndarray) -> bool:
    """Whether every (R, 3) row is of unit length (within float32 rounding) or zero."""
    length = np.sqrt(np.einsum("ij,ij->i", rows, rows))
    return bool(np.all((np.abs(length - 1) < UNIT_TOLERANCE) | (length == 0)))


def _similarity_scales(linear: np.ndarray) -> np.ndarray | None:
    """Each (k, 3, 3) map's squared scale s² where all are similarities (Lᵀ L = s² I: a rotation
    or mirror times a uniform scale), else None."""
    gram = np.matmul(linear.transpose(0, 2, 1), linear)
    scale = np.trace(gram, axis1=1, axis2=2) / 3
    off = np.abs(gram - scale[:, None, None] * np.eye(3)).max(axis=(1, 2))
    if not np.all((off <= UNIT_TOLERANCE * scale) & (scale > 0)):
        return None
    return scale


def _gather_rows(values: np.ndarray, index: np.ndarray | None, out: np.ndarray) -> None:
    """Write (k, R, 3) float32 rows into ``out`` (k·C, 3), gathered at ``index`` (C,), or all
    rows when None, as 12-byte records (numpy's float loops over the 3 floats of each row take
    several times longer than moving whole records)."""
    records = np.ascontiguousarray(values, np.float32).view("V12")[..., 0]
    target = out.view("V12").reshape(len(records), -1)
    if index is None:
        target[:] = records
    else:
        np.take(records, index, axis=1, out=target, mode="clip")  # clip: unbuffered


@dataclass
class _Group:
    """The instances of one mesh: their matrices, the first row and row count of each one's
    material list in the material table, and their indices."""

    mesh: Mesh
    matrices: list[np.ndarray] = field(default_factory=list)
    rows: list[tuple[int, int]] = field(default_factory=list)
    instances: list[int] = field(default_factory=list)  # their indices in Scene.instances


def _flatten_group(group: _Group, warnings: list[str], positions_out: np.ndarray,
                   normals_out: np.ndarray, uv_out: np.ndarray | None,
                   material_out: np.ndarray, clear: np.ndarray) -> np.ndarray | None:
    """Write world positions and normals of every instance of one shared mesh into
    ``positions_out`` and ``normals_out`` (k·V, 3), transformed together in float32 as the GPU
    gets them (each stored point and normal once, then gathered per corner), UVs into
    ``uv_out`` (k·V, 2) if given, and each triangle's material row into ``material_out``
    (k·T,). Returns the mask of vertices on finite triangles whose material row is not
    ``clear``, or None when that is all of them."""
    mesh = group.mesh
    k, triangles = len(group.matrices), mesh.triangle_count
    corners = 3 * triangles
    matrices = np.concatenate(group.matrices).reshape(k, 4, 4).astype(np.float64, copy=False)
    identity = k == 1 and np.array_equal(matrices[0], np.eye(4))
    normals = mesh.normals if np.isfinite(mesh.normals).all() else np.nan_to_num(mesh.normals)
    normals = normals[None]
    scales = None  # the maps' squared scales where all are similarities of unit normals
    with np.errstate(all="ignore"):
        if identity:  # the identity's normal matrix is the identity too
            world = mesh.positions[None]
        else:
            world = _apply(mesh.positions, matrices[:, :3, :])
            linear = np.nan_to_num(matrices[:, :3, :3])
            cofactors = _normal_matrices(linear)
            if _unit_rows(normals[0]):
                scales = _similarity_scales(linear)
            if scales is not None:  # a similarity's cofactor over s² is a rotation
                cofactors /= scales[:, None, None]
            normals = _apply(normals[0], cofactors)
        if scales is None:
            x, y, z = normals[..., 0], normals[..., 1], normals[..., 2]
            length = np.sqrt(x * x + y * y + z * z)  # np.linalg.norm's sums, without its reduce
            normals = normals / length[..., None]
            positive = length > 0
            if not positive.all():
                normals[~positive] = 0.0
    _gather_rows(world, mesh.position_index, positions_out)
    _gather_rows(normals, mesh.normal_index, normals_out)
    keep = None
    if not np.isfinite(world).all():
        finite_points = np.isfinite(world).all(axis=2)
        if mesh.position_index is not None:
            finite_points = finite_points[:, mesh.position_index]
        finite = finite_points.reshape(k, triangles, 3).all(axis=2)
        for row in np.flatnonzero(~finite.all(axis=1)):
            warnings.append(f"mesh '{mesh.name}': {int((~finite[row]).sum())} of "
                            f"{triangles} triangles have NaN/Inf positions and were left out")
        keep = np.repeat(finite, 3, axis=1).ravel()
    if uv_out is not None:
        uvs = mesh.corner_uvs()
        uv_out.reshape(k, corners, 2)[:] = 0.0 if uvs is None else uvs
    slots = np.clip(mesh.material_slots, 0, None)
    # one material list for every instance: one row set, broadcast (10k instances: 0.5 ms
    # against 5 ms for a row set each)
    lists = group.rows[:1] if all(r == group.rows[0] for r in group.rows) else group.rows
    first, count = np.array(lists, np.int64).reshape(-1, 2).T
    material_out.reshape(k, triangles)[:] = first[:, None] + np.minimum(slots[None],
                                                                        count[:, None] - 1)
    if clear.any():
        opaque = np.repeat(~clear[material_out], 3)
        if not opaque.all():
            keep = opaque if keep is None else keep & opaque
    return keep


def flatten_instances(scene: Scene, warnings: list[str], notes: list[str] | None = None
                      ) -> WorldGeometry:
    """All instances in world space with each triangle's material row, written straight into
    the vertex streams. Instances of one mesh are transformed together (the order is
    by each mesh's first instance).

    Triangles whose world positions are not finite (NaN/Inf vertices or transforms) are left
    out, with one warning per instance; so are triangles of clear materials, which light and
    camera rays pass (one line in ``notes``). Glossy materials smoother than
    principled.MIN_ROUGHNESS get one line in ``notes``."""
    table = _MaterialTable(warnings)
    found: dict[int, _Group] = {}
    blocks: dict[tuple, tuple[int, int]] = {}  # by material list and Instance.flags:
    # instances of an object share it
    for index, inst in enumerate(scene.instances):  # one pass: many thousand instances
        group = found.get(id(inst.mesh))
        if group is None:
            group = found[id(inst.mesh)] = _Group(inst.mesh)
        linking = inst.linking
        key = (id(inst.materials), *inst.flags, *linking)
        rows = blocks.get(key)
        if rows is None:
            rows = blocks[key] = table.block(inst.materials or NO_MATERIAL, inst.flags,
                                             linking)
        group.matrices.append(inst.matrix)
        group.rows.append(rows)
        group.instances.append(index)
    groups = [group for group in found.values() if group.mesh.triangle_count]
    textured = bool(table.textures.textures)
    sizes = [len(group.matrices) * group.mesh.triangle_count for group in groups]
    positions = np.empty((3 * sum(sizes), 3), np.float32)
    normals = np.empty((3 * sum(sizes), 3), np.float32)
    uv = np.empty((3 * sum(sizes), 2), np.float32) if textured else None
    triangle_material = np.empty(sum(sizes), np.int32)
    triangle_instance = np.repeat(
        np.array([i for group in groups for i in group.instances], np.int32),
        [group.mesh.triangle_count for group in groups for _ in group.instances])
    clear = np.array(table.clear, bool)
    deform = np.zeros((2, 3 * sum(sizes), 3), np.float32) \
        if any(group.mesh.deform is not None for group in groups) else None
    masks, start = [], 0
    for group, size in zip(groups, sizes, strict=True):
        corners = slice(3 * start, 3 * (start + size))
        masks.append(_flatten_group(group, warnings, positions[corners], normals[corners],
                                    None if uv is None else uv[corners],
                                    triangle_material[start:start + size], clear))
        if deform is not None and group.mesh.deform is not None:
            index = group.mesh.position_index
            moved = group.mesh.deform if index is None else group.mesh.deform[:, index]
            deform[:, corners] = np.tile(moved, (1, len(group.matrices), 1))
        start += size
    is_clear = clear[triangle_material] if clear.any() else np.zeros(0, bool)
    clear_count = int(is_clear.sum())
    clear_triangles = np.zeros((0, 3, 3), np.float32)
    clear_transmission = np.zeros((0, 4), np.float32)
    if clear_count:
        rows = triangle_material[is_clear]
        clear_triangles = positions.reshape(-1, 3, 3)[is_clear]
        finite = np.isfinite(clear_triangles).all(axis=(1, 2))
        clear_triangles = np.ascontiguousarray(clear_triangles[finite])
        clear_transmission = np.array(table.transmission, np.float32).reshape(-1, 4)[
            rows[finite]]
    if any(mask is not None for mask in masks):
        keep = np.concatenate([np.ones(3 * size, bool) if mask is None else mask
                               for mask, size in zip(masks, sizes, strict=True)])
        positions, normals = positions[keep], normals[keep]
        uv = None if uv is None else uv[keep]
        deform = None if deform is None else deform[:, keep]
        triangle_material = triangle_material[keep[::3]]
        triangle_instance = triangle_instance[keep[::3]]
    kept = [size if mask is None else int(mask.sum()) // 3
            for mask, size in zip(masks, sizes, strict=True)]
    firsts = np.cumsum([0, *kept])[:-1]
    instanced = np.array([(first, len(group.matrices), group.mesh.triangle_count)
                          for first, group, mask in zip(firsts, groups, masks, strict=True)
                          if mask is None and len(group.matrices) > 1], np.int64).reshape(-1, 3)
    textures = table.textures.textures
    if clear_count and notes is not None:
        notes.append(f"{clear_count} triangles of clear material(s) "
                     f"{', '.join(repr(n) for n in sorted(table.clear_names))} let light "
                     f"straight through: their tint and Fresnel loss dim direct light, light "
                     f"paths and the camera's view, not VPLs' light (imperfect shadow maps); "
                     f"their reflections and refraction are not rendered")
    if table.clamped and notes is not None:
        notes.append(f"glossy roughness below {principled.MIN_ROUGHNESS:g} is rendered at "
                     f"{principled.MIN_ROUGHNESS:g}: {len(table.clamped)} material(s), e.g. "
                     f"'{min(table.clamped)}'")
    return WorldGeometry(positions, normals, triangle_material, table.rows(),
                         uv if textures else None, textures, instanced, clear_triangles,
                         clear_transmission, triangle_instance, table.materials,
                         deform=deform, **table.linking())


def bounding_sphere(positions: np.ndarray, box: tuple[np.ndarray, np.ndarray] | None = None
                    ) -> tuple[np.ndarray, float]:
    """Centre and radius of a sphere around all points (box-centred; radius > 0); ``box``:
    the points' (min, max) where the caller has it."""
    if len(positions) == 0:
        return np.zeros(3), 1.0
    low, high = box if box is not None else (positions.min(axis=0), positions.max(axis=0))
    low, high = low.astype(np.float64), high.astype(np.float64)
    centre = 0.5 * (low + high)
    radius = float(np.sqrt(((positions - centre) ** 2).sum(axis=1).max()))
    return centre, max(radius, 1e-6 * max(1.0, float(np.abs(centre).max())), 1e-30)


def area_light_outline(light: Light) -> np.ndarray:
    """Points (N, 2) of the light's shape in its local XY plane, as a triangle fan centre first."""
    hx, hy = 0.5 * np.asarray(light.area_size)
    if not light.is_round:
        ring = np.array([[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]])
    else:
        angle = np.linspace(0.0, 2.0 * np.pi, DISK_SEGMENTS, endpoint=False)
        ring = np.stack([hx * np.cos(angle), hy * np.sin(angle)], axis=1)
    return ring


def light_shapes(scene: Scene) -> WorldGeometry:
    """Camera-visible area-light shapes as one-sided emissive triangles (they cast no shadow).

    An area light of power P and area A has radiance P / (pi A) (measured against Cycles)."""
    positions, normals, emission = [], [], []
    for light in scene.lights:
        if light.kind is not LightKind.AREA or light.power <= 0 or not light.visible_to_camera:
            continue
        ring = area_light_outline(light)
        n = len(ring)
        fan = np.stack([np.zeros((n, 2)), ring, np.roll(ring, -1, axis=0)], axis=1).reshape(-1, 2)
        local = np.hstack([fan, np.zeros((len(fan), 1))])
        world = transform_points(light.matrix, local)
        area = light.world_area
        if area <= 0:
            continue
        facing = -light.matrix[:3, 2] / max(np.linalg.norm(light.matrix[:3, 2]), 1e-300)
        radiance = np.asarray(light.color) * light.power / (np.pi * area)
        radiance = np.clip(np.nan_to_num(radiance), 0.0, MAX_SHAPE_RADIANCE)
        positions.append(world)
        normals.append(np.repeat(facing[None], len(world), axis=0))
        emission.append(np.repeat(radiance[None], len(world), axis=0))
    if not positions:
        return empty_geometry()
    pos = np.concatenate(positions)
    return WorldGeometry.from_triangles(pos, np.concatenate(normals),
                                        np.zeros((len(pos) // 3, 3)),
                                        np.concatenate(emission)[::3])
