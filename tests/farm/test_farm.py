"""Render farms: the Blender-style launcher (``python -m addon blender``, tools/vplgi-blender)
and the Flamenco job type farm/vpl_gi.js."""

from __future__ import annotations

import json
import os
import re
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from addon.blender_args import output_pattern, parse, timecode
from addon.cli import CliError

REPO = Path(__file__).resolve().parents[2]
CORNELL = REPO / "sample_scenes" / "cornell_box.blend"
WRAPPER = REPO / "tools" / "vplgi-blender"
FIXTURES = Path(__file__).parent / "fixtures"
# Cheap settings, the same through both command lines.
SETTINGS = {"vpl_count": "32", "visibility": "'exact'", "bias_samples": "4", "seed": "5"}
EXPR = ("import bpy; s = bpy.context.scene; s.render.resolution_x = 16; "
        "s.render.resolution_y = 12; s.render.resolution_percentage = 100; "
        + "; ".join(f"s.vpl_gi.{k} = {v}" for k, v in SETTINGS.items()))
SAVED = re.compile(r"^Saved: '(.*)'$", re.MULTILINE)
TIME = re.compile(r"^Time: \d\d:\d\d\.\d\d \(Saving: \d\d:\d\d\.\d\d\)$", re.MULTILINE)


# Blender's stamp metadata in every PNG: when it was rendered and how long it took, which
# differ between any two renders (even two runs of ``python -m addon render``).
VOLATILE_TEXT = (b"Date\0", b"RenderTime\0")


def image_bytes(path: Path) -> bytes:
    """The PNG's bytes, chunk by chunk, without the date and render-time text chunks:
    every header, colour and pixel byte, compressed as written."""
    data, at, kept = path.read_bytes(), 8, [path.read_bytes()[:8]]
    while at < len(data):
        (length,) = struct.unpack(">I", data[at:at + 4])
        chunk = data[at:at + 12 + length]
        if not (chunk[4:8] == b"tEXt" and chunk[8:].startswith(VOLATILE_TEXT)):
            kept.append(chunk)
        at += 12 + length
    return b"".join(kept)


