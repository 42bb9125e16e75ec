"""One Embree acceleration structure over some rigid parts, and its exact first hits.

Embree (through open3d) finds which triangle a ray hits, in float32 arithmetic that it
compiles per instruction set and picks at run time: its distance is off the exact value by
up to ~100 float32 units in the last place on a tilted plane, and differs between CPU models.
So Embree only proposes a triangle; :meth:`Structure.first_hits` decides the answer in
float64 (``exact_kernels.plane_hits``) from the caller's float64 ray and the triangles as
Embree holds them (docs/rendering.md, "Ground truth"), in this order:

1. the float64 ray meets Embree's triangle (its plane hit lies on the triangle, to within
   ``ON_TRIANGLE_TOL`` metres of an edge, at t >= 0): that hit, exact;
2. otherwise (a ray nearly along a surface, where the float32 ray met the surface somewhere
   else, or a ray through a shared edge), the triangle of the same structure nearest to
   where the float64 ray met the plane, if the float64 ray meets it (same test): a tiled
   wall or ground, whose next tile the float64 ray really hits;
3. otherwise Embree's triangle if the float64 hit lies within ``near_edge_tol(t)`` of it
   (a silhouette edge the float64 ray narrowly misses: depth and label stay together);
4. otherwise the float32 ray's own hit on that triangle, in float64, within the same
   tolerance (a ray so nearly in the triangle's plane that the float64 one meets it far off);
5. otherwise Embree's own distance and normal (a ray in the plane to round-off, or a
   degenerate triangle).

Only step 5 reads Embree's distances. Which triangle Embree proposes, and which one its
closest-point query returns, is still Embree's choice where the float32 ray passes within
float32 round-off of an edge or an outline; at grazing angles that can be a surface
centimetres from the float64 ray's first one (docs/rendering.md, "Ground truth").
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .o3d import import_open3d
from .parts import MeshPart

o3d = import_open3d()

# A float64 plane hit this far (metres) outside a triangle's edge is still on the triangle:
# float64 round-off of the test is ~1e-14 m at a site's coordinates.
ON_TRIANGLE_TOL = 1e-7
# Steps 3 and 4 accept a hit within NEAR_EDGE_TOL_ABS + NEAR_EDGE_TOL_REL * t (metres) of the
# triangle's edges (the same magnitude as the occlusion tolerance of raycast.py).
NEAR_EDGE_TOL_ABS = 1e-3
NEAR_EDGE_TOL_REL = 1e-4


def tensor(a: np.ndarray, dtype=np.float32):
    """An open3d tensor of ``a`` as a contiguous array of ``dtype``."""
    return o3d.core.Tensor.from_numpy(np.ascontiguousarray(a, dtype=dtype))


def near_edge_tol(t: np.ndarray) -> np.ndarray:
    """Steps 3-4's tolerance (metres) at ray distances ``t``."""
    return NEAR_EDGE_TOL_ABS + NEAR_EDGE_TOL_REL * np.abs(t)


def plane_hits(origins, directions, vertices, corners, normals: bool):
    """``exact_kernels.plane_hits`` on new arrays: (t (N,), outside (N,), unit (N, 3) or None)."""
    from .exact_kernels import plane_hits as kernel

    n = len(corners)
    t, outside, unit = np.empty(n), np.empty(n), np.empty((n, 3) if normals else (0, 3))
    kernel(np.ascontiguousarray(origins, dtype=np.float64), np.ascontiguousarray(directions, dtype=np.float64),
           vertices, np.ascontiguousarray(corners), t, unit, outside, normals)
    return t, outside, (unit if normals else None)


def _meets(t: np.ndarray, outside: np.ndarray, tol) -> np.ndarray:
    """(N,) bool: a plane hit in front of the ray (t >= 0) and on the triangle to ``tol`` (NaN: no)."""
    return (outside <= tol) & (t >= 0)


