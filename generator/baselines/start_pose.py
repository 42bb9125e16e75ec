"""The fixed start pose of the exploration baselines, derived from the site's layout.

The paper's evaluation code starts every run of a scene from the camera pose stored in its
.blend. Our sites store a high overview camera, so the start pose follows a rule instead:

1. The **gate** is the widest gap between two collinear fence runs of the site plan
   (``SitePlan.fence_runs``); its midpoint is the entrance.
2. The camera stands on the line through the entrance perpendicular to the fence, pointing
   into the site (towards the centre of the fence), at the first point of that line inside
   the camera spawn volume (``SitePlan.spawn_box``), at the volume's lowest height.
3. It looks along that line, level (zero pitch and roll).

The spawn volume is also the walls of the walks (``bounds``), as the paper's scenes bound
their cameras with a mesh. bpy-free.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry import portable_math
from ..geometry.camera import heading_pose


@dataclass(frozen=True)
class Gate:
    midpoint: np.ndarray  # (2,) world metres on the ground
    inward: np.ndarray  # (2,) unit vector, perpendicular to the fence, into the site
    width: float  # metres


def find_gate(fence_runs) -> Gate:
    """The widest gap between two collinear fence runs (start, end pairs in metres)."""
    runs = [(np.asarray(a, np.float64)[:2], np.asarray(b, np.float64)[:2]) for a, b in fence_runs]
    if not runs:
        raise ValueError("the site plan has no fence runs, so no gate to start from")
    centre = np.mean([p for run in runs for p in run], axis=0)
    best = None
    for i, (a0, a1) in enumerate(runs):
        d = (a1 - a0) / portable_math.vector_norm(a1 - a0)
        for j, (b0, b1) in enumerate(runs):
            if i == j:
                continue
            e = (b1 - b0) / portable_math.vector_norm(b1 - b0)
            gap = b0 - a1
            parallel = abs(d[0] * e[1] - d[1] * e[0]) < 1e-9 and d[0] * e[0] + d[1] * e[1] > 0
            on_line = abs(d[0] * (b0 - a0)[1] - d[1] * (b0 - a0)[0]) < 1e-6
            if parallel and on_line and gap[0] * d[0] + gap[1] * d[1] > 0 and (best is None or portable_math.vector_norm(gap) > best[0]):
                best = (portable_math.vector_norm(gap), (a1 + b0) / 2, d)
    if best is None:
        raise ValueError("the site's fence has no gap between two runs on one line, so no gate to start from")
    width, mid, d = best
    inward = np.array([-d[1], d[0]])
    if inward[0] * (centre - mid)[0] + inward[1] * (centre - mid)[1] < 0:  # dot products without BLAS
        inward = -inward
    return Gate(mid, inward, width)


def entrance_start_pose(fence_runs, spawn_box) -> np.ndarray:
    """world_from_camera (4x4, OpenCV axes) of the rule above."""
    gate = find_gate(fence_runs)
    lo, hi = (np.asarray(v, np.float64) for v in spawn_box)
    # first t >= 0 where midpoint + t * inward lies inside the box's xy slab on every axis
    t_in, t_out = 0.0, np.inf
    for k in range(2):
        m, n = gate.midpoint[k], gate.inward[k]
        if abs(n) < 1e-12:
            if not lo[k] <= m <= hi[k]:
                raise ValueError("the gate's inward line never enters the camera spawn volume")
            continue
        t0, t1 = sorted(((lo[k] - m) / n, (hi[k] - m) / n))
        t_in, t_out = max(t_in, t0), min(t_out, t1)
    if t_in > t_out:
        raise ValueError("the gate's inward line never enters the camera spawn volume")
    xy = gate.midpoint + t_in * gate.inward
    xy = np.clip(xy, lo[:2], hi[:2])  # exactly on the face, not a rounding error outside
    return heading_pose(np.array([xy[0], xy[1], lo[2]]), portable_math.atan2(gate.inward[1], gate.inward[0]), 0.0)


def site_start(plan) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """(start pose, (lo, hi) walk bounds) of a :class:`generator.scene.SitePlan`."""
    if plan.spawn_box is None:
        raise ValueError(f"site plan of seed {plan.seed} has no camera spawn volume")
    lo, hi = (np.asarray(v, np.float64) for v in plan.spawn_box)
    return entrance_start_pose(plan.fence_runs, plan.spawn_box), (lo, hi)
