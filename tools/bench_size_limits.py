"""Size limits of the renderer: 4096 VPLs, 4K frames, millions of triangles and instances.

Each case runs in a fresh Python process so its peak resident memory (``wait4``'s ru_maxrss,
which includes what Mesa llvmpipe allocates for "GPU" buffers) is its own. A case either renders
(the frame must be finite) or is refused with a RenderError / SettingsError message naming the
limit; anything else — a crash, a signal, an out-of-memory kill — is reported as such. A guard
kills a case whose resident memory passes --memory-guard (default 12 GiB) so the bench cannot
take the machine down; that too is reported.

    .venv/bin/python tools/bench_size_limits.py              # every case, a table at the end
    .venv/bin/python tools/bench_size_limits.py 4k-aa2 tris-4M   # chosen cases
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


@dataclass
class Case:
    """One render: frame size, triangle count and settings."""

    width: int = 256
    height: int = 256
    triangles: int = 0  # extra triangles: a finely tessellated floor (0 = two)
    instances: int = 0  # balls of 80 triangles scattered on the floor, one mesh instanced
    settings: dict = field(default_factory=dict)
    note: str = ""


CASES: dict[str, Case] = {
    "vpls-4096-ism": Case(settings={"vpl_count": 4096, "bounces": 1},
                          note="4096 light paths, 1 bounce, imperfect shadow maps"),
    "vpls-4096-bounces4": Case(settings={"vpl_count": 4096, "bounces": 4},
                               note="4096 light paths, 4 bounces (up to 16k VPLs)"),
    "vpls-4096-classic": Case(128, 128, settings={"vpl_count": 4096, "bounces": 1,
                                                  "visibility": "classic"},
                              note="4096 triangle cube shadow maps of 256²"),
    "vpls-65536": Case(64, 64, settings={"vpl_count": 65536, "bounces": 1},
                       note="the largest vpl_count setting"),
    "vpls-65537": Case(64, 64, settings={"vpl_count": 65537, "bounces": 1},
                       note="one above the vpl_count range"),
    "4k-aa1": Case(3840, 2160, settings={"antialiasing": 1}, note="3840×2160, 1 sample/pixel"),
    "4k-aa2": Case(3840, 2160, settings={"antialiasing": 2}, note="3840×2160, 4 samples/pixel"),
    "4k-aa4": Case(3840, 2160, settings={"antialiasing": 4},
                   note="3840×2160, 16 samples/pixel (just under the frame limit)"),
    "4k-aa4-direct": Case(3840, 2160, settings={"antialiasing": 4, "bounces": 0},
                          note="3840×2160, 16 samples/pixel, direct light only"),
    "4k-aa8": Case(3840, 2160, settings={"antialiasing": 8},
                   note="3840×2160, 64 samples/pixel (over the frame limit)"),
    "tris-1M": Case(triangles=1_000_000, settings={"bounces": 2}),
    "tris-2M": Case(triangles=2_000_000, settings={"bounces": 2}),
    "tris-4M": Case(triangles=4_000_000, settings={"bounces": 2}),
    "tris-4M-direct": Case(triangles=4_000_000, settings={"bounces": 0,
                                                          "direct_shadows": "shadow_maps"},
                           note="direct light with shadow maps only: no ray-tracing BVH"),
    "inst-10k": Case(instances=10_000, settings={"bounces": 2},
                     note="10k instances of an 80-triangle ball"),
    "inst-100k": Case(instances=100_000, settings={"bounces": 2},
                      note="100k instances of an 80-triangle ball"),
    "inst-1M": Case(instances=1_000_000, settings={"bounces": 2},
                    note="1M instances of an 80-triangle ball (a geometry-nodes scatter)"),
    "inst-1M-direct": Case(instances=1_000_000, settings={"bounces": 0},
                           note="1M instances, direct light only"),
    "inst-100k-maps": Case(instances=100_000, settings={"bounces": 0,
                                                        "direct_shadows": "shadow_maps"},
                           note="100k instances, direct light with shadow maps: no ray tracer"),
    "inst-1M-maps": Case(instances=1_000_000, settings={"bounces": 0,
                                                        "direct_shadows": "shadow_maps"},
                         note="1M instances, direct light with shadow maps: no ray tracer"),
}


def build_scene(case: Case):
    """A closed 10 × 10 × 5 m room (every light path hits something, so N paths leave N VPLs
    at the first bounce) whose floor is tessellated into ``case.triangles`` triangles and
    carries ``case.instances`` balls (one mesh, seeded random places), with a red wall and a
    point light, seen from under the ceiling by an orthographic camera."""
    import numpy as np

    from addon.core.scene.model import Camera, Instance, Light, LightKind, Material, Mesh, Scene
    from tests.core.builders import grid, icosphere

    def placed(mesh: Mesh, x: list[float], y: list[float], origin: list[float],
               colour: tuple[float, float, float] = (0.8, 0.8, 0.8)) -> Instance:
        """The unit square with its x and y axes mapped to the given vectors, centred at origin."""
        matrix = np.eye(4)
        matrix[:3, 0], matrix[:3, 1], matrix[:3, 3] = x, y, origin
        matrix[:3, 2] = np.cross(x, y) / np.linalg.norm(np.cross(x, y))
        return Instance(mesh, matrix, [Material("m", colour)])

    cells = max(1, round((max(case.triangles, 2) / 2) ** 0.5))
    quad = grid(1)
    room = [placed(grid(cells), [10, 0, 0], [0, 10, 0], [0, 0, 0]),  # the floor
            placed(quad, [10, 0, 0], [0, 10, 0], [0, 0, 5]),  # the ceiling
            placed(quad, [0, 0, 5], [0, 10, 0], [5, 0, 2.5]),
            placed(quad, [0, 0, 5], [0, 10, 0], [-5, 0, 2.5]),
            placed(quad, [10, 0, 0], [0, 0, 5], [0, -5, 2.5]),
            placed(quad, [10, 0, 0], [0, 0, 5], [0, 5, 2.5], (0.8, 0.1, 0.1))]
    ball = icosphere(0.02, 1)
    places = np.random.default_rng(7).uniform(-4.9, 4.9, (case.instances, 2))
    for x, y in places:
        matrix = np.eye(4)
        matrix[:3, 3] = x, y, 0.02
        room.append(Instance(ball, matrix, room[0].materials))
    lamp_matrix = np.eye(4)
    lamp_matrix[:3, 3] = (0, 1.5, 2.5)
    lamp = Light("lamp", LightKind.POINT, lamp_matrix, power=300.0)
    extent_x, extent_y = 6.0, 6.0 * case.height / case.width
    near, far = 0.01, 100.0
    projection = np.array([[2 / extent_x, 0, 0, 0], [0, 2 / extent_y, 0, 0],
                           [0, 0, -2 / (far - near), -(far + near) / (far - near)],
                           [0, 0, 0, 1.0]])
    view = np.eye(4)
    view[2, 3] = -4.9  # the camera at z = 4.9, under the ceiling, looking down
    camera = Camera(view, projection, case.width, case.height, is_orthographic=True)
    return Scene(room, [lamp], camera=camera), \
        cells * cells * 2 + 10 + case.instances * ball.triangle_count


def run_case(name: str) -> dict:
    """Render one case in this process; the result as a dict (printed as JSON by --child)."""
    import numpy as np

    from addon.core.frame.renderer import Renderer, RenderError
    from addon.core.settings import Settings, SettingsError

    case = CASES[name]
    start = time.perf_counter()
    scene, triangles = build_scene(case)
    built = time.perf_counter() - start
    try:
        settings = Settings(**case.settings)
        renderer = Renderer()
        frame, stats = renderer.render(scene, settings)
    except (RenderError, SettingsError) as exc:
        return {"outcome": "refused", "message": f"{type(exc).__name__}: {exc}",
                "seconds": time.perf_counter() - start, "scene_seconds": built,
                "triangles": triangles}
    finite = all(bool(np.isfinite(image).all()) for image in frame.passes.values())
    return {"outcome": "rendered" if finite else "rendered NON-FINITE",
            "seconds": time.perf_counter() - start, "scene_seconds": built,
            "triangles": triangles, "vpls": stats.counts.get("vpls", 0),
            "mean": float(frame.passes["Combined"][..., :3].mean()),
            "warnings": stats.warnings,
            "slowest": sorted(stats.timings.items(), key=lambda kv: -kv[1])[:3]}


def measure(name: str, timeout: float, guard_bytes: int) -> dict:
    """Run a case in a child process; add its peak RSS and how it ended."""
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        child = subprocess.Popen([sys.executable, __file__, "--child", name], cwd=ROOT,
                                 stdout=out, stderr=err, text=True,
                                 env={**os.environ, "PYTHONPATH": str(ROOT)})
        start, stopped, page = time.perf_counter(), "", os.sysconf("SC_PAGE_SIZE")
        while True:
            pid, status, usage = os.wait4(child.pid, os.WNOHANG)
            if pid:
                break
            try:
                rss = int(Path(f"/proc/{child.pid}/statm").read_text().split()[1]) * page
            except (OSError, IndexError):
                rss = 0
            if rss > guard_bytes:
                stopped = f"killed by the bench's memory guard ({guard_bytes / (1 << 30):g} GiB)"
            elif time.perf_counter() - start > timeout:
                stopped = f"timed out after {timeout:.0f} s"
            if stopped:
                child.kill()
                _, status, usage = os.wait4(child.pid, 0)
                break
            time.sleep(0.1)
        child.returncode = os.waitstatus_to_exitcode(status)  # reaped here, not by Popen
        seconds = time.perf_counter() - start
        out.seek(0)
        err.seek(0)
        stdout, stderr = out.read(), err.read()
    result: dict = {}
    for line in stdout.splitlines():
        if line.startswith("{"):
            result = json.loads(line)
    if not result:
        last = (stderr.strip().splitlines() or [""])[-1]
        result = {"outcome": stopped or f"CRASHED (exit {child.returncode})", "message": last,
                  "seconds": seconds}
    result["peak_rss_mib"] = usage.ru_maxrss / 1024  # kilobytes on Linux
    return result


def table(rows: list[tuple[str, dict]]) -> str:
    lines = ["| case | outcome | time (s) | peak RSS (MiB) | details |", "|---|---|---|---|---|"]
    for name, r in rows:
        details = r.get("message") or "; ".join(
            [CASES[name].note] * bool(CASES[name].note)
            + [f"{r['triangles']:,} triangles"] * bool(r.get("triangles"))
            + [f"{r['vpls']:,} VPLs"] * bool(r.get("vpls"))
            + [f"slowest: {', '.join(f'{k} {v:.1f} s' for k, v in r['slowest'])}"]
            * bool(r.get("slowest")))
        lines.append(f"| {name} | {r['outcome']} | {r['seconds']:.1f} | "
                     f"{r['peak_rss_mib']:,.0f} | {details} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="*", help=f"cases to run (default all): {', '.join(CASES)}")
    parser.add_argument("--timeout", type=float, default=600.0, help="seconds per case")
    parser.add_argument("--memory-guard", type=float, default=12.0,
                        help="kill a case whose resident memory passes this many GiB")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        print(json.dumps(run_case(args.child)), flush=True)
        return 0
    names = args.cases or list(CASES)
    unknown = [n for n in names if n not in CASES]
    if unknown:
        parser.error(f"unknown case(s): {', '.join(unknown)}")
    rows = []
    for name in names:
        result = measure(name, args.timeout, int(args.memory_guard * (1 << 30)))
        rows.append((name, result))
        print(f"{name}: {result['outcome']}, {result['seconds']:.1f} s, "
              f"peak RSS {result['peak_rss_mib']:,.0f} MiB", flush=True)
    print()
    print(table(rows))
    return 0


if __name__ == "__main__":
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))  # a crash leaves no core file behind
    sys.exit(main())
