"""Plan a construction site from a seed and parameters (bpy-free, deterministic).

The plan lays out a square site (a road loop that the trucks drive, a gate on the south
side) and then asks every kind of the asset catalogue (:mod:`.kinds`) to place itself, in
the kinds' order: the fence along the boundary, buildings with a tower crane each in the
middle, excavators, trucks, and props (containers, cabins, material stacks and piles, safety
equipment, people) arranged in a grid, scattered or clustered. Footprints never overlap.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from ..checks import check_integer, check_number
from ..geometry.portable_math import sincos
from ..geometry.seeding import stream
from .assets import Footprint
from .building_types import check_building_type
from .contexts import Context, check_context, choose_context
from .catalogue.fence import fence_part  # noqa: F401  (generator.blender.build builds the fence from here)
from .catalogue.ground import GROUND_MARGIN, GroundSurface, check_surface, choose_ground, ground_part, split_margin, wet_materials  # noqa: F401  (and the ground)
from .kinds import all_kinds, kind as kind_named
from .placement import PlacedAsset, Placer, SiteArea  # noqa: F401  (PlacedAsset: the plan's entries)
from .planning import SiteState
from .relief import Relief, plan_terrain
from .timeline import advance, check_stage
from .weather import Weather, check_season, check_weather, choose_weather

LAYOUTS = ("grid", "scattered", "clustered")
GATE = (-4.0, 4.0)  # x range of the gate in the south fence, metres
ROAD_CORNER_M = 8.0  # corner radius of the road loop's centre line (at most half its half-side)
MAX_COUNT = 1000  # most assets of one kind a site may ask for


@dataclass(frozen=True)
class SiteParams:
    """Parameters of a site. Lengths in metres, time in frames at ``fps``.

    size: side of the square site; density: multiplier of the number of props (1 = typical);
    layout: 'grid', 'scattered' or 'clustered' arrangement of props; phase: share of the
    planned floors built, in [0, 1] (None: drawn per building in [0.25, 1]); frames and fps:
    animation length and rate. buildings, trucks, excavators: (fewest, most) of each; counts:
    the same for the catalogue's other counted kinds, ((kind, (fewest, most)), ...) sorted by
    kind (a kind absent has none; the presets take them from the kinds' entries); weather: a
    state of generator/scene/weather.py, ground: a surface of generator/scene/catalogue/ground.py
    (None: drawn per seed); building_type: a type of generator/scene/building_types/ for every
    building (None: drawn per building); context: a kind of generator/scene/contexts.py, what
    surrounds the site (None: drawn per seed); season: a season of generator/scene/weather.py
    (None: drawn per seed).
    """

    size: float = 100.0
    density: float = 1.0
    layout: str = "scattered"
    phase: float | None = None
    buildings: tuple[int, int] = (1, 2)
    floors: tuple[int, int] = (4, 8)
    trucks: tuple[int, int] = (2, 3)
    excavators: tuple[int, int] = (1, 1)
    road_inset: float = 11.0
    frames: int = 250
    fps: float = 10.0
    counts: tuple[tuple[str, tuple[int, int]], ...] = ()
    weather: str | None = None
    ground: str | None = None
    building_type: str | None = None
    context: str | None = None
    season: str | None = None

    @property
    def min_size(self) -> float:
        """Smallest site side whose middle holds a building: the ground inside the road loop
        (road inset, half the 7 m road and 1 m clear on each side) at least 20 m across.
        Presets: small 42 m, medium 51 m, large 53 m."""
        return float(math.ceil(2 * (self.road_inset + 4.5 + 10.0)))

    def validated(self) -> "SiteParams":
        check_number("site size", self.size, 30, 1000, valid="a number of metres in [30, 1000]")
        if self.size < self.min_size:  # smaller, the middle inside the road loop holds no building
            raise ValueError(f"site size {self.size:g} m is too small for a road inset of {self.road_inset:g} m; the minimum is {self.min_size:g} m")
        check_number("object density", self.density, 0, 5)
        if self.layout not in LAYOUTS:
            raise ValueError(f"unknown layout {self.layout!r}; choose one of {', '.join(LAYOUTS)}")
        if self.phase is not None:
            check_number("construction phase", self.phase, 0, 1)
        check_integer("animation length", self.frames, 2, valid="an integer >= 2 frames")
        check_number("fps", self.fps, 0, open_low=True)
        check_weather(self.weather)
        check_surface(self.ground)
        check_building_type(self.building_type)
        check_context(self.context)
        check_season(self.season)
        counts = checked_counts(self.counts)
        return self if counts == self.counts else replace(self, counts=counts)


def checked_counts(counts) -> tuple[tuple[str, tuple[int, int]], ...]:
    """``SiteParams.counts`` (pairs or a mapping kind -> (fewest, most)) as a tuple sorted by
    kind; ValueError naming what is wrong."""
    pairs = counts.items() if isinstance(counts, Mapping) else counts
    if isinstance(pairs, (str, bytes)) or not hasattr(pairs, "__iter__"):
        raise ValueError(f"site counts must be pairs (kind, (fewest, most)), got {counts!r}")
    out = {}
    for pair in pairs:
        if not (isinstance(pair, (tuple, list)) and len(pair) == 2 and isinstance(pair[1], (tuple, list)) and len(pair[1]) == 2):
            raise ValueError(f"site counts must be pairs (kind, (fewest, most)), got {pair!r}")
        name, (lo, hi) = pair
        try:
            entry = kind_named(name)
        except KeyError as e:
            raise ValueError(f"site counts: {e.args[0]}") from None
        if entry.count_param is not None:
            raise ValueError(f"site counts: {name}'s count is the site parameter {entry.count_param!r}; set that instead")
        lo = check_integer(f"the fewest {name}", lo, 0, MAX_COUNT)
        out[name] = (lo, check_integer(f"the most {name}", hi, lo, MAX_COUNT))
    return tuple(sorted(out.items()))


PRESET_SITES: dict[str, dict] = {  # each preset's site; how many of each kind: the kinds' ``counts``
    "small": {"size": 50.0, "floors": (3, 5), "road_inset": 6.5},
    "medium": {"size": 100.0, "floors": (4, 8), "road_inset": 11.0},
    "large": {"size": 200.0, "floors": (5, 12), "road_inset": 12.0},
}


def preset_params(name: str) -> SiteParams:
    """Preset ``name``: its site (:data:`PRESET_SITES`) and each catalogue kind's count in it."""
    fields, counts = dict(PRESET_SITES[name]), {}
    for k in all_kinds():
        if k.count_param is not None:
            fields[k.count_param] = k.counts.get(name, (0, 0))
        elif k.counts.get(name, (0, 0))[1] > 0:
            counts[k.name] = k.counts[name]
    return SiteParams(**fields, counts=tuple(sorted(counts.items())))


PRESETS: dict[str, SiteParams] = {name: preset_params(name) for name in PRESET_SITES}


def site_params(preset: str = "medium", **overrides) -> SiteParams:
    """Parameters of a preset ('small', 'medium', 'large') with overrides, validated."""
    if preset not in PRESETS:
        raise ValueError(f"unknown scene preset {preset!r}; choose one of {', '.join(PRESETS)}")
    unknown = set(overrides) - set(SiteParams.__dataclass_fields__)
    if unknown:
        raise TypeError(f"unknown site parameter(s): {', '.join(sorted(unknown))}")
    return replace(PRESETS[preset], **overrides).validated()


@dataclass
class SitePlan:
    seed: int
    params: SiteParams
    placed: list[PlacedAsset] = field(default_factory=list)
    road: np.ndarray | None = None  # (K, 2) closed polyline of the road centre line
    road_width: float = 7.0
    fence_runs: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)  # (start, end) on the ground
    hook_height: float = 0.0
    spawn_box: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    camera: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None  # position, look-at
    skipped: dict[str, int] = field(default_factory=dict)
    stage: int = 0  # which stage of a timeline of ``stages`` this plan is (docs/phases.md)
    stages: int = 1
    reserved: list[Footprint] = field(default_factory=list)  # ground kept free of assets (roads, gate access)
    area: SiteArea | None = None  # where props go (inside the road loop, the band along the fence)
    weather: Weather | None = None  # sky, sun and weather (generator/scene/weather.py)
    ground: GroundSurface | None = None  # what the ground is made of (generator/scene/catalogue/ground.py)
    relief: Relief | None = None  # digs and terrain (generator/scene/relief.py)
    context: Context | None = None  # what surrounds the site (generator/scene/contexts.py)

    def buildings(self) -> list[dict]:
        """site.json's ``buildings``: per building (in placing order) its ``type``, levels
        built, planned and enclosed, and height in metres (docs/scenes.md, "Building types")."""
        return [{"type": p.asset.info["type"], "floors_built": p.asset.info["floors_built"],
                 "floors_planned": p.asset.info["floors_planned"], "floors_enclosed": p.asset.info["floors_enclosed"],
                 "height_m": round(float(p.asset.info["height"]), 3)}
                for p in self.placed if p.asset.kind == "Building"]

    def summary(self) -> dict:
        """site.json's plan: seed, parameters, assets per kind, skipped ones, hook height; a
        timeline's stage; the catalogue's kinds beyond the first release that this site may
        hold (``added_kinds``: kind -> the module declaring it)."""
        kinds: dict[str, int] = {}
        for p in self.placed:
            kinds[p.asset.kind] = kinds.get(p.asset.kind, 0) + 1
        params = asdict(self.params)
        for name in ("counts", "weather", "ground", "building_type", "context", "season"):
            if not params[name]:
                del params[name]  # the first release's sites have none: their site.json stays as it was
        added = {name: kind_named(name).module for name, (_, most) in self.params.counts if most > 0}
        added |= {p.asset.kind: kind_named(p.asset.kind).module for p in self.placed
                  if not kind_named(p.asset.kind).shared_streams}
        timeline = {"stage": self.stage, "stages": self.stages} if self.stages > 1 else {}
        return ({"seed": self.seed, "params": params, "assets": kinds, "skipped": self.skipped,
                 "hook_height_m": self.hook_height, "weather": self.weather.summary(), "ground": self.ground.summary(),
                 "relief": (self.relief or Relief()).summary(), "buildings": self.buildings(),
                 "context": self.context.name if self.context else None} | timeline | ({"added_kinds": dict(sorted(added.items()))} if added else {}))


