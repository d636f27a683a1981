"""Fixtures shared by the bpy-free test folders (core, stability): one GL context, program cache
and Renderer per session."""

from __future__ import annotations

import pytest

from addon.core.gl import ProgramCache, shared_context
from addon.core.pipeline import Renderer


@pytest.fixture(scope="session")
def programs() -> ProgramCache:
    cache = ProgramCache(shared_context())
    yield cache
    cache.release()


@pytest.fixture(scope="session")
def renderer() -> Renderer:
    r = Renderer()
    yield r
    r.release()
