"""Build the VPL GI sample scenes from code and save them as compressed .blend files.

Run with the project's venv (bpy 4.5 as a Python module, background mode)::

    .venv/bin/python sample_scenes/build_scenes.py [--out DIR]

DIR defaults to this script's folder. The script writes one .blend per entry of ``SCENES``:

- ``cornell_box.blend``: the default scene, a Cornell box lit by a square area light.
- ``light_point.blend``, ``light_spot.blend``, ``light_sun.blend``, ``light_area.blend``,
  ``multi_light.blend``: a shared stage (floor, back wall, cube, sphere) under different
  lights, one light type per file plus one with a mix of them.
- ``interior.blend``: a furnished 6 m × 4 m × 3 m room (with a dark side room behind a
  doorway) lit only by a sun through one window and a dim world, so nearly everything the
  camera sees is lit indirectly; about 70k triangles of tessellated boxes, cylinders and
  spheres, the benchmark scene for indirect light.

Every material is a pure diffuse Principled BSDF (roughness 1, specular 0, metallic 0), so the
scenes compare like for like with Cycles, whose reference settings are stored in each file.
Each scene's render engine is set to ``VPL_GI``; in a bare bpy that engine is not registered,
so a placeholder ``RenderEngine`` with that id is registered while the scenes are built and
unregistered again before the script ends (a registered engine makes bpy hang at exit).

The module is importable: ``build_all(out_dir)`` writes every scene, ``build_scene(name,
out_dir)`` writes one, and ``SCENES`` maps each scene name (the file stem) to a builder that
fills a freshly reset file and returns its ``bpy.types.Scene``.
"""

from __future__ import annotations

import argparse
import itertools
import math
import pathlib
import random
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager

import bpy  # first: importing bpy is what makes bmesh and mathutils importable

# isort: split
import bmesh
from mathutils import Euler, Matrix, Vector

ENGINE_ID = "VPL_GI"
RESOLUTION = 256
SCRIPT_DIR = pathlib.Path(__file__).resolve().parent

Vec3 = tuple[float, float, float]
Color = tuple[float, float, float]
Span = tuple[float, float]  # (low, high) along one axis
Box = tuple[Vec3, Vec3]  # (size, centre)

# Colours (linear RGB) of the materials, one material per colour, named after its role.
CORNELL_WHITE: Color = (0.725, 0.71, 0.68)
CORNELL_RED: Color = (0.63, 0.065, 0.05)
CORNELL_GREEN: Color = (0.14, 0.45, 0.091)
STAGE_WHITE: Color = (0.8, 0.8, 0.8)
STAGE_BLUE: Color = (0.5, 0.6, 0.8)
STAGE_ORANGE: Color = (0.8, 0.4, 0.1)
STAGE_GREEN: Color = (0.2, 0.7, 0.3)
BLACK: Color = (0.0, 0.0, 0.0)
INTERIOR_WALL: Color = (0.8, 0.78, 0.74)
INTERIOR_FLOOR: Color = (0.45, 0.3, 0.18)
INTERIOR_CEILING: Color = (0.85, 0.85, 0.85)
INTERIOR_DARK_WOOD: Color = (0.3, 0.18, 0.1)
INTERIOR_RED: Color = (0.7, 0.1, 0.08)
INTERIOR_BLUE: Color = (0.1, 0.2, 0.6)
INTERIOR_GREEN: Color = (0.12, 0.45, 0.15)
INTERIOR_YELLOW: Color = (0.75, 0.6, 0.12)
INTERIOR_SKY: Color = (0.03, 0.035, 0.04)
INTERIOR_EXPOSURE = 2.0  # display exposure (stops) of the interior scene

# Lens (36 mm sensor) that makes the Cornell box's front opening, 2 m wide at 2.9 m from the
# camera, just fill the frame with a thin margin: 18 * 2.9 / 1.05 = 49.7 mm.
CORNELL_LENS = 50.0


