"""The g-buffer of one image tile: position, normals, albedo and emission per supersample, and
with specular materials each pixel's glossy lobe (gpu_shaders/principled_lib.glsl)."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

import moderngl
import numpy as np

from ..gpu.gl import ProgramCache, read_textures, set_uniforms
from ..gpu.scene_buffers import SceneBuffers
from ..scene.model import Camera
from .gpu_scope import GpuScope

LAYERS = ("position", "normal", "geometric", "albedo", "emission")
GLOSSY_LAYERS = ("lobe_a", "lobe_b", "lobe_c")  # with specular materials; the glossy colour
# is (lobe_c.w, albedo.w, emission.w): OpenGL guarantees eight colour attachments only
TEXTURE_UNITS = 0, 1  # the image textures' array texture and its table of sizes


@dataclass(frozen=True)
class Tile:
    """Supersampled pixels [x0, x1) × [y0, y1) of an image of width × height."""

    x0: int
    x1: int
    y0: int
    y1: int
    width: int
    height: int

    @property
    def size(self) -> tuple[int, int]:
        return self.x1 - self.x0, self.y1 - self.y0


class TextureImages(Mapping[str, np.ndarray]):
    """Textures as (h, w, 4) float32 arrays, each read back from the GPU when first asked for
    (a frame reads only the layers its passes need)."""

    def __init__(self, textures: dict[str, moderngl.Texture]) -> None:
        self._textures = textures
        self._read: dict[str, np.ndarray] = {}

    def __getitem__(self, name: str) -> np.ndarray:
        if name not in self._read:
            self._read[name] = read_textures([self._textures[name]])
        return self._read[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._textures)

    def __len__(self) -> int:
        return len(self._textures)


@dataclass
class GBuffer:
    """The tile's layers as GPU textures (for the gather) and as (h, w, 4) float32 arrays
    (read back when first used); ``view_projection``: world to the tile's clip space, as a
    mat4 uniform; ``view``: the camera uniforms a gather needs for view-dependent
    reflection (glossy lobes, rough diffuse); ``depth``: the depth the layers were drawn with."""

    textures: dict[str, moderngl.Texture]
    images: Mapping[str, np.ndarray]
    view_projection: tuple[float, ...]
    view: dict[str, object] = field(default_factory=dict)
    depth: moderngl.Renderbuffer | None = None

    @property
    def glossy(self) -> bool:
        return GLOSSY_LAYERS[0] in self.textures


def tile_projection(projection: np.ndarray, tile: Tile) -> np.ndarray:
    """Projection whose clip volume covers only the tile's pixels of the image."""
    hx, hy = (tile.x1 - tile.x0) / tile.width, (tile.y1 - tile.y0) / tile.height
    cx, cy = (tile.x0 + tile.x1) / tile.width - 1.0, (tile.y0 + tile.y1) / tile.height - 1.0
    crop = np.array([[1 / hx, 0, 0, -cx / hx], [0, 1 / hy, 0, -cy / hy], [0, 0, 1, 0],
                     [0, 0, 0, 1]])
    return crop @ projection


def render_gbuffer(ctx: moderngl.Context, programs: ProgramCache, scene: SceneBuffers | None,
                   shapes: SceneBuffers | None, camera: Camera, tile: Tile,
                   scope: GpuScope, pass_index: int = 0) -> GBuffer:
    """Rasterise the scene's triangles and the lights' outlines into the tile's g-buffer,
    whose textures ``scope`` owns; cutouts keep their supersamples in a pattern of their own
    in each pass (``pass_index``), so that passes average them."""
    size = tile.size
    glossy = scene is not None and scene.has_specular
    names = LAYERS + GLOSSY_LAYERS if glossy else LAYERS
    layers = [scope.own(ctx.texture(size, 4, dtype="f4")) for _ in names]
    depth = scope.own(ctx.depth_renderbuffer(size))
    fbo = scope.own(ctx.framebuffer(layers, depth))
    fbo.use()
    fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
    ctx.enable(moderngl.DEPTH_TEST)
    ctx.disable(moderngl.BLEND | moderngl.CULL_FACE)
    view_projection = tile_projection(camera.projection_matrix, tile) @ camera.view_matrix
    view = camera.view_uniforms
    uniforms = {
        "u_view_projection": tuple(view_projection.T.astype("f4").ravel()),
        "u_view": tuple(camera.view_matrix.T.astype("f4").ravel()),
        "u_samples_per_pixel": tile.width / camera.width,
        **view,
    }
    textures = scene.textures if scene is not None else None
    scene_defines = {"TEXTURED": 1} if textures else {}
    if scene is not None and scene.has_cutouts:
        scene_defines["CUTOUTS"] = 1
        uniforms["u_cutout_seed"] = pass_index
    shape_defines = {"ONE_SIDED": 1}
    if glossy:
        scene_defines["GLOSSY"] = shape_defines["GLOSSY"] = 1
    for buffers, defines in ((scene, scene_defines), (shapes, shape_defines)):
        if buffers is None:
            continue
        program = programs.get("gbuffer_vert.glsl", "gbuffer_frag.glsl", defines)
        set_uniforms(program, **uniforms)
        streams = buffers.streams()
        if defines is scene_defines and textures:
            array, sizes = textures
            streams.append((buffers.uv, "2f", "in_uv"))
            array.use(TEXTURE_UNITS[0])
            sizes.use(TEXTURE_UNITS[1])
            set_uniforms(program, u_textures=TEXTURE_UNITS[0], u_texture_sizes=TEXTURE_UNITS[1])
        buffers.bind_materials(program)
        if glossy:
            scene.bind_specular(program)
        vao = scope.own(ctx.vertex_array(program, streams, skip_errors=True))
        vao.render(moderngl.TRIANGLES, vertices=buffers.vertex_count)
    ctx.disable(moderngl.DEPTH_TEST)
    by_name = dict(zip(names, layers, strict=True))
    return GBuffer(by_name, TextureImages(by_name), uniforms["u_view_projection"],
                   view, depth)
