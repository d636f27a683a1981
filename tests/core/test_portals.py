"""Cycles' light portals: world light paths start in the opening the portal covers, so every
path enters the room, and the light they bring equals what the sky sends through the opening."""

from __future__ import annotations

import numpy as np
import pytest

from addon.core.scene.geometry import bounding_sphere, flatten_instances
from addon.core.scene.model import Instance, Light, LightKind, Material, Mesh, Scene, World
from addon.core.settings import Settings
from addon.core.transport.vpl import generate_vpls
from tests.core.builders import translation

ALBEDO, SKY, HOLE = 0.5, 2.0, 1.0  # a HOLE × HOLE skylight in the middle of a 4 × 4 × 2 room


def rectangle(corner, u, v) -> np.ndarray:
    """Two triangles of the rectangle corner + [0,1]·u + [0,1]·v (front face: u × v)."""
    a, u, v = (np.asarray(x, dtype=np.float32) for x in (corner, u, v))
    return np.array([a, a + u, a + u + v, a, a + u + v, a + v])


def room() -> Mesh:
    """Floor, four walls and a ceiling with the skylight, every face towards the inside."""
    h = HOLE / 2
    faces = [rectangle((-2, -2, 0), (4, 0, 0), (0, 4, 0)),  # floor, up
             rectangle((-2, -2, 0), (0, 0, 2), (4, 0, 0)),  # y = -2
             rectangle((2, 2, 0), (0, 0, 2), (-4, 0, 0)),  # y = +2
             rectangle((-2, 2, 0), (0, 0, 2), (0, -4, 0)),  # x = -2
             rectangle((2, -2, 0), (0, 0, 2), (0, 4, 0))]  # x = +2
    for corner, u, v in [((-2, -2, 2), (0, 2 - h, 0), (4, 0, 0)),  # ceiling around the hole,
                         ((-2, h, 2), (0, 2 - h, 0), (4, 0, 0)),  # facing down
                         ((-2, -h, 2), (0, HOLE, 0), (2 - h, 0, 0)),
                         ((h, -h, 2), (0, HOLE, 0), (2 - h, 0, 0))]:
        faces.append(rectangle(corner, u, v))
    positions = np.concatenate(faces)
    normals = np.cross(positions[1::3] - positions[0::3], positions[2::3] - positions[0::3])
    normals = np.repeat(normals / np.linalg.norm(normals, axis=1, keepdims=True), 3, axis=0)
    return Mesh("room", positions, normals.astype(np.float32),
                np.zeros(len(positions) // 3, np.int32))


def first_bounce_inside(renderer, portals: list[Light], paths: int) -> tuple[float, float]:
    """(share of first-bounce VPLs inside the room, their summed intensity there)."""
    scene = Scene([Instance(room(), np.eye(4), [Material("wall", (ALBEDO,) * 3)])], [],
                  World(color=(SKY,) * 3), portals=portals)
    geometry = flatten_instances(scene, [])
    centre, radius = bounding_sphere(geometry.positions)
    renderer.tracer.upload(geometry.positions.reshape(-1, 3, 3))
    vpls = generate_vpls(scene, geometry, Settings(vpl_count=paths, bounces=1, seed=3),
                         renderer.tracer, centre, radius)
    inside = np.einsum("ij,ij->i", vpls.normal, np.array([0, 0, 1.0]) - vpls.position) > 0
    return float(inside.mean()), float(vpls.intensity[inside, 0].sum())


def test_every_portal_path_enters_and_brings_the_sky_through_the_opening(renderer):
    portal = Light("skylight", LightKind.AREA, translation(0, 0, 2), size_x=HOLE)
    share, intensity = first_bounce_inside(renderer, [portal], 1024)
    # Flux through the opening: π L A; its first hits hold intensity Φ ρ / π = ρ L A in all.
    assert share == 1.0
    assert intensity == pytest.approx(ALBEDO * SKY * HOLE**2, rel=1e-4)


def test_without_a_portal_few_paths_enter_but_bring_the_same_light(renderer):
    share, intensity = first_bounce_inside(renderer, [], 32768)
    assert share < 0.05  # most world paths light the roof and the outer walls
    assert intensity == pytest.approx(ALBEDO * SKY * HOLE**2, rel=0.1)