# --------------------------------------------------------------------------- render engine


class PlaceholderEngine(bpy.types.RenderEngine):
    """Stand-in for the VPL GI engine so ``scene.render.engine`` can be set to its id."""

    bl_idname = ENGINE_ID
    bl_label = "VPL GI"


def _engine_registered() -> bool:
    return any(
        getattr(cls, "bl_idname", None) == ENGINE_ID and getattr(cls, "is_registered", False)
        for cls in bpy.types.RenderEngine.__subclasses__()
    )


@contextmanager
def engine_available() -> Iterator[None]:
    """Make the ``VPL_GI`` engine id valid inside the block.

    Registers the placeholder only if no engine with that id (the real add-on, or an outer
    block) is registered, and unregisters exactly what it registered on the way out. The
    engine id stored in a scene survives the unregistration, so files saved afterwards keep it.
    """
    if _engine_registered():
        yield
        return
    bpy.utils.register_class(PlaceholderEngine)
    try:
        yield
    finally:
        bpy.utils.unregister_class(PlaceholderEngine)


# --------------------------------------------------------------------------- building blocks


def new_file() -> bpy.types.Scene:
    """Reset bpy to an empty factory file and return its (only) scene."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.context.preferences.filepaths.save_version = 0  # no .blend1 backups
    return bpy.context.scene


def configure_render(scene: bpy.types.Scene) -> None:
    """Set the engine, resolution, frame range and the Cycles reference settings."""
    with engine_available():
        scene.render.engine = ENGINE_ID
    render = scene.render
    render.resolution_x = RESOLUTION
    render.resolution_y = RESOLUTION
    render.resolution_percentage = 100
    scene.frame_start = 1
    scene.frame_end = 1
    scene.frame_current = 1

    cycles = scene.cycles
    cycles.device = "CPU"
    cycles.samples = 512
    cycles.use_denoising = False
    cycles.diffuse_bounces = 4
    cycles.glossy_bounces = 0
    cycles.transmission_bounces = 0
    cycles.volume_bounces = 0
    cycles.transparent_max_bounces = 0
    cycles.max_bounces = 4
    cycles.sample_clamp_direct = 0.0
    cycles.sample_clamp_indirect = 0.0
    cycles.seed = 0


def set_world(scene: bpy.types.Scene, color: Color = BLACK, strength: float = 1.0) -> None:
    """Give the scene a node world with a uniform background colour."""
    world = bpy.data.worlds.new("World")
    world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (*color, 1.0)
    background.inputs["Strength"].default_value = strength
    world.color = color
    scene.world = world


def make_material(name: str, color: Color) -> bpy.types.Material:
    """A pure diffuse Principled BSDF material (roughness 1, no specular, not metallic)."""
    material = bpy.data.materials.new(name)
    material.use_nodes = True
    bsdf = material.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Roughness"].default_value = 1.0
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    bsdf.inputs["Metallic"].default_value = 0.0
    material.diffuse_color = (*color, 1.0)  # viewport colour
    material.roughness = 1.0
    material.metallic = 0.0
    return material


def _add_mesh_object(
    name: str,
    bm: bmesh.types.BMesh,
    material: bpy.types.Material,
    location: Vec3,
    rotation: Vec3,
) -> bpy.types.Object:
    mesh = bpy.data.meshes.new(name)
    bm.to_mesh(mesh)
    bm.free()
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    obj.rotation_euler = rotation
    bpy.context.scene.collection.objects.link(obj)
    return obj


def add_plane(
    name: str,
    size: tuple[float, float],
    location: Vec3,
    material: bpy.types.Material,
    rotation: Vec3 = (0.0, 0.0, 0.0),
) -> bpy.types.Object:
    """A single-quad plane of ``size`` (x, y) in its local XY plane, normal along local +Z."""
    bm = bmesh.new()
    bmesh.ops.create_grid(
        bm,
        x_segments=1,
        y_segments=1,
        size=0.5,
        calc_uvs=True,
        matrix=Matrix.Diagonal((size[0], size[1], 1.0, 1.0)),
    )
    return _add_mesh_object(name, bm, material, location, rotation)


def add_box(
    name: str,
    size: Vec3,
    location: Vec3,
    material: bpy.types.Material,
    rotation_z_deg: float = 0.0,
) -> bpy.types.Object:
    """A box of ``size`` (baked into the mesh) centred on ``location``, turned about Z."""
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=1.0, calc_uvs=True, matrix=Matrix.Diagonal((*size, 1.0)))
    return _add_mesh_object(name, bm, material, location, (0.0, 0.0, math.radians(rotation_z_deg)))


def add_sphere(
    name: str,
    radius: float,
    location: Vec3,
    material: bpy.types.Material,
    segments: int = 32,
    rings: int = 16,
) -> bpy.types.Object:
    """A smooth-shaded UV sphere."""
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(
        bm, u_segments=segments, v_segments=rings, radius=radius, calc_uvs=True
    )
    obj = _add_mesh_object(name, bm, material, location, (0.0, 0.0, 0.0))
    obj.data.shade_smooth()
    return obj


def grid_box(bm: bmesh.types.BMesh, size: Vec3, centre: Vec3, cell: float) -> None:
    """Add to ``bm`` a closed, welded box whose faces are grids of quads about ``cell`` wide.

    Each side is split into ``round(length / cell)`` segments (at least one), so big flat
    surfaces carry a realistic number of triangles. Normals point out of the box.
    """
    centre_v = Vector(centre)
    segments = [max(1, round(length / cell)) for length in size]
    verts: list[bmesh.types.BMVert] = []
    for axis in range(3):
        u_axis, v_axis = (axis + 1) % 3, (axis + 2) % 3  # u × v = +axis
        for sign in (1.0, -1.0):
            normal = Vector.Fill(3, 0.0)
            normal[axis] = sign
            u = Vector.Fill(3, 0.0)
            u[u_axis] = size[u_axis] * sign  # flipping u flips the grid's normal with the side
            v = Vector.Fill(3, 0.0)
            v[v_axis] = size[v_axis]
            origin = centre_v + normal * (size[axis] / 2)
            matrix = Matrix((
                (u.x, v.x, normal.x, origin.x),
                (u.y, v.y, normal.y, origin.y),
                (u.z, v.z, normal.z, origin.z),
                (0.0, 0.0, 0.0, 1.0),
            ))
            verts += bmesh.ops.create_grid(
                bm,
                x_segments=segments[u_axis],
                y_segments=segments[v_axis],
                size=0.5,
                matrix=matrix,
            )["verts"]
    bmesh.ops.remove_doubles(bm, verts=verts, dist=1e-5)


def cylinder(
    bm: bmesh.types.BMesh,
    radius: float,
    height: float,
    base: Vec3,
    segments: int = 24,
    rings: int = 4,
) -> None:
    """Add to ``bm`` a closed vertical cylinder standing on ``base``, its side cut into rings.

    The side is smooth-shaded and its rim edges are sharp, so the flat caps stay flat.
    """
    base_v = Vector(base)
    circles = []
    for ring in range(rings + 1):
        z = height * ring / rings
        circles.append([
            bm.verts.new(base_v + Vector((
                radius * math.cos(2 * math.pi * k / segments),
                radius * math.sin(2 * math.pi * k / segments),
                z,
            )))
            for k in range(segments)
        ])
    for lower, upper in itertools.pairwise(circles):
        for k in range(segments):
            nxt = (k + 1) % segments
            bm.faces.new((lower[k], lower[nxt], upper[nxt], upper[k])).smooth = True
    bm.faces.new(reversed(circles[0]))
    bm.faces.new(circles[-1])
    for rim in (circles[0], circles[-1]):
        for k in range(segments):
            bm.edges.get((rim[k], rim[(k + 1) % segments])).smooth = False


def add_parts(
    name: str,
    bm: bmesh.types.BMesh,
    material: bpy.types.Material,
    location: Vec3 = (0.0, 0.0, 0.0),
    rotation_z_deg: float = 0.0,
) -> bpy.types.Object:
    """An object made of the parts built into ``bm`` (in its local frame), turned about Z."""
    return _add_mesh_object(name, bm, material, location, (0.0, 0.0, math.radians(rotation_z_deg)))


def add_grid_boxes(
    name: str,
    boxes: Sequence[Box],
    material: bpy.types.Material,
    cell: float,
) -> bpy.types.Object:
    """One object made of tessellated boxes, each given as (size, centre) in world space."""
    bm = bmesh.new()
    for size, centre in boxes:
        grid_box(bm, size, centre, cell)
    return add_parts(name, bm, material)


def span_box(x: Span, y: Span, z: Span) -> Box:
    """(size, centre) of the axis-aligned box spanning the intervals ``x``, ``y``, ``z``."""
    return (
        (x[1] - x[0], y[1] - y[0], z[1] - z[0]),
        ((x[0] + x[1]) / 2, (y[0] + y[1]) / 2, (z[0] + z[1]) / 2),
    )


def aim_rotation(location: Vec3, target: Vec3) -> Euler:
    """Rotation that points an object's local -Z axis from ``location`` at ``target``."""
    return direction_rotation(Vector(target) - Vector(location))


