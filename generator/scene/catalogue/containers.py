"""Shipping containers (20 and 40 ft, corrugated), side by side and stacked up to three high,
in the band along the fence; a new stack may arrive at a stage of a timeline."""

from __future__ import annotations

import numpy as np

from ..assets import Asset, Part
from ..kinds import AssetKind, register
from ..materials import SCRATCHES, STREAKS, Material, Pattern
from ..meshes import MeshBuilder
from ..planning import Mix
from ..timeline import Arrives

CONTAINER_COLOURS = ("container_blue", "container_red", "container_green", "container_grey", "container_orange", "container_white")


def container_mesh(length: float, colour: str) -> MeshBuilder:
    """A corrugated ISO container of ``length`` (6.06 or 12.19 m), 2.44 wide, 2.59 tall,
    origin at the centre of its floor."""
    w, h = 2.44, 2.59
    b = MeshBuilder()
    b.box((length - 0.3, w - 0.1, h - 0.2), (0, 0, h / 2), material=colour)  # walls and roof
    for x in (-length / 2 + 0.075, length / 2 - 0.075):  # corner posts and end frames
        for y in (-w / 2 + 0.075, w / 2 - 0.075):
            b.box((0.15, 0.15, h), (x, y, h / 2), material=colour)
        b.box((0.15, w - 0.3, 0.15), (x, 0, 0.075), material=colour)
        b.box((0.15, w - 0.3, 0.15), (x, 0, h - 0.075), material=colour)
    for y in (-w / 2 + 0.075, w / 2 - 0.075):  # top and bottom side rails
        b.box((length - 0.3, 0.15, 0.15), (0, y, 0.075), material=colour)
        b.box((length - 0.3, 0.15, 0.15), (0, y, h - 0.075), material=colour)
    pitch = 0.28
    n = int((length - 0.5) / pitch)
    for k in range(n):  # corrugations on both long sides
        x = -(n - 1) * pitch / 2 + k * pitch
        for s in (-1, 1):
            b.box((0.14, 0.04, h - 0.35), (x, s * (w / 2 - 0.05 + 0.02), h / 2), material=colour)
    m = int((w - 0.5) / pitch)
    for k in range(n):  # roof corrugation
        x = -(n - 1) * pitch / 2 + k * pitch
        b.box((0.14, w - 0.4, 0.03), (x, 0, h - 0.1 + 0.015), material=colour)
    for k in range(m):  # corrugation on the closed end
        y = -(m - 1) * pitch / 2 + k * pitch
        b.box((0.04, 0.14, h - 0.35), (-length / 2 + 0.15 - 0.02, y, h / 2), material=colour)
    for y in (-0.7, -0.35, 0.35, 0.7):  # door locking bars
        b.cylinder(0.015, (length / 2 + 0.02, y, 0.25), (length / 2 + 0.02, y, h - 0.25), segments=6, material="steel_dark")
    return b


def container_stack(rng: np.random.Generator) -> Asset:
    """One to four containers side by side, each column stacked up to three high."""
    length = 6.06 if rng.random() < 0.6 else 12.19
    columns = int(rng.integers(1, 5))
    parts = []
    for c in range(columns):
        levels = int(rng.choice([1, 1, 2, 2, 3]))
        for lev in range(levels):
            colour = CONTAINER_COLOURS[int(rng.integers(len(CONTAINER_COLOURS)))]
            y = (c - (columns - 1) / 2) * 2.5
            parts.append(Part("Container", container_mesh(length, colour).build(), location=(0, y, lev * 2.59)))
    return Asset("Container", parts, (length, columns * 2.5 - 0.06))


RUST = Pattern(4.0, (0.3, 0.15, 0.07), 0.3)

register(AssetKind(
    name="Container", classes=("Container",), build=container_stack, place=Mix(weight=3, band=True), order=50,
    materials=(Material("container_blue", (0.04, 0.14, 0.4), 0.55, 0.3, RUST, layers=(STREAKS, SCRATCHES)),
               Material("container_red", (0.45, 0.05, 0.03), 0.55, 0.3, RUST, layers=(STREAKS, SCRATCHES)),
               Material("container_green", (0.05, 0.25, 0.1), 0.55, 0.3, RUST, layers=(STREAKS, SCRATCHES)),
               Material("container_grey", (0.3, 0.31, 0.32), 0.55, 0.3, RUST, layers=(STREAKS, SCRATCHES)),
               Material("container_orange", (0.7, 0.28, 0.03), 0.55, 0.3, RUST, layers=(STREAKS, SCRATCHES)),
               Material("container_white", (0.7, 0.7, 0.68), 0.55, 0.3, RUST, layers=(STREAKS, SCRATCHES))),
    stage=Arrives(p=0.5, slot=999, band=True, stream="container"), shared_streams=True,
))
