"""A site over time: the deltas between successive stages of one seed's site (bpy-free).

Stage 0 is the seed's plan. Stage k is stage k - 1 changed by deltas drawn from stage k's
own random streams (``stream(seed, "timeline", k, ...)``), so nothing unrelated is drawn
again and everything a delta does not touch keeps its geometry, its place and its name.
What a kind does between stages is its catalogue entry's ``stage`` rule (one of the rules
below; docs/scenes.md, "The asset catalogue", lists them per kind):

- :class:`Rebuilt`: the kind's planner builds each stage's state itself (buildings grow,
  tower cranes slew);
- :class:`Consumed`: material stacks and piles are used up (removed), moved, or a part of a
  row is used; the first release's materials are also delivered anew each stage;
- :class:`Relocates`: excavators are parked elsewhere, groups of workers walk elsewhere;
- :class:`Arrives`: a new one may arrive (a container stack, in the band along the fence);
- no rule: the kind stays as it is (the ground, fence, road, trucks, cabins, ...).

Every placement is checked like the stage-0 plan's (no overlapping footprints, nothing on the
road). Objects keep one name over the timeline (:func:`object_name`), which is how their
instance ids map between stages (docs/phases.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..checks import check_integer
from ..geometry.seeding import stream
from .assets import Asset
from .kinds import all_kinds, kind as kind_named
from .placement import PlacedAsset, Placer, SiteArea, band_candidates, anywhere_then_near

MAX_STAGES = 16
DELIVERIES = (1, 2)  # new material assets per stage (inclusive)
DELIVERY_UID = 1_000_000  # uid of the j-th delivery of stage k: k * DELIVERY_UID + j (arrivals: + their slot)


def check_stage(stage, stages) -> None:
    """ValueError unless ``stages`` is 1..MAX_STAGES and ``stage`` is 0..stages-1."""
    stages = check_integer("stages", stages, 1, MAX_STAGES)
    check_integer("stage", stage, 0, stages - 1)


def object_name(label: str, uid: int, part: int) -> str:
    """The name of part ``part`` of asset ``uid`` in every stage: ``Label.<uid><part:04d>``
    (Blender's ``.NNN`` suffix form, so the label is the name without it)."""
    return f"{label}.{uid}{part:04d}"


@dataclass
class StageStep:
    """Stage ``s`` being made from the previous one: the ``plan`` (changed in place), where
    props go (``area``) and the stage's shared stream ``rng`` (first-release kinds only)."""

    plan: object  # SitePlan
    s: int
    area: SiteArea
    rng: np.random.Generator

    def placer(self, moving: PlacedAsset | None = None) -> Placer:
        taken = [p.footprint for p in self.plan.placed if p is not moving and not p.asset.moves]
        return Placer(self.plan.params.size / 2 - 1.0, self.plan.reserved + taken)

    def relocate(self, placed: PlacedAsset, candidates) -> bool:
        """Move ``placed`` to the first candidate whose footprint is free; False if none is."""
        fit = self.placer(moving=placed).first_fit(placed.asset, candidates)
        if fit is None:
            return False
        x, y, yaw, placed.footprint = fit
        placed.position, placed.yaw = (x, y), yaw
        return True

    def add(self, asset: Asset, candidates, uid: int) -> bool:
        """Place a new ``asset`` (identity ``uid``) at the first free candidate; False if none is."""
        placed = self.placer().try_place(asset, candidates)
        if placed is None:
            return False
        placed.uid = uid
        self.plan.placed.append(placed)
        return True

    def remove(self, placed: PlacedAsset) -> None:
        self.plan.placed[:] = [p for p in self.plan.placed if p is not placed]

    def skip(self, name: str) -> None:
        """Count an asset the stage could not place (site.json's ``skipped``, cumulative over stages)."""
        self.plan.skipped[name] = self.plan.skipped.get(name, 0) + 1


class StageRule:
    """What a kind does between stages: ``change`` each placed one (``u`` a uniform draw,
    ``move`` the asset's own stream for this stage), ``arrive`` new ones once a stage."""

    def change(self, step: StageStep, placed: PlacedAsset, u: float, move: np.random.Generator) -> None:
        pass

    def arrive(self, step: StageStep, kind) -> None:
        pass


@dataclass(frozen=True)
class Rebuilt(StageRule):
    """The kind's planner builds the state of the plan's stage itself (``what`` changes)."""

    what: str


@dataclass(frozen=True)
class Consumed(StageRule):
    """Each stage, with probability ``consumed`` it is used up (removed), else with
    ``moved`` it is moved elsewhere inside the road loop, else with ``part_used`` the last
    part of a row is used up (the footprint stays). ``delivered``: new ones of the kind are
    among the stage's deliveries (first-release kinds of the prop mix, by their mix weight)."""

    consumed: float
    moved: float
    part_used: float = 0.0
    delivered: bool = False

    def change(self, step, placed, u, move):
        if u < self.consumed:
            step.remove(placed)
        elif u < self.consumed + self.moved:
            step.relocate(placed, step.area.inside(move, 60))
        elif u < self.consumed + self.moved + self.part_used and len(placed.asset.parts) > 1:
            a = placed.asset
            placed.asset = Asset(a.kind, a.parts[:-1], a.size, a.placement, a.moves, dict(a.info), a.footprint_from_geometry)


@dataclass(frozen=True)
class Relocates(StageRule):
    """With probability ``p`` a stage, it moves: inside the road loop following the layout,
    or, if ``near``, anywhere inside then near its old spot (a big machine on a crowded site)."""

    p: float
    near: bool = False

    def change(self, step, placed, u, move):
        if u < self.p:
            if self.near:
                step.relocate(placed, anywhere_then_near(move, placed.position, step.area.inner))
            else:
                step.relocate(placed, step.area.inside(move, 60))


@dataclass(frozen=True)
class Arrives(StageRule):
    """With probability ``p`` a stage, a new one arrives: in the band along the fence if
    ``band`` (none arrives on a site without one), else inside the road loop. Its uid is
    ``stage * DELIVERY_UID + slot`` (a slot of its own, at least DELIVERIES[1]). A first-release
    kind draws the arrival from the stage's shared stream and builds from the stage's
    ``stream`` name; a new kind draws both from ``("arrival", name)``."""

    p: float
    slot: int
    band: bool = False
    stream: str | None = None

    def arrive(self, step, kind):
        seed, s = step.plan.seed, step.s
        if kind.shared_streams:
            comes, rng = step.rng.random() < self.p, None
        else:
            rng = stream(seed, "timeline", s, "arrival", kind.name)
            comes = rng.random() < self.p
        if not comes or (self.band and not step.area.has_band):
            return
        if rng is None:
            rng = stream(seed, "timeline", s, self.stream or kind.name)
        asset = kind.make(rng, step.plan.params.frames, step.plan.params.fps)
        band = step.area.band
        cands = band_candidates(rng, band[0], band[1], 60) if self.band else step.area.inside(rng, 60)
        if not step.add(asset, cands, s * DELIVERY_UID + self.slot):
            step.skip("Delivery")


MATERIAL_STOCK = Consumed(consumed=0.12, moved=0.12, delivered=True)  # the first release's material stacks and piles


def advance(plan, area: SiteArea) -> None:
    """Apply the deltas of stages 1..plan.stage to the stage-0 ``plan`` (in place)."""
    kinds = all_kinds()
    _check_slots(kinds)
    for s in range(1, plan.stage + 1):
        step = StageStep(plan, s, area, stream(plan.seed, "timeline", s, "site"))
        _changes(step)
        _deliveries(step, [k for k in kinds if isinstance(k.stage, Consumed) and k.stage.delivered])
        for k in kinds:
            if k.stage is not None:
                k.stage.arrive(step, k)


def _changes(step: StageStep) -> None:
    """Each placed asset's stage rule, in uid order; every first-release asset draws one
    number from the shared stream whatever its rule (so the draws stay in step)."""
    seed, s = step.plan.seed, step.s
    for placed in sorted(step.plan.placed, key=lambda p: p.uid):
        kind = kind_named(placed.asset.kind)
        u = step.rng.random() if kind.shared_streams else stream(seed, "timeline", s, "change", placed.uid).random()
        move = stream(seed, "timeline", s, "move", placed.uid)
        if kind.stage is not None:
            kind.stage.change(step, placed, u, move)


def _deliveries(step: StageStep, delivered: list) -> None:
    """1-2 new material assets a stage, each kind drawn by its mix weight (shared stream)."""
    strangers = [k.name for k in delivered if not k.shared_streams]
    if strangers:
        raise ValueError(f"asset kind(s) {', '.join(strangers)} joined the shared deliveries; a new kind arrives "
                         "with its own Arrives rule")
    count = int(step.rng.integers(DELIVERIES[0], DELIVERIES[1] + 1))
    if not delivered:
        return
    weights = np.array([k.place.weight for k in delivered], dtype=float)
    for j in range(count):
        kind = delivered[int(step.rng.choice(len(delivered), p=weights / weights.sum()))]
        rng = stream(step.plan.seed, "timeline", step.s, "delivery", j)
        asset = kind.make(rng, step.plan.params.frames, step.plan.params.fps)
        if not step.add(asset, step.area.inside(rng, 60), step.s * DELIVERY_UID + j):
            step.skip("Delivery")


def _check_slots(kinds: list) -> None:
    slots: dict[int, str] = {}
    for k in kinds:
        if isinstance(k.stage, Arrives):
            slot = k.stage.slot
            if not DELIVERIES[1] <= slot < DELIVERY_UID or slot in slots:
                raise ValueError(f"asset kind {k.name!r}: arrival slot {slot} is taken ({slots.get(slot, 'deliveries')}) "
                                 f"or outside [{DELIVERIES[1]}, {DELIVERY_UID}); pick a free one")
            slots[slot] = k.name
