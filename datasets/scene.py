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
from exporters.hdf5 import H5_ERRORS, DamagedFileError, attribute, damaged, group, open_file, read, reason, text
from exporters.manifest import read_manifest

SUPPORTED_VERSIONS = (FORMAT_VERSION,)


class DatasetError(ValueError):
    """A folder that cannot be read as a generated scene, or a damaged file in it (the
    message names the file and says what to do)."""


def _checked(call, *args, path=None):
    """``call(*args)``, with a damaged file reported as a :class:`DatasetError`."""
    try:
        return call(*args)
    except DamagedFileError as exc:
        raise DatasetError(str(exc)) from None
    except DatasetError:
        raise
    except H5_ERRORS as exc:  # damaged HDF5 metadata can fail anywhere h5py looks
        if path is None:
            raise
        raise DatasetError(str(damaged(path, reason(exc)))) from None


def check_index(i, n: int, what: str) -> int:
    """Python indexing (negative counts from the end) with a message stating the valid range."""
    if isinstance(i, (bool, np.bool_)) or not isinstance(i, (int, np.integer)):
        raise TypeError(f"{what} index must be an integer, got {type(i).__name__}")
    j = int(i) + n if i < 0 else int(i)
    if not 0 <= j < n:
        raise IndexError(f"{what} index {int(i)} out of range: valid indices are -{n}..{n - 1}" if n
                         else f"{what} index {int(i)} out of range: there are no frames")
    return j


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
            self._file = _checked(open_file, self.path)
            self._pid = os.getpid()
        return self._file

    def read(self, key: str, sel=()) -> np.ndarray:
        """``file[key][sel]``; a damaged dataset (checksum, missing) raises DatasetError."""
        return _checked(lambda: read(self.get(), key, self.path, sel), path=self.path)

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
        _checked(self._read_cameras, path=self._h5.path)

    def _read_cameras(self) -> None:
        h5 = self._h5
        f = h5.get()
        version = text(_checked(attribute, f, "format_version")) if "format_version" in f.attrs else None
        if version not in SUPPORTED_VERSIONS:
            raise DatasetError(f"{h5.path}: format_version {version!r}; this reader reads "
                               f"{', '.join(SUPPORTED_VERSIONS)} (update buildee-sites, or regenerate the seed: python -m generator --seeds N --overwrite, with the options it was made with)")
        self.K = h5.read("cameras/K")
        cams = _checked(group, f, "cameras", h5.path)
        self.width, self.height = (int(_checked(attribute, cams, k, h5.path)) for k in ("width", "height"))
        self.poses = h5.read("cameras/world_from_camera")
        self.timestamps = h5.read("cameras/timestamps")
        self.offsets = h5.read("visibility/offsets")
        self._check(h5.path)

    def _check(self, path: Path) -> None:
        T = len(self.poses)
        problems = [
            (self.K.shape != (3, 3) or not np.isfinite(self.K).all() or self.K[0, 0] <= 0 or self.K[1, 1] <= 0,
             "cameras/K is not a valid intrinsic matrix"),
            (self.width <= 0 or self.height <= 0, "camera size"),
            (self.poses.shape[1:] != (4, 4) or not np.isfinite(self.poses).all(), "cameras/world_from_camera"),
            (self.timestamps.shape != (T,) or not np.isfinite(self.timestamps).all(), "cameras/timestamps"),
            (self.offsets.shape != (T + 1,) or (T and (self.offsets[0] != 0 or np.any(np.diff(self.offsets) < 0))),
             "visibility/offsets"),
        ]
        for bad, what in problems:
            if bad:
                raise DatasetError(f"{path}: damaged file ({what} is inconsistent); regenerate this seed with "
                                   "python -m generator")

    def __len__(self) -> int:
        return len(self.poses)

    def exr_path(self, i: int) -> Path:
        return self.folder / frame_names(i)[0]

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        i = check_index(i, len(self), f"{self.kind} frame")
        path = self.exr_path(i)
        if not path.is_file():
            raise DatasetError(f"{path}: missing frame; the seed folder is incomplete, regenerate it")
        d = _checked(read_frame_exr, path)
        missing = [k for k in ("rgb", "depth", "label", "instance") if k not in d]
        shape = (self.height, self.width)
        if missing or any(d[k].shape[:2] != shape for k in ("rgb", "depth", "label", "instance")):
            raise DatasetError(f"{path}: damaged frame (" + (f"no {', '.join(missing)} channel" if missing else
                               f"not {self.width}x{self.height} pixels") + "); regenerate this seed with python -m generator")
        return Frame(d["rgb"], d["depth"], d["label"], d["instance"], self.K.copy(),
                     self.poses[i].copy(), float(self.timestamps[i]), i, self.kind)

    def visible_tracks(self, t: int) -> dict:
        """Points visible at frame t (Python indexing: -1 is the last frame): ``ids`` (n,),
        ``xy`` (n, 2) pixels, ``depth`` (n,) metres."""
        t = check_index(t, len(self), f"{self.kind} frame")
        a, b = int(self.offsets[t]), int(self.offsets[t + 1])
        out = {k: self._h5.read(f"visibility/{name}", np.s_[a:b]) for k, name in
               (("ids", "index"), ("xy", "xy"), ("depth", "depth"))}
        if any(len(v) != b - a for v in out.values()) or (b > a and (out["ids"].min() < 0 or
                                                                      out["ids"].max() >= len(self.points["label"]))):
            raise DatasetError(f"{self._h5.path}: damaged file (visibility of frame {t} is inconsistent); "
                               "regenerate this seed with python -m generator")
        return out

    def point_positions(self, t: int, ids: np.ndarray) -> np.ndarray:
        """World positions (n, 3) metres of points ``ids`` at frame t (Python indexing; dynamic
        ones moved)."""
        from exporters.tracks import world_positions

        t = check_index(t, len(self), f"{self.kind} frame")
        ids = np.asarray(ids)
        n = len(self.points["label"])
        if ids.size and (ids.dtype.kind not in "iu" or ids.min() < 0 or ids.max() >= n):
            raise IndexError(f"point ids must be integers in 0..{n - 1}")
        return world_positions({"local": self.points["local"], "dynamic_object": self.points["dynamic_object"],
                                "world_from_object": self.object_matrices}, t, ids)

    @cached_property
    def points(self) -> dict:
        """The tracked surface points: local (N, 3), label, instance, dynamic_object (N,)."""
        return {k: self._h5.read(f"points/{k}") for k in ("local", "label", "instance", "dynamic_object")}

    @cached_property
    def object_matrices(self) -> np.ndarray:
        """(T, D, 4, 4) world_from_object of the moving objects."""
        return self._h5.read("objects/world_from_object")

    @cached_property
    def coverage(self) -> np.ndarray:
        """(T,) share of surface points observed at least once after each frame."""
        return self._h5.read("coverage")

    @cached_property
    def tapvid(self) -> dict:
        """TAP-Vid query subset: query_points (Q, 3) (t, y, x), tracks (Q, T, 2) (x, y),
        occluded (Q, T), tracks_3d (Q, T, 3), point_ids (Q,) (checked for consistency)."""
        from exporters.tracks import read_tapvid

        return _checked(lambda: read_tapvid(self._h5.get(), self._h5.path), path=self._h5.path)


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
                               f"{', '.join(SUPPORTED_VERSIONS)} (update buildee-sites, or regenerate the seed: python -m generator --seeds N --overwrite, with the options it was made with)")
        self.manifest = manifest
        try:
            self.seed = int(manifest["seed"])
            self.trajectories: list[str] = [str(k) for k in manifest["config"]["trajectories"]]
        except (KeyError, TypeError, ValueError):
            raise DatasetError(f"{self.path / 'manifest.json'}: damaged manifest (no seed or trajectories); "
                               "regenerate this seed with python -m generator") from None
        if any(Path(k).name != k or k in ("", ".", "..") for k in self.trajectories):
            raise DatasetError(f"{self.path / 'manifest.json'}: damaged manifest (trajectory names "
                               f"{self.trajectories} are not folder names); regenerate this seed")
        labels_path = self.path / "labels.json"
        if not labels_path.is_file():
            raise DatasetError(f"{labels_path}: missing; the seed folder is incomplete, regenerate it")
        try:
            self.labels: list[str] = json.loads(labels_path.read_bytes().decode("utf-8"))
        except (OSError, ValueError) as exc:
            raise DatasetError(f"{labels_path}: unreadable label table ({exc.__class__.__name__}); "
                               "regenerate this seed with python -m generator") from None
        if not isinstance(self.labels, list) or not all(isinstance(n, str) for n in self.labels):
            raise DatasetError(f"{labels_path}: not a JSON list of class names; regenerate this seed")
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
        from exporters.ply import PlyError

        try:
            d = read_ply(path)
        except PlyError as exc:
            raise DatasetError(f"{exc}; regenerate this seed with python -m generator") from None
        missing = [k for k in ("label", "instance", "dynamic") if k not in d.vertex]
        if missing:
            raise DatasetError(f"{path}: no {', '.join(missing)} property; not a ground-truth cloud of "
                               "python -m generator, regenerate this seed")
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
        i = check_index(i, len(self), "frame")
        k = int(np.searchsorted(self.starts, i, side="right") - 1)
        return self.sequences[k], i - int(self.starts[k])

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        seq, j = self.locate(i)
        return seq[j]
