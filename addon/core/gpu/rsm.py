"""First-bounce VPLs from reflective shadow maps (the seed's GPU route, Dachsbacher & Stamminger
2005): render position, normal and albedo of what each light sees, give every texel the flux
it receives (intensity × the texel's solid angle, or irradiance × its area for the sun), and
importance-sample the first hits by reflected flux. Only lights are covered (not the world or
emissive surfaces); further bounces continue from these hits as traced paths (core/vpl.py)."""

from __future__ import annotations

from dataclasses import replace

import moderngl
import numpy as np

from ..scene.geometry import empty_geometry
from ..scene.model import Scene, World
from ..settings import Settings
from ..transport.light_profiles import profile_towards
from ..transport.lights import (
    KIND_COSINE,
    LightSamples,
    build_light_samples,
    spot_mask,
    spread_attenuation,
)
from ..transport.vpl import LUMINANCE, SurfaceHits
from .gl import ProgramCache, set_uniforms
from .scene_buffers import SceneBuffers
from .shadow_atlas import TileTable, draw_tiles, tile_table


def rsm_light_samples(scene: Scene, settings: Settings) -> LightSamples:
    """Each light whose light bounces (Max Bounces above 0) as one point seen from: sphere
    lights and area lights from their centre (area lights keep their cosine emission), suns
    without their angle."""
    lights = [replace(light, radius=0.0, sun_angle=0.0, size_x=0.0, size_y=0.0)
              for light in scene.lights if light.max_bounces > 0]
    plain = Scene([], lights, World(), scene.camera)
    samples = build_light_samples(plain, empty_geometry(),
                                  replace(settings, light_samples=1), [])
    samples.resolution = np.full(len(samples), settings.rsm_resolution)
    samples.casts_shadow = np.ones(len(samples), bool)
    return samples


def _texel_solid_angle(resolution: int) -> np.ndarray:
    """Solid angle of every texel of a 90° cube face (resolution × resolution)."""
    c = (np.arange(resolution) + 0.5) / resolution * 2 - 1
    u, v = np.meshgrid(c, c)
    return (2.0 / resolution) ** 2 / (1 + u * u + v * v) ** 1.5


def render_rsm(ctx: moderngl.Context, programs: ProgramCache, scene: SceneBuffers,
               samples: LightSamples, centre: np.ndarray, radius: float
               ) -> tuple[TileTable, np.ndarray, np.ndarray, np.ndarray]:
    """The tiles and their position, normal and albedo images (tiles, res, res, 4)."""
    res = int(samples.resolution[0]) if len(samples) else 1
    first_tile = np.concatenate([[0], np.cumsum(samples.tiles_per_sample)[:-1]])
    count = int(samples.tiles_per_sample.sum())
    columns = int(np.ceil(np.sqrt(count)))
    table = tile_table(samples, first_tile, columns, centre, radius)
    size = (columns * res, -(-count // columns) * res)
    objects = [table.texture(ctx)]
    targets = [ctx.texture(size, 4, dtype="f4") for _ in range(3)]
    objects += targets
    objects.append(ctx.depth_renderbuffer(size))
    fbo = ctx.framebuffer(targets, objects[-1])
    objects.append(fbo)
    try:
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        objects[0].use(0)
        streams, defines = scene.cutout_streams()
        program = programs.get("shadow_vert.glsl", "rsm_frag.glsl", {"TRIANGLES": 1, **defines})
        set_uniforms(program, u_tiles=0, u_atlas_tiles=(columns, size[1] // res),
                     u_scene_centre=tuple(centre), u_scene_radius=radius)
        scene.bind_cutouts(program)
        vao = ctx.vertex_array(program, streams)
        objects.append(vao)
        draw_tiles(ctx, vao, scene.vertex_count, count)
        images = [np.frombuffer(t.read(), np.float32).reshape(size[1] // res, res, columns, res,
                                                              4).transpose(0, 2, 1, 3, 4)
                  .reshape(-1, res, res, 4)[:count] for t in targets]
    finally:
        for obj in reversed(objects):
            obj.release()
    return table, *images


def rsm_hits(table: TileTable, position: np.ndarray, normal: np.ndarray, albedo: np.ndarray,
             samples: LightSamples, radius: float, count: int, seed: int) -> SurfaceHits:
    """``count`` first hits importance-sampled from the RSM texels by reflected flux, each
    carrying flux Φ/(count p); ranks are a random permutation, so continuing paths are not
    chosen by where they were sampled."""
    res = position.shape[1]
    solid_angle = _texel_solid_angle(res)
    flux = np.zeros((*position.shape[:3], 3))
    for t, (i, face) in enumerate(zip(table.sample, table.face, strict=True)):
        seen = position[t, ..., 3] > 0
        if face < 0:
            flux[t][seen] = samples.intensity[i] * (2 * radius / res) ** 2
            continue
        direction = position[t, ..., :3] - samples.position[i]
        direction /= np.maximum(np.linalg.norm(direction, axis=-1, keepdims=True), 1e-300)
        emitted = np.ones(direction.shape[:2])
        if samples.kind[i] == KIND_COSINE:
            cos = direction @ samples.axis[i]
            emitted = np.maximum(cos, 0.0) * spread_attenuation(cos, *samples.spread[i])
        else:
            emitted = spot_mask(direction @ samples.axis[i], samples.spot_cos[i],
                                samples.spot_smooth[i])
        if samples.has_profiles and samples.profile[i] >= 0:
            light = samples.profiles.lights[samples.profile[i]]
            emitted = emitted * profile_towards(light, direction.reshape(-1, 3)).reshape(
                emitted.shape)
        intensity = samples.intensity[i] * (emitted * solid_angle)[..., None]
        flux[t][seen] = intensity[seen]
    weight = (_texels(flux * albedo[..., :3]) @ LUMINANCE)
    rng = np.random.default_rng(seed)
    if weight.sum() <= 0 or count == 0:
        return SurfaceHits(*(np.zeros((0, 3)),) * 4, np.zeros(0, int))
    cdf = np.cumsum(weight) / weight.sum()
    u = (np.arange(count) + rng.uniform()) / count
    pick = np.minimum(np.searchsorted(cdf, u, side="right"), len(cdf) - 1)
    probability = weight[pick] / weight.sum()
    return SurfaceHits(_texels(position)[pick, :3].astype(np.float64),
                       _texels(normal)[pick, :3].astype(np.float64),
                       _texels(albedo)[pick, :3].astype(np.float64),
                       _texels(flux)[pick] / (count * probability[:, None]),
                       rng.permutation(count))


def _texels(image: np.ndarray) -> np.ndarray:
    return image.reshape(-1, image.shape[-1])
