"""Blender's light and shadow linking (an emitter's Light Linking receiver and blocker
collections, in Object Properties > Shading) as Cycles evaluates them (Blender's depsgraph
light-linking cache). For each of the two kinds of collection apart:

- each collection is an emitter collection (64 at most);
- every object reached from it, through child collections too, is included or excluded by
  the state of its entry (a child collection's entry is its objects' state; an object named
  directly wins over one reached through a child), last entry winning;
- objects with the same (included, excluded) collections form a set (63 at most besides
  set 0, the objects no collection names): receiver sets, blocker sets;
- an emitter whose collection some set includes reaches only the sets that include it, else
  every set; in both cases not the sets that exclude it: the receivers it lights, the
  blockers that cast its shadows."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import bpy

from .core.scene.model import EVERY_RECEIVER_SET

MAX_COLLECTIONS = 64  # Blender's: emitter collections past these are not linked
MAX_SETS = 64  # sets of one kind, set 0 included


@dataclass
class LinkSets:
    """One kind of linking's sets by object and the sets each emitter collection reaches,
    keyed by original pointers."""

    sets: dict[int, int] = field(default_factory=dict)
    reached: dict[int, int] = field(default_factory=dict)  # by emitter collection
    warnings: list[str] = field(default_factory=list)

    def set_of(self, obj: bpy.types.Object) -> int:
        """The object's set (0: no collection names it)."""
        return self.sets.get(obj.original.as_pointer(), 0) if self.sets else 0

    def reached_by(self, collection: bpy.types.Collection | None) -> int:
        """The sets an emitter with this collection reaches (all without one)."""
        if collection is None:
            return EVERY_RECEIVER_SET
        return self.reached.get(collection.original.as_pointer(), EVERY_RECEIVER_SET)


@dataclass
class LightLinking:
    """The scene's receiver sets (light linking) and blocker sets (shadow linking)."""

    receiving: LinkSets = field(default_factory=LinkSets)
    blocking: LinkSets = field(default_factory=LinkSets)

    @property
    def warnings(self) -> list[str]:
        return self.receiving.warnings + self.blocking.warnings

    def receiver_set(self, obj: bpy.types.Object) -> int:
        """The object's receiver set (Instance.receiver_set)."""
        return self.receiving.set_of(obj)

    def receivers_of(self, obj: bpy.types.Object) -> int:
        """The receiver sets an emitter lights (Light.receivers, Instance.emission_receivers)."""
        return self.receiving.reached_by(linked_collection(obj, RECEIVERS))

    def blocker_set(self, obj: bpy.types.Object) -> int:
        """The object's blocker set (Instance.blocker_set)."""
        return self.blocking.set_of(obj)

    def blockers_of(self, obj: bpy.types.Object) -> int:
        """The blocker sets that cast an emitter's shadows (Light.blockers,
        Instance.emission_blockers)."""
        return self.blocking.reached_by(linked_collection(obj, BLOCKERS))


NO_LINKING = LightLinking()


RECEIVERS = "receiver_collection"
BLOCKERS = "blocker_collection"


def linked_collection(obj: bpy.types.Object, kind: str) -> bpy.types.Collection | None:
    """The object's Light Linking collection of ``kind`` (RECEIVERS, BLOCKERS), or None."""
    linking = getattr(obj.original, "light_linking", None)
    return None if linking is None else getattr(linking, kind)


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


def read_link_sets(objects: list[bpy.types.Object], kind: str) -> LinkSets:
    """The sets of ``kind`` (RECEIVERS, BLOCKERS) of the scene whose (evaluated) emitters
    with such a collection are ``objects``."""
    noun = "receiver" if kind == RECEIVERS else "blocker"
    collections: dict[int, int] = {}  # emitter collection pointer -> its bit
    found = LinkSets()
    masks: dict[int, tuple[int, int]] = {}  # member pointer -> (included, excluded) bits
    for obj in objects:
        collection = linked_collection(obj, kind)
        if collection is None:
            continue
        pointer = collection.original.as_pointer()
        if pointer in collections:
            continue
        if len(collections) == MAX_COLLECTIONS:
            found.warnings.append(f"light linking: more than {MAX_COLLECTIONS} {noun} "
                                  f"collections; '{collection.name}' and later ones reach "
                                  f"every object (as in Blender)")
            break
        bit = collections[pointer] = 1 << len(collections)
        for state, member in _entries(collection):
            pointer = member.original.as_pointer()
            included, excluded = masks.get(pointer, (0, 0))
            masks[pointer] = (included | bit, excluded & ~bit) if state == "INCLUDE" \
                else (included & ~bit, excluded | bit)
    ids: dict[tuple[int, int], int] = {}
    for member, key in masks.items():
        if key not in ids and len(ids) + 1 < MAX_SETS:
            ids[key] = len(ids) + 1
        if key in ids:
            found.sets[member] = ids[key]
    if len(set(masks.values())) > len(ids):
        found.warnings.append(f"light linking: more than {MAX_SETS - 1} distinct {noun} "
                              f"sets; the objects of the others are taken as those no {noun} "
                              f"collection names (as in Blender)")
    for pointer, bit in collections.items():
        included = sum(1 << s for (inc, _), s in ids.items() if inc & bit)
        excluded = sum(1 << s for (_, exc), s in ids.items() if exc & bit)
        found.reached[pointer] = (included or EVERY_RECEIVER_SET) & ~excluded
    return found


def scene_light_linking(depsgraph: bpy.types.Depsgraph) -> LightLinking:
    """The light and shadow linking of the depsgraph's scene (NO_LINKING where no object has
    either)."""
    linking = LightLinking()
    for kind, attribute in ((RECEIVERS, "receiving"), (BLOCKERS, "blocking")):
        objects = [obj for obj in depsgraph.objects if linked_collection(obj, kind) is not None]
        if objects:
            setattr(linking, attribute, read_link_sets(objects, kind))
    return linking if linking.receiving.reached or linking.blocking.reached else NO_LINKING