def direction_rotation(direction: Vec3 | Vector) -> Euler:
    """Rotation that points an object's local -Z axis along ``direction`` (local +Y up-ish)."""
    return Vector(direction).to_track_quat("-Z", "Y").to_euler()


def add_light(
    name: str,
    kind: str,
    location: Vec3,
    power: float,
    color: Color = (1.0, 1.0, 1.0),
    target: Vec3 | None = None,
    rotation: Euler | Vec3 = (0.0, 0.0, 0.0),
    **settings: object,
) -> bpy.types.Object:
    """A light of ``kind`` (POINT, SPOT, SUN, AREA) emitting along its local -Z axis.

    ``power`` is the energy in watts (irradiance strength for a sun). With ``target`` the light
    is aimed at that point, else ``rotation`` is used. ``settings`` are set on the light data
    (``shadow_soft_size``, ``spot_size``, ``shape``, ``size``, ...).
    """
    light = bpy.data.lights.new(name, kind)
    light.energy = power
    light.color = color
    for key, value in settings.items():
        setattr(light, key, value)
    obj = bpy.data.objects.new(name, light)
    obj.location = location
    obj.rotation_euler = aim_rotation(location, target) if target is not None else rotation
    bpy.context.scene.collection.objects.link(obj)
    return obj


def add_camera(
    name: str,
    location: Vec3,
    lens: float,
    target: Vec3 | None = None,
    rotation: Euler | Vec3 = (0.0, 0.0, 0.0),
) -> bpy.types.Object:
    """A perspective camera (36 mm sensor) made the scene camera; the rotation is baked in."""
    camera = bpy.data.cameras.new(name)
    camera.type = "PERSP"
    camera.lens = lens
    camera.sensor_width = 36.0
    camera.sensor_fit = "AUTO"
    obj = bpy.data.objects.new(name, camera)
    obj.location = location
    obj.rotation_euler = aim_rotation(location, target) if target is not None else rotation
    scene = bpy.context.scene
    scene.collection.objects.link(obj)
    scene.camera = obj
    return obj


