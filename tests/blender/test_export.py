"""Scene export on small scenes built here through bpy: the mesh cache and instancing,
visibility flags, per-light shadows, materials, bad input and Blender's unit scale."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import addon.engine
from addon.core.frame.renderer import Renderer
from addon.core.settings import Settings
from addon.export import ExportCache, _triangles, export_scene
from tests.blender.rendering import configure_cycles, render_linear
from tests.blender.versions import BLENDER_5, ensure_nodes, nodeless_material

SIZE = 24


@pytest.fixture(scope="module")
def renderer():
    r = Renderer()
    yield r
    r.release()


def new_scene(bpy, size: int = SIZE, ortho_scale: float = 4.0, k: float = 1.0):
    """An empty scene with an orthographic camera looking down at the origin from 5k."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    data = bpy.data.cameras.new("Camera")
    data.type, data.ortho_scale = "ORTHO", ortho_scale * k
    data.clip_start, data.clip_end = 0.01 * k, 100 * k
    camera = bpy.data.objects.new("Camera", data)
    camera.location = (0, 0, 5 * k)
    scene.collection.objects.link(camera)
    scene.camera = camera
    scene.vpl_gi.antialiasing = 1
    scene.vpl_gi.bounces = 0
    return scene


def add_mesh(bpy, name: str, verts, faces, edges=(), location=(0, 0, 0), collection=None):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(v) for v in verts], list(edges), [tuple(f) for f in faces])
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    (collection or bpy.context.scene.collection).objects.link(obj)
    return obj


def add_plane(bpy, name: str, size: float, z: float = 0.0, x: float = 0.0, collection=None):
    h = size / 2
    return add_mesh(bpy, name, [(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)],
                    [(0, 1, 2, 3)], location=(x, 0, z), collection=collection)


def add_light(bpy, kind: str, energy: float, location=(0, 0, 1), **props):
    data = bpy.data.lights.new(f"{kind.title()}Light", kind)
    data.energy = energy
    if kind in ("POINT", "SPOT"):
        data.shadow_soft_size = 0.0
    for key, value in props.items():
        setattr(data, key, value)
    obj = bpy.data.objects.new(data.name, data)
    obj.location = location
    bpy.context.scene.collection.objects.link(obj)
    return obj


def diffuse_material(bpy, name: str, color) -> object:
    material = bpy.data.materials.new(name)
    ensure_nodes(material)
    tree = material.node_tree
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    node = tree.nodes.new("ShaderNodeBsdfDiffuse")
    node.inputs["Color"].default_value = (*color, 1.0)
    tree.links.new(node.outputs[0], out.inputs["Surface"])
    return material


def instance_on_points_tree(bpy, instanced, realize: bool):
    """Geometry nodes: 'instanced' (an object) on 12 points spread over the modified mesh."""
    tree = bpy.data.node_groups.new("Scatter", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = tree.nodes, tree.links
    group_in, group_out = nodes.new("NodeGroupInput"), nodes.new("NodeGroupOutput")
    points = nodes.new("GeometryNodeDistributePointsOnFaces")
    points.distribute_method = "POISSON"
    points.inputs["Distance Min"].default_value = 0.5
    points.inputs["Density Max"].default_value = 3.0
    info = nodes.new("GeometryNodeObjectInfo")
    info.inputs["Object"].default_value = instanced
    info.inputs["As Instance"].default_value = True
    on_points = nodes.new("GeometryNodeInstanceOnPoints")
    rotate = nodes.new("GeometryNodeRotateInstances")
    rotate.inputs["Rotation"].default_value = (0.3, 0.2, 0.7)
    links.new(group_in.outputs[0], points.inputs["Mesh"])
    links.new(points.outputs["Points"], on_points.inputs["Points"])
    links.new(info.outputs["Geometry"], on_points.inputs["Instance"])
    links.new(on_points.outputs["Instances"], rotate.inputs["Instances"])
    last = rotate.outputs["Instances"]
    if realize:
        realized = nodes.new("GeometryNodeRealizeInstances")
        links.new(last, realized.inputs[0])
        last = realized.outputs[0]
    join = nodes.new("GeometryNodeJoinGeometry")
    links.new(last, join.inputs[0])
    links.new(group_in.outputs[0], join.inputs[0])
    links.new(join.outputs[0], group_out.inputs[0])
    return tree


def instanced_scene(bpy, realize: bool):
    """A floor scattering small rotated cubes by geometry nodes, and a collection instance."""
    scene = new_scene(bpy)
    floor = add_plane(bpy, "Floor", 3.0)
    floor.data.materials.append(diffuse_material(bpy, "Grey", (0.6, 0.6, 0.6)))
    hidden = bpy.data.collections.new("Parts")
    cube = add_mesh(bpy, "Cube", [(x, y, z) for x in (-.1, .1) for y in (-.1, .1) for z in (0, .2)],
                    [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4),
                     (1, 5, 7, 3)], collection=hidden)
    cube.data.materials.append(diffuse_material(bpy, "Red", (0.8, 0.1, 0.1)))
    modifier = floor.modifiers.new("Scatter", "NODES")
    modifier.node_group = instance_on_points_tree(bpy, cube, realize)
    empty = bpy.data.objects.new("PartsInstance", None)
    empty.instance_type, empty.instance_collection = "COLLECTION", hidden
    empty.location = (1.2, 1.2, 0.0)
    scene.collection.objects.link(empty)
    add_light(bpy, "SUN", 2.0, angle=0.0).rotation_euler = (0.4, 0.3, 0)
    add_light(bpy, "POINT", 200.0, location=(0.5, -0.5, 2.0))
    return scene


