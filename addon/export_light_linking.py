"""Blender's light linking (an emitter's Light Linking receiver collection, in Object
Properties > Shading) as Cycles evaluates it (Blender's depsgraph light-linking cache):

- each receiver collection is an emitter collection (64 at most);
- every object reached from it, through child collections too, is included or excluded by
  the state of its entry (a child collection's entry is its objects' state; an object named
  directly wins over one reached through a child), last entry winning;
- objects with the same (included, excluded) collections form a receiver set (63 at most
  besides set 0, the objects no collection names);
- an emitter whose collection some set includes lights only the sets that include it, else
  every set; in both cases not the sets that exclude it.

Shadow linking (blocker collections) is not rendered: ``has_shadow_linking`` finds it, and
export.py names it in a warning."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import bpy

from .core.scene.model import EVERY_RECEIVER_SET

MAX_COLLECTIONS = 64  # Blender's: emitter collections past these are not linked
MAX_SETS = 64  # receiver sets, set 0 included


@dataclass
class LightLinking:
    """Receiver sets by object and the sets each emitter lights, keyed by original pointers."""

    sets: dict[int, int] = field(default_factory=dict)
    receivers: dict[int, int] = field(default_factory=dict)  # by emitter collection
    warnings: list[str] = field(default_factory=list)

    def receiver_set(self, obj: bpy.types.Object) -> int:
        """The object's receiver set (Instance.receiver_set)."""
        return self.sets.get(obj.original.as_pointer(), 0) if self.sets else 0

    def receivers_of(self, obj: bpy.types.Object) -> int:
        """The receiver sets an emitter lights (Light.receivers, Instance.emission_receivers)."""
        collection = receiver_collection(obj)
        if collection is None:
            return EVERY_RECEIVER_SET
        return self.receivers.get(collection.original.as_pointer(), EVERY_RECEIVER_SET)


NO_LINKING = LightLinking()


def receiver_collection(obj: bpy.types.Object) -> bpy.types.Collection | None:
    """The object's Light Linking receiver collection, or None."""
    linking = getattr(obj.original, "light_linking", None)
    return None if linking is None else linking.receiver_collection


def has_shadow_linking(obj: bpy.types.Object) -> bool:
    """True if the shadows of the object's light or emission are cast by some objects only
    (Cycles' shadow linking: a blocker collection)."""
    linking = getattr(obj, "light_linking", None)
    return linking is not None and linking.blocker_collection is not None


def _entries(collection: bpy.types.Collection) -> Iterator[tuple[str, bpy.types.Object]]:
    """(link state, object) of every object the collection reaches, children first, as
    Blender's cache visits them."""
    for child, entry in zip(collection.children, collection.collection_children, strict=True):
        state = entry.light_linking.link_state
        for obj in _reached(child):
            yield state, obj
    for obj, entry in zip(collection.objects, collection.collection_objects, strict=True):
        yield entry.light_linking.link_state, obj


def _reached(collection: bpy.types.Collection) -> Iterator[bpy.types.Object]:
    for child in collection.children:
        yield from _reached(child)
    yield from collection.objects


def read_light_linking(objects: list[bpy.types.Object]) -> LightLinking:
    """The light linking of the scene whose (evaluated) ``objects`` are given."""
    collections: dict[int, int] = {}  # emitter collection pointer -> its bit
    found = LightLinking()
    masks: dict[int, tuple[int, int]] = {}  # receiver pointer -> (included, excluded) bits
    for obj in objects:
        collection = receiver_collection(obj)
        if collection is None:
            continue
        pointer = collection.original.as_pointer()
        if pointer in collections:
            continue
        if len(collections) == MAX_COLLECTIONS:
            found.warnings.append(f"light linking: more than {MAX_COLLECTIONS} receiver "
                                  f"collections; '{collection.name}' and later ones light "
                                  f"every object (as in Blender)")
            break
        bit = collections[pointer] = 1 << len(collections)
        for state, receiver in _entries(collection):
            pointer = receiver.original.as_pointer()
            included, excluded = masks.get(pointer, (0, 0))
            masks[pointer] = (included | bit, excluded & ~bit) if state == "INCLUDE" \
                else (included & ~bit, excluded | bit)
    ids: dict[tuple[int, int], int] = {}
    for receiver, key in masks.items():
        if key not in ids and len(ids) + 1 < MAX_SETS:
            ids[key] = len(ids) + 1
        if key in ids:
            found.sets[receiver] = ids[key]
    if len(set(masks.values())) > len(ids):
        found.warnings.append(f"light linking: more than {MAX_SETS - 1} distinct receiver "
                              f"sets; the objects of the others are lit as those no receiver "
                              f"collection names (as in Blender)")
    for pointer, bit in collections.items():
        included = sum(1 << s for (inc, _), s in ids.items() if inc & bit)
        excluded = sum(1 << s for (_, exc), s in ids.items() if exc & bit)
        found.receivers[pointer] = (included or EVERY_RECEIVER_SET) & ~excluded
    return found


def scene_light_linking(depsgraph: bpy.types.Depsgraph) -> LightLinking:
    """The light linking of the depsgraph's scene (NO_LINKING where no object has it)."""
    objects = [obj for obj in depsgraph.objects if receiver_collection(obj) is not None]
    return read_light_linking(objects) if objects else NO_LINKING
