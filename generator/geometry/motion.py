"""Rigid motion between a trajectory's frames, at any time (bpy-free): the sensor's pose and
every moving object's matrix at the instant a beam is fired (docs/lidar.md, "Motion") or a
rolling shutter reads a row (generator/geometry/rolling.py).

The trajectory knows each pose at its frames' timestamps. Between two frames a pose moves
at a constant velocity: its translation linearly, its rotation about one fixed axis at a
constant rate (spherical linear interpolation of the rotation between the two frames);
before the first frame and after the last it stays put. Every step is float64 IEEE
arithmetic with the project's portable sine, cosine and arctangent
(generator/geometry/portable_math.py), so a time gives the same bits on every CPU.

A moving object's matrix may carry a scale (a keyed scale); its rotation part is then
interpolated as the scaled matrix's rotation (the polar factor of each frame's 3x3, assumed
to share the scale of the other frame).
"""

from __future__ import annotations

import numpy as np

from .camera import matmul_exact
from .portable_math import atan2, sincos


def quaternion(rotation: np.ndarray) -> np.ndarray:
    """The unit quaternion (w, x, y, z), w >= 0, of a 3x3 rotation (Shepperd's method: the
    largest of the four squares decides the branch)."""
    r = np.asarray(rotation, dtype=np.float64)
    t = r[0, 0] + r[1, 1] + r[2, 2]
    squares = [1.0 + t, 1.0 + r[0, 0] - r[1, 1] - r[2, 2], 1.0 - r[0, 0] + r[1, 1] - r[2, 2],
               1.0 - r[0, 0] - r[1, 1] + r[2, 2]]
    k = int(np.argmax(squares))
    s = float(np.sqrt(max(squares[k], 0.0))) * 2.0  # 4 |q_k|
    if k == 0:
        q = [s / 4.0, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
    elif k == 1:
        q = [(r[2, 1] - r[1, 2]) / s, s / 4.0, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s]
    elif k == 2:
        q = [(r[0, 2] - r[2, 0]) / s, (r[0, 1] + r[1, 0]) / s, s / 4.0, (r[1, 2] + r[2, 1]) / s]
    else:
        q = [(r[1, 0] - r[0, 1]) / s, (r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, s / 4.0]
    q = np.array(q)
    q = q / float(np.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]))
    return -q if q[0] < 0 else q


def axis_angle(rotation: np.ndarray) -> tuple[np.ndarray, float]:
    """(unit axis (3,), angle in radians in [0, pi]) of a 3x3 rotation; the axis is +z for
    no rotation."""
    q = quaternion(rotation)
    v = q[1:]
    norm = float(np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]))
    if norm == 0.0:
        return np.array([0.0, 0.0, 1.0]), 0.0
    return v / norm, 2.0 * float(atan2(norm, q[0]))


def axis_rotations(axis: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """(M, 3, 3) rotations by ``angles`` (M,) radians about one unit ``axis`` (Rodrigues)."""
    s, c = sincos(np.asarray(angles, dtype=np.float64))
    s, c = np.atleast_1d(s), np.atleast_1d(c)
    x, y, z = (float(a) for a in axis)
    k = 1.0 - c
    out = np.empty((len(c), 3, 3))
    out[:, 0, 0], out[:, 0, 1], out[:, 0, 2] = c + x * x * k, x * y * k - z * s, x * z * k + y * s
    out[:, 1, 0], out[:, 1, 1], out[:, 1, 2] = y * x * k + z * s, c + y * y * k, y * z * k - x * s
    out[:, 2, 0], out[:, 2, 1], out[:, 2, 2] = z * x * k - y * s, z * y * k + x * s, c + z * z * k
    return out


def _scale(m: np.ndarray) -> np.ndarray:
    """The lengths of the columns of a 3x3 (an object's scale along its axes)."""
    return np.sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2])


