"""Sand and gravel piles: cones or ridges at their angle of repose, used up, moved and
delivered over a timeline's stages."""

from __future__ import annotations

import numpy as np

from ...geometry.portable_math import sincos, tan
from ..assets import Asset, Part
from ..kinds import AssetKind, register
from ..materials import Material, Pattern
from ..meshes import MeshBuilder
from ..planning import Mix
from ..timeline import MATERIAL_STOCK


def stadium(rho: float, half_ridge: float, n_arc: int, n_line: int) -> np.ndarray:
    """Points (N, 2), counter-clockwise, at distance ``rho`` from the segment
    [-half_ridge, half_ridge] x {0}: two half circles joined by straight lines."""
    right = [(half_ridge + rho * c, rho * s) for s, c in zip(*sincos(np.linspace(-np.pi / 2, np.pi / 2, n_arc, endpoint=False)))]
    top = [(x, rho) for x in np.linspace(half_ridge, -half_ridge, n_line, endpoint=False)]
    left = [(-half_ridge + rho * c, rho * s) for s, c in zip(*sincos(np.linspace(np.pi / 2, 3 * np.pi / 2, n_arc, endpoint=False)))]
    bottom = [(x, -rho) for x in np.linspace(-half_ridge, half_ridge, n_line, endpoint=False)]
    return np.array(right + top + left + bottom)


def material_pile(rng: np.random.Generator, kind: str, material: str | None = None, label: str | None = None,
                  heights=(1.0, 3.0), repose=(30.0, 35.0), ridges=(1.0, 4.0), rough: float | None = None) -> Asset:
    """A pile of loose material: a cone or a ridge at its angle of repose (``repose`` degrees),
    ``heights`` metres tall, with a rough surface (``rough`` metres of noise; sand's and
    gravel's by default). Its base is exactly its footprint on the ground. ``material``,
    ``label``: sand's or gravel's and the kind by default."""
    height = rng.uniform(*heights)
    slope = tan(np.radians(rng.uniform(*repose)))
    ridge = rng.uniform(*ridges) if rng.random() < 0.5 else 0.0
    radius = height / slope
    rings, n_arc, n_line = 72, 128, 32 if ridge else 0  # ~5 cm radially, ~10 cm around
    if rough is None:
        rough = 0.04 if kind == "SandPile" else 0.09
    rhos = np.linspace(radius, 0.04 * radius, rings)  # outer ring first
    verts = []
    for k, rho in enumerate(rhos):
        ring = stadium(rho, ridge / 2, n_arc, n_line)
        z = np.full(len(ring), height - rho * slope)
        if k > 0:
            z = np.maximum(z + rng.normal(0, rough, len(ring)) * min(z[0], 1.0), 0.02)
        verts.append(np.column_stack([ring, z]))
    n = len(verts[0])
    v = np.concatenate(verts + [[[0.0, 0.0, height - rhos[-1] * slope]], [[0.0, 0.0, 0.0]]])
    top, bottom = len(v) - 2, len(v) - 1
    j = np.arange(n)
    j2 = (j + 1) % n
    quads = np.concatenate([np.stack([k * n + j, k * n + j2, (k + 1) * n + j2, (k + 1) * n + j], 1) for k in range(rings - 1)])
    last = (rings - 1) * n
    tris = np.concatenate([np.stack([last + j, last + j2, np.full(n, top)], 1),  # top cap
                           np.stack([j2, j, np.full(n, bottom)], 1)])  # base on the ground
    b = MeshBuilder().add(v, quads, tris, material=material or ("sand" if kind == "SandPile" else "gravel"))
    return Asset(kind, [Part(label or kind, b.build())], (2 * radius + ridge + 0.2, 2 * radius + 0.2))


def sand_pile(rng: np.random.Generator) -> Asset:
    return material_pile(rng, "SandPile")


def gravel_pile(rng: np.random.Generator) -> Asset:
    return material_pile(rng, "GravelPile")


register(AssetKind(
    name="SandPile", classes=("SandPile",), build=sand_pile, place=Mix(weight=1.5), order=52,
    materials=(Material("sand", (0.6, 0.45, 0.25), 0.95, 0.0, Pattern(25.0, (0.45, 0.33, 0.18), 0.4)),),
    stage=MATERIAL_STOCK, shared_streams=True,
))
register(AssetKind(
    name="GravelPile", classes=("GravelPile",), build=gravel_pile, place=Mix(weight=1.5), order=53,
    materials=(Material("gravel", (0.35, 0.34, 0.32), 0.9, 0.0, Pattern(60.0, (0.15, 0.15, 0.14), 0.7)),),
    stage=MATERIAL_STOCK, shared_streams=True,
))
