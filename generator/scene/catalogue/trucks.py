"""Trucks (three-axle dump trucks and concrete mixers) driving the site's road loop with
rolling wheels; they stay as they are over a timeline's stages."""

from __future__ import annotations

import numpy as np

from ...geometry.portable_math import atan2, sincos
from ...geometry.seeding import stream
from ..assets import Asset, Footprint, Keyframes, Part
from ..kinds import AssetKind, register
from ..materials import Material, Pattern
from ..meshes import MeshBuilder, rotation_y
from ..placement import PlacedAsset
from ..planning import Custom

WHEEL_R = 0.525
WHEEL_W = 0.4


def wheel() -> MeshBuilder:
    """A wheel centred on its origin, axle along local y."""
    w = MeshBuilder()
    core = WHEEL_R - 0.02
    w.cylinder(core, (0, -WHEEL_W / 2, 0), (0, WHEEL_W / 2, 0), segments=32, material="rubber")
    for a in np.arange(0, 2 * np.pi, 2 * np.pi / 24):  # tread blocks, outer corners within WHEEL_R
        s, c = sincos(a)
        mid = core + 0.0075  # blocks span [core - 0.004, WHEEL_R - 0.001] radially
        w.box((0.06, WHEEL_W - 0.04, 0.023), (c * mid, 0, s * mid), rotation=rotation_y(-a + np.pi / 2), material="rubber")
    for s in (-1, 1):
        w.cylinder(0.28, (0, s * WHEEL_W / 2, 0), (0, s * (WHEEL_W / 2 + 0.02), 0), segments=12, material="steel_painted")
    return w


