"""What differs between the Blender versions VPL GI supports (4.2 LTS, 4.5 LTS, 5.x), in one
place: the add-on asks here instead of comparing versions where it reads Blender's data.

Measured with bpy 4.2.23, 4.5.15 and 5.3.0:

- Render pass names: 5.0 renamed DiffDir, DiffInd, DiffCol, GlossDir, GlossInd, GlossCol and
  Emit to "Diffuse Direct", "Diffuse Indirect", "Diffuse Color", "Glossy Direct", "Glossy
  Indirect", "Glossy Color" and "Emission" (Cycles, EEVEE, the compositor's Render Layers node
  and multilayer EXR channels); Combined, Depth and Normal kept their names.
- Shader nodes: 5.0 removed ``use_nodes`` from materials, worlds and lights (still readable,
  always True, deprecated for 6.0): every material, world and light has a node tree, and 4.x
  files whose materials or worlds had nodes off are converted on load to node trees with a
  Cycles-only output (a Diffuse BSDF in the viewport colour for materials).
- Default surface: an object without a material renders in Cycles 4.x as a Diffuse BSDF of 0.8
  grey, in Cycles 5.x as a default Principled BSDF (base colour 0.8, roughness 0.5, specular
  IOR level 0.5), bit for bit the same as a new material's.
- IES profiles: where a spline's outer point lies past the profile's table (at 0° and 360°
  of horizontal angle, and past the last vertical angle short of 180°), Cycles 4.x reads 0
  and 5.x repeats the nearest value (measured against 4.2, 4.5 and 5.3, ``scene/ies.py``):
  4.x renders a rotationally symmetric profile (one horizontal angle) up to 12.5 % brighter
  towards 180° of horizontal angle than towards 0°.
"""

from __future__ import annotations

import bpy

VERSION: tuple[int, int, int] = tuple(bpy.app.version)
"""The running Blender's version, e.g. (4, 5, 15)."""

BLENDER_5 = VERSION >= (5, 0, 0)

_PASS_NAMES_5 = {
    "DiffDir": "Diffuse Direct",
    "DiffInd": "Diffuse Indirect",
    "DiffCol": "Diffuse Color",
    "GlossDir": "Glossy Direct",
    "GlossInd": "Glossy Indirect",
    "GlossCol": "Glossy Color",
    "Emit": "Emission",
    "IndexOB": "Object Index",
    "IndexMA": "Material Index",
    "AO": "Ambient Occlusion",
    "Env": "Environment",
}

OREN_NAYAR_MULTISCATTER = 2 if BLENDER_5 else 1 if VERSION >= (4, 3, 0) else 0
"""The multiple-scattering term of Cycles' rough diffuse lobe (a Diffuse BSDF's Roughness,
the Principled BSDF's Diffuse Roughness, new in 4.3), core/scene/oren_nayar.py's mode:
measured, 4.2's has none, 4.5's scales it by the colour once more than 5.3's (OpenPBR's)."""

SHEEN_DIMS_CAST_LIGHT = BLENDER_5
"""True where Cycles dims a Principled BSDF's emission under its sheen in the light it casts
on other surfaces as well as where the camera sees it (measured: a glowing wall's sheen dims
the floor it lights by 18.9 % in 5.3, not at all in 4.2 and 4.5)."""

DEFAULT_SURFACE_IS_PRINCIPLED = BLENDER_5
"""True where Cycles renders an object without a material as a default Principled BSDF
(glossy part included), False where as a diffuse surface (4.x)."""

IES_SPLINE_EDGE = "repeat" if BLENDER_5 else "zero"
"""What Cycles' IES Texture reads past its profile's table (``IesProfile.edge``)."""


def pass_name(name: str) -> str:
    """Blender's name, in the running version, of the render pass VPL GI calls ``name`` (its
    4.x name: Combined, Depth, Normal, DiffDir, DiffInd, DiffCol, GlossDir, GlossInd, GlossCol,
    Emit, IndexOB, IndexMA, AO, Env)."""
    return _PASS_NAMES_5.get(name, name) if BLENDER_5 else name


def uses_nodes(datablock: bpy.types.Material | bpy.types.World | bpy.types.Light) -> bool:
    """True if Blender renders the material, world or light from its node tree (always in
    5.x, where ``use_nodes`` is deprecated; reading it there only warns)."""
    if datablock.node_tree is None:
        return False
    return True if BLENDER_5 else bool(datablock.use_nodes)


def ensure_nodes(datablock: bpy.types.Material | bpy.types.World | bpy.types.Light) -> None:
    """Give a material, world or light its node tree: ``use_nodes = True`` on 4.x; nothing on
    5.x, where every one has a tree and setting ``use_nodes`` only warns."""
    if not BLENDER_5:
        datablock.use_nodes = True


def cycles_output_node(tree: bpy.types.ShaderNodeTree | None):
    """The output node Cycles renders from (``get_output_node('CYCLES')``, as Cycles itself
    asks): an output for Cycles only wins over one for all engines, an active one over an
    inactive one; outputs for EEVEE only are never chosen. None if the tree has none."""
    if tree is None:
        return None
    return tree.get_output_node("CYCLES")
