"""Where assets may stand: footprints, non-overlapping placement and candidate positions
(bpy-free). Used by the site plan (:mod:`.site`), the catalogue's placement rules
(:mod:`.planning`) and the timeline's moves and deliveries (:mod:`.timeline`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..geometry.camera import apply_affine, matmul_exact
from ..geometry.portable_math import sincos
from .assets import Asset, Footprint, overlaps
from .meshes import rotation_x, rotation_y, rotation_z

BAND_MIN_WIDTH = 3.0  # metres: a narrower band between road and fence holds nothing


@dataclass
class PlacedAsset:
    asset: Asset
    position: tuple[float, float]  # asset origin on the ground, metres
    yaw: float  # radians
    footprint: Footprint  # the ground area it keeps for itself (world)
    uid: int = 0  # the asset's identity over a timeline's stages (1 + its index in the stage-0 plan; docs/phases.md)


@dataclass
class SiteArea:
    """The ground a site's props use: the square inside the road loop (half-side ``inner``),
    the band between the road and the fence (``band`` = (lo, hi) distances from the centre),
    the props' ``layout`` and, for the clustered layout, the cluster ``centres`` (drawn with
    the prop mix; None before)."""

    inner: float
    band: tuple[float, float]
    layout: str
    centres: np.ndarray | None = None

    @property
    def has_band(self) -> bool:
        return self.band[1] - self.band[0] > BAND_MIN_WIDTH

    def inside(self, rng: np.random.Generator, n: int):
        """``n`` candidates inside the road loop, following the layout."""
        return layout_candidates(rng, self.layout, -self.inner, self.inner, n, self.centres)

    def band_or_inside(self, rng: np.random.Generator, band: bool, n: int):
        """``n`` candidates in the band along the fence if ``band`` and the band is wide
        enough, else inside the road loop."""
        if band and self.has_band:
            return band_candidates(rng, self.band[0], self.band[1], n)
        return self.inside(rng, n)


def local_bounds(asset: Asset) -> tuple[np.ndarray, np.ndarray]:
    """xy bounds (min, max) of an asset's geometry in its own frame, at its rest pose."""
    half = np.asarray(asset.size) / 2
    if not asset.footprint_from_geometry:
        return -half, half
    mats = []
    for part in asset.parts:
        m = np.eye(4)
        rx, ry, rz = part.rotation
        r = matmul_exact(matmul_exact(rotation_z(rz), rotation_y(ry)), rotation_x(rx))
        m[:3, :3], m[:3, 3] = r, part.location
        if part.parent is not None:
            m = matmul_exact(mats[part.parent], m)
        mats.append(m)
    pts = [apply_affine(mats[i], p.mesh.vertices) for i, p in enumerate(asset.parts) if p.mesh is not None and len(p.mesh.vertices)]
    allp = np.concatenate(pts)[:, :2]
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    # assets whose moving parts sweep more than their rest pose (excavators) declare a size
    return np.minimum(lo, -half), np.maximum(hi, half)


def footprint_at(asset: Asset, position, yaw: float, bounds: tuple[np.ndarray, np.ndarray] | None = None) -> Footprint:
    """The ground ``asset`` covers with its origin at ``position`` turned by ``yaw``
    (``bounds``: its :func:`local_bounds`, when the caller has them already)."""
    lo, hi = local_bounds(asset) if bounds is None else bounds
    c_local = (lo + hi) / 2
    s, c = sincos(yaw)
    center = np.asarray(position) + np.array([c * c_local[0] - s * c_local[1], s * c_local[0] + c * c_local[1]])
    return Footprint((float(center[0]), float(center[1])), (float(hi[0] - lo[0]), float(hi[1] - lo[1])), yaw)


class Placer:
    """Rejection sampling of non-overlapping footprints inside a square of half-side
    ``half``, clear of the ``reserved`` ones by ``margin`` metres."""

    def __init__(self, half: float, reserved: list[Footprint], margin: float = 0.8):
        self.half = half
        self.taken: list[Footprint] = list(reserved)
        self.margin = margin

    def fits(self, fp: Footprint) -> bool:
        corners = fp.corners()
        if np.any(np.abs(corners) > self.half):
            return False
        grown = fp.grown(self.margin)
        return not any(overlaps(grown, other) for other in self.taken)

    def first_fit(self, asset: Asset, candidates) -> tuple[float, float, float, Footprint] | None:
        """(x, y, yaw, footprint) of the first candidate ((x, y), yaw) where ``asset`` fits,
        or None; nothing is taken."""
        bounds = local_bounds(asset)  # once: the asset is the same at every candidate
        for (x, y), yaw in candidates:
            fp = footprint_at(asset, (x, y), yaw, bounds)
            if self.fits(fp):
                return float(x), float(y), float(yaw), fp
        return None

    def try_place(self, asset: Asset, candidates) -> PlacedAsset | None:
        """The asset at the first candidate ((x, y), yaw) where it fits (its footprint is
        then taken), or None."""
        fit = self.first_fit(asset, candidates)
        return None if fit is None else self.take(asset, fit[:2], fit[2], fit[3])

    def take(self, asset: Asset, position, yaw: float, fp: Footprint) -> PlacedAsset:
        """Place ``asset`` at ``position`` turned by ``yaw``, its footprint ``fp`` (checked by
        the caller with :meth:`fits`) taken."""
        self.taken.append(fp)
        return PlacedAsset(asset, (float(position[0]), float(position[1])), float(yaw), fp)


def layout_candidates(rng: np.random.Generator, layout: str, lo: float, hi: float, n: int, centres=None,
                      grid_step: float = 8.0):
    """Candidate ((x, y), yaw) positions in the square [lo, hi]^2 following a layout pattern."""
    if layout == "grid":
        g = np.arange(lo + grid_step / 2, hi, grid_step)
        cells = np.array([(x, y) for x in g for y in g])
        order = rng.permutation(len(cells))[:n]
        for k in order:
            yield tuple(cells[k]), float(rng.choice([0.0, math.pi / 2]))
    elif layout == "clustered" and centres is not None and len(centres):
        for _ in range(n):
            c = centres[int(rng.integers(len(centres)))]
            xy = np.clip(c + rng.normal(0, (hi - lo) * 0.08, 2), lo, hi)
            yield tuple(xy), float(rng.uniform(0, math.pi))
    else:
        for _ in range(n):
            yield tuple(rng.uniform(lo, hi, 2)), float(rng.uniform(0, math.pi))


def band_candidates(rng: np.random.Generator, lo: float, hi: float, n: int):
    """Positions in the band between the road and the fence, long side along the fence."""
    for _ in range(n):
        side = int(rng.integers(4))
        t = rng.uniform(-hi + 3, hi - 3)
        d = rng.uniform(lo, hi)
        x, y, yaw = [(t, -d, 0.0), (d, t, math.pi / 2), (t, d, 0.0), (-d, t, math.pi / 2)][side]
        yield (x, y), yaw


def anywhere_then_near(rng: np.random.Generator, position, inner: float, n: int = 150):
    """Candidate ((x, y), yaw): ``n`` anywhere inside the road loop, then ``n`` within a
    few metres of ``position`` (a crowded site has room for a big machine near its old spot)."""
    for _ in range(n):
        yield tuple(rng.uniform(-inner, inner, 2)), float(rng.uniform(0, 2 * math.pi))
    for _ in range(n):
        xy = np.clip(np.asarray(position) + rng.normal(0.0, 4.0, 2), -inner, inner)
        yield tuple(xy), float(rng.uniform(0, 2 * math.pi))
