"""What a batch run does for each seed (bpy-free; stored in every seed's manifest)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from trajectories import KINDS  # noqa: F401  (the valid --trajectory values)

from ..checks import check_integer, check_number
from ..render_settings import check_side

# Bounds on what a run accepts, checked before any work (docs/guarantees.md).
MAX_PIXELS = 3840 * 2160  # 4K UHD: a render peaks at ~920 bytes a pixel (measured), ~7.6 GB here
MAX_FRAMES = 10_000  # per trajectory; the site's animation set-up grows faster than linearly past this
MAX_SCORING_POINTS = 25_000_000  # ground-truth cloud: ~220 bytes a point at peak (measured), ~5.5 GB
MAX_PHASES = 16  # stages of a timeline (generator.scene.timeline.MAX_STAGES)
MAX_SURFACE_POINTS = 5_000_000  # simulator points, tracked and projected every frame
MIN_POINTS = 100  # fewest surface or scoring points a site of the preset may get from the densities


IMPLIED_CONFIG = {"phases": 1}  # config keys a manifest leaves out when they hold these values


@dataclass(frozen=True)
class RunConfig:
    """scene_preset: site preset; render_preset: render quality; resolution: (W, H) pixels;
    frames: frames per trajectory (scene animation at 10 fps); trajectories: kinds to fly;
    points_density: surface points per square metre; max_depth: visibility limit in metres
    (planar depth); scoring_density: points per square metre of the ground-truth cloud
    (ground_truth/points.ply); colmap_text: also write the COLMAP model as text; device: Cycles
    device, 'cpu', 'gpu' or 'auto' (the manifest's summary names the one used)."""

    scene_preset: str = "medium"
    render_preset: str = "preview"
    resolution: tuple[int, int] = (640, 480)
    frames: int = 40
    trajectories: tuple[str, ...] = ("orbit", "spline")
    points_density: float = 2.0
    max_depth: float = 60.0
    scoring_density: float = 100.0
    colmap_text: bool = False
    device: str = "auto"
    outputs: tuple[str, ...] = ()  # per-frame modalities to write (exporters/modalities.py); () = all
    phases: int = 1  # stages of the site's timeline, each in phase_K/ (generator/batch/phases.py, docs/phases.md)

    def validated(self) -> "RunConfig":
        """Self, or ValueError naming the first value outside what a run can honour."""
        w, h = self.resolution
        for side, v in (("width", w), ("height", h)):
            check_side(f"resolution {side}", v)
        if w * h > MAX_PIXELS:
            raise ValueError(f"resolution {w}x{h} is {w * h:,} pixels a frame; the limit is {MAX_PIXELS:,} (3840x2160)")
        check_integer("frames", self.frames, 2, MAX_FRAMES)
        check_integer("phases", self.phases, 1, MAX_PHASES)
        if self.phases > 1 and self.outputs and not {"depth", "instance"} <= set(self.outputs):
            raise ValueError("--phases needs the outputs depth and instance (the change masks are made from them); "
                             "add them to --outputs")
        if self.outputs:
            from exporters.modalities import resolve

            resolve(self.outputs)  # ValueError naming an unknown output
        twice = sorted({k for k in self.trajectories if list(self.trajectories).count(k) > 1})
        if twice:
            raise ValueError(f"--trajectory {twice[0]} is given twice; each kind is flown once per seed")
        area = site_area_lower_bound(self.scene_preset)
        for name, density, limit in (("points-density", self.points_density, MAX_SURFACE_POINTS),
                                     ("scoring-density", self.scoring_density, MAX_SCORING_POINTS)):
            check_number(f"--{name}", density, 0, open_low=True)
            if density * area < MIN_POINTS:
                raise ValueError(f"--{name} {density:g}: a {self.scene_preset} site may have only {area:,.0f} m^2 of "
                                 f"surface, so under {MIN_POINTS} points; give at least {MIN_POINTS / area:g}")
            if density * area > limit:
                raise ValueError(f"--{name} {density:g}: a {self.scene_preset} site has more than {area:,.0f} m^2 of "
                                 f"surface, so over {density * area:,.0f} points; the limit is {limit:,}")
        return self

    def to_dict(self) -> dict:
        """The config stored in every seed's manifest (its outputs in table order: canonical_config)."""
        d = asdict(self)
        d["resolution"], d["trajectories"] = list(self.resolution), list(self.trajectories)
        d["outputs"] = list(self.outputs)
        for key, value in IMPLIED_CONFIG.items():  # a one-stage run's config reads as before timelines existed
            if d[key] == value:
                del d[key]
        return canonical_config(d)

    @classmethod
    def from_dict(cls, d: dict) -> "RunConfig":
        return cls(**(d | {"resolution": tuple(d["resolution"]), "trajectories": tuple(d["trajectories"]),
                           "outputs": tuple(d.get("outputs", ()))}))


def canonical_config(config: dict) -> dict:
    """``config`` (RunConfig.to_dict(), or a manifest's config) with its outputs in the order of
    the modality table, the order they are written in whatever order --outputs names them
    (runs before 2026-11-24 stored them as given; they compare equal now); outputs naming
    anything not in the table are left as they are."""
    from exporters.modalities import MODALITIES

    outputs, table = config.get("outputs"), list(MODALITIES)
    if not isinstance(outputs, list) or not all(isinstance(n, str) and n in MODALITIES for n in outputs):
        return config
    return config | {"outputs": sorted(outputs, key=table.index)}


def site_area_lower_bound(preset: str) -> float:
    """Square metres of surface a site of ``preset`` has at least (its ground alone)."""
    from ..scene.site import PRESETS

    size = PRESETS[preset].size
    return size * size  # not ** 2: Python's power is the C library's pow, picked by CPU


def check_point_budget(cfg: RunConfig, surface_points: int) -> None:
    """After the site is built, before rendering: ValueError if the site has more than
    MAX_SURFACE_POINTS simulator points (``surface_points``, at ``cfg.points_density`` per
    m^2), or if ``cfg.scoring_density`` would make a ground-truth cloud over
    MAX_SCORING_POINTS (the site's surface area estimated from its simulator points)."""
    if surface_points > MAX_SURFACE_POINTS:
        raise ValueError(f"--points-density {cfg.points_density:g} on this site gives {surface_points:,} simulator "
                         f"points; the limit is {MAX_SURFACE_POINTS:,}: lower it, e.g. to "
                         f"{0.99 * cfg.points_density * MAX_SURFACE_POINTS / surface_points:.3g}")
    area = surface_points / cfg.points_density
    estimate = cfg.scoring_density * area
    if estimate > MAX_SCORING_POINTS:
        raise ValueError(f"--scoring-density {cfg.scoring_density:g} on this site (about {area:,.0f} m^2 of surface) "
                         f"gives about {estimate:,.0f} points; the limit is {MAX_SCORING_POINTS:,}: lower it, e.g. to "
                         f"{0.99 * cfg.scoring_density * MAX_SCORING_POINTS / estimate:.3g}")


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


def plan_trajectories(sim, kinds, start: np.ndarray, seed: int, frames: int, fps: float) -> list:
    """[(kind, trajectory)] for each of ``kinds`` on the Simulator ``sim``, all planned before
    any frame is rendered (a trajectory that cannot be planned fails in seconds, not after the
    ones before it were rendered).

    Collisions with dynamic objects are checked where the animation stands: the first kind
    at the Simulator's current frame, each later one at frame ``frames``, where flying the
    trajectory before it leaves the Simulator. That is what planning each one right before
    it was flown did (until 2026-11-23), kept so the outputs are unchanged. ``sim`` is put
    back at its frame."""
    first, planned = sim.frame, []
    try:
        for k, kind in enumerate(kinds):
            if k == 1:
                sim.set_frame(frames)
            planned.append((kind, plan_trajectory(kind, sim, sim.spawn_points, start, seed, frames, fps)))
    finally:
        if sim.frame != first:
            sim.set_frame(first)
    return planned
