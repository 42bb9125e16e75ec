"""Trajectories: camera poses plus timestamps, and the interface planners ask about space."""

from __future__ import annotations

import json
import zipfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np

FORMAT = "buildee-trajectory-1"


class MotionChecker(Protocol):
    """What a planner may ask (``generator.Simulator`` implements it)."""

    def can_move(self, start, end) -> bool:
        """May the camera sphere travel straight from ``start`` to ``end`` (world metres)?"""

    def is_free(self, position) -> bool:
        """Does the camera sphere fit at ``position``?"""


class BoundedChecker:
    """A :class:`MotionChecker` that also keeps the camera inside an axis-aligned box
    ``[lo, hi]`` (world metres), e.g. the site's camera spawn volume: planners that would
    otherwise wander off an unbounded ground plane treat its faces as walls."""

    def __init__(self, checker: MotionChecker, lo, hi):
        self.checker, self.lo, self.hi = checker, np.asarray(lo, np.float64), np.asarray(hi, np.float64)
        if (self.lo.shape != (3,) or self.hi.shape != (3,) or not np.all(np.isfinite(self.lo) & np.isfinite(self.hi))
                or np.any(self.lo > self.hi)):
            raise ValueError(f"bounds must be two finite 3-vectors with lo <= hi, got {lo} and {hi}")

    def inside(self, position) -> bool:
        p = np.asarray(position, np.float64)
        return bool(np.all(p >= self.lo) and np.all(p <= self.hi))

    def can_move(self, start, end) -> bool:
        return self.inside(end) and self.checker.can_move(start, end)

    def is_free(self, position) -> bool:
        return self.inside(position) and self.checker.is_free(position)


def _plain(value):
    """A numpy number or array as the Python number or list JSON can write."""
    if isinstance(value, (np.generic, np.ndarray)):
        return value.tolist()
    raise TypeError(f"trajectory parameters must be JSON values or numpy numbers, got {type(value).__name__}")


class TrajectoryError(ValueError):
    """A trajectory cannot be planned or read."""


@dataclass
class Trajectory:
    """``poses`` (T, 4, 4) OpenCV world_from_camera, ``timestamps`` (T,) seconds,
    ``actions`` (T - 1,) the step that led to each pose after the first ('' if none),
    ``kind`` and ``params`` describing how it was planned."""

    poses: np.ndarray
    timestamps: np.ndarray
    kind: str
    actions: list[str] = field(default_factory=list)
    params: dict = field(default_factory=dict)

    def __post_init__(self):
        # plain JSON values (numpy numbers and arrays a caller passed as parameters become
        # Python numbers and lists), so that the header save writes always encodes
        self.params = json.loads(json.dumps(self.params, default=_plain))

    def __len__(self) -> int:
        return len(self.poses)

    @property
    def positions(self) -> np.ndarray:
        return self.poses[:, :3, 3]

    def save(self, path: str | Path) -> Path:
        """Write a .npz: poses, timestamps, actions, and a JSON header (format, kind, params)."""
        path = Path(path)
        header = json.dumps({"format": FORMAT, "kind": self.kind, "params": self.params, "units": {
            "poses": "world_from_camera 4x4, OpenCV camera axes, metres", "timestamps": "seconds"}})
        with open(path, "wb") as f:
            np.savez_compressed(f, poses=self.poses.astype(np.float64), timestamps=self.timestamps.astype(np.float64),
                                actions=np.array(self.actions, dtype=str), header=np.array(header))
        return path

    @classmethod
    def load(cls, path: str | Path) -> "Trajectory":
        path = Path(path)
        if not path.is_file():
            raise TrajectoryError(f"trajectory file not found: {path}")
        need = ("poses", "timestamps", "actions", "header")
        what = f"a .npz with arrays {', '.join(need)}, as Trajectory.save writes"
        try:
            z = load_arrays(path, need)
        except ArrayFileError as exc:
            raise TrajectoryError(f"not a trajectory file: {exc}; give {what}") from None
        if not isinstance(z, dict):  # a .npy array
            raise TrajectoryError(f"not a trajectory file: {path} holds one array; give {what}")
        missing = [k for k in need if k not in z]
        if missing:
            raise TrajectoryError(f"not a trajectory file: {path} has no {', '.join(missing)}; give {what}")
        try:
            header = json.loads(str(z["header"]))
        except (ValueError, RecursionError) as exc:
            raise TrajectoryError(f"not a trajectory file ({exc.__class__.__name__}): {path}; give {what}") from None
        poses, times, actions = z["poses"], z["timestamps"], z["actions"]
        if actions.ndim != 1:
            raise TrajectoryError(f"inconsistent trajectory arrays in {path}: actions must be (T - 1,) strings, got "
                                  f"shape {actions.shape}")
        if not isinstance(header, dict) or not isinstance(header.get("kind"), str):
            raise TrajectoryError(f"not a trajectory file: the header of {path} is not a JSON object with format and kind")
        if header.get("format") != FORMAT:
            raise TrajectoryError(f"unsupported trajectory format {header.get('format')!r} in {path}")
        if poses.ndim != 3 or poses.shape[1:] != (4, 4):
            raise TrajectoryError(f"inconsistent trajectory arrays in {path}: poses must be (T, 4, 4), got "
                                  f"{poses.shape}")
        if times.shape != (len(poses),):
            raise TrajectoryError(f"inconsistent trajectory arrays in {path}: {len(poses)} poses but timestamps of "
                                  f"shape {times.shape}")
        return cls(poses, times, header["kind"], [str(a) for a in actions], header.get("params", {}))


# how numpy, zipfile and zlib fail on a damaged .npy/.npz: an empty file raises EOFError, a
# truncated archive zipfile.BadZipFile, a damaged member zlib.error or BadZipFile (CRC), an
# encrypted member or an unknown compression RuntimeError (NotImplementedError), a bad header
# or pickled data ValueError
ARRAY_FILE_ERRORS = (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error, RuntimeError)


class ArrayFileError(ValueError):
    """An .npy/.npz file that numpy cannot decode (one line: the file and why)."""


def load_arrays(path: str | Path, keys: tuple[str, ...] | None = None) -> np.ndarray | dict[str, np.ndarray]:
    """The array of an .npy file, or {name: array} of an .npz's members (only those named in
    ``keys`` when given), all read now (no pickles), so that any decode failure, whichever
    library raises it, is one :class:`ArrayFileError` naming the file. The one reader of the
    NPY/NPZ files a user gives (trajectories, and every input of ``python -m evaluation``)."""
    try:
        loaded = np.load(path, allow_pickle=False)
        if not isinstance(loaded, np.lib.npyio.NpzFile):
            return loaded
        with loaded as z:
            arrays = {k: z[k] for k in z.files if keys is None or k in keys}
    except ARRAY_FILE_ERRORS as exc:
        why = str(exc).splitlines()[0][:200] if str(exc) else ""
        raise ArrayFileError(f"{path}: not a readable NPY/NPZ file ({exc.__class__.__name__}: {why})") from None
    for k, v in arrays.items():
        if not isinstance(v, np.ndarray):  # a member not written by numpy.save: numpy returns its bytes
            raise ArrayFileError(f"{path}: member {k!r} is not a NumPy array (write the file with numpy.savez)")
    return arrays


def timestamps(n: int, fps: float) -> np.ndarray:
    return np.arange(n, dtype=np.float64) / float(fps)
