"""The surroundings of a site (bpy-free): what stands on the ground beyond the fence, laid
out side by side from the site's context (:mod:`generator.scene.contexts`).

Each side of the site (south, east, north, west) is a band ``d`` metres beyond the site's
edge (its fence line is at ``d`` = -0.5), ``u`` metres along it. From the side's own random
stream ``(seed, "surroundings", side)`` it gets, outwards:

1. a street at ``d`` = 1 (always on the gate's side, the south; on the others with the
   context's chance): sidewalks and a carriageway (:mod:`.catalogue.streets`). Where two
   streets meet at a corner the first side's (S, E, N, W) runs on to the ground's edge and
   the other stops at its sidewalk (a T-junction);
2. street lights on the near sidewalk every 24-34 m, cars parked along both kerbs (each
   place taken with the context's ``parking`` chance; none in front of the gate);
3. lots of neighbouring buildings (:mod:`.catalogue.neighbours`), frontage after frontage
   along the side, set back from the street (or the fence) and facing the site; front
   hedges where the context has hedges; a hedgerow along the fence where it has no
   neighbours;
4. trees wherever they fit.

Everything stands on the terrain: its base sits at the lowest ground height under its
footprint (neighbours and hedges reach below it), streets follow the ground. Nothing
overlaps, nothing reaches inside the fence, and nothing moves over a timeline's stages.
"""

from __future__ import annotations

import numpy as np

from ..geometry.portable_math import atan2
from ..geometry.seeding import stream
from .assets import Asset
from .placement import PlacedAsset, footprint_at
from .planning import Grouped

MARGIN_M = 20.0  # the ground beyond the site's edge (generator/scene/catalogue/ground.py GROUND_MARGIN)
STREET_FROM_M = 1.0  # a street's near edge beyond the site's edge
GATE_CLEAR_M = 8.0  # no car parks within this many metres of the gate's centre line
# outward normal and along-direction (counter-clockwise) of the sides S, E, N, W
SIDES = (((0.0, -1.0), (1.0, 0.0)), ((1.0, 0.0), (0.0, 1.0)), ((0.0, 1.0), (-1.0, 0.0)), ((-1.0, 0.0), (0.0, -1.0)))


class Side:
    """One side's band: world positions of (u, d), the ground's height, what is taken."""

    def __init__(self, site, index: int):
        self.site, self.index = site, index
        self.n, self.t = (np.array(v) for v in SIDES[index])
        self.yaw = float(atan2(self.t[1], self.t[0]))  # an asset's +x along the side, its +y towards the site
        self.half = site.half
        self.taken: list[tuple[float, float, float, float]] = []  # (u0, u1, d0, d1)

    def world(self, u, d) -> np.ndarray:
        u, d = np.broadcast_arrays(np.asarray(u, float), np.asarray(d, float))
        return np.stack([self.n[0] * (self.half + d) + self.t[0] * u, self.n[1] * (self.half + d) + self.t[1] * u], -1)

    def ground(self, xy: np.ndarray) -> np.ndarray:
        """The ground's height (metres) at world points ``xy`` (N, 2) beyond the site's edge."""
        terrain = self.site.plan.relief.terrain
        xy = np.asarray(xy, float).reshape(-1, 2)
        if terrain is None:
            return np.zeros(len(xy))
        beyond = np.maximum(np.max(np.abs(xy), axis=1) - self.half, 0.0)
        return terrain.height(xy, beyond)

    def free(self, u0: float, u1: float, d0: float, d1: float) -> bool:
        return all(u1 <= a0 or u0 >= a1 or d1 <= b0 or d0 >= b1 for a0, a1, b0, b1 in self.taken)

    def put(self, asset: Asset, u: float, d: float, turn: float = 0.0, lift: float = 0.0, box=None) -> None:
        """Place ``asset`` with its origin at (u, d), turned ``turn`` from the side's yaw,
        its base at the lowest ground under its footprint plus ``lift``; mark ``box`` (u0, u1,
        d0, d1; default its footprint) taken."""
        position = tuple(float(c) for c in self.world(u, d))
        fp = footprint_at(asset, position, self.yaw + turn)
        base = float(self.ground(np.vstack([fp.corners(), [position]])).min()) + lift
        for part in asset.parts:
            if part.parent is None:
                part.location = (part.location[0], part.location[1], part.location[2] + base)
        self.site.plan.placed.append(PlacedAsset(asset, position, self.yaw + turn, fp))
        if box is None:
            lx, ly = asset.size[0] / 2, asset.size[1] / 2
            box = (u - lx, u + lx, d - ly, d + ly)
        self.taken.append(box)


