"""Tower cranes: one beside each building, sized to the site and the buildings, slewing
with a travelling trolley; over a timeline's stages they turn to a new heading."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...geometry.portable_math import sincos, vector_norm
from ...geometry.seeding import stream
from ..assets import Asset, Footprint, Keyframes, Part
from ..kinds import AssetKind, register
from ..materials import STREAKS, Material, Pattern
from ..meshes import MeshBuilder
from ..planning import Custom
from ..timeline import Rebuilt

P_SLEW = 0.8  # chance a crane turns to a new heading at a stage
FOOTPRINT = (6.0, 6.0)  # metres: the concrete foundation, what a crane takes on the ground

# A tower crane's trolley runs along the jib at up to 1-1.7 m/s; ours at 1 m/s, stopping
# 2 s at each stop (hooking or setting down a load), whatever the animation's length.
TROLLEY_SPEED = 1.0  # m/s
TROLLEY_DWELL = 2.0  # s


def lattice_member(b: MeshBuilder, p0, p1, radius: float, material: str) -> None:
    b.cylinder(radius, p0, p1, segments=8, material=material)


def trolley_travel(stops: np.ndarray, frames: int, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Keys (frames (K,) float, positions (K,) metres along the jib) of a trolley starting at
    ``stops[0]`` at frame 1 and visiting the other stops in turn at :data:`TROLLEY_SPEED`,
    waiting :data:`TROLLEY_DWELL` at each arrival; cut at frame ``frames`` (``fps`` frames a
    second)."""
    times, xs = [0.0], [float(stops[0])]
    for x in stops[1:]:
        arrive = times[-1] + abs(float(x) - xs[-1]) / TROLLEY_SPEED
        times += [arrive, arrive + TROLLEY_DWELL]
        xs += [float(x), float(x)]
    end = (frames - 1) / fps
    keep = [i for i, t in enumerate(times) if t < end] or [0]
    times_kept, xs_kept = [times[i] for i in keep], [xs[i] for i in keep]
    if end > times_kept[-1]:
        times_kept.append(end)
        xs_kept.append(float(np.interp(end, times, xs)))
    return 1.0 + np.array(times_kept) * fps, np.array(xs_kept)


def crane_mast(side: float, section: float, mast_top: float) -> MeshBuilder:
    """Concrete foundation and a square lattice mast (``side`` wide, K-braced every ``section``)."""
    a = side / 2
    mast = MeshBuilder()
    mast.box((6.0, 6.0, 1.0), (0, 0, 0.5), material="concrete")
    for sx in (-a, a):
        for sy in (-a, a):
            mast.box((0.18, 0.18, mast_top - 1.0), (sx, sy, (mast_top + 1.0) / 2), material="crane_paint")
    levels = np.arange(1.0, mast_top + 1e-6, section)
    corners = [(-a, -a), (a, -a), (a, a), (-a, a)]
    for k, z in enumerate(levels):
        for c in range(4):
            p, q = corners[c], corners[(c + 1) % 4]
            lattice_member(mast, (p[0], p[1], z), (q[0], q[1], z), 0.05, "crane_paint")
            if k + 1 < len(levels):
                z2 = levels[k + 1]
                zm = (z + z2) / 2
                lattice_member(mast, (p[0], p[1], z), (q[0], q[1], zm), 0.045, "crane_paint")  # K-bracing
                lattice_member(mast, (q[0], q[1], zm), (p[0], p[1], z2), 0.045, "crane_paint")
    return mast


def crane_slewing_part(side: float, jib_length: float, jib_h: float, counter: float, n_weights: int) -> MeshBuilder:
    """Slewing ring, cab, lattice jib (``jib_h`` high) and counter-jib (``counter`` long) with
    walkway, railings and ``n_weights`` pairs of concrete counterweights."""
    a = side / 2
    slew = MeshBuilder()
    slew.cylinder(side * 0.8, (0, 0, 0), (0, 0, 1.0), segments=20, material="crane_paint")
    slew.box((2.0, 1.6, 2.2), (0.3, -(a + 0.9), 1.1 + 0.2), material="crane_paint")  # cab
    slew.box((0.05, 1.4, 1.2), (1.31, -(a + 0.9), 1.6), material="glass")  # cab window
    bl, br, tp = (0, -0.8, 1.0), (0, 0.8, 1.0), (0, 0, 1.0 + jib_h)
    xs = np.arange(0.0, jib_length + 1e-6, 2.0)
    for chord in (bl, br, tp):
        slew.box((jib_length + counter, 0.14, 0.14), ((jib_length - counter) / 2, chord[1], chord[2]), material="crane_paint")
    for k in range(len(xs) - 1):
        x, x2 = xs[k], xs[k + 1]
        for p, q in ((bl, tp), (br, tp), (bl, br)):
            lattice_member(slew, (x, p[1], p[2]), (x2, q[1], q[2]), 0.04, "crane_paint")
    slew.box((counter, 1.9, 0.12), (-counter / 2, 0, 0.96), material="steel_painted")  # walkway
    for k in range(n_weights):  # concrete slabs (0.95 x 1.8 x 0.5), two high, on the bottom chords:
        for lev in range(2):  # between the railings (|y| < 0.925) and under the top chord
            slew.box((0.95, 1.8, 0.49), (-counter + 0.6 + k * 1.0, 0, 1.07 + 0.25 + lev * 0.5), material="concrete")
    slew.box((counter, 0.05, 1.0), (-counter / 2, 0.95, 1.5), material="steel_painted")  # railing panels
    slew.box((counter, 0.05, 1.0), (-counter / 2, -0.95, 1.5), material="steel_painted")
    return slew


