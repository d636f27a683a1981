"""End-to-end test of the packaged extension.

Builds ``vpl_gi-<version>-linux_x64.zip`` with ``tools/build_extension.py`` (Blender's own
``blender_ext.py build``/``validate``), then, in a fresh ``bpy`` process whose user resources
live in a temporary folder, installs the zip as an extension, checks the add-on is enabled and
the ``VPL_GI`` engine is registered, renders a tiny scene to EXR and checks the pixels.

The child process can only import what a real Blender has: the standard library, ``bpy`` with
its bundled modules, numpy (and the few modules Blender ships besides), plus the extension's own
wheels. Modules that exist only in the development venv (moderngl, glcontext, xatlas, scipy,
pytest, ...) are hidden, so the test proves the bundled wheels are what gets loaded.
"""

from __future__ import annotations

import importlib.util
import json
import os
import re
import subprocess
import sys
import zipfile
from pathlib import Path
from types import ModuleType

import pytest

REPO = Path(__file__).resolve().parents[2]
PLATFORM = "linux-x64"
CHILD_TIMEOUT_S = 300
RESULT_PREFIX = "VPL_GI_TEST_RESULT "

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="builds and installs the linux-x64 package"
)


def _load_build_tool() -> ModuleType:
    spec = importlib.util.spec_from_file_location(
        "vpl_gi_build_extension", REPO / "tools" / "build_extension.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses need the module registered
    spec.loader.exec_module(module)
    return module


build_tool = _load_build_tool()


@pytest.fixture(scope="module")
def extension_zip(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The linux-x64 zip, built (and validated) into a temporary folder."""
    out = tmp_path_factory.mktemp("dist")
    try:
        zips = build_tool.build([PLATFORM], output_dir=out)
    except build_tool.WheelFetchError as exc:
        pytest.skip(f"cannot fetch the pinned wheels (offline?): {exc}")
    assert len(zips) == 1
    return zips[0]


def test_zip_is_valid_and_holds_linux_wheels(extension_zip: Path) -> None:
    blender_ext = build_tool.blender_ext_script()
    output = build_tool.run_blender_ext(blender_ext, "validate", str(extension_zip))
    assert "Success" in output
    assert extension_zip.name.endswith("-linux_x64.zip")
    with zipfile.ZipFile(extension_zip) as archive:
        names = archive.namelist()
    wheels = [n for n in names if n.endswith(".whl")]
    for package in ("moderngl", "glcontext", "xatlas", "scipy"):
        for python in ("cp311", "cp313"):
            assert any(
                n.startswith(f"wheels/{package}-") and f"-{python}-{python}-" in n for n in wheels
            ), f"no {package} {python} wheel in {extension_zip.name}"
    assert any(n.startswith("wheels/pyoidn-") and "-py3-none-" in n for n in wheels), wheels
    assert all("x86_64" in n or n.endswith("-any.whl") for n in wheels), wheels
    assert not any(n.startswith("wheels/numpy") for n in names)
    assert "__init__.py" in names
    assert any(n.startswith("gpu_shaders/") and n.endswith(".glsl") for n in names)


def test_zip_holds_no_developer_tools(extension_zip: Path) -> None:
    """devtools/ (the report, OBJ scenes, metrics) stays out, and nothing imports matplotlib."""
    with zipfile.ZipFile(extension_zip) as archive:
        names = archive.namelist()
        sources = {n: archive.read(n).decode() for n in names if n.endswith(".py")}
    assert not any(n.startswith("devtools/") for n in names), names
    dev_files = {"report.py", "obj_scene.py", "metrics.py"}
    assert not [n for n in names if n.rsplit("/", 1)[-1] in dev_files]
    matplotlib = re.compile(r"^\s*(import|from)\s+matplotlib\b", re.MULTILINE)
    assert not [n for n, text in sources.items() if matplotlib.search(text)]


# Runs in a fresh interpreter: argv = [zip, work folder]; prints RESULT_PREFIX + JSON.
CHILD_SCRIPT = r'''
import importlib.machinery
import json
import math
import os
import site
import sys

ZIP, WORK = sys.argv[1], sys.argv[2]
RESOURCES = os.environ["BLENDER_USER_RESOURCES"]
MODULE = "bl_ext.user_default.vpl_gi"

# Modules a real Blender 4.5 ships (besides the standard library and bpy's own folders):
# everything else found only in the development venv's site-packages is hidden.
BLENDER_SHIPS = {
    "bpy", "numpy", "requests", "certifi", "charset_normalizer", "idna", "urllib3",
    "zstandard", "Cython", "cython", "pyximport", "pip", "setuptools", "pkg_resources",
    "_distutils_hack",
}
DEV_SITE = {os.path.realpath(p) for p in site.getsitepackages()}


class HideDevVenv:
    """Find non-Blender top-level modules anywhere but in the dev venv's site-packages."""

    @staticmethod
    def find_spec(name, path=None, target=None):
        if path is not None or name in BLENDER_SHIPS:
            return None
        allowed = [p for p in sys.path if os.path.realpath(p or ".") not in DEV_SITE]
        spec = importlib.machinery.PathFinder.find_spec(name, allowed)
        if spec is not None:
            return spec
        if importlib.machinery.PathFinder.find_spec(name, sorted(DEV_SITE)) is not None:
            raise ModuleNotFoundError(
                f"{name!r} is only in the development venv (Blender does not ship it, and no "
                "bundled wheel provides it)", name=name)
        return None


sys.meta_path.insert(0, HideDevVenv)

import bpy  # noqa: E402

result = {"errors": []}
preloaded = sorted({"moderngl", "glcontext", "xatlas", "scipy"} & set(sys.modules))
result["preloaded"] = preloaded
result["extensions_dir"] = bpy.utils.user_resource("EXTENSIONS")

ret = bpy.ops.extensions.package_install_files(
    filepath=ZIP, repo="user_default", enable_on_install=True)
result["install"] = sorted(ret)

import addon_utils  # noqa: E402

result["enabled"] = addon_utils.check(MODULE)[1]
engines = [getattr(c, "bl_idname", None) for c in bpy.types.RenderEngine.__subclasses__()]
result["engine_classes"] = [e for e in engines if e]

# The engine enum is dynamic (bl_rna's enum_items lists only the built-in static item), so read
# the accepted values from the error raised for an unknown one.
scene = bpy.context.scene
try:
    scene.render.engine = "__NO_SUCH_ENGINE__"
except TypeError as exc:
    result["engine_enum_error"] = str(exc)

modules = {}
for name in ("moderngl", "glcontext", "xatlas", "scipy", "pyoidn", "cffi", "pycparser",
             "threadpoolctl"):
    try:
        module = __import__(name)
        modules[name] = module.__file__
    except Exception as exc:
        modules[name] = f"ImportError: {exc}"
result["module_files"] = modules
result["python"] = f"cp{sys.version_info.major}{sys.version_info.minor}"
# Every wheel Blender unpacked for the extension (the site-packages the modules came from),
# as {dist-info folder: [its WHEEL tags]}, and the compiled modules loaded from there.
sites = {os.path.dirname(os.path.dirname(f)) if f.endswith("__init__.py") else
         os.path.dirname(f) for f in modules.values() if not f.startswith("ImportError")}
unpacked = {}
for site_dir in sorted(sites):
    for entry in sorted(os.listdir(site_dir)):
        if entry.endswith(".dist-info"):
            with open(os.path.join(site_dir, entry, "WHEEL"), encoding="utf-8") as wheel:
                unpacked[entry] = [line.split(":", 1)[1].strip() for line in wheel
                                   if line.startswith("Tag:")]
result["site_dirs"] = sorted(sites)
result["unpacked"] = unpacked
result["native_modules"] = sorted(
    os.path.basename(m.__file__) for m in list(sys.modules.values())
    if getattr(m, "__file__", None) and m.__file__.endswith(".so")
    and any(m.__file__.startswith(site_dir + os.sep) for site_dir in sites))

try:
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    mesh = bpy.data.meshes.new("Plane")
    mesh.from_pydata([(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], [], [(0, 1, 2, 3)])
    mesh.update()
    scene.collection.objects.link(bpy.data.objects.new("Plane", mesh))
    light_data = bpy.data.lights.new("Light", type="POINT")
    light_data.energy = 300.0
    light = bpy.data.objects.new("Light", light_data)
    light.location = (0.3, 0.2, 1.5)
    scene.collection.objects.link(light)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location = (0.0, 0.0, 4.0)  # default orientation looks down -Z
    scene.collection.objects.link(camera)
    scene.camera = camera

    render = scene.render
    render.engine = "VPL_GI"
    result["engine_set"] = render.engine
    render.resolution_x = render.resolution_y = 32
    render.resolution_percentage = 100
    render.image_settings.file_format = "OPEN_EXR"
    render.image_settings.color_depth = "32"
    render.filepath = os.path.join(WORK, "render.exr")
    scene.vpl_gi.denoiser = "blur_oidn"  # the bundled pyoidn, inside Blender
    result["render"] = sorted(bpy.ops.render.render(write_still=True))
    monitor = sys.modules[MODULE + ".addon.engine"].monitor
    result["warnings"] = list(monitor.last_warnings)
    result["stages"] = sorted(monitor.last_stats.timings) if monitor.last_stats else []
    prefs = bpy.context.preferences.addons[MODULE].preferences
    result["gpu_default"] = prefs.gpu_device
    prefs.gpu_device = 7  # no such GPU here: the next render says so
    try:
        bpy.ops.render.render(write_still=False)
    except RuntimeError as exc:
        result["gpu_error"] = str(exc)
    prefs.gpu_device = -1

    exrs = sorted(f for f in os.listdir(WORK) if f.endswith(".exr"))
    result["exr_files"] = exrs
    if exrs:
        import numpy as np

        image = bpy.data.images.load(os.path.join(WORK, exrs[0]))
        result["image_size"] = list(image.size)
        pixels = np.empty(image.size[0] * image.size[1] * image.channels, dtype=np.float32)
        image.pixels.foreach_get(pixels)
        rgba = pixels.reshape(-1, image.channels)
        result["all_finite"] = bool(np.isfinite(rgba).all())
        result["max_rgb"] = float(np.nan_to_num(rgba[:, :3]).max())
        result["mean_rgb"] = float(np.nan_to_num(rgba[:, :3]).mean())
except Exception as exc:
    import traceback

    result["errors"].append("".join(traceback.format_exception(exc)))
finally:
    # A bpy process hangs at exit while a RenderEngine subclass is registered.
    bpy.ops.preferences.addon_disable(module=MODULE)
    result["disabled"] = not addon_utils.check(MODULE)[1]

print("\n" + "VPL_GI_TEST_RESULT " + json.dumps(result), flush=True)
'''


def test_install_enable_and_render(extension_zip: Path, tmp_path: Path) -> None:
    resources = tmp_path / "blender_user"
    work = tmp_path / "work"
    resources.mkdir()
    work.mkdir()
    script = tmp_path / "child.py"
    script.write_text(CHILD_SCRIPT, encoding="utf-8")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("BLENDER_", "PYTHON"))}
    env["BLENDER_USER_RESOURCES"] = str(resources)
    try:
        proc = subprocess.run(
            [sys.executable, str(script), str(extension_zip), str(work)],
            capture_output=True, text=True, env=env, timeout=CHILD_TIMEOUT_S, cwd=tmp_path,
            check=False,
        )
    except subprocess.TimeoutExpired as exc:
        pytest.fail(f"bpy child process did not finish within {CHILD_TIMEOUT_S}s: {exc.stdout!r}")
    output = proc.stdout + proc.stderr
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith(RESULT_PREFIX)]
    assert proc.returncode == 0 and lines, f"child failed ({proc.returncode}):\n{output[-4000:]}"
    result = json.loads(lines[-1][len(RESULT_PREFIX):])
    context = f"\nresult: {json.dumps(result, indent=1)}\nchild output tail:\n{output[-3000:]}"

    assert Path(result["extensions_dir"]).resolve().is_relative_to(resources.resolve()), context
    assert result["preloaded"] == [], context
    assert result["install"] == ["FINISHED"], context
    assert result["enabled"], context
    assert "VPL_GI" in result["engine_classes"], context
    assert "'VPL_GI'" in result.get("engine_enum_error", ""), context
    for name, file in result["module_files"].items():
        # Loaded from the wheels Blender unpacked under <user resources>/extensions/.local/.
        assert Path(file).resolve().is_relative_to(resources.resolve()), f"{name}: {file}{context}"
    # ... and those are the wheels pinned for this Blender's Python, and only those.
    python = result["python"]
    assert python == f"cp{sys.version_info.major}{sys.version_info.minor}", context
    pins, _ = build_tool.load_pins()
    expected = {build_tool.normalize_name(p.package): p.version for p in pins
                if p.platform == PLATFORM and p.python == python}
    assert {"moderngl", "glcontext", "xatlas", "scipy"} <= set(expected), expected
    unpacked = {}
    for dist_info, tags in result["unpacked"].items():
        name, version = dist_info.removesuffix(".dist-info").rsplit("-", 1)
        unpacked[build_tool.normalize_name(name)] = version
        assert tags and all(tag.startswith((f"{python}-{python}-", "py3-none-"))
                            for tag in tags), \
            f"{dist_info}: {tags}{context}"
    assert unpacked == expected, context
    assert result["native_modules"], context
    abi = f"cpython-{python.removeprefix('cp')}-"
    assert all(abi in so for so in result["native_modules"]), context
    assert not result["errors"], context
    assert result["engine_set"] == "VPL_GI", context
    assert "denoise" in result["stages"] and not result["warnings"], context
    assert result["render"] == ["FINISHED"], context
    assert result["gpu_default"] == -1, context  # the preference: first device unless chosen
    assert "GPU 7 does not exist" in result.get("gpu_error", ""), context
    assert result["exr_files"], context
    assert result["image_size"] == [32, 32], context
    assert result["all_finite"], context
    assert result["max_rgb"] > 1e-4, context
    assert result["disabled"], context
