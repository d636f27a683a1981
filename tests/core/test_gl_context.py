"""Choosing the OpenGL device and saying what is missing when no context can be made."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from addon.core.gpu.gl import (
    GPU_VARIABLE,
    GLUnavailableError,
    copy_into_texture,
    create_context,
    explain_failure,
    list_devices,
    requested_device,
)


def context_version(device: int | None = None) -> int:
    """The version code of a new context, made in a thread of its own so the test session's
    context stays current."""
    def version() -> int:
        ctx = create_context(device)
        try:
            return ctx.version_code
        finally:
            ctx.release()
    with ThreadPoolExecutor(max_workers=1) as pool:
        return pool.submit(version).result()


def test_every_device_is_listed_with_its_renderer_and_version():
    devices = list_devices()
    assert devices and devices[0].startswith("0: ")
    assert all("OpenGL" in line or "unusable" in line for line in devices)


def test_a_device_is_listed_with_the_version_a_render_gets():
    """NVIDIA's driver makes a 3.3 context unless asked for more: the list asks as a render
    does, so it never calls a usable GPU too old."""
    major, minor = divmod(context_version(0) // 10, 10)
    assert f"OpenGL {major}.{minor}" in list_devices()[0]


def test_a_device_that_does_not_exist_is_named_with_the_count():
    count = len(list_devices())
    with pytest.raises(GLUnavailableError, match=f"GPU {count + 3} does not exist: EGL finds "
                                                 f"{count} device"):
        create_context(count + 3)


def test_the_environment_variable_chooses_the_device(monkeypatch):
    monkeypatch.setenv(GPU_VARIABLE, "0")
    assert requested_device() == 0
    assert context_version() >= 410
    monkeypatch.setenv(GPU_VARIABLE, "first")
    with pytest.raises(GLUnavailableError, match="'first' is not a device number"):
        create_context()


def test_missing_egl_library_names_the_packages(monkeypatch):
    monkeypatch.setenv("GLCONTEXT_LINUX_LIBEGL", "/nonexistent/libEGL.so.1")
    with pytest.raises(GLUnavailableError, match=r"libEGL .* not installed.*libegl1"):
        create_context(0)


def test_a_driver_without_core_contexts_is_told_what_to_do():
    message = explain_failure(["eglCreateContext failed (0x3009)"] * 2, None)
    assert "older OpenGL" in message and "--gpu N" in message and "0x3009" in message


def test_a_copied_float_texture_keeps_its_precision_and_range(programs) -> None:
    """copy_into_texture keeps a float texture float: moderngl's copy_framebuffer into a
    texture would store 8 bits a channel clamped to [0, 1] (the bias compensation read its
    indirect light that way). From an accumulator with a glossy target too, the first (the
    diffuse light) is copied."""
    ctx = programs.ctx
    values = np.array([0.123456789, 3.7, 1e-4, 250.0], np.float32)
    source = ctx.texture((8, 4), 4, np.tile(values, 32).tobytes(), dtype="f4")
    glossy = ctx.texture((8, 4), 4, np.full(128, 9.0, np.float32).tobytes(), dtype="f4")
    copy = ctx.texture((8, 4), 4, dtype="f4")
    made = [copy, glossy, source]
    try:
        for attachments in ([source], [source, glossy]):
            framebuffer = ctx.framebuffer(attachments)
            made.append(framebuffer)
            copy_into_texture(ctx, copy, framebuffer)
            assert np.array_equal(np.frombuffer(copy.read(), np.float32).reshape(-1, 4),
                                  np.tile(values, (32, 1)))
    finally:
        for obj in made:
            obj.release()