def crane_trolley_and_hook(mast_top: float, hook_height: float) -> tuple[MeshBuilder, MeshBuilder]:
    """The trolley and the hook block hanging on its cables at ``hook_height``."""
    trolley = MeshBuilder()
    trolley.box((1.4, 1.8, 0.5), (0, 0, -0.25), material="crane_paint")
    drop = (mast_top + 1.0 - 0.07 - 0.5) - hook_height  # trolley bottom to hook block top
    hook = MeshBuilder()
    for y in (-0.25, 0.25):
        hook.cylinder(0.018, (0, y, -0.01), (0, y, -drop), segments=6, material="steel_cable")
    hook.box((0.7, 0.7, 0.9), (0, 0, -drop - 0.45), material="crane_hook")
    hook.cone(0.12, 0.05, (0, 0, -drop - 0.9), (0, 0, -drop - 1.4), segments=10, material="steel_painted")
    return trolley, hook


@dataclass(frozen=True, eq=False)
class CraneDraws:
    """Everything a tower crane draws from its stream, in the order it draws it (metres,
    radians, radians a second)."""

    side: float
    section: float
    jib_h: float
    counter: float
    n_weights: int
    omega: float
    yaw0: float
    stops: np.ndarray

    @staticmethod
    def draw(rng: np.random.Generator, jib_length: float) -> CraneDraws:
        side, section = rng.uniform(1.6, 2.2), rng.uniform(3.0, 5.0)
        jib_h, counter, n_weights = rng.uniform(1.4, 2.0), rng.uniform(12.0, 18.0), int(rng.integers(3, 6))
        omega = rng.uniform(0.3, 0.9) * 2 * np.pi / 60 * rng.choice([-1, 1])  # rad/s, under 1 turn/min
        yaw0 = rng.uniform(0, 2 * np.pi)
        return CraneDraws(side, section, jib_h, counter, n_weights, omega, yaw0, rng.uniform(6.0, jib_length - 2.0, 4))


def tower_crane(rng: np.random.Generator, hook_height: float, jib_length: float, frames: int, fps: float,
                slew_offset: float = 0.0) -> Asset:
    """A flat-top tower crane: lattice mast on a concrete foundation, slewing jib and
    counter-jib with concrete counterweights, cab, a trolley moving along the jib and a hook
    block hanging at ``hook_height`` metres. It slews at 0.3-0.9 turns per minute, starting
    ``slew_offset`` radians from its drawn heading (a later stage of a timeline)."""
    return crane_from(CraneDraws.draw(rng, jib_length), hook_height, jib_length, frames, fps, slew_offset)


