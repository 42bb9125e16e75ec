"""Plan a construction site from a seed and parameters (bpy-free, deterministic).

The plan places every asset on a square site: a fence along the boundary with a gate, a
road loop that the trucks drive, buildings with a tower crane each in the middle, an
excavator, and props (containers, cabins, material stacks and piles, safety equipment,
people) arranged in a grid, scattered or clustered. Footprints never overlap.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from ..checks import check_integer, check_number
from ..geometry.camera import apply_affine, matmul_exact
from ..geometry.portable_math import atan2, sincos, vector_norm
from ..geometry.seeding import stream
from . import props, structures, vehicles
from .assets import Asset, Footprint, Part, overlaps
from .meshes import MeshBuilder, rotation_x, rotation_y, rotation_z

LAYOUTS = ("grid", "scattered", "clustered")


@dataclass(frozen=True)
class SiteParams:
    """Parameters of a site. Lengths in metres, time in frames at ``fps``.

    size: side of the square site; density: multiplier of the number of props (1 = typical);
    layout: 'grid', 'scattered' or 'clustered' arrangement of props; phase: share of the
    planned floors built, in [0, 1] (None: drawn per building in [0.25, 1]); frames and fps:
    animation length and rate.
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
        return self


PRESETS: dict[str, SiteParams] = {
    "small": SiteParams(size=50.0, density=1.0, buildings=(1, 1), floors=(3, 5), trucks=(1, 1), excavators=(0, 1), road_inset=6.5),
    "medium": SiteParams(size=100.0, density=1.0, buildings=(2, 2), floors=(4, 8), trucks=(2, 3), excavators=(1, 1), road_inset=11.0),
    "large": SiteParams(size=200.0, density=1.0, buildings=(3, 4), floors=(5, 12), trucks=(3, 5), excavators=(1, 2), road_inset=12.0),
}


def site_params(preset: str = "medium", **overrides) -> SiteParams:
    """Parameters of a preset ('small', 'medium', 'large') with overrides, validated."""
    if preset not in PRESETS:
        raise ValueError(f"unknown scene preset {preset!r}; choose one of {', '.join(PRESETS)}")
    unknown = set(overrides) - set(SiteParams.__dataclass_fields__)
    if unknown:
        raise TypeError(f"unknown site parameter(s): {', '.join(sorted(unknown))}")
    return replace(PRESETS[preset], **overrides).validated()


@dataclass
class PlacedAsset:
    asset: Asset
    position: tuple[float, float]  # asset origin on the ground, metres
    yaw: float  # radians
    footprint: Footprint  # the ground area it keeps for itself (world)
    uid: int = 0  # the asset's identity over a timeline's stages (1 + its index in the stage-0 plan; docs/phases.md)


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

    def summary(self) -> dict:
        kinds: dict[str, int] = {}
        for p in self.placed:
            kinds[p.asset.kind] = kinds.get(p.asset.kind, 0) + 1
        timeline = {"stage": self.stage, "stages": self.stages} if self.stages > 1 else {}
        return {"seed": self.seed, "params": asdict(self.params), "assets": kinds, "skipped": self.skipped,
                "hook_height_m": self.hook_height} | timeline


def _local_bounds(asset: Asset) -> tuple[np.ndarray, np.ndarray]:
    """xy bounds (min, max) of an asset's geometry in its own frame, at its rest pose."""
    half = np.asarray(asset.size) / 2
    if not asset.footprint_from_geometry:
        return -half, half
    mats = []
    for part in asset.parts:
        m = np.eye(4)
        rx, ry, rz = part.rotation
        r = matmul_exact(matmul_exact(rotation_z(rz), rotation_y(ry)), rotation_x(rx))
        m[:3, :3], m[:3, 3] = r, part.location
        if part.parent is not None:
            m = matmul_exact(mats[part.parent], m)
        mats.append(m)
    pts = [apply_affine(mats[i], p.mesh.vertices) for i, p in enumerate(asset.parts) if p.mesh is not None and len(p.mesh.vertices)]
    allp = np.concatenate(pts)[:, :2]
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    # assets whose moving parts sweep more than their rest pose (excavators) declare a size
    return np.minimum(lo, -half), np.maximum(hi, half)


def _footprint(asset: Asset, position, yaw: float) -> Footprint:
    lo, hi = _local_bounds(asset)
    c_local = (lo + hi) / 2
    s, c = sincos(yaw)
    center = np.asarray(position) + np.array([c * c_local[0] - s * c_local[1], s * c_local[0] + c * c_local[1]])
    return Footprint((float(center[0]), float(center[1])), (float(hi[0] - lo[0]), float(hi[1] - lo[1])), yaw)


