"""Scoring change detection between two stages of a timeline (``python -m evaluation change``;
definitions in docs/phases.md). No bpy.

Two kinds of prediction, both against ``seed_N/changes.h5`` and the stages' ground truth:

- a **change cloud**: points (metres, world) each labelled ``added`` (1) or ``removed`` (2),
  in an NPZ (``xyz`` (N, 3), ``change`` (N,)) or a PLY (vertex x, y, z, change). The ground
  truth's change cloud is stage k's points marked added plus stage k-1's points marked
  removed. Per class c: precision = share of predicted c points with a ground-truth c point
  closer than ``tau`` (strict <), recall = share of ground-truth c points with a predicted c
  point closer than ``tau``, F-score = 2PR / (P + R), IoU = PR / (P + R - PR) (which is
  TP / (TP + FP + FN) when precision and recall count the same matches);
- **change masks**: an NPZ with ``masks`` (T, H, W) bool for one trajectory (``kind``),
  scored pixel by pixel for the classes changed and unchanged: precision = TP / (TP + FP),
  recall = TP / (TP + FN), IoU = TP / (TP + FP + FN), over all frames together.

A figure whose denominator is empty is None (e.g. precision with no predicted point of a class).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from trajectories.arrays import ArrayFileError, declared_arrays

from .inputs import Cloud, InputError, check_cloud_rows, load_array_file, regular_file

CLOUD_CLASSES = {"added": 1, "removed": 2}  # the codes of exporters.changes.STATUS
DEFAULT_TAU = 0.1  # metres


def _ratio(num: int, den: int) -> float | None:
    return None if den == 0 else num / den


def class_scores(precision: float | None, recall: float | None) -> dict:
    """F-score and IoU from precision and recall (None when both are undefined; 0 when one is)."""
    if precision is None and recall is None:
        return {"precision": None, "recall": None, "fscore": None, "iou": None}
    p, r = precision or 0.0, recall or 0.0
    f = 0.0 if p + r == 0 else 2 * p * r / (p + r)
    iou = 0.0 if p + r - p * r == 0 else p * r / (p + r - p * r)
    return {"precision": precision, "recall": recall, "fscore": f, "iou": iou}


def _matched(a: np.ndarray, b: np.ndarray, tau: float) -> np.ndarray:
    """(len(a),) bool: a point of ``b`` is closer than ``tau`` (strict)."""
    from scipy.spatial import cKDTree

    if len(a) == 0 or len(b) == 0:
        return np.zeros(len(a), bool)
    d, _ = cKDTree(b).query(a, k=1, distance_upper_bound=np.nextafter(tau, np.inf))
    return d < tau


def score_change_cloud(gt_xyz: np.ndarray, gt_change: np.ndarray, pred_xyz: np.ndarray, pred_change: np.ndarray,
                       tau: float = DEFAULT_TAU) -> dict:
    """Per class (added, removed): counts, precision, recall, F-score, IoU (module docstring)."""
    out = {}
    for name, code in CLOUD_CLASSES.items():
        g, p = gt_xyz[gt_change == code], pred_xyz[pred_change == code]
        tp_pred, tp_gt = int(_matched(p, g, tau).sum()), int(_matched(g, p, tau).sum())
        out[name] = {"gt_points": len(g), "pred_points": len(p), "matched_pred": tp_pred, "matched_gt": tp_gt,
                     **class_scores(_ratio(tp_pred, len(p)), _ratio(tp_gt, len(g)))}
    ious = [v["iou"] for v in out.values() if v["iou"] is not None]
    out["mean_iou"] = float(np.mean(ious)) if ious else None
    return out


def score_change_masks(gt: np.ndarray, pred: np.ndarray) -> dict:
    """Pixel scores of the classes changed and unchanged over all frames (module docstring)."""
    out = {}
    for name, g, p in (("changed", gt, pred), ("unchanged", ~gt, ~pred)):
        tp, fp, fn = int((g & p).sum()), int((~g & p).sum()), int((g & ~p).sum())
        out[name] = {"tp": tp, "fp": fp, "fn": fn, "precision": _ratio(tp, tp + fp), "recall": _ratio(tp, tp + fn),
                     "iou": _ratio(tp, tp + fp + fn)}
    ious = [v["iou"] for v in out.values() if v["iou"] is not None]
    out["mean_iou"] = float(np.mean(ious)) if ious else None
    return out


def gt_change_cloud(seed: Path, before: int, after: int):
    """(xyz (N, 3), change codes (N,)) of the ground truth between two consecutive stages, and
    the Changes read from changes.h5 (frame masks included)."""
    changes = _changes(seed)
    _check_stages(changes, seed, before, after)
    pair = changes.pair(before, after)
    xyz_b, xyz_a = _stage_points(seed, after), _stage_points(seed, before)
    if len(xyz_b) != len(pair.points_added) or len(xyz_a) != len(pair.points_removed):
        raise InputError(f"{seed}: changes.h5 does not match the stages' points.ply (regenerate the seed)")
    xyz = np.concatenate([xyz_b[pair.points_added], xyz_a[pair.points_removed]])
    code = np.concatenate([np.full(int(pair.points_added.sum()), CLOUD_CLASSES["added"]),
                           np.full(int(pair.points_removed.sum()), CLOUD_CLASSES["removed"])])
    return xyz, code, changes


def _stage_points(seed: Path, stage: int) -> np.ndarray:
    """(N, 3) float64 of stage ``stage``'s points.ply, read by exporters.ground_truth.read_points."""
    from exporters.ground_truth import GroundTruthError, read_points

    try:
        return read_points(seed / f"phase_{stage}" / "ground_truth").points
    except GroundTruthError as exc:
        raise InputError(str(exc)) from None


