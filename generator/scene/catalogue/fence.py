"""The site's temporary fence: mesh panels on concrete feet along the boundary, 0.5 m
inside it, with a gate on the south side."""

from __future__ import annotations

import numpy as np

from ...geometry.portable_math import atan2, vector_norm
from ..assets import Part
from ..kinds import AssetKind, register
from ..meshes import MeshBuilder
from ..planning import Custom


def fence_run(length: float) -> MeshBuilder:
    """Temporary mesh fence panels (3.5 x 2.0 m, tube frame and wire mesh) on concrete
    feet, along local +x from 0 to ``length``, centred on y = 0."""
    b = MeshBuilder()
    panels = max(1, int(round(length / 3.5)))
    pw = length / panels
    for k in range(panels + 1):
        x = k * pw
        b.box((0.7, 0.2, 0.15), (min(max(x, 0.35), length - 0.35), 0, 0.075), material="concrete")
    for k in range(panels):
        x0 = k * pw + 0.03
        x1 = x0 + pw - 0.06
        z0, z1 = 0.16, 2.0
        for x in (x0, x1):
            b.cylinder(0.02, (x, 0, z0), (x, 0, z1), segments=6, material="steel_galvanized")
        for z in (z0 + 0.02, z1 - 0.02):
            b.cylinder(0.02, (x0 + 0.021, 0, z), (x1 - 0.021, 0, z), segments=6, material="steel_galvanized")
        for x in np.arange(x0 + 0.1, x1 - 0.05, 0.1):  # 100 x 250 mm welded mesh
            b.cylinder(0.002, (x, 0, z0 + 0.041), (x, 0, z1 - 0.041), segments=4, material="steel_galvanized")
        for z in np.arange(z0 + 0.25, z1 - 0.1, 0.25):
            b.cylinder(0.002, (x0 + 0.021, 0.004, z), (x1 - 0.021, 0.004, z), segments=4, material="steel_galvanized")
    return b


def fence_part(start: np.ndarray, end: np.ndarray) -> Part:
    """One straight run of fence from ``start`` to ``end`` (ground xy), as one part."""
    length = vector_norm(end - start)
    yaw = atan2(end[1] - start[1], end[0] - start[0])
    return Part("Fence", fence_run(length).build(), location=(float(start[0]), float(start[1]), 0.0), rotation=(0.0, 0.0, yaw))


def plan_fence(site, kind: AssetKind) -> None:
    """The fence's runs (the plan's ``fence_runs``; Blender builds one part per run): along
    the boundary 0.5 m inside it, open at the gate."""
    f = site.half - 0.5
    gate = site.gate
    site.plan.fence_runs = [
        (np.array([-f + 0.6, -f]), np.array([gate[0], -f])), (np.array([gate[1], -f]), np.array([f - 0.6, -f])),
        (np.array([f, -f + 0.6]), np.array([f, f - 0.6])), (np.array([f - 0.6, f]), np.array([-f + 0.6, f])),
        (np.array([-f, f - 0.6]), np.array([-f, -f + 0.6])),
    ]


register(AssetKind(name="Fence", classes=("Fence",), build=fence_part, place=Custom(plan_fence), order=1,
                   shared_streams=True))
