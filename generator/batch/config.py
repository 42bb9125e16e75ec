"""What a batch run does for each seed (bpy-free; stored in every seed's manifest)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields

import numpy as np

from ..checks import check_integer, check_number
from ..geometry.camera import site_intrinsics
from ..geometry.lens import Lens, lens_of
from ..image_sensor import ImageSensor, image_sensor_of
from ..render_settings import check_side
from ..scene.building_types import check_building_type
from ..scene.contexts import check_context
from ..scene.catalogue.ground import check_surface
from ..scene.weather import check_season, check_weather

# Bounds on what a run accepts, checked before any work (docs/guarantees.md).
MAX_PIXELS = 3840 * 2160  # 4K UHD: a render peaks at ~920 bytes a pixel (measured), ~7.6 GB here
MAX_FRAMES = 10_000  # per trajectory; the site's animation set-up grows faster than linearly past this
MAX_SCORING_POINTS = 25_000_000  # ground-truth cloud: ~220 bytes a point at peak (measured), ~5.5 GB
MAX_PHASES = 16  # stages of a timeline (generator.scene.timeline.MAX_STAGES)
MAX_SURFACE_POINTS = 5_000_000  # simulator points, tracked and projected every frame
MIN_POINTS = 100  # fewest surface or scoring points a site of the preset may get from the densities


IMPLIED_CONFIG = {"phases": 1, "weather": None, "ground": None, "building_type": None, "context": None, "season": None,
                  "camera_model": "pinhole", "distortion": [], "exposure": "as-rendered", "sensor_noise": [],
                  "jpeg_quality": None, "shutter_s": 0.0, "stereo_baseline_m": 0.0, "rig": None, "readout_s": 0.0}  # config keys a manifest leaves out when they hold these values


@dataclass(frozen=True)
class RunConfig:
    """scene_preset: site preset; render_preset: render quality; resolution: (W, H) pixels;
    frames: frames per trajectory (scene animation at 10 fps); trajectories: kinds to fly;
    points_density: surface points per square metre; max_depth: visibility limit in metres
    (planar depth); scoring_density: points per square metre of the ground-truth cloud
    (ground_truth/points.ply); device: Cycles device, 'cpu', 'gpu' or 'auto' (the manifest's
    summary names the one used); exports: the values of the exports' own options, by name
    (exporters/sinks.py: e.g. {"colmap_text": True}, --colmap-text); an option left out holds its
    default. In a manifest's config the export options sit beside the other keys."""

    scene_preset: str = "medium"
    render_preset: str = "preview"
    resolution: tuple[int, int] = (640, 480)
    frames: int = 40
    trajectories: tuple[str, ...] = ("orbit", "spline")
    points_density: float = 2.0
    max_depth: float = 60.0
    scoring_density: float = 100.0
    device: str = "auto"
    outputs: tuple[str, ...] = ()  # per-frame modalities to write (exporters/modalities.py); () = all
    phases: int = 1  # stages of the site's timeline, each in phase_K/ (generator/batch/phases.py, docs/phases.md)
    exports: dict = field(default_factory=dict)  # export option name -> value (export_values)
    weather: str | None = None  # every seed's weather (generator/scene/weather.py); None: drawn per seed
    ground: str | None = None  # every seed's ground surface (generator/scene/catalogue/ground.py); None: drawn per seed
    building_type: str | None = None  # every building's type (generator/scene/building_types/); None: drawn per building
    context: str | None = None  # every seed's context (generator/scene/contexts.py); None: drawn per seed
    season: str | None = None  # every seed's season (generator/scene/weather.py); None: drawn per seed
    camera_model: str = "pinhole"  # the cameras' lens model (generator/geometry/lens.py): pinhole, opencv, fisheye
    distortion: tuple[float, ...] = ()  # its coefficients, OpenCV's order (opencv: k1 k2 p1 p2 k3; fisheye: k1-k4)
    # the image sensor (generator/image_sensor.py): exposure "as-rendered", "auto" or stops; noise
    # (full well electrons, read noise electrons) or (); JPEG quality 1-100 or None
    exposure: str | float = "as-rendered"
    sensor_noise: tuple[float, ...] = ()
    jpeg_quality: int | None = None
    shutter_s: float = 0.0  # motion blur: the shutter's time in seconds, centred on each frame (0: none)
    readout_s: float = 0.0  # --rolling-shutter: seconds from the first row's time to the last's (0: a global shutter)
    stereo_baseline_m: float = 0.0  # --stereo: a right camera this far right of each trajectory's (0: none)
    rig: dict | None = None  # --rig: the rig file's document (generator/batch/rig.py); None: no rig

    def camera_rig(self):
        """The cameras flown with each trajectory's own (``--stereo`` or ``--rig``:
        generator/batch/rig.py ``Rig``), None for none (ValueError in one line for a bad rig)."""
        from .rig import rig_of

        return rig_of(self.stereo_baseline_m, self.rig)

    def image_sensor(self) -> ImageSensor:
        """The cameras' image sensor (ValueError in one line for values it cannot have)."""
        return image_sensor_of(self.exposure, self.sensor_noise, self.jpeg_quality)

    def lens(self) -> Lens:
        """The cameras' lens model (ValueError in one line for a model or coefficients it cannot be)."""
        return lens_of(self.camera_model, self.distortion)

    def site_overrides(self) -> dict:
        """The site parameters this run sets for every seed (given to build_site)."""
        return {"weather": self.weather, "ground": self.ground, "building_type": self.building_type,
                "context": self.context, "season": self.season}

    def validated(self) -> "RunConfig":
        """Self, or ValueError naming the first value outside what a run can honour."""
        w, h = self.resolution
        for side, v in (("width", w), ("height", h)):
            check_side(f"resolution {side}", v)
        if w * h > MAX_PIXELS:
            raise ValueError(f"resolution {w}x{h} is {w * h:,} pixels a frame; the limit is {MAX_PIXELS:,} (3840x2160)")
        check_integer("frames", self.frames, 2, MAX_FRAMES)
        check_integer("phases", self.phases, 1, MAX_PHASES)
        check_weather(self.weather)
        check_surface(self.ground)
        check_building_type(self.building_type)
        check_context(self.context)
        check_season(self.season)
        self.image_sensor()
        check_number("--shutter", self.shutter_s, 0.0, 0.1)  # one frame interval at the sites' 10 fps
        check_number("--rolling-shutter", self.readout_s, 0.0, 0.1)
        if self.readout_s > 0 and (self.rig is not None or self.stereo_baseline_m > 0):
            raise ValueError("--rolling-shutter flies one camera per trajectory (a rig's joint COLMAP model has one "
                             "pose per frame): leave out " + ("--rig" if self.rig is not None else "--stereo"))
        check_number("--stereo", self.stereo_baseline_m, 0.0, 1.0)
        if self.stereo_baseline_m > 0 and (self.camera_model != "pinhole" or self.phases > 1):
            raise ValueError("--stereo makes a rectified pinhole pair of a one-stage run: leave out "
                             + ("--camera-model" if self.camera_model != "pinhole" else "--phases"))
        if self.rig is not None and (self.stereo_baseline_m > 0 or self.phases > 1):
            raise ValueError("--rig flies its cameras in a one-stage run, without --stereo (a stereo pair is a rig "
                             "camera named right): leave out " + ("--stereo" if self.stereo_baseline_m > 0 else "--phases"))
        self.camera_rig()
        lens = self.lens()
        lens.check(site_intrinsics(w, h).K, w, h)  # one-to-one over the image of the sites' camera
        if self.phases > 1 and self.outputs and not {"depth", "instance"} <= set(self.outputs):
            raise ValueError("--phases needs the outputs depth and instance (the change masks are made from them); "
                             "add them to --outputs")
        if self.outputs:
            from exporters.modalities import resolve

            resolve(self.outputs)  # ValueError naming an unknown output
        twice = sorted({k for k in self.trajectories if list(self.trajectories).count(k) > 1})
        if twice:
            raise ValueError(f"--trajectory {twice[0]} is given twice; each kind is flown once per seed")
        from trajectories import TRAJECTORY_KINDS

        for kind in self.trajectories:
            TRAJECTORY_KINDS.get(kind)  # ValueError naming the kinds there are
        check_export_values(export_values(self.exports))
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
        d["distortion"] = list(self.distortion)
        d["sensor_noise"] = list(self.sensor_noise)
        d |= export_values(d.pop("exports"))
        for key, value in IMPLIED_CONFIG.items():  # a one-stage run's config reads as before timelines existed
            if d[key] == value:
                del d[key]
        return canonical_config(d)

    @classmethod
    def from_dict(cls, d: dict) -> "RunConfig":
        """The RunConfig of ``to_dict()``: keys that are not fields are export options."""
        own = {f.name for f in fields(cls)} - {"exports"}
        return cls(**({k: v for k, v in d.items() if k in own} | {
            "resolution": tuple(d["resolution"]), "trajectories": tuple(d["trajectories"]),
            "outputs": tuple(d.get("outputs", ())), "distortion": tuple(d.get("distortion", ())),
            "sensor_noise": tuple(d.get("sensor_noise", ())), "exports": {k: v for k, v in d.items() if k not in own}}))


