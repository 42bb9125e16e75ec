"""Industrial halls (bpy-free, type ``industrial-hall``): a single-storey steel portal-frame
shed on a concrete ground slab. Each frame is two H-section columns and two I-section rafters
meeting at the ridge of a 5-10 degree duo-pitch roof; frames 6-7.5 m apart (4-8 bays) along
x, spans of 18-30 m across y, eaves 6-10 m (span, bays and bay width shrink to fit
``max_length``). The erected bays carry galvanised purlins and side rails, the first bay wall
and roof X-bracing, the end frames two gable posts; the cladding (one colour a building:
green, blue or the steel frame's grey) has a row of windows along the sides, the roof sheets
a roof-light strip in every or every other bay, the far gable one or two roller doors. A
scissor lift stands inside by the newest frame (``Scaffolding``).

A *level* is a group of bays erected along x from the x0 gable: ``planned`` levels (drawn
from ``floors`` as every type does, at most one a bay) share the hall's bays, ``k`` levels
being the first ``ceil(k * bays / planned)`` bays. ``built`` levels: the frames of that many
bays stand, with their purlins and side rails; ``enclosed`` levels (two behind, as for every
type): that many bays have their roof sheets and side cladding, the x0 gable is clad with the
first enclosed level and the far gable (the doors) with the last. ``floor_height`` is the
eaves height (ground to the rafters' underside at the column lines); ``height`` the top of
the ``Building`` part (the ridge: the rafters', or the purlins' and roof sheets' once bays
carry them). Nothing is drawn per level, so every stage keeps the bays of the previous one
as they were, vertex for vertex."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...geometry.portable_math import sincos
from ..assets import Asset, Part
from ..building_parts import facades, free_spans, infill_bay
from ..materials import STREAKS, Material, Pattern
from ..meshes import MeshBuilder, rotation_x
from . import BuildingType, Growth, register_type
from .steel_frame import h_section

COLUMN, COL_FLANGE = 0.5, 0.2  # column section depth (across the span) and flange width, metres
RAFTER, RAF_FLANGE = 0.45, 0.19  # rafter section depth and flange width, metres
POST = 0.25  # gable post section, metres
SLAB = 0.2  # ground slab thickness, metres
PURLIN, RAIL = 0.2, 0.2  # purlin and side rail depth, metres
SKIN = 0.05  # cladding and roof sheet thickness, metres
OVER = 0.15  # roof overhang beyond the walls, metres
BRACE = 0.03  # bracing rod radius, metres
MARGIN_X = COL_FLANGE / 2 + RAIL + SKIN + OVER  # footprint beyond the end frames, metres
MARGIN_Y = COLUMN / 2 + RAIL + SKIN + OVER + (RAFTER + PURLIN + SKIN) * 0.18  # beyond the column lines (sin 10 deg < 0.18)
FILL = 0.8  # the share of ``max_length`` a hall takes at most (room to place it turned by 0.3 rad on a small site)
QUARTER = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # a quarter turn about z
CLADDINGS = ("hall_cladding_green", "hall_cladding_blue", "cladding")


@dataclass(frozen=True)
class Hall:
    """The drawn design: ``bays`` bays ``bay`` wide along x, ``span`` across y, eaves
    ``eaves``, roof pitch ``pitch`` (radians; ``sp``, ``cp``, ``tp`` its sine, cosine and
    tangent), levels ``planned`` / ``own_built`` (stage 0) / ``built`` / ``enclosed``; the
    cladding's material, windows in every ``windows``-th bay (sill ``sill``), a roof light
    ``light`` wide in every ``lights``-th bay, roller ``doors`` ((y, width, share rolled up)
    each) ``door_h`` high, and the side of the scissor lift."""

    span: float
    bay: float
    bays: int
    eaves: float
    pitch: float
    sp: float
    cp: float
    tp: float
    planned: int
    own_built: int
    built: int
    enclosed: int
    cladding: str
    windows: int
    sill: float
    lights: int
    light: float
    doors: tuple
    door_h: float
    lift_side: int

    @property
    def half(self) -> float:
        return self.span / 2

    @property
    def gx(self) -> np.ndarray:
        """The frames' x."""
        return self.bay * (np.arange(self.bays + 1) - self.bays / 2)

    @property
    def outline(self) -> tuple[float, float]:
        """Half the slab's (the rails' outer faces') length and width."""
        return self.bays * self.bay / 2 + COL_FLANGE / 2 + RAIL, self.half + COLUMN / 2 + RAIL

    def bays_of(self, levels: int) -> int:
        """How many bays ``levels`` levels are."""
        return -(-levels * self.bays // self.planned)

    def at(self, s: int, u: float, h: float) -> tuple[float, float]:
        """(y, z) of the point ``h`` metres (normal to the roof) above the rafters' underside
        ``u`` metres (horizontally) from the ridge on side ``s`` (-1: y < 0, 1: y > 0)."""
        return s * (u + h * self.sp), self.eaves + (self.half - u) * self.tp + h * self.cp

    def under_roof(self, u: float) -> float:
        """The height of the roof sheets' underside ``u`` metres (horizontally) from the ridge."""
        return self.eaves + (self.half - u) * self.tp + (RAFTER + PURLIN) / self.cp


def draw_hall(rng: np.random.Generator, phase: float, floors: tuple[int, int], max_length: float,
              growth: Growth | None) -> Hall:
    """The hall's design and state (every draw made whatever the stage)."""
    span, bay, bays = rng.uniform(18.0, 30.0), rng.uniform(6.0, 7.5), int(rng.integers(4, 9))
    eaves, pitch = rng.uniform(6.0, 10.0), rng.uniform(5.0, 10.0) * math.pi / 180.0
    planned = int(rng.integers(floors[0], floors[1] + 1))
    cladding = CLADDINGS[int(rng.integers(len(CLADDINGS)))]
    windows, sill, lights, light = int(rng.integers(1, 3)), rng.uniform(1.2, 3.0), int(rng.integers(1, 3)), rng.uniform(1.0, 2.0)
    two_doors, door_w, door_h = rng.random() < 0.5, rng.uniform(4.0, 5.5), rng.uniform(4.0, 5.0)
    rolled = rng.uniform(0.0, 0.9, size=2) * (rng.random(2) < 0.5)  # the share of each door rolled up
    lift_side = 1 if rng.random() < 0.5 else -1
    room = FILL * max_length
    span = min(span, room - 2 * MARGIN_Y)
    bays = max(2, min(bays, int((room - 2 * MARGIN_X) // bay)))
    bay = min(bay, (room - 2 * MARGIN_X) / bays)
    planned = min(planned, bays)
    built = own_built = max(1, int(round(phase * planned)))
    enclosed = max(0, own_built - 2)
    if growth is not None:
        growth.check(own_built, planned)
        built, enclosed = growth.built, growth.enclosed
    half = span / 2
    doors = [(0.0, min(door_w, half - 0.8), rolled[0])]  # between the gable posts
    if two_doors and half / 2 - 1.0 >= 2.5:  # between a gable post and a column
        doors.append((0.75 * half * lift_side, min(door_w, half / 2 - 1.0), rolled[1]))
    sp, cp = sincos(pitch)
    return Hall(span, bay, bays, eaves, pitch, sp, cp, sp / cp, planned, own_built, built, enclosed, cladding,
                windows, sill, lights, light, tuple(doors), min(door_h, eaves - 1.5), lift_side)


def slope_box(b: MeshBuilder, h: Hall, s: int, xs: tuple[float, float], us: tuple[float, float], above: float,
              thick: float, material: str) -> None:
    """A box in the roof plane of side ``s``: from x ``xs[0]`` to ``xs[1]``, from ``us[0]`` to
    ``us[1]`` metres (horizontally) from the ridge, ``thick`` thick, its underside ``above``
    metres above the rafters' underside."""
    y, z = h.at(s, (us[0] + us[1]) / 2, above + thick / 2)
    b.box((xs[1] - xs[0], (us[1] - us[0]) / h.cp, thick), ((xs[0] + xs[1]) / 2, y, z),
          rotation=rotation_x(-s * h.pitch), material=material)


def add_frames(b: MeshBuilder, h: Hall, frames: int) -> None:
    """The first ``frames`` portal frames: columns from the slab to the rafters, rafters from
    the columns' outer faces to the ridge (their top flanges meet there); gable posts at the
    quarter points of an end frame."""
    u_in, u_out = -RAFTER * h.sp, h.half + COLUMN / 2  # past the ridge by as much as the top flange needs
    rafter = MeshBuilder()
    h_section(rafter, (0.0, 0.0, 0.0), (u_out - u_in) / h.cp, "y", RAFTER, RAF_FLANGE, "steel_primer")
    rafter = rafter.build()
    col_top = h.eaves + COLUMN / 2 * h.tp  # the rafter's underside at the column's inner face
    for i in range(frames):
        x = h.gx[i]
        for s in (-1, 1):
            h_section(b, (x, s * h.half, (SLAB + col_top) / 2), col_top - SLAB, "z", COLUMN, COL_FLANGE, "steel_primer")
            y, z = h.at(s, (u_in + u_out) / 2, RAFTER / 2)
            b.merge(rafter, rotation=rotation_x(-s * h.pitch), offset=(x, y, z))
            if i in (0, h.bays):
                post_top = h.at(s, h.half / 2, 0.0)[1]
                h_section(b, (x, s * h.half / 2, (SLAB + post_top) / 2), post_top - SLAB, "z", POST, POST, "steel_primer")


def add_bay_steel(b: MeshBuilder, h: Hall, i: int) -> None:
    """Bay ``i``'s purlins (about 1.8 m apart on each slope) and side rails (2 m apart),
    X-bracing in the walls and the roof of the first bay."""
    xa, xb = h.gx[i], h.gx[i + 1]
    purlins = np.linspace(0.3, h.half + COLUMN / 2 - 0.1, int(h.half // 1.8) + 2)
    for s in (-1, 1):
        for u in purlins:
            slope_box(b, h, s, (xa, xb), (u - 0.04, u + 0.04), RAFTER, PURLIN, "steel_galvanized")
        for z in np.arange(1.5, h.eaves - 0.6, 2.0):
            b.box((xb - xa, RAIL, 0.15), ((xa + xb) / 2, s * (h.half + COLUMN / 2 + RAIL / 2), z), material="steel_galvanized")
        if i == 0:
            (ye, ze), (yr, zr) = h.at(s, h.half, RAFTER / 2), h.at(s, 0.3, RAFTER / 2)
            for x0, x1 in ((xa, xb), (xb, xa)):
                b.cylinder(BRACE, (x0, s * h.half, SLAB), (x1, s * h.half, h.eaves), segments=8, material="steel_primer")
                b.cylinder(BRACE, (x0, ye, ze), (x1, yr, zr), segments=8, material="steel_primer")


def add_bay_cladding(b: MeshBuilder, h: Hall, i: int) -> None:
    """Bay ``i``'s roof sheets (a roof-light strip in every ``lights``-th bay) and side walls
    (a window in every ``windows``-th bay); the end bays' run on over the gables."""
    lx, ly = h.outline
    xa = h.gx[i] if i > 0 else -lx - SKIN
    xb = h.gx[i + 1] if i < h.bays - 1 else lx + SKIN
    above = RAFTER + PURLIN
    u0, u1 = -(above + SKIN) * h.sp, ly + SKIN + OVER  # the sheets' top faces meet at the ridge
    pieces = [(u0, u1, "roof_sheet")]
    if i % h.lights == 0:
        a = 0.4 * h.half
        pieces = [(u0, a, "roof_sheet"), (a, a + h.light, "glass"), (a + h.light, u1, "roof_sheet")]
    for s in (-1, 1):
        for p0, p1, material in pieces:
            ends = (xa - OVER if i == 0 else xa, xb + OVER if i == h.bays - 1 else xb)
            slope_box(b, h, s, ends, (p0, p1), above, SKIN, material)
    top = h.under_roof(ly + SKIN)
    for _, line, _, _ in facades(-lx, lx, -ly, ly, 0.0, SKIN)[:2]:
        if i % h.windows:
            b.box((xb - xa, SKIN, top), ((xa + xb) / 2, line, top / 2), material=h.cladding)
            continue
        zb = h.sill - 0.9  # infill_bay's sill is 0.9 m above its foot
        b.box((xb - xa, SKIN, zb), ((xa + xb) / 2, line, zb / 2), material=h.cladding)
        infill_bay(b, True, line, xa, xb, zb, top, xb - xa - 1.0, True, thick=SKIN, material=h.cladding)


def add_gable(b: MeshBuilder, h: Hall, far: bool) -> None:
    """The cladding of the x0 gable, or of the far one (``far``) with its roller doors: wall
    up to the door head between the doors, a pentagon above it up to the roof sheets; each
    door a curtain (part of it rolled up) and a coil box inside above it."""
    lx, ly = h.outline
    _, line, a0, a1 = facades(-lx, lx, -ly, ly, 0.0, SKIN)[3 if far else 2]
    doors = h.doors if far else ()
    for c0, c1 in free_spans(a0, a1, [(y - w / 2, y + w / 2) for y, w, _ in doors]):
        b.box((SKIN, c1 - c0, h.door_h), (line, (c0 + c1) / 2, h.door_h / 2), material=h.cladding)
    eaves = h.under_roof(a1)
    profile = [(a0, h.door_h), (a1, h.door_h), (a1, eaves), (0.0, h.under_roof(0.0)), (a0, eaves)]
    b.prism(profile, SKIN, rotation=QUARTER, offset=(line, 0.0, 0.0), material=h.cladding)
    inward = -1.0 if far else 1.0
    for y, w, rolled in doors:
        shut = h.door_h * (1.0 - rolled)
        if shut > 0.05:
            b.box((SKIN, w, shut), (line, y, h.door_h - shut / 2), material="steel_galvanized")
        b.box((0.45, w + 0.2, 0.45), (line + inward * 0.3, y, h.door_h + 0.25), material="steel_galvanized")


def scissor_lift(b: MeshBuilder, x: float, y: float, deck: float) -> None:
    """A scissor lift (2.6 x 1.2 m) standing on the slab at (x, y), its deck ``deck`` metres
    up: wheels, chassis, two scissor stacks, the deck and its guard rails."""
    for dx in (-0.9, 0.9):
        for dy in (-0.5, 0.5):
            b.cylinder(0.19, (x + dx, y + dy - 0.06, SLAB + 0.19), (x + dx, y + dy + 0.06, SLAB + 0.19), segments=12,
                       material="rubber")
    b.box((2.5, 1.0, 0.35), (x, y, SLAB + 0.3), material="steel_painted")
    zs = np.linspace(SLAB + 0.48, deck, max(2, math.ceil((deck - SLAB) / 1.6)) + 1)
    for za, zb in zip(zs[:-1], zs[1:]):
        for dy in (-0.45, 0.45):
            b.cylinder(0.04, (x - 1.0, y + dy, za), (x + 1.0, y + dy, zb), segments=6, material="steel_painted")
            b.cylinder(0.04, (x + 1.0, y + dy, za), (x - 1.0, y + dy, zb), segments=6, material="steel_painted")
    b.box((2.6, 1.2, 0.1), (x, y, deck + 0.05), material="steel_painted")
    corners = [(x - 1.25, y - 0.55), (x + 1.25, y - 0.55), (x + 1.25, y + 0.55), (x - 1.25, y + 0.55)]
    for k, (cx, cy) in enumerate(corners):
        b.cylinder(0.025, (cx, cy, deck + 0.1), (cx, cy, deck + 1.2), segments=6, material="steel_galvanized")
        nx, ny = corners[(k + 1) % 4]
        for dz in (0.6, 1.1):
            b.cylinder(0.02, (cx, cy, deck + dz), (nx, ny, deck + dz), segments=6, material="steel_galvanized")


def industrial_hall(rng: np.random.Generator, phase: float, floors: tuple[int, int], max_length: float = 60.0,
                    growth: Growth | None = None) -> Asset:
    """A steel portal-frame hall under construction, centred on the origin (see the module's
    docstring); ``phase``, ``floors``, ``max_length`` and ``growth`` as for every building
    type (generator/scene/building_types/__init__.py)."""
    h = draw_hall(rng, phase, floors, max_length, growth)
    lx, ly = h.outline
    steel, works = MeshBuilder(), MeshBuilder()
    steel.box((2 * lx, 2 * ly, SLAB), (0.0, 0.0, SLAB / 2), material="concrete")
    framed, clad = h.bays_of(h.built), h.bays_of(h.enclosed)
    add_frames(steel, h, framed + 1)
    for i in range(framed):
        add_bay_steel(steel, h, i)
    for i in range(clad):
        add_bay_cladding(steel, h, i)
    if h.enclosed:
        add_gable(steel, h, far=False)
    if h.enclosed == h.planned:
        add_gable(steel, h, far=True)
    j = framed if h.built < h.planned else max(clad, 1)  # the newest frame, or the cladding's front
    scissor_lift(works, h.gx[j] - 2.0, h.lift_side * (h.half - 2.5), h.eaves - 1.6)
    building = steel.build()
    size = (2 * (lx + SKIN + OVER), 2 * (ly + SKIN + OVER + (RAFTER + PURLIN + SKIN) * h.sp))
    return Asset("Building", [Part("Building", building), Part("Scaffolding", works.build())], size,
                 info={"floors_built": h.built, "floors_planned": h.planned, "floors_enclosed": h.enclosed,
                       "height": float(building.vertices[:, 2].max()), "floor_height": h.eaves, "span": h.span,
                       "bay": h.bay, "bays": h.bays, "bays_framed": framed, "bays_clad": clad,
                       "pitch_deg": h.pitch * 180.0 / math.pi})


def _cladding(name: str, colour, stain) -> Material:
    """Profiled wall cladding of ``colour``: vertical ribs (a pattern stretched 30x along z), streaks."""
    return Material(name, colour, 0.45, 0.5, Pattern(5.0, stain, 0.55, stretch=(1.0, 1.0, 30.0)), layers=(STREAKS,))


register_type(BuildingType(
    name="industrial-hall", build=industrial_hall, weight=0.2, module=__name__,
    structure="single-storey steel portal-frame hall (span 18-30 m, bays 6-7.5 m, eaves 6-10 m, a 5-10 degree "
              "duo-pitch roof) on a concrete slab: purlins and side rails, X-bracing in the first bay, profiled "
              "cladding (green, blue or grey) with a row of windows, roof sheets with roof-light strips, one or two "
              "roller doors in the far gable; a scissor lift by the newest frame. A stage erects the frames of 1-2 "
              "more groups of bays along the hall; the roof and wall cladding follows two groups behind",
    materials=(Material("roof_sheet", (0.55, 0.56, 0.56), 0.4, 0.8, Pattern(5.0, (0.42, 0.43, 0.44), 0.5,
                                                                          stretch=(1.0, 30.0, 1.0)), reflectivity=0.45),
               _cladding("hall_cladding_green", (0.07, 0.16, 0.1), (0.04, 0.1, 0.06)),
               _cladding("hall_cladding_blue", (0.05, 0.1, 0.24), (0.03, 0.06, 0.15))),
))
