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
    """Flattened triangles: 3 vertices per triangle, attributes per vertex (float32), stored
    interleaved as the GPU reads them; ``positions``, ``normals``, ``albedo`` and ``emission``
    are views of ``vertices``.

    Textured materials have their textures' average colour in ``albedo`` and ``emission``
    (the per-triangle values light sampling and path termination use); ``texture_vertices``
    (views ``uv`` and ``texture``: albedo layer, emission layer — -1 for none — and emission
    strength) is set only when some material has a texture."""

    vertices: np.ndarray  # (V, 12) C-contiguous: position, normal, albedo, emission
    texture_vertices: np.ndarray | None = None  # (V, 5) C-contiguous: uv, texture attribute
    textures: list[Texture] = field(default_factory=list)

    @classmethod
    def from_columns(cls, positions: np.ndarray, normals: np.ndarray, albedo: np.ndarray,
                     emission: np.ndarray) -> WorldGeometry:
        """Untextured geometry from its four (V, 3) vertex attributes."""
        return cls(np.hstack([positions, normals, albedo, emission]).astype(np.float32))

    @property
    def positions(self) -> np.ndarray:
        return self.vertices[:, 0:3]

    @property
    def normals(self) -> np.ndarray:
        return self.vertices[:, 3:6]

    @property
    def albedo(self) -> np.ndarray:
        return self.vertices[:, 6:9]

    @property
    def emission(self) -> np.ndarray:
        return self.vertices[:, 9:12]

    @property
    def uv(self) -> np.ndarray | None:
        return None if self.texture_vertices is None else self.texture_vertices[:, 0:2]

    @property
    def texture(self) -> np.ndarray | None:
        return None if self.texture_vertices is None else self.texture_vertices[:, 2:5]

    @property
    def vertex_count(self) -> int:
        return len(self.vertices)

    @property
    def has_textures(self) -> bool:
        """Whether the g-buffer needs its texture path (some material has a texture)."""
        return bool(self.textures)

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


def _instance_tables(members: list[Instance], width: int, tables: dict, warnings: list[str],
                     textures: tex.TextureSet | None) -> list[np.ndarray]:
    """Albedo, emission and, with ``textures``, the texture attribute per instance and mesh
    slot, (n, width, 3) float32: n = 1 when all instances share their materials (it broadcasts
    over them), else one row per instance. Slots past an instance's materials take its last."""
    index_of: dict[tuple, int] = {}
    distinct: list[list[Material]] = []
    index = np.empty(len(members), np.intp)
    for row, inst in enumerate(members):
        key = tuple(id(m) for m in inst.materials)
        if key not in index_of:
            index_of[key] = len(distinct)
            distinct.append(inst.materials)
        index[row] = index_of[key]
    per_slot = [np.zeros((len(distinct), width, 3), np.float32)
                for _ in range(2 if textures is None else 3)]
    for row, (key, materials) in enumerate(zip(index_of, distinct, strict=True)):
        if key not in tables:
            tables[key] = _material_tables(materials or [Material("(no material)")], warnings,
                                           textures)
        clipped = np.minimum(np.arange(width), len(tables[key][0]) - 1)
        for table, values in zip(per_slot, tables[key], strict=True):
            table[row] = values[clipped]
    return per_slot if len(distinct) == 1 else [table[index] for table in per_slot]


def _per_corner(table: np.ndarray, slots: np.ndarray) -> np.ndarray:
    """Per-slot rows (n, width, c) as (n, T, 1, c), to broadcast over triangles' corners."""
    return table[:, :, None] if table.shape[1] == 1 else table[:, slots, None]


