"""Exact nearest neighbours in 3-D, Euclidean and Manhattan (L1), in a k-d tree whose nodes
keep the tight bounding box of their points (numba, compiled once and cached on disk).

Why our own tree: scipy's and nanoflann's trees prune a cell by the box of its splitting
planes, which keeps the full extent of every axis never split. On a site (a flat ground
and objects standing on it) no cell is split in height until it is small, so a point far
above the ground visits every cell within the objects' height horizontally. With tight
boxes, a cell of ground points is flat and is pruned at once.

The distances are computed exactly as scipy does (float64, L1 = |dx| + |dy| + |dz| left to
right, squared L2 = dx dx + dy dy + dz dz), and a cell is pruned only when the distance to
its box is larger than the best distance so far: a lower bound of every point's computed
distance (rounding is monotone), so the answers are the exact minima. Ties (equal computed
distances) go to the point with the lowest index.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

# Points per leaf (at most): measured on the 1 M vs 1 M benchmark (docs/benchmarks.md).
LEAF_SIZE = 16
# Queries are cut into this many chunks per thread (outliers cost far more than inliers).
CHUNKS_PER_THREAD = 16


@numba.njit(cache=True, nogil=True)
def _build(points, leaf_size):
    """Nodes in breadth-first order; a node covers rows start:end of the reordered points;
    child[i] is its first child (the second is child[i] + 1), -1 for a leaf."""
    n = len(points)
    pts = points.copy()
    perm = np.arange(n)
    cap = 16 + 4 * (n // leaf_size + 1)
    lo = np.empty((cap, 3))
    hi = np.empty((cap, 3))
    start = np.empty(cap, np.int64)
    end = np.empty(cap, np.int64)
    child = np.empty(cap, np.int64)
    depth = np.zeros(cap, np.int64)
    start[0], end[0] = 0, n
    count, node, max_depth = 1, 0, 0
    while node < count:
        s, e = start[node], end[node]
        for d in range(3):
            lo[node, d] = pts[s, d]
            hi[node, d] = pts[s, d]
        for k in range(s + 1, e):
            for d in range(3):
                v = pts[k, d]
                if v < lo[node, d]:
                    lo[node, d] = v
                elif v > hi[node, d]:
                    hi[node, d] = v
        axis = 0
        for d in range(1, 3):
            if hi[node, d] - lo[node, d] > hi[node, axis] - lo[node, axis]:
                axis = d
        max_depth = max(max_depth, depth[node])
        if e - s <= leaf_size or hi[node, axis] <= lo[node, axis]:
            child[node] = -1
            node += 1
            continue
        # midpoint of the tight box (lo < mid <= hi): both sides get at least one point
        mid = 0.5 * lo[node, axis] + 0.5 * hi[node, axis]
        if not (lo[node, axis] < mid <= hi[node, axis]):
            mid = hi[node, axis]
        i, j = s, e - 1
        while i <= j:
            if pts[i, axis] < mid:
                i += 1
            else:
                for d in range(3):
                    pts[i, d], pts[j, d] = pts[j, d], pts[i, d]
                perm[i], perm[j] = perm[j], perm[i]
                j -= 1
        if count + 2 > cap:
            cap *= 2
            lo = _grow2(lo, cap)
            hi = _grow2(hi, cap)
            start = _grow1(start, cap)
            end = _grow1(end, cap)
            child = _grow1(child, cap)
            depth = _grow1(depth, cap)
        child[node] = count
        start[count], end[count] = s, i
        start[count + 1], end[count + 1] = i, e
        depth[count] = depth[count + 1] = depth[node] + 1
        count += 2
        node += 1
    return pts, perm, lo[:count].copy(), hi[:count].copy(), start[:count].copy(), end[:count].copy(), \
        child[:count].copy(), max_depth


@numba.njit(cache=True, nogil=True)
def _grow1(a, cap):
    out = np.empty(cap, a.dtype)
    out[:len(a)] = a
    return out


@numba.njit(cache=True, nogil=True)
def _grow2(a, cap):
    out = np.empty((cap, a.shape[1]), a.dtype)
    out[:len(a)] = a
    return out


@numba.njit(cache=True, nogil=True, inline="always")
def _box_distance(lo, hi, node, x0, x1, x2, manhattan):
    """Distance from x to the node's box: L1, or squared L2."""
    g0 = max(lo[node, 0] - x0, x0 - hi[node, 0], 0.0)
    g1 = max(lo[node, 1] - x1, x1 - hi[node, 1], 0.0)
    g2 = max(lo[node, 2] - x2, x2 - hi[node, 2], 0.0)
    if manhattan:
        return g0 + g1 + g2
    return g0 * g0 + g1 * g1 + g2 * g2


