"""The automatic mode's stage: parameters chosen from a cost model measured once on this
machine and an error model, for the frame's workload."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..gpu.gl import GLUnavailableError
from ..gpu.raytrace import RayTracer
from ..scene.geometry import WorldGeometry, bounding_sphere, flatten_instances
from ..scene.model import Scene
from ..settings import Settings
from ..transport.vpl import VPLs, generate_vpls
from . import autotune
from .gpu_session import GpuSession
from .planner import reaches_bounds
from .progressive import maps_undersample, ray_traced_from
from .ray_probe import ray_probe_seconds, visibility_probe_seconds
from .result import Frame, Stats
from .reuse import KeptProducts
from .stages import indirect_per_pixel, near_field_rays
from .state import FrameState, Stage
from .vpl_stage import may_guide, upload_triangles

PROBE_PATHS = 64  # light paths the automatic mode traces to learn how many VPLs a path leaves

RenderFunction = Callable[[Scene, Settings], tuple[Frame, Stats]]


class ChooseParameters(Stage):
    """Replace the frame's settings by the automatic mode's choice (when it is on and the
    frame has indirect light)."""

    name = "automatic parameters"
    needs = ("camera", "geometry", "centre", "plan", "light_samples")

    def __init__(self, gpu: GpuSession, kept: KeptProducts, render: RenderFunction) -> None:
        self.gpu, self.kept, self.render = gpu, kept, render
        self.cost_cache: Path | None = autotune.default_cost_cache()
        """Where the measured cost model is kept (None: measure each time)."""
        self.last: tuple[Settings, autotune.Workload, autotune.Choice] | None = None
        """The last frame's settings, workload and choice (for :meth:`rechoose`)."""
        self.later: tuple[Settings, autotune.Workload] | None = None
        """The settings and workload of the later passes :meth:`rechoose` chose for."""
        self.split = 1
        """Passes the time mode would share the next frame's time_budget among (budget.py;
        the choice's ``passes`` says whether it did, see autotune.choose)."""
        self._cost: tuple[tuple, autotune.CostModel] | None = None
        self._error: tuple[tuple, autotune.ErrorModel] | None = None

    def cost_model(self, stats: Stats, report: Callable[[float, str], None]
                   ) -> autotune.CostModel:
        """This machine's cost model: cached, or measured now (once) and cached. The file is
        read again only when it changed (its path, size or modification time)."""
        name = str(self.gpu.ctx.info["GL_RENDERER"])
        key = (name, _file_stamp(self.cost_cache))
        if self._cost is not None and key[1] is not None and self._cost[0] == key:
            return self._cost[1]

        def measure() -> autotune.CostModel:
            report(0.0, "Measuring this machine's cost model (once)")
            with stats.timed("cost model calibration"):
                model = autotune.calibrate(self._calibration_frame, name,
                                           Settings(light_samples=4))
            self.kept.forget(anchors=False)
            return model

        model = autotune.cached_cost_model(self.cost_cache, name, measure)
        self._cost = ((name, _file_stamp(self.cost_cache)), model)  # the file may be new
        return model

    def _measured_cost(self) -> autotune.CostModel:
        """The cost model, measured already (by the frame whose choice is made again)."""
        return self.cost_model(Stats(), lambda _f, _m: None)

    def error_model(self) -> autotune.ErrorModel:
        """The error model (autotune.ERROR_MODEL_FILE), read again only when it changed."""
        key = _file_stamp(autotune.ERROR_MODEL_FILE)
        if self._error is None or self._error[0] != key:
            self._error = (key, autotune.load_error_model())
        return self._error[1]

    def rechoose(self, fixed: float, chosen: float, budget: float, traced_share: float = 0.0
                 ) -> autotune.Choice | None:
        """The last frame's choice made again for ``budget`` seconds a pass, from its measured
        seconds: ``fixed`` of the work it does not choose, ``chosen`` of the work it does (None:
        no frame chose yet); ``traced_share`` of the passes trace their VPLs' visibility."""
        self.later = None
        if self.last is None:
            return None
        settings, work, last = self.last
        cost = self._measured_cost()
        modelled = autotune.chosen_seconds(cost, work,
                                           *autotune.chosen_parameters(last.settings))
        scale = min(max(chosen / modelled, 0.25), 8.0) if modelled > 0 and chosen > 0 else 1.0
        work = replace(work, fixed=fixed, scale=scale, spent=0.0,
                       area_table=self._ism_area_table(work.triangles), ray_traced_from=None,
                       traced_share=traced_share, pass_paths=autotune.MIN_PASS_PATHS)
        self.later = (settings, work)
        return self._filled(settings, work, cost, budget)

    def rescale_traced(self, wall: float, traced: Settings) -> None:
        """Scale the later passes' visibility cost so that the model predicts a traced pass of
        ``traced`` settings at ``wall`` seconds, its measured time (the visibility probe
        traces every pair, the gather only facing ones: Sponza's traced passes took 8.0 s
        where 12.6 s was predicted). Nothing where :meth:`rechoose` has not measured the later
        passes."""
        if self.later is None:
            return
        cost = self._measured_cost()
        settings, work = self.later
        s = autotune.chosen_parameters(traced)
        untraced = autotune.predict_seconds(cost, replace(work, visibility_cost=0.0), *s,
                                            traced=True)
        modelled = autotune.predict_seconds(cost, work, *s, traced=True)
        if modelled > untraced:
            scale = min(max((wall - untraced) / (modelled - untraced), 0.25), 4.0)
            self.later = (settings, replace(work, visibility_cost=work.visibility_cost * scale))

    def rechoose_traced(self, budget: float) -> autotune.Choice | None:
        """The traced passes' choice made again for ``budget`` seconds a pass (after
        :meth:`rescale_traced`); None where :meth:`rechoose` has not measured the later
        passes."""
        if self.later is None:
            return None
        settings, work = self.later
        return self._filled(settings, replace(work, traced_share=1.0), self._measured_cost(),
                            budget)

    def _filled(self, settings: Settings, work: autotune.Workload, cost: autotune.CostModel,
                budget: float) -> autotune.Choice:
        """The choice of least predicted error for ``budget`` seconds a pass, its light paths
        raised to fill them (autotune.fill)."""
        errors = self.error_model()
        choice = autotune.choose(replace(settings, time_budget=budget), work, cost, errors)
        return autotune.fill(choice, work, cost, errors, budget)

    def run(self, frame: FrameState) -> None:
        self.last = None
        if frame.settings.auto_parameters == "off" or not frame.plan.indirect:
            return
        settings, stats = frame.settings, frame.stats
        cost = self.cost_model(stats, frame.report)
        camera = frame.camera
        with stats.timed("automatic parameters"):
            try:
                tracer = upload_triangles(self.gpu, self.kept, frame.geometry, frame.stats)
            except GLUnavailableError:
                tracer = None
            rays = near_field_rays(settings)
            triangles = frame.geometry.vertex_count // 3
            switch = ray_traced_from(settings, triangles) if self.split > 1 else None
            per_path, probe_vpls = self._vpls_per_path(frame, tracer)
            work = autotune.Workload(
                pixels=camera.width * camera.height * settings.antialiasing**2,
                triangles=triangles,
                shadow_tiles=int(frame.light_samples.tiles_per_sample.sum()),
                **per_path,
                bounces=settings.bounces,
                gather_antialiasing=self._gather_antialiasing(settings,
                                                              frame.geometry.has_specular),
                area_table=self._ism_area_table(triangles),
                compensation_rays=rays,
                ray_cost=_against(cost.probe, tracer, lambda t: ray_probe_seconds(
                    camera, frame.geometry, t, frame.radius,
                    settings.clamp_distance * frame.radius)) if rays else 1.0,
                ray_traced_from=switch,
                undersampled=maps_undersample(settings, triangles))
            if autotune.may_trace(settings, work, cost, self.error_model(), self.split):
                work = replace(work, visibility_cost=_against(
                    cost.visibility_probe, tracer, lambda t: visibility_probe_seconds(
                        camera, frame.geometry, t, frame.radius, probe_vpls)))
            elif switch is not None:
                stats.skipped["visibility probe"] = (
                    f"no plan of passes that trace from pass {switch + 1} fits "
                    f"{settings.time_budget:g} s")
        work = replace(work, spent=time.perf_counter() - frame.started)
        choice = autotune.choose(settings, work, cost, self.error_model(), self.split)
        self.last = (settings, work, choice)
        priced = (f"; bias compensation rays at {work.ray_cost:.1f}× the calibration room's "
                  "cost" if work.compensation_rays else "")
        stats.notes.append(f"automatic parameters ({settings.auto_parameters}): "
                           f"{choice.describe()}{priced}")
        stats.counts.update(auto_vpl_count=choice.settings.vpl_count)
        frame.settings = choice.settings

    @staticmethod
    def _gather_antialiasing(settings: Settings, specular: bool) -> int:
        """Supersamples per pixel edge the VPLs are gathered once for (indirect light per
        pixel: the antialiasing), else 1."""
        return settings.antialiasing if indirect_per_pixel(settings, specular) else 1

    def _ism_area_table(self, triangles: int) -> bool:
        """Whether the ISM area table of these triangles is built already."""
        return getattr(self.gpu.ism_if_made, "prepared_triangles", None) == triangles

    def _vpls_per_path(self, frame: FrameState, tracer: RayTracer | None
                       ) -> tuple[dict[str, float | None], np.ndarray]:
        """The workload's VPLs that can light the view per light path, from a probe of
        PROBE_PATHS paths, and with camera guidance the VPLs gathered per path: all of the
        probe's (guidance keeps as many as the paths leave, chosen where the camera looks);
        and the positions of the probe's VPLs that can light the view."""
        settings = frame.settings
        if tracer is None:
            return {"vpls_per_path": float(settings.bounces)}, np.zeros((0, 3))
        vpls = _probe_vpls(frame.scene, frame.geometry, settings, tracer, frame.centre,
                           frame.radius)
        samples = vpls.as_light_samples(settings.vpl_shadow_resolution)
        in_view = reaches_bounds(samples, frame.in_view) if frame.in_view is not None \
            else np.ones(len(vpls), bool)
        guided = len(vpls) / PROBE_PATHS if may_guide(settings) else None
        return ({"vpls_per_path": max(int(in_view.sum()), 1) / PROBE_PATHS,
                 "gathered_per_path": guided}, vpls.position[in_view])

    def _calibration_frame(self, settings: Settings) -> dict[str, float | int]:
        """Stage timings and counts of one frame of the calibration scene."""
        self.kept.forget(anchors=False)
        scene = autotune.calibration_scene()
        _, stats = self.render(scene, settings)
        camera = scene.camera
        geometry = flatten_instances(scene, [])
        centre, radius = bounding_sphere(geometry.positions)
        tracer = upload_triangles(self.gpu, self.kept, geometry, stats)  # kept by the render
        probe = ray_probe_seconds(camera, geometry, tracer, radius,
                                  settings.clamp_distance * radius)
        vpls = _probe_vpls(scene, geometry, settings, tracer, centre, radius)
        visibility = visibility_probe_seconds(camera, geometry, tracer, radius, vpls.position)
        return {**stats.timings, "vpls": stats.counts["vpls"], "ray probe": probe,
                "visibility probe": visibility,
                "pixels": camera.width * camera.height * settings.antialiasing**2,
                "triangles": stats.counts["triangles"],
                "shadow_tiles": stats.counts["shadow_maps"],  # the room has no glossy material:
                "gather_antialiasing": self._gather_antialiasing(settings, False)}


def _probe_vpls(scene: Scene, geometry: WorldGeometry, settings: Settings, tracer: RayTracer,
                centre: np.ndarray, radius: float) -> VPLs:
    """The VPLs of PROBE_PATHS light paths (not incremental): the automatic mode's probe."""
    return generate_vpls(scene, geometry, replace(settings, vpl_count=PROBE_PATHS,
                                                  incremental=False), tracer, centre, radius)


def _against(reference: float, tracer: RayTracer | None,
             probe: Callable[[RayTracer], float]) -> float:
    """A probe's seconds in this frame against the calibration room's ``reference`` (1 where
    either is unmeasured: the probe runs only where there is a tracer and a reference)."""
    if tracer is None or reference <= 0.0:
        return 1.0
    seconds = probe(tracer)
    return seconds / reference if seconds > 0.0 else 1.0


def _file_stamp(path: Path | None) -> tuple[str, int, int] | None:
    """A file's path, size and modification time (ns), or None when there is no such file."""
    if path is None:
        return None
    try:
        stat = path.stat()
    except OSError:
        return None
    return str(path), stat.st_size, stat.st_mtime_ns
