"""A WorldGeometry on the GPU: its position and normal buffers, its material table and each
triangle's row (as textures read by gpu_shaders/materials_lib.glsl; with light or shadow
linking each triangle's receiver set beside its row, and with shadow linking its blocker set
after that), and its UVs and image textures when textured."""

from __future__ import annotations

import moderngl
import numpy as np

from ..scene import principled
from ..scene.geometry import WorldGeometry
from .gl import set_uniforms
from .texture_array import upload as upload_textures

MATERIAL_UNITS = 6, 7  # texture units of the triangles' rows and the material table (units
# 0-5 are the passes' own)
GGX_TABLES_UNIT = 8  # the glossy lobe's tables (principled_lib.glsl)
CUTOUT_TEXTURE_UNITS = 9, 10  # the image textures for the cutouts of shadow maps and RSMs
TABLE_WIDTH = 4096  # texels per line of both tables


def table_texture(ctx: moderngl.Context, values: np.ndarray, components: int, dtype: str
                   ) -> moderngl.Texture:
    """``values`` (n, components) as a texture of TABLE_WIDTH-texel lines (entry i at
    (i % width, i // width)); ValueError when it exceeds the GPU's texture size."""
    count = max(len(values), 1)
    width = min(count, TABLE_WIDTH)
    height = -(-count // width)
    if height > ctx.info["GL_MAX_TEXTURE_SIZE"]:
        raise ValueError(f"{len(values):,} table entries exceed the GPU's texture size")
    padded = np.zeros((width * height, components), values.dtype)
    padded[:len(values)] = values
    texture = ctx.texture((width, height), components, padded, dtype=dtype)
    texture.filter = moderngl.NEAREST, moderngl.NEAREST
    return texture


class SceneBuffers:
    """GPU copies of one WorldGeometry with at least one triangle; release() frees them."""

    def __init__(self, ctx: moderngl.Context, geometry: WorldGeometry) -> None:
        self.vertex_count = geometry.vertex_count
        self._objects: list = []
        try:
            self.positions = self._own(ctx.buffer(geometry.positions))
            self.normals = self._own(ctx.buffer(geometry.normals))
            rows = geometry.triangle_material.astype(np.int32, copy=False)[:, None]
            sets = [geometry.receiver_set, geometry.blocker_set]  # light_linking_lib.glsl,
            # shadow_frag.glsl
            if sets[1] is not None:
                sets[0] = np.zeros(len(rows), np.int32) if sets[0] is None else sets[0]
            for column in sets:
                if column is not None:
                    rows = np.concatenate([rows, column[:, None]], axis=1)
            self.triangle_material = self._own(table_texture(ctx, rows, rows.shape[1], "i4"))
            table = geometry.materials.reshape(-1, 4)  # eleven RGBA texels a row
            self.materials = self._own(table_texture(ctx, table, 4, "f4"))
            self.uv = None if geometry.uv is None else self._own(ctx.buffer(geometry.uv))
            self.textures = tuple(self._own(t) for t in upload_textures(ctx, geometry.textures)) \
                if geometry.has_textures else None
            self.has_specular = geometry.has_specular
            self.has_coat = geometry.has_coat
            self.has_sheen = geometry.has_sheen
            self.has_rough_diffuse = geometry.has_rough_diffuse
            self.has_translucency = geometry.has_translucency
            self.has_cutouts = bool(geometry.cutout.any())
            self.ggx_tables = None
            if self.has_specular:
                values = principled.tables()
                self.ggx_tables = self._own(ctx.texture(values.shape[::-1], 1, values.tobytes(),
                                                        dtype="f4"))
                self.ggx_tables.filter = moderngl.NEAREST, moderngl.NEAREST
        except Exception:
            self.release()
            raise

    def _own(self, obj):
        self._objects.append(obj)
        return obj

    def streams(self, normals: bool = True) -> list[tuple]:
        """Vertex-array streams of the positions (``in_position``) and, with ``normals``, the
        normals (``in_normal``)."""
        streams = [(self.positions, "3f", "in_position")]
        return [*streams, (self.normals, "3f", "in_normal")] if normals else streams

    def bind_materials(self, program: moderngl.Program) -> None:
        """Bind the triangles' rows and the material table for materials_lib.glsl."""
        self.bind_triangle_rows(program)
        self.materials.use(MATERIAL_UNITS[1])
        program["u_materials"].value = MATERIAL_UNITS[1]

    def bind_triangle_rows(self, program: moderngl.Program) -> None:
        """Bind the triangles' rows (and receiver sets) alone (light_linking_lib.glsl)."""
        self.triangle_material.use(MATERIAL_UNITS[0])
        program["u_triangle_materials"].value = MATERIAL_UNITS[0]

    def cutout_streams(self) -> tuple[list[tuple], dict[str, int]]:
        """For a draw of the positions that leaves cutouts out (shadow_vert.glsl,
        cutout_lib.glsl): its streams (the positions, and the UVs when textured) and the defines
        (CUTOUTS where some material is a cutout, TEXTURED with UVs)."""
        streams = self.streams(normals=False)
        if not self.has_cutouts:
            return streams, {}
        if self.textures is None:
            return streams, {"CUTOUTS": 1}
        return [*streams, (self.uv, "2f", "in_uv")], {"CUTOUTS": 1, "TEXTURED": 1}

    def bind_cutouts(self, program: moderngl.Program) -> None:
        """Bind the material table, and the image textures when textured, for a draw that
        leaves cutouts out (``cutout_streams``)."""
        self.bind_materials(program)
        if self.has_cutouts and self.textures is not None:
            for texture, unit in zip(self.textures, CUTOUT_TEXTURE_UNITS, strict=True):
                texture.use(unit)
            program["u_textures"].value, program["u_texture_sizes"].value = \
                CUTOUT_TEXTURE_UNITS

    def bind_specular(self, program: moderngl.Program) -> None:
        """Bind the glossy lobe's tables for principled_lib.glsl (scenes with specular), where
        the program reads them."""
        self.ggx_tables.use(GGX_TABLES_UNIT)
        set_uniforms(program, u_ggx_tables=GGX_TABLES_UNIT)

    def release(self) -> None:
        for obj in self._objects:
            obj.release()
        self._objects.clear()