def plan_site(seed: int, params: SiteParams, stage: int = 0, stages: int = 1) -> SitePlan:
    """Place every asset of the site of ``seed`` (same seed and parameters, same plan).

    With ``stages`` > 1 the site is one of a timeline (docs/phases.md): ``stage`` 0 is the
    seed's plan, and stage k is stage k - 1 with the deltas drawn from stage k's own random
    streams (:mod:`.timeline`): buildings grow, cranes slew, materials come and go,
    machinery moves. Cranes and the camera volume are sized for the timeline's last stage,
    so they are the same in every stage. ``stages`` = 1 gives the site as it always was."""
    params = params.validated()
    check_stage(stage, stages)
    site = lay_out(seed, params, stage, stages)
    for members in planning_groups(all_kinds()):
        members[0].place.plan(site, members)
    plan = site.plan
    for i, p in enumerate(plan.placed):
        p.uid = i + 1
    if stages > 1:
        advance(plan, site.area)
    set_camera_volume(plan, site)
    return plan


def lay_out(seed: int, params: SiteParams, stage: int, stages: int) -> SiteState:
    """The empty site: its context and the terrain beyond the fence, the road loop, the
    ground kept free (road, gate access), where props go, and the planning state the kinds
    place themselves on."""
    plan = SitePlan(seed, params, stage=stage, stages=stages, weather=choose_weather(seed, params.weather, params.season),
                    ground=choose_ground(seed, params.ground), context=choose_context(seed, params.context))
    plan_terrain(plan, GROUND_MARGIN, plan.context.terrain)  # before the kinds: the surroundings stand on it
    half = params.size / 2
    road_half = half - params.road_inset
    plan.road = road_loop(road_half, ROAD_CORNER_M)
    w = plan.road_width
    reserved = [Footprint((0.0, s * road_half), (2 * road_half + w, w)) for s in (-1, 1)]
    reserved += [Footprint((s * road_half, 0.0), (w, 2 * road_half + w)) for s in (-1, 1)]
    reserved.append(Footprint((0.0, -(road_half + half) / 2), (GATE[1] - GATE[0], half - road_half)))  # gate access
    plan.reserved = list(reserved)
    plan.area = SiteArea(road_half - w / 2 - 1.0, (road_half + w / 2 + 1.0, half - 1.5), params.layout)
    return SiteState(seed, params, plan, stream(seed, "site-layout"), Placer(half - 1.0, reserved), half, road_half,
                     GATE, plan.area)


