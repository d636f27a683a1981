"""The ID passes: Cryptomatte's hash and float ids, the ranking of a pixel's ids, and the
Object Index, Material Index and Cryptomatte passes of a rendered scene, over progressive
passes."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from addon.core.frame.id_passes import (
    crypto_pass_names,
    hash_to_float,
    merge_ranks,
    metadata,
    murmur3_32,
    name_hash,
    split_ranks,
)
from addon.core.frame.progressive import Accumulator
from addon.core.frame.result import Frame
from addon.core.scene.model import Identity, Instance, LightKind, Material
from addon.core.settings import Settings
from tests.core.builders import floor_scene, light, pixel_centres, quad, translation


@pytest.mark.parametrize(("data", "seed", "expected"), [
    (b"", 0, 0x00000000), (b"", 1, 0x514E28B7), (b"a", 0, 0x3C2569B2),
    (b"abc", 0, 0xB3DD93FA), (b"hello", 0, 0x248BFA47), (b"Hello, world!", 0, 0xC0363E43)])
def test_murmur3_matches_the_reference_vectors(data, seed, expected):
    assert murmur3_32(data, seed) == expected


def test_names_hash_as_in_cycles_manifests():
    """Hashes read from a Cycles render's EXR manifest (bpy 4.5 and 5.3)."""
    assert f"{name_hash('Cube'):08x}" == "a8fce865"
    assert f"{name_hash('default_surface'):08x}" == "78d05529"
    assert f"{name_hash('ViewLayer.CryptoObject'):08x}"[:7] == "542cafa"


@pytest.mark.parametrize("value", [0x00000000, 0x007FFFFF, 0x7F800000, 0xFFFFFFFF, 0x80000001])
def test_float_ids_are_never_zero_denormal_inf_or_nan(value):
    f = np.float32(hash_to_float(value))
    assert np.isfinite(f) and abs(f) >= np.finfo(np.float32).tiny
    bits = int(np.array(f).view(np.uint32))
    assert bits & 0x807FFFFF == value & 0x807FFFFF  # sign and mantissa kept


def test_ranks_sum_equal_ids_and_put_the_largest_first():
    ids = np.array([[[3, 0, 3, 5, 5, 5, 0, 0, 2]]], np.float32)
    ranked, weights = merge_ranks(ids, np.full(ids.shape, 1 / 9, np.float32), 4)
    assert ranked.tolist() == [[[5, 3, 2, 0]]]
    np.testing.assert_allclose(weights, [[[3 / 9, 2 / 9, 1 / 9, 0]]], atol=1e-7)


def test_passes_merge_their_ranks_weighted():
    """Two passes of one pixel: an id seen in both has the weighted mean of its coverages;
    one seen in only one pass keeps its share of it."""
    def frame(pairs):
        image = np.array(pairs, np.float32).reshape(1, 1, 4)
        return Frame(1, 1, {"CryptoObject00": image, "Combined": np.zeros((1, 1, 4))})

    accumulator = Accumulator()
    accumulator.add(frame([7, 0.75, 8, 0.25]), weight=1.0)
    accumulator.add(frame([9, 0.5, 7, 0.5]), weight=3.0)
    ids, weights = split_ranks([accumulator.average().passes["CryptoObject00"]])
    assert ids.tolist() == [[[7, 9]]]  # 8 (0.0625) loses its rank to 9 (0.375)
    np.testing.assert_allclose(weights, [[[0.5625, 0.375]]])


def test_metadata_keys_and_manifest():
    scene = floor_scene([])
    scene.instances[0].identity = Identity("Floor", 1, "Rig")
    fields = metadata(scene, ["CryptoObject", "CryptoAsset", "CryptoMaterial"], "ViewLayer")
    assert fields["cryptomatte/542cafa/name"] == "ViewLayer.CryptoObject"
    assert fields["cryptomatte/542cafa/hash"] == "MurmurHash3_32"
    assert fields["cryptomatte/542cafa/conversion"] == "uint32_to_float32"
    assert fields["cryptomatte/542cafa/manifest"] == f'{{"Floor":"{name_hash("Floor"):08x}"}}'
    assert '"Rig"' in fields["cryptomatte/aa21542/manifest"]
    assert '"floor"' in next(v for k, v in fields.items() if k.endswith("manifest")
                             and "ViewLayer.CryptoMaterial" in fields[k[:-8] + "name"])


def test_a_rendered_frame_has_each_objects_ids(renderer):
    """A floor and a box on it seen from above, over three progressive passes: the index
    passes hold each object's and material's Pass Index at pixel centres, Cryptomatte ranks
    each pixel's objects by coverage (one at a pixel inside an object, two on its edge)."""
    box = Instance(quad(1.0, 1.0, z=0.5), translation(0.3, 0.0, 0.0),
                   [Material("red", (0.8, 0.1, 0.1), pass_index=6)], identity=Identity("Box", 4))
    scene = floor_scene([light(LightKind.SUN, np.eye(4), power=3.0)], extra=[box], size=32)
    scene.instances[0].identity = Identity("Floor", 2)
    scene.instances[0].materials[0] = replace(scene.instances[0].materials[0], pass_index=5)
    passes = frozenset({"IndexOB", "IndexMA", *crypto_pass_names("CryptoObject", 4)})
    frame, _ = renderer.render_progressive(scene, Settings(antialiasing=2, bounces=0,
                                                           passes=3), passes=passes)
    x, y = pixel_centres(32)
    def within(half: float) -> np.ndarray:
        return (np.abs(x - 0.3) < half) & (np.abs(y) < half)

    inside, outside = within(0.85), ~within(1.15)  # whole pixels (0.1875 m) off the edge
    for name, (box_index, floor_index) in {"IndexOB": (4, 2), "IndexMA": (6, 5)}.items():
        image = frame.passes[name][..., 0]
        assert np.all(image[inside] == box_index) and np.all(image[outside] == floor_index)
        assert set(np.unique(image)) == {box_index, floor_index}
    ids, weights = split_ranks([frame.passes[n] for n in crypto_pass_names("CryptoObject", 4)])
    box_id, floor_id = (np.float32(hash_to_float(name_hash(n))) for n in ("Box", "Floor"))
    assert np.all(ids[inside][:, 0] == box_id) and np.allclose(weights[inside][:, 0], 1.0)
    assert np.all(ids[outside][:, 0] == floor_id)
    np.testing.assert_allclose(weights.sum(axis=-1), 1.0, atol=1e-5)  # no background seen
    edge = (weights[..., 1] > 0).mean()
    assert 0 < edge < 0.3 and set(np.unique(ids[..., :2])) <= {0.0, box_id, floor_id}
