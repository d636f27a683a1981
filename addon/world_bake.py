"""World bakes: a world whose light the exporter cannot read from its nodes (a Sky Texture, a
gradient, a mix of backgrounds, an environment map mapped other than turned about Z …) is
evaluated by Cycles' Environment bake into an equirectangular map, then lit like an HDRI.

The bake renders a temporary sphere whose UV map is Cycles' equirectangular layout, so each
texel holds the world's radiance in its direction (within 0.04° of the texel's centre). A sun
disc narrower than a texel is integrated right only in fine texels: with 4 samples a texel a
Sky Texture's sun (35° high) lit a plane 12 % too dimly at 2048 texels around the horizon, so
the texels around the brightest one are baked again 16 times finer (the plane's irradiance
then within 0.3 % of Cycles' own, for 0.65 s of baking in a process that has run Cycles).

Where it runs: with the material bakes (bake.bake_scene: before background renders, in the
viewport, by Bake Materials), on a temporary scene that shows the user's world unchanged.
Bakes are kept per world name and node-tree hash for the process."""

from __future__ import annotations

import time
from dataclasses import dataclass

import bpy
import numpy as np

from . import bake_tree
from .bake import CACHE, NOT_BAKED, Temporary, run_bake
from .blender_compat import ensure_nodes
from .core.frame.result import Stats
from .core.scene.environment import equirect_directions, mean_radiance
from .core.scene.model import EnvironmentMap, Light, World
from .core.scene.sun_disc import map_power, peak_window, take_out_sun, window_ranges

MAP_WIDTH = 1024  # texels around the horizon (height: half)
BAKE_SAMPLES = 4  # Cycles samples per texel
SPHERE_QUADS = (128, 64)  # the bake sphere's quads around and from pole to pole
PEAK_TEXELS = 16  # bake texels each way around the brightest one baked again finer
PEAK_FACTOR = 16  # how much finer (each of those texels: 256 × BAKE_SAMPLES samples)
KEPT_WORLDS = 4  # bakes kept (one per world and node tree; each MAP_WIDTH² × 6 bytes)


@dataclass
class WorldBake:
    """One world's baked radiance: (height, width, 3) linear RGB, rows bottom-up, the sun
    disc taken out of it as a sun light, if any, and for a world that shows the camera
    something else than its light (Light Path), what the camera sees."""

    pixels: np.ndarray
    seconds: float
    sun: Light | None = None
    camera_pixels: np.ndarray | None = None

    def world(self) -> World:
        """The world as the renderer takes it: the map, its mean as the colour."""
        environment = EnvironmentMap(self.pixels)
        shown = None if self.camera_pixels is None else EnvironmentMap(self.camera_pixels)
        return World(tuple(float(c) for c in mean_radiance(environment)), 1.0, environment,
                     self.sun if shown is None else None, shown)


_BAKES: dict[tuple, WorldBake] = {}
_FAILED: dict[tuple, str] = {}
_UNREPORTED: list[float] = []  # seconds of the bakes made since the last report


def world_key(world: bpy.types.World) -> tuple:
    """The cache key of a world's bake: its name and node tree."""
    original = world.original
    return original.name_full, bake_tree.tree_hash(original.node_tree)


def _reads_ray_type(tree: bpy.types.NodeTree) -> bool:
    """Whether a world's own node tree holds a Light Path node."""
    return any(node.type == "LIGHT_PATH" for node in tree.nodes)


def _group_reads_ray_type(tree: bpy.types.NodeTree, seen: set[str] | None = None) -> bool:
    """Whether a node group inside a tree (or inside those) holds a Light Path node."""
    seen = set() if seen is None else seen
    for node in tree.nodes:
        group = getattr(node, "node_tree", None)
        if node.type == "GROUP" and group is not None and group.name_full not in seen:
            seen.add(group.name_full)
            if _reads_ray_type(group) or _group_reads_ray_type(group, seen):
                return True
    return False


def why_not_baked(world: bpy.types.World) -> str:
    """Why a world that needs a bake has none: it cannot be baked, its bake failed, or no
    bake pass has run since it changed."""
    if _group_reads_ray_type(world.original.node_tree):
        return "not baked: a node group in it reads the ray type (Light Path)"
    return _FAILED.get(world_key(world), NOT_BAKED)