def planning_groups(kinds: list) -> list[list]:
    """The kinds that place themselves, in order, those sharing a rule's group together (at
    the group's first kind's turn)."""
    groups: dict[str, list] = {}
    for k in kinds:
        if k.place is not None:
            groups.setdefault(k.place.group or f"kind:{k.name}", []).append(k)
    return list(groups.values())


def set_camera_volume(plan: SitePlan, site: SiteState) -> None:
    """The camera spawn box (above the tallest building, below the crane hooks where they
    are higher) and the scene camera (from the south-west, looking at the middle)."""
    half = site.half
    top = max(plan.hook_height - 3.0, site.tallest + 6.0)
    plan.spawn_box = ((-half + 2.0, -half + 2.0, 1.5), (half - 2.0, half - 2.0, top))
    plan.camera = ((-half * 0.55, -half * 0.95, min(20.0, top)), (0.0, 0.0, 2.0))


def site_ground(plan: SitePlan):
    """The ground's part of ``plan``: its surface, road, verge and relief (generator/scene/ground_layout.py)."""
    road_half = plan.params.size / 2 - plan.params.road_inset
    return ground_part(plan.params.size, plan.ground, road_half, min(ROAD_CORNER_M, road_half * 0.5), plan.road_width, GATE,
                       plan.relief)


def road_loop(half_inner: float, radius: float) -> np.ndarray:
    """Rounded square of half-side ``half_inner`` (centre line), corners sampled every 10°."""
    pts = []
    r = min(radius, half_inner * 0.5)
    for cx, cy, a0 in ((half_inner - r, -half_inner + r, -90), (half_inner - r, half_inner - r, 0),
                       (-half_inner + r, half_inner - r, 90), (-half_inner + r, -half_inner + r, 180)):
        for s, c in zip(*sincos(np.radians(np.arange(a0, a0 + 90.001, 10)))):
            pts.append((cx + r * c, cy + r * s))
    return np.array(pts)
