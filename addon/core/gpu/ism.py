"""Imperfect shadow maps (Ritschel et al. 2008; the seed's ISM steps 2 and 3): a low-quality
paraboloid depth map per VPL, splatted from a few thousand surface points and hole-filled by
pull-push, all VPLs at once on the GPU (OpenGL 4.3 compute shaders).

1. Points (``prepare``, ``gpu_shaders/ism_points_lib.glsl``): a set of ``points_per_vpl``
   points per atlas tile, drawn on the GPU inside the splat from hashes of (seed, tile, point
   index), each set uniform by area and stratified on its own (systematic sampling of the
   triangles' area CDF with a hashed offset, a hashed shift of the R2 sequence within each
   triangle). The CPU computes and uploads only the CDF, once per geometry version
   (O(triangles)); points are triangle index + barycentrics, so they follow moved or deformed
   triangles.
2. Splat (``ism_splat_comp.glsl``): each VPL's points go into its tile of an atlas of
   paraboloid maps (the hemisphere around the VPL's normal, ``gpu_shaders/ism_lib.glsl``) with
   ``imageAtomicMin`` of their distance. A point stands for a disc of its share of the
   surface, of ``footprint_scale`` times that radius, and covers the texels inside the ellipse
   the disc projects to (grown by half a texel, at most ``max_footprint`` of the tile edge
   across): long and thin where the surface is seen at a grazing angle, so walls seen edge-on
   close without bloating everything else; each texel of it holds the depth of the point's
   tangent plane along that texel's ray. (Directional maps splat squares of the projected
   area, rounded up or down at random to keep the mean area.)
3. Pull-push (``ism_pull_comp.glsl``, ``ism_push_comp.glsl``): ``pull_push_levels`` halvings of
   every tile. Pull averages the valid texels of each 2x2 block (equal weights); push fills the
   empty texels of each finer level with the bilinear interpolation of the valid texels of the
   coarser level (weights renormalised). Valid texels are kept, except on the finest level
   those the coarser level shows over ``BEHIND`` times nearer on both sides (left and right,
   or below and above): a farther surface seen through a gap between a nearer surface's
   splats, which pull-push alone never replaces (the receiver's own wall behind a closed
   wall: light got through it; issue 19, the closed cube of tests/stability/test_bad_input.py
   leaked 19.1 % of the open wall's light, now 9.6 %, mostly along the wall joints, within
   the lookup's bias); beside a silhouette only one side is nearer, so silhouettes stay.
   They are filled like holes. Texels still empty after the coarsest level
   become ``FAR`` (lit). log2(resolution) levels fill every hole.

Choices, measured against ray-traced visibility (64 VPLs on a 70k-triangle room with boxes,
3000 receivers each, 8k points per VPL; "leak": shadowed receivers found lit, "error": mean
|ISM visibility - exact|): single-texel splats leave the maps so sparse that most shadowed
receivers are lit (leak 80 % at 256² without pull-push, 41 % with it: pull-push fills holes
but cannot remove a farther surface splatted into a gap of a nearer one, since it never moves
a valid texel); footprints of scale 1.25 bring the error from 0.16-0.17 to 0.047 (128²) and
0.040 (256²), a larger scale shadows too much (1.5: 0.052, 0.047); plane depths beat the
point's own depth over the footprint (0.047 against 0.056 at 128²) for 20 % more splat time;
bilinear push beats nearest (0.17 against 0.23 for single texels at 256²). With footprints
pull-push changes the error by at most 0.003 (few holes are left) but still guarantees a
depth in every texel. The lookup's bias of 1 texel does best (0.5 and 2: 0.060, 0.056).

The shading side calls ``ism_visibility`` of ``ism_lib.glsl`` on the atlas that ``render``
returns (tile k = VPL k at column k % columns, row k // columns); ``visibility`` runs the same
lookup for a batch of points, for tests and debugging.
"""

from __future__ import annotations

import math
import time

import moderngl
import numpy as np

