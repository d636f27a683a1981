"""Shader node trees for bakes: a content hash of a tree, whether its diffuse colour and
emission can be baked, and the Emission tree that shows one of them in a material copy.

The diffuse colour (albedo) and emitted radiance of a surface built from Principled, Diffuse
and Emission shaders under Mix and Add Shader nodes are expressions of the tree's sockets; a
bake evaluates the expression with Cycles through an Emission shader of strength 1."""

from __future__ import annotations

import hashlib
from collections.abc import Iterator
from dataclasses import dataclass

import bpy

from .blender_compat import cycles_output_node
from .blender_read import rgb, surface_node

CHANNELS = ("albedo", "emission")
"""What a bake holds: the diffuse colour, or the emitted radiance (colour × strength)."""

_CLOSURES = {"BSDF_PRINCIPLED", "BSDF_DIFFUSE", "EMISSION", "MIX_SHADER", "ADD_SHADER",
             "REROUTE"}
BLACK = (0.0, 0.0, 0.0)

# -- content hash ---------------------------------------------------------------------------

_SKIPPED = {"rna_type", "location", "location_absolute", "width", "height", "dimensions",
            "select", "show_options", "show_preview", "show_texture", "hide", "mute_label",
            "label", "color", "use_custom_color", "parent", "warning_propagation",
            "internal_links", "inputs", "outputs", "bl_width_default", "bl_width_min",
            "bl_width_max", "bl_height_default", "bl_height_min", "bl_height_max",
            "bl_description", "bl_icon", "bl_static_type", "bl_label", "is_active_output"}


def _plain(value) -> object:
    """A property value as comparable text: arrays (colours, vectors) as tuples."""
    return tuple(value) if hasattr(value, "__len__") and not isinstance(value, str) else value


def _struct(value, out: list, depth: int = 0) -> None:
    """Append a struct's properties (recursing into owned structs and collections, such as a
    ColorRamp's elements or a curve's points) as text; IDs by name."""
    if value is None or depth > 4:
        out.append("None")
        return
    if isinstance(value, bpy.types.ID):
        out.append(f"ID:{value.name_full}")
        if isinstance(value, bpy.types.Image):
            out.append(f"{value.filepath}|{tuple(value.size)}|{value.is_dirty}")
        elif isinstance(value, bpy.types.NodeTree):
            out.append(tree_hash(value))
        return
    for prop in value.bl_rna.properties:
        name = prop.identifier
        if name in _SKIPPED:
            continue
        item = getattr(value, name, None)
        if prop.type == "POINTER":
            out.append(name)
            _struct(item, out, depth + 1)
        elif prop.type == "COLLECTION":
            out.append(f"{name}[")
            for element in item:
                _struct(element, out, depth + 1)
            out.append("]")
        else:
            out.append(f"{name}={_plain(item)}")


def struct_hash(value) -> str:
    """A hash of a struct's settings (a modifier's), IDs by name."""
    out: list[str] = []
    _struct(value, out)
    return hashlib.blake2b("\n".join(out).encode(), digest_size=16).hexdigest()


def tree_hash(tree: bpy.types.NodeTree) -> str:
    """A hash of everything in a node tree that can change what it computes: each node's
    type, settings and unlinked input values, the links, and node groups' trees."""
    out: list[str] = []
    for node in sorted(tree.nodes, key=lambda n: n.name):
        out.append(f"node {node.name} {node.bl_idname} mute={node.mute}")
        _struct(node, out)
        for socket in node.inputs:
            value = getattr(socket, "default_value", None)
            out.append(f"in {socket.identifier}={_plain(value)}")
    for link in tree.links:
        out.append(f"link {link.from_node.name}.{link.from_socket.identifier}->"
                   f"{link.to_node.name}.{link.to_socket.identifier} {link.is_muted}")
    return hashlib.blake2b("\n".join(out).encode(), digest_size=16).hexdigest()


# -- what a bake evaluates ------------------------------------------------------------------

@dataclass
class Term:
    """A colour: a constant, or an output socket of the material's tree (times a constant
    or a socket for emission strength)."""

    constant: tuple[float, float, float] = BLACK
    socket: object | None = None


class NotBakeable(Exception):
    """The surface holds a closure whose diffuse colour the bake cannot express."""


