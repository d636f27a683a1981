"""Build the VPL GI Blender extension zips with Blender's own extension tooling.

Steps:

1. Fetch the wheels pinned in ``tools/wheels.toml`` that are missing from ``wheels/``
   (``python -m pip download``, unmodified binary wheels from PyPI).
2. Check ``wheels/`` against the ``wheels`` list of ``blender_manifest.toml``: every listed wheel
   of the platforms being built must exist, every file in ``wheels/`` must be listed, and every
   listed wheel must be a pinned one.
3. Run ``blender_ext.py build --split-platforms`` (from the ``bpy`` module's ``bl_pkg`` add-on)
   with this Python, producing ``dist/vpl_gi-<version>-<platform>.zip``.
4. Run ``blender_ext.py validate`` on each zip and check each one holds exactly the wheels of its
   platform.

Usage::

    .venv/bin/python tools/build_extension.py                         # all platforms
    .venv/bin/python tools/build_extension.py --platform linux-x64    # only that one

A single-platform build is staged in a temporary copy of the source whose manifest lists only the
selected platforms and their wheels, because ``blender_ext.py build`` always builds every platform
its manifest names. The zip names are the same as in a full build.

Exits with status 1 and a one-line ``error: ...`` message on failure.
"""

from __future__ import annotations

import argparse
import importlib.util
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib
import zipfile
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
MANIFEST_NAME = "blender_manifest.toml"
PINS_FILE = REPO / "tools" / "wheels.toml"
WHEEL_DIR_NAME = "wheels"
PLATFORMS = ("linux-x64", "windows-x64", "macos-arm64", "macos-x64")

# Never copied into the staging folder of a single-platform build (the builder's own
# `paths_exclude_pattern` decides what goes into the zip; this only avoids copying bulk).
_STAGING_SKIP = {
    ".git", ".venv", "dist", WHEEL_DIR_NAME, "__pycache__", ".pytest_cache", ".ruff_cache",
    ".cache", "renders",
}
_WHEEL_RE = re.compile(
    r"^(?P<name>[^-]+)-(?P<version>[^-]+)(?:-(?P<build>\d[^-]*))?"
    r"-(?P<python>[^-]+)-(?P<abi>[^-]+)-(?P<platform>[^-]+)\.whl$"
)


class BuildError(Exception):
    """A build step failed; the message is one line meant for the user."""


class WheelFetchError(BuildError):
    """``pip download`` failed (typically: no network access)."""


@dataclass(frozen=True)
class Pin:
    """One pinned wheel: a package version for a Blender platform and a CPython tag."""

    platform: str  # Blender platform, e.g. "linux-x64"
    python: str  # CPython tag, e.g. "cp311"
    package: str
    version: str

    @property
    def python_version(self) -> str:
        """``"3.11"`` for ``cp311``."""
        digits = self.python.removeprefix("cp")
        return f"{digits[0]}.{digits[1:]}"


@dataclass(frozen=True)
class WheelName:
    """The parts of a wheel file name (PEP 427)."""

    filename: str
    name: str
    version: str
    python_tags: tuple[str, ...]
    abi: str
    platform_tags: tuple[str, ...]

    @classmethod
    def parse(cls, filename: str) -> WheelName | None:
        """Split ``filename``; ``None`` if it does not follow the wheel naming spec."""
        match = _WHEEL_RE.match(filename)
        if match is None:
            return None
        return cls(
            filename=filename,
            name=normalize_name(match["name"]),
            version=match["version"],
            python_tags=tuple(match["python"].split(".")),
            abi=match["abi"],
            platform_tags=tuple(match["platform"].split(".")),
        )

    def blender_platforms(self) -> set[str]:
        """The Blender platforms (``linux-x64`` ...) this wheel can be installed on."""
        result: set[str] = set()
        for tag in self.platform_tags:
            result |= blender_platforms_from_tag(tag)
        return result

    def supports_python(self, python: str) -> bool:
        """True if the wheel is ABI-compatible with CPython ``python`` (e.g. ``cp311``)."""
        if self.abi == python:
            return python in self.python_tags
        if self.abi == "abi3":
            wanted = int(python.removeprefix("cp"))
            return any(
                tag.startswith("cp") and tag[2:].isdigit() and int(tag[2:]) <= wanted
                for tag in self.python_tags
            )
        if self.abi == "none":
            return any(tag in {"py3", "py2.py3", python} for tag in self.python_tags)
        return False

    def matches(self, pin: Pin) -> bool:
        """True if this file is a valid wheel for ``pin``."""
        return (
            self.name == normalize_name(pin.package)
            and self.version == pin.version
            and self.supports_python(pin.python)
            and pin.platform in self.blender_platforms()
        )


