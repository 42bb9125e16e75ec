"""The per-call work of visibility in one pass each (numba, compiled once and cached on
disk), written straight into float32 ray arrays:
- :func:`select_rays`, for :class:`.point_blocks.PointBlocks` (``compute_point_cloud``):
  blocks and groups against the view, rule 3 per group, the per-point tests of the groups
  that are not settled, and the occlusion rays of the points that remain;
- :func:`omni_rays`, for :mod:`.observability` (a viewpoint looking in every direction):
  rule 3 per point and the occlusion ray of every point that passes it.

The per-point arithmetic is that of :mod:`.visibility_rules`, operation for operation and
in the same order (numba without ``fastmath`` neither reorders nor fuses multiply-adds;
``tests/test_visibility.py`` checks the bits and the compiled code), so the answers are
the same bits as the reference. A block or group is decided as a whole only with the
margin ``MARGIN`` (see :mod:`.point_blocks`), far above the round-off of those tests.

Both kernels and the helpers they inline live in this one file on purpose: numba's disk
cache is refreshed when this file changes, not when a file it imports from does. The
occlusion tolerances of :mod:`.raycast` are compiled in too; after changing them, delete
this package's ``__pycache__`` (or set ``NUMBA_CACHE_DIR`` elsewhere).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from .raycast import OCCLUSION_TOL_ABS, OCCLUSION_TOL_REL

# A box or group counts as wholly inside a half-space (or wholly facing one way) only if it
# is so by this share of the magnitudes involved: far above the round-off of the per-point
# tests (~1e-15 relative), so that skipping them never changes an answer.
MARGIN = 1e-9

# answers to rule 4 kept per point (see PointBlocks): not known yet, visible, hidden
UNKNOWN, VISIBLE, HIDDEN = 0, 1, 2

# slots of the ``counts`` array filled by select_rays
IN_VIEW, CULLED, ONE_BY_ONE, SETTLED = 0, 1, 2, 3


@numba.njit(cache=True, nogil=True, inline="always")
def view_coords(dx, dy, dz, a_z, a_u, a_v):
    """Planar depth z, u = pixel x * z and v = pixel y * z of an offset from the camera
    centre (as :func:`.visibility_rules.in_view`)."""
    z = dx * a_z[0] + dy * a_z[1] + dz * a_z[2]
    u = dx * a_u[0] + dy * a_u[1] + dz * a_u[2]
    v = dx * a_v[0] + dy * a_v[1] + dz * a_v[2]
    return z, u, v


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def segment_keep(dx, dy, dz):
    """Share of the offset that rule 4's segment keeps (as :func:`.visibility_rules.occlusion_rays`;
    0: an empty segment, the point is never hidden)."""
    dist = math.sqrt(dx * dx + dy * dy + dz * dz)
    keep = 1.0 - (OCCLUSION_TOL_ABS + OCCLUSION_TOL_REL * dist) / dist
    if keep < 0.0:
        keep = 0.0
    return keep


@numba.njit(cache=True, nogil=True, inline="always")
def write_ray(rays, m, ox, oy, oz, dx, dy, dz, keep):
    """Row ``m`` of the float32 ray array ``rays``: rule 4's segment from the camera centre
    (``ox, oy, oz``, float32) along the offset ``keep`` * (dx, dy, dz) (as
    :func:`.visibility_rules.occlusion_rays`: the product in float64, then rounded)."""
    rays[m, 0], rays[m, 1], rays[m, 2] = ox, oy, oz
    rays[m, 3] = np.float32(dx * keep)
    rays[m, 4] = np.float32(dy * keep)
    rays[m, 5] = np.float32(dz * keep)


@numba.njit(cache=True, nogil=True)
def view_coords_of(dx, dy, dz, a_z, a_u, a_v):
    """:func:`view_coords` over arrays (M,) each: (3, M) (for the tests of the arithmetic)."""
    out = np.empty((3, len(dx)))
    for i in range(len(dx)):
        out[0, i], out[1, i], out[2, i] = view_coords(dx[i], dy[i], dz[i], a_z, a_u, a_v)
    return out


@numba.njit(cache=True, nogil=True, error_model="numpy")
def segment_keep_of(dx, dy, dz):
    """:func:`segment_keep` over arrays (M,) each (for the tests of the arithmetic)."""
    out = np.empty(len(dx))
    for i in range(len(dx)):
        out[i] = segment_keep(dx[i], dy[i], dz[i])
    return out


@numba.njit(cache=True, nogil=True, inline="always")
def _box_in_view(a, b, slack, centre, half, extent, i):
    """Box ``i`` (columns of centre, half, extent (3, M)) against the view's half-spaces
    a . p + b >= 0: 0 outside one by the margin, 2 inside all by the margin, 1 on the edge."""
    inside = True
    for k in range(a.shape[0]):
        ax, ay, az = a[k, 0], a[k, 1], a[k, 2]
        mid = ax * centre[0, i] + ay * centre[1, i] + az * centre[2, i] + b[k]
        spread = abs(ax) * half[0, i] + abs(ay) * half[1, i] + abs(az) * half[2, i]
        margin = MARGIN * (abs(ax) * extent[0, i] + abs(ay) * extent[1, i] + abs(az) * extent[2, i]) + slack[k]
        if mid + spread < -margin:
            return 0
        if not mid - spread > margin:
            inside = False
    return 2 if inside else 1


@numba.njit(cache=True, nogil=True, inline="always")
def _group_facing(g, c, c_abs, axis, spread, centre, half, radius):
    """Rule 3 for group ``g`` from its box and normal cone: 1 all its points face away
    from ``c`` (n . (p - c) > 0), -1 all face it, 0 mixed (test them one by one).
    n . (p - c) lies within m . (p - c) +- spread * |p - c| for the cone's axis m."""
    rx, ry, rz = centre[0, g] - c[0], centre[1, g] - c[1], centre[2, g] - c[2]
    mid = axis[0, g] * rx + axis[1, g] * ry + axis[2, g] * rz
    reach = abs(axis[0, g]) * half[0, g] + abs(axis[1, g]) * half[1, g] + abs(axis[2, g]) * half[2, g]
    far = math.sqrt(rx * rx + ry * ry + rz * rz) + radius[g]
    slack = spread[g] * far + MARGIN * (far + c_abs + 1.0)
    if mid - reach > slack:
        return 1
    if mid + reach < -slack:
        return -1
    return 0