def _source(socket) -> Term:
    if socket.is_linked:
        return Term(socket=socket.links[0].from_socket)
    return Term(rgb(socket.default_value))


def _node_of(socket):
    return socket.links[0].from_node if socket.is_linked else None


def check(node) -> None:
    """Raise NotBakeable (naming the node) unless every closure under ``node`` is one whose
    diffuse colour and emission the bake can express."""
    if node is None:
        return
    if node.type not in _CLOSURES:
        raise NotBakeable(f"shader '{node.bl_label}' is not supported")
    if node.type in ("MIX_SHADER", "ADD_SHADER", "REROUTE"):
        for socket in node.inputs:
            if socket.type == "SHADER":
                check(_node_of(socket))


def _upstream(node) -> Iterator:
    """The links into ``node`` and into every node upstream of it, each node's once."""
    seen: set[str] = set()
    pending = [node] if node is not None else []
    while pending:
        current = pending.pop()
        if current.name in seen:
            continue
        seen.add(current.name)
        for socket in current.inputs:
            for link in socket.links:
                yield link
                pending.append(link.from_node)


def linked_inputs(node) -> list[str]:
    """Labels of the nodes feeding the closures' colour, strength and mix inputs (the whole
    chain upstream, e.g. 'Color Ramp' and 'Noise Texture'): what makes a bake necessary."""
    nodes = {} if node is None or node.type in _CLOSURES else {node.name: node.bl_label}
    for link in _upstream(node):
        if link.from_node.type not in _CLOSURES:
            nodes.setdefault(link.from_node.name, link.from_node.bl_label)
    return list(nodes.values())


VIEW_DEPENDENT = {"LAYER_WEIGHT": None, "FRESNEL": None, "LIGHT_PATH": None, "CAMERA": None,
                  "TEX_COORD": {"Camera", "Window", "Reflection"},
                  "NEW_GEOMETRY": {"Incoming", "Backfacing"}}
"""Nodes (and of some, the outputs; None: any) whose value depends on the ray that sees the
surface, which a bake evaluates once, looking straight at it."""


def scene_dependent(node) -> list[str]:
    """Labels of the nodes upstream of ``node`` that look at the scene around the surface
    (Ambient Occlusion, unless Only Local), which a bake sees without it, each once."""
    found: list[str] = []
    for link in _upstream(node):
        source = link.from_node
        if source.type == "AMBIENT_OCCLUSION" and not source.only_local and \
                source.bl_label not in found:
            found.append(source.bl_label)
    return found


def view_dependent(node) -> list[str]:
    """Labels of the nodes upstream of ``node`` whose outputs in use depend on the viewing
    ray (VIEW_DEPENDENT), each once."""
    found: list[str] = []
    for link in _upstream(node):
        outputs = VIEW_DEPENDENT.get(link.from_node.type, ())
        if (outputs is None or link.from_socket.name in outputs) and \
                link.from_node.bl_label not in found:
            found.append(link.from_node.bl_label)
    return found


def specular_constants(material: bpy.types.Material) -> dict[str, object]:
    """The specular inputs of a surface that is one Principled BSDF, where they are
    constants (a baked material keeps them; linked ones keep the Material's defaults)."""
    node = surface_node(material.node_tree)
    while node is not None and node.type == "REROUTE":
        node = _node_of(node.inputs[0])
    if node is None or node.type != "BSDF_PRINCIPLED":
        return {}
    found: dict[str, object] = {}
    for name, key in (("Roughness", "roughness"), ("Metallic", "metallic"), ("IOR", "ior"),
                      ("Specular IOR Level", "specular_ior_level")):
        socket = node.inputs[name]
        if not socket.is_linked:
            found[key] = float(socket.default_value)
    tint = node.inputs["Specular Tint"]
    if not tint.is_linked:
        found["specular_tint"] = tuple(float(c) for c in tint.default_value[:3])
    return found


# -- the Emission tree in a copy ------------------------------------------------------------