def new_scene(world_color: Color = BLACK) -> bpy.types.Scene:
    """Reset to an empty file and set up render settings and world."""
    scene = new_file()
    configure_render(scene)
    set_world(scene, world_color)
    return scene


# --------------------------------------------------------------------------- scenes


def build_cornell_box() -> bpy.types.Scene:
    """The default scene: a Cornell box open at the front (y = -1), lit from the ceiling."""
    scene = new_scene()
    white = make_material("White", CORNELL_WHITE)
    red = make_material("Red", CORNELL_RED)
    green = make_material("Green", CORNELL_GREEN)

    # Interior x, y in [-1, 1], z in [0, 2]; every wall's normal faces into the box.
    quarter = math.pi / 2
    add_plane("Floor", (2.0, 2.0), (0.0, 0.0, 0.0), white)
    add_plane("Ceiling", (2.0, 2.0), (0.0, 0.0, 2.0), white, rotation=(math.pi, 0.0, 0.0))
    add_plane("BackWall", (2.0, 2.0), (0.0, 1.0, 1.0), white, rotation=(quarter, 0.0, 0.0))
    add_plane("LeftWall", (2.0, 2.0), (-1.0, 0.0, 1.0), red, rotation=(0.0, quarter, 0.0))
    add_plane("RightWall", (2.0, 2.0), (1.0, 0.0, 1.0), green, rotation=(0.0, -quarter, 0.0))

    add_box("TallBlock", (0.6, 0.6, 1.2), (-0.33, 0.3, 0.6), white, rotation_z_deg=17.0)
    add_box("ShortBlock", (0.6, 0.6, 0.6), (0.35, -0.3, 0.3), white, rotation_z_deg=-17.0)

    add_light("Light.Area", "AREA", (0.0, 0.0, 1.98), 50.0, shape="SQUARE", size=0.5)
    add_camera("Camera", (0.0, -3.9, 1.0), CORNELL_LENS, rotation=(quarter, 0.0, 0.0))
    return scene


