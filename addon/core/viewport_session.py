"""The interactive viewport's frame logic, free of Blender so it runs (and is tested) headless.

A ``ViewportSession`` owns a worker thread with its own OpenGL context and Renderer. The
Blender side hands it edits (a new scene export, a new view camera, new settings or display
mode) and draws the latest finished frame; it never waits for the GPU. Per edit the worker
renders a few levels of increasing resolution (a quick first frame, then refinement), then,
while nothing changes, further passes at full resolution with their own VPLs (``viewport_passes``
in all, as Cycles' viewport samples), showing their running average, and then sleeps until the
next edit. An edit arriving mid-frame cancels that frame and starts the average over.

What an edit costs follows from the Renderer's reuse between frames: geometry that did not
change keeps its ray-tracing upload, VPLs are regenerated only when lights, world, geometry or
their settings changed (and then incrementally, reusing the VPLs the lights still reach), and
the imperfect shadow maps only when the VPLs or the geometry changed. A camera-only edit
therefore runs the g-buffer and shading alone. An edit that redraws every shadow map (lights
moved, or geometry, world or settings changed) renders its quick first frame with a quarter of
the lights' samples, and one that must make every VPL afresh also with fewer world and emission
samples, light paths and ISM points, in smaller ISMs.
``records`` keeps, per edit, its kind, the latency to its first frame and which stages ran or
were skipped.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace

import numpy as np

from .frame.progressive import Accumulator, ray_traced_from, traces
from .frame.renderer import RenderCancelled, Renderer, RenderError
from .frame.result import Frame, Stats
from .frame.scene_size import flattened_triangles
from .gpu.gl import GLUnavailableError, create_context
from .scene.model import RENDERED_OBJECT_TYPES, Camera, Scene
from .settings import Choice, Settings, SettingsError

DISPLAY_MODES = (
    Choice("combined", "Combined", "The full image"),
    Choice("direct", "Direct Light", "Direct light and emission only"),
    Choice("indirect", "Indirect Light", "Only the light the VPLs bring"),
    Choice("vpls", "VPL Positions", "The image with each VPL as a dot coloured by its bounce "
                                    "(yellow first, then orange, pink, blue)"),
    Choice("ism", "ISM Atlas", "The imperfect shadow maps, near as white"))
"""What the Rendered viewport can show (final renders are unaffected)."""
DISPLAY_PASSES = {"direct": frozenset({"DiffDir", "DiffCol", "Emit"}),
                  "indirect": frozenset({"DiffInd", "DiffCol"})}
"""Passes a display mode reads besides Combined."""
QUICK_ISM_RESOLUTION = 64  # a quick first frame's imperfect shadow maps, at most (texels a side)
QUICK_MIN_SAMPLES = 4  # a quick first frame's least count of each kind of direct-light sample
MAX_LEVEL_DIVISOR = 8  # the coarsest level's resolution divisor, at most
START_PIXELS = 64 * 64
"""The first level is the coarsest at most this many pixels, as Cycles' viewport starts (its
Start Resolution, 64): 80×45 of a 640×360 view; then the resolution doubles per level."""
GENERATION_COLOURS = np.array([[1.0, 0.9, 0.2], [1.0, 0.4, 0.1], [0.9, 0.1, 0.5],
                               [0.4, 0.2, 1.0], [0.1, 0.7, 1.0]], np.float32)
GEOMETRY_OBJECTS = RENDERED_OBJECT_TYPES | {"CURVES", "POINTCLOUD", "VOLUME"}
"""Object types whose edits can change what is rendered (some not rendered yet)."""
GEOMETRY_DATA = {"MESH", "CURVE", "METABALL", "CURVES", "POINTCLOUD", "VOLUME", "TEXT"}
AVERAGED_DISPLAYS = ("combined", "direct", "indirect")
"""Display modes that idle passes refine (VPL dots and the ISM atlas are one pass's)."""


@dataclass(frozen=True)
class Update:
    """One entry of Blender's ``depsgraph.updates``, reduced to what decides the work."""

    id_type: str  # Blender's ID type: OBJECT, MESH, LIGHT, MATERIAL, WORLD, SCENE, ...
    name: str
    object_type: str = ""  # for objects: MESH, LIGHT, CAMERA, ...
    geometry: bool = False
    transform: bool = False
    shading: bool = False


@dataclass
class Changes:
    """What an edit changed, as far as the renderer is concerned."""

    camera: bool = False
    lights: bool = False
    geometry: set[str] = field(default_factory=set)  # objects/meshes whose geometry to re-read
    transforms: bool = False
    materials: bool = False
    world: bool = False
    settings: bool = False
    display: bool = False

    @property
    def needs_export(self) -> bool:
        """Whether the scene must be exported again (anything beyond camera and display)."""
        return bool(self.lights or self.geometry or self.transforms or self.materials
                    or self.world or self.settings)

    @property
    def regenerates(self) -> bool:
        """Whether VPLs must be made from scratch (nothing to reuse incrementally): geometry
        moved or changed, the world or the settings changed."""
        return bool(self.geometry or self.transforms or self.world or self.settings)

    def describe(self) -> str:
        parts = [name for name in ("camera", "lights", "transforms", "materials", "world",
                                   "settings", "display") if getattr(self, name)]
        if self.geometry:
            parts.append("geometry")
        return "+".join(parts) or "nothing"


def classify(updates: Iterable[Update]) -> Changes:
    """Sort depsgraph updates into the kinds of change the renderer reacts to."""
    changes = Changes()
    for u in updates:
        if u.id_type == "OBJECT":
            if u.object_type == "LIGHT":
                changes.lights = True
            elif u.object_type == "CAMERA":
                changes.camera = True
            elif u.object_type in GEOMETRY_OBJECTS or u.object_type == "EMPTY":
                if u.geometry:
                    changes.geometry.add(u.name)
                if u.transform:
                    changes.transforms = True
                if u.shading:
                    changes.materials = True
                if not (u.geometry or u.transform or u.shading):  # visibility, parenting, ...
                    changes.transforms = True
        elif u.id_type == "LIGHT":
            changes.lights = True
        elif u.id_type == "CAMERA":
            changes.camera = True
        elif u.id_type in GEOMETRY_DATA:
            if u.geometry:
                changes.geometry.add(u.name)
            elif u.shading:  # a material assigned or changed
                changes.materials = True
        elif u.id_type in ("MATERIAL", "NODETREE", "IMAGE", "TEXTURE"):
            changes.materials = True
        elif u.id_type == "WORLD":
            changes.world = True
        elif u.id_type == "COLLECTION":
            changes.transforms = True
        elif u.id_type == "SCENE":
            changes.settings = True
    return changes


def view_camera(view_matrix: np.ndarray, window_matrix: np.ndarray, width: int, height: int,
                is_perspective: bool) -> Camera:
    """The camera of a 3D viewport region (its view and projection matrices and size)."""
    return Camera(np.asarray(view_matrix, np.float64), np.asarray(window_matrix, np.float64),
                  max(1, int(width)), max(1, int(height)), is_orthographic=not is_perspective)


def quick_settings(settings: Settings, changes: Changes) -> Settings:
    """The first frame's settings after an edit, so that it comes quickly: a quarter of the
    samples of area, sphere and angled sun lights (at least QUICK_MIN_SAMPLES) where lights
    moved or every shadow map is redrawn; where the edit regenerates every VPL and shadow map,
    also a quarter of the emission and world samples, an eighth of the light paths (at least
    64), a quarter of the ISM points and maps of at most QUICK_ISM_RESOLUTION². (A light edit
    keeps the world's and emission's samples: their shadow maps are kept.)"""
    def quarter(samples: int) -> int:
        return min(samples, max(QUICK_MIN_SAMPLES, samples // 4))

    if changes.regenerates:
        settings = replace(settings, ism_points=max(16, settings.ism_points // 4),
                           ism_resolution=min(settings.ism_resolution, QUICK_ISM_RESOLUTION),
                           vpl_count=min(settings.vpl_count, max(64, settings.vpl_count // 8)),
                           emission_samples=quarter(settings.emission_samples),
                           world_samples=quarter(settings.world_samples))
    if changes.regenerates or changes.lights:
        settings = replace(settings, light_samples=quarter(settings.light_samples))
    return settings


def scaled_camera(camera: Camera, divisor: int) -> Camera:
    """The same view at 1/divisor of the resolution (at least one pixel)."""
    return replace(camera, width=max(1, camera.width // divisor),
                   height=max(1, camera.height // divisor))


def refinement_levels(camera: Camera) -> list[int]:
    """Resolution divisors of the levels of one edit, coarse to fine (always ending at 1)."""
    divisor = 1
    while divisor < MAX_LEVEL_DIVISOR and \
            (camera.width // divisor) * (camera.height // divisor) > START_PIXELS:
        divisor *= 2
    return [divisor >> k for k in range(divisor.bit_length())]


def display_image(frame: Frame, mode: str, camera: Camera, vpls=None,
                  ism_atlas: np.ndarray | None = None) -> np.ndarray:
    """The (h, w, 4) scene-linear RGBA image a display mode shows: the combined pass, direct or
    indirect light alone, VPL positions (coloured by bounce) over the combined pass, or the
    ISM atlas (depth as grey, nearest texels)."""
    p = frame.passes
    alpha = p["Combined"][..., 3:4]
    if mode == "direct":
        return np.concatenate([p["DiffDir"] * p["DiffCol"] + p["Emit"], alpha], axis=-1)
    if mode == "indirect":
        return np.concatenate([p["DiffInd"] * p["DiffCol"], alpha], axis=-1)
    if mode == "ism" and ism_atlas is not None and ism_atlas.size:
        return _atlas_image(ism_atlas, frame.width, frame.height)
    image = p["Combined"].copy()
    if mode == "vpls" and vpls is not None and len(vpls):
        _draw_points(image, camera, vpls.position, GENERATION_COLOURS[
            np.minimum(vpls.generation - 1, len(GENERATION_COLOURS) - 1)])
    return image


def _draw_points(image: np.ndarray, camera: Camera, points: np.ndarray,
                 colours: np.ndarray) -> None:
    """Paint 3×3-pixel dots at the projections of world points in front of the camera."""
    h, w = image.shape[:2]
    clip = np.hstack([points, np.ones((len(points), 1))]) @ (
        camera.projection_matrix @ camera.view_matrix).T
    front = clip[:, 3] > 1e-9
    ndc = clip[front, :2] / clip[front, 3:4]
    x = np.floor((ndc[:, 0] * 0.5 + 0.5) * w).astype(int)
    y = np.floor((ndc[:, 1] * 0.5 + 0.5) * h).astype(int)
    colours = colours[front]
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            xs, ys = x + dx, y + dy
            inside = (xs >= 0) & (xs < w) & (ys >= 0) & (ys < h)
            image[ys[inside], xs[inside], :3] = colours[inside]
            image[ys[inside], xs[inside], 3] = 1.0


def _atlas_image(atlas: np.ndarray, width: int, height: int) -> np.ndarray:
    """The atlas scaled (nearest) into a width × height image, near = white, far = black."""
    finite = atlas[np.isfinite(atlas) & (atlas < 1e30)]
    scale = float(finite.max()) if finite.size else 1.0
    grey = np.where(atlas < 1e30, 1.0 - np.clip(atlas / max(scale, 1e-30), 0, 1), 0.0)
    rows = (np.arange(height) * atlas.shape[0] // max(1, height)).clip(0, atlas.shape[0] - 1)
    cols = (np.arange(width) * atlas.shape[1] // max(1, width)).clip(0, atlas.shape[1] - 1)
    picked = grey[rows][:, cols].astype(np.float32)
    return np.dstack([picked, picked, picked, np.ones_like(picked)])


@dataclass
class ViewportFrame:
    """A finished frame for display: scene-linear RGBA at the level's resolution."""

    image: np.ndarray
    number: int  # increases with every published frame
    edit: int  # the edit it shows
    level: int  # 0 = the quick first frame
    levels: int
    stats: Stats
    passes: int = 1  # passes averaged (more than one: idle refinement at full resolution)


@dataclass
class EditRecord:
    """What one edit triggered: its kind, the seconds to its first frame and to its last
    refinement level (idle passes not counted), the stages that ran (with seconds) or were
    skipped in the first frame, with its counts, and the passes its last frame averaged."""

    edit: int
    kind: str
    latency: float | None = None
    converged: float | None = None
    ran: dict[str, float] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    passes: int = 0  # full-resolution passes averaged in its last frame


class ViewportSession:
    """Renders the viewport in a worker thread with its own OpenGL context; see the module
    docstring. ``on_frame`` is called from the worker after each published frame (it must only
    set flags: Blender's API is not thread-safe)."""

    def __init__(self, on_frame: Callable[[], None] | None = None,
                 renderer_factory: Callable[[], Renderer] | None = None) -> None:
        self._on_frame = on_frame or (lambda: None)
        self._factory = renderer_factory or (lambda: Renderer(create_context()))
        self._cond = threading.Condition()
        self._scene: Scene | None = None
        self._camera: Camera | None = None
        self._settings = Settings()
        self._display = "combined"
        self._changes = Changes()
        self._edit = 0
        self._finished_edit = 0
        self._closed = False
        self._latest: ViewportFrame | None = None
        self._frames = 0
        self._started: dict[int, float] = {}
        self.records: list[EditRecord] = []
        self.status = "VPL GI | Starting"
        self.error: str | None = None
        self._thread = threading.Thread(target=self._run, name="VPL GI viewport", daemon=True)
        self._thread.start()

    # -- the Blender side -----------------------------------------------------------------
    def edit(self, changes: Changes, scene: Scene | None = None, camera: Camera | None = None,
             settings: Settings | None = None, display: str | None = None) -> None:
        """Hand over what changed; the worker starts over with it."""
        modes = tuple(mode.value for mode in DISPLAY_MODES)
        if display is not None and display not in modes:
            raise ValueError(f"display mode {display!r} is not one of {modes}")
        with self._cond:
            if scene is not None:
                self._scene = scene
            if camera is not None:
                self._camera = camera
            if settings is not None:
                self._settings = settings
            if display is not None:
                self._display = display
            self._changes = changes
            self._edit += 1
            self._started[self._edit] = time.perf_counter()
            self.records.append(EditRecord(self._edit, changes.describe()))
            self._cond.notify_all()

    @property
    def camera(self) -> Camera | None:
        return self._camera

    def latest(self) -> ViewportFrame | None:
        """The newest finished frame (None before the first)."""
        with self._cond:
            return self._latest

    @property
    def idle(self) -> bool:
        """True when every edit has been rendered to its last level (no work, no CPU)."""
        with self._cond:
            return self._finished_edit == self._edit

    def wait_idle(self, timeout: float) -> bool:
        """Block until idle or ``timeout`` seconds; True when idle."""
        with self._cond:
            return self._cond.wait_for(lambda: self._finished_edit == self._edit
                                       or self._closed, timeout)

    def close(self, timeout: float = 30.0) -> None:
        """Stop the worker (cancelling its frame) and release its GPU resources."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout)

    @property
    def alive(self) -> bool:
        return self._thread.is_alive()

    # -- the worker -----------------------------------------------------------------------
    def _run(self) -> None:
        try:
            renderer = self._factory()
        except (GLUnavailableError, RuntimeError) as exc:
            self.error = str(exc)
            self.status = f"VPL GI | Error: {exc}"
            with self._cond:
                self._closed = True
                self._cond.notify_all()
            return
        # Idle passes render with a second Renderer on the same context, so that what the
        # first keeps for the next edit (its VPLs, their shadow maps, the incremental
        # anchors) stays untouched by the passes' own VPL sets; it uses the first's compiled
        # programs.
        idle = Renderer(renderer.ctx, share_programs_of=renderer)
        try:
            while True:
                with self._cond:
                    self._cond.wait_for(lambda: self._closed or self._edit != self._finished_edit)
                    if self._closed:
                        return
                    edit, scene, camera = self._edit, self._scene, self._camera
                    settings, display, changes = self._settings, self._display, self._changes
                if scene is not None and camera is not None:
                    self._render_edit(renderer, idle, edit, scene, camera, settings, display,
                                      changes)
                with self._cond:
                    if self._edit == edit:
                        self._finished_edit = edit
                        self._cond.notify_all()
        finally:
            idle.release()
            renderer.release()
            renderer.ctx.release()

    def _superseded(self, edit: int) -> bool:
        return self._closed or self._edit != edit

    def _render_edit(self, renderer: Renderer, idle: Renderer, edit: int, scene: Scene,
                     camera: Camera, settings: Settings, display: str, changes: Changes) -> None:
        levels = refinement_levels(camera)
        if changes.display and not (changes.needs_export or changes.camera):
            levels = levels[-1:]
        # The automatic mode is for final renders: a choice per refinement level (each of its
        # own size) would make the VPLs afresh at every level.
        view_settings = replace(settings, antialiasing=1, incremental=True,
                                auto_parameters="off")
        quick = quick_settings(view_settings, changes) if len(levels) > 1 else view_settings
        record = self.records[edit - 1]
        full = Accumulator()
        for level, divisor in enumerate(levels):
            level_camera = scaled_camera(camera, divisor)
            self.status = f"VPL GI | Rendering {level + 1}/{len(levels)}"
            frame = self._frame(renderer, edit, replace(scene, camera=level_camera),
                                quick if level == 0 else view_settings, display)
            if frame is None:
                return
            last = level == len(levels) - 1
            if last:
                full.add(frame[0])
            if not self._publish(renderer, edit, record, frame, display, level_camera, level,
                                 len(levels), 1,
                                 "" if last else f"Refining {level + 2}/{len(levels)}"):
                return
        if display not in AVERAGED_DISPLAYS:
            return
        # Idle refinement: independent VPL sets (not incremental ones), averaged with the clamp
        # shrinking and the visibility ray traced from ray_traced_from_pass as in final renders.
        independent = replace(view_settings, incremental=False)
        traced = replace(independent, visibility="exact")
        switch = ray_traced_from(independent, flattened_triangles(scene))
        for index in range(1, settings.viewport_passes):
            frame = self._frame(idle, edit, replace(scene, camera=camera),
                                traced if traces(switch, index) else independent, display,
                                index)
            if frame is None:
                return
            full.add(frame[0])
            if not self._publish(idle, edit, record, (full.average(), frame[1]), display,
                                 camera, len(levels) - 1, len(levels), full.count, ""):
                return

    def _frame(self, renderer: Renderer, edit: int, scene: Scene, settings: Settings,
               display: str, pass_index: int = 0) -> tuple[Frame, Stats] | None:
        """One frame of ``edit`` (None when a newer edit cancelled it, or it failed: then
        the error is shown)."""
        if self._superseded(edit):
            return None
        try:
            result = renderer.render(scene, settings, cancelled=lambda: self._superseded(edit),
                                     passes=DISPLAY_PASSES.get(display, frozenset()),
                                     pass_index=pass_index)
        except RenderCancelled:
            return None
        except (RenderError, SettingsError, GLUnavailableError) as exc:
            self.error = str(exc)
            self.status = f"VPL GI | Error: {exc}"
            return None
        self.error = None
        return result

    def _publish(self, renderer: Renderer, edit: int, record: EditRecord,
                 result: tuple[Frame, Stats], display: str, camera: Camera, level: int,
                 levels: int, passes: int, refining: str) -> bool:
        """Make a frame the latest one (False when a newer edit came first)."""
        frame, stats = result
        vpls = renderer.last_vpls if display == "vpls" else None
        atlas = renderer.ism.read_atlas() if display == "ism" and renderer.has_ism else None
        image = display_image(frame, display, camera, vpls, atlas)
        with self._cond:
            if self._edit != edit:
                return False
            self._frames += 1
            self._latest = ViewportFrame(image, self._frames, edit, level, levels, stats,
                                         passes)
            elapsed = time.perf_counter() - self._started[edit]
            if level == 0 and passes == 1:
                record.latency = elapsed
                record.ran = dict(stats.timings)
                record.skipped = dict(stats.skipped)
                record.counts = dict(stats.counts)
            record.passes = passes
            if passes == 1:  # idle passes do not move the time to the last level
                record.converged = elapsed
        pass_note = f"Pass {passes} | " if passes > 1 else ""
        self.status = f"VPL GI | {refining}" if refining else \
            f"VPL GI | {pass_note}{stats.summary()}"
        for warning in stats.warnings:
            self.status += f" | {warning}"
        self._on_frame()
        return True
