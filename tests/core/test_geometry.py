"""Flattening: indexed meshes give exactly their per-corner equivalents, each triangle finds
its material row, and non-finite points drop only the triangles that use them."""

from __future__ import annotations

import numpy as np
import pytest

from addon.core.scene.geometry import flatten_instances
from addon.core.scene.model import Instance, Material, Mesh, Scene
from addon.core.scene.textures import NO_TEXTURE


def _indexed_mesh(rng: np.random.Generator, points: int = 30, triangles: int = 50) -> Mesh:
    """A random mesh with shared points, one normal per triangle (a flat mesh: Blender's FACE
    domain), per-corner UVs, and three material slots."""
    position_index = rng.integers(0, points, 3 * triangles).astype(np.int32)
    normals = rng.normal(size=(triangles, 3)).astype(np.float32)
    return Mesh("indexed", rng.normal(size=(points, 3)).astype(np.float32), normals,
                rng.integers(0, 3, triangles).astype(np.int32),
                rng.random((3 * triangles, 2)).astype(np.float32), position_index,
                np.repeat(np.arange(triangles, dtype=np.int32), 3), None)


def _soup(mesh: Mesh) -> Mesh:
    return Mesh("soup", mesh.corner_positions(), mesh.corner_normals(), mesh.material_slots,
                mesh.corner_uvs())


