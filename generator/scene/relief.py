"""The ground's relief (bpy-free): what of a site's ground is not the flat working level at
z = 0 (docs/scenes.md, "Relief").

- **Digs** cut into the ground inside the road loop: a basement excavation (a *pit*: a
  rectangular floor 1.5-3 m down, sides battered at 45-60 degrees, a 4 m wide ramp at 1 in
  4 for trucks at one end) and a utility *trench* (0.7-1.2 m wide, 1-1.8 m deep, sides
  nearly vertical). Their faces belong to the ground's one mesh and share its vertices
  along the rim, so the ground stays watertight.
- **Spoil heaps**: the soil dug out, heaped next to the pit (the catalogue kind
  ``SpoilHeap``, labelled ``Ground``; generator/scene/catalogue/spoil.py).
- **Terrain beyond the fence**: it rises over the ground's margin, with gentle waves of
  20-50 m, from the fence line (level there) to 0.5-3 m at the margin's edge.
- **Ruts**: the haul road's tyre tracks are sunk 4 cm on unpaved roads
  (:mod:`.ground_layout`).

Everything else stands on the working level, and nothing is placed on a dig: the digs and
the heap are planned after the buildings, cranes and excavators and before the trucks and
props (:func:`plan_digs`, the ``SpoilHeap`` kind's placement rule), from the seed's own
``relief`` streams; the terrain by :func:`plan_terrain`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from ..geometry.portable_math import sin, sincos
from ..geometry.seeding import stream
from .assets import Footprint

PIT_CHANCE = 0.75  # share of sites with a basement excavation
TRENCH_CHANCE = 0.5  # share of sites with a utility trench
RAMP_WIDTH_M = 4.0
RAMP_RUN = 4.0  # the ramp's horizontal run per metre of depth (a grade of 1 in 4)
TERRAIN_FLAT_M = 8.0  # the terrain beyond the fence leaves the working level over this many metres
HEAP_REACH_M = (2.0, 7.5)  # a spoil heap's candidate centres: this far beyond its dig's half-length


@dataclass(frozen=True)
class Dig:
    """A rectangular excavation: its ``floor`` (length along its own x, width) ``depth`` metres
    down, sides running ``batter`` metres out per metre of depth, and with a ramp (``ramp``
    metres wide, 0 for none) rising from the floor's +x edge at 1 in ``RAMP_RUN``. Placed with
    its floor's centre at ``centre`` turned by ``turns`` quarter turns (exact: the rim's
    vertices are the ground's)."""

    kind: str  # "pit" or "trench"
    centre: tuple[float, float]
    turns: int
    floor: tuple[float, float]
    depth: float
    batter: float
    ramp: float = 0.0

    def _sizes(self):
        fl, fw = self.floor[0] / 2, self.floor[1] / 2
        b = self.batter * self.depth
        return fl, fw, fl + b, fw + b, fl + RAMP_RUN * self.depth, self.ramp / 2

    def to_world(self, xy: np.ndarray) -> np.ndarray:
        """Points (n, 2) of the dig's own frame (its floor's centre at the origin, its ramp towards
        +x) in the world: quarter turns by swapping and negating (exact), then the centre."""
        x, y = xy[:, 0], xy[:, 1]
        turned = [(x, y), (-y, x), (-x, -y), (y, -x)][self.turns % 4]
        return np.column_stack(turned) + np.asarray(self.centre, dtype=np.float64)

    def _local_outline(self) -> np.ndarray:
        fl, fw, a, c, e, h = self._sizes()
        east = [(a, -h), (e, -h), (e, h), (a, h)] if self.ramp else []
        return np.array([(-a, -c), (a, -c)] + east + [(a, c), (-a, c)], dtype=np.float64)

    def outline(self) -> np.ndarray:
        """(N, 2) the rim on the working level, counter-clockwise seen from above (world)."""
        return self.to_world(self._local_outline())

    def faces(self) -> tuple[np.ndarray, np.ndarray]:
        """(vertices (V, 3), triangles (T, 3)) of the floor, the battered sides and the ramp
        (world), every face turned towards the open air; the rim's vertices are
        :meth:`outline`'s, bit for bit."""
        fl, fw, a, c, e, h = self._sizes()
        d = -self.depth
        polys = [[(-a, -c, 0), (a, -c, 0), (fl, -fw, d), (-fl, -fw, d)],  # south side (faces +y)
                 [(a, c, 0), (-a, c, 0), (-fl, fw, d), (fl, fw, d)],  # north
                 [(-a, c, 0), (-a, -c, 0), (-fl, -fw, d), (-fl, fw, d)]]  # west (faces +x)
        if self.ramp:
            polys += [[(a, -c, 0), (a, -h, 0), (fl, -h, d), (fl, -fw, d)],  # east, either side of the ramp
                      [(a, h, 0), (a, c, 0), (fl, fw, d), (fl, h, d)],
                      [(fl, -h, d), (e, -h, 0), (e, h, 0), (fl, h, d)],  # the ramp (faces -x and up)
                      [(e, h, 0), (a, h, 0), (fl, h, d)],  # its side walls
                      [(a, -h, 0), (e, -h, 0), (fl, -h, d)],
                      [(-fl, -fw, d), (fl, -fw, d), (fl, -h, d), (fl, h, d), (fl, fw, d), (-fl, fw, d)]]  # floor
        else:
            polys += [[(a, -c, 0), (a, c, 0), (fl, fw, d), (fl, -fw, d)],
                      [(-fl, -fw, d), (fl, -fw, d), (fl, fw, d), (-fl, fw, d)]]
        verts, tris = [], []
        for poly in polys:  # convex, counter-clockwise seen from the air: a fan from the first vertex
            p = np.array(poly, dtype=np.float64)
            k = sum(len(v) for v in verts)
            tris += [(k, k + i, k + i + 1) for i in range(1, len(p) - 1)]
            verts.append(np.column_stack([self.to_world(p[:, :2]), p[:, 2]]))
        return np.concatenate(verts), np.array(tris, dtype=np.int64)

    def footprint(self) -> Footprint:
        """The ground the dig keeps for itself (its rim's bounding rectangle, world)."""
        _, _, a, c, e, _ = self._sizes()
        x1 = e if self.ramp else a
        centre = self.to_world(np.array([[(x1 - a) / 2, 0.0]]))[0]
        return Footprint((float(centre[0]), float(centre[1])), (x1 + a, 2 * c), self.turns * np.pi / 2)

    def summary(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class Terrain:
    """The ground beyond the fence: ``rise`` metres up at the margin's edge (``margin`` metres
    out), plus ``waves`` (kx, ky in radians per metre, phase, amplitude in metres), all faded
    in over the first ``TERRAIN_FLAT_M`` metres so that the fence line stays level."""

    rise: float
    margin: float
    waves: tuple[tuple[float, float, float, float], ...]

    def height(self, xy: np.ndarray, beyond: np.ndarray) -> np.ndarray:
        """z (metres) at points ``xy`` (n, 2) lying ``beyond`` (n,) metres outside the fence."""
        t = np.clip(beyond / TERRAIN_FLAT_M, 0.0, 1.0)
        fade = t * t * (3.0 - 2.0 * t)
        z = self.rise * np.clip(beyond / self.margin, 0.0, 1.0)
        for kx, ky, phase, amp in self.waves:
            z = z + amp * sin(kx * xy[:, 0] + ky * xy[:, 1] + phase)
        return fade * z

    def summary(self) -> dict:
        return {"rise_m": self.rise, "waves": [list(w) for w in self.waves]}


@dataclass
class Relief:
    """A site's relief: its digs and the terrain beyond the fence (None: level). Its spoil
    heaps are placed assets of the plan (kind ``SpoilHeap``)."""

    digs: list[Dig] = field(default_factory=list)
    terrain: Terrain | None = None

    def summary(self) -> dict:
        """site.json's ``relief``."""
        return {"digs": [d.summary() for d in self.digs], "terrain": None if self.terrain is None else self.terrain.summary()}


def draw_terrain(rng: np.random.Generator, margin: float) -> Terrain:
    """Rise 0.5-3 m over ``margin`` metres, three waves 20-50 m long, slopes of a few percent each."""
    rise = float(rng.uniform(0.5, 3.0))
    waves = []
    for _ in range(3):
        length = float(rng.uniform(20.0, 50.0))
        s, c = sincos(float(rng.uniform(0.0, 2 * np.pi)))
        k = 2 * np.pi / length
        waves.append((k * c, k * s, float(rng.uniform(0.0, 2 * np.pi)), length * float(rng.uniform(0.005, 0.012))))
    return Terrain(rise, margin, tuple(waves))


def draw_dig(rng: np.random.Generator, kind: str) -> Dig:
    """A pit or a trench's dimensions (placed at the origin)."""
    if kind == "pit":
        depth = float(rng.uniform(1.5, 3.0))
        slope = float(rng.uniform(45.0, 60.0))
        s, c = sincos(np.radians(slope))
        return Dig("pit", (0.0, 0.0), 0, (float(rng.uniform(6.0, 12.0)), float(rng.uniform(5.0, 9.0))), depth,
                   c / s, RAMP_WIDTH_M)
    return Dig("trench", (0.0, 0.0), 0, (float(rng.uniform(8.0, 20.0)), float(rng.uniform(0.7, 1.2))),
               float(rng.uniform(1.0, 1.8)), 0.1)


def inside_road_loop(points: np.ndarray, road: np.ndarray, clearance: float) -> bool:
    """True if every point (n, 2) lies inside the closed centre line ``road`` (K, 2, convex,
    counter-clockwise) at least ``clearance`` metres from it."""
    a, b = road, np.roll(road, -1, axis=0)
    ab = b - a
    for p in points:
        ap = p - a
        if np.any(ab[:, 0] * ap[:, 1] - ab[:, 1] * ap[:, 0] <= 0):  # right of an edge: outside
            return False
        t = np.clip((ap * ab).sum(axis=1) / (ab * ab).sum(axis=1), 0.0, 1.0)
        gap = ap - t[:, None] * ab
        if np.sqrt((gap * gap).sum(axis=1)).min() < clearance:
            return False
    return True


def _place_dig(dig: Dig, site, rng: np.random.Generator, tries: int = 300) -> Dig | None:
    """``dig`` at the first free candidate inside the road loop (its footprint then taken), or
    None; its rim stays a metre clear of the road, rounded corners included."""
    inner = site.area.inner
    clearance = site.plan.road_width / 2 + 1.0
    for _ in range(tries):
        x, y = rng.uniform(-inner, inner, 2)
        placed = Dig(dig.kind, (float(x), float(y)), int(rng.integers(4)), dig.floor, dig.depth, dig.batter, dig.ramp)
        fp = placed.footprint()
        if site.placer.fits(fp) and inside_road_loop(placed.outline(), site.plan.road, clearance):
            site.placer.taken.append(fp)
            site.plan.reserved.append(fp)
            return placed
    return None


def _heap_candidates(dig: Dig, rng: np.random.Generator, n: int = 80):
    """((x, y), yaw) beside ``dig``: on a ring just outside its footprint."""
    fp = dig.footprint()
    reach = max(fp.size) / 2
    for _ in range(n):
        s, c = sincos(float(rng.uniform(0.0, 2 * np.pi)))
        r = reach + float(rng.uniform(*HEAP_REACH_M))
        yield (fp.center[0] + r * c, fp.center[1] + r * s), float(rng.uniform(0.0, np.pi))


def plan_digs(site, kind) -> None:
    """The placement rule of the catalogue's ``SpoilHeap`` (``kind``): a pit (with a spoil heap
    beside it, where one fits) and a trench, where they fit in the ground left free, into
    ``site.plan.relief``. Draws only from the seed's ``relief`` streams."""
    seed, plan = site.seed, site.plan
    plan.relief = plan.relief or Relief()
    rng = stream(seed, "relief", "digs")
    for name, chance in (("pit", PIT_CHANCE), ("trench", TRENCH_CHANCE)):
        if rng.random() >= chance:
            continue
        dig = _place_dig(draw_dig(rng, name), site, rng)
        if dig is None:
            site.skip(name.capitalize())
            continue
        plan.relief.digs.append(dig)
        if name == "pit":
            heap = kind.make(stream(seed, "relief", "heap"), site.params.frames, site.params.fps)
            site.place(kind.name, heap, _heap_candidates(dig, rng))


def plan_terrain(plan, margin: float, factor: float = 1.0) -> None:
    """The terrain beyond the fence of ``plan`` (``margin`` metres of it), from the seed's own
    ``relief`` stream, its rise and waves scaled by ``factor`` (the context's: 0 keeps the
    ground level), into ``plan.relief``."""
    plan.relief = plan.relief or Relief()
    t = draw_terrain(stream(plan.seed, "relief", "terrain"), margin)
    plan.relief.terrain = Terrain(t.rise * factor, margin, tuple((kx, ky, ph, amp * factor) for kx, ky, ph, amp in t.waves))