class _Placer:
    """Rejection sampling of non-overlapping footprints inside an area."""

    def __init__(self, half: float, reserved: list[Footprint], margin: float = 0.8):
        self.half = half
        self.taken: list[Footprint] = list(reserved)
        self.margin = margin

    def fits(self, fp: Footprint) -> bool:
        corners = fp.corners()
        if np.any(np.abs(corners) > self.half):
            return False
        grown = fp.grown(self.margin)
        return not any(overlaps(grown, other) for other in self.taken)

    def try_place(self, asset: Asset, candidates) -> PlacedAsset | None:
        for (x, y), yaw in candidates:
            fp = _footprint(asset, (x, y), yaw)
            if self.fits(fp):
                self.taken.append(fp)
                return PlacedAsset(asset, (float(x), float(y)), float(yaw), fp)
        return None


def _road_loop(half_inner: float, radius: float) -> np.ndarray:
    """Rounded square of half-side ``half_inner`` (centre line), corners sampled every 10°."""
    pts = []
    r = min(radius, half_inner * 0.5)
    for cx, cy, a0 in ((half_inner - r, -half_inner + r, -90), (half_inner - r, half_inner - r, 0),
                       (-half_inner + r, half_inner - r, 90), (-half_inner + r, -half_inner + r, 180)):
        for s, c in zip(*sincos(np.radians(np.arange(a0, a0 + 90.001, 10)))):
            pts.append((cx + r * c, cy + r * s))
    return np.array(pts)


def _candidates(rng: np.random.Generator, layout: str, lo: float, hi: float, n: int, centres=None, grid_step=8.0):
    """Candidate ((x, y), yaw) positions in the square [lo, hi]^2 following a layout pattern."""
    if layout == "grid":
        g = np.arange(lo + grid_step / 2, hi, grid_step)
        cells = np.array([(x, y) for x in g for y in g])
        order = rng.permutation(len(cells))[:n]
        for k in order:
            yield tuple(cells[k]), float(rng.choice([0.0, math.pi / 2]))
    elif layout == "clustered" and centres is not None and len(centres):
        for _ in range(n):
            c = centres[int(rng.integers(len(centres)))]
            xy = np.clip(c + rng.normal(0, (hi - lo) * 0.08, 2), lo, hi)
            yield tuple(xy), float(rng.uniform(0, math.pi))
    else:
        for _ in range(n):
            yield tuple(rng.uniform(lo, hi, 2)), float(rng.uniform(0, math.pi))


PROP_KINDS = (  # (builder, relative frequency, prefers the outer band along the fence)
    ("Container", props.container_stack, 3, True),
    ("Cabin", props.cabin_block, 2, True),
    ("SandPile", lambda r: props.material_pile(r, "SandPile"), 1.5, False),
    ("GravelPile", lambda r: props.material_pile(r, "GravelPile"), 1.5, False),
    ("BrickPallet", props.brick_pallets, 2.5, False),
    ("PipeStack", props.pipe_stack, 1.5, False),
    ("TimberStack", props.timber_stack, 1.5, False),
    ("RebarBundle", props.rebar_bundles, 1.5, False),
    ("Barrier", props.barriers, 1.5, False),
    ("TrafficCone", props.traffic_cones, 2, False),
    ("PortableToilet", props.portable_toilets, 1, True),
    ("Skip", props.skip, 1.5, False),
    ("Generator", props.generator_set, 1, True),
    ("Worker", props.workers, 2.5, False),
)


