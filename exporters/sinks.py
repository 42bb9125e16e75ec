"""Per-frame sinks: the contract between the trajectory loop and every export (bpy-free).

The loop that flies a trajectory builds one :class:`TrajectoryContext`, makes every sink
from it, hands each rendered frame to every sink as a :class:`FrameRecord` and finally
calls ``close()``. A sink knows nothing else: adding an export is one new sink class plus
its registration in :data:`SINKS`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Protocol

import numpy as np


@dataclass(frozen=True)
class TrajectoryContext:
    """Everything constant over one trajectory.

    folder: the trajectory's output folder (``seed_N/<kind>``); kind: trajectory kind.
    K (3, 3), width, height: the pinhole camera (OpenCV convention, pixels).
    poses (T, 4, 4): world_from_camera of every frame (OpenCV axes), known up front.
    timestamps (T,): seconds from the first frame.
    labels: class names (label id = index); instances: rows ``{"id", "object", "label",
    "label_id"}`` (instance id = index, as in the ``instance`` modality).
    parts: the scene's rigid parts (``generator.geometry.parts.MeshPart``) in instance-id
    order; dynamic parts in their object frame.
    dynamic_objects: names of the dynamic parts (the order of ``FrameRecord.object_matrices``).
    point_table: the ground-truth point set as stored in exports (``Simulator.point_table``).
    modalities: names of the per-frame modalities being written (``--outputs``), in the
    order of ``exporters.modalities.MODALITIES``.
    options: free-form per-run options (e.g. ``{"colmap_text": False, "plan": site plan}``).
    object_matrices (T, D, 4, 4): world_from_object of ``dynamic_objects`` at every frame.
    clip: (near, far) planar depth limits of the rendered surfaces, metres.
    scene_bounds (2, 3): world axis-aligned bounds (min, max) of every part over all frames.
    """

    folder: Path
    kind: str
    seed: int
    K: np.ndarray
    width: int
    height: int
    poses: np.ndarray
    timestamps: np.ndarray
    labels: list[str]
    instances: list[dict]
    parts: list
    dynamic_objects: list[str]
    point_table: dict
    modalities: tuple[str, ...]
    options: dict = field(default_factory=dict)
    object_matrices: np.ndarray | None = None
    clip: tuple[float, float] = (0.0, float("inf"))
    scene_bounds: np.ndarray | None = None


@dataclass
class FrameRecord:
    """One frame of the trajectory, as every sink sees it.

    index: 0-based frame index; timestamp: seconds.
    world_from_camera (4, 4): OpenCV camera-to-world pose.
    outputs: modality name -> array (H, W[, C]) as declared in the modality registry
    (e.g. ``rgb``, ``rgb_linear``, ``depth``, ``label``, ``instance``, ``normal``, ``flow``).
    points (N, 3): world positions of every ground-truth point at this frame.
    visible (N,) bool: the point is visible in this frame (docs/conventions.md).
    object_matrices (D, 4, 4): world_from_object of ``dynamic_objects`` at this frame.
    coverage: share of points observed at least once, after this frame (0..1).
    """

    index: int
    timestamp: float
    world_from_camera: np.ndarray
    outputs: dict[str, np.ndarray]
    points: np.ndarray
    visible: np.ndarray
    object_matrices: np.ndarray
    coverage: float


class Sink(Protocol):
    def add_frame(self, frame: FrameRecord) -> None: ...

    def close(self) -> None: ...


# name -> factory(context) -> Sink; filled by the modules that define sinks.
SINKS: dict[str, Callable[[TrajectoryContext], Sink]] = {}

# the modules whose imports register the exports (a new export adds its module here)
SINK_MODULES = ("exporters.frames", "exporters.trajectory_sinks", "exporters.nerfstudio", "exporters.coco", "exporters.boxes3d")


def load_sinks() -> dict[str, Callable[[TrajectoryContext], Sink]]:
    """Import every module of :data:`SINK_MODULES` (registering their sinks) and return
    :data:`SINKS`, in registration order."""
    import importlib

    for name in SINK_MODULES:
        importlib.import_module(name)
    return SINKS


def register_sink(name: str):
    """Class decorator: ``@register_sink("coco")`` makes the sink available to the loop."""

    def wrap(factory):
        old = SINKS.get(name)
        if old is not None and (old.__module__, old.__qualname__) != (factory.__module__, factory.__qualname__):
            raise ValueError(f"sink {name!r} is registered twice")
        SINKS[name] = factory
        return factory

    return wrap
