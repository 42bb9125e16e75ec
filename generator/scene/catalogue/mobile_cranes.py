"""Mobile cranes: all-terrain telescopic cranes set up on their outriggers, boom raised.

A real one (a 60-100 t all-terrain crane) is a carrier 12-14 m long and 2.55 m wide on 4-5
axles of 1.35 m tyres, its cab low at the front; four outrigger beams put pads 6-7.5 m apart;
the slewing superstructure (operator cab, counterweight) carries a telescopic boom of 3-4
nested box sections, 10-11 m retracted and 20-35 m extended, luffed at 30-70 degrees, with a
hook block on the hoist rope. Static; parked elsewhere at most stages of a timeline.

The truck carrier (:class:`Carrier`, :func:`carrier`), the box between two points
(:func:`box_between`), scaled tyres (:func:`tyre`) and the standing, centred asset
(:func:`standing_asset`) serve the other machinery kinds too (pump trucks, rollers, loaders,
piling rigs).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...geometry.camera import matmul_exact, rows_times
from ...geometry.portable_math import atan2, hypot, sincos
from ..assets import Asset, Part
from ..kinds import AssetKind, register
from ..materials import STREAKS, Material, Pattern
from ..meshes import MeshBuilder, MeshData, rotation_y, rotation_z
from ..planning import Scatter
from ..timeline import Relocates
from .trucks import WHEEL_R, WHEEL_W, wheel

P_MOVES = 0.7  # chance a machine is parked elsewhere at a stage
# The machinery kinds (mobile cranes, pump trucks, piling rigs, loaders, rollers: BEFORE_PROPS
# to BEFORE_PROPS + 4, the largest first) are planned right after the trucks (40), before the
# prop mix (50-63): planned after the props, as a new kind is by default, a site has no room
# left inside its road loop for footprints this large (none of medium seeds 0-19 placed a
# mobile crane or a pump truck, 2 of 9 piling rigs fitted; no small site placed a loader or
# a roller).
BEFORE_PROPS = 41
FOOTPRINT_MARGIN = 0.02  # metres added to the plan-view bounds of a machine's footprint


def tyre(radius: float, width: float) -> MeshBuilder:
    """The trucks' wheel (:func:`.trucks.wheel`) scaled to a tyre of ``radius`` and ``width``
    (metres, over its hub caps), centred on its origin, axle along y."""
    k = radius / WHEEL_R
    return MeshBuilder().merge(wheel(), rotation=np.diag([k, width / (WHEEL_W + 0.04), k]))  # caps 2 cm out each side


def box_between(b: MeshBuilder, p0, p1, width: float, height: float, material: str) -> MeshBuilder:
    """A box from point ``p0`` to point ``p1`` (its length), ``width`` across it horizontally
    and ``height`` across it in its vertical plane: booms, arms, struts, beams."""
    p0, p1 = np.asarray(p0, dtype=np.float64), np.asarray(p1, dtype=np.float64)
    d = p1 - p0
    flat = hypot(d[0], d[1])
    yaw = atan2(d[1], d[0]) if flat > 1e-9 else 0.0
    turn = matmul_exact(rotation_z(yaw), rotation_y(-atan2(d[2], flat)))
    return b.box((hypot(flat, d[2]), width, height), (p0 + p1) / 2, rotation=turn, material=material)


def standing_asset(kind: str, meshes: list[MeshData], info: dict) -> Asset:
    """An :class:`Asset` of kind ``kind`` (parts labelled with the class of the same name) of
    ``meshes`` built in one frame, each part moved so that the asset's plan-view bounds are
    centred on the origin and its lowest vertex is at z = 0; its size is those bounds."""
    v = np.concatenate([m.vertices for m in meshes])
    lo, hi = v.min(axis=0), v.max(axis=0)
    shift = (float(-(lo[0] + hi[0]) / 2), float(-(lo[1] + hi[1]) / 2), float(-lo[2]))
    parts = [Part(kind, m, location=shift) for m in meshes]
    size = (float(hi[0] - lo[0]) + FOOTPRINT_MARGIN, float(hi[1] - lo[1]) + FOOTPRINT_MARGIN)
    return Asset(kind, parts, size, info=info)


@dataclass(frozen=True)
class Carrier:
    """A truck carrier in its own frame (x forward, y left, z up, metres): ``length`` and
    ``width``; ``axles`` (x of each); ``tyres`` (radius, width); ``deck`` (top of its body);
    ``cab`` (length, width, height) at the front, on the left where narrower than the carrier;
    ``outriggers`` ((x, reach from the centre line to the pad's centre), ...), one each side."""

    length: float
    width: float
    axles: tuple[float, ...]
    tyres: tuple[float, float]
    deck: float
    cab: tuple[float, float, float]
    outriggers: tuple[tuple[float, float], ...]


def carrier(c: Carrier, paint: str) -> MeshBuilder:
    """The carrier ``c``: frame, body up to the deck, cab, wheels and outriggers extended on
    their pads (the pads' bottoms at z = 0, the tyres touching the ground)."""
    b = MeshBuilder()
    r, w = c.tyres
    front = c.length / 2
    body_low = 2 * r + 0.05  # the body above the tyres, the frame between them
    b.box((c.length - 0.3, c.width - 2 * w - 0.1, body_low - r + 0.2), (0, 0, (body_low + r - 0.2) / 2), material="steel_dark")
    body_x0 = -front
    body_x1 = front - c.cab[0]
    b.box((body_x1 - body_x0, c.width, c.deck - body_low), ((body_x0 + body_x1) / 2, 0, (c.deck + body_low) / 2), material=paint)
    cab_len, cab_w, cab_h = c.cab
    cab_y = (c.width - cab_w) / 2
    b.box((cab_len, cab_w, cab_h), (front - cab_len / 2, cab_y, r + cab_h / 2), material=paint)
    b.box((0.05, cab_w - 0.2, cab_h * 0.4), (front + 0.02, cab_y, r + cab_h * 0.7), material="glass")  # windscreen
    b.box((0.3, c.width, 0.4), (front - 0.1, 0, r), material="steel_dark")  # bumper
    for x in c.axles:
        for s in (-1, 1):
            b.merge(tyre(r, w), offset=(x, s * (c.width / 2 - w / 2), r))
    for x, reach in c.outriggers:
        b.box((0.6, c.width, 0.45), (x, 0, body_low), material=paint)  # outrigger box
        for s in (-1, 1):
            b.box((0.35, reach, 0.4), (x, s * reach / 2, body_low), material=paint)
            b.cylinder(0.14, (x, s * reach, body_low), (x, s * reach, 0.1), segments=12, material="steel_galvanized")
            b.box((0.6, 0.6, 0.1), (x, s * reach, 0.05), material="steel_dark")  # pad
    return b


def slew_along(rng: np.random.Generator, within_deg: float) -> float:
    """A slew angle (radians) over the carrier's front or its rear (even odds), up to
    ``within_deg`` degrees off its axis: a boom over the carrier keeps its footprint narrow."""
    return (0.0 if rng.random() < 0.5 else np.pi) + np.radians(rng.uniform(-within_deg, within_deg))


def crane_carrier(rng: np.random.Generator) -> Carrier:
    """An all-terrain crane's carrier: 12-14 m long, 2.55 m wide, 4-5 axles of 1.35 m tyres
    (two at the front, the rest at the rear), outriggers spread 6-7.5 m."""
    length = rng.uniform(12.0, 14.0)
    n_axles = int(rng.integers(4, 6))
    front = (length / 2 - 2.2, length / 2 - 3.85)
    rear = tuple(-length / 2 + 1.7 + 1.65 * k for k in range(n_axles - 2))
    reach = rng.uniform(3.0, 3.75)
    outriggers = ((0.5 * (front[1] + rear[-1]), reach), (-length / 2 + 0.55, reach))
    return Carrier(length, 2.55, front + rear, (0.675, 0.52), 1.95, (1.9, 1.15, 1.8), outriggers)


def superstructure(paint: str) -> MeshBuilder:
    """The slewing superstructure in its own frame (origin on the slewing ring's bottom, +x
    towards the boom's head): frame, counterweight, operator cab beside the boom."""
    u = MeshBuilder()
    u.cylinder(1.1, (0, 0, 0), (0, 0, 0.3), segments=20, material="steel_dark")  # slewing ring
    u.box((4.4, 2.5, 0.8), (-0.5, 0, 0.7), material=paint)  # frame
    u.box((1.2, 2.5, 1.5), (-3.1, 0, 1.05), material=paint)  # counterweight
    u.box((1.8, 0.85, 1.6), (0.6, -1.05, 1.9), material=paint)  # operator cab, right of the boom
    u.box((0.05, 0.7, 0.9), (1.52, -1.05, 2.2), material="glass")
    return u


BOOM_FOOT = np.array([-2.0, 0.0, 1.9])  # the boom's pivot in the superstructure's frame


def telescopic_boom(u: MeshBuilder, rng: np.random.Generator, paint: str) -> dict:
    """Add to the superstructure ``u`` a boom of 3-4 nested box sections, 10-11.5 m each
    (overlapping by at least 1.5 m), extended to 20-35 m and luffed at 30-70 degrees, with
    its luffing cylinder and head; returns its sections, length, angle and head point."""
    n = int(rng.integers(3, 5))
    section = rng.uniform(10.0, 11.5)
    length = rng.uniform(20.0, min(35.0, section + (n - 1) * (section - 1.5)))
    angle = np.radians(rng.uniform(30.0, 70.0))
    s, c = sincos(angle)
    along = np.array([c, 0.0, s])
    step = (length - section) / (n - 1)
    for i in range(n):
        start, end = BOOM_FOOT + along * (i * step), BOOM_FOOT + along * (i * step + section)
        box_between(u, start, end, 0.95 - 0.14 * i, 1.2 - 0.17 * i, paint)
    head = BOOM_FOOT + along * (length + 0.35)
    box_between(u, BOOM_FOOT + along * (length - 0.3), head, 0.6, 0.9, "steel_dark")
    u.cylinder(0.35, head + (0, -0.25, 0), head + (0, 0.25, 0), segments=16, material="steel_dark")  # sheaves
    box_between(u, (0.9, 0, 1.1), BOOM_FOOT + along * 4.5, 0.35, 0.35, "steel_galvanized")  # luffing cylinder
    return {"sections": n, "boom_length": float(length), "boom_angle_deg": float(np.degrees(angle)), "head": head}


def hook_block(tip, hook_z: float) -> MeshBuilder:
    """The hoist rope hanging from ``tip`` (x, y, z) to a hook block whose top is at ``hook_z``."""
    h = MeshBuilder()
    x, y, z = (float(t) for t in tip)
    for dy in (-0.12, 0.12):
        h.cylinder(0.02, (x, y + dy, z - 0.35), (x, y + dy, hook_z), segments=6, material="steel_cable")
    h.box((0.5, 0.6, 0.9), (x, y, hook_z - 0.45), material="crane_hook")
    h.cone(0.12, 0.05, (x, y, hook_z - 0.9), (x, y, hook_z - 1.4), segments=10, material="steel_painted")
    return h


def mobile_crane(rng: np.random.Generator) -> Asset:
    """An all-terrain mobile crane (carrier 12-14 m x 2.55 m on 4-5 axles, outriggers spread
    6-7.5 m) with its telescopic boom (3-4 sections, 20-35 m) raised at 30-70 degrees over
    the front or the rear, up to 20 degrees off the carrier's axis, its hook 2 m above the ground
    or higher; the boom head 14-37 m up."""
    c = crane_carrier(rng)
    paint = "mobile_crane_paint"
    u = superstructure(paint)
    boom = telescopic_boom(u, rng, paint)
    slew = slew_along(rng, 20.0)
    ring = np.array([-c.length / 2 + 3.3, 0.0, c.deck])
    turn = rotation_z(slew)
    upper = MeshBuilder().merge(u, rotation=turn, offset=ring)
    tip = ring + rows_times(boom.pop("head"), turn.T)  # the head in the carrier's frame
    hook_z = rng.uniform(3.4, max(3.5, tip[2] - 3.0))
    info = boom | {"carrier_length": float(c.length), "axles": len(c.axles), "outrigger_span": float(2 * c.outriggers[0][1]),
                   "slew_deg": float(np.degrees(slew)), "head_height": float(tip[2]), "hook_height": float(hook_z - 1.4)}
    meshes = [carrier(c, paint).build(), upper.build(), hook_block(tip, hook_z).build()]
    return standing_asset("MobileCrane", meshes, info)


register(AssetKind(
    name="MobileCrane", classes=("MobileCrane",), build=mobile_crane, place=Scatter(follow_layout=False, tries=300),
    order=BEFORE_PROPS,
    counts={"small": (0, 1), "medium": (0, 1), "large": (0, 2)},
    materials=(Material("mobile_crane_paint", (0.9, 0.62, 0.02), 0.4, 0.2, Pattern(5.0, (0.4, 0.3, 0.1), 0.2),
                        layers=(STREAKS,)),),
    stage=Relocates(P_MOVES, near=True),
))
