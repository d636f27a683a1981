"""The render passes a view layer asks for (its pass toggles, Cryptomatte layers, light
groups and Shader AOVs) and the names Blender gives them."""

from __future__ import annotations

from .blender_compat import pass_name
from .core.frame.id_passes import crypto_pass_names
from .core.frame.light_groups import PASS_PREFIX
from .core.frame.result import AOV_COLOR, AOV_VALUE, aov_of

DENOISING_DATA = "cycles.denoising_store_passes"
"""Cycles' "Denoising Data" checkbox (View Layer > Passes > Data), which VPL GI honours too."""

# Pass name (VPL GI's, Blender 4.x's) -> (channels, channel ids, type, view-layer toggle that
# enables it; a dotted path for a toggle in a property group, such as Cycles' view-layer
# settings). Registered and written under the running Blender's names (blender_compat).
OPTIONAL_PASSES = {
    "Depth": (1, "Z", "VALUE", "use_pass_z"),
    "Normal": (3, "XYZ", "VECTOR", "use_pass_normal"),
    "DiffDir": (3, "RGB", "COLOR", "use_pass_diffuse_direct"),
    "DiffInd": (3, "RGB", "COLOR", "use_pass_diffuse_indirect"),
    "DiffCol": (3, "RGB", "COLOR", "use_pass_diffuse_color"),
    "GlossDir": (3, "RGB", "COLOR", "use_pass_glossy_direct"),
    "GlossInd": (3, "RGB", "COLOR", "use_pass_glossy_indirect"),
    "GlossCol": (3, "RGB", "COLOR", "use_pass_glossy_color"),
    "Emit": (3, "RGB", "COLOR", "use_pass_emit"),
    "Mist": (1, "Z", "VALUE", "use_pass_mist"),
    "Position": (3, "XYZ", "VECTOR", "use_pass_position"),
    "Denoising Normal": (3, "XYZ", "VECTOR", DENOISING_DATA),
    "Denoising Albedo": (3, "RGB", "COLOR", DENOISING_DATA),
    "Denoising Depth": (1, "Z", "VALUE", DENOISING_DATA),
    "IndexOB": (1, "X", "VALUE", "use_pass_object_index"),
    "IndexMA": (1, "X", "VALUE", "use_pass_material_index"),
    "Vector": (4, "XYZW", "VECTOR", "use_pass_vector"),
    "AO": (3, "RGB", "COLOR", "use_pass_ambient_occlusion"),
    "Env": (3, "RGB", "COLOR", "use_pass_environment"),
    "Shadow Catcher": (3, "RGB", "COLOR", "cycles.use_pass_shadow_catcher"),
}
CRYPTOMATTE_TOGGLES = {"CryptoObject": "use_pass_cryptomatte_object",
                       "CryptoMaterial": "use_pass_cryptomatte_material",
                       "CryptoAsset": "use_pass_cryptomatte_asset"}
"""Cryptomatte's layers (id_passes.CRYPTO_FAMILIES) and their view-layer toggles; the
layer's Levels (``pass_cryptomatte_depth``) give the passes (id_passes.crypto_pass_names)."""


def toggle_owner(layer: object, toggle: str) -> tuple[object, str] | None:
    """The property group that holds the view layer's ``toggle`` (an attribute, or a dotted
    path) and the toggle's name; None where it does not exist (Cycles' settings need the
    Cycles add-on enabled)."""
    *path, name = toggle.split(".")
    owner = layer
    for part in path:
        owner = getattr(owner, part, None)
    return (owner, name) if owner is not None and hasattr(owner, name) else None


def toggled(layer: object, toggle: str) -> bool:
    """Whether the view layer's ``toggle`` (see :func:`toggle_owner`) is on; False where it
    does not exist."""
    found = toggle_owner(layer, toggle)
    return found is not None and bool(getattr(*found))


def cryptomatte_families(layer: object) -> list[str]:
    """The Cryptomatte layers the view layer asks for."""
    return [family for family, toggle in CRYPTOMATTE_TOGGLES.items() if toggled(layer, toggle)]


def cryptomatte_passes(layer: object) -> list[str]:
    """The Cryptomatte passes the view layer asks for, as Blender names them."""
    levels = int(getattr(layer, "pass_cryptomatte_depth", 6))
    return [name for family in cryptomatte_families(layer)
            for name in crypto_pass_names(family, levels)]


def layer_passes(layer: object) -> frozenset[str]:
    """The optional passes (OPTIONAL_PASSES, Cryptomatte's, the light groups', the Shader
    AOVs') the view layer asks for; Combined is always rendered."""
    return frozenset(name for name, (*_, toggle) in OPTIONAL_PASSES.items()
                     if toggled(layer, toggle)) | frozenset(cryptomatte_passes(layer)) \
        | frozenset(light_group_passes(layer)) | frozenset(aov_passes(layer))


def aov_passes(layer: object) -> list[str]:
    """The view layer's Shader AOVs' passes (result.AOV_VALUE or AOV_COLOR + the AOV's
    name; Blender's name is the AOV's), but for those whose name another pass has (Blender
    marks them invalid)."""
    return [(AOV_COLOR if aov.type == "COLOR" else AOV_VALUE) + aov.name
            for aov in getattr(layer, "aovs", ()) if aov.name and aov.is_valid]


def blender_pass_name(name: str) -> str:
    """Blender's name of a VPL GI pass (pass_name; a Shader AOV's: its AOV's)."""
    aov = aov_of(name)
    return pass_name(name) if aov is None else aov[0]


def light_group_passes(layer: object) -> list[str]:
    """The view layer's light groups' passes (Combined_<group>, as Cycles names them)."""
    return [PASS_PREFIX + group.name for group in getattr(layer, "lightgroups", ())]
