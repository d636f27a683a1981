"""What the stages of one frame hand each other, the stage interface, and a render's errors."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from ..scene.geometry import WorldGeometry
from ..scene.model import Camera, Scene
from ..settings import Settings
from ..transport.lights import LightSamples
from ..transport.vpl import PathSequence, VPLs
from .planner import Bounds, FramePlan
from .result import Stats

if TYPE_CHECKING:
    from .gather import Compensation, LightPass
    from .id_passes import IdTables
    from .ism_maps import ImperfectShadowMapFrame
    from .motion import InstanceMotion
    from .near_field import NearField


class RenderError(RuntimeError):
    """The scene cannot be rendered; the message says why, for the user."""


class RenderCancelled(RuntimeError):
    """The user asked the render to stop."""


ProgressCallback = Callable[[float, str], None]
CancelCallback = Callable[[], bool]


def labelled(progress: ProgressCallback, label: str) -> ProgressCallback:
    """``progress`` with each message put after ``label`` (a part of the render: a light
    group, the shadow catchers alone, a stereo view)."""
    def report(fraction: float, message: str) -> None:
        progress(fraction, label + (f" | {message}" if message else ""))
    return report


@dataclass
class FrameState:
    """One frame's input and every product a stage makes for the stages after it."""

    scene: Scene
    settings: Settings
    passes: frozenset[str] | None
    stats: Stats
    report: ProgressCallback
    cancelled: CancelCallback
    pass_index: int = 0  # the pass of a progressive render (see progressive.py)
    user_seed: int = 0  # the settings' seed before the pass's own: ISM points and the light
    # paths' sequence (path_sequence) stay the same in every pass
    first_path: int = 0  # the pass's first light path in the user's seed's sequence: the
    # passes of a render continue one sequence (transport/vpl.py PathSequence)
    camera: Camera | None = None
    geometry: WorldGeometry | None = None
    shapes: WorldGeometry | None = None  # light outlines seen by the camera
    centre: np.ndarray | None = None  # bounding sphere of the geometry
    radius: float = 0.0
    box: Bounds | None = None  # bounding box of the geometry (None without triangles)
    plan: FramePlan | None = None
    in_view: Bounds | None = None
    light_samples: LightSamples | None = None
    vpls: VPLs | None = None
    vpl_keys: np.ndarray | None = None  # identities of the VPLs kept in vpl_samples
    vpl_samples: LightSamples | None = None
    light_passes: list[LightPass] = field(default_factory=list)
    compensation: Compensation | None = None  # bias compensation by gathering VPLs again
    near_field: NearField | None = None  # bias compensation from the image
    ism_maps: ImperfectShadowMapFrame | None = None
    blur_radius: int = 0
    output: dict[str, np.ndarray] | None = None
    id_tables: IdTables | None = None  # the ID passes' lookups (id_passes.py)
    instance_motion: InstanceMotion | None = None  # the Vector pass's (motion.py)
    traces_rays: bool = False  # a light pass or the bias compensation uses the ray tracer
    steps: int = 0  # light passes × tiles, for the progress bar
    steps_done: int = 0
    started: float = field(default_factory=time.perf_counter)  # when the frame began

    @property
    def path_sequence(self) -> PathSequence:
        """The light paths this pass traces (``first_path`` on, the user's seed's sequence)."""
        return PathSequence(self.user_seed, self.first_path)

    def check_cancelled(self) -> None:
        """Raise RenderCancelled if the user asked to stop."""
        if self.cancelled():
            raise RenderCancelled("render cancelled")


class Stage:
    """One step of a frame: reads the FrameState fields named in ``needs`` and sets those in
    ``makes``; a Renderer runs its stages in order."""

    name: ClassVar[str]
    needs: ClassVar[tuple[str, ...]] = ()
    makes: ClassVar[tuple[str, ...]] = ()

    def run(self, frame: FrameState) -> None:
        raise NotImplementedError
