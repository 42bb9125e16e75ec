"""Voxels with labels (numpy only): the majority label of groups of labelled points, and a
voxel map that accumulates labelled world points and reads out one point per occupied
voxel at its centre with its majority label."""

from __future__ import annotations

import numpy as np

from ..checks import check_number


def majority_labels(group: np.ndarray, label: np.ndarray, count: np.ndarray | None = None,
                    num_groups: int | None = None) -> np.ndarray:
    """Most frequent label per group (ties: the smallest id). ``group`` (N,) ids in
    [0, num_groups), ``label`` (N,) ints, ``count`` (N,) how many points each row stands
    for (default 1)."""
    group, label = np.asarray(group, np.int64), np.asarray(label, np.int64)
    count = np.ones(len(group), np.int64) if count is None else np.asarray(count, np.int64)
    num_groups = int(group.max()) + 1 if num_groups is None else num_groups
    pairs, inverse = np.unique(np.column_stack([group, label]), axis=0, return_inverse=True)
    totals = np.bincount(inverse.reshape(-1), weights=count).astype(np.int64)
    order = np.lexsort((pairs[:, 1], -totals, pairs[:, 0]))  # per group: highest total, then smallest id
    g = pairs[order, 0]
    first = np.ones(len(order), bool)
    first[1:] = g[1:] != g[:-1]
    best = np.full(num_groups, -1, np.int64)
    best[g[first]] = pairs[order, 1][first]
    return best


class VoxelMap:
    """Voxels of size ``voxel`` metres; voxel (i, j, k) covers [i v, (i + 1) v) x ... and is
    represented by its centre ((i + 0.5) v, ...). Each voxel keeps per-label point counts;
    its label is the most frequent one (ties: the smallest id)."""

    def __init__(self, voxel: float):
        self.voxel = check_number("voxel size", voxel, 0, open_low=True, valid="a positive number of metres")
        self._keys: list[np.ndarray] = []  # rows: (i, j, k, label)
        self._counts: list[np.ndarray] = []

    def add(self, points: np.ndarray, labels: np.ndarray) -> None:
        """Add world points (N, 3) metres with label ids (N,); points with label < 0 or
        non-finite coordinates are ignored."""
        points = np.asarray(points, np.float64).reshape(-1, 3)
        labels = np.asarray(labels).reshape(-1)
        ok = np.isfinite(points).all(axis=1) & (labels >= 0)
        if not ok.any():
            return
        ijk = np.floor(points[ok] / self.voxel).astype(np.int64)
        rows = np.column_stack([ijk, labels[ok].astype(np.int64)])
        uniq, counts = np.unique(rows, axis=0, return_counts=True)
        self._keys.append(uniq)
        self._counts.append(counts)
        if len(self._keys) > 16:  # keep memory bounded: merge what we have
            self._merge()

    def _merge(self) -> None:
        if len(self._keys) <= 1:
            return
        keys, inverse = np.unique(np.concatenate(self._keys), axis=0, return_inverse=True)
        counts = np.bincount(inverse.reshape(-1), weights=np.concatenate(self._counts)).astype(np.int64)
        self._keys, self._counts = [keys], [counts]

    def __len__(self) -> int:
        self._merge()
        return 0 if not self._keys else len(np.unique(self._keys[0][:, :3], axis=0))

    def points(self) -> tuple[np.ndarray, np.ndarray]:
        """Voxel centres (M, 3) metres and their majority labels (M,)."""
        self._merge()
        if not self._keys:
            return np.zeros((0, 3)), np.zeros(0, np.int64)
        keys, counts = self._keys[0], self._counts[0]
        voxels, group = np.unique(keys[:, :3], axis=0, return_inverse=True)
        return (voxels + 0.5) * self.voxel, majority_labels(group.reshape(-1), keys[:, 3], counts, len(voxels))
