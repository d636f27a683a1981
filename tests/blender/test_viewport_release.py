"""Viewport sessions stop (thread joined, GPU objects released) when Blender opens another file
and when the add-on is disabled."""

from __future__ import annotations

from pathlib import Path

SAMPLE = Path(__file__).resolve().parents[2] / "sample_scenes" / "light_point.blend"


def test_opening_a_file_and_disabling_the_add_on_stop_viewport_sessions(blender):
    from addon import viewport
    from addon.core.viewport_session import ViewportSession

    opened = ViewportSession()
    viewport._sessions.add(opened)
    assert opened.alive
    blender.ops.wm.open_mainfile(filepath=str(SAMPLE), load_ui=False)
    assert not opened.alive

    disabled = ViewportSession()
    viewport._sessions.add(disabled)
    viewport.unregister()
    try:
        assert not disabled.alive
        assert viewport._on_load_pre not in blender.app.handlers.load_pre
    finally:
        viewport.register()
