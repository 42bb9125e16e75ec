"""The asset model: a site object as rigid parts with parents and keyframes (bpy-free).

An :class:`Asset` is built in its own frame (origin on the ground at its footprint centre,
+x along its length) and placed by its footprint. Each :class:`Part` becomes one Blender
object named after its class, so labels survive saving (``Crane``, ``Crane.001``, ...).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..geometry.portable_math import sincos
from .meshes import MeshData


@dataclass
class Keyframes:
    """Linear keyframes of a part's local transform: frames (K,), location (K, 3) metres,
    rotation (K, 3) XYZ Euler radians. Either may be None (not animated)."""

    frames: np.ndarray
    location: np.ndarray | None = None
    rotation: np.ndarray | None = None


@dataclass
class Part:
    """One Blender object: ``label`` (a taxonomy class, or '' for an empty pivot), its mesh
    (None for an empty), transform relative to its parent (or to the asset frame);
    ``scenery``: the object is scenery, whatever its kind (the ground beyond the fence;
    :class:`generator.scene.kinds.AssetKind` ``scenery``)."""

    label: str
    mesh: MeshData | None
    location: tuple = (0.0, 0.0, 0.0)
    rotation: tuple = (0.0, 0.0, 0.0)
    parent: int | None = None
    keys: Keyframes | None = None
    scenery: bool = False


@dataclass
class Footprint:
    """Oriented rectangle on the ground: centre (x, y) and size (length along the
    footprint's x, width) in metres, yaw in radians."""

    center: tuple[float, float]
    size: tuple[float, float]
    yaw: float = 0.0

    def corners(self) -> np.ndarray:
        lx, ly = self.size[0] / 2, self.size[1] / 2
        s, c = sincos(self.yaw)
        lx_, ly_ = np.array([-lx, lx, lx, -lx]), np.array([-ly, -ly, ly, ly])
        return np.column_stack([lx_ * c - ly_ * s, lx_ * s + ly_ * c]) + np.asarray(self.center)

    def grown(self, margin: float) -> "Footprint":
        return Footprint(self.center, (self.size[0] + 2 * margin, self.size[1] + 2 * margin), self.yaw)


@dataclass
class Asset:
    """A group of parts that belongs together (a building, a container stack, a truck)."""

    kind: str
    parts: list[Part]
    size: tuple[float, float]  # footprint length and width in the asset frame, metres
    placement: Footprint | None = None  # where it stands; None for assets animated in world coordinates
    moves: bool = False
    info: dict = field(default_factory=dict)
    footprint_from_geometry: bool = True  # False: only ``size`` reserves ground (crane jibs pass overhead)

    @property
    def triangle_count(self) -> int:
        return sum(p.mesh.triangle_count for p in self.parts if p.mesh is not None)


def overlaps(a: Footprint, b: Footprint) -> bool:
    """Separating-axis test of two oriented rectangles."""
    ca, cb = a.corners(), b.corners()
    for poly in (ca, cb):
        for k in range(4):
            edge = poly[(k + 1) % 4] - poly[k]
            axis = np.array([-edge[1], edge[0]])
            pa, pb = ca[:, 0] * axis[0] + ca[:, 1] * axis[1], cb[:, 0] * axis[0] + cb[:, 1] * axis[1]
            if pa.max() <= pb.min() or pb.max() <= pa.min():
                return False
    return True