from ..scene.surface_points import SurfacePoints, area_cdf, cdf_guide
from ..scene.vectors import triangle_areas, unit
from .gl import ProgramCache, require_compute

BINDING_CDF = 20  # ISM_BINDING_CDF in ism_points_lib.glsl
BINDING_VERTICES = 21  # ISM_BINDING_VERTICES in ism_splat_comp.glsl
BINDING_VPLS = 22  # ISM_BINDING_VPLS in ism_splat_comp.glsl and ism_lookup_comp.glsl
BINDING_QUERIES = 23  # ISM_BINDING_QUERIES in ism_lookup_comp.glsl
BINDING_RESULTS = 24  # ISM_BINDING_RESULTS in ism_lookup_comp.glsl
BINDING_TILE_LIST = 25  # ISM_TILE_LIST of ism_tile_list_lib.glsl: tiles a partial update does
BINDING_POINT_OUT = 26  # ISM_BINDING_POINT_OUT in ism_points_comp.glsl
BINDING_GUIDE = 27  # ISM_BINDING_GUIDE in ism_points_lib.glsl
POINT_LOCAL_SIZE = 64  # local_size_x of ism_splat_comp.glsl and ism_lookup_comp.glsl
IMAGE_LOCAL_SIZE = 8  # local_size_x and _y of ism_pull_comp.glsl and ism_push_comp.glsl
SPLAT_POINTS_PER_DISPATCH = 1 << 20  # a splat dispatch's points (VPLs × points per VPL): about
# 0.15 s on llvmpipe, which holds Python's lock for a whole dispatch (Ctrl-C waits for it)
FAR = float(np.float32(3.0e38))  # ISM_FAR in ism_lib.glsl: the depth of texels left empty
EMPTY_BITS = 0xFFFFFFFF  # ISM_EMPTY_BITS: an empty splat texel, above every float's bits
EMPTY_STRIP_TEXELS = 1 << 20  # texels per upload that fills a new splat image with EMPTY_BITS
BEHIND = 1.25  # ISM_BEHIND: a splat this many times as far as the surface around is a hole
FOOTPRINT_SCALE = 1.1  # the footprint disc's radius / that of the point's share of the
# surface; 0: one texel. Measured with elliptic footprints at 1.0 / 1.1 / 1.25: the interior
# 8.6 / 8.8 / 9.1 % error, the Cornell box 5.33 / 5.35 / 5.37 %, the closed cube's leak
# 12.0 / 9.1 / 7.2 % (bound 12 %); square footprints at 1.25 gave 9.3 %, 5.31 % and 10.3 %.
MAX_FOOTPRINT = 1 / 8  # largest footprint side, as a fraction of the tile edge
ISM_BIAS_TEXELS = 1.0  # depth tolerance in texels (the receiver is lifted 1.5× that along its
# normal: ISM_NORMAL_OFFSET in gpu_shaders/ism_lib.glsl); measured best against exact visibility

QUERY_DTYPE = np.dtype([("world", "<f4", 3), ("vpl", "<i4"), ("normal", "<f4", 3),
                        ("pad", "<f4")])


