"""What a batch run does for each seed (bpy-free; stored in every seed's manifest)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from trajectories import KINDS  # noqa: F401  (the valid --trajectory values)


@dataclass(frozen=True)
class RunConfig:
    """scene_preset: site preset; render_preset: render quality; resolution: (W, H) pixels;
    frames: frames per trajectory (scene animation at 10 fps); trajectories: kinds to fly;
    points_density: surface points per square metre; max_depth: visibility limit in metres
    (planar depth); scoring_density: points per square metre of the ground-truth cloud
    (ground_truth/points.ply); colmap_text: also write the COLMAP model as text."""

    scene_preset: str = "medium"
    render_preset: str = "preview"
    resolution: tuple[int, int] = (640, 480)
    frames: int = 40
    trajectories: tuple[str, ...] = ("orbit", "spline")
    points_density: float = 2.0
    max_depth: float = 60.0
    scoring_density: float = 100.0
    colmap_text: bool = False

    def to_dict(self) -> dict:
        d = asdict(self)
        d["resolution"], d["trajectories"] = list(self.resolution), list(self.trajectories)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "RunConfig":
        return cls(**(d | {"resolution": tuple(d["resolution"]), "trajectories": tuple(d["trajectories"])}))


def plan_trajectory(kind: str, checker, spawn_points: np.ndarray, start: np.ndarray, seed: int, frames: int, fps: float):
    """A trajectory of ``kind`` over a site whose flyable space is given by its spawn points."""
    from trajectories import BoundedChecker, lawnmower, modified_random_walk, orbit, random_walk, spline_flythrough

    from ..geometry.camera import levelled

    from ..geometry.seeding import stream

    lo, hi = spawn_points.min(axis=0), spawn_points.max(axis=0)
    centre = (lo + hi) / 2
    size = float(max(hi[0] - lo[0], hi[1] - lo[1]))
    rng = stream(seed, "trajectory", kind)
    if kind == "orbit":
        return orbit(checker, centre[:2], 0.45 * size, max(0.3 * size, 15.0), frames, look_at_height=2.0, fps=fps)
    if kind == "lawnmower":
        margin = 0.1 * size
        return lawnmower(checker, ((lo[0] + margin, lo[1] + margin), (hi[0] - margin, hi[1] - margin)),
                         max(0.25 * size, 15.0), frames, spacing=size / 4, fps=fps)
    if kind == "spline":
        top = min(hi[2], max(lo[2] + 5.0, 0.2 * size))
        return spline_flythrough(checker, ((lo[0], lo[1], max(lo[2], 2.0)), (hi[0], hi[1], top)), frames, rng, fps=fps)
    walk = {"random_walk": random_walk, "modified_random_walk": modified_random_walk}.get(kind)
    if walk is None:
        raise ValueError(f"unknown trajectory kind {kind!r}")
    # level camera ('forward' is horizontal), kept inside the flyable volume
    return walk(BoundedChecker(checker, lo, hi), levelled(start), frames - 1, rng, step=1.0, angle=15.0, fps=fps)
