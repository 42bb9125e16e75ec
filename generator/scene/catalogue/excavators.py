"""Hydraulic excavators: placed inside the road loop, swinging and digging; parked
elsewhere at most stages of a timeline."""

from __future__ import annotations

import numpy as np

from ...geometry.camera import matmul_exact, rows_times
from ..assets import Asset, Keyframes, Part
from ..kinds import AssetKind, register
from ..materials import STREAKS, Material, Pattern
from ..meshes import MeshBuilder, rotation_y
from ..planning import Scatter
from ..timeline import Relocates

P_MOVES = 0.7  # chance an excavator is parked elsewhere at a stage


def bucket_lowest(boom, arm, bucket, geom) -> float:
    """Lowest z (metres) of the bucket for boom/arm/bucket angles (radians), by forward
    kinematics with the same rotations as the keyframes (boom about y by -angle, arm and
    bucket by +angle); swinging about z does not change heights."""
    pivot = np.array(geom["pivot_world"])
    lowest = np.inf
    for b, a, c in zip(boom, arm, bucket):
        r1 = rotation_y(-b)
        p_arm = pivot + rows_times(np.array([geom["boom"], 0, 0]), r1.T)  # r1 @ v, without BLAS
        r2 = matmul_exact(r1, rotation_y(a))
        p_bucket = p_arm + rows_times(np.array([geom["arm"], 0, 0]), r2.T)
        r3 = matmul_exact(r2, rotation_y(c))
        for corner in ((1.1, 0, -0.6), (0, 0, -0.8), (1.1, 0, 0.2)):
            lowest = min(lowest, (p_bucket + rows_times(np.array(corner, dtype=np.float64), r3.T))[2])
    return lowest


def excavator(rng: np.random.Generator, frames: int, fps: float) -> Asset:
    """A 20 t hydraulic excavator on tracks (4.5 m x 2.8 m): its upper body swings back and
    forth and its boom, arm and bucket go through a digging cycle above the ground."""
    tracks = MeshBuilder()
    for s in (-1, 1):
        y = s * 1.1
        tracks.box((3.6, 0.6, 0.9), (0, y, 0.45), material="steel_dark")
        for x in (-1.8, 1.8):
            tracks.cylinder(0.45, (x, y - 0.3, 0.45), (x, y + 0.3, 0.45), segments=16, material="steel_dark")
    tracks.box((2.6, 1.6, 0.3), (0, 0, 0.9), material="steel_dark")  # undercarriage frame
    tracks.cylinder(1.0, (0, 0, 1.0), (0, 0, 1.1), segments=20, material="steel_dark")  # slewing ring

    # the upper body sits on the slewing ring (its origin is the ring's top); cab top 3.0 m
    upper = MeshBuilder()
    upper.box((3.0, 2.5, 0.9), (-0.5, 0, 0.45), material="excavator_paint")
    upper.box((1.0, 2.5, 1.1), (-1.9, 0, 0.55), material="excavator_paint")  # counterweight
    upper.box((1.6, 0.95, 1.9), (0.4, 0.72, 0.95), material="excavator_paint")  # cab
    upper.box((0.05, 0.8, 1.0), (1.21, 0.72, 1.3), material="glass")
    upper.cylinder(0.08, (-1.2, -0.8, 0.9), (-1.2, -0.8, 1.9), segments=8, material="steel_dark")  # exhaust
    body_z = 1.1  # upper body origin above the ground: the slewing ring's top
    pivot = (1.0, -0.35, 0.6)  # boom foot in the upper body's frame
    geom = {"pivot_world": (pivot[0], pivot[1], body_z + pivot[2]), "boom": rng.uniform(5.2, 5.8), "arm": rng.uniform(2.6, 3.0)}
    boom = MeshBuilder().box((geom["boom"], 0.5, 0.6), (geom["boom"] / 2, 0, 0), material="excavator_paint")
    arm = MeshBuilder().box((geom["arm"], 0.35, 0.45), (geom["arm"] / 2, 0, 0), material="excavator_paint")
    bucket = MeshBuilder()
    bucket.prism([(0, 0.2), (0.2, -0.6), (1.1, -0.7), (1.1, 0.2)], 1.0, material="steel_dark")

    n = 6
    key_frames = np.linspace(1, frames, n).round().astype(int)
    boom_a = np.radians(rng.uniform(15, 45, n))
    arm_a = np.radians(rng.uniform(60, 110, n))
    bucket_a = np.radians(rng.uniform(20, 90, n))
    # keep the bucket at least 0.3 m above the ground over the whole cycle (sampled finely)
    fine = np.linspace(0, 1, 60)

    def sampled(a):
        return np.interp(fine, np.linspace(0, 1, n), a)

    for _ in range(40):
        if bucket_lowest(sampled(boom_a), sampled(arm_a), sampled(bucket_a), geom) >= 0.3:
            break
        boom_a = np.minimum(boom_a + np.radians(3), np.radians(60))
        arm_a = np.maximum(arm_a - np.radians(3), np.radians(30))
    swing = np.radians(rng.uniform(-40, 40, n))
    zeros = np.zeros(n)
    parts = [
        Part("Excavator", tracks.build()),
        Part("Excavator", upper.build(), location=(0, 0, body_z), parent=0,
             keys=Keyframes(key_frames, rotation=np.column_stack([zeros, zeros, swing]))),
        Part("Excavator", boom.build(), location=pivot, parent=1,
             keys=Keyframes(key_frames, rotation=np.column_stack([zeros, -boom_a, zeros]))),
        Part("Excavator", arm.build(), location=(geom["boom"], 0, 0), parent=2,
             keys=Keyframes(key_frames, rotation=np.column_stack([zeros, arm_a, zeros]))),
        Part("Excavator", bucket.build(), location=(geom["arm"], 0, 0), parent=3,
             keys=Keyframes(key_frames, rotation=np.column_stack([zeros, bucket_a, zeros]))),
    ]
    reach = 1.0 + geom["boom"] + geom["arm"] + 1.2
    lowest = bucket_lowest(sampled(boom_a), sampled(arm_a), sampled(bucket_a), geom)
    return Asset("Excavator", parts, (2 * reach, 2 * reach), info={"reach": reach, "bucket_lowest_z": lowest})


register(AssetKind(
    name="Excavator", classes=("Excavator",), build=excavator, place=Scatter(follow_layout=False, tries=300), order=30,
    count_param="excavators", counts={"small": (0, 1), "medium": (1, 1), "large": (1, 2)},
    materials=(Material("excavator_paint", (0.85, 0.55, 0.02), 0.4, 0.2, Pattern(5.0, (0.35, 0.3, 0.2), 0.25), layers=(STREAKS,)),),
    motion="swings its upper body and cycles boom, arm and bucket, the bucket kept 0.3 m above the ground",
    stage=Relocates(P_MOVES, near=True), shared_streams=True,
))
