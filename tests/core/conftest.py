"""Shared fixtures of the core tests: one Renderer (one GL context) for the whole session."""

from __future__ import annotations

import pytest

from addon.core.pipeline import Renderer


@pytest.fixture(scope="session")
def renderer() -> Renderer:
    r = Renderer()
    yield r
    r.release()