def relative_rmse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)) / max(np.mean(np.abs(b)), 1e-30))


# -- 1. the cache and instancing ------------------------------------------------------------

def test_instances_share_one_mesh_and_render_like_realised_geometry(blender, renderer):
    bpy = blender
    instanced_scene(bpy, realize=False)
    cache = ExportCache()
    scene = export_scene(bpy.context.evaluated_depsgraph_get(), cache)
    cubes = [i for i in scene.instances if i.mesh.triangle_count == 12]
    assert len(cubes) >= 8
    assert len({id(i.mesh) for i in cubes}) == 1  # one core Mesh for every cube instance
    assert len({i.matrix.tobytes() for i in cubes}) == len(cubes)
    assert cache.stats == {"meshes_read": 2, "meshes_reused": len(cubes) - 1}
    assert all(i.materials[0].name == "Red" for i in cubes)
    settings = Settings(antialiasing=2, bounces=1, vpl_count=256)
    frame, _ = renderer.render(scene, settings)
    instanced_scene(bpy, realize=True)
    realised = export_scene(bpy.context.evaluated_depsgraph_get())
    triangles = sum(i.mesh.triangle_count for i in realised.instances)
    assert triangles == sum(i.mesh.triangle_count for i in scene.instances)
    assert len(realised.instances) == 2  # floor with the cubes realised, the collection instance
    reference, _ = renderer.render(realised, settings)
    a, b = frame.passes["Combined"][..., :3], reference.passes["Combined"][..., :3]
    assert relative_rmse(a, b) < 0.01


def test_cache_reuses_unchanged_meshes_and_rereads_forgotten_ones(blender):
    bpy = blender
    new_scene(bpy)
    shared = add_plane(bpy, "Shared", 1.0)
    twin = bpy.data.objects.new("Twin", shared.data)
    twin.location.x = 2.0
    bpy.context.scene.collection.objects.link(twin)
    modified = add_plane(bpy, "Modified", 1.0, x=-2.0)
    modified.modifiers.new("Subdivide", "SUBSURF").levels = 1
    cache = ExportCache()

    def export():
        """Instances in x order (Modified, Shared, Twin) and the cache's counts."""
        scene = export_scene(bpy.context.evaluated_depsgraph_get(), cache)
        return sorted(scene.instances, key=lambda i: i.matrix[0, 3]), dict(cache.stats)

    (mod1, shared1, twin1), stats = export()
    assert stats == {"meshes_read": 2, "meshes_reused": 1}
    assert shared1.mesh is twin1.mesh  # one mesh datablock, one core Mesh
    assert mod1.mesh.triangle_count == 8
    (mod2, shared2, twin2), stats = export()
    assert stats == {"meshes_read": 0, "meshes_reused": 3}
    assert mod2.mesh is mod1.mesh and shared2.mesh is twin2.mesh is shared1.mesh

    twin.location.x = 3.0  # transforms are always read
    modified.modifiers["Subdivide"].levels = 2  # geometry: stale until forgotten
    (mod3, _, twin3), stats = export()
    assert stats["meshes_read"] == 0
    assert twin3.matrix[0, 3] == 3.0 and mod3.mesh.triangle_count == 8
    cache.forget("Modified")
    (mod4, _, _), stats = export()
    assert stats["meshes_read"] == 1 and mod4.mesh.triangle_count == 32

    shared.data.vertices[0].co.z = 0.5  # an edit of the mesh datablock
    shared.data.update()
    (_, shared5, _), stats = export()
    assert stats["meshes_read"] == 0 and shared5.mesh.positions[:, 2].max() == 0.0
    cache.forget(shared.data.name)
    (_, shared6, twin6), stats = export()
    assert stats["meshes_read"] == 1 and shared6.mesh is twin6.mesh
    assert shared6.mesh.positions[:, 2].max() == pytest.approx(0.5)
    cache.forget("Twin")  # an object's name forgets the mesh datablock it uses
    assert export()[1]["meshes_read"] == 1
    cache.clear()
    assert export()[1] == {"meshes_read": 2, "meshes_reused": 1}


