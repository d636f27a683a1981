"""Fixtures shared by the bpy-free test folders (core, stability): one GL context, program cache,
ray tracer and Renderer per session."""

from __future__ import annotations

import os
import sys

import pytest

from addon.core.frame.renderer import Renderer
from addon.core.gpu.gl import ProgramCache, shared_context
from addon.core.gpu.raytrace import RayTracer


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--full-sweep", action="store_true", default=False,
                     help="stability suite: the slow, wide parametrisations (scales, powers, "
                          "albedos, bounce counts, wedge angles, more random scenes)")


@pytest.fixture(scope="session")
def programs() -> ProgramCache:
    cache = ProgramCache(shared_context())
    yield cache
    cache.release()


@pytest.fixture(scope="session")
def tracer(programs: ProgramCache) -> RayTracer:
    """A ray tracer of its own (the renderer's keeps its frame's triangles)."""
    rt = RayTracer(programs.ctx, programs)
    yield rt
    rt.release()


@pytest.fixture(scope="session")
def renderer() -> Renderer:
    r = Renderer()
    yield r
    r.release()


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    session.config.stash[_EXIT_STATUS] = int(exitstatus)


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config: pytest.Config) -> None:
    """End a session that imported bpy without Python's teardown: bpy 4.5's static destructor
    waits forever on its own sound-device thread when the bpy module outlives interpreter
    teardown (seen after 300 tests, in some orders of them; fixed in bpy 5.0). Every result
    and the summary are printed by now."""
    if "bpy" in sys.modules:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(config.stash.get(_EXIT_STATUS, 0))


_EXIT_STATUS = pytest.StashKey[int]()
