"""LiDAR scans of generated seeds for training (no bpy; torch optional): the sweeps that
``python -m generator --lidar NAME`` wrote (docs/lidar.md, docs/format.md "LiDAR scans"),
read by their one reader (exporters/semantickitti.py).

    from datasets import ScanDataset
    ds = ScanDataset(["output/seed_000000"], sensor="os1-128")
    item = ds[0]    # points (N, 4) x, y, z, intensity; label, instance (N,) int64; ring; time; pose
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from exporters.semantickitti import read_lidar_json, read_scan, scan_folder

from .scene import DatasetError, check_index
from .tasks import TaskDataset, scenes_of, trajectory_kinds


def sensors_of(trajectory_folder: Path) -> list[str]:
    """The sensors whose sweeps a trajectory folder holds (``lidar/<NAME>/lidar.json``)."""
    root = Path(trajectory_folder) / "lidar"
    return sorted(p.parent.name for p in root.glob("*/lidar.json")) if root.is_dir() else []


def checked(read, *args):
    """``read(*args)`` (a reader of exporters/semantickitti.py), a damaged or missing file as
    one DatasetError line."""
    from exporters.hdf5 import DamagedFileError

    try:
        return read(*args)
    except (DamagedFileError, ValueError) as exc:
        raise DatasetError(str(exc)) from None


class ScanDataset(TaskDataset):
    """One item per sweep of ``sensor`` (a name given to ``--lidar``, e.g. ``os1-128`` or
    ``vlp16@drone``) over the trajectories of the seeds ``paths``: a dict with ``points``
    (N, 4) float32 x, y, z, intensity in the sensor frame (the raw sweep, or the de-skewed one
    with ``deskewed=True``: the scene frozen at the sweep's start), ``label`` and ``instance``
    (N,) int64 (class and object ids: the seed's labels.json and instance images), ``ring``
    (N,) int64, ``time`` (N,) float32 s after the sweep's start, ``pose`` (4, 4) float64
    world_from_sensor at the sweep's start, ``start_time_s``, ``scene`` (seed),
    ``trajectory``, ``sensor``, ``index`` (the sweep's). A trajectory without that sensor's
    sweeps is a DatasetError here, not in a DataLoader worker. Sweeps hold different numbers
    of returns: batch them with a collate function of your own."""

    def __init__(self, paths, sensor: str, trajectories: list[str] | None = None, deskewed: bool = False,
                 transform: Callable | None = None, as_tensor: bool = False):
        super().__init__(transform, as_tensor)
        self.scenes, self.sensor, self.deskewed = scenes_of(paths), str(sensor), bool(deskewed)
        self.index: list[tuple[int, str, int]] = []
        self.docs: dict[tuple[int, str], dict] = {}
        for s, (scene, kinds) in enumerate(zip(self.scenes, trajectory_kinds(self.scenes, trajectories))):
            for kind in kinds:
                folder = scan_folder(scene.path / kind, self.sensor)
                if not (folder / "lidar.json").is_file():
                    have = sensors_of(scene.path / kind)
                    raise DatasetError(f"{scene.path / kind}: no sweeps of {self.sensor!r} (has "
                                       f"{', '.join(have) or 'none'}); write them with python -m generator "
                                       f"--lidar {self.sensor}")
                self.docs[s, kind] = checked(read_lidar_json, folder)
                self.index += [(s, kind, k) for k in range(len(self.docs[s, kind]["scans"]))]

    def __len__(self) -> int:
        return len(self.index)

    def __getitem__(self, i: int) -> dict:
        s, kind, k = self.index[check_index(i, len(self), "ScanDataset item")]
        scene = self.scenes[s]
        scan = checked(read_scan, scan_folder(scene.path / kind, self.sensor), k, self.docs[s, kind])
        xyz = scan.xyz_deskewed if self.deskewed else scan.xyz
        sample = {"points": np.concatenate([xyz, scan.intensity[:, None]], axis=1).astype(np.float32),
                  "label": scan.label.astype(np.int64), "instance": scan.instance.astype(np.int64),
                  "ring": scan.ring.astype(np.int64), "time": scan.time, "pose": scan.world_from_sensor,
                  "start_time_s": scan.start_time_s, "scene": scene.seed, "trajectory": kind,
                  "sensor": self.sensor, "index": k}
        return self._finish(sample)
