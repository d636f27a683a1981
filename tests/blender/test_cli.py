"""The command line, run as a user would: ``python -m addon render ...`` in a subprocess."""

from __future__ import annotations

import hashlib
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from tests.blender.rendering import SAMPLE_SCENES, open_scene

REPO = Path(__file__).resolve().parents[2]
CORNELL = SAMPLE_SCENES / "cornell_box.blend"


def run_cli(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "addon", *args], cwd=REPO, capture_output=True,
                          text=True, timeout=timeout)


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_renders_a_png_and_says_where_it_went(tmp_path):
    out = tmp_path / "cornell.png"
    result = run_cli("render", str(CORNELL), "-o", str(out), "-r", "40x30",
                     "--set", "visibility=exact", "--set", "bias_compensation=on",
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
