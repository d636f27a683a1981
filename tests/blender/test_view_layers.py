"""View layers: Blender renders each of a scene's view layers in turn, and each render goes to
its own layer of the result (a scene of two used to get the second's image in the first
layer and a black second). The Cornell box, its short block left out of a second view layer
(its collection excluded), each layer read through the compositor against Cycles' (48², 32
samples)."""

from __future__ import annotations

from pathlib import Path

import bpy
import numpy as np

from tests.blender.rendering import configure_cycles, open_scene, render_linear
from tests.blender.versions import compositor_output

LAYERS = ("ViewLayer", "Second")


def _layer_image(scene: bpy.types.Scene, engine: str, layer: str, path: Path) -> np.ndarray:
    scene.render.engine = engine
    tree, output = compositor_output(scene)
    node = tree.nodes.new("CompositorNodeRLayers")
    node.layer = layer
    tree.links.new(node.outputs["Image"], output)
    return render_linear(scene, engine, path)[..., :3]


def test_each_view_layer_gets_its_own_render(blender, tmp_path):
    scene = open_scene("cornell_box", 48)
    second = scene.view_layers.new(LAYERS[1])
    block = scene.objects["ShortBlock"]
    own = bpy.data.collections.new("Block")
    scene.collection.children.link(own)
    for collection in list(block.users_collection):
        collection.objects.unlink(block)
    own.objects.link(block)
    second.layer_collection.children["Block"].exclude = True
    configure_cycles(scene, 32, bounces=scene.vpl_gi.bounces)
    images = {(engine, layer): _layer_image(scene, engine, layer,
                                            tmp_path / f"{engine}_{layer}.exr")
              for engine in ("CYCLES", "VPL_GI") for layer in LAYERS}

    def off(ours: str, cycles: str) -> float:
        reference = images["CYCLES", cycles]
        return float(np.abs(images["VPL_GI", ours] - reference).mean() / reference.mean())

    for layer, other in (LAYERS, LAYERS[::-1]):
        print(f"{layer}: {off(layer, layer):.3f} of Cycles' mean off its {layer}, "
              f"{off(layer, other):.3f} off its {other}")
        assert images["VPL_GI", layer].mean() > 0.5 * images["CYCLES", layer].mean()
        assert off(layer, layer) < 0.6 * off(layer, other)
