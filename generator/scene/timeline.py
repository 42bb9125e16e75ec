"""A site over time: the deltas between successive stages of one seed's site (bpy-free).

Stage 0 is the seed's plan. Stage k is stage k - 1 changed by deltas drawn from stage k's
own random streams (``stream(seed, "timeline", k, ...)``), so nothing unrelated is drawn
again and everything a delta does not touch keeps its geometry, its place and its name:

- buildings grow: one or two floors of frame a stage until the planned height, the brick
  infill two floors behind, then the remaining facades one floor a stage; the rebar and
  formwork on the top slab climb with it and the scaffolding gains lifts;
- tower cranes slew (a new heading, the same slewing motion);
- material stacks and piles are consumed (removed), moved, or a pallet of a row is used;
  new ones are delivered; a new container stack may arrive in the band along the fence;
- excavators are parked elsewhere, groups of workers walk elsewhere;
- the ground, fence, road, trucks, cabins, toilets, generators, skips, barriers and cones
  stay as they are.

Every placement is checked like the stage-0 plan's (no overlapping footprints, nothing on the
road). Objects keep one name over the timeline (:func:`object_name`), which is how their
instance ids map between stages (docs/phases.md).
"""

from __future__ import annotations

import math

import numpy as np

from ..checks import check_integer
from ..geometry.seeding import stream
from . import props, structures
from .assets import Asset

MAX_STAGES = 16
MATERIALS = ("SandPile", "GravelPile", "BrickPallet", "PipeStack", "TimberStack", "RebarBundle")
P_CONSUMED, P_MOVED, P_PALLET_USED = 0.12, 0.12, 0.2  # per material asset and stage
P_EXCAVATOR_MOVES, P_WORKERS_MOVE, P_CONTAINER, P_SLEW = 0.7, 0.5, 0.5, 0.8
DELIVERIES = (1, 2)  # new material assets per stage (inclusive)
DELIVERY_UID = 1_000_000  # uid of the j-th delivery of stage k: k * DELIVERY_UID + j


def check_stage(stage, stages) -> None:
    """ValueError unless ``stages`` is 1..MAX_STAGES and ``stage`` is 0..stages-1."""
    stages = check_integer("stages", stages, 1, MAX_STAGES)
    check_integer("stage", stage, 0, stages - 1)


def object_name(label: str, uid: int, part: int) -> str:
    """The name of part ``part`` of asset ``uid`` in every stage: ``Label.<uid><part:04d>``
    (Blender's ``.NNN`` suffix form, so the label is the name without it)."""
    return f"{label}.{uid}{part:04d}"


def building_schedule(seed: int, index: int, own_built: int, planned: int, stage: int) -> tuple[int, int]:
    """(floors built, floors enclosed) of building ``index`` at ``stage``, from its stage-0
    state: each stage adds 1-2 floors of frame (infill two floors behind) until ``planned``,
    then one more enclosed floor a stage."""
    built, enclosed = own_built, max(0, own_built - 2)
    for s in range(1, stage + 1):
        r = stream(seed, "timeline", s, "Building", index)
        if built < planned:
            built = min(planned, built + int(r.integers(1, 3)))
            enclosed = max(enclosed, built - 2)
        else:
            enclosed = min(built, enclosed + 1)
    return built, enclosed


def grow_buildings(plan, buildings: list, stage: int) -> None:
    """Replace each placed building's asset by its state at ``stage`` (same place)."""
    for placed in buildings:
        k, phase, max_length = placed.asset.info["design"]
        base = _building(plan, k, phase, max_length, None)
        built, enclosed = building_schedule(plan.seed, k, base.info["floors_built"], base.info["floors_planned"], stage)
        growth = structures.Growth(built, enclosed, lambda f, k=k: stream(plan.seed, "asset", "Building", k, "floor", f))
        placed.asset = _building(plan, k, phase, max_length, growth)


def _building(plan, k: int, phase: float, max_length: float, growth) -> Asset:
    brng = stream(plan.seed, "asset", "Building", k)
    if plan.params.phase is None:
        brng.uniform(0.25, 1.0)  # the phase draw of site.plan_site
    asset = structures.building(brng, phase, plan.params.floors, max_length=max_length, growth=growth)
    asset.info["design"] = (k, phase, max_length)
    return asset


def slew_offset(seed: int, crane: int, stage: int) -> float:
    """Heading (radians) crane ``crane`` has turned by at ``stage`` from stage 0."""
    offset = 0.0
    for s in range(1, stage + 1):
        r = stream(seed, "timeline", s, "Crane", crane)
        if r.random() < P_SLEW:
            offset = float(r.uniform(0.0, 2 * math.pi))
    return offset


