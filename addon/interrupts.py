"""Ctrl-C for the command line: the process ends at once with exit code 130, whatever it is
doing, and leaves no half-written image."""

from __future__ import annotations

import os
import signal
import sys
import threading


class Interrupts:
    """Ctrl-C at any moment (while Blender loads, during export, shader compilation or a
    frame) ends the process at once with exit code 130.

    SIGINT is blocked in every thread and taken by one waiting thread: Python runs its own
    signal handlers only between the main thread's bytecodes, which long calls into C (loading
    a .blend, compiling shaders, building a BVH) hold up for seconds. An image being saved is
    finished first (``saving``), so none is left half-written."""

    def __init__(self) -> None:
        self.saving = threading.Lock()

    def start(self) -> None:
        """Take over SIGINT; call first, before any other thread starts (threads inherit the
        mask) and before the slow imports (numpy, bpy)."""
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        threading.Thread(target=self._wait, name="ctrl-c", daemon=True).start()

    def _wait(self) -> None:
        signal.sigwait({signal.SIGINT})
        self.saving.acquire()
        sys.stdout.flush()
        sys.stderr.write("\ncancelled: no image written for this frame\n")
        sys.stderr.flush()
        os._exit(130)  # no teardown: bpy can hang at exit, and there is nothing to keep


interrupts = Interrupts()
