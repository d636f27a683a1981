"""Indexed mesh export: corner positions, normals, UVs and material slots bit for bit those of a
straightforward per-corner reading through RNA (Blender's triangles and quad split, triangles
with NaN/Inf or zero area left out with one warning each), for every normal domain."""

from __future__ import annotations

import numpy as np

from addon.export import _quad_dot, _zero_area, export_scene
from tests.blender.test_export import add_mesh, new_scene

NAN, INF = float("nan"), float("inf")


def _rows(values) -> np.ndarray:
    return np.array([tuple(v) for v in values], dtype=np.float32)


def reference(mesh, label: str) -> tuple[dict[str, np.ndarray | None], list[str]]:
    """Per-corner arrays of an evaluated mesh, read item by item: triangle faces, then quads
    split by is_quad_flip_v3_first_third_fast as np.cross rounds it, then Blender's loop
    triangles of the n-gons."""
    co = _rows(v.co for v in mesh.vertices)
    corner_vert = [loop.vertex_index for loop in mesh.loops]
    faces = [range(p.loop_start, p.loop_start + p.loop_total) for p in mesh.polygons]
    triangles = [(tuple(f), i) for i, f in enumerate(faces) if len(f) == 3]
    for i, f in enumerate(faces):
        if len(f) == 4:
            v0, v1, v2, v3 = (co[corner_vert[c]] for c in f)
            d12, d13, d14 = v1 - v0, v2 - v0, v3 - v0
            flip = (np.cross(d12, d13) * np.cross(d14, d13)).sum() > 0
            split = [(0, 1, 3), (1, 2, 3)] if flip else [(0, 1, 2), (0, 2, 3)]
            triangles += [(tuple(f[k] for k in t), i) for t in split]
    mesh.calc_loop_triangles()
    triangles += [(tuple(t.loops), t.polygon_index) for t in mesh.loop_triangles
                  if len(faces[t.polygon_index]) > 4]
    normals = _rows(n.vector for n in mesh.corner_normals)
    layer = next((layer for layer in mesh.uv_layers if layer.active_render), None)
    uvs = None if layer is None else np.array([d.uv for d in layer.data], dtype=np.float32)
    problems, kept, count = [], [], len(triangles)
    finite = [t for t in triangles if np.isfinite(co[[corner_vert[c] for c in t[0]]]).all()]
    if len(finite) < count:
        problems.append(f"{label}: {count - len(finite)} of {count} triangles have NaN/Inf "
                        f"vertices and were left out")
    for corners, face in finite:
        p0, p1, p2 = (co[corner_vert[c]] for c in corners)
        if np.cross(p1 - p0, p2 - p0).any():
            kept.append((corners, face))
    if len(kept) < len(finite):
        problems.append(f"{label}: {len(finite) - len(kept)} of {count} triangles have zero "
                        f"area and were left out")
    corner = [c for corners, _ in kept for c in corners]
    return {"positions": co[[corner_vert[c] for c in corner]].reshape(-1, 3),
            "normals": normals[corner].reshape(-1, 3),
            "uvs": None if uvs is None else uvs[corner].reshape(-1, 2),
            "material_slots": np.array([mesh.polygons[f].material_index for _, f in kept],
                                       dtype=np.int32)}, problems


def quads_and_triangles(rng: np.random.Generator, side: int) -> tuple[list, list]:
    """A grid of shared, shuffled vertices, jittered into non-planar and some concave quads
    (some split along 1-3), some cells two triangles; and quads with a zero-area triangle:
    flipped (either triangle of the 1-3 split) or not."""
    x, y = np.meshgrid(np.arange(side + 1.0), np.arange(side + 1.0))
    verts = np.stack([x + rng.uniform(-0.45, 0.45, x.shape), y + rng.uniform(-0.45, 0.45, x.shape),
                      rng.normal(0, 0.3, x.shape)], axis=-1).reshape(-1, 3)
    order = rng.permutation(len(verts))
    verts, number = verts[order].tolist(), np.argsort(order).reshape(side + 1, side + 1)
    faces = []
    for i in range(side):
        for j in range(side):
            a, b, c, d = number[i, j], number[i, j + 1], number[i + 1, j + 1], number[i + 1, j]
            faces += [(a, b, c), (a, c, d)] if (i + j) % 5 == 0 else [(a, b, c, d)]
    special = [[(0, 0, 0), (1, 0, 0), (-1, 2, 0), (0, 1, 0)],  # flipped, 1-2-3 on a line
               [(0, 0, 0), (1, 0, 0), (0, 1, 0), (2, 0, 0)],  # flipped, 0-1-3 on a line
               [(0, 0, 5), (1, 0, 5), (1, 0, 5), (0, 1, 5)],  # 0-1-2 has zero area
               [(0, 0, 7), (1, 0, 7), (2, 0, 7), (3, 1, 7)]]  # a zero-area triangle too
    for quad in special:
        faces.append(tuple(range(len(verts), len(verts) + 4)))
        verts += quad
    return verts, faces


