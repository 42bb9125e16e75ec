"""Truck-mounted concrete pumps, set up on their outriggers, boom folded or unfolded.

A real one (a 24-36 m boom pump) is a truck 10-12 m long and 2.5 m wide on 3-4 axles, its
cab at the front, the boom's turret just behind the cab, the hopper at the rear; four
outriggers put pads 6-8 m apart; the placing boom has four sections (together 20-36 m) that
fold in a Z over the truck for driving and unfold to reach up and out, a 3-4 m rubber
delivery hose hanging from its tip. Static; parked elsewhere at most stages of a timeline.
"""

from __future__ import annotations

import numpy as np

from ...geometry.portable_math import hypot, sincos
from ..assets import Asset
from ..kinds import AssetKind, register
from ..materials import STREAKS, Material, Pattern
from ..meshes import MeshBuilder
from ..planning import Scatter
from ..timeline import Relocates
from .mobile_cranes import BEFORE_PROPS, P_MOVES, Carrier, box_between, carrier, slew_along, standing_asset
from .trucks import WHEEL_R, WHEEL_W

SECTION_SHARES = (0.28, 0.25, 0.25, 0.22)  # each boom section's share of the boom's length
SECTION_SIZES = ((0.6, 0.7), (0.52, 0.6), (0.45, 0.5), (0.38, 0.42))  # (width, height) of each section


def pump_carrier(rng: np.random.Generator) -> Carrier:
    """A 3-4 axle truck 10-12 m long (one or two front axles, a rear tandem), 2.5 m wide,
    the trucks' 1.05 m wheels; outriggers behind the cab and at the rear, spread 6-8 m."""
    length = rng.uniform(10.0, 12.0)
    front = (length / 2 - 1.5,) + ((length / 2 - 3.1,) if rng.random() < (length - 10.0) / 2 else ())  # two on long trucks
    rear = (-length / 2 + 2.85, -length / 2 + 1.5)
    outriggers = ((length / 2 - 4.2, rng.uniform(3.0, 4.0)), (-length / 2 + 3.75, rng.uniform(3.0, 3.6)))
    return Carrier(length, 2.5, front + rear, (WHEEL_R, WHEEL_W), 1.55, (2.1, 2.5, 2.0), outriggers)


def pump_body(c: Carrier) -> tuple[MeshBuilder, np.ndarray]:
    """The pump's own parts on the carrier ``c``: the turret behind the cab, the hopper at the
    rear and the pumping cylinders between them; returns them and the boom's pivot."""
    b = MeshBuilder()
    turret_x = c.length / 2 - 3.0
    b.box((1.5, 2.2, 0.8), (turret_x, 0, c.deck + 0.4), material="pump_paint")
    b.cylinder(0.75, (turret_x, 0, c.deck + 0.8), (turret_x, 0, c.deck + 1.3), segments=20, material="pump_boom")
    rear = -c.length / 2
    hopper = [(rear - 0.1, 1.55), (rear + 0.25, 0.8), (rear + 0.95, 0.8), (rear + 1.25, 1.55)]
    b.prism(hopper, 1.9, offset=(0, 0, 0.15), material="pump_paint")  # 0.75 m deep, 1.35 m across the top
    for y in (-0.35, 0.35):  # the two pumping cylinders, hopper to mid-deck
        b.cylinder(0.16, (rear + 1.1, y, 1.35), (rear + 4.6, y, 1.35), segments=12, material="steel_galvanized")
    b.box((1.6, 2.4, 0.9), (rear + 5.6, 0, c.deck + 0.45), material="pump_paint")  # water tank
    return b, np.array([turret_x, 0.0, c.deck + 1.5])


def unfolded_joints(rng: np.random.Generator, pivot: np.ndarray, lengths: np.ndarray) -> list[np.ndarray]:
    """The boom's five joints (pivot to tip) unfolded in a vertical plane slewed to over the
    cab or over the rear (within 17 degrees): sections at 55-85, 10-50, 0-35 and 30-70
    degrees down from the horizontal in turn, the tip at least 3.9 m up."""
    slew = slew_along(rng, 17.0)
    ss, cs = sincos(slew)
    angles = np.radians([rng.uniform(55, 85), rng.uniform(10, 50), rng.uniform(0, 35), -rng.uniform(30, 70)])
    s, c = sincos(angles)
    joints = [pivot]
    for k in range(4):
        joints.append(joints[-1] + lengths[k] * np.array([c[k] * cs, c[k] * ss, s[k]]))
    return joints


