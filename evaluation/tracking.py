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

from pathlib import Path

import numpy as np

from exporters.hdf5 import H5_ERRORS, DamagedFileError, damaged, reason

from .inputs import InputError, load_array_file, regular_file

THRESHOLDS = (1, 2, 4, 8, 16)
MAX_PIXELS = 1e6  # |x|, |y| of a visible predicted position: beyond it, refused (not a pixel position)


def read_tracks_gt(path: Path) -> tuple[dict, tuple[int, int]]:
    """The TAP-Vid subset of a tracks.h5 and its image size (W, H), checked (checksums where
    the file has them, consistency always); a damaged file raises InputError naming it."""
    from exporters.tracks import TrackReader

    try:
        reader = TrackReader(path)
        try:
            truth = reader.tapvid(verify_checksums=True)  # a damaged ground truth is never scored
            size = (reader.width, reader.height)
        finally:
            reader.close()
    except DamagedFileError as exc:
        raise InputError(f"{exc} (or give a trajectory's tracks.h5 written by python -m generator)") from None
    except H5_ERRORS as exc:  # damaged metadata can fail anywhere h5py looks
        raise InputError(f"{damaged(path, reason(exc))}") from None
    if min(size) <= 0:
        raise InputError(f"{path}: damaged file (image size {size}); regenerate this seed with python -m generator")
    return truth, size


def _check_declared(declared, queries: int, frames: int, path) -> None:
    """Refuse, before reading, tracks or occluded arrays of other shapes than the ground truth's."""
    if not isinstance(declared, dict):
        return  # an .npy: refused by the caller once read (it is no larger than the file)
    want = {"tracks": (queries, frames, 2), "occluded": (queries, frames)}
    for name, shape in want.items():
        if name in declared and declared[name].shape != shape:
            raise InputError(f"{path}: {name} declares {declared[name].shape}; expected {shape} for this ground "
                             f"truth's {queries} queries and {frames} frames")


def read_tracks_pred(pred, queries: int, frames: int) -> tuple[np.ndarray, np.ndarray, str]:
    """Predicted ``tracks`` (Q, T, 2) float64 and ``occluded`` (Q, T) bool from an NPZ file
    or a dict, checked against the ground truth's Q queries and T frames. Points predicted
    occluded keep their positions (TAP-Vid scores <delta on every pair visible in the ground
    truth, whatever the predicted flag); a non-finite one becomes inf, never within delta."""
    source = "arrays"
    if not isinstance(pred, dict):
        source = str(pred)
        path = regular_file(pred, "predicted tracks")
        if path.suffix.lower() != ".npz":
            raise InputError(f"{path}: predicted tracks must be an NPZ with arrays 'tracks' (Q, T, 2) and "
                             "'occluded' (Q, T) (numpy.savez); got a " + (path.suffix or "suffix-less") + " file")
        pred = load_array_file(path, ("tracks", "occluded"), expansion=False,
                               check=lambda declared: _check_declared(declared, queries, frames, path))
        if not isinstance(pred, dict):
            raise InputError(f"{path}: holds one array (an .npy under an .npz name); write 'tracks' and 'occluded' "
                             "with numpy.savez")
    if "tracks" not in pred or "occluded" not in pred:
        raise InputError(f"{source}: needs arrays 'tracks' (Q, T, 2) and 'occluded' (Q, T)")
    tracks, occluded = np.asarray(pred["tracks"]), np.asarray(pred["occluded"])
    if tracks.shape != (queries, frames, 2) or occluded.shape != (queries, frames):
        raise InputError(f"{source}: tracks {tracks.shape} and occluded {occluded.shape}; expected ({queries}, {frames}, 2) "
                         f"and ({queries}, {frames}) for this ground truth's {queries} queries and {frames} frames")
    if tracks.dtype.kind not in "iuf":
        raise InputError(f"{source}: tracks must be real numbers (dtype {tracks.dtype})")
    if occluded.dtype.kind != "b" and not (occluded.dtype.kind in "iuf" and np.isin(occluded, (0, 1)).all()):
        raise InputError(f"{source}: occluded must be booleans (or 0/1), dtype {occluded.dtype}")
    occluded = occluded.astype(bool)
    visible = tracks[~occluded].astype(np.float64)
    if not np.isfinite(visible).all():
        raise InputError(f"{source}: track positions of visible points must be finite numbers")
    if visible.size and np.abs(visible).max() > MAX_PIXELS:
        raise InputError(f"{source}: a visible track position is {np.abs(visible).max():.3g} pixels from the origin "
                         f"(limit {MAX_PIXELS:.0e}); positions are (x, y) pixels of the stored frames")
    tracks = tracks.astype(np.float64)
    tracks[~np.isfinite(tracks)] = np.inf
    return tracks, occluded, source


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
        if len(resize_to) != 2 or not all(np.isfinite(v) and v > 0 for v in resize_to):
            raise InputError(f"resize_to must be a positive (width, height) in pixels, got {resize_to}")
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
