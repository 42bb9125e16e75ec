"""The site's ground: one flat top surface, wider than the site (added by the Blender build
to every site; not placed by the plan)."""

from __future__ import annotations

from ..assets import Part
from ..kinds import AssetKind, register
from ..materials import Material, Pattern
from ..meshes import MeshBuilder

GROUND_MARGIN = 20.0  # metres of ground beyond the site's edge on every side (seen from the spawn volume)


def ground_part(size: float) -> Part:
    """The ground: one flat top surface at z = 0 (two triangles, normal up), ``GROUND_MARGIN``
    metres wider than the site on every side. It has no underside and no sides below
    grade: nothing a camera above it could see (docs/scenes.md)."""
    h = size / 2 + GROUND_MARGIN
    verts = [(-h, -h, 0.0), (h, -h, 0.0), (h, h, 0.0), (-h, h, 0.0)]  # counter-clockwise seen from above
    return Part("Ground", MeshBuilder().add(verts, quads=[(0, 1, 2, 3)], material="ground").build())


register(AssetKind(
    name="Ground", classes=("Ground",), build=ground_part, order=0,
    # compacted soil with texture at every scale a camera sees: damp and dry areas tens of
    # metres across, light patches and a dark mottle of a metre or two, clods of decimetres,
    # gravel of centimetres; roughness and specular drawn per seed as the paper's ground
    materials=(Material("ground", (0.23, 0.18, 0.12), 0.9, 0.0, Pattern(0.04, (0.12, 0.1, 0.07), 0.6, detail=4.0),
                        roughness_range=(0.5, 1.0), specular_range=(0.1, 0.7),
                        layers=(Pattern(0.5, (0.5, 0.44, 0.35), 0.7, detail=4.0),
                                Pattern(1.5, (0.08, 0.06, 0.04), 0.85, kind="voronoi"),
                                Pattern(0.9, (0.1, 0.08, 0.05), 0.6, detail=3.0),
                                Pattern(5.0, (0.13, 0.1, 0.08), 0.6, kind="voronoi"),
                                Pattern(25.0, (0.42, 0.37, 0.3), 0.5, kind="voronoi"))),),
    shared_streams=True,
))
