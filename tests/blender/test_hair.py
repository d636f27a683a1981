"""Hair and point clouds rendered as Cycles renders them: a tuft of grass strands (a Curves
object), a fur of hair particles with children, grass of a Principled Hair BSDF and a
Geometry Nodes point cloud against Cycles; what the export reads (the radius, Cycles'
default without one, material slots per curve, a warning for curves that are not finite,
hair shaders' colours); deforming hair in the Vector pass."""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest

from addon.core.scene.hair import TUBE_SIDES, circumradius
from addon.export import export_scene
from addon.export_hair import DEFAULT_RADIUS
from tests.blender.rendering import (
    add_camera,
    add_primitive,
    add_sun,
    assert_near_cycles,
    configure_cycles,
    cycles_and_ours,
    render_linear,
    shader_material,
)

SIZE = 96


def hair_object(name: str, points: np.ndarray, radii: np.ndarray | None = None
                ) -> bpy.types.Object:
    """A Curves object of equal-length curves (``points``: curves × points × 3) linked to the
    scene; ``radii`` (points per curve) set on every curve, or no radius attribute."""
    count, length = points.shape[:2]
    curves = bpy.data.hair_curves.new(name)
    curves.add_curves([length] * count)
    curves.attributes["position"].data.foreach_set(
        "vector", points.astype(np.float32).ravel())
    if radii is not None:
        radius = curves.attributes.new("radius", "FLOAT", "POINT")
        radius.data.foreach_set("value", np.tile(radii, count).astype(np.float32))
    obj = bpy.data.objects.new(name, curves)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def grass(count: int = 400, points: int = 5) -> np.ndarray:
    """Seeded strands 0.5 m tall, rooted in a 1.2 m square, leaning as they rise."""
    rng = np.random.default_rng(1)
    roots = np.stack([rng.uniform(-0.6, 0.6, count), rng.uniform(-0.6, 0.6, count),
                      np.zeros(count)], axis=1)
    lean = rng.normal(0.0, 0.15, (count, 2))
    t = np.linspace(0.0, 1.0, points)
    rise = np.stack([lean[:, None, 0] * t ** 2, lean[:, None, 1] * t ** 2,
                     np.broadcast_to(0.5 * t, (count, points))], axis=-1)
    return roots[:, None] + rise


