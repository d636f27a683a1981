"""The command line, run as a user would: ``python -m addon render ...`` in a subprocess."""

from __future__ import annotations

import hashlib
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from tests.blender.rendering import SAMPLE_SCENES, open_scene

REPO = Path(__file__).resolve().parents[2]
CORNELL = SAMPLE_SCENES / "cornell_box.blend"


def run_cli(*args: str, timeout: float = 120,
            env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    """``python -m addon ARGS`` in the repository, with ``env`` added to the environment."""
    return subprocess.run([sys.executable, "-m", "addon", *args], cwd=REPO, capture_output=True,
                          text=True, timeout=timeout, env={**os.environ, **(env or {})})


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_renders_a_png_and_says_where_it_went(tmp_path):
    out = tmp_path / "cornell.png"
    result = run_cli("render", str(CORNELL), "-o", str(out), "-r", "40x30",
                     "--set", "visibility=exact", "--set", "bias_compensation=full",
                     "--set", "vpl_count=32", "--set", "bias_samples=4")
    assert result.returncode == 0, result.stderr
    assert f"Saved {out}" in result.stdout
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "100.0%" in result.stderr  # the progress bar reached the end


def test_frame_range_writes_numbered_linear_exrs(tmp_path):
    result = run_cli("render", str(CORNELL), "-o", str(tmp_path / "frame_##.exr"), "-f", "1..2",
                     "-r", "16x16")
    assert result.returncode == 0, result.stderr
    for frame in (1, 2):
        data = (tmp_path / f"frame_{frame:02d}.exr").read_bytes()
        assert data[:4] == b"\x76\x2f\x31\x01"  # OpenEXR magic number


@pytest.mark.parametrize("args, message", [
    (["render", "missing.blend", "-o", "x.png"], "scene file not found"),
    (["render", str(CORNELL), "-o", "x.png", "-f", "3..1"], "ends before it starts"),
    (["render", str(CORNELL), "-o", "x.png", "-r", "big"], "cannot read resolution"),
    (["render", str(CORNELL), "-o", "x.png", "--set", "seed=-1"], "seed"),
    (["render", str(CORNELL), "-o", "x.png", "--set", "visibility=fast"], "not one of"),
    (["render", str(CORNELL), "-o", "x.png", "--set", "bounces=two"], "not a valid int"),
    (["render", str(CORNELL), "-o", "x.png", "--set", "ism_resolution=7"],
     "ism_resolution = '7' is not one of 32, 64, 128, 256, 512"),
    (["render", str(CORNELL), "-o", "x.png", "--set", "interleave=3"], "not one of 1, 2, 4, 8"),
    (["render", str(CORNELL), "-o", "x.png", "--set", "bounce=2"], "unknown setting 'bounce'"),
    (["render", str(CORNELL), "-o", "/proc/forbidden/x.png"], "cannot create output folder"),
    (["render", str(CORNELL), "-o", str(REPO / "sample_scenes")], "-o names a folder"),
    (["render", str(CORNELL), "-o", "x.gif"], "cannot write '.gif' images"),
    (["render", str(CORNELL), "-o", "x.png", "-r", "1x1"], "resolution 1x1 is outside 4..65536"),
    (["render", str(CORNELL), "-o", "x.png", "-r", "64x64", "-p", "1"],
     "the image has no pixels: 64x64 at 1 % is 0x0"),
])
def test_bad_input_is_one_clear_line_and_exit_code_2(args, message):
    result = run_cli(*args)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert lines[-1].startswith("error: ") and message in lines[-1]
    assert "Traceback" not in result.stderr


def test_integer_choices_and_float_bounds_set_from_the_command_line_render(tmp_path):
    """Integer choices are enums in Blender, and time_budget's minimum comes back from Blender's
    single-precision property slightly below 0.01: both render."""
    out = tmp_path / "set.png"
    result = run_cli("render", str(CORNELL), "-o", str(out), "-r", "16x16",
                     "--set", "ism_resolution=64", "--set", "interleave=2",
                     "--set", "time_budget=0.01", "--set", "vpl_source=rsm",
                     "--set", "rsm_resolution=64", "--set", "vpl_count=32")
    assert result.returncode == 0, result.stderr
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_never_overwrites_the_scene(tmp_path):
    scene = tmp_path / "scene.blend"
    scene.write_bytes(CORNELL.read_bytes())
    before = digest(scene)
    result = run_cli("render", str(scene), "-o", str(scene))
    assert result.returncode == 2 and "refusing" in result.stderr
    assert digest(scene) == before


def test_scene_without_camera_is_refused(blender, tmp_path):
    scene = open_scene("light_point", 16)
    blender.data.objects.remove(scene.camera)
    path = tmp_path / "no_camera.blend"
    blender.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    result = run_cli("render", str(path), "-o", str(tmp_path / "x.png"))
    assert result.returncode == 2 and "no active camera" in result.stderr


def test_image_format_follows_the_extension(tmp_path):
    result = run_cli("render", str(CORNELL), "-o", str(tmp_path / "x.jpg"), "-r", "16x16",
                     "--set", "visibility=exact", "--set", "vpl_count=8")
    assert result.returncode == 0, result.stderr
    assert [p.name for p in tmp_path.iterdir()] == ["x.jpg"]
    assert (tmp_path / "x.jpg").read_bytes()[:3] == b"\xff\xd8\xff"  # JPEG


def test_a_stereo_scene_writes_each_eye(blender, tmp_path):
    """Stereoscopy with individual views: each eye's file (_L, _R), and each named, with
    no error line (Blender reports the plain path unsaved after writing the views)."""
    scene = open_scene("light_point", 16)
    scene.render.use_multiview, scene.render.views_format = True, "STEREO_3D"
    path = tmp_path / "stereo.blend"
    blender.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    result = run_cli("render", str(path), "-o", str(tmp_path / "eye.png"),
                     "--set", "vpl_count=8")
    assert result.returncode == 0, result.stderr
    assert sorted(p.name for p in tmp_path.glob("eye*")) == ["eye_L.png", "eye_R.png"]
    saved = [line for line in result.stdout.splitlines() if line.startswith("Saved ")]
    assert [line.split()[1] for line in saved] == [str(tmp_path / "eye_L.png"),
                                                   str(tmp_path / "eye_R.png")]
    assert "could not be saved" not in result.stdout + result.stderr


@pytest.mark.parametrize("change, message", [
    ("border", "the render border leaves no pixels of the 32x32 at 100 % image"),
    ("empty", "frame 1: the scene camera 'Empty' is not a camera but an object of type Empty"),
])
def test_scene_that_cannot_render_is_refused_before_rendering(blender, tmp_path, change,
                                                              message):
    scene = open_scene("light_point", 32)
    if change == "border":
        scene.render.use_border = True
        scene.render.border_min_x = scene.render.border_max_x = 0.5
    else:
        empty = blender.data.objects.new("Empty", None)
        scene.collection.objects.link(empty)
        scene.camera = empty
    path = tmp_path / f"{change}.blend"
    blender.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    result = run_cli("render", str(path), "-o", str(tmp_path / "x.png"))
    assert result.returncode == 2, result.stderr
    assert result.stderr.strip().splitlines()[-1].startswith(f"error: {message}")
    assert "Traceback" not in result.stderr and not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("delay", [0.3, 1.0, 2.0])
def test_ctrl_c_at_any_moment_exits_130_within_a_second(tmp_path, delay):
    """While Python imports, Blender loads, the scene exports or shaders compile: Python's own
    handler would wait for the main thread (or raise KeyboardInterrupt anywhere)."""
    out = tmp_path / "x.png"
    process = subprocess.Popen(
        [sys.executable, "-m", "addon", "render", str(CORNELL), "-o", str(out), "-r", "64x64"],
        cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(delay)
    sent = time.monotonic()
    process.send_signal(signal.SIGINT)
    try:
        _, stderr = process.communicate(timeout=60)
    finally:
        process.kill()
    assert process.returncode == 130, stderr
    assert time.monotonic() - sent < 1.0
    assert "Traceback" not in stderr and not out.exists()


def test_ctrl_c_cancels_and_exits_130(tmp_path):
    process = subprocess.Popen(
        [sys.executable, "-m", "addon", "render", str(CORNELL), "-o", str(tmp_path / "x.png"),
         "-r", "256x256", "--set", "light_samples=1024", "--set", "antialiasing=4"],
        cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    started = threading.Event()
    lines: list[str] = []

    def read_progress() -> None:  # the progress bar's first line: our render has started
        for line in process.stderr:
            lines.append(line)
            if "frame 1/1" in line:
                started.set()

    reader = threading.Thread(target=read_progress, daemon=True)
    reader.start()
    assert started.wait(timeout=90), f"no progress line within 90 s: {lines[-5:]}"
    assert process.poll() is None, "the render ended before Ctrl-C"
    process.send_signal(signal.SIGINT)
    try:
        process.wait(timeout=60)
    finally:
        process.kill()
    reader.join(timeout=5)
    assert process.returncode == 130, "".join(lines[-10:])
    assert not (tmp_path / "x.png").exists()
