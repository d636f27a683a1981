"""Running developer tools inside bpy with the add-on registered."""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from typing import NoReturn


def run_registered(body: Callable[[], None]) -> NoReturn:
    """Run ``body`` with the add-on registered, unregister it and leave the process at once
    (bpy can hang in its exit handlers): status 0 when ``body`` returned, 1 when it raised
    (the traceback printed)."""
    from addon import register, unregister

    code = 1
    register()
    try:
        body()
        code = 0
    finally:
        unregister()
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