def add_case(bpy, name: str, seed: int, shading: str, uvs: bool, slots: int = 1,
             ngons: int = 0, bad: tuple = ()) -> object:
    """A mesh object of quads and triangles (and ``ngons`` non-planar hexagons), shaded flat,
    smooth, mixed, with custom split normals or free custom normals on the POINT or FACE
    domain."""
    rng = np.random.default_rng(seed)
    verts, faces = quads_and_triangles(rng, 16)
    for index, value in zip((5, 50), bad, strict=False):
        verts[index] = (value, 0.0, 1.0)
    for k in range(ngons):
        faces.append(tuple(range(len(verts), len(verts) + 6)))
        verts += [(30 + 3 * k + np.cos(a), np.sin(a), 0.1 * np.sin(3 * a))
                  for a in np.linspace(0, 2 * np.pi, 7)[:-1]]
    obj = add_mesh(bpy, name, verts, faces)
    mesh = obj.data
    if shading != "flat":
        mesh.shade_smooth()
    if shading == "mixed":
        mesh.polygons.foreach_set("use_smooth", np.arange(len(faces)) % 4 != 0)
    elif shading == "custom":
        normals = rng.normal(size=(len(mesh.loops), 3))
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        mesh.normals_split_custom_set(normals.tolist())
    elif shading in ("free POINT", "free FACE"):
        attribute = mesh.attributes.new("custom_normal", "FLOAT_VECTOR", shading.split()[1])
        attribute.data.foreach_set("vector", rng.normal(size=len(attribute.data) * 3)
                                   .astype(np.float32))
    if uvs:
        for layer_name in ("UVMap", "Render"):
            layer = mesh.uv_layers.new(name=layer_name)
            layer.data.foreach_set("uv", rng.random(len(mesh.loops) * 2, dtype=np.float32))
        mesh.uv_layers["Render"].active_render = True
    for _ in range(slots - 1):
        mesh.materials.append(None)
    mesh.polygons.foreach_set("material_index",
                              rng.integers(0, slots, len(faces)).astype(np.int32))
    mesh.update()
    return obj


CASES = {  # name: shading, UVs, material slots, n-gons, NaN/Inf vertex positions
    "Flat": ("flat", True, 3, 0, ()),
    "Smooth": ("smooth", False, 1, 0, (NAN, INF)),
    "Mixed": ("mixed", True, 2, 0, (NAN,)),
    "MixedNgon": ("mixed", True, 2, 1, (INF,)),  # n-gon triangles read one by one
    "SmoothNgons": ("smooth", False, 1, 300, ()),  # read with all loop triangles
    "Custom": ("custom", True, 1, 0, ()),
    "FreePoint": ("free POINT", False, 2, 0, ()),
    "FreeFace": ("free FACE", True, 1, 0, (NAN,)),
}


def test_indexed_meshes_give_the_per_corner_arrays_bit_for_bit(blender):
    bpy = blender
    new_scene(bpy)
    objects = {name: add_case(bpy, name, seed, *case)
               for seed, (name, case) in enumerate(CASES.items())}
    depsgraph = bpy.context.evaluated_depsgraph_get()
    scene = export_scene(depsgraph)
    exported = {i.mesh.name: i.mesh for i in scene.instances}
    assert sorted(exported) == sorted(CASES)
    expected_warnings, domains = [], set()
    for name, obj in objects.items():
        evaluated = obj.evaluated_get(depsgraph).data
        domains.add(evaluated.normals_domain)
        with np.errstate(invalid="ignore"):
            expected, problems = reference(evaluated, f"mesh '{obj.data.name}'")
        expected_warnings += problems
        mesh = exported[name]
        assert mesh.positions.shape == (len(evaluated.vertices), 3)
        actual = {"positions": mesh.corner_positions(), "normals": mesh.corner_normals(),
                  "uvs": mesh.corner_uvs(), "material_slots": mesh.material_slots}
        for key, values in expected.items():
            if values is None:
                assert actual[key] is None, (name, key)
            else:  # bits: float32 rounding and the sign of zero too
                assert actual[key].dtype == values.dtype, (name, key)
                np.testing.assert_array_equal(actual[key].view(np.uint32),
                                              values.view(np.uint32), err_msg=f"{name} {key}")
        assert all(index is None or index.dtype == np.int32 for index in
                   (mesh.position_index, mesh.normal_index, mesh.uv_index))
    assert domains == {"POINT", "FACE", "CORNER"}
    assert sorted(scene.warnings) == sorted(expected_warnings)
    assert any("zero area" in w for w in expected_warnings)
    assert any("NaN/Inf" in w for w in expected_warnings)


def test_mesh_without_triangles_left_is_skipped(blender):
    """Every triangle left out (zero area): no instance, the warning only."""
    bpy = blender
    new_scene(bpy)
    add_mesh(bpy, "Line", [(0, 0, 0), (1, 0, 0), (2, 0, 0), (3, 0, 0)], [(0, 1, 2, 3)])
    scene = export_scene(bpy.context.evaluated_depsgraph_get())
    assert scene.instances == []
    assert scene.warnings == ["mesh 'Line': 2 of 2 triangles have zero area and were left out"]


def test_quad_rule_and_zero_area_round_as_numpy_does():
    """The quad split's dot (exactly) and the zero-area test are those of np.cross and a row
    sum: on a small lattice (exact zeros, collinear corners) and on floats of every magnitude
    (rounding), NaN and Inf included."""
    rng = np.random.default_rng(7)
    lattice = rng.integers(-2, 3, (3000, 3)).astype(np.float32)
    wide = (rng.normal(size=(3000, 3)) * 10.0 ** rng.integers(-6, 7, (3000, 3))).astype(np.float32)
    wide[::97], wide[::89, 1] = NAN, INF
    for co in (lattice, wide):
        vertex = rng.integers(0, len(co), (30000, 4)).astype(np.int32)
        with np.errstate(invalid="ignore", over="ignore"):
            v = co[vertex]
            d12, d13, d14 = (v[:, k] - v[:, 0] for k in (1, 2, 3))
            first = np.cross(d12, d13)
            expected = (first * np.cross(d14, d13)).sum(axis=1)
            dot = _quad_dot(co.T.copy(), vertex)
            zero = _zero_area(co.T.copy(), vertex[:, :3])
        np.testing.assert_array_equal(dot, expected)  # exactly (NaN where NaN, 0 == -0)
        np.testing.assert_array_equal(zero, ~first.any(axis=1))
        assert (dot > 0).any() and zero.any()