def launch(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    """tools/vplgi-blender as a Flamenco worker runs it: no shell, this test's Python."""
    env = dict(os.environ, VPLGI_PYTHON=sys.executable)
    return subprocess.run([str(WRAPPER), *args], cwd="/", capture_output=True, text=True,
                          timeout=timeout, env=env)


def flamenco_args(out: Path, frames: str) -> list[str]:
    return ["-b", "-y", str(CORNELL), "--scene", "Scene", "--python-expr", EXPR,
            "--render-output", str(out / "######"), "--render-format", "PNG",
            "--render-frame", frames]


# --- argument parsing (no Blender) -------------------------------------------------------

@pytest.mark.parametrize("frames", ["1", "1,2", "1..3"])
def test_parses_flamencos_argument_forms(frames):
    args = parse(["-b", "-y", "f.blend", "--scene", "S", "--python-expr", "x = 1",
                  "--render-output", "/o/######", "--render-format", "PNG",
                  "--render-frame", frames])
    assert (args.scene, args.frames, args.output, args.file_format) == \
        (Path("f.blend"), frames, "/o/######", "PNG")
    assert args.steps == [("scene", "S"), ("expr", "x = 1")]


@pytest.mark.parametrize("argv, message", [
    (["-b", "f.blend"], "nothing to render"),
    (["-b", "--render-frame", "1"], "no .blend file"),
    (["f.blend", "-E", "CYCLES", "-f", "1"], "VPL_GI only"),
    (["f.blend", "-F", "JPEG", "-f", "1"], "not supported"),
    (["f.blend", "--wobble", "-f", "1"], "unsupported Blender option --wobble"),
    (["f.blend", "-f", "1", "-f", "2"], "only one"),
    (["f.blend", "--scene"], "needs a value"),
])
def test_refuses_what_it_cannot_do(argv, message):
    with pytest.raises(CliError, match=message):
        parse(argv)


def test_output_pattern_follows_blender():
    blend = Path("/s/f.blend")
    assert output_pattern("/o/######", "PNG", blend) == "/o/######.png"
    assert output_pattern("/o/frame_", "OPEN_EXR", blend) == "/o/frame_####.exr"
    assert output_pattern("/o/x_##.png", "PNG", blend) == "/o/x_##.png"
    assert output_pattern("//out/####", "PNG", blend) == "/s/out/####.png"


def test_timecode_is_blenders():
    assert timecode(1.234) == "00:01.23"
    assert timecode(83.5) == "01:23.50"
    assert timecode(3725.01) == "01:02:05.01"


def test_wrapper_exits_non_zero_on_bad_arguments():
    result = launch("-b", str(CORNELL), "--render-format", "TIFF", "--render-frame", "1")
    assert result.returncode == 2
    assert "TIFF is not supported" in result.stderr


# --- rendering ---------------------------------------------------------------------------

def test_launcher_prints_blenders_lines_and_matches_the_render_command(tmp_path):
    farm, local, alone = tmp_path / "farm", tmp_path / "local", tmp_path / "alone"
    result = launch(*flamenco_args(farm, "1,2"))
    assert result.returncode == 0, result.stderr
    saved = SAVED.findall(result.stdout)
    assert saved == [str(farm / "000001.png"), str(farm / "000002.png")]
    assert len(TIME.findall(result.stdout)) == 2

    overrides = [a for k, v in SETTINGS.items() for a in ("--set", f"{k}={v.strip(chr(39))}")]
    local_run = subprocess.run(
        [sys.executable, "-m", "addon", "render", str(CORNELL), "-o", str(local / "######.png"),
         "-f", "1,2", "-r", "16x12", "-p", "100", *overrides],
        cwd=REPO, capture_output=True, text=True, timeout=300)
    assert local_run.returncode == 0, local_run.stderr
    for frame in (1, 2):
        name = f"{frame:06d}.png"
        assert image_bytes(farm / name) == image_bytes(local / name), name

    # A frame rendered alone (a chunk of one) equals the same frame inside a chunk.
    result = launch(*flamenco_args(alone, "2"))
    assert result.returncode == 0, result.stderr
    assert SAVED.findall(result.stdout) == [str(alone / "000002.png")]
    assert image_bytes(alone / "000002.png") == image_bytes(farm / "000002.png")


def test_launcher_fails_on_a_broken_python_expr(tmp_path):
    result = launch("-b", str(CORNELL),
                    "--python-expr", "bpy.context.scene.vpl_gi.visibility = 'x'",
                    "--render-output", str(tmp_path / "######"), "--render-frame", "1")
    assert result.returncode != 0
    assert "--python-expr failed" in result.stderr
    assert not SAVED.search(result.stdout)


def test_launcher_fails_on_an_unknown_scene(tmp_path):
    result = launch("-b", str(CORNELL), "--scene", "Nope",
                    "--render-output", str(tmp_path / "######"), "--render-frame", "1")
    assert result.returncode != 0
    assert "no scene 'Nope'" in result.stderr


# --- the Flamenco job type ---------------------------------------------------------------

@pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed")
def test_job_type_compiles_to_the_recorded_commands():
    result = subprocess.run(
        ["node", str(Path(__file__).parent / "harness.js"), str(REPO / "farm" / "vpl_gi.js"),
         str(FIXTURES / "job.json")], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    compiled = json.loads(result.stdout)
    assert compiled == json.loads((FIXTURES / "job_compiled.json").read_text())
    # Every render command is one the launcher reads, with the settings pinned.
    for task in compiled["tasks"]:
        for command in task["commands"]:
            if command["name"] != "blender-render":
                continue
            parameters = command["parameters"]
            args = parse([*parameters["argsBefore"], parameters["blendfile"],
                          *parameters["args"]])
            expr = dict(args.steps)["expr"]
            assert "v.auto_parameters = \"off\"" in expr and "v.incremental = False" in expr
            assert "s.render.engine = 'VPL_GI'" in expr
            assert "v.bl_rna.properties[\"vpl_count\"]; v.vpl_count = 32" in expr
