"""Piling rigs: tracked rigs with a vertical leader mast, driving a pile or drilling with an
auger.

A real one (a 50-90 t rig) stands on crawler tracks 5-6 m long and 3.5-4.2 m wide over
them; its upper body carries the cab, the engine and a counterweight; a leader mast 18-26 m
tall stands vertically at its front, held by backstay struts from the body, and carries
either a hammer (3.5-5.5 m long) driving a precast concrete pile, or a rotary drive turning
a continuous-flight auger string down to the ground. Static; parked elsewhere at most stages
of a timeline.
"""

from __future__ import annotations

import numpy as np

from ..assets import Asset
from ..kinds import AssetKind, register
from ..materials import STREAKS, Material, Pattern
from ..meshes import MeshBuilder
from ..planning import Scatter
from ..timeline import Relocates
from .mobile_cranes import BEFORE_PROPS, P_MOVES, box_between, standing_asset

MAST = 0.9  # the leader mast's square section, metres


def crawler_base(b: MeshBuilder, length: float, width: float) -> None:
    """Two crawler tracks ``length`` long (0.75 m wide, 1 m high, ``width`` over both),
    rounded at the ends, the car body between them and the slewing ring (top at 1.3 m)."""
    track = [(-length / 2 + 0.45, 0.0), (length / 2 - 0.45, 0.0), (length / 2, 0.5), (length / 2 - 0.4, 1.0),
             (-length / 2 + 0.4, 1.0), (-length / 2, 0.5)]
    for s in (-1, 1):
        b.prism(track, 0.75, offset=(0, s * (width / 2 - 0.375), 0), material="steel_dark")
        for x in (-length / 2 + 0.5, length / 2 - 0.5):  # sprocket and idler hubs
            b.cylinder(0.3, (x, s * (width / 2 - 0.02), 0.5), (x, s * width / 2, 0.5), segments=12, material="piling_paint")
    b.box((length - 1.6, width - 1.5, 0.6), (0, 0, 0.7), material="steel_dark")  # car body
    b.cylinder(1.1, (0, 0, 1.0), (0, 0, 1.3), segments=20, material="steel_dark")  # slewing ring


def upper_body(b: MeshBuilder, length: float) -> float:
    """The upper body on the slewing ring (x from -``length``/2 - 0.6 to ``length``/2 - 0.6,
    2.9 m wide): frame, engine housing, counterweight at the rear and the cab on the left
    front; returns the x of its front."""
    x0, x1 = -length / 2 - 0.6, length / 2 - 0.6
    b.box((x1 - x0, 2.9, 0.7), ((x0 + x1) / 2, 0, 1.65), material="piling_paint")  # frame
    b.box((2.2, 2.6, 1.3), (x0 + 1.9, 0, 2.65), material="piling_paint")  # engine housing
    b.box((0.9, 2.9, 1.6), (x0 + 0.45, 0, 2.8), material="steel_dark")  # counterweight
    b.box((1.7, 1.0, 1.9), (x1 - 1.1, 0.95, 2.95), material="piling_paint")  # cab
    b.box((0.05, 0.85, 1.0), (x1 - 0.23, 0.95, 3.25), material="glass")
    return x1


def leader_mast(b: MeshBuilder, x: float, height: float, front: float) -> None:
    """The leader mast (``MAST`` square) at ``x`` from 0.3 m to ``height``, with guide rails
    on its front, the head's sheaves, the lower strut to the body's ``front`` and two
    backstays from the body's rear to a third of the way up."""
    b.box((MAST, MAST, height - 0.3 - 0.7), (x, 0, (height - 0.7 + 0.3) / 2), material="piling_paint")
    for y in (-0.3, 0.3):  # guide rails
        b.box((0.12, 0.12, height - 1.5), (x + MAST / 2 + 0.06, y, (height - 1.5 + 0.6) / 2), material="steel_galvanized")
    b.box((1.6, 1.1, 0.7), (x + 0.2, 0, height - 0.35), material="piling_paint")  # mast head
    b.cylinder(0.3, (x + 0.7, -0.35, height - 0.35), (x + 0.7, 0.35, height - 0.35), segments=16, material="steel_dark")
    box_between(b, (front - 0.3, 0, 1.9), (x - MAST / 2, 0, 3.2), 0.7, 0.5, "piling_paint")  # lower strut
    for s in (-1, 1):
        box_between(b, (front - 3.2, s * 1.0, 3.4), (x - MAST / 2, s * 0.3, height / 3), 0.22, 0.22, "piling_paint")  # backstay