def _viewed(world: bpy.types.World, temporary: Temporary, camera: bool) -> bpy.types.World:
    """A temporary copy of the world whose Light Path nodes are constants: as a camera ray
    that misses every surface sees it (Is Camera Ray 1), or as direct-light sampling
    evaluates it (every output 0); the user's world is left as it is."""
    copy = temporary.add(bpy.data.worlds, world.original.copy())
    tree = copy.node_tree
    for node in [n for n in tree.nodes if n.type == "LIGHT_PATH"]:
        for output in node.outputs:
            for link in list(output.links):
                value = tree.nodes.new("ShaderNodeValue")
                value.outputs[0].default_value = \
                    1.0 if camera and output.identifier == "Is Camera Ray" else 0.0
                tree.links.new(value.outputs[0], link.to_socket)
        tree.nodes.remove(node)
    return copy


def cached(world: bpy.types.World) -> WorldBake | None:
    """The world's bake, if one was made for its current node tree."""
    return _BAKES.get(world_key(world))


def _sphere_patch(temporary: Temporary, u_range: tuple[float, float],
                  v_range: tuple[float, float], quads: tuple[int, int]) -> bpy.types.Object:
    """The part of a unit sphere about the origin that Cycles' equirectangular layout
    (Blender's, core/scene/environment.py) maps to ``u_range`` × ``v_range``,
    smooth shaded, its UV map that rectangle stretched over the unit square."""
    around, up = quads
    s, t = np.meshgrid(np.linspace(0.0, 1.0, around + 1), np.linspace(0.0, 1.0, up + 1))
    vertices = equirect_directions(u_range[0] + s * (u_range[1] - u_range[0]),
                                   v_range[0] + t * (v_range[1] - v_range[0])).reshape(-1, 3)
    first = (np.arange(up)[:, None] * (around + 1) + np.arange(around)[None, :]).ravel()
    faces = np.stack([first, first + 1, first + around + 2, first + around + 1], -1)
    mesh = temporary.add(bpy.data.meshes, bpy.data.meshes.new("VPL GI world bake"))
    mesh.from_pydata(vertices.tolist(), [], faces.tolist())
    mesh.polygons.foreach_set("use_smooth", np.ones(len(mesh.polygons), bool))
    corner_vertex = np.empty(len(mesh.loops), np.int32)
    mesh.loops.foreach_get("vertex_index", corner_vertex)
    layer = mesh.uv_layers.new(name="VPL GI world bake")
    layer.uv.foreach_set("vector", np.stack([s.ravel(), t.ravel()], -1)[corner_vertex].ravel())
    return temporary.add(bpy.data.objects, bpy.data.objects.new("VPL GI world bake", mesh))


def _bake_patch(world: bpy.types.World, u_range: tuple[float, float],
                v_range: tuple[float, float], size: tuple[int, int],
                quads: tuple[int, int]) -> np.ndarray:
    """The world's radiance over an equirectangular rectangle, (height, width, 3) rows
    bottom-up, by Cycles' Environment bake of the sphere's patch."""
    width, height = size
    with Temporary() as temporary:
        scene = temporary.add(bpy.data.scenes, bpy.data.scenes.new("VPL GI world bake"))
        scene.render.engine = "CYCLES"
        scene.cycles.device = "CPU"
        scene.cycles.samples = BAKE_SAMPLES
        scene.world = world.original
        patch = _sphere_patch(temporary, u_range, v_range, quads)
        scene.collection.objects.link(patch)
        image = temporary.add(bpy.data.images, bpy.data.images.new(
            "VPL GI world bake", width, height, alpha=False, float_buffer=True))
        material = temporary.add(bpy.data.materials, bpy.data.materials.new("VPL GI world bake"))
        ensure_nodes(material)
        node = material.node_tree.nodes.new("ShaderNodeTexImage")
        node.image = image
        material.node_tree.nodes.active = node
        patch.data.materials.append(material)
        run_bake(scene, patch, "ENVIRONMENT")
        pixels = np.empty(width * height * 4, np.float32)
        image.pixels.foreach_get(pixels)
    rgb = np.nan_to_num(pixels.reshape(height, width, 4)[..., :3], nan=0.0, posinf=0.0)
    return np.maximum(rgb, 0.0)


