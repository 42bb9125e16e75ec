"""Indexable datasets for the common training tasks, over one or many seed folders.

They follow the PyTorch ``Dataset`` protocol (``__len__``, ``__getitem__``) without importing
torch, open files lazily in whichever process reads them (safe with DataLoader workers),
and return dicts of numpy arrays, or torch tensors with ``as_tensor=True`` (torch needed).
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable, Iterable

import numpy as np

from generator.checks import check_integer

from .scene import DatasetError, Scene, Sequence, check_index


def scenes_of(paths: str | Path | Scene | Iterable) -> list[Scene]:
    """Scenes from seed folders (one path, a Scene, or several); DatasetError for none."""
    if isinstance(paths, (str, Path, Scene)):
        paths = [paths]
    scenes = [p if isinstance(p, Scene) else Scene(p) for p in paths]
    if not scenes:
        raise DatasetError("no scenes given")
    return scenes


def _check_count(name: str, value) -> None:
    if value is not None:
        check_integer(name, value, 1, valid="None or an integer >= 1")


def to_tensor(sample: dict) -> dict:
    """``sample`` with its numeric arrays as torch tensors (nested dicts too; float16 as float32)."""
    try:
        import torch
    except ImportError:
        raise DatasetError("as_tensor=True needs PyTorch; install torch or leave as_tensor=False") from None
    out = {}
    for k, v in sample.items():
        if isinstance(v, np.ndarray) and v.dtype != object and v.dtype.kind not in "US":
            out[k] = torch.from_numpy(np.ascontiguousarray(v if v.dtype != np.float16 else v.astype(np.float32)))
        elif isinstance(v, dict):
            out[k] = to_tensor(v)
        else:
            out[k] = v
    return out


def trajectory_kinds(scenes: list, trajectories) -> list[list[str]]:
    """Per scene (or Timeline: anything with ``path`` and ``trajectories``), the trajectory
    kinds to use (one name or several; default: all); an unknown kind is a DatasetError."""
    if isinstance(trajectories, str):
        trajectories = [trajectories]
    out = []
    for scene in scenes:
        kinds = list(trajectories) if trajectories else list(scene.trajectories)
        missing = [k for k in kinds if k not in scene.trajectories]
        if missing:
            raise DatasetError(f"{scene.path}: no trajectory {', '.join(map(repr, missing))} (has "
                               f"{', '.join(scene.trajectories)})")
        out.append(kinds)
    return out


def _sequences(scenes: list[Scene], kinds: list[list[str]]) -> list[Sequence]:
    return [scene[kind] for scene, names in zip(scenes, kinds) for kind in names]


def checked_keys(keys, sequences: list[Sequence]) -> tuple[str, ...] | None:
    """The modality names to read (one name or several; None: every stored one), each checked
    against what every chosen sequence stores, here rather than in a DataLoader worker."""
    if keys is None:
        return None
    keys = (keys,) if isinstance(keys, str) else tuple(keys)
    for seq in sequences:
        missing = [k for k in keys if k not in seq.modalities]
        if missing:
            raise DatasetError(f"{seq.folder}: no modality {', '.join(missing)} (written: "
                               f"{', '.join(seq.modalities)})")
    return keys


class TaskDataset:
    """What every dataset of this package shares: an optional ``transform`` applied to each
    sample, then (``as_tensor``) numeric arrays as torch tensors."""

    def __init__(self, transform: Callable | None, as_tensor: bool):
        self.transform, self.as_tensor = transform, as_tensor

    def _finish(self, sample: dict) -> dict:
        if self.transform is not None:
            sample = self.transform(sample)
        return to_tensor(sample) if self.as_tensor else sample


class FrameDataset(TaskDataset):
    """Single frames (depth, normals, flow, segmentation, novel-view synthesis): each item is a
    dict with the frame's modalities (rgb, rgb_linear, depth, label, instance, normal, flow,
    backward_flow: those stored), K, pose, timestamp, scene (seed), trajectory, index.

    ``trajectories``: kinds to include (default: all); ``keys``: modalities to return
    (default: every stored one; exporters/modalities.py). ``annotations=True`` adds the
    frame's objects, ``boxes2d`` and ``boxes3d`` (:meth:`Sequence.annotations`); their
    lengths vary by frame, so batch them with a collate function of your own. Keys,
    trajectories and annotations are checked here (DatasetError), not in a worker."""

    def __init__(self, paths, trajectories: list[str] | None = None, transform: Callable | None = None,
                 as_tensor: bool = False, keys: tuple[str, ...] | None = None, annotations: bool = False):
        super().__init__(transform, as_tensor)
        self.scenes = scenes_of(paths)
        kinds = trajectory_kinds(self.scenes, trajectories)
        sequences = _sequences(self.scenes, kinds)
        self.keys, self.annotations = checked_keys(keys, sequences), annotations
        if annotations:  # a seed made without the instance output has none: say so here
            for seq in sequences:
                seq.check_annotations()
        self.index: list[tuple[int, str, int]] = []
        for s, scene in enumerate(self.scenes):
            for kind in kinds[s]:
                self.index += [(s, kind, i) for i in range(len(scene[kind]))]

    def __len__(self) -> int:
        return len(self.index)

    def __getitem__(self, i: int) -> dict:
        s, kind, j = self.index[check_index(i, len(self), "FrameDataset item")]
        scene = self.scenes[s]
        f = scene[kind].read(j, self.keys)
        sample = dict(f.outputs)
        sample |= {"K": f.K, "pose": f.pose, "timestamp": f.timestamp, "scene": scene.seed, "trajectory": kind,
                   "index": j}
        if self.annotations:
            sample |= scene[kind].annotations(j)
        return self._finish(sample)


class ClipDataset(TaskDataset):
    """Clips of ``length`` consecutive frames (``stride`` apart) with their point tracks
    (tracking, optical / scene flow). Each item: ``frames`` (list of frame dicts with the
    modalities ``keys``, default all stored, and K, pose, timestamp), ``tracks``:
    ``ids`` (n,) of the points visible in the first frame, ``xy`` (length, n, 2) their pixel
    positions in every frame (projected even when hidden), ``visible`` (length, n) bool,
    ``depth`` (length, n) planar metres, ``xyz`` (length, n, 3) world positions."""

    def __init__(self, paths, length: int = 2, stride: int = 1, trajectories: list[str] | None = None,
                 transform: Callable | None = None, as_tensor: bool = False, max_points: int | None = None,
                 keys: tuple[str, ...] | None = None):
        super().__init__(transform, as_tensor)
        length, stride = check_integer("length", length, 1), check_integer("stride", stride, 1)
        _check_count("max_points", max_points)
        self.scenes, self.length, self.stride, self.max_points = scenes_of(paths), length, stride, max_points
        kinds = trajectory_kinds(self.scenes, trajectories)
        self.keys = checked_keys(keys, _sequences(self.scenes, kinds))
        self.index: list[tuple[int, str, int]] = []
        span = (length - 1) * stride
        for s, scene in enumerate(self.scenes):
            for kind in kinds[s]:
                self.index += [(s, kind, i) for i in range(len(scene[kind]) - span)]
        if not self.index:
            longest = max((len(scene[kind]) for s, scene in enumerate(self.scenes) for kind in kinds[s]), default=0)
            raise DatasetError(f"a clip of length {length} with stride {stride} spans {span + 1} frames; the longest "
                               f"trajectory has {longest}: use a shorter length or a smaller stride")

    def __len__(self) -> int:
        return len(self.index)

    def __getitem__(self, i: int) -> dict:
        s, kind, start = self.index[check_index(i, len(self), "ClipDataset item")]
        seq: Sequence = self.scenes[s][kind]
        times = [start + k * self.stride for k in range(self.length)]
        frames = [seq.read(t, self.keys) for t in times]
        ids = seq.visible_tracks(times[0])["ids"]
        if self.max_points is not None and len(ids) > self.max_points:
            ids = np.sort(np.random.default_rng([s, start]).choice(ids, self.max_points, replace=False))
        xy = np.zeros((self.length, len(ids), 2))
        depth = np.zeros((self.length, len(ids)))
        xyz = np.zeros((self.length, len(ids), 3))
        visible = np.zeros((self.length, len(ids)), bool)
        for k, t in enumerate(times):
            xyz[k] = seq.point_positions(t, ids)
            xy[k], depth[k] = seq.project_points(t, ids)  # through the lens (and a rolling shutter)
            visible[k] = np.isin(ids, seq.visible_tracks(t)["ids"])
        sample = {"frames": [dict(f.outputs) | {"K": f.K, "pose": f.pose, "timestamp": f.timestamp} for f in frames],
                  "tracks": {"ids": ids, "xy": xy, "visible": visible, "depth": depth, "xyz": xyz},
                  "scene": self.scenes[s].seed, "trajectory": kind, "index": start}
        if self.transform is not None:
            # image transforms apply frame by frame; the tracks follow the first frame's change
            new_frames = []
            for k, f in enumerate(sample["frames"]):
                out = self.transform(f | {"tracks": {"xy": xy[k], "visible": visible[k]}})
                new_frames.append({key: v for key, v in out.items() if key != "tracks"})
                xy[k], visible[k] = out["tracks"]["xy"], out["tracks"]["visible"]  # off the new image: not visible
            sample["frames"], sample["tracks"]["xy"] = new_frames, xy
        if self.as_tensor:
            sample = to_tensor({k: v for k, v in sample.items() if k != "frames"}) | {
                "frames": [to_tensor(f) for f in sample["frames"]]}
        return sample


class PointCloudDataset(TaskDataset):
    """Labelled ground-truth point clouds (3D semantic segmentation), one item per scene:
    ``xyz`` (N, 3) float32 metres, ``label``, ``instance`` (N,) int32, ``dynamic`` (N,) bool.
    ``num_points``: a seeded random subset of that size per item (all points by default)."""

    def __init__(self, paths, num_points: int | None = None, static_only: bool = False,
                 transform: Callable | None = None, as_tensor: bool = False):
        super().__init__(transform, as_tensor)
        _check_count("num_points", num_points)
        self.scenes, self.num_points, self.static_only = scenes_of(paths), num_points, static_only

    def __len__(self) -> int:
        return len(self.scenes)

    def __getitem__(self, i: int) -> dict:
        scene = self.scenes[check_index(i, len(self), "PointCloudDataset item")]
        cloud = scene.point_cloud(self.static_only)
        if self.num_points is not None and self.num_points < len(cloud["xyz"]):
            keep = np.sort(np.random.default_rng(scene.seed).choice(len(cloud["xyz"]), self.num_points, replace=False))
            cloud = {k: v[keep] for k, v in cloud.items()}
        return self._finish(cloud | {"scene": scene.seed})
