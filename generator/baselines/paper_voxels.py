"""The paper's voxel rule (its ``point_cloud_segmentation.py``), to compare with ours.

Voxel (i, j, k) = floor(p / v) covers [i v, (i + 1) v) x ...; the paper represents it by
its corner (i v, j v, k v) and labels it with the first label seen there (earlier frames
win; within a frame, the first pixel in row-major order), where ours
(:class:`generator.geometry.voxels.VoxelMap`) uses the centre and the majority label.
Points with a non-finite coordinate or a negative label are ignored, as in both. numpy only.
"""

from __future__ import annotations

import numpy as np

from ..checks import check_number

_BITS = 21  # per axis: voxel indices in [-2^20, 2^20)
_OFFSET = 1 << (_BITS - 1)


def _encode(ijk: np.ndarray) -> np.ndarray:
    if ijk.size and (ijk.min() < -_OFFSET or ijk.max() >= _OFFSET):
        raise ValueError(f"voxel indices beyond +-{_OFFSET} (points too far for this voxel size)")
    u = (ijk + _OFFSET).astype(np.int64)
    return (u[:, 0] << (2 * _BITS)) | (u[:, 1] << _BITS) | u[:, 2]


class FirstSeenVoxels:
    """Voxels of ``voxel`` metres, each with the first label seen, read out at its corner."""

    def __init__(self, voxel: float):
        self.voxel = check_number("voxel size", voxel, 0, open_low=True, valid="a positive number of metres")
        self._keys = np.zeros(0, np.int64)  # sorted
        self._ijk = np.zeros((0, 3), np.int64)  # in the order of _keys
        self._labels = np.zeros(0, np.int64)

    def add(self, points: np.ndarray, labels: np.ndarray) -> None:
        """Add world points (..., 3) metres with label ids (...) in pixel (row-major) order."""
        points = np.asarray(points, np.float64).reshape(-1, 3)
        labels = np.asarray(labels).reshape(-1).astype(np.int64)
        ok = np.isfinite(points).all(axis=1) & (labels >= 0)
        ijk = np.floor(points[ok] / self.voxel).astype(np.int64)
        keys, first = np.unique(_encode(ijk), return_index=True)  # first occurrence in this frame
        pos = np.searchsorted(self._keys, keys)
        known = (pos < len(self._keys)) & (self._keys[np.minimum(pos, len(self._keys) - 1)] == keys) \
            if len(self._keys) else np.zeros(len(keys), bool)
        new = ~known
        all_keys = np.concatenate([self._keys, keys[new]])
        order = np.argsort(all_keys, kind="stable")
        self._keys = all_keys[order]
        self._ijk = np.concatenate([self._ijk, ijk[first[new]]])[order]
        self._labels = np.concatenate([self._labels, labels[ok][first[new]]])[order]

    def __len__(self) -> int:
        return len(self._keys)

    def points(self) -> tuple[np.ndarray, np.ndarray]:
        """Voxel corners (M, 3) metres and their first-seen labels (M,)."""
        return self._ijk * self.voxel, self._labels.copy()