def stage(world_color: Color = BLACK) -> bpy.types.Scene:
    """The stage shared by the light scenes: floor, back wall, cube, sphere and camera."""
    scene = new_scene(world_color)
    add_plane("Floor", (8.0, 8.0), (0.0, 0.0, 0.0), make_material("White", STAGE_WHITE))
    add_plane(
        "BackWall",
        (8.0, 4.0),
        (0.0, 2.5, 2.0),
        make_material("Blue", STAGE_BLUE),
        rotation=(math.pi / 2, 0.0, 0.0),
    )
    add_box(
        "Cube",
        (1.0, 1.0, 1.0),
        (-0.7, 0.0, 0.5),
        make_material("Orange", STAGE_ORANGE),
        rotation_z_deg=20.0,
    )
    add_sphere("Sphere", 0.5, (0.9, 0.4, 0.5), make_material("Green", STAGE_GREEN))
    add_camera("Camera", (0.0, -6.5, 3.2), 35.0, target=(0.0, 0.0, 0.6))
    return scene


def build_light_point() -> bpy.types.Scene:
    """Stage lit by one point light (radius 0: a hard-shadowed point)."""
    scene = stage()
    add_light("Light.Point", "POINT", (-1.5, -1.5, 3.0), 600.0, shadow_soft_size=0.0)
    return scene


def build_light_spot() -> bpy.types.Scene:
    """Stage lit by one spot light aimed at the origin."""
    scene = stage()
    add_light(
        "Light.Spot",
        "SPOT",
        (0.5, -2.0, 4.0),
        1500.0,
        target=(0.0, 0.0, 0.0),
        spot_size=math.radians(50.0),
        spot_blend=0.3,
        shadow_soft_size=0.0,
        show_cone=False,
    )
    return scene


def build_light_sun() -> bpy.types.Scene:
    """Stage lit by a sun; (-0.4, -0.6, 0.7) points from the scene towards the sun."""
    scene = stage()
    to_sun = Vector((-0.4, -0.6, 0.7)).normalized()
    add_light(
        "Light.Sun", "SUN", (0.0, 0.0, 5.0), 3.0, rotation=direction_rotation(-to_sun), angle=0.0
    )
    return scene


