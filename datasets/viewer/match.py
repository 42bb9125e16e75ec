"""The reconstruction score as a Rerun recording (``python -m evaluation reconstruction ... --rrd``):
the prediction beside the ground truth coloured as in the paper's figure 9 (docs/viewer.md).

    world/prediction          the predicted cloud (class colours when labelled, else grey)
    world/ground_truth        the GT cloud by label
    world/figure9             the GT cloud by match: 0 matched (blue), 1 wrong label (orange), 2 unmatched (red)

All three are static and subsampled by the same rule as seeds (common.subsample_stride).
"""

from __future__ import annotations

import numpy as np

from .common import MAX_POINTS, annotation_context, class_ids, recording_file, subsample_stride

MATCH_NAMES = ("matched", "wrong label", "unmatched")
PREDICTION_GREY = (160, 160, 160)
RADIUS = 0.03  # metres


def write_match_recording(path, context: dict, tau: float, max_points: int = MAX_POINTS) -> dict:
    """Write ``path`` (.rrd) from the context of ``evaluation.score_reconstruction``; returns the
    number of points logged per entity."""
    import rerun as rr

    from evaluation.api import MATCH_COLOURS

    pred, gt, match = context["pred"], context["gt"], np.asarray(context["match"])
    counts = {}
    with recording_file(path, "reconstruction") as rec:
        rec.log("/", annotation_context(context["names"]), static=True)
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        k = subsample_stride(len(pred.points), max_points)
        points = pred.points[::k]
        style = ({"class_ids": class_ids(pred.labels[::k])} if pred.labels is not None
                 else {"colors": PREDICTION_GREY})
        rec.log("world/prediction", rr.Points3D(points, radii=RADIUS, **style), static=True)
        counts["world/prediction"] = len(points)
        k = subsample_stride(len(gt.points), max_points)
        points = gt.points[::k]
        if gt.labels is not None:
            rec.log("world/ground_truth", rr.Points3D(points, class_ids=class_ids(gt.labels[::k]), radii=RADIUS),
                    static=True)
            counts["world/ground_truth"] = len(points)
        infos = [rr.AnnotationInfo(id=i, label=f"{name} (tau {tau:g} m)", color=tuple(int(c) for c in MATCH_COLOURS[i]))
                 for i, name in enumerate(MATCH_NAMES)]
        rec.log("world/figure9", rr.AnnotationContext(infos), static=True)
        rec.log("world/figure9", rr.Points3D(points, class_ids=match[::k].astype(np.uint16), radii=RADIUS), static=True)
        counts["world/figure9"] = len(points)
    return counts
