"""Shadow linking in the renderer: an emitter's shadows are cast only by the objects of the
blocker sets its ``blockers`` bits name (Instance.blocker_set), in every direct-shadow mode
(the Blender side, and the comparison with Cycles: tests/blender/test_shadow_linking.py)."""

from __future__ import annotations

import numpy as np
import pytest

from addon.core.scene.model import EVERY_RECEIVER_SET, Instance, LightKind, Material
from addon.core.settings import Settings
from tests.core.builders import floor_scene, light, quad, rotation_x, traced_vpls, translation

ONLY_SET_1 = 1 << 1


def panels(left_set: int = 0, right_set: int = 1) -> list[Instance]:
    """Two grey panels 1 m over the floor, over x < 0 and x > 0 (inset from the edges), in
    blocker sets ``left_set`` and ``right_set``."""
    grey = [Material("panel", (0.5, 0.5, 0.5))]
    return [Instance(quad(0.8, 1), translation(-1.2, 0, 1), grey, blocker_set=left_set),
            Instance(quad(0.8, 1), translation(1.2, 0, 1), grey, blocker_set=right_set)]


@pytest.mark.parametrize("shadows", ["hybrid", "ray_traced", "shadow_maps"])
@pytest.mark.parametrize("kind", [LightKind.POINT, LightKind.SUN, LightKind.AREA])
def test_only_the_blockers_cast_an_emitters_shadows(renderer, shadows, kind):
    """Seen from above, the panels' shadows on the floor beside them, cast by a light at a
    slant: the panel in set 1 casts the shadow of a light whose blockers are set 1, the one in
    set 0 casts none (the floor there as without panels); with every blocker both cast
    theirs."""
    slant = rotation_x(np.radians(-45))  # light travelling towards -y and down
    matrix = translation(0, 3, 3) @ slant if kind is not LightKind.SUN else slant
    power = {LightKind.POINT: 400.0, LightKind.SUN: 3.0, LightKind.AREA: 400.0}[kind]
    lamp = light(kind, matrix, power=power, blockers=ONLY_SET_1)
    settings = Settings(bounces=0, antialiasing=1, direct_shadows=shadows)
    frame, _ = renderer.render(floor_scene([lamp], extra=panels()), settings)
    linked = frame.passes["DiffDir"][..., 0]
    lamp.blockers = EVERY_RECEIVER_SET
    frame, _ = renderer.render(floor_scene([lamp], extra=panels()), settings)
    unlinked = frame.passes["DiffDir"][..., 0]
    frame, _ = renderer.render(floor_scene([lamp]), settings)
    bare = frame.passes["DiffDir"][..., 0]
    # the panels' shadows fall 1 m towards -y of them: rows of y in [-1.9, -1.1]
    shadow_rows = slice(12, 20)
    left, right = slice(11, 25), slice(39, 52)  # x in [-1.9, -0.7], [0.7, 1.9]
    print(f"{kind} {shadows}: left shadow {linked[shadow_rows, left].mean():.4f} (bare "
          f"{bare[shadow_rows, left].mean():.4f}, unlinked "
          f"{unlinked[shadow_rows, left].mean():.4f}); right "
          f"{linked[shadow_rows, right].mean():.4f}")
    assert bare[shadow_rows, left].mean() > 0.05
    np.testing.assert_allclose(linked[shadow_rows, left], bare[shadow_rows, left], rtol=0.05,
                               atol=0.02 * bare.max())
    assert linked[shadow_rows, right].mean() < 0.3 * bare[shadow_rows, right].mean()
    assert unlinked[shadow_rows, left].mean() < 0.3 * bare[shadow_rows, left].mean()


@pytest.mark.parametrize("incremental", [False, True])
def test_light_paths_pass_and_light_the_objects_that_cast_no_shadow(renderer, incremental):
    """A lamp over a panel in set 1 over the floor: linked to set 0's blockers only, its
    light paths light the panel and pass it (first-bounce VPLs on it and on the floor under
    it), as Cycles lights both; unlinked, the panel stops them. Incremental Instant
    Radiosity keeps one hit a path: the floor's."""
    panel = Instance(quad(1, 1), translation(0, 0, 1), [Material("panel", (0.5, 0.5, 0.5))],
                     blocker_set=1)
    lamp = light(LightKind.POINT, translation(0, 0, 2), power=100.0)
    settings = Settings(vpl_count=512, bounces=1, incremental=incremental)
    for blockers in (1 << 0, EVERY_RECEIVER_SET):
        lamp.blockers = blockers
        vpls = traced_vpls(renderer, floor_scene([lamp], extra=[panel]), settings)
        first = vpls.position[vpls.generation == 1]
        high = first[:, 2] > 0.5
        under = ~high & (np.abs(first[:, :2]).max(axis=1) < 0.9)
        print(f"blockers {blockers:#x}: {len(first)} first-bounce VPLs, {high.sum()} on the "
              f"panel, {under.sum()} under it")
        linked = blockers != EVERY_RECEIVER_SET
        assert high.any() == (not linked or not incremental)
        assert under.any() == linked