@numba.njit(cache=True, nogil=True)
def _query(pts, perm, lo, hi, start, end, child, max_depth, queries, order, a, b, bound, manhattan,
           out_d, out_i):
    """Nearest point of the tree for queries[order[a:b]], no farther than ``bound`` (per query;
    np.inf for none): its distance (L1, or squared L2) and original index (-1 if none is
    within the bound)."""
    stack = np.empty(max_depth + 2, np.int64)
    stack_d = np.empty(max_depth + 2)
    for t in range(a, b):
        q = order[t]
        x0, x1, x2 = queries[q, 0], queries[q, 1], queries[q, 2]
        best = bound[q]
        best_i = -1
        stack[0] = 0
        stack_d[0] = _box_distance(lo, hi, 0, x0, x1, x2, manhattan)
        sp = 1
        while sp > 0:
            sp -= 1
            node = stack[sp]
            if stack_d[sp] > best:
                continue
            while child[node] >= 0:
                left = child[node]
                d_left = _box_distance(lo, hi, left, x0, x1, x2, manhattan)
                d_right = _box_distance(lo, hi, left + 1, x0, x1, x2, manhattan)
                if d_left <= d_right:
                    near, d_near, far, d_far = left, d_left, left + 1, d_right
                else:
                    near, d_near, far, d_far = left + 1, d_right, left, d_left
                if d_far <= best:
                    stack[sp] = far
                    stack_d[sp] = d_far
                    sp += 1
                if d_near > best:
                    node = -1
                    break
                node = near
            if node < 0:
                continue
            for k in range(start[node], end[node]):
                if manhattan:
                    d = abs(x0 - pts[k, 0]) + abs(x1 - pts[k, 1]) + abs(x2 - pts[k, 2])
                else:
                    d0, d1, d2 = x0 - pts[k, 0], x1 - pts[k, 1], x2 - pts[k, 2]
                    d = d0 * d0 + d1 * d1 + d2 * d2
                if d < best or (d == best and (best_i < 0 or perm[k] < best_i)):
                    best = d
                    best_i = perm[k]
        out_d[q] = best
        out_i[q] = best_i


@numba.njit(cache=True, nogil=True)
def _morton_order(points):
    """Indices of ``points`` along a Z-order curve of their bounding box (21 bits per axis)."""
    n = len(points)
    lo = np.empty(3)
    scale = np.empty(3)
    for d in range(3):
        lo[d] = points[:, d].min()
        extent = points[:, d].max() - lo[d]
        scale[d] = (2 ** 21 - 1) / extent if extent > 0 else 0.0
    codes = np.empty(n, np.int64)
    for k in range(n):
        c = 0
        for d in range(3):
            v = np.int64((points[k, d] - lo[d]) * scale[d])
            v &= 0x1FFFFF
            v = (v | (v << 32)) & 0x1F00000000FFFF
            v = (v | (v << 16)) & 0x1F0000FF0000FF
            v = (v | (v << 8)) & 0x100F00F00F00F00F
            v = (v | (v << 4)) & 0x10C30C30C30C30C3
            v = (v | (v << 2)) & 0x1249249249249249
            c |= v << d
        codes[k] = c
    return np.argsort(codes, kind="mergesort")


def _threads() -> int:
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


def _checked(points: np.ndarray, name: str) -> np.ndarray:
    points = np.ascontiguousarray(points, np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"KDTree: {name} must have shape (N, 3), got {points.shape}")
    if not np.isfinite(points).all():
        raise ValueError(f"KDTree: {name} contain NaN or infinite coordinates; drop or fix those rows")
    return points


class KDTree:
    """Exact nearest-neighbour queries against ``points`` (N, 3), N >= 1, float64. Many equal
    points make a leaf that is scanned whole: query the distinct points only."""

    def __init__(self, points: np.ndarray, leaf_size: int = LEAF_SIZE):
        points = _checked(points, "points")
        if len(points) == 0:
            raise ValueError("KDTree needs at least one point")
        self.size = len(points)
        self._tree = _build(points, int(leaf_size))

    @property
    def order(self) -> np.ndarray:
        """Indices of the tree's points, leaf by leaf: an order that keeps near points together
        (queries run fastest in such an order)."""
        return self._tree[1]

    def _run(self, queries: np.ndarray, bound: np.ndarray, manhattan: bool,
             order: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        queries = _checked(queries, "queries")
        n = len(queries)
        out_d, out_i = np.empty(n), np.empty(n, np.int64)
        if n == 0:
            return out_d, out_i
        order = _morton_order(queries) if order is None else np.ascontiguousarray(order, np.int64)
        threads = _threads()
        cuts = np.linspace(0, n, min(n, threads * CHUNKS_PER_THREAD) + 1).astype(np.int64)
        bound = np.ascontiguousarray(bound, np.float64)

        def work(k: int) -> None:
            _query(*self._tree, queries, order, cuts[k], cuts[k + 1], bound, manhattan, out_d, out_i)

        if threads == 1 or len(cuts) <= 2:
            for k in range(len(cuts) - 1):
                work(k)
        else:
            with ThreadPoolExecutor(threads) as pool:
                list(pool.map(work, range(len(cuts) - 1)))
        return out_d, out_i

    def nearest(self, queries: np.ndarray, order: np.ndarray | None = None) -> np.ndarray:
        """Index (M,) of each query's Euclidean nearest point (ties: the lowest index).
        ``order``: a permutation of the queries keeping near ones together (default: along
        a Z-order curve)."""
        return self._run(queries, np.full(len(queries), np.inf), False, order)[1]

    def nearest_manhattan(self, queries: np.ndarray, bound: np.ndarray, order: np.ndarray | None = None) -> np.ndarray:
        """L1 distance (M,) from each query to its L1-nearest point, given ``bound`` (M,), an
        L1 distance each query is known to reach (e.g. to one of the points): the answer is
        min(bound, the nearest L1 distance), exact; a tight bound prunes most of the tree.
        ``order``: as in :meth:`nearest`."""
        return self._run(queries, bound, True, order)[0]