def route_poses(points: np.ndarray, speed: float, frames: int, fps: float, offset: float) -> tuple:
    """Keyframes for driving a closed polyline at ``speed`` m/s from ``offset`` metres along it.

    Every segment gets a key at its start and one 5 cm before its end with the segment's
    heading, so the vehicle drives straight along segments and turns at vertices (routes
    have rounded corners sampled every few degrees). Returns (frames (K,), xy (K, 2),
    yaw (K,) unwrapped radians, distance driven (K,) metres).
    """
    seg = np.diff(np.vstack([points, points[:1]]), axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    heading = atan2(seg[:, 1], seg[:, 0])
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    perimeter = cum[-1]
    total = speed * (frames - 1) / fps
    s0 = offset % perimeter
    laps = int(np.ceil((s0 + total) / perimeter)) + 1
    delta = np.minimum(0.05, seg_len / 4)
    keys_s, keys_seg = [], []
    for lap in range(laps):
        for i in range(len(seg)):
            a = lap * perimeter + cum[i]
            keys_s += [a, a + seg_len[i] - delta[i]]
            keys_seg += [i, i]
    keys_s, keys_seg = np.array(keys_s), np.array(keys_seg)
    inside = (keys_s > s0) & (keys_s < s0 + total)
    s = np.concatenate([[s0], keys_s[inside], [s0 + total]])
    which = np.concatenate([[-1], keys_seg[inside], [-1]])
    for k in (0, len(s) - 1):  # boundary keys take the segment they fall in
        local = s[k] % perimeter
        which[k] = min(np.searchsorted(cum, local, side="right") - 1, len(seg) - 1)
    local = s % perimeter
    local = np.where(np.isclose(local, perimeter), 0.0, local)
    frac = np.clip((s - np.floor(s / perimeter) * perimeter - cum[which]) / seg_len[which], 0.0, 1.0)
    xy = points[which] + frac[:, None] * seg[which]
    yaw = np.unwrap(heading[which])
    key_frames = 1 + (s - s0) / speed * fps
    return key_frames, xy, yaw, s - s0


def truck(rng: np.random.Generator, kind: str, route: np.ndarray, speed: float, offset: float, frames: int, fps: float) -> Asset:
    """A three-axle dump truck (8-9 m long, about 3.3 m tall, a ~5 m tipper) or concrete
    mixer (9-10 m, about 3.9 m tall), 2.5 m wide, driving the closed
    ``route`` (polyline, metres) at ``speed`` m/s; its wheels roll (rotation = distance /
    radius) and a mixer's drum turns."""
    length = rng.uniform(8.0, 9.0) if kind == "dump" else rng.uniform(9.0, 10.0)
    cab_h = 2.05 if kind == "dump" else 2.3  # cab from 1.25 m up: tops at 3.3 and 3.55 m
    body = MeshBuilder()
    paint = "truck_paint"
    body.box((length - 0.4, 0.9, 0.35), (0, 0, 0.95), material="steel_dark")  # chassis
    cab_x = length / 2 - 1.2
    body.box((2.2, 2.5, cab_h), (cab_x, 0, 1.25 + cab_h / 2), material=paint)  # cab
    body.box((0.05, 2.1, 0.9), (cab_x + 1.11, 0, 1.25 + cab_h - 0.65), material="glass")  # windscreen
    body.box((0.3, 2.4, 0.35), (length / 2 - 0.05, 0, 0.85), material="steel_dark")  # bumper
    for s in (-1, 1):  # fenders over the front wheels
        body.box((1.3, 0.45, 0.08), (cab_x + 0.1, s * 1.05, 1.2), material=paint)
    parts = [Part("Truck", None)]  # filled below
    drum_part = None
    if kind == "dump":
        bl, bw, bh = length - 3.5, 2.4, rng.uniform(1.2, 1.4)  # tipper 4.5-5.5 m
        bx = -length / 2 + bl / 2 + 0.2
        z0 = 1.15
        body.box((bl, bw, 0.1), (bx, 0, z0 + 0.05), material=paint)
        for s in (-1, 1):
            body.box((bl, 0.08, bh), (bx, s * (bw / 2 - 0.04), z0 + 0.1 + bh / 2), material=paint)
        body.box((0.08, bw - 0.16, bh), (bx - bl / 2 + 0.04, 0, z0 + 0.1 + bh / 2), material=paint)
        body.box((0.08, bw - 0.16, bh + 0.4), (bx + bl / 2 - 0.04, 0, z0 + 0.1 + (bh + 0.4) / 2), material=paint)
    else:
        body.box((0.3, 1.2, 1.57), (cab_x - 1.4, 0, 1.1 + 1.57 / 2), material="steel_dark")  # drum stand, front
        body.box((0.3, 1.2, 1.17), (-length / 2 + 0.6, 0, 1.1 + 1.17 / 2), material="steel_dark")  # drum stand, rear
        drum = MeshBuilder()
        dl = rng.uniform(4.3, 4.8)
        drum.cone(0.7, 1.15, (-dl / 2, 0, 0), (0.2, 0, 0), segments=24, material="mixer_drum")
        drum.cone(1.15, 0.45, (0.2, 0, 0), (dl / 2, 0, 0), segments=24, material="mixer_drum")
        # the drum's axis rises towards the rear at about 15 degrees
        drum_part = Part("Truck", drum.build(), location=(-0.6, 0, 2.62), rotation=(0.0, np.radians(15), 0.0))
    parts[0] = Part("Truck", body.build())

    key_frames, xy, yaw, dist = route_poses(route, speed, frames, fps, offset)
    parts[0].keys = Keyframes(key_frames, location=np.column_stack([xy, np.zeros(len(xy))]),
                              rotation=np.column_stack([np.zeros((len(xy), 2)), yaw]))
    spin = dist / WHEEL_R  # rolling without slipping
    for x in (cab_x + 0.1, -length / 2 + 2.2, -length / 2 + 0.85):
        for s in (-1, 1):
            y = s * (1.25 - WHEEL_W / 2)
            parts.append(Part("Truck", wheel().build(), location=(x, y, WHEEL_R), parent=0,
                              keys=Keyframes(key_frames, rotation=np.column_stack([np.zeros(len(spin)), spin, np.zeros(len(spin))]))))
    if drum_part is not None:
        drum_spin = np.linspace(0, rng.uniform(0.2, 0.4) * 2 * np.pi * (frames - 1) / fps, 2)  # 12-24 rpm
        drum_part.parent = 0
        drum_part.keys = Keyframes(np.array([1, frames]), rotation=np.column_stack([drum_spin, np.full(2, np.radians(15)), np.zeros(2)]))
        parts.append(drum_part)
    return Asset("Truck", parts, (length, 2.5), placement=None, moves=True, info={"kind": kind, "speed_m_s": speed})


def plan_trucks(site, kind: AssetKind) -> None:
    """Trucks on the road loop, evenly spaced, all at one speed (so they never catch up)."""
    plan, params = site.plan, site.params
    n_trucks = site.count(kind)
    perimeter = float(np.sum(np.linalg.norm(np.diff(np.vstack([plan.road, plan.road[:1]]), axis=0), axis=1)))
    speed = float(site.rng.uniform(3.0, 5.0))
    for k in range(n_trucks):
        trng = stream(site.seed, "asset", kind.name, k)
        offset = perimeter * k / max(n_trucks, 1) + float(trng.uniform(0, 0.2 * perimeter / max(n_trucks, 1)))
        body = "dump" if trng.random() < 0.5 else "mixer"
        asset = truck(trng, body, plan.road, speed, offset, params.frames, params.fps)
        plan.placed.append(PlacedAsset(asset, (0.0, 0.0), 0.0, Footprint((0.0, 0.0), (0.0, 0.0))))


register(AssetKind(
    name="Truck", classes=("Truck",), build=truck, place=Custom(plan_trucks), order=40, count_param="trucks",
    counts={"small": (1, 1), "medium": (2, 3), "large": (3, 5)},
    materials=(Material("truck_paint", (0.7, 0.25, 0.03), 0.35, 0.3, Pattern(4.0, (0.3, 0.22, 0.15), 0.2)),
               Material("mixer_drum", (0.75, 0.75, 0.72), 0.4, 0.3, Pattern(5.0, (0.45, 0.42, 0.38), 0.4))),
    motion="drives the road loop at the site's one truck speed (3-5 m/s), wheels rolling; a mixer's drum turns at 12-24 rpm",
    shared_streams=True,
))