def _changes(seed: Path):
    from exporters.changes import FILE, read_changes

    if not (seed / FILE).is_file():
        raise InputError(f"--gt {seed}: no {FILE}; give a seed folder made with python -m generator --phases K (K >= 2)")
    return read_changes(seed)


def _check_stages(changes, seed: Path, before: int, after: int) -> None:
    if not (0 <= before < changes.stages and 0 <= after < changes.stages and after == before + 1):
        raise InputError(f"--stages {before} {after}: {seed} has stages 0 to {changes.stages - 1}; give two "
                         "consecutive stages K-1 K")


PREDICTION_KEYS = ("xyz", "change", "masks")


def prediction_kind(path: Path) -> str:
    """"masks" or "cloud": what the prediction file ``path`` holds, from its headers only; an
    NPZ holding both is refused (which would be scored?)."""
    path = regular_file(path, "--pred")
    if path.suffix.lower() == ".ply":
        return "cloud"
    try:
        declared = declared_arrays(path, PREDICTION_KEYS)
    except ArrayFileError as exc:
        raise InputError(f"--pred {exc}") from None
    if not isinstance(declared, dict):
        raise InputError(f"--pred {path}: holds one array; give an NPZ with masks (T, H, W), or xyz and change")
    if "masks" in declared and ("xyz" in declared or "change" in declared):
        raise InputError(f"--pred {path}: holds both masks and a change cloud (xyz, change); give one of them")
    if "masks" in declared and declared["masks"].dtype.kind not in "biuf":
        raise InputError(f"--pred {path}: masks must be booleans (or 0/1), got dtype {declared['masks'].dtype}")
    return "masks" if "masks" in declared else "cloud"


def read_change_prediction(path: Path, masks_shape: tuple[int, ...] | None = None) -> dict:
    """{"xyz", "change"} (a change cloud) or {"masks"} from an NPZ or PLY (module docstring).
    ``masks_shape``: the ground truth's (T, H, W); masks declaring another shape are refused
    before they are read (a cloud is held to evaluation.inputs.MAX_CLOUD_POINTS)."""
    path = regular_file(path, "--pred")
    if path.suffix.lower() == ".ply":
        data = _read_ply_change(path)
    elif prediction_kind(path) == "masks":
        data = load_array_file(path, ("masks",), check=lambda d: _check_masks_shape(d, masks_shape, path),
                               expansion=masks_shape is None)
    else:
        data = load_array_file(path, ("xyz", "change"), check=lambda d: check_cloud_rows(d, path))
    if "masks" in data:
        return {"masks": _checked_masks(np.asarray(data["masks"]), path)}
    if "xyz" not in data or "change" not in data:
        raise InputError(f"--pred {path}: needs xyz (N, 3) and change (N,) (1 added, 2 removed), or masks (T, H, W)")
    xyz = Cloud(data["xyz"], None, f"--pred {path}: xyz").points  # (N, 3) finite real metres, as any cloud
    change = np.asarray(data["change"])
    if change.shape != (len(xyz),) or change.dtype.kind not in "iuf":
        raise InputError(f"--pred {path}: change must be (N,) numbers for {len(xyz)} points, got {change.dtype} "
                         f"{change.shape}")
    if not np.isin(change, list(CLOUD_CLASSES.values())).all():
        raise InputError(f"--pred {path}: change values must be 1 (added) or 2 (removed)")
    return {"xyz": xyz, "change": change.astype(np.int64)}


