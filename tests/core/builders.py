"""Small scenes built in code for the core (bpy-free) tests."""

from __future__ import annotations

import math

import numpy as np

from addon.core.frame.reuse import settings_key
from addon.core.frame.vpl_stage import INCREMENTAL_FIELDS
from addon.core.scene.geometry import bounding_sphere, flatten_instances
from addon.core.scene.model import Camera, Instance, Light, LightKind, Material, Mesh, Scene, World
from addon.core.settings import Settings
from addon.core.transport.incremental import IncrementalVPLs
from addon.core.transport.vpl import VPLs, generate_vpls


def quad(half_x: float, half_y: float, z: float = 0.0, flip: bool = False) -> Mesh:
    """An axis-aligned rectangle in the XY plane at height z, normal +Z (or -Z)."""
    p = np.array([[-half_x, -half_y, z], [half_x, -half_y, z], [half_x, half_y, z],
                  [-half_x, -half_y, z], [half_x, half_y, z], [-half_x, half_y, z]],
                 dtype=np.float32)
    if flip:
        p = p[[0, 2, 1, 3, 5, 4]]
    normal = np.array([0, 0, -1 if flip else 1], dtype=np.float32)
    return Mesh("quad", p, np.tile(normal, (6, 1)), np.zeros(2, dtype=np.int32))