def _rotated(triples: np.ndarray) -> set[tuple[int, ...]]:
    """Triangles as corner triples rotated to start at their smallest corner (orientation kept)."""
    return {tuple(np.roll(t, -int(np.argmin(t)))) for t in triples.reshape(-1, 3)}


@pytest.mark.parametrize("ngon", [False, True])
def test_triangulation_matches_blenders_loop_triangles(blender, ngon):
    """Random non-planar and concave quads (and triangles) split as Blender splits them."""
    bpy = blender
    new_scene(bpy)
    rng = np.random.default_rng(1)
    verts, faces = [], []
    for i in range(400):
        base = len(verts)
        corners = 4 if i % 3 else 3
        angle = np.sort(rng.uniform(0, 2 * np.pi, corners))
        radius = rng.uniform(0.2, 1.0, corners)  # some quads concave
        verts += [(i + r * np.cos(a), r * np.sin(a), rng.normal(0, 0.3))
                  for a, r in zip(angle, radius, strict=True)]
        faces.append(tuple(range(base, base + corners)))
    if ngon:
        faces.append((0, 1, 2, 4, 5, 6))
    obj = add_mesh(bpy, "Quads", verts, faces)
    mesh = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
    co = np.array([v.co for v in mesh.vertices], dtype=np.float32)
    corner_vert = np.array([loop.vertex_index for loop in mesh.loops], dtype=np.int32)
    corner, vertex, face, _ = _triangles(mesh, co.T.copy(), corner_vert)
    mesh.calc_loop_triangles()
    expected = np.array([t.loops[:] for t in mesh.loop_triangles])
    assert _rotated(corner) == _rotated(expected)
    assert np.array_equal(vertex, corner_vert[corner])
    assert sorted(face) == sorted(t.polygon_index for t in mesh.loop_triangles)
    exported = export_scene(bpy.context.evaluated_depsgraph_get()).instances[0].mesh
    assert exported.triangle_count == len(expected)


# -- 2. visibility and per-light shadows ----------------------------------------------------

@pytest.fixture
def engine_export(monkeypatch):
    """Render with the engine (F12's path) and keep the Scene it exported."""
    exported = []

    def recording(depsgraph, cache=None, **options):
        scene = export_scene(depsgraph, cache, **options)
        exported.append(scene)
        return scene

    monkeypatch.setattr(addon.engine, "export_scene", recording)

    def render(scene, path: Path):
        image = render_linear(scene, "VPL_GI", path)
        assert addon.engine.monitor.last_error is None
        return image, exported[-1], list(addon.engine.monitor.last_warnings)

    return render