def _check_masks_shape(declared: dict, shape: tuple[int, ...] | None, path: Path) -> None:
    if shape is not None and declared["masks"].shape != tuple(shape):
        raise InputError(f"--pred {path}: masks are {declared['masks'].shape}, the ground truth's {tuple(shape)} "
                         "(T, H, W)")


def _read_ply_change(path: Path) -> dict:
    """{"xyz", "change"} of a PLY change cloud (vertex x, y, z, change)."""
    from exporters.ply import PlyError, read_ply

    try:
        v = read_ply(path).vertex
    except PlyError as exc:
        raise InputError(f"--pred {exc}") from None
    if "change" not in v or not isinstance(v["change"], np.ndarray):
        raise InputError(f"--pred {path}: no change property (one number per vertex); a change cloud has x, y, z "
                         "and change (1 added, 2 removed)")
    return {"xyz": np.stack([v[c] for c in "xyz"], axis=1), "change": v["change"]}


def _checked_masks(masks: np.ndarray, path: Path) -> np.ndarray:
    """``masks`` as bool: booleans, or numbers that are all 0 or 1."""
    if masks.dtype.kind == "b":
        return masks
    if masks.dtype.kind not in "iuf":
        raise InputError(f"--pred {path}: masks must be booleans (or 0/1), got dtype {masks.dtype}")
    bad = np.flatnonzero(~np.isin(masks, (0, 1)))
    if bad.size:
        raise InputError(f"--pred {path}: masks must be booleans (or 0/1), got {masks.dtype} values such as "
                         f"{masks.flat[bad[0]]!r}; threshold probabilities first")
    return masks.astype(bool)


def score_change(gt: str | Path, before: int, after: int, pred: str | Path, tau: float = DEFAULT_TAU,
                 kind: str | None = None) -> dict:
    """Score ``pred`` against the change from stage ``before`` to ``after`` of the seed folder ``gt``."""
    seed, pred = Path(gt), Path(pred)
    common = {"gt": str(seed), "pred": str(pred), "stages": [before, after]}
    if prediction_kind(pred) == "masks":
        changes = _changes(seed)
        _check_stages(changes, seed, before, after)
        masks = changes.pair(before, after).masks
        if kind is None:
            kind = sorted(masks)[0] if len(masks) == 1 else None
        if kind not in masks:
            raise InputError(f"--kind {kind or '(none)'}: name the trajectory the masks are for, one of "
                             f"{', '.join(sorted(masks))}")
        truth = masks[kind]
        prediction = read_change_prediction(pred, truth.shape)
        return {"task": "change-masks", "parameters": common | {"kind": kind, **changes.parameters},
                "scores": score_change_masks(truth, prediction["masks"])}
    prediction = read_change_prediction(pred)
    xyz, code, changes = gt_change_cloud(seed, before, after)
    return {"task": "change-cloud", "parameters": common | {"tau_m": tau, "strict": True, **changes.parameters},
            "scores": score_change_cloud(xyz, code, prediction["xyz"], prediction["change"], tau)}


def change_table(results: dict) -> str:
    s = results["scores"]
    classes = [k for k in s if k != "mean_iou"]

    def f(v):
        return "-" if v is None else f"{v:.4f}"

    lines = [f"{results['task']} stages {results['parameters']['stages']}", f"{'class':<10} {'precision':>9} {'recall':>9} {'IoU':>9}"]
    lines += [f"{c:<10} {f(s[c]['precision']):>9} {f(s[c]['recall']):>9} {f(s[c]['iou']):>9}" for c in classes]
    lines.append(f"mean IoU {f(s['mean_iou'])}")
    return "\n".join(lines)