def advance(plan, inner: float, band: tuple[float, float], centres: np.ndarray) -> None:
    """Apply the deltas of stages 1..plan.stage to the stage-0 ``plan`` (in place)."""
    for s in range(1, plan.stage + 1):
        _stage_deltas(plan, s, inner, band, centres)


def _placer(plan, moving=None):
    from .site import _Placer

    taken = [p.footprint for p in plan.placed if p is not moving and not p.asset.moves]
    return _Placer(plan.params.size / 2 - 1.0, plan.reserved + taken)


def _relocate(plan, placed, cands) -> bool:
    """Move ``placed`` to the first candidate whose footprint is free; False if none is."""
    from .site import _footprint

    placer = _placer(plan, moving=placed)
    for (x, y), yaw in cands:
        fp = _footprint(placed.asset, (x, y), yaw)
        if placer.fits(fp):
            placed.position, placed.yaw, placed.footprint = (float(x), float(y)), float(yaw), fp
            return True
    return False


def _add(plan, asset: Asset, cands, uid: int) -> bool:
    from .site import PlacedAsset

    placed = _placer(plan).try_place(asset, cands)
    if placed is None:
        return False
    placed.uid = uid
    plan.placed.append(placed)
    return True


def _stage_deltas(plan, s: int, inner: float, band: tuple[float, float], centres: np.ndarray) -> None:
    from .site import PROP_KINDS, _band_candidates, _candidates

    seed, layout = plan.seed, plan.params.layout
    rng = stream(seed, "timeline", s, "site")
    for placed in sorted(plan.placed, key=lambda p: p.uid):
        kind = placed.asset.kind
        u = rng.random()
        move = stream(seed, "timeline", s, "move", placed.uid)
        if kind in MATERIALS:
            if u < P_CONSUMED:
                plan.placed[:] = [p for p in plan.placed if p is not placed]
            elif u < P_CONSUMED + P_MOVED:
                _relocate(plan, placed, _candidates(move, layout, -inner, inner, 60, centres))
            elif u < P_CONSUMED + P_MOVED + P_PALLET_USED and kind == "BrickPallet" and len(placed.asset.parts) > 1:
                a = placed.asset  # the last pallet of the row is used up; the footprint stays
                placed.asset = Asset(a.kind, a.parts[:-1], a.size, a.placement, a.moves, dict(a.info), a.footprint_from_geometry)
        elif kind == "Excavator" and u < P_EXCAVATOR_MOVES:
            _relocate(plan, placed, _near_then_anywhere(move, placed.position, inner))
        elif kind == "Worker" and u < P_WORKERS_MOVE:
            _relocate(plan, placed, _candidates(move, layout, -inner, inner, 60, centres))
    builders = {name: (build, weight) for name, build, weight, _ in PROP_KINDS if name in MATERIALS}
    weights = np.array([builders[m][1] for m in MATERIALS], dtype=float)
    for j in range(int(rng.integers(DELIVERIES[0], DELIVERIES[1] + 1))):
        name = MATERIALS[int(rng.choice(len(MATERIALS), p=weights / weights.sum()))]
        drng = stream(seed, "timeline", s, "delivery", j)
        if not _add(plan, builders[name][0](drng), _candidates(drng, layout, -inner, inner, 60, centres),
                    s * DELIVERY_UID + j):
            _skipped(plan, "Delivery")
    if rng.random() < P_CONTAINER and band[1] - band[0] > 3.0:
        crng = stream(seed, "timeline", s, "container")
        if not _add(plan, props.container_stack(crng), _band_candidates(crng, band[0], band[1], 60),
                    s * DELIVERY_UID + 999):
            _skipped(plan, "Delivery")


def _skipped(plan, kind: str) -> None:
    """Count an asset the stage could not place (site.json's ``skipped``, cumulative over stages)."""
    plan.skipped[kind] = plan.skipped.get(kind, 0) + 1


def _near_then_anywhere(rng: np.random.Generator, position, inner: float, n: int = 150):
    """Candidate ((x, y), yaw): ``n`` anywhere inside the road loop, then ``n`` within a
    few metres of ``position`` (a crowded site has room for a big machine near its old spot)."""
    for _ in range(n):
        yield tuple(rng.uniform(-inner, inner, 2)), float(rng.uniform(0, 2 * math.pi))
    for _ in range(n):
        xy = np.clip(np.asarray(position) + rng.normal(0.0, 4.0, 2), -inner, inner)
        yield tuple(xy), float(rng.uniform(0, 2 * math.pi))
