"""World-space triangle data for the GPU: instances flattened into one vertex stream with
per-vertex material values, visible light shapes, and the scene's bounding sphere."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import textures as tex
from .scene import Instance, Light, LightKind, Material, Scene, Texture

DISK_SEGMENTS = 48
MAX_SHAPE_RADIANCE = 1e30  # a near-zero-area light's shape radiance stays a finite float32


@dataclass
class WorldGeometry:
    """Flattened triangles: 3 vertices per triangle, attributes per vertex (float32).

    Textured materials have their textures' average colour in ``albedo`` and ``emission``
    (the per-triangle values light sampling and path termination use); ``uv`` and
    ``texture`` (albedo layer, emission layer — -1 for none — and emission strength) are
    set only when some material has a texture."""

    positions: np.ndarray  # (V, 3)
    normals: np.ndarray  # (V, 3)
    albedo: np.ndarray  # (V, 3)
    emission: np.ndarray  # (V, 3)
    uv: np.ndarray | None = None  # (V, 2)
    texture: np.ndarray | None = None  # (V, 3)
    textures: list[Texture] = field(default_factory=list)

    @property
    def vertex_count(self) -> int:
        return len(self.positions)

    @property
    def has_textures(self) -> bool:
        """Whether the g-buffer needs its texture path (some material has a texture)."""
        return bool(self.textures)

    def texture_vertices(self) -> np.ndarray:
        """The texture path's second vertex stream, (V, 5) float32: uv, texture attribute."""
        return np.ascontiguousarray(np.hstack([self.uv, self.texture]), dtype=np.float32)

    def albedo_at(self, triangle: np.ndarray, position: np.ndarray) -> np.ndarray:
        """Albedo (m, 3) at points on triangles: the base colour, or the texture sampled at the
        interpolated UV (bilinear, Repeat), capped like base colours."""
        albedo = self.albedo.reshape(-1, 3, 3)[triangle, 0].astype(np.float64)
        if not self.has_textures or len(triangle) == 0:
            return albedo
        layer = self.texture.reshape(-1, 3, 3)[triangle, 0, 0].astype(int)
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

    def interleaved(self) -> np.ndarray:
        """Vertex data as one (V, 12) float32 array: position, normal, albedo, emission."""
        return np.ascontiguousarray(np.hstack(
            [self.positions, self.normals, self.albedo, self.emission]), dtype=np.float32)


def _transform_points(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
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


def _albedo_table(materials: list[Material], warnings: list[str]) -> np.ndarray:
    """Base colours per material slot, capped to [0, MAX_ALBEDO] with one warning per material
    (Blender allows colours above 1; with them every bounce would add energy)."""
    table = np.array([m.base_color for m in materials], dtype=np.float64)
    table = np.where(np.isfinite(table), table, 0.0)
    for material, row in zip(materials, table, strict=True):
        if row.max() > MAX_ALBEDO or row.min() < 0:
            message = (f"material '{material.name}': base colour {tuple(np.round(row, 3))} "
                       f"capped to [0, {MAX_ALBEDO:g}] (energy would grow with every bounce)")
            if message not in warnings:
                warnings.append(message)
    return np.clip(table, 0.0, MAX_ALBEDO)


def _material_tables(materials: list[Material], warnings: list[str],
                     textures: tex.TextureSet | None) -> tuple[np.ndarray, ...]:
    """Albedo (capped, see ``_albedo_table``), emission (finite, >= 0) and, with ``textures``,
    the texture attribute per material slot; textures count with their average colour."""
    albedo = _albedo_table(materials, warnings)
    emission = np.array([m.emission for m in materials] or [(0.0, 0.0, 0.0)], np.float64)
    emission = np.where(np.isfinite(emission), np.maximum(emission, 0), 0)
    if textures is None:
        return albedo, emission
    for row, material in enumerate(materials):
        if material.base_color_texture is not None:
            albedo[row] = np.clip(tex.mean_color(material.base_color_texture), 0, MAX_ALBEDO)
        if material.emission_texture is not None:
            emission[row] *= tex.mean_color(material.emission_texture)
    attribute = np.array([textures.columns(m) for m in materials], np.float64)
    return albedo, emission, attribute


def _flatten_group(members: list[Instance], tables: dict, warnings: list[str],
                   textures: tex.TextureSet | None) -> tuple[np.ndarray, ...]:
    """World positions, normals, albedo and emission of every instance of one shared mesh,
    transformed together (float32, as the GPU gets them); with ``textures`` also UVs and the
    texture attribute."""
    mesh = members[0].mesh
    k, vertices = len(members), len(mesh.positions)
    matrices = np.stack([inst.matrix for inst in members]).astype(np.float64)
    with np.errstate(all="ignore"):
        world = np.matmul(mesh.positions.astype(np.float32)[None],
                          matrices[:, :3, :3].transpose(0, 2, 1).astype(np.float32)) \
            + matrices[:, None, :3, 3].astype(np.float32)
    finite = np.isfinite(world).all(axis=2).reshape(k, -1, 3).all(axis=2)
    for row in np.flatnonzero(~finite.all(axis=1)):
        warnings.append(f"mesh '{mesh.name}': {int((~finite[row]).sum())} of {finite.shape[1]} "
                        f"triangles have NaN/Inf positions and were left out")
    with np.errstate(all="ignore"):
        normal_matrices = _normal_matrices(np.nan_to_num(matrices[:, :3, :3]))
        normals = np.matmul(np.nan_to_num(mesh.normals.astype(np.float32))[None],
                            normal_matrices.transpose(0, 2, 1).astype(np.float32))
        length = np.linalg.norm(normals, axis=2, keepdims=True)
        normals = np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)
    slots_per_vertex = np.repeat(mesh.material_slots, 3)
    width = max(1, int(slots_per_vertex.max(initial=0)) + 1)
    per_slot = [np.zeros((k, width, 3), np.float32) for _ in range(2 if textures is None else 3)]
    for row, inst in enumerate(members):
        key = tuple(id(m) for m in inst.materials)
        if key not in tables:
            tables[key] = _material_tables(inst.materials or [Material("(no material)")],
                                           warnings, textures)
        clipped = np.minimum(np.arange(width), len(tables[key][0]) - 1)
        for table, values in zip(per_slot, tables[key], strict=True):
            table[row] = values[clipped]
    slots = np.clip(slots_per_vertex, 0, width - 1)
    columns = (world, normals, *(table[:, slots] for table in per_slot))
    if textures is not None:
        uv = mesh.uvs if mesh.uvs is not None else np.zeros((vertices, 2), np.float32)
        columns = (*columns[:4], np.broadcast_to(uv, (k, vertices, 2)), columns[4])
    if finite.all():
        return tuple(c.reshape(k * vertices, -1) for c in columns)
    keep = np.repeat(finite, 3, axis=1)
    return tuple(c[keep] for c in columns)


