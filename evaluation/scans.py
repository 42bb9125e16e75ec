"""Scoring a predicted labelling of LiDAR sweeps (``python -m evaluation scans``), as
SemanticKITTI's benchmark does: per-class IoU over every return of every sweep, and their
mean (docs/lidar.md, "Scoring a labelling").

Ground truth: a scan folder written by ``python -m generator --lidar NAME``
(``SEED/<trajectory>/lidar/<NAME>``, read by exporters/semantickitti.py). Prediction: a
folder of ``NNNNNN.label`` files, one per sweep, uint32 little-endian per return in the
sweep's order, the class id in the low 16 bits (the upper 16 are ignored, as SemanticKITTI's
evaluation does), or the same in a ``predictions/`` subfolder (SemanticKITTI's submission
layout). Class ids are the seed's (labels.yaml). The mean IoU is over the classes present in
the ground truth (SemanticKITTI's mean runs over a fixed class list; ours has 31 classes, of
which a site shows a part), and every class's IoU is reported.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from exporters.semantickitti import read_lidar_json, read_scan

from .inputs import InputError
from .metrics import iou_per_class


def prediction_file(folder: Path, index: int) -> Path:
    """The prediction of sweep ``index`` in ``folder`` (or in its ``predictions/``)."""
    for base in (folder, folder / "predictions"):
        path = base / f"{index:06d}.label"
        if path.is_file():
            return path
    raise InputError(f"{folder}: no prediction {index:06d}.label for sweep {index} (one NNNNNN.label per sweep, "
                     "uint32 per return: class id in the low 16 bits)")


def read_prediction(path: Path, returns: int) -> np.ndarray:
    """The class ids (int64) of a ``.label`` file of ``returns`` returns."""
    size = path.stat().st_size
    if size != 4 * returns:
        raise InputError(f"{path}: {size} bytes, expected {4 * returns} (uint32 for each of the sweep's {returns:,} returns)")
    return (np.fromfile(path, dtype="<u4") & 0xFFFF).astype(np.int64)


def score_scans(gt: str | Path, pred: str | Path) -> dict:
    """Per-class IoU and mIoU of the labelling ``pred`` of the sweeps in the scan folder ``gt``."""
    gt, pred = Path(gt), Path(pred)
    if not pred.is_dir():
        raise InputError(f"{pred}: not a folder of NNNNNN.label predictions")
    doc = read_lidar_json(gt)  # DamagedFileError: one line from the CLI
    classes = doc["classes"]
    truth, guess = [], []
    for k, row in enumerate(doc["scans"]):
        scan = read_scan(gt, k, doc)
        truth.append(scan.label.astype(np.int64))
        guess.append(read_prediction(prediction_file(pred, k), row["returns"]))
    truth, guess = np.concatenate(truth), np.concatenate(guess)
    iou, union = iou_per_class(truth, guess, len(classes))
    present = np.bincount(truth, minlength=len(classes)) > 0
    return {"task": "scans", "sensor": doc["sensor"], "sweeps": len(doc["scans"]), "returns": int(len(truth)),
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
