"""Trajectories: camera poses plus timestamps, and the interface planners ask about space."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np

from .arrays import ArrayFileError, Declared, load_arrays

FORMAT = "buildee-trajectory-1"
MAX_POSES = 1_000_000  # poses a trajectory file may declare (128 MB of float64 matrices)
MAX_HEADER_BYTES = 16 << 20


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
            z = load_arrays(path, need, check=lambda declared: _check_rows(declared, path))
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


def _check_rows(declared: Declared | dict[str, Declared], path: Path) -> None:
    """Refuse, before reading, a trajectory file declaring more than MAX_POSES poses (or
    timestamps, actions) or a header over MAX_HEADER_BYTES."""
    for name, d in (declared.items() if isinstance(declared, dict) else ()):
        if d.rows > MAX_POSES or (name == "header" and d.nbytes > MAX_HEADER_BYTES):
            raise ArrayFileError(f"{path}: member {name!r} declares {d.dtype} {d.shape}; a trajectory holds at most "
                                 f"{MAX_POSES:,} poses and a header of {MAX_HEADER_BYTES >> 20} MiB")


def timestamps(n: int, fps: float) -> np.ndarray:
    return np.arange(n, dtype=np.float64) / float(fps)