def flatten_instances(scene: Scene, warnings: list[str]) -> WorldGeometry:
    """All instances in world space, with each triangle's material spread to its vertices.
    Instances of one mesh are transformed together (the order is by each mesh's first
    instance).

    Triangles whose world positions are not finite (NaN/Inf vertices or transforms) are left
    out, with one warning per instance."""
    groups: dict[int, list[Instance]] = {}
    for inst in scene.instances:
        if inst.mesh.triangle_count:
            groups.setdefault(id(inst.mesh), []).append(inst)
    tables: dict[tuple, tuple[np.ndarray, ...]] = {}
    textured = any(m.base_color_texture or m.emission_texture
                   for members in groups.values() for inst in members for m in inst.materials)
    textures = tex.TextureSet() if textured else None
    parts = [_flatten_group(members, tables, warnings, textures) for members in groups.values()]
    parts = [p for p in parts if len(p[0])]
    if not parts:
        empty = np.zeros((0, 3), dtype=np.float32)
        return WorldGeometry(empty, empty, empty, empty)
    columns = [np.ascontiguousarray(np.concatenate(c), dtype=np.float32)
               for c in zip(*parts, strict=True)]
    if textures is None or not textures.textures:
        return WorldGeometry(*columns[:4])
    return WorldGeometry(*columns, textures=textures.textures)


def bounding_sphere(positions: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre and radius of a sphere around all points (box-centred; radius > 0)."""
    if len(positions) == 0:
        return np.zeros(3), 1.0
    low, high = positions.min(axis=0).astype(np.float64), positions.max(axis=0).astype(np.float64)
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
        world = _transform_points(light.matrix, local)
        axis_x, axis_y = light.matrix[:3, 0], light.matrix[:3, 1]
        area = light.local_area * float(np.linalg.norm(np.cross(axis_x, axis_y)))
        if area <= 0:
            continue
        facing = -light.matrix[:3, 2] / max(np.linalg.norm(light.matrix[:3, 2]), 1e-300)
        radiance = np.asarray(light.color) * light.power / (np.pi * area)
        radiance = np.clip(np.nan_to_num(radiance), 0.0, MAX_SHAPE_RADIANCE)
        positions.append(world)
        normals.append(np.repeat(facing[None], len(world), axis=0))
        emission.append(np.repeat(radiance[None], len(world), axis=0))
    if not positions:
        empty = np.zeros((0, 3), dtype=np.float32)
        return WorldGeometry(empty, empty, empty, empty)
    pos = np.concatenate(positions).astype(np.float32)
    return WorldGeometry(pos, np.concatenate(normals).astype(np.float32),
                         np.zeros_like(pos), np.concatenate(emission).astype(np.float32))