def hammer_and_pile(b: MeshBuilder, rng: np.random.Generator, x: float, height: float) -> dict:
    """An impact hammer (3.5-5.5 m) on the mast's rails at ``x`` (the mast's centre), its
    bottom 6 m up or higher, driving a precast concrete pile (0.3-0.45 m square) standing on
    the ground; the hoist rope from the mast head."""
    length = rng.uniform(3.5, 5.5)
    bottom = rng.uniform(6.0, height - length - 1.5)
    cx = x + MAST / 2 + 0.12 + 0.45
    b.box((0.9, 0.9, length), (cx, 0, bottom + length / 2), material="steel_dark")
    b.box((0.7, 0.7, 0.4), (cx, 0, bottom - 0.2), material="piling_paint")  # helmet
    side = rng.uniform(0.3, 0.45)
    b.box((side, side, bottom - 0.4), (cx, 0, (bottom - 0.4) / 2), material="concrete")
    b.cylinder(0.025, (cx, 0, bottom + length), (cx, 0, height - 0.7), segments=6, material="steel_cable")
    return {"tool": "hammer", "hammer_length": float(length), "pile_length": float(bottom - 0.4), "pile_side": float(side)}


def auger(b: MeshBuilder, rng: np.random.Generator, x: float, height: float) -> dict:
    """A rotary drive (1.6 m) on the mast's rails at ``x`` (the mast's centre), 8 m up or
    higher, turning a continuous-flight auger (0.6-1 m) whose tip rests on the ground."""
    drive = rng.uniform(8.0, height - 3.5)
    radius = rng.uniform(0.3, 0.5)
    cx = x + MAST / 2 + 0.12 + 0.6
    b.box((1.1, 1.2, 1.6), (cx, 0, drive + 0.8), material="piling_paint")
    b.cylinder(0.12, (cx, 0, 0.4), (cx, 0, drive), segments=10, material="steel_dark")
    b.cone(0.1, 0.0, (cx, 0, 0.4), (cx, 0, 0.0), segments=10, material="steel_dark")  # tip on the ground
    for z in np.arange(0.45, drive - 0.3, 0.6):  # flights, one a pitch, tilted as a helix's (about 13 degrees)
        b.cylinder(radius, (cx, -0.007, z), (cx, 0.007, z + 0.06), segments=14, material="steel_galvanized")
    return {"tool": "auger", "drive_height": float(drive), "auger_diameter": float(2 * radius)}


def piling_rig(rng: np.random.Generator) -> Asset:
    """A piling rig: crawler tracks 5-6 m long and 3.5-4.2 m wide, an upper body with cab and
    counterweight, a vertical leader mast 18-26 m tall at its front held by backstays, and
    on the mast a hammer driving a concrete pile or (half of them) a rotary drive turning an
    auger string down to the ground."""
    length = rng.uniform(5.0, 6.0)
    width = rng.uniform(3.5, 4.2)
    height = rng.uniform(18.0, 26.0)
    b = MeshBuilder()
    crawler_base(b, length, width)
    front = upper_body(b, length)
    mast_x = front + 0.9
    leader_mast(b, mast_x, height, front)
    tool = auger(b, rng, mast_x, height) if rng.random() < 0.5 else hammer_and_pile(b, rng, mast_x, height)
    info = {"track_length": float(length), "track_width": float(width), "mast_height": float(height)} | tool
    return standing_asset("PileDriver", [b.build()], info)


register(AssetKind(
    name="PileDriver", classes=("PileDriver",), build=piling_rig, place=Scatter(follow_layout=False, tries=300),
    order=BEFORE_PROPS + 2,  # as the mobile cranes (mobile_cranes.BEFORE_PROPS)
    counts={"small": (0, 1), "medium": (0, 1), "large": (0, 2)},
    materials=(Material("piling_paint", (0.6, 0.06, 0.03), 0.4, 0.2, Pattern(5.0, (0.3, 0.08, 0.05), 0.25), layers=(STREAKS,)),),
    stage=Relocates(P_MOVES, near=True),
))
