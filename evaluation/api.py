"""The evaluation's Python API: the same functions ``python -m evaluation`` runs, on files
or on arrays (for a training loop)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from exporters.ground_truth import GroundTruthError, read_ground_truth, read_points
from exporters.manifest import read_manifest, stage_count, timeline_stage

from .coverage import CoverageScorer, Poses, coverage_auc, read_poses
from .inputs import (Cloud, InputError, check_label_range, check_metres, check_sweep, ply_cloud, read_cloud,
                     read_label_table)
from .metrics import (DEFAULT_SWEEP, DEFAULT_TAU, Neighbours, fscore, iou_per_class, match_categories,
                      reconstruction_metrics, voxel_downsample)


def versions() -> dict:
    import numba
    import scipy

    from exporters import FORMAT_VERSION

    try:
        from importlib.metadata import version

        ours = version("buildee-sites")
    except Exception:  # not installed (running from a checkout)
        ours = "unknown"
    return {"buildee-sites": ours, "format_version": FORMAT_VERSION, "numpy": np.__version__, "scipy": scipy.__version__,
            "numba": numba.__version__}


def _seed_folder_gt(folder: Path) -> Path:
    stage = timeline_stage(folder)  # phase_K of a timeline seed: its manifest is one level up
    home = stage[0] if stage else folder
    manifest = read_manifest(home)
    if stage is None and manifest is not None and stage_count(manifest) > 1:
        n = stage_count(manifest)
        raise InputError(f"{folder}: a timeline of {n} stages (--phases); score one stage: --gt {folder / 'phase_K'} "
                         f"(K = 0 to {n - 1})")
    gt = folder / "ground_truth" if (folder / "ground_truth").is_dir() or (home / "manifest.json").exists() else folder
    if gt != folder and manifest is None:
        raise InputError(f"{folder}: incomplete seed folder (no readable manifest.json); regenerate this seed with "
                         "python -m generator (move a folder with a damaged manifest away first)")
    missing = [n for n in ("points.ply", "mesh.ply", "scene.h5") if not (gt / n).is_file()]
    if missing:
        raise InputError(f"{gt}: incomplete ground truth, missing {', '.join(missing)}; rerun python -m generator for this seed")
    return gt


def load_gt_cloud(path: str | Path, include_dynamic: bool = True) -> tuple[Cloud, list[str]]:
    """The ground-truth cloud and its label table from a seed folder, its ground_truth/
    folder, or a labelled point cloud file (label names from the PLY header or labels.json
    beside it, else the generator's taxonomy)."""
    path = Path(path)
    if path.is_dir():
        gt = _seed_folder_gt(path)
        try:
            ply = read_points(gt)  # the one reader of points.ply: format version and properties checked
        except GroundTruthError as exc:
            raise InputError(str(exc)) from None
        path, near = gt / "points.ply", None
        cloud = ply_cloud(ply, path)
    elif not path.exists():
        raise InputError(f"{path}: no such file or folder")
    else:
        # a PLY names its labels in its header; other files may hold class names, read with the table beside them
        near = None if path.suffix.lower() == ".ply" else _label_table_near(path)
        cloud = read_cloud(path, label_names=near)
    if not include_dynamic and cloud.dynamic is not None:
        cloud = cloud.subset(~cloud.dynamic)
    return cloud, cloud.names or near or _label_table_near(path)


def _label_table_near(path: Path) -> list[str]:
    for candidate in (path.parent / "labels.json", path.parent.parent / "labels.json"):
        if candidate.is_file():
            return read_label_table(candidate)
    from generator.scene.taxonomy import CLASSES

    return list(CLASSES)


def crop_to_bounds(cloud: Cloud, bounds: np.ndarray, margin: float) -> Cloud:
    """Keep the points inside the axis-aligned box ``bounds`` (2, 3) grown by ``margin`` metres."""
    return cloud.subset(np.all((cloud.points >= bounds[0] - margin) & (cloud.points <= bounds[1] + margin), axis=1))


def score_reconstruction(pred: Cloud | str | Path, gt: Cloud | str | Path, tau: float = DEFAULT_TAU,
                         sweep: tuple[float, ...] = DEFAULT_SWEEP, crop: bool = False, crop_margin: float | None = None,
                         voxel: float | None = None, pred_labels: str | Path | None = None,
                         include_dynamic: bool = True, label_names: list[str] | None = None) -> tuple[dict, dict]:
    """Score a predicted cloud against the ground truth (files or :class:`Cloud` s).
    ``label_names``: the label table (default: the one stored with the GT, else the
    generator's taxonomy).

    Returns (results, context): results is the JSON document (metrics, parameters,
    versions); context holds the arrays used (for the coloured PLY)."""
    check_metres("tau", tau)
    sweep = check_sweep(sweep)
    if crop_margin is not None:
        check_metres("crop_margin", crop_margin, or_equal=True)
    if voxel is not None:
        check_metres("voxel", voxel)
    if isinstance(gt, Cloud):
        gt_cloud, names = gt, label_names
    else:
        gt_cloud, names = load_gt_cloud(gt, include_dynamic)
        names = label_names or names
    if names is None:
        from generator.scene.taxonomy import CLASSES

        names = list(CLASSES)
    pred_cloud = pred if isinstance(pred, Cloud) else read_cloud(pred, pred_labels, names)
    check_label_range(pred_cloud, names, "predicted")
    check_label_range(gt_cloud, names, "ground-truth")
    n_pred_in, n_gt_in = len(pred_cloud), len(gt_cloud)
    margin = tau if crop_margin is None else crop_margin
    if crop:
        bounds = np.stack([gt_cloud.points.min(axis=0), gt_cloud.points.max(axis=0)])
        pred_cloud = crop_to_bounds(pred_cloud, bounds, margin)
        if len(pred_cloud) == 0:
            raise InputError(f"{pred_cloud.source}: no predicted point lies within the ground truth's bounds "
                             f"(+{margin} m); check the coordinate frame (world, metres, Z up)")
    if voxel:
        extent = max(np.abs(pred_cloud.points).max(), np.abs(gt_cloud.points).max())
        if extent / voxel >= 2 ** 52:  # voxel indices must stay exact integers
            raise InputError(f"voxel {voxel} m is too small for coordinates up to {extent:.3g} m; use a larger voxel")
        p, pl = voxel_downsample(pred_cloud.points, pred_cloud.labels, voxel)
        g, gl = voxel_downsample(gt_cloud.points, gt_cloud.labels, voxel)
        go = None
        if gt_cloud.observable is not None:  # a voxel is observable when most of its points are
            go = voxel_downsample(gt_cloud.points, gt_cloud.observable.astype(np.int64), voxel)[1].astype(bool)
        pred_cloud, gt_cloud = Cloud(p, pl, pred_cloud.source), Cloud(g, gl, gt_cloud.source, observable=go)
    labelled = pred_cloud.labels is not None and gt_cloud.labels is not None
    nn = Neighbours.compute(pred_cloud.points, gt_cloud.points)
    metrics = reconstruction_metrics(pred_cloud.points, gt_cloud.points, pred_cloud.labels if labelled else None,
                                     gt_cloud.labels if labelled else None, tau, tuple(sweep), names, neighbours=nn)
    metrics["observable"] = observable_metrics(metrics, nn, gt_cloud.observable, pred_cloud.labels if labelled else None,
                                               gt_cloud.labels if labelled else None, tau, names)
    results = {
        "task": "reconstruction",
        "parameters": {"pred": pred_cloud.source, "gt": gt_cloud.source, "tau": tau, "sweep": list(sweep),
                       "crop": crop, "crop_margin": margin if crop else None, "voxel": voxel,
                       "include_dynamic": include_dynamic, "threshold": "strict: distance < tau",
                       "units": "metres (chamfer_l2: square metres)"},
        "inputs": {"pred_points": n_pred_in, "gt_points": n_gt_in, "pred_points_scored": len(pred_cloud),
                   "gt_points_scored": len(gt_cloud), "pred_labelled": pred_cloud.labels is not None,
                   "gt_labelled": gt_cloud.labels is not None},
        "labels": names,
        "metrics": metrics,
        "versions": versions(),
    }
    match = match_categories(pred_cloud.labels, gt_cloud.labels, nn.d_gp, nn.i_gp, tau)
    return results, {"pred": pred_cloud, "gt": gt_cloud, "names": names, "match": match}


NO_OBSERVABLE_MASK = ("this ground truth has no observable mask (written before format 0.4, or not our "
                      "ground truth); regenerate the seed for the observable-only figures")


def observable_metrics(metrics: dict, nn: Neighbours, observable: np.ndarray | None, pred_labels: np.ndarray | None,
                       gt_labels: np.ndarray | None, tau: float, names: list[str]) -> dict:
    """The figures of :func:`reconstruction_metrics` that divide by the ground truth,
    recomputed over the GT points marked observable (``observable`` (M,) bool): completeness,
    Chamfer-L1/L2 (with the full accuracy), recall and F-score (with the full precision) at
    tau and over the sweep, GT->pred Semantic Chamfer and mIoU on GT points. Figures over
    predicted points do not change. ``{"available": False, "note": ...}`` without a mask."""
    if observable is None:
        return {"available": False, "note": NO_OBSERVABLE_MASK}
    obs = np.asarray(observable, bool)
    n = int(obs.sum())
    out: dict = {"available": True, "gt_points": n, "share_of_gt": n / len(obs) if len(obs) else 0.0}
    if n == 0:
        return out | {"note": "no ground-truth point is observable"}
    d = nn.d_gp[obs]
    completeness = float(d.mean())
    recall = float(np.count_nonzero(d < tau) / n)
    out |= {"completeness": completeness, "chamfer_l1": (metrics["accuracy"] + completeness) / 2,
            "chamfer_l2": float((np.mean(nn.d_pg ** 2) + np.mean(d ** 2)) / 2),
            "recall": recall, "fscore": fscore(metrics["precision"], recall)}
    s = np.sort(d)
    out["sweep"] = [{"tau": e["tau"], "recall": float(np.searchsorted(s, e["tau"], side="left") / n),
                     "fscore": fscore(e["precision"], float(np.searchsorted(s, e["tau"], side="left") / n))}
                    for e in metrics["sweep"]]
    if pred_labels is not None and gt_labels is not None:
        g, i = np.asarray(gt_labels)[obs], nn.i_gp[obs]
        close = d < tau
        transferred = np.where(close, pred_labels[i], -1)
        iou, union = iou_per_class(g, transferred, len(names))
        present = union > 0
        out["semantic"] = {
            "semantic_chamfer_gt_to_pred": float(np.count_nonzero(close & (g == pred_labels[i]) & (g >= 0)) / n),
            "miou": float(np.mean(iou[present])) if present.any() else 0.0,
            "iou": {names[c]: float(iou[c]) for c in np.flatnonzero(present)}}
    return out


MATCH_COLOURS = np.array([[40, 90, 220], [245, 150, 30], [220, 30, 30]], np.uint8)  # matched, wrong label, unmatched


def colour_ply(path: str | Path, context: dict, tau: float) -> Path:
    """The paper's figure 9: GT points coloured blue (a prediction within tau with the right
    label), orange (within tau, wrong label), red (no prediction within tau); ``context``
    from :func:`score_reconstruction`."""
    from exporters.ply import write_ply

    gt, cat = context["gt"], context["match"]
    colours = MATCH_COLOURS[cat]
    vertex = {"x": gt.points[:, 0].astype(np.float32), "y": gt.points[:, 1].astype(np.float32),
              "z": gt.points[:, 2].astype(np.float32), "red": colours[:, 0], "green": colours[:, 1],
              "blue": colours[:, 2], "match": cat.astype(np.uint8)}
    return write_ply(path, vertex, comments=[f"match 0 = within {tau} m with the right label (blue), "
                                             "1 = wrong label (orange), 2 = unmatched (red)"])


def score_coverage(gt: str | Path, trajectory: str | Path | Poses, frames: str = "auto", progress=None,
                   max_depth: float | None = None) -> dict:
    """Coverage curve of a trajectory over a seed folder's ground truth (see coverage.py).
    ``max_depth``: visibility limit in metres (planar depth); default: the generator's."""
    gt = Path(gt)
    if not gt.exists():
        raise InputError(f"{gt}: no such file or folder")
    if not gt.is_dir():
        raise InputError(f"{gt}: coverage needs a seed folder (or its ground_truth/ folder) with scene.h5")
    folder = _seed_folder_gt(gt)
    try:
        scene = read_ground_truth(folder)
    except GroundTruthError as exc:
        raise InputError(str(exc)) from None
    if max_depth is not None:
        scene.far = check_metres("max_depth", max_depth, scene.near)
    poses = trajectory if isinstance(trajectory, Poses) else read_poses(trajectory, scene, frames)
    clamped = 0
    if poses.frames is not None:
        clamped = int(np.count_nonzero((poses.frames < scene.frames[0]) | (poses.frames > scene.frames[-1])))
    scorer = CoverageScorer(scene)
    curve, curve_obs, observed = scorer.curves(poses, progress)
    return {
        "task": "coverage",
        "parameters": {"gt": str(folder), "trajectory": poses.source, "frames": frames,
                       "poses_outside_the_animation": clamped,
                       "animation_frames": [int(scene.frames[0]), int(scene.frames[-1])],
                       "near": scene.near, "far": scene.far, "far_units": "metres, planar depth",
                       "camera": _camera_report(scene, poses)},
        "num_poses": len(curve), "num_points": int(len(observed)),
        "coverage": curve.tolist(), "auc": coverage_auc(curve), "final_coverage": float(curve[-1]),
        "observable": ({"available": False, "note": NO_OBSERVABLE_MASK} if curve_obs is None else
                       {"available": True, "num_points": int(scorer.observable.sum()),
                        "share_of_points": float(scorer.observable.mean()) if len(observed) else 0.0,
                        "coverage": curve_obs.tolist(), "auc": coverage_auc(curve_obs),
                        "final_coverage": float(curve_obs[-1])}),
        "units": "coverage: share of ground-truth surface points observed at least once (0..1); "
                 "AUC over an x-axis normalised to [0, 1] across all poses",
        "versions": versions(),
    }


def score_tracks(gt: str | Path, pred: str | Path | dict, mode: str = "first", resize_to: tuple[int, int] | None = None) -> dict:
    """TAP-Vid scores (evaluation/tracking.py) of predicted tracks for the query subset of a
    trajectory's ``tracks.h5`` (``gt``: that file or its trajectory folder). ``pred``: an
    NPZ (or dict) with ``tracks`` (Q, T, 2) (x, y) pixels and ``occluded`` (Q, T) bool, in the
    order of ``tapvid/query_points``."""
    from .tracking import read_tracks_gt, read_tracks_pred, tapvid_metrics

    gt = Path(gt)
    if gt.is_dir():
        gt = gt / "tracks.h5"
    if not gt.is_file():
        raise InputError(f"{gt}: no such file; give a trajectory's tracks.h5 or its folder")
    truth, size = read_tracks_gt(gt)
    if mode not in ("first", "strided"):
        raise InputError(f"query mode must be first or strided, got {mode!r}")
    tracks, occluded, source = read_tracks_pred(pred, *truth["occluded"].shape)
    metrics = tapvid_metrics(truth["tracks"], truth["occluded"], tracks, occluded,
                             truth["query_points"][:, 0], mode, size, resize_to)
    return {"task": "tracks", "parameters": {"gt": str(gt), "pred": source, "query_mode": mode,
                                             "image_size": list(size), "resize_to": list(resize_to) if resize_to else None,
                                             "units": "pixels (x, y); thresholds strict"},
            "metrics": metrics, "versions": versions()}


def _camera_report(scene, poses) -> dict:
    """The camera a coverage score used: K, size and (when it distorts) the lens."""
    lens = scene.lens if poses.lens is None else poses.lens
    return ({"K": (scene.K if poses.K is None else poses.K).tolist(),
             "width": scene.width if poses.width is None else poses.width,
             "height": scene.height if poses.height is None else poses.height}
            | ({} if lens.ideal else {"lens": lens.as_dict()}))