def crane_from(d: CraneDraws, hook_height: float, jib_length: float, frames: int, fps: float,
               slew_offset: float = 0.0) -> Asset:
    """The crane of :func:`tower_crane` built from its draws ``d``."""
    mast_top = hook_height + 6.0
    mast = crane_mast(d.side, d.section, mast_top)
    slew = crane_slewing_part(d.side, jib_length, d.jib_h, d.counter, d.n_weights)
    trolley, hook = crane_trolley_and_hook(mast_top, hook_height)
    # animation: slewing (linear), trolley travel (piecewise linear, seeded)
    yaw0 = d.yaw0 + slew_offset
    slew_keys = Keyframes(np.array([1, frames]), rotation=np.array([[0, 0, yaw0], [0, 0, yaw0 + d.omega * (frames - 1) / fps]]))
    key_frames, xs_trolley = trolley_travel(d.stops, frames, fps)
    n_keys = len(key_frames)
    trolley_keys = Keyframes(key_frames, location=np.stack([xs_trolley, np.zeros(n_keys), np.full(n_keys, 1.0 - 0.07)], 1))
    parts = [
        Part("Crane", mast.build()),
        Part("", None, location=(0, 0, mast_top), keys=slew_keys),  # slewing pivot (an empty)
        Part("Crane", slew.build(), parent=1),
        Part("Crane", trolley.build(), location=(xs_trolley[0], 0, 1.0 - 0.07), parent=2, keys=trolley_keys),
        Part("Crane", hook.build(), parent=3),
    ]
    return Asset("Crane", parts, FOOTPRINT, moves=False, footprint_from_geometry=False,
                 info={"hook_height": hook_height, "jib_length": jib_length, "counter_jib": d.counter, "mast_top": mast_top,
                       "top": mast_top + 1.0 + d.jib_h + 0.07,
                       "slew_rad_per_s": d.omega})


def slew_offset(seed: int, crane: int, stage: int) -> float:
    """Heading (radians) crane ``crane`` has turned by at ``stage`` from stage 0."""
    offset = 0.0
    for s in range(1, stage + 1):
        r = stream(seed, "timeline", s, "Crane", crane)
        if r.random() < P_SLEW:
            offset = float(r.uniform(0.0, 2 * math.pi))
    return offset


def crane_spot(crng: np.random.Generator, fp, hook_height: float, cranes: list) -> tuple | None:
    """A drawn mast position beside the building footprint ``fp``, its jib (reaching the far
    corner, 20-60 m) and hook height: None if its jib circle would reach another crane's mast.
    Cranes whose jib circles overlap otherwise are stacked: the new one hangs its hook 3 m
    above the other's jib."""
    side = crng.choice([-1, 1])
    along = crng.uniform(-0.4, 0.4) * fp.size[0]
    offset = fp.size[1] / 2 + 5.5
    s, c = sincos(fp.yaw)
    pos = np.array(fp.center) + np.array([c * along - s * side * offset, s * along + c * side * offset])
    far = max(np.linalg.norm(fp.corners() - pos, axis=1))
    jib = float(np.clip(far + 3.0, 20.0, 60.0))
    hook = hook_height
    for q, reach, top in cranes:
        d = vector_norm(pos - q)
        if d >= jib + reach + 4.0:
            continue
        if d >= max(jib, reach) + 3.0:
            hook = max(hook, top + 3.0)
        else:
            return None
    return pos, jib, hook


def plan_cranes(site, kind: AssetKind) -> None:
    """One tower crane per building, 5.5 m off one of its long sides (100 tries), built for
    the plan's stage (its heading turned by :func:`slew_offset`)."""
    plan, params = site.plan, site.params
    cranes: list[tuple[np.ndarray, float, float]] = []  # (mast position, jib reach, top height)
    for k, b in enumerate(site.buildings):
        crng = stream(site.seed, "asset", kind.name, k)
        for _ in range(100):
            spot = crane_spot(crng, b.footprint, plan.hook_height, cranes)
            if spot is None:
                continue
            pos, jib, hook = spot
            draws = CraneDraws.draw(crng, jib)
            yaw = float(crng.uniform(0, math.pi / 2))
            fp = Footprint((float(pos[0]), float(pos[1])), FOOTPRINT, yaw)  # footprint_at's, without the meshes
            if not site.placer.fits(fp):
                continue  # its meshes are built only where it fits (they take most of a plan's time)
            asset = crane_from(draws, hook, jib, params.frames, params.fps,
                               slew_offset(site.seed, k, plan.stage) if plan.stages > 1 else 0.0)
            plan.placed.append(site.placer.take(asset, pos, yaw, fp))
            cranes.append((pos, jib + 1.0, asset.info["top"]))
            break
        else:
            site.skip(kind.name)


register(AssetKind(
    name="Crane", classes=("Crane",), build=tower_crane, place=Custom(plan_cranes), order=20,
    materials=(Material("steel_cable", (0.1, 0.1, 0.1), 0.4, 1.0),
               Material("crane_paint", (0.8, 0.55, 0.02), 0.45, 0.2, Pattern(6.0, (0.5, 0.35, 0.05), 0.2), layers=(STREAKS,)),
               Material("crane_hook", (0.8, 0.1, 0.05), 0.4, 0.2)),
    motion="slews at 0.3-0.9 turns a minute; the trolley travels the jib at 1 m/s between seeded stops",
    stage=Rebuilt(f"turns to a new heading at a stage with probability {P_SLEW}"),
    shared_streams=True,
))
