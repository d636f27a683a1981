"""The renderer: g-buffer, shadow maps and direct light for one frame, in image tiles and
light batches, composed into Blender's passes."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import moderngl
import numpy as np

from .frame import Frame, Stats
from .geometry import WorldGeometry, bounding_sphere, flatten_instances, light_shapes
from .gl import ProgramCache, shared_context
from .lights import LightSamples, build_light_samples
from .scene import Camera, Scene
from .settings import Settings

BACKGROUND_DEPTH = 1e10  # Blender's Z pass value where no surface is hit
MAX_TILE = 1024  # supersampled pixels per image tile edge
ATLAS_TEXELS = 1 << 25  # texels per shadow atlas batch (128 MiB of float32)
VERTEX_FORMAT = "3f 3f 3f 3f"
VERTEX_ATTRIBUTES = ("in_position", "in_normal", "in_albedo", "in_emission")


class RenderError(RuntimeError):
    """The scene cannot be rendered; the message says why, for the user."""


class RenderCancelled(RuntimeError):
    """The user asked the render to stop."""


ProgressCallback = Callable[[float, str], None]
CancelCallback = Callable[[], bool]


@dataclass
class _Batch:
    samples: LightSamples
    resolution: int
    first_tile: np.ndarray
    columns: int
    rows: int


def _plan_batches(samples: LightSamples, max_texture: int) -> list[_Batch]:
    """Group samples by shadow resolution and cut the groups so each atlas fits the budget."""
    batches: list[_Batch] = []
    tiles = samples.tiles_per_sample
    shadowless = np.flatnonzero(tiles == 0)
    if len(shadowless):
        batches.append(_Batch(samples.subset(shadowless), 1, np.zeros(len(shadowless), int), 1, 1))
    for resolution in np.unique(samples.resolution[tiles > 0]):
        res = int(resolution)
        index = np.flatnonzero((tiles > 0) & (samples.resolution == res))
        per_edge = max(1, max_texture // res)
        capacity = min(per_edge * per_edge, max(6, ATLAS_TEXELS // (res * res)))
        start = 0
        while start < len(index):
            used, stop = 0, start
            while stop < len(index) and used + tiles[index[stop]] <= capacity:
                used += tiles[index[stop]]
                stop += 1
            chunk = index[start:stop]
            first = np.concatenate([[0], np.cumsum(tiles[chunk])[:-1]])
            columns = min(used, per_edge)
            batches.append(_Batch(samples.subset(chunk), res, first, columns,
                                  -(-used // columns)))
            start = stop
    return batches


def _tile_projection(projection: np.ndarray, x0: int, x1: int, y0: int, y1: int,
                     width: int, height: int) -> np.ndarray:
    """Projection whose clip volume covers only pixels [x0, x1) × [y0, y1) of the image."""
    hx, hy = (x1 - x0) / width, (y1 - y0) / height
    cx, cy = (x0 + x1) / width - 1.0, (y0 + y1) / height - 1.0
    crop = np.array([[1 / hx, 0, 0, -cx / hx], [0, 1 / hy, 0, -cy / hy], [0, 0, 1, 0],
                     [0, 0, 0, 1]])
    return crop @ projection


def _set_uniforms(program: moderngl.Program, **values: object) -> None:
    """Set the uniforms the compiler kept (unused ones are optimised away)."""
    for name, value in values.items():
        if name in program:
            program[name].value = value


def _downsample(image: np.ndarray, factor: int) -> np.ndarray:
    if factor == 1:
        return image
    h, w, c = image.shape
    return image.reshape(h // factor, factor, w // factor, factor, c).mean(axis=(1, 3))


class Renderer:
    """Renders Scenes with one standalone OpenGL context. Create once, call render() per frame."""

    def __init__(self, ctx: moderngl.Context | None = None) -> None:
        self.ctx = ctx or shared_context()
        self.programs = ProgramCache(self.ctx)
        self.max_texture = int(self.ctx.info["GL_MAX_TEXTURE_SIZE"])

    def release(self) -> None:
        self.programs.release()

    # -- one frame ------------------------------------------------------------------------
    def render(self, scene: Scene, settings: Settings, progress: ProgressCallback | None = None,
               cancelled: CancelCallback | None = None) -> tuple[Frame, Stats]:
        """Render all passes of ``scene``. Raises RenderError or RenderCancelled."""
        settings.validate()
        camera = scene.camera
        if camera is None:
            raise RenderError("the scene has no camera")
        if camera.width < 1 or camera.height < 1:
            raise RenderError(f"resolution {camera.width}×{camera.height} is empty")
        stats = Stats(warnings=list(scene.warnings))
        report = progress or (lambda _f, _m: None)
        check = cancelled or (lambda: False)

        with stats.timed("geometry"):
            geometry = flatten_instances(scene, stats.warnings)
            shapes = light_shapes(scene)
            centre, radius = bounding_sphere(geometry.positions)
        with stats.timed("light samples"):
            samples = build_light_samples(scene, geometry, settings, stats.warnings)
        batches = _plan_batches(samples, self.max_texture)
        stats.counts.update(triangles=geometry.vertex_count // 3, light_samples=len(samples),
                            shadow_maps=int(samples.tiles_per_sample.sum()))

        aa = settings.antialiasing
        width, height = camera.width * aa, camera.height * aa
        tiles = [(x, min(x + MAX_TILE, width), y, min(y + MAX_TILE, height))
                 for y in range(0, height, MAX_TILE) for x in range(0, width, MAX_TILE)]
        output = {name: np.zeros((camera.height, camera.width, c), np.float32)
                  for name, c in (("Combined", 4), ("Depth", 1), ("Normal", 3), ("DiffDir", 3),
                                  ("DiffInd", 3), ("DiffCol", 3), ("Emit", 3))}
        resources = _FrameResources(self.ctx, geometry, shapes, self.programs)
        try:
            steps, done = len(tiles) * max(1, len(batches)), 0
            keep_atlas = len(batches) == 1
            for (x0, x1, y0, y1) in tiles:
                with stats.timed("g-buffer"):
                    gbuffer = resources.gbuffer(camera, x0, x1, y0, y1, width, height)
                accumulator = resources.accumulator(x1 - x0, y1 - y0)
                for batch in batches:
                    if check():
                        raise RenderCancelled("render cancelled")
                    with stats.timed("shadow maps"):
                        atlas = resources.atlas(batch, centre, radius, reuse=keep_atlas)
                        self.ctx.finish()
                    with stats.timed("direct light"):
                        resources.shade(batch, atlas, gbuffer, accumulator, centre, radius,
                                        settings.shadow_bias)
                        self.ctx.finish()
                    done += 1
                    report(done / steps, f"direct light {done}/{steps}")
                with stats.timed("compose"):
                    light = resources.read_accumulator(accumulator)
                    self._compose(output, gbuffer, light, scene, aa, x0, y0)
        finally:
            resources.release()
        self._sanitize(output, stats)
        return Frame(camera.width, camera.height, output), stats

    @staticmethod
    def _compose(output: dict[str, np.ndarray], gbuffer: dict[str, np.ndarray],
                 light: np.ndarray, scene: Scene, aa: int, x0: int, y0: int) -> None:
        """Turn one supersampled tile's buffers into Blender's passes at output resolution."""
        covered = gbuffer["normal"][..., 3:4]
        albedo, emission = gbuffer["albedo"][..., :3], gbuffer["emission"][..., :3]
        diff_dir = light[..., :3]
        background = np.zeros(4) if scene.film_transparent else \
            np.append(scene.world.radiance, 1.0)
        combined = np.concatenate([diff_dir * albedo + emission, covered], axis=-1)
        combined += (1.0 - covered) * background
        depth = np.where(covered > 0, gbuffer["position"][..., 3:4], BACKGROUND_DEPTH)
        h, w = covered.shape[0] // aa, covered.shape[1] // aa
        region = (slice(y0 // aa, y0 // aa + h), slice(x0 // aa, x0 // aa + w))
        output["Combined"][region] = _downsample(combined, aa)
        output["DiffDir"][region] = _downsample(diff_dir, aa)
        output["DiffCol"][region] = _downsample(albedo, aa)
        output["Emit"][region] = _downsample(emission, aa)
        output["Normal"][region] = _downsample(gbuffer["normal"][..., :3], aa)
        output["Depth"][region] = depth.reshape(h, aa, w, aa, 1).min(axis=(1, 3))

    @staticmethod
    def _sanitize(output: dict[str, np.ndarray], stats: Stats) -> None:
        """Never hand out NaN or Inf: replace them and say how many there were."""
        for name, image in output.items():
            bad = ~np.isfinite(image)
            if bad.any():
                stats.warnings.append(f"{int(bad.sum())} non-finite values in {name} set to 0")
                image[bad] = 0.0


class _FrameResources:
    """GPU objects of one frame: vertex buffers, g-buffer, shadow atlas and accumulator."""

    def __init__(self, ctx: moderngl.Context, geometry: WorldGeometry, shapes: WorldGeometry,
                 programs: ProgramCache) -> None:
        self.ctx = ctx
        self.programs = programs
        self._objects: list = []
        self._tile_objects: list = []
        self._atlas_objects: list = []
        self.scene_vbo = self._buffer(geometry)
        self.scene_vertices = geometry.vertex_count
        self.shape_vbo = self._buffer(shapes)
        self.shape_vertices = shapes.vertex_count
        self._atlas: tuple[moderngl.Texture, _Batch] | None = None
        self._light_table: moderngl.Texture | None = None

    def _own(self, obj):
        self._objects.append(obj)
        return obj

    def _buffer(self, geometry: WorldGeometry) -> moderngl.Buffer | None:
        if geometry.vertex_count == 0:
            return None
        return self._own(self.ctx.buffer(geometry.interleaved().tobytes()))

    def release(self) -> None:
        self._release_tile()
        for obj in self._atlas_objects + self._objects:
            obj.release()
        self._objects.clear()

    def _tile(self, obj):
        self._tile_objects.append(obj)
        return obj

    def _release_tile(self) -> None:
        for obj in self._tile_objects:
            obj.release()
        self._tile_objects.clear()

    # -- g-buffer -------------------------------------------------------------------------
    def gbuffer(self, camera: Camera, x0: int, x1: int, y0: int, y1: int, width: int,
                height: int) -> dict[str, np.ndarray]:
        self._release_tile()
        size = (x1 - x0, y1 - y0)
        names = ("position", "normal", "geometric", "albedo", "emission")
        textures = [self._tile(self.ctx.texture(size, 4, dtype="f4")) for _ in names]
        fbo = self._tile(self.ctx.framebuffer(textures, self._tile(
            self.ctx.depth_renderbuffer(size))))
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.BLEND | moderngl.CULL_FACE)
        projection = _tile_projection(camera.projection_matrix, x0, x1, y0, y1, width, height)
        view_projection = projection @ camera.view_matrix
        camera_to_world = np.linalg.inv(camera.view_matrix)
        uniforms = {
            "u_view_projection": tuple(view_projection.T.astype("f4").ravel()),
            "u_view": tuple(camera.view_matrix.T.astype("f4").ravel()),
            "u_camera_position": tuple(camera_to_world[:3, 3]),
            "u_camera_forward": tuple(-camera_to_world[:3, 2] /
                                      np.linalg.norm(camera_to_world[:3, 2])),
            "u_orthographic": camera.is_orthographic,
        }
        for vbo, count, defines in ((self.scene_vbo, self.scene_vertices, None),
                                    (self.shape_vbo, self.shape_vertices, {"ONE_SIDED": 1})):
            if vbo is None:
                continue
            program = self.programs.get("gbuffer_vert.glsl", "gbuffer_frag.glsl", defines)
            _set_uniforms(program, **uniforms)
            vao = self._tile(self.ctx.vertex_array(
                program, [(vbo, VERTEX_FORMAT, *VERTEX_ATTRIBUTES)], skip_errors=True))
            vao.render(moderngl.TRIANGLES, vertices=count)
        self.ctx.disable(moderngl.DEPTH_TEST)
        self._gbuffer_textures = dict(zip(names, textures, strict=True))
        return {name: np.frombuffer(tex.read(), dtype=np.float32).reshape(size[1], size[0], 4)
                for name, tex in self._gbuffer_textures.items()}

    def accumulator(self, width: int, height: int) -> moderngl.Framebuffer:
        texture = self._tile(self.ctx.texture((width, height), 4, dtype="f4"))
        fbo = self._tile(self.ctx.framebuffer([texture]))
        fbo.clear(0.0, 0.0, 0.0, 0.0)
        return fbo

    # -- shadows --------------------------------------------------------------------------
    def atlas(self, batch: _Batch, centre: np.ndarray, radius: float, reuse: bool
              ) -> moderngl.Texture:
        """Render the batch's shadow maps into one atlas of tiles (cube faces or directional)."""
        if reuse and self._atlas is not None and self._atlas[1] is batch:
            return self._atlas[0]
        for obj in self._atlas_objects:
            obj.release()
        self._atlas_objects.clear()
        keep = self._atlas_objects.append
        res = batch.resolution
        size = (batch.columns * res, batch.rows * res)
        texture = self.ctx.texture(size, 1, dtype="f4")
        depth = self.ctx.depth_renderbuffer(size)
        fbo = self.ctx.framebuffer([texture], depth)
        for obj in (texture, depth, fbo):
            keep(obj)
        fbo.use()
        fbo.clear(3.0e38, 0.0, 0.0, 0.0, depth=1.0)
        self._atlas = (texture, batch)
        s = batch.samples
        if self.scene_vbo is None or not s.casts_shadow.any():
            return texture
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.BLEND | moderngl.CULL_FACE)
        program = self.programs.get("shadow_vert.glsl", "shadow_frag.glsl")
        vao = self.ctx.vertex_array(program, [(self.scene_vbo, "3f 36x", "in_position")])
        keep(vao)
        _set_uniforms(program, u_scene_centre=tuple(centre), u_scene_radius=radius)
        near, far = self.near_far(s, centre, radius)
        for i in range(len(s)):
            directional = s.kind[i] == 3
            origin = s.axis[i] if directional else s.position[i]
            faces = (-1,) if directional else range(6)
            for k, face in enumerate(faces):
                tile = int(batch.first_tile[i]) + k
                x, y = (tile % batch.columns) * res, (tile // batch.columns) * res
                fbo.viewport = (x, y, res, res)
                fbo.scissor = (x, y, res, res)
                _set_uniforms(program, u_origin=tuple(origin), u_face=face,
                              u_near=float(near[i]), u_far=float(far[i]))
                vao.render(moderngl.TRIANGLES, vertices=self.scene_vertices)
        fbo.scissor = None
        self.ctx.disable(moderngl.DEPTH_TEST)
        return texture

    @staticmethod
    def near_far(samples: LightSamples, centre: np.ndarray, radius: float
                 ) -> tuple[np.ndarray, np.ndarray]:
        """Clip distances of each sample's cube maps, relative to the scene's size."""
        far = np.linalg.norm(samples.position - centre, axis=1) + radius * 1.01
        near = np.maximum(far * 1e-5, radius * 1e-6)
        return near, far

    # -- shading --------------------------------------------------------------------------
    def shade(self, batch: _Batch, atlas: moderngl.Texture, gbuffer: dict[str, np.ndarray],
              accumulator: moderngl.Framebuffer, centre: np.ndarray, radius: float,
              bias: float) -> None:
        """Add the batch's direct light to the accumulator (additive blending)."""
        s = batch.samples
        near, far = self.near_far(s, centre, radius)
        table = s.table(batch.first_tile, near, far)
        light_table = self.ctx.texture((4, len(s)), 4, table.tobytes(), dtype="f4")
        textures = self._gbuffer_textures
        for unit, name in enumerate(("position", "normal", "geometric")):
            textures[name].use(unit)
        light_table.use(3)
        atlas.use(4)
        program = self.programs.get("fullscreen_vert.glsl", "direct_frag.glsl")
        _set_uniforms(program, u_position=0, u_normal=1, u_geometric=2, u_light_table=3,
                      u_shadow_atlas=4, u_atlas_columns=batch.columns,
                      u_scene_centre=tuple(centre), u_scene_radius=radius, u_shadow_bias=bias,
                      u_first=0, u_count=len(s))
        accumulator.use()
        self.ctx.enable(moderngl.BLEND)
        self.ctx.blend_func = moderngl.ONE, moderngl.ONE
        vao = self.ctx.vertex_array(program, [])
        vao.render(moderngl.TRIANGLES, vertices=3)
        self.ctx.disable(moderngl.BLEND)
        vao.release()
        light_table.release()

    def read_accumulator(self, accumulator: moderngl.Framebuffer) -> np.ndarray:
        w, h = accumulator.size
        return np.frombuffer(accumulator.read(components=4, dtype="f4"),
                             dtype=np.float32).reshape(h, w, 4)
