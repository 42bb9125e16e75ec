"""MeshParts (the simulator's geometry) from the site generator's MeshBuilder, for tests
that build scenes in numpy without Blender."""

import numpy as np

from generator.geometry.parts import MeshPart, closed_and_orientation


def mesh_part(name: str, builder, **kw) -> MeshPart:
    """The builder's quads (as two triangles each) and triangles, closed and oriented as
    ``closed_and_orientation`` finds them; ``kw`` goes to MeshPart (``dynamic``, ``matrix``)."""
    d = builder.build()
    tris = np.concatenate([d.quads[:, [0, 1, 2]], d.quads[:, [0, 2, 3]], d.tris]) if len(d.quads) else d.tris
    closed, outward = closed_and_orientation(d.vertices, tris)
    return MeshPart(name, name, d.vertices, tris, closed=closed, outward=outward, **kw)