def grid(cells: int, size: float = 1.0) -> Mesh:
    """A size × size square centred at the origin of cells × cells quads (2 triangles each) in
    the XY plane, normal +Z."""
    edge = np.linspace(-size / 2, size / 2, cells + 1, dtype=np.float32)
    x, y = np.meshgrid(edge, edge)
    corner = np.stack([x, y, np.zeros_like(x)], axis=-1)
    a, b = corner[:-1, :-1].reshape(-1, 3), corner[:-1, 1:].reshape(-1, 3)
    c, d = corner[1:, 1:].reshape(-1, 3), corner[1:, :-1].reshape(-1, 3)
    positions = np.stack([a, b, c, a, c, d], axis=1).reshape(-1, 3)
    normals = np.zeros_like(positions)
    normals[:, 2] = 1.0
    return Mesh("grid", positions, normals, np.zeros(len(positions) // 3, np.int32))


def translation(x: float, y: float, z: float) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def rotation_x(angle: float) -> np.ndarray:
    m = np.eye(4)
    c, s = np.cos(angle), np.sin(angle)
    m[1:3, 1:3] = [[c, -s], [s, c]]
    return m


def top_down_camera(size: int = 64, extent: float = 6.0, height: float = 5.0) -> Camera:
    """Orthographic camera at z = height looking down -Z over [-extent/2, extent/2]²."""
    view = translation(0, 0, -height)
    near, far = 0.01, 100.0
    projection = np.array([[2 / extent, 0, 0, 0], [0, 2 / extent, 0, 0],
                           [0, 0, -2 / (far - near), -(far + near) / (far - near)],
                           [0, 0, 0, 1]])
    return Camera(view, projection, size, size, is_orthographic=True)


def pixel_centres(size: int = 64, extent: float = 6.0) -> tuple[np.ndarray, np.ndarray]:
    """World x, y of each pixel centre of top_down_camera (row 0 at the bottom)."""
    xs = (np.arange(size) + 0.5) / size * extent - extent / 2
    return np.meshgrid(xs, xs)


def floor_scene(lights: list[Light], albedo: float = 0.8, extra: list[Instance] | None = None,
                world: World | None = None, size: int = 64) -> Scene:
    """A 10 m floor at z = 0 seen from above, with the given lights."""
    floor = Instance(quad(5, 5), np.eye(4), [Material("floor", (albedo,) * 3)])
    return Scene([floor, *(extra or [])], lights, world or World(), top_down_camera(size))


def light(kind: LightKind, matrix: np.ndarray, **kwargs) -> Light:
    return Light(kind.value.lower(), kind, matrix, **kwargs)


def icosphere(radius: float, subdivisions: int) -> Mesh:
    """A geodesic sphere (flat-shaded triangles) of the given circumradius."""
    t = (1 + 5**0.5) / 2
    vertices = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                         [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1],
                         [-t, 0, 1]], dtype=np.float64)
    faces = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9],
                      [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2],
                      [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10],
                      [8, 6, 7], [9, 8, 1]])
    tri = vertices[faces]
    tri /= np.linalg.norm(tri, axis=-1, keepdims=True)
    for _ in range(subdivisions):
        a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
        ab, bc, ca = [(p + q) / np.linalg.norm(p + q, axis=-1, keepdims=True)
                      for p, q in ((a, b), (b, c), (c, a))]
        tri = np.concatenate([np.stack(f, axis=1) for f in
                              ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
    positions = (tri * radius).reshape(-1, 3).astype(np.float32)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    return Mesh("sphere", positions, np.repeat(normal, 3, axis=0).astype(np.float32),
                np.zeros(len(tri), dtype=np.int32))


def inside_sphere_camera(size: int = 32) -> Camera:
    """A perspective camera at the origin looking down -Z with a 90° field of view."""
    near, far = 0.01, 100.0
    projection = np.array([[1, 0, 0, 0], [0, 1, 0, 0],
                           [0, 0, -(far + near) / (far - near), -2 * far * near / (far - near)],
                           [0, 0, -1, 0]])
    return Camera(np.eye(4), projection, size, size)


def profile_text(upward: bool = False) -> str:
    """A type C profile over the whole sphere, 10° apart vertically and 45° horizontally:
    a lobe straight down (straight up with ``upward``) that leans towards 0° of horizontal
    angle, and a weaker sideways light that differs between all four quadrants."""
    v_angles = list(range(0, 181, 10))
    h_angles = list(range(0, 361, 45))
    rows = []
    for h in h_angles:
        lean = 0.6 * math.cos(math.radians(h)) + 0.25 * math.sin(math.radians(h))
        row = []
        for v in v_angles:
            down = max(math.cos(math.radians(180 - v if upward else v)), 0.0)
            row.append(1000.0 * down**2 * (1 + lean * math.sin(math.radians(v)))
                       + 150.0 * math.sin(math.radians(v))**2 * (1 + 0.5 * lean))
        rows.append(" ".join(f"{c:.2f}" for c in row))
    return "\n".join(["IESNA:LM-63-2002", "[TEST] VPL GI test profile", "TILT=NONE",
                      f"1 -1 1 {len(v_angles)} {len(h_angles)} 1 2 0 0 0", "1 1 120",
                      " ".join(map(str, v_angles)), " ".join(map(str, h_angles)), *rows, ""])


def downlight_text() -> str:
    """A rotationally symmetric downlight (one horizontal angle, the commonest kind of file):
    a lobe straight down over a floor of 50 cd, 5° apart, nothing above the horizon."""
    v_angles = list(range(0, 91, 5))
    values = " ".join(f"{1000 * math.cos(math.radians(v))**1.5 + 50:.2f}" for v in v_angles)
    return "\n".join(["IESNA:LM-63-2002", "[TEST] VPL GI test downlight", "TILT=NONE",
                      f"1 -1 1 {len(v_angles)} 1 1 2 0 0 0", "1 1 100",
                      " ".join(map(str, v_angles)), "0", values, ""])


def traced_vpls(renderer, scene: Scene, settings: Settings) -> VPLs:
    """The scene's VPLs traced by the renderer's ray tracer: fresh light paths, or with
    ``settings.incremental`` Incremental Instant Radiosity's first frame."""
    geometry = flatten_instances(scene, [])
    centre, radius = bounding_sphere(geometry.positions)
    renderer.tracer.upload(geometry.positions.reshape(-1, 3, 3),
                           blocker_set=geometry.blocker_set)
    if settings.incremental:
        return IncrementalVPLs().update(scene, geometry, settings, renderer.tracer, centre,
                                        radius, shape_version=0,
                                        key=settings_key(settings, INCREMENTAL_FIELDS))
    return generate_vpls(scene, geometry, settings, renderer.tracer, centre, radius)