def test_hidden_and_excluded_objects_stay_out_and_ray_flags_are_kept(blender, engine_export,
                                                                     tmp_path):
    bpy = blender
    scene = new_scene(bpy, 8)
    add_plane(bpy, "Floor", 3.0)
    add_plane(bpy, "HiddenForRender", 1.0, z=0.5).hide_render = True
    excluded = bpy.data.collections.new("Excluded")
    scene.collection.children.link(excluded)
    add_plane(bpy, "InExcluded", 1.0, z=0.6, collection=excluded)
    scene.view_layers[0].layer_collection.children["Excluded"].exclude = True
    ghost = add_plane(bpy, "Ghost", 1.0, z=0.7)
    ghost.visible_camera = ghost.visible_diffuse = ghost.visible_shadow = False
    add_plane(bpy, "NoShadow", 0.5, z=0.8, x=1.0).visible_shadow = False
    add_plane(bpy, "NoDiffuse", 0.5, z=0.8, x=2.0).visible_diffuse = False
    holdout = add_plane(bpy, "Holdout", 0.5, z=0.8, x=-1.0)
    holdout.is_holdout = True
    parts = bpy.data.collections.new("Parts")
    scene.collection.children.link(parts)
    add_plane(bpy, "InvisibleToCamera", 0.2, z=0.9, collection=parts).visible_camera = False
    for x in (-0.5, 0.5):  # the same object twice more through collection instances
        empty = bpy.data.objects.new(f"Parts{x}", None)
        empty.instance_type, empty.instance_collection = "COLLECTION", parts
        empty.location.x = x
        scene.collection.objects.link(empty)
    add_light(bpy, "SUN", 1.0)
    image, exported, warnings = engine_export(scene, tmp_path / "visibility.exr")
    names = sorted(i.mesh.name for i in exported.instances)
    assert names == ["Floor", "Holdout", "InvisibleToCamera", "InvisibleToCamera",
                     "InvisibleToCamera", "NoDiffuse", "NoShadow"]
    assert not [w for w in warnings if "is not supported" in w]
    assert sorted((i.mesh.name, *i.flags) for i in exported.instances) == [
        ("Floor", True, False, True, True), ("Holdout", True, True, True, True),
        *[("InvisibleToCamera", False, False, True, True)] * 3,
        ("NoDiffuse", True, False, True, False), ("NoShadow", True, False, False, True)]
    assert np.isfinite(image).all()


def shadow_scene(bpy, cast_shadow: bool):
    """Floor at z=0, a 0.2 m occluder at (0.5, 0, 0.5), a 100 W point light at (0, 0, 1): the
    occluder's shadow falls on the floor around x = 1."""
    scene = new_scene(bpy, 32)
    add_plane(bpy, "Floor", 4.0).data.materials.append(
        diffuse_material(bpy, "Floor", (0.5, 0.5, 0.5)))
    add_plane(bpy, "Occluder", 0.2, z=0.5, x=0.5)
    add_light(bpy, "POINT", 100.0, use_shadow=cast_shadow)
    return scene


@pytest.mark.parametrize("cast_shadow", [True, False])
def test_light_cast_shadow_switch_reaches_the_renderer(blender, engine_export, tmp_path,
                                                       cast_shadow):
    """Floor radiance ρ P cosθ / (4π² d²) in the occluder's shadow when the light casts no
    shadow, 0 when it does."""
    bpy = blender
    image, exported, _ = engine_export(shadow_scene(bpy, cast_shadow), tmp_path / "shadow.exr")
    assert exported.lights[0].cast_shadow is cast_shadow
    def floor_radiance(row: np.ndarray, col: np.ndarray) -> np.ndarray:
        x, y = (col + 0.5) * 4.0 / 32 - 2.0, (row + 0.5) * 4.0 / 32 - 2.0
        d2 = x**2 + y**2 + 1.0
        return 0.5 * 100.0 / (4 * math.pi**2) / d2**1.5  # cosθ = 1 / d

    rows, cols = np.meshgrid([15, 16], [23, 24], indexing="ij")  # umbra: floor x ≈ 1
    umbra = image[rows, cols, 0]
    if cast_shadow:
        assert umbra.max() < 1e-6
    else:
        np.testing.assert_allclose(umbra, floor_radiance(rows, cols), rtol=0.01)
    rows, cols = np.meshgrid([15, 16], [8, 9], indexing="ij")  # floor x ≈ -1: lit in both
    np.testing.assert_allclose(image[rows, cols, 0], floor_radiance(rows, cols), rtol=0.01)


# -- 3. materials -----------------------------------------------------------------------------

def shader_material(bpy, name: str, build) -> object:
    """A material whose Surface is the node returned by build(nodes, links)."""
    material = bpy.data.materials.new(name)
    ensure_nodes(material)
    tree = material.node_tree
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    tree.links.new(build(tree.nodes, tree.links).outputs[0], out.inputs["Surface"])
    return material


def mix_material(bpy):
    def build(nodes, links):
        diffuse = nodes.new("ShaderNodeBsdfDiffuse")
        diffuse.inputs["Color"].default_value = (0.8, 0.2, 0.1, 1)
        emission = nodes.new("ShaderNodeEmission")
        emission.inputs["Color"].default_value = (0.1, 1.0, 0.2, 1)
        emission.inputs["Strength"].default_value = 2.0
        mix = nodes.new("ShaderNodeMixShader")
        mix.inputs["Fac"].default_value = 0.25
        links.new(diffuse.outputs[0], mix.inputs[1])
        links.new(emission.outputs[0], mix.inputs[2])
        return mix
    return shader_material(bpy, "Mix", build)