def build_light_area() -> bpy.types.Scene:
    """Stage lit by a rectangular and a disk area light."""
    scene = stage()
    add_light(
        "Light.AreaRect",
        "AREA",
        (-1.0, -1.2, 3.0),
        400.0,
        color=(1.0, 0.9, 0.8),
        target=(-0.5, 0.0, 0.0),
        shape="RECTANGLE",
        size=1.0,
        size_y=0.5,
    )
    add_light(
        "Light.AreaDisk",
        "AREA",
        (1.5, -1.0, 2.5),
        300.0,
        color=(0.8, 0.9, 1.0),
        target=(0.8, 0.4, 0.3),
        shape="DISK",
        size=0.8,
    )
    return scene


def build_multi_light() -> bpy.types.Scene:
    """Stage under a point, a spot, a sun and an ellipse area light, with a dim blue world."""
    scene = stage(world_color=(0.05, 0.06, 0.08))
    add_light(
        "Light.Point",
        "POINT",
        (-2.0, -1.0, 2.5),
        300.0,
        color=(1.0, 0.8, 0.6),
        shadow_soft_size=0.0,
    )
    add_light(
        "Light.Spot",
        "SPOT",
        (1.5, -2.5, 3.5),
        800.0,
        color=(0.7, 0.8, 1.0),
        target=(0.9, 0.4, 0.5),
        spot_size=math.radians(40.0),
        spot_blend=0.2,
        shadow_soft_size=0.0,
        show_cone=False,
    )
    to_sun = Vector((0.5, -0.3, 0.8)).normalized()
    add_light(
        "Light.Sun", "SUN", (0.0, 0.0, 5.0), 0.5, rotation=direction_rotation(-to_sun), angle=0.0
    )
    add_light(
        "Light.AreaEllipse",
        "AREA",
        (0.0, 1.0, 2.8),
        150.0,
        target=(0.0, 0.0, 0.0),
        shape="ELLIPSE",
        size=0.6,
        size_y=0.3,
    )
    return scene


def add_chair(
    name: str, material: bpy.types.Material, location: Vec3, rotation_z_deg: float
) -> None:
    """A chair (seat, four cylinder legs, backrest) facing its local +Y."""
    bm = bmesh.new()
    grid_box(bm, (0.44, 0.42, 0.04), (0.0, 0.0, 0.45), 0.04)
    for x in (-0.19, 0.19):
        for y in (-0.18, 0.18):
            cylinder(bm, 0.02, 0.43, (x, y, 0.0), segments=16, rings=4)
    grid_box(bm, (0.44, 0.03, 0.45), (0.0, -0.195, 0.695), 0.04)
    add_parts(name, bm, material, location, rotation_z_deg)


def add_books(
    materials: dict[str, bpy.types.Material], shelves: Sequence[float], x: Span, y_front: float
) -> None:
    """Rows of upright books (boxes) on the shelf boards whose tops are at heights ``shelves``.

    Sizes, gaps and colours come from a fixed-seed generator, so every build is the same; the
    books of one colour form one object, ``Books.<colour>``.
    """
    rng = random.Random(7)
    boxes: dict[str, list[Box]] = {colour: [] for colour in materials}
    for z in shelves:
        left = x[0] + 0.02
        while left < x[1] - 0.08:
            if rng.random() < 0.1:
                left += rng.uniform(0.05, 0.15)  # a gap in the row
                continue
            width = rng.uniform(0.025, 0.06)
            height = rng.uniform(0.22, 0.36)
            depth = rng.uniform(0.18, 0.26)
            colour = rng.choice(list(materials))
            boxes[colour].append(
                span_box((left, left + width), (y_front, y_front + depth), (z, z + height))
            )
            left += width + 0.002
    for colour, material in materials.items():
        add_grid_boxes(f"Books.{colour}", boxes[colour], material, 0.1)