class MotionTrack:
    """One rigid pose over time: ``matrices`` (T, 4, 4) at increasing ``times`` (T,) seconds;
    :meth:`at` gives the pose at any times (see the module's docstring)."""

    def __init__(self, times: np.ndarray, matrices: np.ndarray):
        self.times = np.asarray(times, dtype=np.float64)
        self.matrices = np.asarray(matrices, dtype=np.float64)
        if self.matrices.shape != (len(self.times), 4, 4) or len(self.times) == 0:
            raise ValueError(f"MotionTrack: {len(self.times)} times need ({len(self.times)}, 4, 4) matrices, "
                             f"got {self.matrices.shape}")
        if np.any(np.diff(self.times) <= 0):
            raise ValueError("MotionTrack: times must increase strictly")
        scales = np.stack([_scale(m[:3, :3]) for m in self.matrices])
        self.scales = scales
        rotations = self.matrices[:, :3, :3] / scales[:, None, :]
        self.rotations = rotations
        self.steps = [axis_angle(matmul_exact(rotations[i].T, rotations[i + 1])) for i in range(len(self.times) - 1)]
        self.still = bool(np.all(self.matrices == self.matrices[0]))

    def at(self, t) -> np.ndarray:
        """(M, 4, 4) poses at the times ``t`` (M,) seconds (clamped to the frames' span)."""
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        if self.still or len(self.times) == 1:
            return np.broadcast_to(self.matrices[0], (len(t), 4, 4)).copy()
        i = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self.times) - 2)
        t0, t1 = self.times[i], self.times[i + 1]
        u = np.clip((t - t0) / (t1 - t0), 0.0, 1.0)
        out = np.zeros((len(t), 4, 4))
        out[:, 3, 3] = 1.0
        out[:, :3, 3] = self.matrices[i, :3, 3] + u[:, None] * (self.matrices[i + 1, :3, 3] - self.matrices[i, :3, 3])
        for k in np.unique(i):
            rows = np.flatnonzero(i == k)
            axis, angle = self.steps[k]
            turn = axis_rotations(axis, u[rows] * angle)
            rot = matmul_exact(self.rotations[k][None], turn)
            scale = self.scales[k] + u[rows, None] * (self.scales[k + 1] - self.scales[k])
            out[rows, :3, :3] = rot * scale[:, None, :]
        return out

    def speed_bound(self, radius: float, start: float = -np.inf, end: float = np.inf) -> float:
        """Metres per second: no point within ``radius`` metres (in the object's own units, times
        its largest scale) of the pose's origin moves faster between two frames whose interval
        meets [``start``, ``end``] seconds (|translation step| + radius x angle step, over the
        step's time); 0 outside the frames' span (the pose stays put)."""
        if len(self.times) < 2:
            return 0.0
        dt = np.diff(self.times)
        step = np.diff(self.matrices[:, :3, 3], axis=0)
        moves = np.sqrt(step[:, 0] * step[:, 0] + step[:, 1] * step[:, 1] + step[:, 2] * step[:, 2])
        turns = np.array([angle for _, angle in self.steps])
        reach = radius * float(np.max(self.scales))
        meets = (self.times[1:] >= start) & (self.times[:-1] <= end)
        return float(np.max(((moves + reach * turns) / dt)[meets], initial=0.0))


def body_pose(world_from_camera: np.ndarray) -> np.ndarray:
    """world_from_body: the camera's centre, x along its view turned level (along the image's
    up direction when it looks straight down or up), z up, y = z x x."""
    m = np.asarray(world_from_camera, dtype=np.float64)
    forward = m[:3, 2].copy()
    if forward[0] * forward[0] + forward[1] * forward[1] < 1e-12:
        forward = -m[:3, 1]  # straight down: the top of the image is ahead
    x, y = forward[0], forward[1]
    n = float(np.sqrt(x * x + y * y))
    out = np.eye(4)
    out[:3, 0] = (x / n, y / n, 0.0)
    out[:3, 1] = (-y / n, x / n, 0.0)
    out[:3, 3] = m[:3, 3]
    return out