def _average_blocks(pixels: np.ndarray, v_range: tuple[float, float], factor: int) -> np.ndarray:
    """``factor`` × ``factor`` texels to one, each weighted by its solid angle (its row's
    sine of the polar angle; rows bottom-up over ``v_range``), float32."""
    height, width = pixels.shape[:2]
    v = v_range[0] + (np.arange(height) + 0.5) / height * (v_range[1] - v_range[0])
    weight = np.sin(np.pi * v)[:, None, None]
    blocks = (pixels * weight).reshape(height // factor, factor, width // factor, factor, 3)
    total = weight.reshape(height // factor, factor, 1).sum(axis=1) * factor
    return (blocks.sum(axis=(1, 3)) / total[:, :, None]).astype(np.float32)


def bake_world(world: bpy.types.World) -> WorldBake:
    """Cycles' Environment bake of the world into a MAP_WIDTH × MAP_WIDTH / 2 map, the
    PEAK_TEXELS² texels around its brightest one baked again PEAK_FACTOR times finer (a sun
    disc narrower than a texel), and a sun disc found there taken out as a sun light; a
    world reading the ray type (Light Path) is baked as its light and again as the camera
    sees it. RuntimeError if Cycles refuses."""
    start = time.perf_counter()
    width, height = MAP_WIDTH, MAP_WIDTH // 2
    with Temporary() as temporary:
        two_views = _reads_ray_type(world.original.node_tree)
        light = _viewed(world, temporary, camera=False) if two_views else world
        rgb = _bake_patch(light, (0.0, 1.0), (0.0, 1.0), (width, height), SPHERE_QUADS)
        rows, columns = peak_window(rgb, PEAK_TEXELS)
        u_range, v_range = window_ranges(rows, columns, rgb.shape)
        fine = PEAK_TEXELS * PEAK_FACTOR
        peak = _bake_patch(light, u_range, v_range, (fine, fine), (PEAK_TEXELS, PEAK_TEXELS))
        camera = _bake_patch(_viewed(world, temporary, camera=True), (0.0, 1.0), (0.0, 1.0),
                             (width, height), SPHERE_QUADS) if two_views else None
    rgb[rows, columns] = _average_blocks(peak, v_range, PEAK_FACTOR)
    sun = take_out_sun(peak, u_range, v_range, map_power(EnvironmentMap(rgb)),
                       f"{world.original.name} sun disc")
    if sun is not None:
        rgb[rows, columns] = _average_blocks(peak, v_range, PEAK_FACTOR)
    return WorldBake(rgb, time.perf_counter() - start, sun, camera)


def bake_if_needed(world: bpy.types.World | None, reason: str | None) -> float:
    """Bake the scene's world where the exporter gives a ``reason`` it cannot read it and
    no bake of its current node tree is kept (a failure goes to the bake pass's problems);
    the bake's seconds, 0 if none was made."""
    if world is None or reason is None or _group_reads_ray_type(world.original.node_tree):
        return 0.0
    key = world_key(world)
    if key in _BAKES:
        return 0.0
    try:
        entry = bake_world(world)
    except (RuntimeError, ValueError) as exc:
        _FAILED[key] = f"not baked: the bake failed: {str(exc).strip()}"
        CACHE.problems.append(f"world '{world.original.name}': {_FAILED[key]}")
        return 0.0
    _FAILED.pop(key, None)
    while len(_BAKES) >= KEPT_WORLDS:
        del _BAKES[next(iter(_BAKES))]
    _BAKES[key] = entry
    _UNREPORTED.append(entry.seconds)
    return entry.seconds


def report(stats: Stats) -> None:
    """The time of the world bakes made since the last report, as a 'world bake' stage."""
    if _UNREPORTED:
        stats.timings["world bake"] = sum(_UNREPORTED)
        _UNREPORTED.clear()


def clear() -> None:
    """Forget every world bake (the add-on's unregister)."""
    _BAKES.clear()
    _FAILED.clear()
    _UNREPORTED.clear()