def test_materials_mix_principled_fallbacks_and_empty_slots(blender):
    bpy = blender
    new_scene(bpy)
    mix = mix_material(bpy)

    def principled(nodes, _links):
        node = nodes.new("ShaderNodeBsdfPrincipled")
        node.inputs["Base Color"].default_value = (0.2, 0.4, 0.6, 1)
        node.inputs["Roughness"].default_value = 0.3
        node.inputs["Metallic"].default_value = 0.7
        node.inputs["IOR"].default_value = 1.45
        node.inputs["Specular IOR Level"].default_value = 0.3
        node.inputs["Specular Tint"].default_value = (1.0, 0.5, 0.25, 1)
        return node
    metal = shader_material(bpy, "Metal", principled)

    def toon(nodes, _links):
        return nodes.new("ShaderNodeBsdfToon")
    shiny = shader_material(bpy, "Shiny", toon)
    shiny.diffuse_color = (0.3, 0.2, 0.1, 1)

    def textured(nodes, links):
        node = nodes.new("ShaderNodeBsdfDiffuse")
        links.new(nodes.new("ShaderNodeTexChecker").outputs[0], node.inputs["Color"])
        return node
    checker = shader_material(bpy, "Checker", textured)
    checker.diffuse_color = (0.5, 0.6, 0.7, 1)
    plain, plain_warned = nodeless_material("Plain", (0.9, 0.5, 0.1, 1))
    for i, material in enumerate([mix, metal, shiny, checker, plain, None]):
        for j in range(3):  # three objects per material: warnings stay one per material
            obj = add_plane(bpy, f"P{i}{j}", 0.2, x=i * 0.5 - 1.2, z=0.1 * j)
            obj.data.materials.append(material)
    scene = export_scene(bpy.context.evaluated_depsgraph_get())
    got = {i.materials[0].name: i.materials[0] for i in scene.instances if i.materials[0]}
    assert got["Mix"].base_color == pytest.approx((0.6, 0.15, 0.075))
    assert got["Mix"].emission == pytest.approx((0.05, 0.5, 0.1))
    assert (got["Metal"].roughness, got["Metal"].metallic) == pytest.approx((0.3, 0.7))
    assert (got["Metal"].ior, got["Metal"].specular_ior_level) == pytest.approx((1.45, 0.3))
    assert got["Metal"].specular_tint == pytest.approx((1.0, 0.5, 0.25))
    assert got["Shiny"].specular_ior_level == 0.0  # a fallback is diffuse
    assert got["Metal"].base_color == pytest.approx((0.2, 0.4, 0.6))
    assert got["Shiny"].base_color == pytest.approx((0.3, 0.2, 0.1))
    assert got["Checker"].base_color == pytest.approx((0.5, 0.6, 0.7))
    assert got["Plain"].base_color == pytest.approx((0.9, 0.5, 0.1))
    assert got["(no material)"].base_color == pytest.approx((0.8, 0.8, 0.8))  # empty slot
    assert sorted(scene.warnings) == [
        "material 'Checker': input 'Color' of 'Diffuse BSDF' is linked to 'Checker Texture' "
        "(nodes: Checker Texture); using its viewport colour (not baked: bakes run before "
        "background renders, in the viewport and by Bake Materials)",
        *(["material 'Plain' has no shader nodes: rendered as a diffuse surface in its "
           "viewport colour (as Cycles does)"] if plain_warned else []),
        "material 'Shiny': shader 'Toon BSDF' is not supported; using its viewport colour"]
    # Cycles 5.x renders an empty slot as a default Principled BSDF (specular level 0.5)
    assert got["(no material)"].specular_ior_level == (0.5 if BLENDER_5 else 0.0)
    assert scene.notes == []


