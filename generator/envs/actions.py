"""Actions of the exploration environment as camera poses (bpy-free).

Discrete (the paper's five): 0 forward, 1 left, 2 right (moves of ``step`` metres along the
camera's z, -x, +x axes), 3 turn left, 4 turn right (``angle`` degrees about the world Z
axis through the camera centre; the horizon stays as it is).

Continuous: a vector of 5 numbers in [-1, 1]: ``(forward, right, up, yaw, pitch)``. The
camera first turns (yaw right by ``yaw * angle`` degrees about world Z, pitch up by
``pitch * angle`` degrees, kept within +-``MAX_PITCH_DEG``, zero roll; with yaw and pitch
both 0 the orientation is kept exactly), then moves
``forward * step`` metres along its horizontal heading, ``right * step`` metres along its
horizontal right and ``up * step`` metres along world +Z, as one straight segment.

Turns never collide. A move is refused when the straight segment collides (the
Simulator's rule) or ends outside the scene's bounds; the camera then keeps its position
(and, for a continuous action, still turns).
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry import portable_math
from ..geometry.camera import heading_pose, translated_along_axis, turned_about_world_z

DISCRETE_ACTIONS = ("forward", "left", "right", "turn_left", "turn_right")
CONTINUOUS_FIELDS = ("forward", "right", "up", "yaw", "pitch")
MAX_PITCH_DEG = 80.0


def discrete_target(pose: np.ndarray, action: int, step: float, angle: float) -> tuple[np.ndarray, bool]:
    """(pose after discrete ``action``, whether it is a move that may collide)."""
    if action == 0:
        return translated_along_axis(pose, 2, step), True
    if action in (1, 2):
        return translated_along_axis(pose, 0, step if action == 2 else -step), True
    if action in (3, 4):
        a = math.radians(angle)
        return turned_about_world_z(pose, a if action == 4 else -a), False
    raise ValueError(f"action must be an integer in 0..4 ({', '.join(DISCRETE_ACTIONS)}), got {action!r}")


def heading_and_pitch(pose: np.ndarray) -> tuple[float, float]:
    """Heading (radians from +X, counter-clockwise seen from above) and pitch (radians above
    the horizon) of the camera's optical axis. Looking straight down (up), the axis has no
    heading: it is then the direction the top (bottom) of the image points to, where the
    camera heads when it tilts up (down) from there."""
    m = np.asarray(pose, dtype=np.float64)
    f = m[:3, 2]
    # portable_math: the same bits on every CPU; atan2(z, |xy|) is asin(z) of a unit axis
    horizontal = portable_math.hypot(f[0], f[1])
    pitch = portable_math.atan2(f[2], horizontal)
    if horizontal == 0.0:
        up = -m[:3, 1] if f[2] < 0 else m[:3, 1]  # camera y points down the image
        return portable_math.atan2(up[1], up[0]), pitch
    return portable_math.atan2(f[1], f[0]), pitch


def real_action(action) -> np.ndarray:
    """``action`` as 5 finite float64 numbers; anything else (another count, NaN or infinity,
    and values whose conversion would drop or invent information: complex numbers, booleans,
    strings, bytes, dates, Python objects) is a one-line ValueError."""
    try:
        raw = np.asarray(action)
    except (ValueError, TypeError):
        raw = None
    if raw is None or raw.dtype.kind not in "iuf":
        kind = "a ragged sequence" if raw is None else f"dtype {raw.dtype}"
        raise ValueError(f"a continuous action is 5 finite real numbers {CONTINUOUS_FIELDS} (integers or floats), "
                         f"got {kind}: {_short(action)}")
    a = raw.astype(np.float64).reshape(-1)
    if a.shape != (5,) or not np.all(np.isfinite(a)):
        raise ValueError(f"a continuous action is 5 finite numbers {CONTINUOUS_FIELDS}, got {_short(action)}")
    return a


def _short(value) -> str:
    """``repr(value)`` on one line, at most 200 characters."""
    text = " ".join(repr(value).split())
    return text if len(text) <= 200 else text[:197] + "..."


def continuous_targets(pose: np.ndarray, action: np.ndarray, step: float, angle: float) -> tuple[np.ndarray, np.ndarray]:
    """(turned pose, turned and moved pose) of a continuous action (see the module docstring)."""
    a = np.clip(real_action(action), -1.0, 1.0)
    pose = np.asarray(pose, dtype=np.float64)
    yaw, pitch = heading_and_pitch(pose)
    if a[3] == 0 and a[4] == 0:
        turned = pose.copy()  # no turn: the orientation is kept exactly (roll included)
    else:
        yaw -= math.radians(a[3] * angle)  # positive yaw turns right (clockwise seen from above)
        limit = math.radians(MAX_PITCH_DEG)
        pitch = float(np.clip(pitch + math.radians(a[4] * angle), -limit, limit))
        turned = heading_pose(pose[:3, 3], yaw, pitch)
    sin_yaw, cos_yaw = portable_math.sincos(yaw)
    forward = np.array([cos_yaw, sin_yaw, 0.0])
    right = np.array([sin_yaw, -cos_yaw, 0.0])
    moved = turned.copy()
    moved[:3, 3] += step * (a[0] * forward + a[1] * right + a[2] * np.array([0.0, 0.0, 1.0]))
    return turned, moved
