"""Single-drum vibratory soil compactors (rollers) on earthworks.

A real one (a 10-13 t machine) is 5.5-6 m long and 2.1-2.3 m wide: a smooth steel drum
about 1.5 m in diameter and 2.1 m wide at the front in a yoke frame, an articulated rear
frame carrying the engine on two large tyres (about 1.6 m), and the operator under a ROPS
canopy or in a cab about 3 m up. Static; parked elsewhere at most stages of a timeline.
"""

from __future__ import annotations

import numpy as np

from ..assets import Asset
from ..kinds import AssetKind, register
from ..materials import STREAKS, Material, Pattern
from ..meshes import MeshBuilder
from ..planning import Scatter
from ..timeline import Relocates
from .mobile_cranes import BEFORE_PROPS, P_MOVES, standing_asset, tyre


def drum_end(b: MeshBuilder, x: float, width: float, radius: float) -> float:
    """The drum (axle along y, its bottom at z = 0) centred at ``x`` in its yoke, ``width``
    over the side plates: the plates, a cross beam over the drum and the scraper; returns the
    x of the articulation joint."""
    drum = width - 0.2
    b.cylinder(radius, (x, -drum / 2, radius), (x, drum / 2, radius), segments=24, material="steel_dark")
    for s in (-1, 1):  # side plates, hub to above the drum, and the drive motors
        b.box((0.7, 0.08, radius + 0.6), (x, s * (width / 2 - 0.06), radius + (radius + 0.6) / 2 - 0.3), material="roller_paint")
        b.cylinder(0.3, (x, s * (width / 2 - 0.02), radius), (x, s * width / 2, radius), segments=12, material="steel_dark")
    b.box((0.7, width - 0.04, 0.3), (x, 0, 2 * radius + 0.15), material="roller_paint")  # cross beam
    b.box((0.15, drum, 0.12), (x + radius + 0.05, 0, radius + 0.35), material="steel_dark")  # scraper
    joint = x - radius - 0.55
    b.box((0.9, 0.9, 0.7), (joint + 0.45, 0, radius + 0.55), material="roller_paint")  # yoke neck to the joint
    return joint


def rear_frame(b: MeshBuilder, joint: float, rear: float, width: float, tyre_r: float) -> None:
    """The rear frame from the articulation ``joint`` back to ``rear``: engine housing over
    the axle, tyres of radius ``tyre_r`` at the edge of ``width``, the operator's platform."""
    tyre_w = 0.6
    axle_x = rear + 1.25
    for s in (-1, 1):
        b.merge(tyre(tyre_r, tyre_w), offset=(axle_x, s * (width / 2 - tyre_w / 2), tyre_r))
    b.box((joint - rear, width - 2 * tyre_w - 0.1, 0.6), ((joint + rear) / 2, 0, tyre_r), material="steel_dark")  # frame
    engine = (rear, joint - 1.75)  # behind the operator
    b.box((engine[1] - rear, width - 2 * tyre_w - 0.1, tyre_r + 0.15), (sum(engine) / 2, 0, 1.5 * tyre_r + 0.1),
          material="roller_paint")  # engine, between the tyres
    b.box((engine[1] - rear, width - 0.2, 0.6), (sum(engine) / 2, 0, 2 * tyre_r + 0.35), material="roller_paint")  # hood
    b.box((0.15, width - 0.3, 0.5), (rear + 0.075, 0, tyre_r + 0.3), material="steel_dark")  # rear bumper
    b.box((1.2, width - 0.2, 0.25), (joint - 0.55, 0, 1.45), material="roller_paint")  # platform


def operator_shelter(b: MeshBuilder, x0: float, x1: float, width: float, height: float, closed: bool) -> None:
    """A ROPS canopy over [x0, x1] from the platform (1.58 m) to ``height``, four posts and
    a roof, glazed all round when ``closed`` (a cab); the seat and steering wheel inside."""
    half = width / 2 - 0.08
    for x in (x0 + 0.06, x1 - 0.06):
        for s in (-1, 1):
            b.box((0.1, 0.1, height - 1.58), (x, s * half, (height + 1.58) / 2), material="roller_paint")
    b.box((x1 - x0 + 0.1, width, 0.12), ((x0 + x1) / 2, 0, height - 0.06), material="roller_paint")  # roof
    if closed:
        b.box((x1 - x0 - 0.2, width - 0.26, 1.4), ((x0 + x1) / 2, 0, height - 0.95), material="glass")
    b.box((0.5, 0.5, 0.5), (x0 + 0.45, 0, 1.83), material="steel_dark")  # seat
    b.cylinder(0.2, (x1 - 0.35, -0.08, 2.25), (x1 - 0.35, 0.08, 2.25), segments=12, material="steel_dark")  # steering wheel


def roller(rng: np.random.Generator) -> Asset:
    """A single-drum vibratory soil compactor: 5.5-6 m long, 2.1-2.3 m wide, a steel drum
    1.45-1.6 m in diameter at the front, an articulated rear frame on two 1.5-1.65 m tyres,
    the operator under a canopy or in a cab (half of them) 2.9-3.1 m high."""
    length = rng.uniform(5.5, 6.0)
    width = rng.uniform(2.1, 2.3)
    drum_r = rng.uniform(0.725, 0.8)
    height = rng.uniform(2.9, 3.1)
    closed = bool(rng.random() < 0.5)
    b = MeshBuilder()
    front = length / 2
    joint = drum_end(b, front - 0.125 - drum_r, width, drum_r)  # the scraper at the front
    rear = -front
    rear_frame(b, joint, rear, width, rng.uniform(0.75, 0.825))
    operator_shelter(b, joint - 1.75, joint - 0.05, min(width, 1.9), height, closed)
    info = {"length": float(length), "width": float(width), "drum_diameter": float(2 * drum_r), "height": float(height),
            "cab": closed}
    return standing_asset("Roller", [b.build()], info)


register(AssetKind(
    name="Roller", classes=("Roller",), build=roller, place=Scatter(follow_layout=False, tries=300),
    order=BEFORE_PROPS + 4,  # as the mobile cranes (mobile_cranes.BEFORE_PROPS)
    counts={"small": (0, 1), "medium": (0, 1), "large": (0, 2)},
    materials=(Material("roller_paint", (0.9, 0.42, 0.02), 0.4, 0.2, Pattern(5.0, (0.4, 0.22, 0.08), 0.25), layers=(STREAKS,)),),
    stage=Relocates(P_MOVES, near=True),
))