def _flatten_group(members: list[Instance], tables: dict, warnings: list[str],
                   textures: tex.TextureSet | None, out: np.ndarray,
                   texture_out: np.ndarray | None) -> np.ndarray | None:
    """Write world positions, normals, albedo and emission of every instance of one shared mesh
    into ``out`` (k·V, 12), transformed together in float32 as the GPU gets them, and with
    ``textures`` UVs and the texture attribute into ``texture_out`` (k·V, 5). Returns the mask
    of vertices on finite triangles, or None when all are finite."""
    mesh = members[0].mesh
    k, vertices, triangles = len(members), len(mesh.positions), mesh.triangle_count
    block = out.reshape(k, vertices, 12)
    records = block.view("V12")  # (k, V, 4): position, normal, albedo, emission
    matrices = np.stack([inst.matrix for inst in members]).astype(np.float64)
    identity = k == 1 and np.array_equal(matrices[0], np.eye(4))
    normals = mesh.normals if np.isfinite(mesh.normals).all() else np.nan_to_num(mesh.normals)
    normals = normals[None]
    with np.errstate(all="ignore"):
        if identity:  # the identity's normal matrix is the identity too
            world = mesh.positions[None]
        else:
            world = np.matmul(mesh.positions.astype(np.float32, copy=False)[None],
                              matrices[:, :3, :3].transpose(0, 2, 1).astype(np.float32))
            world += matrices[:, None, :3, 3].astype(np.float32)
            normal_matrices = _normal_matrices(np.nan_to_num(matrices[:, :3, :3]))
            normals = np.matmul(normals, normal_matrices.transpose(0, 2, 1).astype(np.float32))
        x, y, z = normals[..., 0], normals[..., 1], normals[..., 2]
        length = np.sqrt(x * x + y * y + z * z)  # np.linalg.norm's sums, without its reduce
        normals = normals / length[..., None]
        positive = length > 0
        if not positive.all():
            normals[~positive] = 0.0
    # contiguous results copied in as 12-byte records: numpy's float loops over the 3 floats
    # of each strided vertex take about twice as long
    records[..., 0] = np.ascontiguousarray(world, np.float32).view("V12")[..., 0]
    records[..., 1] = normals.view("V12")[..., 0]
    keep = None
    if not np.isfinite(world).all():
        finite = np.isfinite(world).all(axis=2).reshape(k, -1, 3).all(axis=2)
        for row in np.flatnonzero(~finite.all(axis=1)):
            warnings.append(f"mesh '{mesh.name}': {int((~finite[row]).sum())} of "
                            f"{finite.shape[1]} triangles have NaN/Inf positions and were left out")
        keep = np.repeat(finite, 3, axis=1).ravel()
    slots = np.clip(mesh.material_slots, 0, None)
    width = int(slots.max(initial=0)) + 1
    per_slot = _instance_tables(members, width, tables, warnings, textures)
    # albedo and emission in one pass, copied as 24-byte records (numpy's float loop over the
    # 6 floats of each vertex would take about twice as long)
    colours = np.ascontiguousarray(np.concatenate(per_slot[:2], axis=2)).view("V24")
    block.view("V24").reshape(k, triangles, 3, 2)[..., 1] = _per_corner(colours, slots)[..., 0]
    if texture_out is not None:
        stream = texture_out.reshape(k, vertices, 5)
        stream[..., 0:2] = mesh.uvs if mesh.uvs is not None else 0.0
        stream.reshape(k, triangles, 3, 5)[..., 2:5] = _per_corner(per_slot[2], slots)
    return keep


def flatten_instances(scene: Scene, warnings: list[str]) -> WorldGeometry:
    """All instances in world space, with each triangle's material spread to its vertices,
    written straight into the interleaved vertex arrays. Instances of one mesh are transformed
    together (the order is by each mesh's first instance).

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
    sizes = [len(members) * len(members[0].mesh.positions) for members in groups.values()]
    vertices = np.empty((sum(sizes), 12), np.float32)
    stream = np.empty((sum(sizes), 5), np.float32) if textured else None
    masks, start = [], 0
    for members, size in zip(groups.values(), sizes, strict=True):
        part = slice(start, start + size)
        masks.append(_flatten_group(members, tables, warnings, textures, vertices[part],
                                    None if stream is None else stream[part]))
        start += size
    if any(mask is not None for mask in masks):
        keep = np.concatenate([np.ones(size, bool) if mask is None else mask
                               for mask, size in zip(masks, sizes, strict=True)])
        vertices = vertices[keep]
        stream = None if stream is None else stream[keep]
    if textures is None or not textures.textures:
        return WorldGeometry(vertices)
    return WorldGeometry(vertices, stream, textures.textures)


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
        return WorldGeometry(np.zeros((0, 12), np.float32))
    pos = np.concatenate(positions)
    return WorldGeometry.from_columns(pos, np.concatenate(normals), np.zeros_like(pos),
                                      np.concatenate(emission))