@numba.njit(cache=True, nogil=True, error_model="numpy")
def select_rays(block_first, block_groups, block_centre, block_half, block_extent,
                group_start, group_size, group_part, group_centre, group_half, group_extent, group_radius,
                cone_axis, cone_spread, xyz, nxyz, order, cullable,
                a, b, slack, c, a_z, a_u, a_v, near, far, width, height,
                answers, use_answers, mask, pos, rays, counts):
    """Rules 1-3 for every point, block by block and group by group, and the occlusion ray
    of every point that passes them and whose rule 4 answer is not known yet.

    Writes the positions (group order) of those points into ``pos`` and their rays (float32
    [origin, direction], the segment ending at t = 1) into ``rays``, and returns their
    count. Points known visible (``answers``, when ``use_answers``) and points closer than
    the occlusion tolerance are set in ``mask`` (caller's order, through ``order``) at once;
    the latter are recorded as visible in ``answers``. ``cullable`` (parts,) says which
    parts rule 3 applies to (empty: no normals). ``counts`` receives the points in view,
    hidden by rule 3, tested one by one (the points of the groups not settled as a whole),
    and settled without a ray (known answers, empty segments)."""
    with_normals = len(cullable) > 0
    c_abs = abs(c[0]) + abs(c[1]) + abs(c[2])
    wz, hz = float(width), float(height)
    ox, oy, oz = np.float32(c[0]), np.float32(c[1]), np.float32(c[2])
    n_in = n_culled = n_one = n_settled = 0
    m = 0
    for blk in range(len(block_first)):
        block_state = _box_in_view(a, b, slack, block_centre, block_half, block_extent, blk)
        if block_state == 0:
            continue
        g0 = block_first[blk]
        for g in range(g0, g0 + block_groups[blk]):
            edge = False
            if block_state == 1:
                state = _box_in_view(a, b, slack, group_centre, group_half, group_extent, g)
                if state == 0:
                    continue
                edge = state == 1
            facing = -1  # rule 3 moot or settled as "faces the camera"
            if with_normals and cullable[group_part[g]]:
                facing = _group_facing(g, c, c_abs, cone_axis, cone_spread, group_centre, group_half, group_radius)
            start, size = group_start[g], group_size[g]
            if not edge and facing == 1:  # wholly in view, on the back of a solid
                n_in += size
                n_culled += size
                continue
            if edge or facing == 0:
                n_one += size
            for p in range(start, start + size):
                dx = xyz[0, p] - c[0]
                dy = xyz[1, p] - c[1]
                dz = xyz[2, p] - c[2]
                if edge:  # rules 1 and 2 point by point
                    z, u, v = view_coords(dx, dy, dz, a_z, a_u, a_v)
                    if not (z > near and z <= far and u >= 0 and u < wz * z and v >= 0 and v < hz * z):
                        continue
                n_in += 1
                if facing == 1:
                    n_culled += 1
                    continue
                if facing == 0 and nxyz[0, p] * dx + nxyz[1, p] * dy + nxyz[2, p] * dz > 0:  # rule 3
                    n_culled += 1
                    continue
                if use_answers:
                    known = answers[p]
                    if known != UNKNOWN:
                        if known == VISIBLE:
                            mask[order[p]] = True
                        n_settled += 1
                        continue
                keep = segment_keep(dx, dy, dz)
                if keep == 0.0:  # closer than the tolerance: never hidden
                    mask[order[p]] = True
                    answers[p] = VISIBLE
                    n_settled += 1
                    continue
                write_ray(rays, m, ox, oy, oz, dx, dy, dz, keep)
                pos[m] = p
                m += 1
    counts[IN_VIEW], counts[CULLED], counts[ONE_BY_ONE], counts[SETTLED] = n_in, n_culled, n_one, n_settled
    return m


@numba.njit(cache=True, nogil=True)
def store_answers(blocked, pos, order, answers, mask):
    """Record the rays' answers (``blocked`` (M,) for the points at ``pos``) in ``answers``
    and set the visible points in ``mask`` (caller's order)."""
    for k in range(len(pos)):
        p = pos[k]
        if blocked[k]:
            answers[p] = HIDDEN
        else:
            answers[p] = VISIBLE
            mask[order[p]] = True


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
