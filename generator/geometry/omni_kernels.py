"""Rules 3 and 4 from a viewpoint looking in every direction (:mod:`.observability`), in one
pass (numba, compiled once and cached on disk): rule 3 per point and the occlusion ray of
every point that passes it, written straight into a float32 ray array.

The per-point arithmetic is that of :mod:`.visibility_rules` (``facing_away``,
``occlusion_rays``), operation for operation and in the same order, through the shared
helpers :func:`.point_block_kernels.segment_keep` and ``write_ray`` (numba without ``fastmath`` neither
reorders nor fuses multiply-adds; tests/test_visibility.py checks the compiled code), so
the answers are the same bits as the numpy evaluation of the rules
(tests/test_observability.py compares with the six-view cube map through
``visible_points``).
"""

from __future__ import annotations

import numba
import numpy as np

from .point_block_kernels import segment_keep, write_ray


@numba.njit(cache=True, nogil=True, error_model="numpy")
def omni_rays(xyz, nxyz, part, cullable, todo, c, seen, pos, rays):
    """For the points ``todo`` (M,) (indices into the columns of ``xyz`` (3, N), world
    metres) seen from ``c`` (3,): rule 3 with the outward normals ``nxyz`` (3, N) and the
    parts ``part`` (N,) (``cullable`` (P,): the parts it applies to from ``c``; empty: no
    normals, no rule 3), then rule 4's segment.

    A point closer than the occlusion tolerance is never hidden: ``seen[k]`` is set for it
    (k its position in ``todo``). Every other point that passes rule 3 gets its ray (float32
    [origin, direction], the segment ending at t = 1) in ``rays`` and its position in ``todo``
    in ``pos``. Returns the number of rays written."""
    with_normals = len(cullable) > 0
    ox, oy, oz = np.float32(c[0]), np.float32(c[1]), np.float32(c[2])
    m = 0
    for k in range(len(todo)):
        p = todo[k]
        dx = xyz[0, p] - c[0]
        dy = xyz[1, p] - c[1]
        dz = xyz[2, p] - c[2]
        if with_normals and cullable[part[p]] and nxyz[0, p] * dx + nxyz[1, p] * dy + nxyz[2, p] * dz > 0:
            continue  # rule 3: on the back of a solid
        keep = segment_keep(dx, dy, dz)
        if keep == 0.0:  # closer than the tolerance: never hidden
            seen[k] = True
            continue
        write_ray(rays, m, ox, oy, oz, dx, dy, dz, keep)
        pos[m] = k
        m += 1
    return m