def atlas_grid(tiles: int) -> tuple[int, int]:
    """(columns, rows) of an atlas of ``tiles`` tiles (at least one): ceil(sqrt(n)) columns."""
    columns = max(1, math.ceil(math.sqrt(tiles)))
    return columns, max(1, -(-tiles // columns))


def level_resolutions(resolution: int, levels: int) -> list[int]:
    """Tile edge of each pull-push level, finest first: each halves the last (rounding up),
    ``levels`` times or until one texel, whichever comes first."""
    sizes = [resolution]
    while len(sizes) <= levels and sizes[-1] > 1:
        sizes.append((sizes[-1] + 1) // 2)
    return sizes


def _vertices(triangles: np.ndarray, passed: np.ndarray | None = None) -> np.ndarray:
    """(T * 3, 4) float32: the vertices as vec4, at least one; w 1 on ``passed`` (T,)
    triangles' (ism_splat_comp.glsl)."""
    tris = np.asarray(triangles, np.float32).reshape(-1, 3)
    out = np.zeros((max(1, len(tris)), 4), np.float32)
    out[:len(tris), :3] = tris
    if passed is not None:
        out[:len(tris), 3] = np.repeat(np.asarray(passed, np.float32), 3)
    return out


def _vpl_data(position: np.ndarray, normal: np.ndarray,
              directional: np.ndarray | None = None, tiles: np.ndarray | None = None
              ) -> np.ndarray:
    """(2 n, 4) float32, (position, directional flag), (unit normal or direction of travel,
    atlas tile: k unless ``tiles`` says otherwise) per VPL, at least one row pair."""
    p = np.asarray(position, np.float64).reshape(-1, 3)
    n = np.asarray(normal, np.float64).reshape(-1, 3)
    if len(p) != len(n):
        raise ValueError(f"{len(p)} VPL positions but {len(n)} normals")
    out = np.zeros((max(1, len(p)), 2, 4), np.float32)
    out[:len(p), 0, :3] = p
    out[:len(p), 1, :3] = unit(n)
    if directional is not None:
        out[:len(p), 0, 3] = directional
    out[:len(p), 1, 3] = np.arange(len(p)) if tiles is None else tiles
    return out.reshape(-1, 4)


class ImperfectShadowMaps:
    """Imperfect shadow maps of many VPLs at once (needs OpenGL 4.3).

    ``prepare`` once per geometry version (the area CDF the points are drawn from), then
    ``render`` per frame with the current triangles and VPLs. ``timings`` holds the seconds
    of the last render's stages (measured with ``ctx.finish()``)."""

    def __init__(self, ctx: moderngl.Context, programs: ProgramCache,
                 footprint_scale: float = FOOTPRINT_SCALE,
                 max_footprint: float = MAX_FOOTPRINT) -> None:
        require_compute(ctx)
        self.ctx = ctx
        self.programs = programs
        self.footprint_scale = footprint_scale
        self.max_footprint = max_footprint
        self.columns = 1
        self.resolution = 1
        self.timings: dict[str, float] = {}
        self._prepared: tuple | None = None  # (triangle count, version) of the uploaded CDF
        self._has_area = False
        self._points_per_vpl = 0
        self._passed: np.ndarray | None = None  # (T,) triangles splatted as lit (prepare)
        self._seed = 0
        self._triangle_count = 0
        self._buffers: dict[int, moderngl.Buffer] = {}
        self._layout: tuple | None = None  # (width, height, resolution, level resolutions)
        self._splat: moderngl.Texture | None = None
        self._atlas: moderngl.Texture | None = None
        self._levels: list[moderngl.Texture] = []
        self._scene_sphere: tuple[np.ndarray, float] = (np.zeros(3), 1.0)
        self._listed = 0  # tiles of the tile list the current pull-push runs on (0: all)

    # -- points ------------------------------------------------------------------------------

    def prepare(self, triangles: np.ndarray, points_per_vpl: int, seed: int,
                version: object = None, coverage: np.ndarray | None = None,
                passed: np.ndarray | None = None) -> bool:
        """Draw ``points_per_vpl`` points per map from ``seed`` from now on, and upload the
        triangles' area CDF (each area times its ``coverage`` (T,) where given: cutouts hold
        fewer points) unless the triangle count and the caller's geometry ``version`` repeat
        (the points follow moved or deformed triangles meanwhile); True when it was
        uploaded. The points of ``passed`` (T,) triangles (diffuse bounces pass them) are
        splatted as lit texels: they shade nothing, and keep pull-push from filling the maps
        where they lie with nearer surfaces' depths (which shaded them from behind)."""
        self._points_per_vpl = points_per_vpl
        self._passed = passed
        self._seed = seed & 0xFFFFFFFF
        count = len(np.asarray(triangles).reshape(-1, 3, 3))
        if (count, version) == self._prepared:
            return False
        cdf = area_cdf(triangles, coverage)
        limit = int(self.ctx.info["GL_MAX_SHADER_STORAGE_BLOCK_SIZE"])
        if cdf is not None and cdf.nbytes + 4 > limit:
            raise ValueError(f"the area table of {count} triangles needs {cdf.nbytes >> 20} "
                             f"MiB of storage buffer; this GPU allows {limit >> 20} MiB")
        self._write(BINDING_CDF, cdf if cdf is not None else np.ones(1, np.float32))
        self._write(BINDING_GUIDE, cdf_guide(cdf) if cdf is not None else np.zeros(2, np.uint32))
        self._has_area = cdf is not None
        self._triangle_count = count
        self._prepared = (count, version)
        return True

    @property
    def prepared_triangles(self) -> int | None:
        """The triangle count whose area CDF is uploaded, or None before ``prepare``."""
        return None if self._prepared is None else self._prepared[0]

    def points(self, first_set: int, sets: int) -> SurfacePoints:
        """The points the splat draws for maps (sets) ``first_set`` .. ``first_set + sets - 1``
        of the prepared triangles, read back from the GPU (for tests and benchmarks)."""
        if self._prepared is None:
            raise RuntimeError("call prepare() before points()")
        count = self._points_per_vpl * sets if self._has_area else 0
        if count == 0:
            return SurfacePoints(np.zeros(0, np.int32), np.zeros((0, 2), np.float32))
        out = self._buffer(BINDING_POINT_OUT, 16 * count)
        out.bind_to_storage_buffer(BINDING_POINT_OUT)
        shader = self.programs.compute("ism_points_comp.glsl")
        self._point_uniforms(shader)
        shader["u_first_set"] = first_set
        shader.run(-(-self._points_per_vpl // POINT_LOCAL_SIZE), sets)
        self.ctx.memory_barrier(moderngl.BUFFER_UPDATE_BARRIER_BIT)
        data = np.frombuffer(out.read(16 * count), np.uint32).reshape(-1, 4)
        return SurfacePoints(data[:, 0].astype(np.int32), data[:, 1:3].view(np.float32).copy())

    # -- per frame -----------------------------------------------------------------------------

    def render(self, triangles: np.ndarray, vpl_position: np.ndarray, vpl_normal: np.ndarray,
               resolution: int, pull_push_levels: int, directional: np.ndarray | None = None,
               scene_sphere: tuple[np.ndarray, float] = (np.zeros(3), 1.0),
               tiles: np.ndarray | None = None, tile_count: int = 0) -> moderngl.Texture:
        """The r32f depth atlas of the VPLs (n, 3) with ``resolution``² tiles (the map in tile
        k splats point set k, see ``points``). ``pull_push_levels`` = 0 keeps the raw
        splats. Where ``directional`` is true the "VPL" is a direction of travel
        (``vpl_normal``) and its map is orthographic over ``scene_sphere`` (centre, radius).

        A partial update: with ``tiles``, VPL k is rendered into tile ``tiles[k]`` of an atlas
        of ``tile_count`` tiles and every other tile keeps what an earlier render with the same
        layout, resolution and levels left there."""
        self._scene_sphere = scene_sphere
        if self._prepared is None:
            raise RuntimeError("call prepare() before render()")
        tris = np.asarray(triangles, np.float32).reshape(-1, 3, 3)
        if len(tris) != self._triangle_count:
            raise ValueError(f"{len(tris)} triangles; the points were sampled on "
                             f"{self._triangle_count}")
        start = time.perf_counter()
        positions = np.asarray(vpl_position, np.float64).reshape(-1, 3)
        vpl_count = len(positions)
        self._allocate(max(vpl_count, tile_count), resolution, pull_push_levels)
        self._write(BINDING_VERTICES, _vertices(tris, self._passed))
        self._write(BINDING_VPLS, _vpl_data(positions, vpl_normal, directional, tiles))
        listed = 0
        if tiles is not None:
            listed = len(tiles)
            self._write(BINDING_TILE_LIST, np.asarray(tiles, np.int32).reshape(-1) if listed
                        else np.zeros(1, np.int32))
        self.ctx.finish()
        uploaded = time.perf_counter()
        if self._has_area and self._points_per_vpl and vpl_count:
            self._run_splat(vpl_count, triangle_areas(tris).sum())
        self.ctx.finish()
        splatted = time.perf_counter()
        if tiles is None or listed:
            self._run_pull_push(pull_push_levels, listed if tiles is not None else 0)
        self.ctx.finish()
        self.timings = {"upload": uploaded - start, "splat": splatted - uploaded,
                        "pull_push": time.perf_counter() - splatted}
        return self._atlas

    @property
    def atlas(self) -> moderngl.Texture | None:
        """The atlas of the last ``render`` (None before the first, or once taken)."""
        return self._atlas

    def take_atlas(self) -> moderngl.Texture:
        """Hand the last ``render``'s atlas to the caller, who releases it; the next render
        fills a new one (a frame whose VPLs need several atlases keeps each)."""
        if self._atlas is None:
            raise RuntimeError("call render() before take_atlas()")
        taken, self._atlas = self._atlas, None
        return taken

    def read_atlas(self) -> np.ndarray:
        """The last atlas as a (rows * resolution, columns * resolution) float32 array."""
        width, height = self._atlas.size
        return np.frombuffer(self._atlas.read(), np.float32).reshape(height, width).copy()

    def pull_push(self, depth: np.ndarray, resolution: int, levels: int) -> np.ndarray:
        """Run pull-push alone on a sparse depth atlas (tiles of ``resolution``², non-finite =
        empty) and return the filled atlas, as ``render`` would fill its splats."""
        depth = np.asarray(depth, np.float32)
        height, width = depth.shape
        if width % resolution or height % resolution:
            raise ValueError(f"a {width}x{height} atlas is no grid of {resolution}² tiles")
        self._allocate_images(width, height, resolution, levels)
        self.columns = width // resolution
        bits = depth.view(np.uint32).copy()
        bits[~np.isfinite(depth)] = EMPTY_BITS
        self._splat.write(bits.tobytes())
        self._run_pull_push(levels)
        return self.read_atlas()

    def visibility(self, vpl: np.ndarray, world: np.ndarray, normal: np.ndarray,
                   bias: float = ISM_BIAS_TEXELS) -> np.ndarray:
        """``ism_visibility`` of the last atlas for points ``world`` (Q, 3) with geometric
        normals (Q, 3), each towards VPL ``vpl[q]`` of the last render: (Q,) float32."""
        queries = np.zeros(max(1, len(world)), QUERY_DTYPE)
        queries["world"][:len(world)] = world
        queries["normal"][:len(world)] = normal
        queries["vpl"][:len(world)] = vpl
        self._write(BINDING_QUERIES, queries)
        results = self._buffer(BINDING_RESULTS, 4 * len(queries))
        results.bind_to_storage_buffer(BINDING_RESULTS)
        for binding in (BINDING_VPLS, BINDING_QUERIES):
            self._buffers[binding].bind_to_storage_buffer(binding)
        shader = self.programs.compute("ism_lookup_comp.glsl")
        self._atlas.use(0)
        shader["u_atlas"] = 0
        shader["u_columns"] = self.columns
        shader["u_resolution"] = float(self.resolution)
        shader["u_bias"] = bias
        shader["u_count"] = len(world)
        shader.run(-(-len(queries) // POINT_LOCAL_SIZE))
        self.ctx.memory_barrier(moderngl.BUFFER_UPDATE_BARRIER_BIT)
        return np.frombuffer(results.read(4 * len(world)), np.float32).copy()

    def memory_bytes(self) -> int:
        """GPU memory of the splat image, the atlas and the pull-push levels."""
        return sum(t.width * t.height * 4 for t in (self._splat, self._atlas, *self._levels)
                   if t is not None)

    def release(self) -> None:
        for buffer in self._buffers.values():
            buffer.release()
        self._buffers.clear()
        self._release_images()
        self._prepared = None

    # -- internals -----------------------------------------------------------------------------

    def _buffer(self, binding: int, nbytes: int) -> moderngl.Buffer:
        """The storage buffer of ``binding``, grown to at least ``nbytes``."""
        buffer = self._buffers.get(binding)
        if buffer is None or buffer.size < nbytes:
            if buffer is not None:
                buffer.release()
            buffer = self._buffers[binding] = self.ctx.buffer(reserve=nbytes)
        return buffer

    def _write(self, binding: int, data: np.ndarray) -> None:
        self._buffer(binding, data.nbytes).write(np.ascontiguousarray(data).tobytes())

    def _allocate(self, vpl_count: int, resolution: int, levels: int) -> None:
        columns, rows = atlas_grid(vpl_count)
        limit = int(self.ctx.info["GL_MAX_TEXTURE_SIZE"])
        if max(columns, rows) * resolution > limit:
            raise ValueError(f"{vpl_count} tiles of {resolution}² need a "
                             f"{columns * resolution}² atlas; this GPU allows {limit}²")
        if vpl_count > 65535:
            raise ValueError(f"{vpl_count} VPLs are more than one dispatch can splat")
        self.columns = columns
        self._allocate_images(columns * resolution, rows * resolution, resolution, levels)

    def _allocate_images(self, width: int, height: int, resolution: int, levels: int) -> None:
        """The splat image (all empty), the atlas and the coarser levels, kept while the
        layout and level count repeat."""
        self.resolution = resolution
        sizes = level_resolutions(resolution, levels)[1:]
        if self._layout == (width, height, resolution, tuple(sizes)):
            if self._atlas is None:  # handed over by take_atlas
                self._atlas = self._new_atlas(width, height)
            return
        self._release_images()
        self._layout = (width, height, resolution, tuple(sizes))
        self._splat = self.ctx.texture((width, height), 1, dtype="u4")
        rows = max(1, EMPTY_STRIP_TEXELS // width)  # a strip at a time: no atlas-sized array
        strip = np.full(width * rows, EMPTY_BITS, np.uint32)
        for y in range(0, height, rows):
            count = min(rows, height - y)
            self._splat.write(strip[:width * count], viewport=(0, y, width, count))
        self._atlas = self._new_atlas(width, height)
        tiles = (width // resolution, height // resolution)
        self._levels = [self.ctx.texture((tiles[0] * s, tiles[1] * s), 1, dtype="f4")
                        for s in sizes]

    def _new_atlas(self, width: int, height: int) -> moderngl.Texture:
        atlas = self.ctx.texture((width, height), 1, dtype="f4")
        atlas.filter = (moderngl.NEAREST, moderngl.NEAREST)
        return atlas

    def _release_images(self) -> None:
        for texture in (self._splat, self._atlas, *self._levels):
            if texture is not None:
                texture.release()
        self._splat = self._atlas = None
        self._levels = []
        self._layout = None

    def _run_splat(self, vpl_count: int, total_area: float) -> None:
        for binding in (BINDING_VERTICES, BINDING_VPLS):
            self._buffers[binding].bind_to_storage_buffer(binding)
        shader = self.programs.compute("ism_splat_comp.glsl")
        self._splat.bind_to_image(0, read=True, write=True)
        self._point_uniforms(shader)
        shader["u_columns"] = self.columns
        shader["u_resolution"] = self.resolution
        shader["u_point_area"] = total_area / self._points_per_vpl
        shader["u_footprint_scale"] = self.footprint_scale
        shader["u_max_footprint"] = max(1, round(self.resolution * self.max_footprint))
        centre, radius = self._scene_sphere
        shader["u_scene_centre"] = tuple(float(c) for c in centre)
        shader["u_scene_radius"] = float(radius)
        groups = -(-self._points_per_vpl // POINT_LOCAL_SIZE)
        rows = max(1, SPLAT_POINTS_PER_DISPATCH // max(1, self._points_per_vpl))
        for first in range(0, vpl_count, rows):  # Ctrl-C and Esc are heard between them
            shader["u_first_row"] = first
            shader.run(groups, min(rows, vpl_count - first))
            self.ctx.finish()
        self.ctx.memory_barrier(moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT)

    def _point_uniforms(self, shader: moderngl.ComputeShader) -> None:
        """Bind the area CDF and set the uniforms of ism_points_lib.glsl."""
        for binding in (BINDING_CDF, BINDING_GUIDE):
            self._buffers[binding].bind_to_storage_buffer(binding)
        shader["u_points_per_vpl"] = self._points_per_vpl
        shader["u_triangle_count"] = self._triangle_count
        shader["u_point_seed"] = self._seed

    def _run_pull_push(self, levels: int, listed: int = 0) -> None:
        """Pull into each coarser level, push back down to each finer level in place, and
        last into the atlas (which resets the splat image to empty for the next frame); with
        ``listed`` > 0, only the first ``listed`` tiles of the tile list."""
        images = [self._splat, *self._levels]
        sizes = level_resolutions(self.resolution, levels)
        self._listed = listed
        if listed:
            self._buffers[BINDING_TILE_LIST].bind_to_storage_buffer(BINDING_TILE_LIST)
        for level in range(len(sizes) - 1):
            self._pull(level, images[level], images[level + 1], sizes[level], sizes[level + 1])
        for level in range(len(sizes) - 2, 0, -1):
            self._push(images[level], images[level], images[level + 1], sizes[level],
                       sizes[level + 1], -1.0)
        coarse = (images[1], sizes[1]) if len(sizes) > 1 else (self._atlas, 0)
        self._push(self._splat, self._atlas, coarse[0], sizes[0], coarse[1], FAR)

    def _defines(self, fine_splat: bool) -> dict[str, object] | None:
        """Defines of a pull or push pass: the splat image as input, a partial update."""
        defines: dict[str, object] = {"ISM_FINE_SPLAT": 1} if fine_splat else {}
        if self._listed:
            defines["ISM_TILE_LIST"] = BINDING_TILE_LIST
        return defines or None

    def _pull(self, level: int, fine: moderngl.Texture, coarse: moderngl.Texture,
              fine_resolution: int, coarse_resolution: int) -> None:
        shader = self.programs.compute("ism_pull_comp.glsl", self._defines(level == 0))
        fine.bind_to_image(0, read=True, write=False)
        coarse.bind_to_image(1, read=False, write=True)
        shader["u_fine_resolution"] = fine_resolution
        shader["u_coarse_resolution"] = coarse_resolution
        shader["u_coarse_size"] = coarse.size
        self._run_image_pass(shader, coarse.size, coarse_resolution)

    def _push(self, fine: moderngl.Texture, target: moderngl.Texture, coarse: moderngl.Texture,
              resolution: int, coarse_resolution: int, unfilled: float) -> None:
        """Fill the empty texels of ``fine`` from ``coarse`` (none if ``coarse_resolution`` is
        0) into ``target``: ``fine`` itself, or the atlas when ``fine`` is the splat image."""
        from_splat = fine is self._splat
        shader = self.programs.compute("ism_push_comp.glsl", self._defines(from_splat))
        fine.bind_to_image(0, read=True, write=True)
        coarse.bind_to_image(1, read=True, write=False)
        if from_splat:
            target.bind_to_image(2, read=False, write=True)
        shader["u_resolution"] = resolution
        shader["u_coarse_resolution"] = coarse_resolution
        shader["u_size"] = fine.size
        shader["u_unfilled"] = unfilled
        self._run_image_pass(shader, fine.size, resolution)

    def _run_image_pass(self, shader: moderngl.ComputeShader, size: tuple[int, int],
                        resolution: int) -> None:
        """One invocation per texel of the level, or of each listed tile's part of it."""
        if self._listed:
            groups = -(-resolution // IMAGE_LOCAL_SIZE)
            shader.run(groups, groups, self._listed)
        else:
            shader.run(-(-size[0] // IMAGE_LOCAL_SIZE), -(-size[1] // IMAGE_LOCAL_SIZE))
        self.ctx.memory_barrier()  # all bits: the atlas is next fetched, read or written
