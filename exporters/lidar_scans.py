"""``--lidar NAME`` (repeatable): each trajectory's LiDAR sweeps, in the SemanticKITTI layout
``<trajectory>/lidar/<NAME>/`` (exporters/semantickitti.py) and, for a terrestrial scanner,
also as LAS 1.4 (``lidar/<NAME>/las/NNNNNN.las``, exporters/las.py). docs/lidar.md.

The sensor rides on what carries the trajectory's camera: its body is the camera's centre,
heading along the camera's view (turned level), x forward, y left, z up; the sensor sits on
the body with its mount's rotation. A spinning or rosette sensor sweeps at its rate from the
trajectory's first frame (sweep k starts at k / rate_hz seconds) for as long as the
trajectory lasts; a terrestrial scanner (kind ``dome``) scans from :data:`STATIONS` stations,
the camera's place at evenly spaced frames, standing still while it scans. The site's
machines move during a sweep as they do in the frames (generator/geometry/motion.py). Every file
lands in the seed's manifest with the rest."""

from __future__ import annotations

import argparse

import numpy as np

from generator.cli_args import Option
from generator.geometry.motion import MotionTrack, body_pose
from generator.lidar.scanner import Scanner
from generator.lidar.sensors import PRESETS, lidar

from .palette import label_colors
from .sinks import FrameRecord, TrajectoryContext, register_sink

STATIONS = 4  # a terrestrial scanner's stations per trajectory


def lidar_name(text: str) -> str:
    """An argparse type: a LiDAR preset's name, optionally ``@drone``."""
    try:
        return lidar(text).name
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def sweep_starts(sensor, times: np.ndarray) -> list[float]:
    """Start times (s) of the sweeps over a trajectory of frame ``times``: every 1 / rate_hz
    from the first frame while a whole sweep fits (at least one); a dome scanner's stations
    at :data:`STATIONS` evenly spaced frames."""
    if sensor.kind == "dome":
        frames = np.unique(np.linspace(0, len(times) - 1, min(STATIONS, len(times))).round().astype(int))
        return [float(times[i]) for i in frames]
    period = 1.0 / sensor.rate_hz
    count = max(1, int(np.floor((times[-1] - times[0]) / period + 1e-9)))
    return [float(times[0] + k * period) for k in range(count)]


@register_sink("lidar", options=(Option("--lidar", "add a LiDAR's sweeps to each trajectory (repeatable): "
                                          + ", ".join(PRESETS) + ", or NAME@drone (docs/lidar.md)",
                                          type=lidar_name, action="append"),))
class LidarSink:
    """Sweeps every ``--lidar`` sensor over the trajectory when it closes (the poses and the
    machines' matrices are known up front: nothing waits on the renderer)."""

    def __init__(self, context: TrajectoryContext):
        self.context = context
        self.sensors = [lidar(n) for n in dict.fromkeys(context.options.get("lidar") or [])]

    def add_frame(self, frame: FrameRecord) -> None:
        pass

    def close(self) -> None:
        if self.sensors:
            scanner = self._scanner()
            for sensor in self.sensors:
                self._write(scanner, sensor)

    def _scanner(self) -> Scanner:
        c = self.context
        return Scanner.of_parts(c.parts, [row["label_id"] for row in c.instances], c.seed)

    def _tracks(self) -> tuple[MotionTrack, dict[int, MotionTrack]]:
        c = self.context
        times = np.asarray(c.timestamps, dtype=np.float64)
        body = MotionTrack(times, np.stack([body_pose(p) for p in c.poses]))
        index = {name: k for k, name in enumerate(c.dynamic_objects)}
        objects = {}
        if c.object_matrices is not None:
            for i, part in enumerate(c.parts):
                if part.dynamic and part.name in index:
                    objects[i] = MotionTrack(times, c.object_matrices[:, index[part.name]])
        return body, objects

    def _write(self, scanner: Scanner, sensor) -> None:
        from .las import write_las
        from .semantickitti import ScanWriter, scan_folder

        c = self.context
        body, objects = self._tracks()
        folder = scan_folder(c.folder, sensor.name)
        colours = [tuple(int(v) for v in rgb) for rgb in label_colors(c.labels)]
        writer = ScanWriter(folder, sensor.summary(), list(c.labels), colours)
        for k, start in enumerate(sweep_starts(sensor, np.asarray(c.timestamps, dtype=np.float64))):
            carrier = body if sensor.kind != "dome" else MotionTrack(np.array([start]), body.at(start))
            sweep = scanner.sweep(sensor, k, start, carrier, objects)
            writer.add(sweep.scan, sweep.motion_bound_m)
            if sensor.kind == "dome":
                (folder / "las").mkdir(exist_ok=True)
                write_las(folder / "las" / f"{k:06d}.las", sweep.scan, list(c.labels))
        writer.close()