class Structure:
    """One Embree structure (open3d ``RaycastingScene``) over some parts, with the float32
    triangles it was given, for deciding its hits in float64. A structure built with
    ``first_hits=False`` (occlusion and inside tests only) keeps no copy of them and refuses
    :meth:`first_hits`."""

    def __init__(self, parts: Sequence[MeshPart], first_hits: bool = True):
        self.scene = o3d.t.geometry.RaycastingScene()
        vertices, faces = [], []
        self.count = 0
        for part in parts:
            if len(part.faces) == 0:
                continue  # open3d gives geometry ids in insertion order, skipping nothing added
            v, f = np.ascontiguousarray(part.world_vertices(), dtype=np.float32), part.faces.astype(np.uint32)
            self.scene.add_triangles(tensor(v), tensor(f, np.uint32))
            if first_hits:
                vertices.append(v)
                faces.append(f)
            self.count += 1
        self._vertices, self._faces = (vertices, faces) if first_hits else (None, None)
        self._triangles = None

    def triangles(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(vertices (V, 3) float32, the values Embree holds, of every geometry in order; faces
        (F, 3) int32 indices into them; first face (G + 1,) int64 of each geometry id)."""
        if self._vertices is None:
            raise ValueError("this structure was built for occlusion tests only (first_hits=False)")
        if self._triangles is None:
            starts = np.cumsum([0] + [len(v) for v in self._vertices])
            face_start = np.cumsum([0] + [len(f) for f in self._faces]).astype(np.int64)
            if starts[-1] > np.iinfo(np.int32).max:
                raise ValueError(f"a structure of {starts[-1]:,} vertices: more than int32 indices hold")
            faces = np.concatenate([(f.astype(np.int64) + s).astype(np.int32) for f, s in zip(self._faces, starts)])
            self._triangles = (np.concatenate(self._vertices), faces, face_start)
        return self._triangles

    def first_hits(self, origins: np.ndarray, directions: np.ndarray, rays: np.ndarray, normals: bool):
        """First hits of the float64 rays (``origins``, ``directions``: (N, 3)), ``rays`` (N, 6)
        being them in float32 (Embree's input): returns per ray t (N,) float64 (inf: a miss),
        geometry id (N,) int64 (-1: a miss), face (N,) int64 index into that geometry's faces
        (-1: a miss) and unit normal (N, 3) float32 (zero for a miss) or None, decided by the
        steps of the module's docstring."""
        from .exact_kernels import proposed_hits

        ans = self.scene.cast_rays(tensor(rays))
        t_embree = ans["t_hit"].numpy()
        vertices, faces, face_start = self.triangles()
        n = len(origins)
        t, geometry, face, outside = np.empty(n), np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64), np.empty(n)
        unit, settled = np.empty((n, 3) if normals else (0, 3), dtype=np.float32), np.empty(n, dtype=bool)
        degenerate = proposed_hits(  # step 1
            origins, directions, t_embree, ans["geometry_ids"].numpy(), ans["primitive_ids"].numpy(), face_start,
            vertices, faces, ON_TRIANGLE_TOL, t, geometry, face, outside, unit, settled, normals)
        retry = np.flatnonzero(~settled & np.isfinite(t))
        if len(retry):  # step 2: the triangle nearest to the float64 plane hit
            o, d = origins[retry], directions[retry]
            with np.errstate(over="ignore", invalid="ignore"):  # far past the site: found below
                near = self.scene.compute_closest_points(tensor(o + t[retry, None] * d))
            geometry2 = near["geometry_ids"].numpy().astype(np.int64)
            found = geometry2 < self.count  # none (Embree's invalid id) for a point past float32's range
            retry, geometry2 = retry[found], geometry2[found]
            face2 = near["primitive_ids"].numpy()[found].astype(np.int64)
            t2, outside2, unit2 = plane_hits(origins[retry], directions[retry], vertices,
                                             faces[face_start[geometry2] + face2], normals)
            take = _meets(t2, outside2, ON_TRIANGLE_TOL)
            sel = retry[take]
            t[sel], face[sel], geometry[sel] = t2[take], face2[take], geometry2[take]
            if normals:
                unit[sel] = unit2[take]
            settled[sel] = True
        retry = np.flatnonzero(~settled)
        retry = retry[~_meets(t[retry], outside[retry], near_edge_tol(t[retry]))]  # step 3 keeps the others
        if len(retry):  # step 4: the float32 ray on Embree's triangle
            t32, outside32, unit32 = plane_hits(rays[retry, :3], rays[retry, 3:], vertices,
                                                faces[face_start[geometry[retry]] + face[retry]], normals)
            take = _meets(t32, outside32, near_edge_tol(t32))
            sel = retry[take]
            t[sel] = t32[take]
            if normals:
                unit[sel] = unit32[take]
            retry = retry[~take]
        lost = retry
        if normals and degenerate:  # step 5 also gives the normals of degenerate triangles
            lost = np.union1d(retry, np.flatnonzero(~np.isfinite(unit[:, 0])))
        if len(lost):  # step 5: Embree's own answer
            t[lost] = t_embree[lost]
            if normals:
                unit[lost] = ans["primitive_normals"].numpy()[lost]
        return t, geometry, face, (unit if normals else None)
