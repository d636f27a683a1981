"""World-space triangle data for the GPU: instances flattened into one vertex stream with
per-vertex material values, visible light shapes, and the scene's bounding sphere."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .scene import Instance, Light, LightKind, Material, Scene

DISK_SEGMENTS = 48


@dataclass
class WorldGeometry:
    """Flattened triangles: 3 vertices per triangle, attributes per vertex (float32)."""

    positions: np.ndarray  # (V, 3)
    normals: np.ndarray  # (V, 3)
    albedo: np.ndarray  # (V, 3)
    emission: np.ndarray  # (V, 3)

    @property
    def vertex_count(self) -> int:
        return len(self.positions)

    def interleaved(self) -> np.ndarray:
        """Vertex data as one (V, 12) float32 array: position, normal, albedo, emission."""
        return np.ascontiguousarray(np.hstack(
            [self.positions, self.normals, self.albedo, self.emission]), dtype=np.float32)


def _transform_points(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    return points @ matrix[:3, :3].T + matrix[:3, 3]


def _transform_normals(matrix: np.ndarray, normals: np.ndarray) -> np.ndarray:
    linear = matrix[:3, :3]
    det = np.linalg.det(linear)
    normal_matrix = np.linalg.inv(linear).T if abs(det) > 1e-300 else linear
    out = normals @ normal_matrix.T
    length = np.linalg.norm(out, axis=1, keepdims=True)
    return np.divide(out, length, out=np.zeros_like(out), where=length > 0)


MAX_ALBEDO = 1.0  # a diffuse surface cannot reflect more than it receives


def _albedo_table(inst: Instance, warnings: list[str]) -> np.ndarray:
    """Base colours per material slot, capped to [0, MAX_ALBEDO] with one warning per material
    (Blender allows colours above 1; with them every bounce would add energy)."""
    materials = inst.materials or [Material("(no material)")]
    table = np.array([m.base_color for m in materials], dtype=np.float64)
    table = np.where(np.isfinite(table), table, 0.0)
    for material, row in zip(materials, table, strict=True):
        if row.max() > MAX_ALBEDO or row.min() < 0:
            message = (f"material '{material.name}': base colour {tuple(np.round(row, 3))} "
                       f"capped to [0, {MAX_ALBEDO:g}] (energy would grow with every bounce)")
            if message not in warnings:
                warnings.append(message)
    return np.clip(table, 0.0, MAX_ALBEDO)


def flatten_instances(scene: Scene, warnings: list[str]) -> WorldGeometry:
    """All instances in world space, with each triangle's material spread to its vertices.

    Triangles whose world positions are not finite (NaN/Inf vertices or transforms) are left
    out, with one warning per instance."""
    parts: list[tuple[np.ndarray, ...]] = []
    for inst in scene.instances:
        mesh = inst.mesh
        if mesh.triangle_count == 0:
            continue
        with np.errstate(all="ignore"):
            world = _transform_points(inst.matrix, mesh.positions.astype(np.float64))
        finite = np.isfinite(world).all(axis=1).reshape(-1, 3).all(axis=1)
        if not finite.all():
            warnings.append(f"mesh '{mesh.name}': {int((~finite).sum())} of {len(finite)} "
                            f"triangles have NaN/Inf positions and were left out")
            if not finite.any():
                continue
        albedo_table = _albedo_table(inst, warnings)
        emission_table = np.array([m.emission for m in inst.materials] or [(0.0, 0.0, 0.0)],
                                  dtype=np.float64)
        emission_table = np.where(np.isfinite(emission_table), np.maximum(emission_table, 0), 0)
        slots = np.clip(mesh.material_slots, 0, len(albedo_table) - 1)
        keep = np.repeat(finite, 3)
        per_vertex = np.repeat(slots, 3)[keep]
        normals = np.nan_to_num(mesh.normals[keep].astype(np.float64))
        parts.append((
            world[keep],
            _transform_normals(inst.matrix, normals),
            albedo_table[per_vertex],
            emission_table[per_vertex],
        ))
    if not parts:
        empty = np.zeros((0, 3), dtype=np.float32)
        return WorldGeometry(empty, empty, empty, empty)
    columns = [np.concatenate(c).astype(np.float32) for c in zip(*parts, strict=True)]
    return WorldGeometry(*columns)


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
        positions.append(world)
        normals.append(np.repeat(facing[None], len(world), axis=0))
        emission.append(np.repeat(radiance[None], len(world), axis=0))
    if not positions:
        empty = np.zeros((0, 3), dtype=np.float32)
        return WorldGeometry(empty, empty, empty, empty)
    pos = np.concatenate(positions).astype(np.float32)
    return WorldGeometry(pos, np.concatenate(normals).astype(np.float32),
                         np.zeros_like(pos), np.concatenate(emission).astype(np.float32))
