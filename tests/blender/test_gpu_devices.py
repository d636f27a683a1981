"""GPU choice and missing OpenGL features on the command line: one clear line, no traceback."""

from __future__ import annotations

from tests.blender.test_cli import CORNELL, run_cli


def test_gpus_lists_the_devices():
    result = run_cli("gpus")
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("0: ") and "OpenGL" in result.stdout


def test_a_gpu_that_does_not_exist_fails_the_render_with_its_name(tmp_path):
    out = tmp_path / "x.png"
    result = run_cli("render", str(CORNELL), "-o", str(out), "-r", "16x16", "--gpu", "9")
    assert result.returncode == 1
    assert "GPU 9 does not exist" in result.stderr and "Traceback" not in result.stderr
    assert not out.exists()


def test_opengl_4_1_fails_a_frame_that_needs_indirect_light_and_renders_direct_only(tmp_path):
    env = {"MESA_GL_VERSION_OVERRIDE": "4.1"}  # Mesa's llvmpipe then offers 4.1, as macOS does
    out = tmp_path / "x.png"
    result = run_cli("render", str(CORNELL), "-o", str(out), "-r", "16x16", env=env)
    assert result.returncode == 1 and not out.exists()
    assert "need OpenGL 4.3 (compute shaders)" in result.stderr
    assert "offers 4.1" in result.stderr and "Traceback" not in result.stderr
    result = run_cli("render", str(CORNELL), "-o", str(out), "-r", "16x16",
                     "--set", "bounces=0", "--set", "direct_shadows=shadow_maps", env=env)
    assert result.returncode == 0, result.stderr
    assert out.exists()