def plan_site(seed: int, params: SiteParams, stage: int = 0, stages: int = 1) -> SitePlan:
    """Place every asset of the site of ``seed`` (same seed and parameters, same plan).

    With ``stages`` > 1 the site is one of a timeline (docs/phases.md): ``stage`` 0 is the
    seed's plan, and stage k is stage k - 1 with the deltas drawn from stage k's own random
    streams (:mod:`.timeline`): buildings grow, cranes slew, materials come and go,
    machinery moves. Cranes and the camera volume are sized for the timeline's last stage,
    so they are the same in every stage. ``stages`` = 1 gives the site as it always was."""
    from .timeline import check_stage

    params = params.validated()
    check_stage(stage, stages)
    rng = stream(seed, "site-layout")
    plan = SitePlan(seed, params, stage=stage, stages=stages)
    half = params.size / 2
    road_half = half - params.road_inset
    plan.road = _road_loop(road_half, 8.0)
    w = plan.road_width
    reserved = [Footprint((0.0, s * road_half), (2 * road_half + w, w)) for s in (-1, 1)]
    reserved += [Footprint((s * road_half, 0.0), (w, 2 * road_half + w)) for s in (-1, 1)]
    gate = (-4.0, 4.0)
    reserved.append(Footprint((0.0, -(road_half + half) / 2), (gate[1] - gate[0], half - road_half)))  # gate access
    placer = _Placer(half - 1.0, reserved)
    plan.reserved = list(reserved)
    inner = road_half - w / 2 - 1.0

    # fence along the boundary, 0.5 m inside, with a gate on the south side
    f = half - 0.5
    plan.fence_runs = [
        (np.array([-f + 0.6, -f]), np.array([gate[0], -f])), (np.array([gate[1], -f]), np.array([f - 0.6, -f])),
        (np.array([f, -f + 0.6]), np.array([f, f - 0.6])), (np.array([f - 0.6, f]), np.array([-f + 0.6, f])),
        (np.array([-f, f - 0.6]), np.array([-f, -f + 0.6])),
    ]

    # buildings in the middle
    n_build = int(rng.integers(params.buildings[0], params.buildings[1] + 1))
    building_plans = []
    for k in range(n_build):
        brng = stream(seed, "asset", "Building", k)
        phase = params.phase if params.phase is not None else float(brng.uniform(0.25, 1.0))
        max_length = 2 * inner * (0.9 if n_build == 1 else 0.6)
        asset = structures.building(brng, phase, params.floors, max_length=max_length)
        asset.info["design"] = (k, phase, max_length)  # what a later stage rebuilds it from (.timeline)
        yaw0 = 0.0 if params.layout == "grid" else float(brng.uniform(-0.3, 0.3))
        cands = [((brng.uniform(-inner, inner), brng.uniform(-inner, inner)), yaw0 + brng.choice([0, math.pi / 2])) for _ in range(300)]
        placed = placer.try_place(asset, cands)
        if placed is None:
            plan.skipped["Building"] = plan.skipped.get("Building", 0) + 1
            continue
        plan.placed.append(placed)
        building_plans.append(placed)
    if stages > 1:
        from .timeline import grow_buildings

        grow_buildings(plan, building_plans, stages - 1)  # every building as at the timeline's last stage
    tallest = max((p.asset.info["height"] for p in building_plans), default=10.0)
    plan.hook_height = tallest + 4.0

    # one tower crane per building. Cranes whose jib circles overlap are stacked: the new one
    # hangs its hook 3 m above the other's jib, and neither jib can reach the other's mast.
    cranes: list[tuple[np.ndarray, float, float]] = []  # (mast position, jib reach, top height)
    for k, b in enumerate(building_plans):
        crng = stream(seed, "asset", "Crane", k)
        fp = b.footprint
        for _ in range(100):
            side = crng.choice([-1, 1])
            along = crng.uniform(-0.4, 0.4) * fp.size[0]
            offset = fp.size[1] / 2 + 5.5
            s, c = sincos(fp.yaw)
            pos = np.array(fp.center) + np.array([c * along - s * side * offset, s * along + c * side * offset])
            far = max(np.linalg.norm(fp.corners() - pos, axis=1))
            jib = float(np.clip(far + 3.0, 20.0, 60.0))
            hook = plan.hook_height
            ok = True
            for q, reach, top in cranes:
                d = vector_norm(pos - q)
                if d >= jib + reach + 4.0:
                    continue
                if d >= max(jib, reach) + 3.0:
                    hook = max(hook, top + 3.0)
                else:
                    ok = False
                    break
            if not ok:
                continue
            state_before = crng.bit_generator.state
            asset = structures.tower_crane(crng, hook, jib, params.frames, params.fps)
            if stages > 1:  # the same draws, the stage's heading
                from .timeline import slew_offset

                rebuild = np.random.Generator(np.random.PCG64())
                rebuild.bit_generator.state = state_before
                asset = structures.tower_crane(rebuild, hook, jib, params.frames, params.fps, slew_offset(seed, k, stage))
            placed = placer.try_place(asset, [((pos[0], pos[1]), float(crng.uniform(0, math.pi / 2)))])
            if placed is not None:
                plan.placed.append(placed)
                cranes.append((pos, jib + 1.0, asset.info["top"]))
                break
        else:
            plan.skipped["Crane"] = plan.skipped.get("Crane", 0) + 1

    # excavators
    for k in range(int(rng.integers(params.excavators[0], params.excavators[1] + 1))):
        erng = stream(seed, "asset", "Excavator", k)
        asset = vehicles.excavator(erng, params.frames, params.fps)
        placed = placer.try_place(asset, _candidates(erng, "scattered", -inner, inner, 300))
        if placed is None:
            plan.skipped["Excavator"] = plan.skipped.get("Excavator", 0) + 1
        else:
            plan.placed.append(placed)

    # trucks on the road loop, evenly spaced, all at one speed (so they never catch up)
    n_trucks = int(rng.integers(params.trucks[0], params.trucks[1] + 1))
    perimeter = float(np.sum(np.linalg.norm(np.diff(np.vstack([plan.road, plan.road[:1]]), axis=0), axis=1)))
    speed = float(rng.uniform(3.0, 5.0))
    for k in range(n_trucks):
        trng = stream(seed, "asset", "Truck", k)
        offset = perimeter * k / max(n_trucks, 1) + float(trng.uniform(0, 0.2 * perimeter / max(n_trucks, 1)))
        kind = "dump" if trng.random() < 0.5 else "mixer"
        asset = vehicles.truck(trng, kind, plan.road, speed, offset, params.frames, params.fps)
        plan.placed.append(PlacedAsset(asset, (0.0, 0.0), 0.0, Footprint((0.0, 0.0), (0.0, 0.0))))

    # props
    area = params.size * params.size  # not ** 2: the C library's pow is picked by CPU
    n_props = int(round(params.density * area / 170.0))
    weights = np.array([w for _, _, w, _ in PROP_KINDS], dtype=float)
    kinds = rng.choice(len(PROP_KINDS), size=n_props, p=weights / weights.sum())
    centres = rng.uniform(-inner, inner, (max(2, int(area / 2500)), 2))
    band_lo, band_hi = road_half + w / 2 + 1.0, half - 1.5
    for k, ki in enumerate(kinds):
        name, build, _, outer = PROP_KINDS[ki]
        prng = stream(seed, "asset", name, k)
        asset = build(prng)
        if outer and band_hi - band_lo > 3.0:
            cands = _band_candidates(prng, band_lo, band_hi, 60)
        else:
            cands = _candidates(prng, params.layout, -inner, inner, 60, centres)
        placed = placer.try_place(asset, cands)
        if placed is None:
            plan.skipped[name] = plan.skipped.get(name, 0) + 1
        else:
            plan.placed.append(placed)

    for i, p in enumerate(plan.placed):
        p.uid = i + 1
    if stages > 1:
        from .timeline import advance

        grow_buildings(plan, building_plans, stage)
        advance(plan, inner, (band_lo, band_hi), centres)
    top = max(plan.hook_height - 3.0, tallest + 6.0)
    plan.spawn_box = ((-half + 2.0, -half + 2.0, 1.5), (half - 2.0, half - 2.0, top))
    plan.camera = ((-half * 0.55, -half * 0.95, min(20.0, top)), (0.0, 0.0, 2.0))
    return plan