def export_values(given: dict) -> dict:
    """Every export option's value (exporters/sinks.py: each export declares its own options,
    and they are parameters of the run): ``given``'s, and the others' defaults. ValueError
    naming an unknown option, or an export option named like a parameter of RunConfig."""
    from exporters.sinks import export_options

    options = {o.dest: o for o in export_options()}
    shadowed = sorted(set(options) & {f.name for f in fields(RunConfig)})
    if shadowed:
        raise ValueError(f"the export option {options[shadowed[0]].flag} has the name of a run parameter "
                         f"({shadowed[0]}): rename the option")
    unknown = sorted(set(given) - set(options))
    if unknown:
        raise ValueError(f"unknown export option {unknown[0]!r}; the exports' options are: "
                         f"{', '.join(sorted(options)) or 'none'}")
    return {dest: given.get(dest, option.default) for dest, option in options.items()}


def check_export_values(values: dict) -> None:
    """ValueError if an on/off export option (``action="store_true"``) holds anything but a
    bool, or a repeatable one (``action="append"``) anything but None or a list of values its
    ``type`` accepts."""
    import argparse

    from exporters.sinks import export_options

    for option in export_options():
        value = values[option.dest]
        if option.action in ("store_true", "store_false") and not isinstance(value, bool):
            raise ValueError(f"{option.flag} ({option.dest}) must be True or False, got {value!r}")
        if option.action == "append" and value is not None:
            if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
                raise ValueError(f"{option.flag} ({option.dest}) must be a list of names, got {value!r}")
            for v in value:
                try:
                    option.type(v) if option.type else v
                except argparse.ArgumentTypeError as exc:
                    raise ValueError(f"{option.flag} ({option.dest}): {exc}") from None


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


def run_timing(t0: float, executor: str) -> dict:
    """A manifest's timing: wall-clock seconds since ``t0`` (time.perf_counter) and, when
    known, the name of the executor that ran the seed (neither is a parameter of the seed:
    both may differ between runs that make the same files)."""
    import time

    return {"seconds": time.perf_counter() - t0} | ({"executor": executor} if executor else {})


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
    """A trajectory of ``kind`` over a site whose flyable space is given by its spawn points,
    fitted as the kind's registration says (trajectories/: ``@register_kind``), with the
    seed's random stream of that kind."""
    from trajectories import FlightSite, fit_kind

    from ..geometry.seeding import stream

    site = FlightSite(checker, spawn_points.min(axis=0), spawn_points.max(axis=0), start,
                      stream(seed, "trajectory", kind), frames, fps)
    return fit_kind(kind, site)


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
