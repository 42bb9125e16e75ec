"""Streets beyond the fence, the cars parked on them and their street lights.

- ``Street`` (class ``Ground``: it is ground, as the site's own road is): a carriageway of
  asphalt with a dashed centre line, between kerbed sidewalks of paving slabs (none on a
  country road), draped over the terrain (its top follows the ground's height at every
  2 m; its sides reach 0.3 m below);
- ``Car`` (class ``Car``): a parked car 3.9-4.8 m long, 1.7-1.85 m wide, 1.4-1.55 m high,
  in one of six paints;
- ``StreetLight`` (class ``StreetLight``): a galvanised column 6-9 m high with an arm
  reaching 1-1.8 m over the carriageway and a lantern.

The surroundings place them (:mod:`generator.scene.catalogue.surroundings`)."""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..assets import Asset, Part
from ..kinds import AssetKind, register
from ..materials import Material, Pattern
from ..meshes import MeshBuilder
from ..surroundings import SURROUNDINGS

SIDEWALK_UP_M = 0.15  # top of a sidewalk above the ground
ROAD_UP_M = 0.04  # top of a carriageway above the ground
SKIRT_M = 0.3  # the street's sides reach this far below the ground
STEP_M = 2.0  # rows of the street along its length (and its centre-line dashes)
CAR_PAINTS = ("car_red", "car_white", "car_silver", "car_black", "car_blue", "car_green")


def street_profile(sidewalk: float, carriageway: float) -> list[tuple[float, float, str]]:
    """The cross-section from the site's side (+y) to the far side: (y, height above the
    ground, material of the face from the previous point), in the street's frame."""
    half = sidewalk + carriageway / 2
    pts = [(half, -SKIRT_M, "")]
    if sidewalk > 0:
        pts += [(half, SIDEWALK_UP_M, "paving"), (half - sidewalk, SIDEWALK_UP_M, "paving"), (half - sidewalk, ROAD_UP_M, "kerb")]
    else:
        pts += [(half, ROAD_UP_M, "asphalt")]
    pts += [(0.08, ROAD_UP_M, "asphalt"), (-0.08, ROAD_UP_M, "marking"), (sidewalk - half, ROAD_UP_M, "asphalt")]
    if sidewalk > 0:
        pts += [(sidewalk - half, SIDEWALK_UP_M, "kerb"), (-half, SIDEWALK_UP_M, "paving")]
    return pts + [(-half, -SKIRT_M, "paving" if sidewalk > 0 else "asphalt")]


def street(rng: np.random.Generator, length: float = 60.0, sidewalk: float = 2.0, carriageway: float = 7.0,
           ground: Callable[[np.ndarray], np.ndarray] | None = None) -> Asset:
    """A straight street ``length`` metres along x, centred on the origin: ``sidewalk``
    metres of paving on each side (0: none), a ``carriageway`` of asphalt with a dashed
    centre line (2 m dashes, 2 m gaps). ``ground(xy)`` gives the ground's height at the
    street's points (N, 2) in its frame (None: level at z = 0); the top follows it."""
    profile = street_profile(sidewalk, carriageway)
    xs = np.linspace(-length / 2, length / 2, max(2, int(np.ceil(length / STEP_M)) + 1))
    ys = np.array([p[0] for p in profile])
    xy = np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1).reshape(-1, 2)
    z = (np.zeros(len(xy)) if ground is None else np.asarray(ground(xy), float)).reshape(len(xs), len(ys))
    z = z + np.array([p[1] for p in profile])
    verts = np.column_stack([xy, z.ravel()])
    m = len(ys)
    b = MeshBuilder()
    n = len(xs)
    rows = np.arange(n - 1)
    for j in range(m - 1):  # one strip of quads per segment of the profile, top faces up
        strip = np.concatenate([verts[j::m], verts[j + 1::m]])  # the segment's two edges, row by row
        quads = np.stack([rows, rows + n, rows + n + 1, rows + 1], 1)
        material = profile[j + 1][2]
        if material == "marking":  # dashes on the even rows
            b.add(strip, quads=quads[1::2], material="asphalt")
            b.add(strip, quads=quads[0::2], material="marking")
        else:
            b.add(strip, quads=quads, material=material)
    for i, sign in ((0, 1), (len(xs) - 1, -1)):  # the ends, down to the skirt
        for j in range(m - 1):
            (y0, z0), (y1, z1) = (ys[j], z[i, j]), (ys[j + 1], z[i, j + 1])
            if abs(y1 - y0) < 1e-9:
                continue
            zb = min(z0, z1) - SKIRT_M
            quad = [(xs[i], y0, z0), (xs[i], y0, zb), (xs[i], y1, zb), (xs[i], y1, z1)]
            b.add(quad if sign > 0 else quad[::-1], quads=[(0, 1, 2, 3)], material="kerb")
    return Asset("Street", [Part("Ground", b.build())], (length, 2 * sidewalk + carriageway),
                 info={"sidewalk": sidewalk, "carriageway": carriageway})


