"""The frame's shape: stages that declare what they read and make, visibility modes that
register themselves, and GPU scopes that release on every path."""

from __future__ import annotations

from dataclasses import fields

import numpy as np
import pytest

from addon.core.frame.gpu_scope import GpuScope
from addon.core.frame.renderer import Renderer
from addon.core.frame.state import FrameState
from addon.core.frame.visibility import VISIBILITY
from addon.core.gpu.gl import SHADER_DIR
from addon.core.scene.model import Instance, LightKind, Material
from addon.core.settings import SCHEMA, Settings
from tests.core.builders import floor_scene, light, quad, rotation_x, translation

INPUTS = {"scene", "settings", "passes", "stats", "report", "cancelled"}


def lit_corner():
    """A floor and a wall beside a point light: indirect light reaches the floor."""
    wall = Instance(quad(5, 2), translation(0, 2, 2) @ rotation_x(np.pi / 2),
                    [Material("wall", (0.8, 0.2, 0.2))])
    return floor_scene([light(LightKind.POINT, translation(0, 1, 1), power=50)], extra=[wall])


def test_every_stage_reads_only_what_an_earlier_stage_made(renderer: Renderer) -> None:
    made = set(INPUTS)
    state_fields = {f.name for f in fields(FrameState)}
    for stage in renderer.stages:
        assert set(stage.needs) <= made, (stage.name, set(stage.needs) - made)
        assert set(stage.makes) <= state_fields, stage.name
        made |= set(stage.makes)
    assert "output" in made


def test_each_stage_makes_what_it_declares(renderer: Renderer, monkeypatch) -> None:
    """Run a frame with indirect light and check, after each stage, its declared products."""
    seen: list[str] = []
    for stage in renderer.stages:
        run = stage.run

        def checked(frame: FrameState, stage=stage, run=run) -> None:
            run(frame)
            missing = [name for name in stage.makes if getattr(frame, name) is None]
            assert not missing, (stage.name, missing)
            seen.append(stage.name)

        monkeypatch.setattr(stage, "run", checked)
    renderer.render(lit_corner(), Settings(antialiasing=1, vpl_count=16, bounces=1))
    assert seen == [stage.name for stage in renderer.stages]


def test_visibility_modes_are_the_settings_choices_and_have_a_shader_branch() -> None:
    assert [c.value for c in SCHEMA["visibility"].choices] == list(VISIBILITY)
    shader = (SHADER_DIR / "lights_lib.glsl").read_text()
    for name, mode in VISIBILITY.items():
        for define in mode.defines:
            assert f"#ifdef {define}" in shader or f"defined({define})" in shader, name
        assert mode.label and mode.description, name


@pytest.mark.parametrize("mode", list(VISIBILITY))
def test_every_visibility_mode_renders(renderer: Renderer, mode: str) -> None:
    renderer.forget_frames()
    frame, stats = renderer.render(lit_corner(), Settings(antialiasing=1, vpl_count=16, bounces=1,
                                                   visibility=mode))
    assert frame.passes["DiffInd"].max() > 0, stats.summary()


class _Counted:
    released = 0

    def release(self) -> None:
        _Counted.released += 1


def test_a_gpu_scope_releases_what_it_owns_when_an_error_leaves_it() -> None:
    _Counted.released = 0
    with pytest.raises(RuntimeError), GpuScope() as scope:
        scope.own(_Counted())
        scope.own(_Counted())
        raise RuntimeError("a stage failed")
    assert _Counted.released == 2
