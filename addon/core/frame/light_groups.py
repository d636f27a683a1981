"""Light groups (View Layer > Light Groups): Cycles' Combined_<group> passes, the light of one
group's emitters (its lights, the emission of its objects, the world where the world is in
it) through every bounce, seen directly too. VPL GI renders each asked-for group as a frame
of the scene with only that group's emitters (the others dark, their objects kept: they
still cast shadows and reflect light), with the settings the scene's frame used."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..scene.model import Instance, Material, Scene, World

PASS_PREFIX = "Combined_"
"""A light group's pass: Combined_<group name>, as Cycles names it."""


def requested_groups(passes: frozenset[str] | None) -> list[str]:
    """The light groups whose passes ``passes`` asks for, in a stable order (none where
    ``passes`` is None: the planner-off default asks for every VPL GI pass, and groups are
    the view layer's)."""
    if passes is None:
        return []
    return sorted(name[len(PASS_PREFIX):] for name in passes
                  if name.startswith(PASS_PREFIX) and len(name) > len(PASS_PREFIX))


def group_scene(scene: Scene, group: str) -> Scene:
    """``scene`` lit only by ``group``'s emitters: the lights of other groups left out, the
    emission of other groups' objects off, the world black unless it is in the group."""
    lights = [light for light in scene.lights if light.lightgroup == group]
    world = scene.world if scene.world.lightgroup == group else World(lightgroup=group)
    dark: dict[int, Material] = {}
    instances = [inst if inst.lightgroup == group or not _emits(inst)
                 else _without_emission(inst, dark) for inst in scene.instances]
    return replace(scene, lights=lights, world=world, instances=instances, warnings=[],
                   notes=[])


def has_emitters(scene: Scene) -> bool:
    """Whether anything in ``scene`` emits light: a light of some power, a world that is
    not black, an object with emission."""
    world = scene.world
    return any(light.power != 0 for light in scene.lights) \
        or world.environment is not None or bool(np.any(world.radiance != 0)) \
        or any(_emits(inst) for inst in scene.instances)


def _emits(inst: Instance) -> bool:
    return any(any(c != 0 for c in material.emission) for material in inst.materials)


def _without_emission(inst: Instance, dark: dict[int, Material]) -> Instance:
    """The instance with its materials' emission off (one dark copy per material)."""
    materials = []
    for material in inst.materials:
        if id(material) not in dark:
            dark[id(material)] = replace(material, emission=(0.0, 0.0, 0.0),
                                         emission_texture=None)
        materials.append(dark[id(material)])
    return replace(inst, materials=materials)
