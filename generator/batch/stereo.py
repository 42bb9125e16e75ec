"""A stereo pair (``--stereo B``): each trajectory flown by a second camera B metres to the
right of the first (bpy-free; docs/cameras.md, "Stereo pairs").

The right camera of frame t is the left one's pose moved B metres along its own x axis
(OpenCV: right): ``right = left @ [I | (B, 0, 0)]``, same K, same timestamps, same frames of
the site's animation, no distortion. The pair is rectified by construction: a surface point
at planar depth Z seen at (x, y) by the left camera is seen at (x - fx B / Z, y) by the right
one; its disparity is fx B / Z pixels. The right camera flies in ``<kind>_right/`` with every
output of a trajectory (tracks of the same point ids, COLMAP, nerfstudio...).
"""

from __future__ import annotations

import numpy as np

from trajectories import Trajectory

from ..geometry.camera import matmul_exact

RIGHT = "_right"  # the right camera's folder: the trajectory's kind and this


def right_camera(traj: Trajectory, baseline_m: float, left: str) -> Trajectory:
    """The right camera of ``traj`` (flown as ``left``), ``baseline_m`` metres to its right."""
    shift = np.eye(4)
    shift[0, 3] = baseline_m
    poses = matmul_exact(np.asarray(traj.poses, np.float64), shift[None])
    return Trajectory(poses, np.asarray(traj.timestamps), traj.kind, list(traj.actions),
                      dict(traj.params) | {"stereo": {"left": left, "baseline_m": float(baseline_m)}})


def with_right_cameras(planned: list, baseline_m: float) -> list:
    """``planned`` [(kind, trajectory)] followed by each one's right camera (none for B = 0)."""
    if baseline_m <= 0:
        return list(planned)
    return list(planned) + [(kind + RIGHT, right_camera(traj, baseline_m, kind)) for kind, traj in planned]


def flown_kinds(kinds, baseline_m: float) -> list[str]:
    """The trajectory folders of a run of ``kinds`` with a baseline of ``baseline_m``."""
    kinds = [str(k) for k in kinds]
    return kinds + ([k + RIGHT for k in kinds] if baseline_m > 0 else [])