def build_interior() -> bpy.types.Scene:
    """A furnished room lit only through one window by a sun and a dim sky: indirect light.

    The main room is x in [-3, 3], y in [-2, 2], z in [0, 3]; the window (1.6 m wide, 1.4 m
    high, sill at 0.9 m) is in its south wall (y = -2), and a partition at x = -3 has a
    doorway into a dark side room (x in [-4.7, -3.2]). Floor, ceiling and walls are 0.2 m
    thick boxes; walls reach into each other at the corners and 0.1 m into the floor and
    ceiling slabs, so there is no seam for light to leak through. The sun (35° high, 20° west
    of due north) throws the window's patch onto the rug; the camera, in the south-east corner
    with the window behind it, sees only surfaces lit by bounce light besides that patch.
    """
    scene = new_scene(world_color=INTERIOR_SKY)
    # Bounce light is dim (the room averages ~0.02): brighten the display only. Renders and
    # saved EXRs stay linear and unscaled; view-transformed images of both engines get it.
    scene.view_settings.exposure = INTERIOR_EXPOSURE
    wall = make_material("Wall", INTERIOR_WALL)
    floor = make_material("Floor", INTERIOR_FLOOR)
    ceiling = make_material("Ceiling", INTERIOR_CEILING)
    wood = make_material("DarkWood", INTERIOR_DARK_WOOD)
    red = make_material("Red", INTERIOR_RED)
    blue = make_material("Blue", INTERIOR_BLUE)
    green = make_material("Green", INTERIOR_GREEN)
    yellow = make_material("Yellow", INTERIOR_YELLOW)

    # Shell: the outside of the building is x in [-4.9, 3.2], y in [-2.2, 2.2].
    cell = 0.14
    outside_x, outside_y = (-4.9, 3.2), (-2.2, 2.2)
    wall_z = (-0.1, 3.1)
    end_y = (-2.1, 2.1)  # end walls reach 0.1 m into the long walls
    add_grid_boxes("Floor", [span_box(outside_x, outside_y, (-0.2, 0.0))], floor, cell)
    add_grid_boxes("Ceiling", [span_box(outside_x, outside_y, (3.0, 3.2))], ceiling, cell)
    add_grid_boxes("Wall.North", [span_box(outside_x, (2.0, 2.2), wall_z)], wall, cell)
    window_x, window_z, south_y = (-0.4, 1.2), (0.9, 2.3), (-2.2, -2.0)
    south = [
        span_box((outside_x[0], window_x[0]), south_y, wall_z),
        span_box((window_x[1], outside_x[1]), south_y, wall_z),
        span_box(window_x, south_y, (wall_z[0], window_z[0])),
        span_box(window_x, south_y, (window_z[1], wall_z[1])),
    ]
    add_grid_boxes("Wall.South", south, wall, cell)
    add_grid_boxes("Wall.East", [span_box((3.0, 3.2), end_y, wall_z)], wall, cell)
    add_grid_boxes("Wall.West", [span_box((-4.9, -4.7), end_y, wall_z)], wall, cell)
    door_y, door_top, partition_x = (0.5, 1.4), 2.1, (-3.2, -3.0)
    partition = [
        span_box(partition_x, (end_y[0], door_y[0]), wall_z),
        span_box(partition_x, (door_y[1], end_y[1]), wall_z),
        span_box(partition_x, door_y, (door_top, wall_z[1])),
    ]
    add_grid_boxes("Wall.Partition", partition, wall, cell)

    # Furniture.
    add_grid_boxes("Rug", [span_box((-0.3, 1.7), (-0.4, 0.9), (0.0, 0.012))], red, 0.05)

    table = bmesh.new()
    grid_box(table, (1.4, 0.8, 0.04), (0.0, 0.0, 0.73), 0.04)
    for x in (-0.62, 0.62):
        for y in (-0.32, 0.32):
            cylinder(table, 0.03, 0.71, (x, y, 0.0), segments=24, rings=6)
    add_parts("Table", table, wood, (-1.6, -0.6, 0.0))
    add_chair("Chair.South", green, (-1.6, -1.3, 0.0), 0.0)
    add_chair("Chair.North", green, (-1.6, 0.1, 0.0), 180.0)

    shelf_x, shelf_y = (-2.6, -1.4), (1.65, 1.98)
    boards = (0.05, 0.5, 0.95, 1.4, 1.87)
    shelf = [
        span_box((shelf_x[0], shelf_x[0] + 0.03), shelf_y, (0.0, 1.9)),
        span_box((shelf_x[1] - 0.03, shelf_x[1]), shelf_y, (0.0, 1.9)),
        span_box(shelf_x, (shelf_y[1], 2.0), (0.0, 1.9)),
    ]
    shelf += [
        span_box((shelf_x[0] + 0.03, shelf_x[1] - 0.03), shelf_y, (z, z + 0.03)) for z in boards
    ]
    add_grid_boxes("Bookshelf", shelf, wood, 0.08)
    book_materials = {"Red": red, "Blue": blue, "Green": green, "Yellow": yellow, "Cream": wall}
    add_books(book_materials, [z + 0.03 for z in boards[:-1]], shelf_x, shelf_y[0] + 0.02)

    sofa = [
        span_box((0.4, 2.6), (1.1, 2.0), (0.0, 0.38)),  # base
        span_box((0.4, 2.6), (1.75, 2.0), (0.38, 0.85)),  # back
        span_box((0.4, 0.6), (1.1, 1.75), (0.38, 0.62)),  # arms
        span_box((2.4, 2.6), (1.1, 1.75), (0.38, 0.62)),
        span_box((0.6, 1.5), (1.1, 1.75), (0.38, 0.5)),  # seat cushions
        span_box((1.5, 2.4), (1.1, 1.75), (0.38, 0.5)),
    ]
    add_grid_boxes("Sofa", sofa, blue, 0.06)

    add_sphere("Sphere.Floor", 0.35, (-0.5, 1.45, 0.35), yellow, segments=64, rings=32)
    add_sphere("Sphere.Table", 0.12, (-1.25, -0.5, 0.87), blue, segments=64, rings=32)

    # Light only through the window: a sun 35° high, shining north and a little west.
    elevation, azimuth = math.radians(35.0), math.radians(20.0)
    travel = Vector((
        -math.sin(azimuth) * math.cos(elevation),
        math.cos(azimuth) * math.cos(elevation),
        -math.sin(elevation),
    ))
    add_light(
        "Light.Sun", "SUN", (0.4, -6.0, 5.0), 4.0, rotation=direction_rotation(travel), angle=0.0
    )
    add_camera("Camera", (2.75, -1.75, 1.6), 24.0, target=(-1.2, 0.8, 0.35))
    return scene


