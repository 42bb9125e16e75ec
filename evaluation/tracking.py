"""Point-tracking scores in the TAP-Vid conventions (Doersch et al., 2022) for the query
subset stored in a trajectory's ``tracks.h5`` (``tapvid/``).

Queries are (t, y, x); tracks are (x, y) pixels (top-left pixel centre at (0.5, 0.5));
``occluded`` is True where the point is not visible. A query is evaluated on the frames
after its query frame ('first' mode) or on every frame but its own ('strided' mode).
Distance thresholds δ are in pixels of the frames as stored; with ``resize_to=(256, 256)``
positions are first scaled to that size, as the TAP-Vid benchmark does.

- occlusion accuracy: share of evaluated (query, frame) pairs whose occlusion flag is right;
- <δ: share of evaluated pairs visible in the ground truth whose prediction lies closer
  than δ (strict), averaged over δ in (1, 2, 4, 8, 16) ("<δ avg");
- Jaccard at δ: TP / (TP + FP + FN), TP = visible in both and within δ, FN = visible in
  the ground truth but predicted occluded or too far, FP = predicted visible but occluded
  in the ground truth or too far; Average Jaccard = mean over δ.
"""

from __future__ import annotations

import numpy as np

THRESHOLDS = (1, 2, 4, 8, 16)


def evaluation_mask(query_t: np.ndarray, num_frames: int, mode: str = "first") -> np.ndarray:
    """(Q, T) bool: which frames count for each query."""
    t = np.arange(num_frames)[None, :]
    q = np.asarray(query_t).astype(np.int64)[:, None]
    if mode == "first":
        return t > q
    if mode == "strided":
        return t != q
    raise ValueError(f"query mode must be 'first' or 'strided', got {mode!r}")


def tapvid_metrics(gt_tracks: np.ndarray, gt_occluded: np.ndarray, pred_tracks: np.ndarray,
                   pred_occluded: np.ndarray, query_t: np.ndarray, mode: str = "first",
                   image_size: tuple[int, int] | None = None, resize_to: tuple[int, int] | None = None,
                   thresholds: tuple[float, ...] = THRESHOLDS) -> dict:
    """TAP-Vid scores of predicted tracks (Q, T, 2) and occlusion flags (Q, T) against the
    ground truth. ``image_size`` (W, H) is needed with ``resize_to`` (W', H')."""
    gt_tracks, pred_tracks = np.asarray(gt_tracks, np.float64), np.asarray(pred_tracks, np.float64)
    gt_vis, pred_vis = ~np.asarray(gt_occluded, bool), ~np.asarray(pred_occluded, bool)
    if resize_to is not None:
        if image_size is None:
            raise ValueError("resize_to needs image_size")
        scale = np.array(resize_to, np.float64) / np.array(image_size, np.float64)
        gt_tracks, pred_tracks = gt_tracks * scale, pred_tracks * scale
    evaluated = evaluation_mask(query_t, gt_tracks.shape[1], mode)
    dist = np.linalg.norm(pred_tracks - gt_tracks, axis=-1)
    out = {"num_queries": int(len(gt_tracks)), "num_frames": int(gt_tracks.shape[1]), "query_mode": mode,
           "thresholds_px": list(thresholds), "resize_to": list(resize_to) if resize_to else None,
           "occlusion_accuracy": _share(pred_vis == gt_vis, evaluated)}
    within, jaccard = [], []
    for delta in thresholds:
        close = dist < delta
        within.append(_share(close, evaluated & gt_vis))
        tp = np.count_nonzero(close & gt_vis & pred_vis & evaluated)
        fn = np.count_nonzero(gt_vis & evaluated) - tp
        fp = np.count_nonzero(pred_vis & evaluated & ~(gt_vis & close))
        jaccard.append(tp / (tp + fp + fn) if tp + fp + fn else 0.0)
    out |= {"pts_within": dict(zip(map(str, thresholds), within)), "average_pts_within": float(np.mean(within)),
            "jaccard": dict(zip(map(str, thresholds), jaccard)), "average_jaccard": float(np.mean(jaccard))}
    return out


def _share(values: np.ndarray, mask: np.ndarray) -> float:
    n = np.count_nonzero(mask)
    return float(np.count_nonzero(values & mask) / n) if n else 0.0