class _Builder:
    """Nodes added to a material copy's tree that compute a channel of the surface."""

    def __init__(self, tree: bpy.types.NodeTree) -> None:
        self.tree = tree

    def _mix(self, blend: str, fac, a: Term, b: Term) -> Term:
        node = self.tree.nodes.new("ShaderNodeMixRGB")
        node.blend_type = blend
        for socket, term in ((node.inputs[1], a), (node.inputs[2], b)):
            self.feed(socket, term)
        if isinstance(fac, float):
            node.inputs[0].default_value = fac
        else:
            self.tree.links.new(fac, node.inputs[0])
        return Term(socket=node.outputs[0])

    def feed(self, socket, term: Term) -> None:
        if term.socket is None:
            socket.default_value = (*term.constant, 1.0)
        else:
            self.tree.links.new(term.socket, socket)

    def _scaled(self, color: Term, strength) -> Term:
        """``color`` × ``strength`` (an input socket of the shader)."""
        if not strength.is_linked:
            value = float(strength.default_value)
            if color.socket is None:
                return Term(tuple(c * value for c in color.constant))
            return self._mix("MULTIPLY", 1.0, color, Term((value,) * 3))
        return self._mix("MULTIPLY", 1.0, color, Term(socket=strength.links[0].from_socket))

    def channel(self, node, channel: str) -> Term:
        """The diffuse colour or emission of the closure ``node`` as a Term."""
        if node is None:
            return Term()
        if node.type == "REROUTE":
            return self.channel(_node_of(node.inputs[0]), channel)
        if node.type == "BSDF_PRINCIPLED":
            if channel == "albedo":
                return _source(node.inputs["Base Color"])
            return self._scaled(_source(node.inputs["Emission Color"]),
                                node.inputs["Emission Strength"])
        if node.type == "BSDF_DIFFUSE":
            return _source(node.inputs["Color"]) if channel == "albedo" else Term()
        if node.type == "EMISSION":
            if channel == "albedo":
                return Term()
            return self._scaled(_source(node.inputs["Color"]), node.inputs["Strength"])
        if node.type == "ADD_SHADER":
            a, b = (self.channel(_node_of(s), channel) for s in node.inputs[:2])
            return self._mix("ADD", 1.0, a, b)
        # MIX_SHADER: (1 - fac) a + fac b, fac clamped as Cycles clamps it
        a, b = (self.channel(_node_of(s), channel) for s in node.inputs[1:3])
        fac_socket = node.inputs[0]
        fac = fac_socket.links[0].from_socket if fac_socket.is_linked else \
            float(min(max(fac_socket.default_value, 0.0), 1.0))
        return self._mix("MIX", fac, a, b)


def constant_channel(material: bpy.types.Material, channel: str) -> Term | None:
    """The channel's value when it is a constant (no socket to evaluate), else None. Reads
    the material without changing it."""
    term = _Inspector().channel(surface_node(material.node_tree), channel)
    return None if term.socket is not None else term


class _Inspector(_Builder):
    """A builder that adds no nodes: any mix of a socket is 'a socket'."""

    def __init__(self) -> None:
        super().__init__(None)  # type: ignore[arg-type]

    def _mix(self, blend: str, fac, a: Term, b: Term) -> Term:
        if a.socket is None and b.socket is None and isinstance(fac, float):
            if blend == "ADD":
                return Term(tuple(x + y for x, y in zip(a.constant, b.constant, strict=True)))
            if blend == "MULTIPLY":
                return Term(tuple(x * y for x, y in zip(a.constant, b.constant, strict=True)))
            return Term(tuple((1 - fac) * x + fac * y
                              for x, y in zip(a.constant, b.constant, strict=True)))
        return Term(socket=True)


def show_channel(copy: bpy.types.Material, channel: str, image: bpy.types.Image) -> None:
    """Rewire a material copy so that Cycles' Emit bake writes ``channel`` into ``image``:
    an Emission shader of the channel's value on the Cycles output, and an active Image
    Texture node of ``image`` (the bake target)."""
    tree = copy.node_tree
    output = cycles_output_node(tree) or tree.nodes.new("ShaderNodeOutputMaterial")
    builder = _Builder(tree)
    term = builder.channel(surface_node(tree), channel)
    emission = tree.nodes.new("ShaderNodeEmission")
    emission.inputs["Strength"].default_value = 1.0
    builder.feed(emission.inputs["Color"], term)
    for link in list(output.inputs["Surface"].links):
        tree.links.remove(link)
    tree.links.new(emission.outputs[0], output.inputs["Surface"])
    target = tree.nodes.new("ShaderNodeTexImage")
    target.image = image
    tree.nodes.active = target
