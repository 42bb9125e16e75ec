"""Per-frame sinks: the contract between the trajectory loop and every export (bpy-free).

The loop that flies a trajectory builds one :class:`TrajectoryContext`, makes every sink
from it, hands each rendered frame to every sink as a :class:`FrameRecord` and finally
calls ``close()``. A sink knows nothing else. Each sink lives beside the format it writes
and registers itself there with :func:`register_sink`, with the command-line options it
needs (``--colmap-text``): their values reach it in ``TrajectoryContext.options`` and are
part of the run's parameters (a manifest's config). Every module of ``exporters/`` is
imported on the first lookup, so adding an export is one new file.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Protocol

import numpy as np

from generator.cli_args import Option
from generator.geometry.lens import PINHOLE, Lens
from generator.image_sensor import IDEAL, ImageSensor
from generator.registry import Registry, RegistryError, origin


@dataclass(frozen=True)
class TrajectoryContext:
    """Everything constant over one trajectory.

    folder: the trajectory's output folder (``seed_N/<kind>``); kind: trajectory kind.
    K (3, 3), width, height: the camera (OpenCV convention, pixels); lens: its lens model
    (generator/geometry/lens.py; the ideal pinhole unless ``--camera-model`` says otherwise).
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
    options: per-run options: the values of the sinks' own options (``{"colmap_text": False}``:
    :func:`export_options`) and what the run knows of the site (``"plan"``: the site plan,
    ``"ground_truth"``, ``"segmentation_sensitivity"``: the Simulator's settings).
    object_matrices (T, D, 4, 4): world_from_object of ``dynamic_objects`` at every frame.
    clip: (near, far) planar depth limits of the rendered surfaces, metres.
    scene_bounds (2, 3): world axis-aligned bounds (min, max) of every part over all frames.
    rolling: the rolling shutter's rows and motion (None: a global shutter); sinks place points
    in the image with :meth:`project_points`.
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
    lens: Lens = PINHOLE
    image_sensor: ImageSensor = IDEAL
    rolling: object | None = None  # a rolling shutter's generator.geometry.rolling.RollingCamera (None: global)

    def project_points(self, index: int, ids: np.ndarray, world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Where the points ``ids`` of the point table (their world positions ``world`` at frame
        ``index``'s time) land in frame ``index``'s image: (pixels (n, 2) as (x, y), planar
        depth (n,)), through the lens, and through the rolling shutter when there is one (each
        point at the time its row is read: generator/geometry/rolling.py)."""
        from generator.geometry.camera import project

        if self.rolling is None:
            return project(world, self.poses[index], self.K, self.lens)
        table = self.point_table
        return self.rolling.project(index, np.asarray(table["local"])[ids], np.asarray(table["dynamic_object"])[ids],
                                    self.K, self.lens)


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
    exposure_gain: the linear gain the image sensor applied to the display colour (1: as rendered).
    """

    index: int
    timestamp: float
    world_from_camera: np.ndarray
    outputs: dict[str, np.ndarray]
    points: np.ndarray
    visible: np.ndarray
    object_matrices: np.ndarray
    coverage: float
    exposure_gain: float = 1.0


class Sink(Protocol):
    def add_frame(self, frame: FrameRecord) -> None: ...

    def close(self) -> None: ...


@dataclass(frozen=True)
class SinkEntry:
    """A registered export: ``factory(context) -> Sink`` (the sink class) and the command-line
    ``options`` it adds (generator.cli_args.Option; each one's ``dest`` is its key in
    ``TrajectoryContext.options`` and in the run's config)."""

    name: str
    factory: Callable[[TrajectoryContext], Sink]
    options: tuple[Option, ...] = ()


SINKS: Registry[SinkEntry] = Registry("export", "exporters")


def register_sink(name: str, options: tuple[Option, ...] = ()):
    """Class decorator: ``@register_sink("coco")`` makes the sink available to the loop;
    ``options`` are the command-line options it reads from ``context.options``."""

    def wrap(factory):
        SINKS.add(name, SinkEntry(name, factory, tuple(options)), origin(factory))
        return factory

    return wrap


def load_sinks() -> dict[str, Callable[[TrajectoryContext], Sink]]:
    """Every registered sink factory by name (name order), the modules of ``exporters/``
    imported first."""
    return {name: entry.factory for name, entry in SINKS.items()}


def export_options() -> list[Option]:
    """The command-line options of every export, in the exports' name order; RegistryError if
    two declare the same option."""
    seen: dict[str, str] = {}
    options = []
    for name, entry in SINKS.items():
        for option in entry.options:
            if option.dest in seen:
                raise RegistryError(f"option {option.flag} is declared by the exports {seen[option.dest]!r} and "
                                    f"{name!r}: rename one")
            seen[option.dest] = name
            options.append(option)
    return options