def _band_candidates(rng: np.random.Generator, lo: float, hi: float, n: int):
    """Positions in the band between the road and the fence, long side along the fence."""
    for _ in range(n):
        side = int(rng.integers(4))
        t = rng.uniform(-hi + 3, hi - 3)
        d = rng.uniform(lo, hi)
        x, y, yaw = [(t, -d, 0.0), (d, t, math.pi / 2), (t, d, 0.0), (-d, t, math.pi / 2)][side]
        yield (x, y), yaw


GROUND_MARGIN = 20.0  # metres of ground beyond the site's edge on every side (seen from the spawn volume)


def ground_part(size: float) -> Part:
    """The ground: one flat top surface at z = 0 (two triangles, normal up), ``GROUND_MARGIN``
    metres wider than the site on every side. It has no underside and no sides below
    grade: nothing a camera above it could see (docs/scenes.md)."""
    h = size / 2 + GROUND_MARGIN
    verts = [(-h, -h, 0.0), (h, -h, 0.0), (h, h, 0.0), (-h, h, 0.0)]  # counter-clockwise seen from above
    return Part("Ground", MeshBuilder().add(verts, quads=[(0, 1, 2, 3)], material="ground").build())


def fence_part(start: np.ndarray, end: np.ndarray) -> Part:
    length = vector_norm(end - start)
    yaw = atan2(end[1] - start[1], end[0] - start[0])
    return Part("Fence", props.fence_run(length).build(), location=(float(start[0]), float(start[1]), 0.0), rotation=(0.0, 0.0, yaw))