def car(rng: np.random.Generator) -> Asset:
    """A parked car along x (its front at +x): body, cabin with windows, four wheels,
    lights."""
    length, width, high = rng.uniform(3.9, 4.8), rng.uniform(1.7, 1.85), rng.uniform(1.4, 1.55)
    paint = CAR_PAINTS[int(rng.integers(len(CAR_PAINTS)))]
    r, clear = 0.31, 0.18
    b = MeshBuilder()
    waist = 0.62 * high
    b.box((length, width, waist - clear), (0, 0, (waist + clear) / 2), material=paint)
    hood, boot = rng.uniform(0.9, 1.2), rng.uniform(0.5, 0.9)
    x0, x1 = -length / 2 + boot, length / 2 - hood  # the cabin's foot
    cabin = [(x0, waist), (x1, waist), (x1 - 0.55, high), (x0 + 0.35, high)]
    b.prism(cabin, width - 0.1, material=paint)
    glass = [(x0 + 0.12, waist + 0.05), (x1 - 0.1, waist + 0.05), (x1 - 0.6, high - 0.06), (x0 + 0.42, high - 0.06)]
    b.prism(glass, width - 0.06, material="glass")
    for sx in (-1, 1):
        for sy in (-1, 1):
            y = sy * (width / 2 - 0.12)
            b.cylinder(r, (sx * (length / 2 - 0.75), y - 0.11, r), (sx * (length / 2 - 0.75), y + 0.11, r), segments=16,
                       material="rubber")
        for sy in (-1, 1):
            b.box((0.03, 0.35, 0.12), (sx * (length / 2 + 0.01), sy * (width / 2 - 0.3), waist - 0.12),
                  material="plastic_white" if sx > 0 else "tail_light")
    return Asset("Car", [Part("Car", b.build())], (length + 0.1, width + 0.1), info={"length": float(length)})


def street_light(rng: np.random.Generator) -> Asset:
    """A street light: a column 6-9 m high on a 0.5 m footing sunk into the ground, an arm
    reaching 1-1.8 m along +y (over the carriageway), a lantern at its end."""
    high, reach = rng.uniform(6.0, 9.0), rng.uniform(1.0, 1.8)
    b = MeshBuilder()
    b.cone(0.09, 0.06, (0, 0, -0.5), (0, 0, high), segments=10, material="steel_galvanized")
    b.box((0.3, 0.3, 0.6), (0, 0, -0.2), material="concrete")
    b.cylinder(0.04, (0, 0, high - 0.1), (0, reach, high + 0.15), segments=8, material="steel_galvanized")
    b.box((0.28, 0.6, 0.12), (0, reach + 0.2, high + 0.1), material="steel_galvanized")
    b.box((0.22, 0.5, 0.02), (0, reach + 0.2, high + 0.03), material="plastic_white")
    span = reach + 0.55
    return Asset("StreetLight", [Part("StreetLight", b.build(), location=(0.0, -span / 2 + 0.15, 0.0))],
                 (0.4, span + 0.3), info={"height": float(high)})


def paint(name: str, colour) -> Material:
    """Car paint: glossy, a faint mottle of dust."""
    return Material(name, colour, 0.25, 0.3, Pattern(6.0, tuple(c * 0.8 for c in colour), 0.15))


register(AssetKind(
    name="Street", classes=("Ground",), build=street, place=SURROUNDINGS, scenery=True, order=2003,
    materials=(Material("paving", (0.42, 0.4, 0.37), 0.85, 0.0, Pattern(2.5, (0.3, 0.29, 0.27), 0.35, kind="voronoi"),
                        layers=(Pattern(15.0, (0.5, 0.48, 0.45), 0.3, detail=2.0),), planar=True),
               Material("kerb", (0.5, 0.49, 0.46), 0.8, 0.0, Pattern(8.0, (0.36, 0.35, 0.33), 0.4)),
               Material("marking", (0.75, 0.75, 0.72), 0.6, 0.0, Pattern(10.0, (0.4, 0.4, 0.38), 0.35), planar=True)),
))
register(AssetKind(
    name="Car", classes=("Car",), build=car, place=SURROUNDINGS, scenery=True, order=2004,
    materials=tuple(paint(n, c) for n, c in zip(CAR_PAINTS, ((0.5, 0.03, 0.02), (0.75, 0.75, 0.73), (0.42, 0.43, 0.45),
                                                              (0.02, 0.02, 0.025), (0.04, 0.1, 0.35), (0.05, 0.2, 0.1))))
    + (Material("tail_light", (0.6, 0.02, 0.01), 0.3),),
))
register(AssetKind(
    name="StreetLight", classes=("StreetLight",), build=street_light, place=SURROUNDINGS, scenery=True, order=2005,
))
