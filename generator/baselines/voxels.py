"""A labelled voxel map (numpy only): accumulate labelled world points, read out one point
per occupied voxel at its centre with its majority label."""

from __future__ import annotations

import numpy as np


class VoxelMap:
    """Voxels of size ``voxel`` metres; voxel (i, j, k) covers [i v, (i + 1) v) x ... and is
    represented by its centre ((i + 0.5) v, ...). Each voxel keeps per-label point counts;
    its label is the most frequent one (ties: the smallest id)."""

    def __init__(self, voxel: float):
        if not (voxel > 0 and np.isfinite(voxel)):
            raise ValueError(f"voxel size must be a positive number of metres, got {voxel!r}")
        self.voxel = float(voxel)
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
        # sort by voxel, then count descending, then label ascending: the first row of each voxel wins
        order = np.lexsort((keys[:, 3], -counts, keys[:, 2], keys[:, 1], keys[:, 0]))
        keys = keys[order]
        first = np.ones(len(keys), bool)
        first[1:] = np.any(keys[1:, :3] != keys[:-1, :3], axis=1)
        best = keys[first]
        return (best[:, :3] + 0.5) * self.voxel, best[:, 3]
