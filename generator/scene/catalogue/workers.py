"""Groups of workers in hi-vis vests and hard hats, standing; they walk elsewhere at
about half the stages of a timeline."""

from __future__ import annotations

import numpy as np

from ..assets import Asset, Part
from ..kinds import AssetKind, register
from ..materials import Material
from ..meshes import MeshBuilder
from ..planning import Mix
from ..timeline import Relocates

P_MOVE = 0.5  # chance a group walks elsewhere at a stage


def workers(rng: np.random.Generator) -> Asset:
    """One to four workers (1.6-1.9 m) in hi-vis vests and hard hats, standing."""
    count = int(rng.integers(1, 5))
    parts = []
    for k in range(count):
        h = rng.uniform(1.6, 1.9)
        s = h / 1.75
        b = MeshBuilder()
        for y in (-0.1, 0.1):
            b.box((0.16 * s, 0.14 * s, 0.82 * s), (0, y * s, 0.41 * s), material="work_trousers")
            b.box((0.28 * s, 0.12 * s, 0.08 * s), (0.05 * s, y * s, 0.04 * s), material="rubber")  # boots
        b.box((0.26 * s, 0.42 * s, 0.58 * s), (0, 0, 0.82 * s + 0.29 * s), material="hivis")
        for y in (-0.26, 0.26):
            b.box((0.12 * s, 0.1 * s, 0.6 * s), (0, y * s, 0.82 * s + 0.26 * s), material="hivis")
        b.box((0.1 * s, 0.1 * s, 0.08 * s), (0, 0, 1.44 * s), material="skin")  # neck
        b.cone(0.1 * s, 0.09 * s, (0, 0, 1.48 * s), (0, 0, 1.68 * s), segments=10, material="skin")
        b.cone(0.14 * s, 0.08 * s, (0, 0, 1.64 * s), (0, 0, 1.75 * s), segments=12, material="hard_hat")
        parts.append(Part("Worker", b.build(), location=(0, (k - (count - 1) / 2) * 0.8, 0), rotation=(0, 0, rng.uniform(-0.8, 0.8))))
    return Asset("Worker", parts, (0.8, count * 0.8))


register(AssetKind(
    name="Worker", classes=("Worker",), build=workers, place=Mix(weight=2.5), order=63,
    materials=(Material("hivis", (0.9, 0.7, 0.0), 0.6, reflectivity=0.9), Material("work_trousers", (0.05, 0.06, 0.1), 0.9),
               Material("skin", (0.55, 0.35, 0.25), 0.6), Material("hard_hat", (0.9, 0.9, 0.85), 0.35)),
    stage=Relocates(P_MOVE), shared_streams=True,
))