def test_material_is_read_from_the_output_cycles_renders(blender):
    """Outputs for EEVEE only are skipped, and one for Cycles only wins over one for all
    engines, as Cycles chooses (Blender 5.x converts 4.x materials without nodes into such
    trees)."""
    bpy = blender
    new_scene(bpy)
    material = bpy.data.materials.new("Targets")
    ensure_nodes(material)
    nodes, links = material.node_tree.nodes, material.node_tree.links
    nodes.clear()
    for target, color in (("EEVEE", (0.1, 0.9, 0.1, 1)), ("ALL", (0.9, 0.1, 0.1, 1)),
                          ("CYCLES", (0.2, 0.3, 0.7, 1))):
        output = nodes.new("ShaderNodeOutputMaterial")
        output.target = target
        diffuse = nodes.new("ShaderNodeBsdfDiffuse")
        diffuse.inputs["Color"].default_value = color
        links.new(diffuse.outputs[0], output.inputs["Surface"])
    add_plane(bpy, "Tile", 0.5).data.materials.append(material)
    scene = export_scene(bpy.context.evaluated_depsgraph_get())
    assert scene.instances[0].materials[0].base_color == pytest.approx((0.2, 0.3, 0.7))
    assert not scene.warnings
    nodes.remove(next(n for n in nodes if n.type == "OUTPUT_MATERIAL" and n.target == "CYCLES"))
    scene = export_scene(bpy.context.evaluated_depsgraph_get())
    assert scene.instances[0].materials[0].base_color == pytest.approx((0.9, 0.1, 0.1))


def test_mix_shader_renders_as_cycles(blender, tmp_path):
    """A Mix of Diffuse and Emission lit by a sun: our Combined equals Cycles' (0 bounces)."""
    bpy = blender
    scene = new_scene(bpy, 16, ortho_scale=1.0)
    add_plane(bpy, "Floor", 2.0).data.materials.append(mix_material(bpy))
    add_light(bpy, "SUN", 3.0, angle=0.0)
    configure_cycles(scene, 16)
    cycles = render_linear(scene, "CYCLES", tmp_path / "cycles.exr")[..., :3].mean(axis=(0, 1))
    ours = render_linear(scene, "VPL_GI", tmp_path / "ours.exr")[..., :3].mean(axis=(0, 1))
    expected = np.array([0.6, 0.15, 0.075]) * 3 / math.pi + [0.05, 0.5, 0.1]
    np.testing.assert_allclose(cycles, expected, rtol=0.01)
    np.testing.assert_allclose(ours, cycles, rtol=0.01)


# -- 4. bad input ---------------------------------------------------------------------------

def _nan_vertices(bpy):
    obj = add_plane(bpy, "Broken", 1.0, z=0.3)
    obj.data.vertices[0].co = (math.nan, 0.0, math.inf)
    return "mesh 'Broken': 2 of 2 triangles have NaN/Inf vertices and were left out"


def _zero_area(bpy):
    add_mesh(bpy, "Sliver", [(0, 0, .3), (1, 0, .3), (2, 0, .3), (0, 1, .3), (1, 1, .3)],
             [(0, 1, 2), (0, 1, 4), (0, 4, 3)])
    return "mesh 'Sliver': 1 of 3 triangles have zero area and were left out"


def _no_faces(bpy):
    add_mesh(bpy, "Wire", [(0, 0, .3), (1, 0, .3), (1, 1, .3)], [], edges=[(0, 1), (1, 2)])
    return "mesh 'Wire' has no faces (3 vertices): nothing to render"


def _material_without_nodes(bpy):
    if BLENDER_5:
        pytest.skip("Blender 5.x materials always have shader nodes (use_nodes was removed)")
    material, _ = nodeless_material("Nodeless", (0.8, 0.8, 0.8, 1))
    add_plane(bpy, "Tile", 0.5, z=0.3).data.materials.append(material)
    return ("material 'Nodeless' has no shader nodes: rendered as a diffuse surface in its "
            "viewport colour (as Cycles does)")


def _zero_size_area_light(bpy):
    light = add_light(bpy, "AREA", 20.0, location=(0.5, 0, 1), size=-1.0)
    assert light.data.size == 0.0  # Blender clamps a negative size to 0
    return "area light 'AreaLight' has zero size: it gives no light, as in Cycles"


def _zero_scale_light(bpy):
    add_light(bpy, "POINT", 20.0, location=(0.5, 0, 1)).scale = (0, 0, 0)
    return "light 'PointLight' has a zero-scale transform and was left out"


@pytest.mark.parametrize("case", [_nan_vertices, _zero_area, _no_faces, _material_without_nodes,
                                  _zero_size_area_light, _zero_scale_light])