def plan_surroundings(site, kinds: list) -> None:
    """Lay out every side's surroundings (module docstring) from the site's context."""
    build = {k.name: k.build for k in kinds}
    context = site.plan.context
    rngs = [stream(site.seed, "surroundings", i) for i in range(4)]
    streets = [i == 0 or bool(rngs[i].random() < context.street) for i in range(4)]
    for i in range(4):
        side, rng = Side(site, i), rngs[i]
        far = STREET_FROM_M - 0.5
        if streets[i]:
            far = lay_street(side, rng, build, context, streets)
        lay_lots(side, rng, build, context, far)
        lay_trees(side, rng, build, context, far)


def lay_street(side: Side, rng, build, context, streets: list[bool]) -> float:
    """The side's street, its lights and parked cars; the street's far edge (d)."""
    sw, cw = context.sidewalk, context.carriageway
    d0, d1 = STREET_FROM_M, STREET_FROM_M + 2 * sw + cw
    ends = []
    for end, other in ((-1, (side.index - 1) % 4), (1, (side.index + 1) % 4)):
        through = not streets[other] or side.index < other
        ends.append(end * (side.half + (MARGIN_M if through else STREET_FROM_M - 0.05)))
    u0, u1 = ends
    centre_d = (d0 + d1) / 2
    origin = side.world((u0 + u1) / 2, centre_d)
    s_, c_ = side.t[1], side.t[0]

    def ground(xy):  # street frame -> world
        world = np.column_stack([origin[0] + c_ * xy[:, 0] - s_ * xy[:, 1], origin[1] + s_ * xy[:, 0] + c_ * xy[:, 1]])
        return side.ground(world)

    asset = build["Street"](rng, length=u1 - u0, sidewalk=sw, carriageway=cw, ground=ground)
    side.site.plan.placed.append(PlacedAsset(asset, (float(origin[0]), float(origin[1])), side.yaw,
                                             footprint_at(asset, tuple(origin), side.yaw)))
    side.taken.append((u0, u1, d0, d1))
    gate = side.index == 0
    if sw > 0:
        u = -side.half + rng.uniform(2.0, 12.0)
        while u < side.half - 2.0:
            if not (gate and abs(u) < GATE_CLEAR_M):
                side.put(build["StreetLight"](rng), u, d0 + 0.35, turn=np.pi, box=(u - 0.2, u + 0.2, d0, d0 + 0.6))
            u += rng.uniform(24.0, 34.0)
    for lane_d in (d0 + sw + 1.1, d1 - sw - 1.1):
        u = -side.half + rng.uniform(3.0, 6.0)
        while u < side.half - 3.0:
            car = build["Car"](rng)
            step = car.size[0] + rng.uniform(0.8, 2.0)
            if rng.random() < context.parking and not (gate and abs(u) < GATE_CLEAR_M):
                side.put(car, u, lane_d, turn=0.0 if rng.random() < 0.5 else np.pi, lift=0.04,
                         box=(u - step / 2, u + step / 2, lane_d - 1.0, lane_d + 1.0))
            u += step
    return d1


def lay_lots(side: Side, rng, build, context, start: float) -> None:
    """Neighbours frontage after frontage (with front hedges), or a hedgerow."""
    if not context.neighbour:
        if context.hedges:
            u = -side.half + rng.uniform(0.0, 4.0)
            d = start + 1.5
            while u < side.half - 4.0:
                length = min(rng.uniform(6.0, 16.0), side.half - u)
                hedge = build["Hedge"](rng, length=length)
                side.put(hedge, u + length / 2, d)
                u += length + rng.uniform(1.0, 6.0)
        return
    u = -side.half + rng.uniform(0.0, context.gap[1] + 1.0)
    while True:
        frontage = rng.uniform(*context.lot)
        if u + frontage > side.half:
            frontage = side.half - u
            if frontage < context.lot[0] * 0.7:
                break
        depth, setback = rng.uniform(*context.depth), rng.uniform(*context.setback)
        storeys = int(rng.integers(context.storeys[0], context.storeys[1] + 1))
        d = start + setback + depth / 2
        house = build["Neighbour"](rng, style=context.neighbour, frontage=frontage, depth=depth, storeys=storeys)
        side.put(house, u + frontage / 2, d, lift=-0.05)
        if context.hedges and setback > 1.6:
            for a, b in ((u + 0.2, u + frontage / 2 - 0.7), (u + frontage / 2 + 0.7, u + frontage - 0.2)):
                side.put(build["Hedge"](rng, length=b - a), (a + b) / 2, start + 0.6)
        u += frontage + rng.uniform(*context.gap)


def lay_trees(side: Side, rng, build, context, start: float) -> None:
    """Trees where they fit, beyond the street (or the fence), within the ground's margin."""
    tries = int(round(context.trees * 2 * side.half / 100.0))
    for _ in range(tries):
        tree = build["Tree"](rng)
        r = tree.size[0] / 2
        u, d = rng.uniform(-side.half + r, side.half - r), rng.uniform(start + r + 0.3, MARGIN_M - 0.5)
        if d - r > start and side.free(u - r, u + r, d - r, d + r):
            side.put(tree, u, d)


SURROUNDINGS = Grouped(plan_surroundings, "surroundings")
