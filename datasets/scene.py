"""One generated seed folder, read lazily with no bpy (formats: docs/format.md).

Files are opened when they are read and closed straight after (HDF5 files are kept open
per process and reopened after a fork), so a :class:`Scene` can be handed to DataLoader
worker processes.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import h5py
import numpy as np

from exporters import FORMAT_VERSION
from exporters.exr import read_frame_exr
from exporters.frames import frame_names
from exporters.manifest import read_manifest

SUPPORTED_VERSIONS = (FORMAT_VERSION,)


class DatasetError(ValueError):
    """A folder that cannot be read as a generated scene (the message says why)."""


@dataclass
class Frame:
    """One rendered frame, exactly as stored. ``rgb`` (H, W, 3) float16 display sRGB in [0, 1]
    (Blender's view transform applied; ``.astype(np.float32)`` for arithmetic); ``depth`` (H, W)
    float32 planar metres (+inf: no surface); ``label``, ``instance`` (H, W) int32 (-1: none);
    ``K`` (3, 3); ``pose`` (4, 4) OpenCV world_from_camera; ``timestamp`` seconds."""

    rgb: np.ndarray
    depth: np.ndarray
    label: np.ndarray
    instance: np.ndarray
    K: np.ndarray
    pose: np.ndarray
    timestamp: float
    index: int
    trajectory: str

    def as_dict(self) -> dict:
        return dict(self.__dict__)


class _H5:
    """An HDF5 file opened once per process (h5py handles must not cross a fork)."""

    def __init__(self, path: Path):
        self.path, self._pid, self._file = path, None, None

    def get(self) -> h5py.File:
        if self._file is None or self._pid != os.getpid():
            self._file = h5py.File(self.path, "r")
            self._pid = os.getpid()
        return self._file

    def __getstate__(self):
        return {"path": self.path, "_pid": None, "_file": None}


class Sequence:
    """The frames of one trajectory of a scene: ``len``, ``seq[i]`` -> :class:`Frame`,
    ``seq[a:b]`` -> list, plus the point tracks of ``tracks.h5``."""

    def __init__(self, folder: Path, labels: list[str]):
        self.folder, self.kind, self.labels = folder, folder.name, labels
        for name in ("tracks.h5", "trajectory.npz"):
            if not (folder / name).is_file():
                raise DatasetError(f"{folder}: missing {name}; the seed folder is incomplete, regenerate it")
        self._h5 = _H5(folder / "tracks.h5")
        f = self._h5.get()
        version = f.attrs.get("format_version")
        if version not in SUPPORTED_VERSIONS:
            raise DatasetError(f"{folder / 'tracks.h5'}: format_version {version!r}; this reader reads "
                               f"{', '.join(SUPPORTED_VERSIONS)} (update buildee-sites or regenerate)")
        self.K = f["cameras/K"][()]
        self.width, self.height = int(f["cameras"].attrs["width"]), int(f["cameras"].attrs["height"])
        self.poses = f["cameras/world_from_camera"][()]
        self.timestamps = f["cameras/timestamps"][()]
        self.offsets = f["visibility/offsets"][()]

    def __len__(self) -> int:
        return len(self.poses)

    def exr_path(self, i: int) -> Path:
        return self.folder / frame_names(i)[0]

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        i = int(i)
        if i < 0:
            i += len(self)
        if not 0 <= i < len(self):
            raise IndexError(f"frame {i} out of range: {self.kind} has {len(self)} frames")
        path = self.exr_path(i)
        if not path.is_file():
            raise DatasetError(f"{path}: missing frame; the seed folder is incomplete, regenerate it")
        d = read_frame_exr(path)
        return Frame(d["rgb"], d["depth"], d["label"], d["instance"], self.K.copy(),
                     self.poses[i].copy(), float(self.timestamps[i]), i, self.kind)

    def visible_tracks(self, t: int) -> dict:
        """Points visible at frame t: ``ids`` (n,), ``xy`` (n, 2) pixels, ``depth`` (n,) metres."""
        f = self._h5.get()
        a, b = int(self.offsets[t]), int(self.offsets[t + 1])
        return {"ids": f["visibility/index"][a:b], "xy": f["visibility/xy"][a:b], "depth": f["visibility/depth"][a:b]}

    def point_positions(self, t: int, ids: np.ndarray) -> np.ndarray:
        """World positions (n, 3) metres of points ``ids`` at frame t (dynamic ones moved)."""
        from exporters.tracks import world_positions

        return world_positions({"local": self.points["local"], "dynamic_object": self.points["dynamic_object"],
                                "world_from_object": self.object_matrices}, t, np.asarray(ids))

    @cached_property
    def points(self) -> dict:
        """The tracked surface points: local (N, 3), label, instance, dynamic_object (N,)."""
        f = self._h5.get()
        return {k: f[f"points/{k}"][()] for k in ("local", "label", "instance", "dynamic_object")}

    @cached_property
    def object_matrices(self) -> np.ndarray:
        """(T, D, 4, 4) world_from_object of the moving objects."""
        return self._h5.get()["objects/world_from_object"][()]

    @cached_property
    def coverage(self) -> np.ndarray:
        """(T,) share of surface points observed at least once after each frame."""
        return self._h5.get()["coverage"][()]

    @cached_property
    def tapvid(self) -> dict:
        """TAP-Vid query subset: query_points (Q, 3) (t, y, x), tracks (Q, T, 2) (x, y),
        occluded (Q, T), tracks_3d (Q, T, 3), point_ids (Q,)."""
        g = self._h5.get()["tapvid"]
        return {k: g[k][()] for k in g}


class Scene:
    """Everything one seed folder holds, read lazily.

    ``scene.labels`` the label table; ``scene.trajectories`` the kinds; ``scene[kind]`` a
    :class:`Sequence`; ``scene.frames`` all frames of all trajectories (index or slice);
    ``scene.point_cloud()`` the labelled ground-truth cloud; ``scene.manifest``.
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)
        if not self.path.is_dir():
            raise DatasetError(f"{self.path}: no such folder")
        manifest = read_manifest(self.path)
        if manifest is None:
            raise DatasetError(f"{self.path}: not a complete seed folder (no readable manifest.json); "
                               "point at output/seed_NNNNNN written by python -m generator")
        version = manifest.get("format_version")
        if version not in SUPPORTED_VERSIONS:
            raise DatasetError(f"{self.path}: format_version {version!r}; this reader reads "
                               f"{', '.join(SUPPORTED_VERSIONS)} (update buildee-sites or regenerate)")
        self.manifest = manifest
        self.seed = int(manifest["seed"])
        labels_path = self.path / "labels.json"
        if not labels_path.is_file():
            raise DatasetError(f"{labels_path}: missing; the seed folder is incomplete, regenerate it")
        self.labels: list[str] = json.loads(labels_path.read_text())
        self.trajectories: list[str] = list(manifest["config"]["trajectories"])
        self._sequences: dict[str, Sequence] = {}

    def __repr__(self) -> str:
        return f"Scene(seed={self.seed}, trajectories={self.trajectories}, frames={len(self.frames)})"

    def __getitem__(self, kind: str) -> Sequence:
        if kind not in self.trajectories:
            raise KeyError(f"no trajectory {kind!r} in {self.path} (has {', '.join(self.trajectories)})")
        if kind not in self._sequences:
            self._sequences[kind] = Sequence(self.path / kind, self.labels)
        return self._sequences[kind]

    @property
    def sequences(self) -> list[Sequence]:
        return [self[k] for k in self.trajectories]

    @cached_property
    def frames(self) -> "_Frames":
        return _Frames(self.sequences)

    def point_cloud(self, static_only: bool = False) -> dict:
        """The labelled ground-truth cloud: xyz (N, 3) float32 metres, label, instance (N,)
        int32, dynamic (N,) bool (objects at the first animation frame)."""
        from exporters.ply import read_ply

        path = self.path / "ground_truth" / "points.ply"
        if not path.is_file():
            raise DatasetError(f"{path}: missing; the seed folder is incomplete, regenerate it")
        d = read_ply(path)
        out = {"xyz": np.stack([d.vertex[c] for c in "xyz"], 1), "label": d.vertex["label"],
               "instance": d.vertex["instance"], "dynamic": d.vertex["dynamic"].astype(bool)}
        if static_only:
            keep = ~out["dynamic"]
            out = {k: v[keep] for k, v in out.items()}
        return out


class _Frames:
    """All frames of several sequences as one list (index or slice)."""

    def __init__(self, sequences: list[Sequence]):
        self.sequences = sequences
        self.starts = np.cumsum([0] + [len(s) for s in sequences])

    def __len__(self) -> int:
        return int(self.starts[-1])

    def locate(self, i: int) -> tuple[Sequence, int]:
        if i < 0:
            i += len(self)
        if not 0 <= i < len(self):
            raise IndexError(f"frame {i} out of range ({len(self)} frames)")
        k = int(np.searchsorted(self.starts, i, side="right") - 1)
        return self.sequences[k], i - int(self.starts[k])

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        seq, j = self.locate(int(i))
        return seq[j]