SCENES: dict[str, Callable[[], bpy.types.Scene]] = {
    "cornell_box": build_cornell_box,
    "light_point": build_light_point,
    "light_spot": build_light_spot,
    "light_sun": build_light_sun,
    "light_area": build_light_area,
    "multi_light": build_multi_light,
    "interior": build_interior,
}


# --------------------------------------------------------------------------- saving


def build_scene(name: str, out_dir: pathlib.Path) -> pathlib.Path:
    """Build scene ``name`` (a key of ``SCENES``) and save it as ``out_dir/<name>.blend``."""
    out_dir = pathlib.Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"{name}.blend"
    with engine_available():
        SCENES[name]()
        bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=True)
    return path


def build_all(out_dir: pathlib.Path) -> list[pathlib.Path]:
    """Build every scene of ``SCENES`` into ``out_dir``; return the written paths in order."""
    with engine_available():
        paths = [build_scene(name, out_dir) for name in SCENES]
    # Leave bpy with an empty file rather than the last scene.
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return paths


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--out",
        type=pathlib.Path,
        default=SCRIPT_DIR,
        help="folder to write the .blend files into (default: this script's folder)",
    )
    args = parser.parse_args(argv)
    for path in build_all(args.out):
        print(f"wrote {path} ({path.stat().st_size / 1024:.0f} KiB)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
