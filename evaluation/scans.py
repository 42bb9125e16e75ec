"""Scoring a predicted labelling of LiDAR sweeps (``python -m evaluation scans``), as
SemanticKITTI's benchmark does: per-class IoU over every return of every sweep, and their
mean (docs/evaluation.md, "LiDAR sweeps").

Ground truth: a scan folder written by ``python -m generator --lidar NAME``
(``SEED/<trajectory>/lidar/<NAME>``, read by exporters/semantickitti.py). Prediction: a
folder of ``NNNNNN.label`` files, one per sweep, uint32 little-endian per return in the
sweep's order, the class id in the low 16 bits (the upper 16 are ignored, as SemanticKITTI's
evaluation does), or the same in a ``predictions/`` subfolder (SemanticKITTI's submission
layout). Class ids are the seed's (labels.yaml). The mean IoU is over the classes present in
the ground truth (SemanticKITTI's mean runs over a fixed class list; ours has 31 classes, of
which a site shows a part), and every class's IoU is reported.

With ``change=True`` (``--change``) the labelling scored is the change since the previous
stage of a timeline (``--phases K``, stage k > 0): ``NNNNNN.change`` files, int8 per return,
the codes of exporters.changes.STATUS (0 unchanged, 1 added, 3 moved, 4 grown), against the
returns' ground-truth change labels; IoU per status and their mean over the statuses present.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from exporters.semantickitti import read_lidar_json, read_scan

from .inputs import InputError
from .metrics import iou_per_class


# what a prediction file holds: suffix -> (dtype, what it is, the ids read from it)
PREDICTIONS = {".label": ("<u4", "uint32 per return: class id in the low 16 bits", lambda a: a & 0xFFFF),
               ".change": ("<i1", "int8 per return: exporters.changes.STATUS code", lambda a: a)}


def prediction_file(folder: Path, index: int, suffix: str = ".label") -> Path:
    """The prediction of sweep ``index`` in ``folder`` (or in its ``predictions/``)."""
    for base in (folder, folder / "predictions"):
        path = base / f"{index:06d}{suffix}"
        if path.is_file():
            return path
    raise InputError(f"{folder}: no prediction {index:06d}{suffix} for sweep {index} (one NNNNNN{suffix} per sweep, "
                     f"{PREDICTIONS[suffix][1]})")


def read_prediction(path: Path, returns: int) -> np.ndarray:
    """The ids (int64) of a prediction file (``.label`` or ``.change``) of ``returns`` returns."""
    dtype, what, ids = PREDICTIONS[path.suffix]
    size, width = path.stat().st_size, np.dtype(dtype).itemsize
    if size != width * returns:
        raise InputError(f"{path}: {size} bytes, expected {width * returns} ({what}, for each of the sweep's "
                         f"{returns:,} returns)")
    return ids(np.fromfile(path, dtype=dtype)).astype(np.int64)


def score_scans(gt: str | Path, pred: str | Path, change: bool = False) -> dict:
    """Per-class IoU and mIoU of the labelling ``pred`` of the sweeps in the scan folder ``gt``
    (``change``: of their change since the previous stage)."""
    from exporters.changes import STATUS

    gt, pred = Path(gt), Path(pred)
    suffix = ".change" if change else ".label"
    if not pred.is_dir():
        raise InputError(f"{pred}: not a folder of NNNNNN{suffix} predictions")
    doc = read_lidar_json(gt)  # DamagedFileError: one line from the CLI
    if change and not all(row["change"] for row in doc["scans"]):
        raise InputError(f"{gt}: its sweeps have no change labels (stage 0 of a timeline, or no timeline: "
                         "python -m generator --phases K --lidar NAME labels stages 1..K-1)")
    if not doc["scans"]:
        raise InputError(f"{gt}: holds no sweeps; nothing to score")
    classes = list(STATUS) if change else doc["classes"]
    truth, guess = [], []
    for k, row in enumerate(doc["scans"]):
        scan = read_scan(gt, k, doc)
        truth.append((scan.change if change else scan.label).astype(np.int64))
        guess.append(read_prediction(prediction_file(pred, k, suffix), row["returns"]))
    truth, guess = np.concatenate(truth), np.concatenate(guess)
    iou, union = iou_per_class(truth, guess, len(classes))
    present = np.bincount(truth, minlength=len(classes)) > 0
    return {"task": "scan changes" if change else "scans", "sensor": doc["sensor"], "sweeps": len(doc["scans"]), "returns": int(len(truth)),
            "accuracy": float(np.mean(truth == guess)) if len(truth) else float("nan"),
            "miou": float(np.nanmean(iou[present])) if present.any() else float("nan"),
            "iou": {classes[c]: float(iou[c]) for c in range(len(classes)) if union[c] > 0},
            "classes_in_gt": [classes[c] for c in np.flatnonzero(present)],
            "parameters": {"gt": str(gt), "pred": str(pred), "mean_over": "classes present in the ground truth"}}


def scans_table(results: dict) -> str:
    """The scores as a text table."""
    lines = [f"{results['sensor']}: {results['sweeps']} sweeps, {results['returns']:,} returns",
             f"  mIoU {results['miou']:.4f} (over {len(results['classes_in_gt'])} classes in the ground truth), "
             f"accuracy {results['accuracy']:.4f}"]
    lines += [f"  {name:<16}{value:.4f}" for name, value in sorted(results["iou"].items())]
    return "\n".join(lines)
