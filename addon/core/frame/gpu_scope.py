"""GPU object lifetimes: a scope releases what it owns when it closes, errors included."""

from __future__ import annotations

from typing import Protocol, TypeVar


class Releasable(Protocol):
    def release(self) -> None: ...


T = TypeVar("T", bound=Releasable)


class GpuScope:
    """Owns GPU objects (textures, buffers, framebuffers, vertex arrays) of one frame, tile or
    batch. Use as a context manager, or call ``release`` to empty it for reuse."""

    def __init__(self) -> None:
        self._objects: list[Releasable] = []

    def own(self, obj: T) -> T:
        """Release ``obj`` with this scope; returns it."""
        self._objects.append(obj)
        return obj

    def release(self) -> None:
        """Release every object owned so far, newest first; the scope stays usable."""
        while self._objects:
            self._objects.pop().release()

    def __enter__(self) -> GpuScope:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.release()