def folded_segments(pivot: np.ndarray, lengths: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """The four sections folded in a Z on top of each other over the truck: the first
    towards the rear, the next forward, and so on, each 0.55 m above the one before."""
    out, start = [], pivot
    for k in range(4):
        direction = -1.0 if k % 2 == 0 else 1.0
        end = start + (direction * lengths[k], 0.0, 0.0)
        out.append((start, end))
        start = end + (-direction * 0.3, 0.0, 0.55)
    return out


def placing_boom(rng: np.random.Generator, pivot: np.ndarray, length: float) -> tuple[MeshBuilder, dict]:
    """A four-section placing boom ``length`` metres long in all from ``pivot``, folded on
    the truck (a third of pumps) or unfolded in a seeded pose, the delivery line along it,
    the hose hanging from its tip."""
    lengths = length * np.array(SECTION_SHARES)
    folded = bool(rng.random() < 1 / 3)
    if folded:
        segments = folded_segments(pivot, lengths)
    else:
        joints = unfolded_joints(rng, pivot, lengths)
        segments = list(zip(joints[:-1], joints[1:]))
    b = MeshBuilder()
    d = segments[0][1] - segments[0][0]
    across = np.array([-d[1], d[0], 0.0]) / hypot(d[0], d[1])  # horizontal, across the boom's plane
    for (p0, p1), (w, h) in zip(segments, SECTION_SIZES):
        box_between(b, p0, p1, w, h, "pump_boom")
        box_between(b, p0 + (0, 0, h / 2 + 0.08), p1 + (0, 0, h / 2 + 0.08), 0.13, 0.13, "steel_galvanized")  # delivery line
        knuckle = across * (w / 2 + 0.05)
        b.cylinder(h * 0.6, p1 - knuckle, p1 + knuckle, segments=12, material="steel_dark")
    tip = segments[-1][1]
    hose = min(rng.uniform(3.0, 4.0), tip[2] - 1.0) if not folded else 0.6
    b.cylinder(0.065, tip, tip - (0, 0, hose), segments=10, material="rubber")
    top = max(float(max(p0[2], p1[2])) for p0, p1 in segments)
    return b, {"folded": folded, "boom_length": float(length), "boom_top": top, "tip_height": float(tip[2]), "hose": float(hose)}


def pump_truck(rng: np.random.Generator) -> Asset:
    """A truck-mounted concrete pump: a 3-4 axle truck (10-12 m x 2.5 m, cab 3.2 m high) on
    outriggers spread 6-8 m, its four-section placing boom (20-36 m, longer on longer trucks)
    folded on the truck (about 5 m high) or unfolded over the cab or the rear, its highest
    joint 8-26 m up and its tip 9-31 m out, the delivery hose hanging from the tip; the
    hopper at the rear."""
    c = pump_carrier(rng)
    body, pivot = pump_body(c)
    boom_length = float(np.clip(20.0 + 8.0 * (c.length - 10.0) + rng.uniform(-2.0, 2.0), 20.0, 36.0))  # longer on longer trucks
    boom, info = placing_boom(rng, pivot, boom_length)
    info |= {"truck_length": float(c.length), "axles": len(c.axles)}
    return standing_asset("PumpTruck", [carrier(c, "pump_paint").merge(body).build(), boom.build()], info)


register(AssetKind(
    name="PumpTruck", classes=("PumpTruck",), build=pump_truck, place=Scatter(follow_layout=False, tries=300),
    order=BEFORE_PROPS + 1,  # as the mobile cranes (mobile_cranes.BEFORE_PROPS)
    counts={"small": (0, 1), "medium": (0, 1), "large": (0, 2)},
    materials=(Material("pump_paint", (0.8, 0.8, 0.78), 0.4, 0.2, Pattern(5.0, (0.45, 0.44, 0.4), 0.25), layers=(STREAKS,)),
               Material("pump_boom", (0.3, 0.38, 0.5), 0.4, 0.3, Pattern(4.0, (0.18, 0.2, 0.24), 0.2), layers=(STREAKS,))),
    stage=Relocates(P_MOVES, near=True),
))