def _transforms() -> list[np.ndarray]:
    turned = np.eye(4)
    turned[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
    turned[:3, 3] = (1.0, 2.0, 3.0)
    mirrored = np.diag([-1.0, 2.0, 0.5, 1.0])
    return [np.eye(4), turned, mirrored]


def _materials() -> tuple[list[Material], list[Material]]:
    red, green = Material("red", (0.8, 0.1, 0.1)), Material("green", (0.1, 0.8, 0.1))
    lamp = Material("lamp", (0.0, 0.0, 0.0), (5.0, 4.0, 3.0))
    return [red, green, lamp], [green]


def _scene(mesh: Mesh) -> Scene:
    full, short = _materials()
    lists = [full, full, short]
    return Scene([Instance(mesh, m, materials) for m, materials in
                  zip(_transforms(), lists, strict=True)])


def test_an_indexed_mesh_flattens_exactly_like_its_per_corner_soup():
    mesh = _indexed_mesh(np.random.default_rng(1))
    indexed, soup = (flatten_instances(_scene(m), []) for m in (mesh, _soup(mesh)))
    for name in ("positions", "normals", "albedo", "emission"):
        np.testing.assert_array_equal(getattr(indexed, name), getattr(soup, name), err_msg=name)
    assert indexed.triangle_count == 3 * mesh.triangle_count
    assert indexed.positions.flags.c_contiguous and indexed.normals.flags.c_contiguous


def test_each_triangle_takes_its_slots_material_and_lists_share_rows():
    mesh = _indexed_mesh(np.random.default_rng(2))
    geometry = flatten_instances(_scene(mesh), [])
    full, short = _materials()
    assert len(geometry.materials) == len(full) + len(short)  # the two instances of `full` share
    triangles = mesh.triangle_count
    for instance, materials in enumerate([full, full, short]):
        rows = slice(instance * triangles, (instance + 1) * triangles)
        # slots past a list's end take its last material, as in Blender
        expected = [materials[min(slot, len(materials) - 1)] for slot in mesh.material_slots]
        np.testing.assert_allclose(geometry.albedo[rows], [m.base_color for m in expected])
        np.testing.assert_allclose(geometry.emission[rows], [m.emission for m in expected])
    assert np.all(geometry.materials[:, 8:10] == NO_TEXTURE)
    assert not geometry.has_textures and geometry.uv is None


@pytest.mark.parametrize("used", [True, False])
def test_a_non_finite_point_drops_only_the_triangles_using_it(used):
    rng = np.random.default_rng(3)
    mesh = _indexed_mesh(rng)
    nan_point = int(mesh.position_index[0]) if used else len(mesh.positions)
    if not used:  # an extra point no triangle uses
        mesh.positions = np.vstack([mesh.positions, np.zeros((1, 3), np.float32)])
    mesh.positions[nan_point] = np.nan
    warnings: list[str] = []
    geometry = flatten_instances(Scene([Instance(mesh, np.eye(4), _materials()[0])]), warnings)
    users = (mesh.position_index.reshape(-1, 3) == nan_point).any(axis=1)
    assert geometry.triangle_count == mesh.triangle_count - int(users.sum())
    assert np.isfinite(geometry.positions).all()
    assert len(warnings) == int(used)
    if used:
        assert f"{int(users.sum())} of {mesh.triangle_count} triangles" in warnings[0]
        kept = flatten_instances(Scene([Instance(_soup(mesh), np.eye(4), _materials()[0])]), [])
        np.testing.assert_array_equal(geometry.positions, kept.positions)
        np.testing.assert_array_equal(geometry.albedo, kept.albedo)


def test_runs_of_shared_meshes_are_listed_after_dropped_triangles():
    rng = np.random.default_rng(4)
    single, shared, broken = (_indexed_mesh(rng, triangles=n) for n in (7, 11, 5))
    broken.positions[int(broken.position_index[0])] = np.nan  # its copies lose triangles
    materials = _materials()[0]
    scene = Scene([Instance(mesh, matrix, materials) for mesh, matrix in [
        (broken, np.eye(4)), (shared, np.eye(4)), (single, np.eye(4)), (broken, np.eye(4)),
        *[(shared, matrix) for matrix in _transforms()]]])
    geometry = flatten_instances(scene, [])
    kept = broken.triangle_count - int(
        (broken.position_index.reshape(-1, 3) == broken.position_index[0]).any(axis=1).sum())
    assert geometry.instanced.tolist() == [[2 * kept, 4, 11]]  # by each mesh's first instance
    first = 3 * 2 * kept
    copies = geometry.positions[first:first + 3 * 4 * 11].reshape(4, 11 * 3, 3)
    np.testing.assert_array_equal(copies[0], shared.corner_positions())
    assert geometry.triangle_count == 2 * kept + 4 * 11 + 7


def test_triangles_of_clear_materials_are_left_out_with_one_note():
    """Instances of one mesh whose lists make a slot clear in some of them: those lose the
    slot's triangles (and leave the shared-mesh runs), the others keep all."""
    mesh = _indexed_mesh(np.random.default_rng(5))
    glass = Material("glass", (0.0, 0.0, 0.0), transmission=(0.9, 0.9, 0.9))  # no Fresnel
    assert glass.is_clear and not Material("veil", (0.4,) * 3, transmission=(0.5,) * 3).is_clear
    full = _materials()[0]
    glazed = [full[0], glass, full[2]]
    scene = Scene([Instance(mesh, m, materials) for m, materials in
                   zip(_transforms(), [full, glazed, full], strict=True)])
    notes: list[str] = []
    geometry = flatten_instances(scene, [], notes)
    clear = int((mesh.material_slots == 1).sum())
    assert geometry.triangle_count == 3 * mesh.triangle_count - clear
    assert len(notes) == 1 and notes[0].startswith(
        f"{clear} triangles of clear material(s) 'glass' let light straight through")
    assert geometry.clear_triangles.shape == (clear, 3, 3)
    np.testing.assert_allclose(geometry.clear_transmission, [[0.9, 0.9, 0.9, 0.0]] * clear,
                               rtol=1e-6)
    turned = _transforms()[1]
    corners = mesh.corner_positions().reshape(-1, 3, 3)[mesh.material_slots == 1]
    np.testing.assert_allclose(geometry.clear_triangles,
                               corners @ turned[:3, :3].T + turned[:3, 3], atol=1e-5)
    assert 4 not in geometry.triangle_material  # the glazed list's rows: 3, 4 (glass), 5
    plain = flatten_instances(Scene([Instance(mesh, m, full) for m in _transforms()]), [])
    kept = mesh.triangle_count
    np.testing.assert_array_equal(geometry.positions[:3 * kept], plain.positions[:3 * kept])
    assert geometry.instanced.size == 0


def test_normals_are_unit_and_face_the_same_way_through_any_transform():
    """Similarities (turned, uniformly scaled, mirrored: their normals are not normalised
    again) and general maps (sheared, squashed) give each triangle's unit normal, on the side
    its normal was on (a mirror reverses the winding, not the side)."""
    rng = np.random.default_rng(5)
    turn = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    linears = {"turned and scaled": 3.0 * turn, "mirrored and scaled": 0.01 * turn @ np.diag(
        [-1.0, 1.0, 1.0]), "sheared": np.array([[1.0, 0.7, 0.0], [0.0, 1.0, 0.0], [0, 0, 2]]),
               "squashed": np.diag([1.0, 1.0, 1e-3])}
    points = rng.normal(size=(3, 3)).astype(np.float32)
    face = np.cross(points[1] - points[0], points[2] - points[0])
    mesh = Mesh("one", points, (face / np.linalg.norm(face))[None].astype(np.float32),
                np.zeros(1, np.int32), None, None, np.zeros(3, np.int32), None)
    for name, linear in linears.items():
        matrix = np.eye(4)
        matrix[:3, :3] = linear
        geometry = flatten_instances(Scene([Instance(mesh, matrix, [])] * 2), [])
        world = geometry.positions[:3].astype(np.float64)
        winding = np.cross(world[1] - world[0], world[2] - world[0])
        expected = np.sign(np.linalg.det(linear)) * winding / np.linalg.norm(winding)
        np.testing.assert_allclose(geometry.normals[:6], np.tile(expected, (6, 1)), atol=2e-5,
                                   err_msg=name)
