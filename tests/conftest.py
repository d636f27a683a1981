"""Fixtures shared by the bpy-free test folders (core, stability): one GL context, program cache
and Renderer per session."""

from __future__ import annotations

import pytest

from addon.core.gl import ProgramCache, shared_context
from addon.core.pipeline import Renderer


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
def renderer() -> Renderer:
    r = Renderer()
    yield r
    r.release()