def test_bad_input_gives_one_warning_and_a_finite_frame(blender, engine_export, tmp_path, case):
    bpy = blender
    scene = new_scene(bpy, 16)
    scene.vpl_gi.bounces = 1
    scene.vpl_gi.vpl_count = 64
    add_plane(bpy, "Floor", 3.0)
    add_light(bpy, "SUN", 1.0)
    expected = case(bpy)
    image, _, warnings = engine_export(scene, tmp_path / "bad.exr")
    assert warnings == [expected]
    assert np.isfinite(image).all()
    assert image[..., :3].max() > 0


# -- 5. units ---------------------------------------------------------------------------------

def units_scene(bpy, scale_length: float, k: float):
    """Floor and wall lit by a point light, modelled k Blender units per metre. Both are
    diffuse 0.8 grey (without a material Cycles 5.x would add a specular highlight)."""
    scene = new_scene(bpy, 16, k=k)
    scene.unit_settings.scale_length = scale_length
    grey = diffuse_material(bpy, "Grey", (0.8, 0.8, 0.8))
    add_plane(bpy, "Floor", 4.0 * k).data.materials.append(grey)
    wall = add_plane(bpy, "Wall", 2.0 * k, x=-0.5 * k, z=0.5 * k)
    wall.data.materials.append(grey)
    wall.rotation_euler.y = 0.5
    add_light(bpy, "POINT", 100.0 * k**2, location=(0.5 * k, 0, 1 * k))
    configure_cycles(scene, 16)
    return scene


def test_unit_scale_is_ignored_as_cycles_ignores_it(blender, tmp_path):
    """Cycles ignores scale_length (one Blender unit is one metre for light falloff): a scene
    modelled in millimetres (×1000, scale_length 0.001, power ×10⁶) renders as in metres, and
    the same scene with only scale_length changed renders unchanged."""
    bpy = blender
    images = {}
    for label, scale_length, k in [("m", 1.0, 1.0), ("mm", 0.001, 1000.0),
                                   ("scale only", 0.001, 1.0)]:
        for engine in ("CYCLES", "VPL_GI"):
            scene = units_scene(bpy, scale_length, k)
            images[label, engine] = render_linear(scene, engine, tmp_path / "u.exr")[..., :3]
    for engine in ("CYCLES", "VPL_GI"):
        np.testing.assert_allclose(images["scale only", engine], images["m", engine], rtol=1e-4)
    assert relative_rmse(images["mm", "VPL_GI"], images["m", "VPL_GI"]) < 1e-3
    for label in ("m", "mm"):
        ours, cycles = images[label, "VPL_GI"], images[label, "CYCLES"]
        assert ours.mean() == pytest.approx(cycles.mean(), rel=0.02)


def test_light_portal_guides_world_light_and_emits_nothing(blender):
    bpy = blender
    new_scene(bpy)
    add_plane(bpy, "Floor", 4.0)
    portal = add_light(bpy, "AREA", 1000.0, location=(0, 0, 2), size=1.5)
    portal.data.cycles.is_portal = True
    add_light(bpy, "AREA", 50.0, location=(1, 0, 2))
    scene = export_scene(bpy.context.evaluated_depsgraph_get())
    assert [light.name for light in scene.lights] == ["AreaLight.001"]
    assert [p.name for p in scene.portals] == ["AreaLight"]
    assert scene.portals[0].world_area == pytest.approx(1.5**2)


def test_subsurface_scattering_is_diffuse_in_its_colour_with_a_warning(blender):
    from addon.export import export_material
    from tests.blender.rendering import shader_material
    blender.ops.wm.read_factory_settings(use_empty=True)
    warnings: list[str] = []
    skin = export_material(shader_material("Skin", "ShaderNodeSubsurfaceScattering",
                                           Color=(0.8, 0.5, 0.4, 1.0)), warnings)
    assert skin.base_color == pytest.approx((0.8, 0.5, 0.4)) and skin.metallic == 0.0
    assert warnings == ["material 'Skin': Subsurface Scattering rendered as a Diffuse BSDF of "
                        "its colour (no light scattered under the surface)"]


def test_a_holdout_shader_is_a_holdout_material(blender):
    from addon.export import export_material
    from tests.blender.rendering import shader_material
    blender.ops.wm.read_factory_settings(use_empty=True)
    warnings: list[str] = []
    hole = export_material(shader_material("Hole", "ShaderNodeHoldout"), warnings)
    assert hole.holdout and hole.base_color == (0.0, 0.0, 0.0) and not warnings
