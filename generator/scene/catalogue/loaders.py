"""Wheel loaders: articulated front-end loaders with their bucket raised or lowered.

A real one (a 15-20 t machine) is 7-8.5 m long with its bucket, 2.8 m wide over four 1.6 m
tyres (a wheelbase of about 3.3 m), an articulated front frame carrying the lift arms and a
bucket 2.5-3 m wide, a rear frame carrying the cab (about 3.4 m up), the engine and the
counterweight. Static; parked elsewhere at most stages of a timeline.
"""

from __future__ import annotations

import numpy as np

from ...geometry.portable_math import atan2, sincos
from ..assets import Asset
from ..kinds import AssetKind, register
from ..materials import STREAKS, Material, Pattern
from ..meshes import MeshBuilder
from ..planning import Scatter
from ..timeline import Relocates
from .mobile_cranes import BEFORE_PROPS, P_MOVES, box_between, standing_asset, tyre

ARM_PIVOT = np.array([0.95, 0.0, 2.05])  # the lift arms' pivot on the front frame
BUCKET_DEPTH = 1.4  # hinge to cutting edge, metres
BUCKET_DROP = 0.63  # hinge to the bucket's lowest point


def loader_frames(b: MeshBuilder, wheelbase: float, tyre_r: float, height: float) -> float:
    """Both frames (the joint at x = 0), their four tyres 2.8 m apart over the outside, the
    engine hood and counterweight at the rear and the cab up to ``height``; returns the x
    of the rear end."""
    for x in (-wheelbase / 2, wheelbase / 2):
        for s in (-1, 1):
            b.merge(tyre(tyre_r, 0.62), offset=(x, s * 1.09, tyre_r))
    b.box((wheelbase / 2 + 0.9, 1.1, 0.8), ((wheelbase / 2 + 0.9) / 2, 0, tyre_r + 0.1), material="loader_paint")  # front frame
    b.box((0.7, 1.1, ARM_PIVOT[2] - tyre_r), (ARM_PIVOT[0], 0, (ARM_PIVOT[2] + tyre_r) / 2), material="loader_paint")  # tower
    rear = -wheelbase / 2 - 1.35
    b.box((-rear, 1.3, 0.8), (rear / 2, 0, tyre_r + 0.1), material="loader_paint")  # rear frame
    b.box((-rear - 0.95, 1.7, 1.25), ((rear - 0.95) / 2, 0, tyre_r + 1.05), material="loader_paint")  # engine hood
    b.box((0.55, 2.3, 0.95), (rear + 0.275, 0, tyre_r + 0.35), material="loader_paint")  # counterweight
    for x in (-wheelbase / 2, wheelbase / 2):  # fenders
        b.box((1.5, 2.6, 0.08), (x, 0, 2 * tyre_r + 0.12), material="loader_paint")
    b.box((1.5, 1.55, height - 1.8), (-0.2, 0, (height + 1.8) / 2), material="glass")  # cab
    b.box((1.6, 1.65, 0.12), (-0.2, 0, height - 0.06), material="loader_paint")  # cab roof
    for x in (-0.92, 0.52):
        for s in (-1, 1):
            b.box((0.08, 0.08, height - 1.8), (x, s * 0.79, (height + 1.8) / 2), material="loader_paint")  # cab posts
    exhaust = np.array([rear + 1.2, 0.4, tyre_r + 1.6])
    b.cylinder(0.1, exhaust, exhaust + (0, 0, 0.4), segments=8, material="steel_dark")
    return rear


def lift_arms(b: MeshBuilder, hinge: np.ndarray, width: float) -> None:
    """The lift arms from their pivot to the bucket's ``hinge``, their lift cylinders, the
    tilt linkage and the bucket (``width`` across) level below the hinge."""
    for s in (-1, 1):
        side = np.array([0.0, s * 0.72, 0.0])
        box_between(b, ARM_PIVOT + side, hinge + side, 0.2, 0.45, "loader_paint")
        box_between(b, (1.25, s * 0.72, 1.0), 0.55 * ARM_PIVOT + 0.45 * hinge + side - (0, 0, 0.25), 0.18, 0.18,
                    "steel_galvanized")  # lift cylinder
    b.cylinder(0.12, 0.5 * (ARM_PIVOT + hinge) + (0, -0.72, 0), 0.5 * (ARM_PIVOT + hinge) + (0, 0.72, 0), segments=10,
               material="loader_paint")  # cross tube
    box_between(b, ARM_PIVOT + (0.2, 0, 0.55), hinge + (0.05, 0, 0.5), 0.25, 0.3, "loader_paint")  # tilt link
    x, z = hinge[0], hinge[2]
    b.box((BUCKET_DEPTH, width, 0.05), (x + BUCKET_DEPTH / 2 + 0.05, 0, z - BUCKET_DROP + 0.025), material="steel_dark")  # floor
    box_between(b, (x, 0, z + 0.55), (x - 0.02, 0, z - 0.35), width, 0.07, "loader_paint")  # back wall
    box_between(b, (x - 0.02, 0, z - 0.35), (x + 0.3, 0, z - BUCKET_DROP + 0.05), width, 0.07, "loader_paint")  # its curve
    for s in (-1, 1):
        side = [(x, z + 0.55), (x, z - BUCKET_DROP), (x + BUCKET_DEPTH + 0.05, z - BUCKET_DROP), (x + 0.5, z + 0.55)]
        b.prism(side, 0.05, offset=(0, s * (width / 2 - 0.025), 0), material="loader_paint")


def loader(rng: np.random.Generator) -> Asset:
    """A wheel loader: four 1.55-1.7 m tyres on a 3.2-3.45 m wheelbase (2.8 m wide over
    them), cab 3.3-3.5 m high, lift arms raising a 2.5-3 m wide bucket's hinge to 0.65-3.9 m
    (the bucket lowered to the ground or carried up to dumping height); 7.3-8.5 m long."""
    wheelbase = rng.uniform(3.2, 3.45)
    tyre_r = rng.uniform(0.775, 0.85)
    height = rng.uniform(3.3, 3.5)
    width = rng.uniform(2.5, 3.0)
    arm = rng.uniform(2.7, 3.0)
    hinge_z = rng.uniform(BUCKET_DROP + 0.02, 3.9)
    rise = hinge_z - ARM_PIVOT[2]
    angle = atan2(rise, np.sqrt(arm * arm - rise * rise))
    s, c = sincos(angle)
    hinge = ARM_PIVOT + arm * np.array([c, 0.0, s])
    b = MeshBuilder()
    rear = loader_frames(b, wheelbase, tyre_r, height)
    lift_arms(b, hinge, width)
    info = {"length": float(hinge[0] + BUCKET_DEPTH + 0.05 - rear), "bucket_width": float(width), "hinge_height": float(hinge_z),
            "bucket_lowest": float(hinge_z - BUCKET_DROP), "arm_angle_deg": float(np.degrees(angle)),
            "tyre_diameter": float(2 * tyre_r), "height": float(height)}
    return standing_asset("Loader", [b.build()], info)


register(AssetKind(
    name="Loader", classes=("Loader",), build=loader, place=Scatter(follow_layout=False, tries=300),
    order=BEFORE_PROPS + 3,  # as the mobile cranes (mobile_cranes.BEFORE_PROPS)
    counts={"small": (0, 1), "medium": (0, 1), "large": (0, 2)},
    materials=(Material("loader_paint", (0.82, 0.57, 0.02), 0.4, 0.2, Pattern(5.0, (0.38, 0.3, 0.12), 0.25), layers=(STREAKS,)),),
    stage=Relocates(P_MOVES, near=True),
))
