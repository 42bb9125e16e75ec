"""Exploration scoring: which ground-truth surface points a sequence of camera poses
observes, recomputed from ``ground_truth/scene.h5`` with the simulator's visibility rules
(``generator.geometry.visibility``), with no bpy.

coverage(t) = share of the scene's surface points observed at least once by poses 0..t
(also over the points marked observable, when the ground truth has the mask);
AUC = trapezoid of coverage over an x-axis normalised to [0, 1] across all poses (the
initial pose included).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from exporters.ground_truth import GroundTruthScene
from generator.geometry.surface_points import SurfacePoints

from .inputs import InputError, check_poses, check_timestamps, regular_file


@dataclass
class Poses:
    """``world_from_camera`` (T, 4, 4) OpenCV poses; ``frames`` (T,) animation frame of each
    pose (None: the first frame); camera ``K``/``width``/``height``/``lens`` (None: the
    generator's)."""

    world_from_camera: np.ndarray
    frames: np.ndarray | None = None
    K: np.ndarray | None = None
    width: int | None = None
    height: int | None = None
    source: str = ""
    lens: object = None

    def __post_init__(self):
        """Refuse poses, frames or a camera that would score silently wrong (InputError)."""
        self.world_from_camera = check_poses(self.world_from_camera, self.source or "poses")
        if self.frames is not None:
            f = np.asarray(self.frames)
            if f.shape != (len(self.world_from_camera),) or f.dtype.kind not in "iu":
                raise InputError(f"{self.source or 'poses'}: frames must be one integer per pose, got {f.dtype} {f.shape}")
        if self.K is not None:
            K = np.asarray(self.K, np.float64)
            if (K.shape != (3, 3) or not np.isfinite(K).all() or K[0, 0] <= 0 or K[1, 1] <= 0
                    or not (self.width and self.height and 0 < self.width <= 65536 and 0 < self.height <= 65536)):
                raise InputError(f"{self.source or 'poses'}: the camera needs K (3, 3) with positive focal lengths "
                                 "and a width and height in pixels")


def coverage_auc(coverage: np.ndarray) -> float:
    """Trapezoid of the coverage curve over x in [0, 1] (a single pose: 0, as the paper's
    ``np.trapz(coverages, np.linspace(0, 1, len(coverages)))``)."""
    c = np.asarray(coverage, np.float64)
    return float(np.trapezoid(c, np.linspace(0.0, 1.0, len(c))))


class CoverageScorer:
    """Visibility of a scene's surface points from arbitrary poses, built once per scene."""

    def __init__(self, scene: GroundTruthScene):
        from generator.geometry.raycast import SceneGeometry  # open3d: loaded only when coverage is scored

        self.scene = scene
        self.geometry = SceneGeometry(scene.parts)
        s = scene.surface
        self.points = SurfacePoints.from_arrays(self.geometry.parts, s["local"], s["local_normals"], s["part"], s["label"])
        self._frame = None

    def set_frame(self, frame: int) -> None:
        """Move dynamic parts (and their points) to animation ``frame``."""
        if frame == self._frame:
            return
        self.geometry.set_matrices(self.scene.matrices_at(frame))
        self.points.update(self.geometry.parts)
        self._frame = frame

    def visible(self, world_from_camera: np.ndarray, K: np.ndarray, width: int, height: int,
                frame: int | None = None, lens=None) -> np.ndarray:
        """(N,) bool: surface points visible from one pose at ``frame`` (default: the first),
        through ``lens`` (default: the ground truth's camera's)."""
        from generator.geometry.visibility import ViewLimits, visible_points

        self.set_frame(int(self.scene.frames[0]) if frame is None else int(frame))
        pts = self.points
        return visible_points(self.geometry, pts.world, pts.world_normals, pts.part,
                              np.asarray(world_from_camera, np.float64), np.asarray(K, np.float64), int(width),
                              int(height), ViewLimits(self.scene.near, self.scene.far),
                              lens=self.scene.lens if lens is None else lens)

    @property
    def observable(self) -> np.ndarray | None:
        """(N,) bool mask of the observable surface points, None if the ground truth has none."""
        obs = self.scene.surface.get("observable")
        return None if obs is None else np.asarray(obs, bool)

    def curve(self, poses: Poses, progress=None) -> tuple[np.ndarray, np.ndarray]:
        """Coverage after each pose (T,) and the observed mask (N,)."""
        out, _, observed = self.curves(poses, progress)
        return out, observed

    def curves(self, poses: Poses, progress=None) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        """Coverage after each pose (T,) over all surface points and over the observable ones
        (None without a mask), and the observed mask (N,)."""
        K = self.scene.K if poses.K is None else poses.K
        w = self.scene.width if poses.width is None else poses.width
        h = self.scene.height if poses.height is None else poses.height
        lens = self.scene.lens if poses.lens is None else poses.lens
        observed = np.zeros(len(self.points), bool)
        obs = self.observable
        out = np.empty(len(poses.world_from_camera))
        out_obs = None if obs is None else np.empty(len(out))
        n_obs = 0 if obs is None else int(obs.sum())
        it = range(len(out)) if progress is None else progress(range(len(out)))
        for t in it:
            frame = None if poses.frames is None else int(poses.frames[t])
            observed |= self.visible(poses.world_from_camera[t], K, w, h, frame, lens)
            out[t] = observed.mean() if len(observed) else 0.0
            if out_obs is not None:
                out_obs[t] = np.count_nonzero(observed & obs) / n_obs if n_obs else 0.0
        return out, out_obs, observed


def read_poses(path: str | Path, scene: GroundTruthScene, frames: str = "auto") -> Poses:
    """Poses from a trajectory .npz written by the generator (``trajectories.Trajectory``) or
    a COLMAP model folder (binary or text; images in name order, PINHOLE-like camera).
    ``frames``: 'auto' (from the timestamps when there are any, else the first frame),
    'timestamps' or 'first'."""
    path = Path(path)
    if frames not in ("auto", "timestamps", "first"):
        raise InputError(f"--frames must be auto, timestamps or first, got {frames!r}")
    if path.is_dir():
        return _read_colmap(path, frames)
    if not path.exists():
        raise InputError(f"{path}: no such file or folder")
    regular_file(path, "trajectory .npz")  # not a pipe or a device (reading one could block)
    from trajectories.base import Trajectory, TrajectoryError

    try:
        traj = Trajectory.load(path)
    except TrajectoryError as exc:
        raise InputError(f"{exc}; give a trajectory .npz written by the generator or a COLMAP model folder") from None
    poses = check_poses(traj.poses, str(path))
    f = None
    if frames in ("auto", "timestamps"):
        f = int(scene.frames[0]) + np.round(check_timestamps(traj.timestamps, len(poses), str(path)) * scene.fps).astype(np.int64)
    return Poses(poses, f, source=str(path))


def _read_colmap(folder: Path, frames: str) -> Poses:
    from exporters.colmap import ColmapError, read_colmap_model

    if frames == "timestamps":
        raise InputError(f"{folder}: a COLMAP model has no timestamps; use --frames first")
    try:
        model = read_colmap_model(folder)
    except ColmapError as exc:
        raise InputError(str(exc)) from None
    return Poses(model.world_from_camera, None, model.K, model.width, model.height, str(folder), model.lens)