def sunlit_floor(size: int) -> tuple[bpy.types.Scene, bpy.types.Material]:
    """A new scene: a grey floor (8 m) under a sun of angle 0 (40° from the zenith), a dim
    world and a camera looking down at the floor's middle (size × size pixels); returns the
    scene and the grey material."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    grey = shader_material("Grey", "ShaderNodeBsdfDiffuse", Color=(0.7, 0.7, 0.7, 1))
    add_primitive("plane", grey, size=8)
    add_sun(scene, (40, 0, 30))
    scene.world = bpy.data.worlds.new("Dim")
    add_camera(scene, size, location=(0, -2.2, 1.3), rotation=(math.radians(62), 0, 0))
    return scene, grey


def test_a_tuft_of_grass_against_cycles(blender, tmp_path):
    """Green strands (radius 12 → 3 mm) on a grey floor under a sun of angle 0, one bounce,
    96² against Cycles' 256 samples. Measured (bpy 4.5): energy −0.5 %, relRMSE 7.0 % (8-pixel
    blocks: 2.0 %; Cycles against itself, another seed: 1.2 %), most of it each pixel's
    coverage of strands one or two pixels wide (with four-sided tubes antialiasing 8 took
    0.9 points off); four-sided tubes measured 7.9 %; the grass left out 74 %."""
    scene, _ = sunlit_floor(SIZE)
    tuft = hair_object("Grass", grass(), np.linspace(0.012, 0.003, 5))
    tuft.data.materials.append(shader_material("Green", "ShaderNodeBsdfDiffuse",
                                               Color=(0.2, 0.6, 0.1, 1)))
    reference, ours = cycles_and_ours(scene, tmp_path, 256, 1)
    tuft.hide_render = True
    without = render_linear(scene, "VPL_GI", tmp_path / "without.exr")
    assert_near_cycles("grass", ours[..., :3], reference[..., :3], (0.015, 0.09),
                       without[..., :3], "without the grass")


def principled_hair(parametrization: str, colour: tuple, melanin: float) -> bpy.types.Material:
    """A Principled Hair BSDF (Chiang) of ``colour`` and ``melanin``, parametrised by one."""
    material = shader_material("Hair", "ShaderNodeBsdfHairPrincipled")
    node = material.node_tree.nodes["Principled Hair BSDF"]
    node.parametrization = "MELANIN"  # an input is found by name only while the mode shows it
    node.inputs["Melanin"].default_value = melanin
    node.parametrization = "COLOR"
    node.inputs["Color"].default_value = (*colour, 1.0)
    node.parametrization = parametrization
    return material


@pytest.mark.parametrize("parametrization", ["COLOR", "MELANIN"])
def test_principled_hair_against_cycles(blender, tmp_path, parametrization):
    """Dense grass (2000 strands) of a Principled Hair BSDF, rendered as a diffuse surface of
    the colour its fibres give a mass of hair, against Cycles (one diffuse bounce, three
    glossy and transmission ones: the light through and between fibres); the viewport
    colour (what it rendered as before) must be off by 1.5 times more. Measured (bpy 4.5,
    64², 128 samples): Direct Coloring energy −14.5 %, relRMSE 26.3 % (the viewport colour
    41.6 %); Melanin −15.3 %, 24.5 % (68.4 %): an approximation, Cycles' strands paler than
    the colour, their highlights and the light through them left out."""
    scene, _ = sunlit_floor(64)
    tuft = hair_object("Grass", grass(2000), np.linspace(0.012, 0.003, 5))
    tuft.data.materials.append(principled_hair(parametrization, (0.5, 0.3, 0.1), 0.3))
    configure_cycles(scene, 128, bounces=1)
    scene.cycles.glossy_bounces = scene.cycles.transmission_bounces = 3
    scene.cycles.max_bounces = 8
    reference = render_linear(scene, "CYCLES", tmp_path / "cycles.exr")
    scene.vpl_gi.bounces, scene.vpl_gi.antialiasing = 1, 4
    ours = render_linear(scene, "VPL_GI", tmp_path / "ours.exr")
    tuft.data.materials[0] = shader_material("Viewport", "ShaderNodeBsdfDiffuse")
    without = render_linear(scene, "VPL_GI", tmp_path / "without.exr")
    assert_near_cycles(f"principled hair ({parametrization})", ours[..., :3],
                       reference[..., :3], (0.2, 0.3), without[..., :3], "the viewport colour",
                       factor=1.5)


def test_hair_particles_against_cycles(blender, tmp_path):
    """A plane's hair particles (300 parents, 5 interpolated children each in renders, keys
    from the render steps, radius 7.5 → 1.5 mm, the plane's second material) on a grey floor
    under a sun of angle 0, one bounce, 96² against Cycles' 256 samples. Measured (bpy 4.5):
    energy −1.5 %, relRMSE 11.6 %: strands of a pixel or less, each pixel's coverage from
    16 supersamples; the hair left out 152 %."""
    scene, grey = sunlit_floor(SIZE)
    patch = add_primitive("plane", grey, size=1.2, location=(0.2, 0.0, 0.1))
    patch.rotation_euler = (0.0, 0.0, 0.3)
    patch.data.materials.append(shader_material("Fur", "ShaderNodeBsdfDiffuse",
                                                Color=(0.8, 0.4, 0.1, 1)))
    fur = patch.modifiers.new("Fur", "PARTICLE_SYSTEM")
    settings = fur.particle_system.settings
    settings.type, settings.count, settings.hair_length, settings.material = "HAIR", 300, 0.4, 2
    settings.child_type, settings.rendered_child_count = "INTERPOLATED", 5
    settings.root_radius, settings.tip_radius, settings.radius_scale = 1.0, 0.2, 0.015
    settings.use_advanced_hair = True
    settings.normal_factor, settings.tangent_factor, settings.factor_random = 1.0, 0.3, 0.3
    reference, ours = cycles_and_ours(scene, tmp_path, 256, 1)
    fur.show_render = False
    without = render_linear(scene, "VPL_GI", tmp_path / "without.exr")
    assert_near_cycles("hair particles", ours[..., :3], reference[..., :3], (0.02, 0.14),
                       without[..., :3], "without the hair")


def test_radius_slots_and_bad_curves(blender):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    straight = np.array([[[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0], [1.0, 0.0, 1.0]],
                         [[2.0, 0.0, 0.0], [2.0, 0.0, np.nan]]])
    strands = hair_object("Strands", straight)
    strands.data.materials.append(shader_material("A", "ShaderNodeBsdfDiffuse"))
    strands.data.materials.append(shader_material("B", "ShaderNodeBsdfDiffuse"))
    index = strands.data.attributes.new("material_index", "INT", "CURVE")
    index.data.foreach_set("value", np.array([0, 1, 1], np.int32))
    collection = bpy.context.scene.collection  # empty hair and points: nothing, no warning
    collection.objects.link(bpy.data.objects.new("Bald", bpy.data.hair_curves.new("Bald")))
    collection.objects.link(bpy.data.objects.new("Dust", bpy.data.pointclouds.new("Dust")))
    scene = export_scene(bpy.context.evaluated_depsgraph_get())
    assert "object 'Strands': 1 of 3 curves have NaN/Inf points or radii and were left out" \
        in scene.warnings
    assert len(scene.warnings) == 1
    instance, = scene.instances
    mesh = instance.mesh
    assert [m.name for m in instance.materials] == ["A", "B"]
    first = mesh.positions[mesh.positions[:, 0] < 0.5]
    assert np.linalg.norm(first[:, :2], axis=1) == pytest.approx(
        np.full(len(first), circumradius(TUBE_SIDES) * DEFAULT_RADIUS), rel=1e-4)
    corners = mesh.corner_positions().reshape(-1, 3, 3)
    assert (mesh.material_slots == (corners[:, :, 0].mean(axis=1) > 0.5)).all()


def swaying(obj: bpy.types.Object, metres_per_frame: float) -> None:
    """A Geometry Nodes modifier that moves every point of ``obj`` along x by
    ``metres_per_frame`` × the frame: the curves deform, the object stays put."""
    tree = bpy.data.node_groups.new("Sway", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = tree.nodes, tree.links
    move = nodes.new("GeometryNodeSetPosition")
    scale = nodes.new("ShaderNodeMath")
    scale.operation, scale.inputs[1].default_value = "MULTIPLY", metres_per_frame
    offset = nodes.new("ShaderNodeCombineXYZ")
    links.new(nodes.new("GeometryNodeInputSceneTime").outputs["Frame"], scale.inputs[0])
    links.new(scale.outputs[0], offset.inputs["X"])
    links.new(nodes.new("NodeGroupInput").outputs[0], move.inputs["Geometry"])
    links.new(offset.outputs[0], move.inputs["Offset"])
    links.new(move.outputs[0], nodes.new("NodeGroupOutput").inputs[0])
    obj.modifiers.new("Sway", "NODES").node_group = tree


def test_deforming_hair_moves_in_the_vector_pass_as_in_cycles(blender, tmp_path):
    """test_motion's scene with its box still and, before it, nine strands that a Geometry
    Nodes modifier moves sideways (0.1 m a frame, about 1.9 px). Measured (bpy 4.5): median
    error 0.04 px where they move over a pixel (read as still, the hair's own motion alone:
    1.9 px). Cycles' vectors of hair that bends come from the curve's keys interpolated
    linearly in the spline's parameter (its centre line is not linear in it), so only a
    uniform motion is compared."""
    from tests.blender.test_motion import motion_scene, vector_pass

    scene = motion_scene(False)
    bpy.data.objects["Cube"].animation_data_clear()
    points = np.array([[[x, -0.5, -1.0], [x, -0.5, 1.0]] for x in np.linspace(-1, 1, 9)])
    hair = hair_object("Hair", points, np.array([0.08, 0.08]))
    hair.data.materials.append(shader_material("Red", "ShaderNodeBsdfDiffuse"))
    swaying(hair, 0.1)
    reference = vector_pass(scene, "CYCLES", tmp_path / "cycles_vectors.exr")
    ours = vector_pass(scene, "VPL_GI", tmp_path / "ours_vectors.exr")
    moving = np.abs(reference[..., :2]).max(axis=2) > 1.0
    error = np.abs(ours - reference).max(axis=2)[moving]
    print(f"vector pass, deforming hair: {moving.mean():.3f} of pixels move over 1 px, "
          f"median error {np.median(error):.3f} px, mean {error.mean():.3f} px")
    assert moving.mean() > 0.1
    assert np.median(error) < 0.1


def test_hair_shaders_export_as_the_colour_of_their_fibres(blender):
    from addon.core.scene.hair_fibre import colour_from_absorption, melanin_absorption
    from addon.export import export_material

    bpy.ops.wm.read_factory_settings(use_empty=True)
    warnings: list[str] = []
    direct = export_material(principled_hair("COLOR", (0.5, 0.3, 0.1), 0.3), warnings)
    assert direct.base_color == pytest.approx((0.5, 0.3, 0.1))
    melanin = export_material(principled_hair("MELANIN", (0.5, 0.3, 0.1), 0.3), warnings)
    assert melanin.base_color == pytest.approx(
        colour_from_absorption(melanin_absorption(0.3, 1.0, (1, 1, 1), 0.3), 0.3))
    fibre = export_material(shader_material("Fibre", "ShaderNodeBsdfHair",
                                            Color=(0.2, 0.4, 0.6, 1)), warnings)
    assert fibre.base_color == pytest.approx((0.2, 0.4, 0.6))
    assert warnings == [
        "material 'Hair': Principled Hair BSDF rendered as a Diffuse BSDF of the colour of "
        "its fibres (no highlights along them, no light through them)",
        "material 'Hair.001': Principled Hair BSDF rendered as a Diffuse BSDF of the colour "
        "of its fibres (no highlights along them, no light through them)",
        "material 'Fibre': Hair BSDF rendered as a Diffuse BSDF of its colour (no highlights "
        "along the fibres)"]


def scattered_points(obj: bpy.types.Object, density: float, radius: float,
                     material: bpy.types.Material) -> None:
    """A Geometry Nodes modifier that turns ``obj``'s faces into a point cloud: seeded points
    of ``density`` per m², of ``radius`` and ``material``."""
    tree = bpy.data.node_groups.new("Scatter", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = tree.nodes, tree.links
    scatter = nodes.new("GeometryNodeDistributePointsOnFaces")
    scatter.inputs["Density"].default_value = density
    sized = nodes.new("GeometryNodeSetPointRadius")
    sized.inputs["Radius"].default_value = radius
    painted = nodes.new("GeometryNodeSetMaterial")
    painted.inputs["Material"].default_value = material
    links.new(nodes.new("NodeGroupInput").outputs[0], scatter.inputs["Mesh"])
    links.new(scatter.outputs["Points"], sized.inputs["Points"])
    links.new(sized.outputs[0], painted.inputs["Geometry"])
    links.new(painted.outputs[0], nodes.new("NodeGroupOutput").inputs[0])
    obj.modifiers.new("Scatter", "NODES").node_group = tree


def test_a_point_cloud_against_cycles(blender, tmp_path):
    """Pebbles: a Geometry Nodes point cloud (200 points a m² on a 1.2 m square, radius
    3 cm, orange) on a grey floor under a sun of angle 0, one bounce, 96² against Cycles'
    256 samples. Measured (bpy 4.5): energy +1.0 %, relRMSE 4.2 %; the modifier off (its
    plane instead) 34.6 %."""
    scene, grey = sunlit_floor(SIZE)
    patch = add_primitive("plane", grey, size=1.2, location=(0.0, 0.0, 0.05))
    scattered_points(patch, 200.0, 0.03, shader_material("Orange", "ShaderNodeBsdfDiffuse",
                                                         Color=(0.8, 0.4, 0.1, 1)))
    reference, ours = cycles_and_ours(scene, tmp_path, 256, 1)
    patch.modifiers["Scatter"].show_render = False
    without = render_linear(scene, "VPL_GI", tmp_path / "without.exr")
    assert_near_cycles("point cloud", ours[..., :3], reference[..., :3], (0.02, 0.1),
                       without[..., :3], "without the points")


def test_esc_while_hair_particles_are_read_cancels(blender):
    """Reading a fur asks whether to stop every few thousand strands (Esc in Blender, the
    command line's host): the render ends cancelled, not failed, before any frame."""
    from addon.core.frame.state import RenderCancelled
    from addon.engine import monitor
    from addon.export_hair import CANCEL_STRANDS, read_particle_hair

    scene, grey = sunlit_floor(16)
    patch = add_primitive("plane", grey, size=1.0)
    settings = patch.modifiers.new("Fur", "PARTICLE_SYSTEM").particle_system.settings
    settings.type, settings.count = "HAIR", CANCEL_STRANDS + 10
    evaluated = patch.evaluated_get(bpy.context.evaluated_depsgraph_get())
    asked = []
    with pytest.raises(RenderCancelled):
        read_particle_hair(evaluated, False, "fur", lambda: asked.append(1) or len(asked) > 1)
    assert len(asked) == 2  # once before each block of strands
    scene.render.engine = "VPL_GI"
    monitor.cancel_requested = True
    try:
        bpy.ops.render.render()
    finally:
        monitor.cancel_requested = False
    assert monitor.last_error is None and monitor.last_stats is None