def normalize_name(name: str) -> str:
    """Normalize a distribution name as wheel file names do (PEP 503, ``-`` → ``_``)."""
    return re.sub(r"[-_.]+", "_", name).lower()


def blender_platforms_from_tag(tag: str) -> set[str]:
    """Map one wheel platform tag to Blender platforms (mirrors ``blender_ext.py``'s rules)."""
    if tag == "any":
        return set(PLATFORMS)
    if tag == "win_amd64":
        return {"windows-x64"}
    if tag.startswith(("manylinux", "musllinux", "linux_")):
        if tag.endswith("_x86_64"):
            return {"linux-x64"}
        if tag.endswith("_aarch64"):
            return {"linux-arm64"}
        return set()
    if tag.startswith("macosx_"):
        if tag.endswith("_x86_64"):
            return {"macos-x64"}
        if tag.endswith("_arm64"):
            return {"macos-arm64"}
        if tag.endswith("_universal2"):
            return {"macos-x64", "macos-arm64"}
    return set()


def wheel_platforms(filename: str) -> set[str]:
    """Blender platforms of a wheel file name (empty if the name is not a wheel's)."""
    parsed = WheelName.parse(filename)
    return parsed.blender_platforms() if parsed else set()


def load_pins(pins_file: Path = PINS_FILE) -> tuple[list[Pin], dict[str, list[str]]]:
    """Read ``tools/wheels.toml``: the pins and the pip ``--platform`` tags per platform."""
    try:
        data = tomllib.loads(pins_file.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise BuildError(f"cannot read {pins_file}: {exc}") from exc
    pip_platforms: dict[str, list[str]] = data.get("pip_platforms", {})
    pins: list[Pin] = []
    for platform, by_python in data.get("wheels", {}).items():
        if platform not in PLATFORMS:
            raise BuildError(f"{pins_file.name}: unknown platform {platform!r}")
        if not pip_platforms.get(platform):
            raise BuildError(f"{pins_file.name}: no [pip_platforms] tags for {platform!r}")
        for python, packages in by_python.items():
            if not re.fullmatch(r"cp3\d+", python):
                raise BuildError(f"{pins_file.name}: bad Python tag {python!r} for {platform}")
            for package, version in packages.items():
                pins.append(Pin(platform, python, package, version))
    return pins, pip_platforms


def read_manifest(source_dir: Path) -> dict:
    """Parse ``blender_manifest.toml`` in ``source_dir``."""
    path = source_dir / MANIFEST_NAME
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise BuildError(f"cannot read {path}: {exc}") from exc


def manifest_wheel_files(manifest: dict) -> list[str]:
    """File names of the manifest's ``wheels`` entries, which must be ``./wheels/<file>``."""
    names: list[str] = []
    for entry in manifest.get("wheels", []):
        prefix = f"./{WHEEL_DIR_NAME}/"
        if not entry.startswith(prefix) or "/" in entry[len(prefix):]:
            raise BuildError(f"{MANIFEST_NAME}: wheel {entry!r} must be written as {prefix}<file>")
        names.append(entry[len(prefix):])
    return names


def find_wheel(pin: Pin, wheel_dir: Path) -> Path | None:
    """An existing file in ``wheel_dir`` that satisfies ``pin``, if any."""
    if not wheel_dir.is_dir():
        return None
    for path in sorted(wheel_dir.glob("*.whl")):
        parsed = WheelName.parse(path.name)
        if parsed is not None and parsed.matches(pin):
            return path
    return None


def fetch_wheels(
    pins: list[Pin], pip_platforms: dict[str, list[str]], wheel_dir: Path
) -> list[Path]:
    """Download the pinned wheels missing from ``wheel_dir``; return the file of every pin."""
    wheel_dir.mkdir(parents=True, exist_ok=True)
    found: dict[Pin, Path] = {}
    missing: dict[tuple[str, str], list[Pin]] = {}
    for pin in pins:
        path = find_wheel(pin, wheel_dir)
        if path is None:
            missing.setdefault((pin.platform, pin.python), []).append(pin)
        else:
            found[pin] = path
    for (platform, python), group in missing.items():
        with tempfile.TemporaryDirectory(prefix="vpl_gi_wheels_") as tmp:
            cmd = [
                sys.executable, "-m", "pip", "download", "--quiet", "--disable-pip-version-check",
                "--only-binary=:all:", "--no-deps", "--no-cache-dir",
                "--python-version", group[0].python_version, "--implementation", "cp",
                "--abi", python, "--abi", "abi3", "--abi", "none",
            ]
            for tag in pip_platforms[platform]:
                cmd += ["--platform", tag]
            cmd += ["--dest", tmp, *(f"{pin.package}=={pin.version}" for pin in group)]
            print(f"fetching {platform} {python}: " + ", ".join(
                f"{pin.package}=={pin.version}" for pin in group), flush=True)
            proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
            if proc.returncode != 0:
                last = (proc.stderr.strip() or proc.stdout.strip() or "no output").splitlines()[-1]
                raise WheelFetchError(f"pip download failed for {platform} {python}: {last}")
            fetched = sorted(Path(tmp).glob("*.whl"))
            for pin in group:
                hits = [p for p in fetched if (w := WheelName.parse(p.name)) and w.matches(pin)]
                if not hits:
                    raise BuildError(
                        f"pip found no {python} {platform} wheel for {pin.package}=={pin.version} "
                        f"(got: {', '.join(p.name for p in fetched) or 'nothing'})")
                target = wheel_dir / hits[0].name
                shutil.move(hits[0], target)
                found[pin] = target
    return [found[pin] for pin in pins]


def check_wheels(
    manifest: dict, pins: list[Pin], wheel_dir: Path, platforms: list[str]
) -> list[str]:
    """Cross-check the manifest's wheel list, the pins and ``wheel_dir``.

    Returns the manifest wheel file names that belong to ``platforms``.
    """
    listed = manifest_wheel_files(manifest)
    if len(set(listed)) != len(listed):
        raise BuildError(f"{MANIFEST_NAME}: a wheel is listed twice")
    manifest_platforms = manifest.get("platforms", [])
    for name in listed:
        parsed = WheelName.parse(name)
        if parsed is None:
            raise BuildError(f"{MANIFEST_NAME}: {name!r} is not a wheel file name")
        if not any(parsed.matches(pin) for pin in pins):
            raise BuildError(
                f"{MANIFEST_NAME} lists {name}, which no pin in {PINS_FILE.name} describes")
        if not parsed.blender_platforms() & set(manifest_platforms):
            raise BuildError(f"{MANIFEST_NAME} lists {name}, which fits none of its platforms")
    for pin in pins:
        if not any((w := WheelName.parse(name)) and w.matches(pin) for name in listed):
            raise BuildError(
                f"{MANIFEST_NAME} lists no wheel for {pin.package}=={pin.version} "
                f"{pin.python} {pin.platform} (pinned in {PINS_FILE.name})")
    on_disk = sorted(p.name for p in wheel_dir.iterdir()) if wheel_dir.is_dir() else []
    strays = [name for name in on_disk if name not in listed]
    if strays:
        raise BuildError(
            f"{WHEEL_DIR_NAME}/{strays[0]} is not listed in {MANIFEST_NAME} "
            f"(delete it or add it; {len(strays)} such file(s))")
    selected = [
        name for name in listed
        if wheel_platforms(name) & set(platforms)
    ]
    absent = [name for name in selected if name not in on_disk]
    if absent:
        raise BuildError(
            f"{MANIFEST_NAME} lists {WHEEL_DIR_NAME}/{absent[0]}, which does not exist "
            f"({len(absent)} missing)")
    return selected


def blender_ext_script() -> Path:
    """Locate ``blender_ext.py`` inside the installed ``bpy`` module (without importing bpy)."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or spec.origin is None:
        raise BuildError(f"bpy is not installed for {sys.executable}; use the repo's .venv python")
    matches = sorted(
        Path(spec.origin).parent.glob("[0-9]*.[0-9]*/scripts/addons_core/bl_pkg/cli/blender_ext.py")
    )
    if not matches:
        raise BuildError(f"blender_ext.py not found under {Path(spec.origin).parent}")
    return matches[-1]


def valid_tags_file(blender_ext: Path) -> Path | None:
    """Blender's list of valid extension tags (``_bpy_internal/extensions/tags.py``)."""
    scripts = blender_ext.parents[3]
    path = scripts / "modules" / "_bpy_internal" / "extensions" / "tags.py"
    return path if path.is_file() else None


def run_blender_ext(blender_ext: Path, *args: str) -> str:
    """Run ``blender_ext.py`` with this interpreter; return its output, raise on failure."""
    proc = subprocess.run(
        [sys.executable, str(blender_ext), *args], capture_output=True, text=True, check=False
    )
    output = (proc.stdout + proc.stderr).strip()
    if proc.returncode != 0:
        lines = [ln for ln in output.splitlines() if ln.strip()] or ["no output"]
        errors = [ln for ln in lines if "rror" in ln] or lines
        raise BuildError(f"blender_ext.py {args[0]} failed: {errors[-1].strip()}")
    return output


def _toml_str_list(items: list[str]) -> str:
    return "[" + ", ".join(f'"{item}"' for item in items) + "]"


def stage_source(
    source_dir: Path, staging: Path, platforms: list[str], wheel_files: list[str]
) -> None:
    """Copy ``source_dir`` to ``staging`` with a manifest narrowed to ``platforms``."""

    def ignore(_dir: str, names: list[str]) -> set[str]:
        return {name for name in names
                if name in _STAGING_SKIP or name.startswith(".venv")}  # .venv-5.3 ...

    shutil.copytree(source_dir, staging, ignore=ignore, symlinks=True)
    (staging / WHEEL_DIR_NAME).mkdir()
    for name in wheel_files:
        shutil.copy2(source_dir / WHEEL_DIR_NAME / name, staging / WHEEL_DIR_NAME / name)
    text = (source_dir / MANIFEST_NAME).read_text(encoding="utf-8")
    wheels_toml = _toml_str_list([f"./{WHEEL_DIR_NAME}/{name}" for name in wheel_files])
    text, n_platforms = re.subn(
        r"^platforms\s*=\s*\[[^\]]*\]", f"platforms = {_toml_str_list(platforms)}", text,
        count=1, flags=re.MULTILINE)
    text, n_wheels = re.subn(
        r"^wheels\s*=\s*\[[^\]]*\]", f"wheels = {wheels_toml}", text,
        count=1, flags=re.MULTILINE)
    wanted = {"platforms": platforms, "wheels": [f"./{WHEEL_DIR_NAME}/{n}" for n in wheel_files]}
    try:
        staged = tomllib.loads(text)
    except tomllib.TOMLDecodeError:
        staged = {}
    if n_platforms != 1 or n_wheels != 1 or {k: staged.get(k) for k in wanted} != wanted:
        raise BuildError(
            f"{MANIFEST_NAME}: could not narrow the top-level `platforms`/`wheels` arrays "
            "for a single-platform build (keep them as plain arrays without ']' in comments)")
    (staging / MANIFEST_NAME).write_text(text, encoding="utf-8")


def check_zip(zip_path: Path, expected_wheels: list[str], source_dir: Path) -> None:
    """Check a built zip: its wheels are exactly ``expected_wheels``; shaders and entry present."""
    with zipfile.ZipFile(zip_path) as archive:
        names = set(archive.namelist())
    wheels = sorted(n.removeprefix(f"{WHEEL_DIR_NAME}/") for n in names if n.endswith(".whl"))
    if wheels != sorted(expected_wheels):
        extra = sorted(set(wheels) - set(expected_wheels))
        lacking = sorted(set(expected_wheels) - set(wheels))
        raise BuildError(f"{zip_path.name}: wrong wheels (extra: {extra}, missing: {lacking})")
    required = {"__init__.py", MANIFEST_NAME}
    required |= {
        p.relative_to(source_dir).as_posix() for p in (source_dir / "gpu_shaders").glob("*.glsl")
    }
    if absent := sorted(required - names):
        raise BuildError(f"{zip_path.name}: missing {', '.join(absent)}")
    leaked = sorted(
        n for n in names
        if n.split("/", 1)[0] in {"tests", "tools", "devtools", "sample_scenes", "dist", ".venv",
                                   ".git"}
        or n.endswith((".blend", ".blend1", ".pyc"))
    )
    if leaked:
        raise BuildError(f"{zip_path.name}: holds excluded file {leaked[0]}")


def build(
    platforms: list[str] | None = None,
    *,
    source_dir: Path = REPO,
    output_dir: Path | None = None,
) -> list[Path]:
    """Fetch wheels, build and validate the extension zips; return their paths.

    ``platforms``: Blender platforms to build (``None``: every platform of the manifest).
    ``source_dir``: the extension source (holds ``blender_manifest.toml`` and ``wheels/``).
    ``output_dir``: where the zips go (default ``<source_dir>/dist``).
    """
    source_dir = source_dir.resolve()
    output_dir = (output_dir or source_dir / "dist").resolve()
    manifest = read_manifest(source_dir)
    manifest_platforms: list[str] = manifest.get("platforms", [])
    selected = list(manifest_platforms) if platforms is None else list(dict.fromkeys(platforms))
    if unknown := [p for p in selected if p not in manifest_platforms]:
        raise BuildError(f"platform {unknown[0]!r} is not in the manifest's {manifest_platforms}")
    if not selected:
        raise BuildError("no platform to build")

    pins, pip_platforms = load_pins()
    wheel_dir = source_dir / WHEEL_DIR_NAME
    fetch_wheels([pin for pin in pins if pin.platform in selected], pip_platforms, wheel_dir)
    wheel_files = check_wheels(manifest, pins, wheel_dir, selected)

    blender_ext = blender_ext_script()
    tags = valid_tags_file(blender_ext)
    tag_args = [f"--valid-tags={tags}"] if tags else []
    output_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="vpl_gi_stage_") as tmp:
        build_dir = source_dir
        if set(selected) != set(manifest_platforms):
            build_dir = Path(tmp) / "src"
            stage_source(source_dir, build_dir, selected, wheel_files)
        try:
            output = run_blender_ext(
                blender_ext, "build", "--source-dir", str(build_dir),
                "--output-dir", str(output_dir), "--split-platforms", *tag_args,
            )
        except BuildError as exc:  # name the real manifest, not the staged copy
            raise BuildError(str(exc).replace(str(build_dir), str(source_dir))) from None
        print(output, flush=True)

    prefix = f"{manifest['id']}-{manifest['version']}"
    zips: list[Path] = []
    for platform in selected:
        zip_path = output_dir / f"{prefix}-{platform.replace('-', '_')}.zip"
        if not zip_path.is_file():
            raise BuildError(f"blender_ext.py did not produce {zip_path}")
        print(run_blender_ext(blender_ext, "validate", *tag_args, str(zip_path)), flush=True)
        expected = [
            name for name in wheel_files
            if platform in wheel_platforms(name)
        ]
        check_zip(zip_path, expected, source_dir)
        zips.append(zip_path)
    return zips


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--platform", action="append", choices=PLATFORMS, dest="platforms",
        help="build only this platform (repeatable; default: every platform in the manifest)",
    )
    args = parser.parse_args(argv)
    try:
        zips = build(args.platforms)
    except BuildError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    cwd = Path.cwd()
    for zip_path in zips:
        shown = zip_path.relative_to(cwd) if zip_path.is_relative_to(cwd) else zip_path
        print(f"built {shown}  ({zip_path.stat().st_size:,} bytes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
