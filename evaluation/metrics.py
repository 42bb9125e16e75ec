"""Reconstruction metrics (definitions: the Metrics section of DESIGN.md, restated in
docs/evaluation.md). Distances in metres, Euclidean unless stated; thresholds strict (<).

Everything is derived from one exact nearest-neighbour query per direction (float64, all
cores, against the distinct points only, in :class:`evaluation.kdtree.KDTree`), plus one L1
query per direction bounded by the L1 distance to the Euclidean nearest neighbour (the
paper-compatibility block), in the same trees.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from generator.geometry.voxels import majority_labels

from .inputs import Cloud, InputError, check_metres, check_sweep


DEFAULT_TAU = 0.1
DEFAULT_SWEEP = (0.01, 0.02, 0.05, 0.1, 0.2, 0.5)


def unique_rows(points: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """The distinct rows of ``points`` (N, 3) in order of first occurrence and those rows'
    indices into ``points``; ``(points, None)`` when all rows are distinct. Nearest-neighbour
    trees on many equal points degrade to a linear scan per query (10,000 copies of one
    point took minutes to score), so queries run against the distinct rows only."""
    h = points @ np.array([1.0, np.pi, np.e])  # equal rows give equal keys
    hs = np.sort(h)
    if not np.any(hs[1:] == hs[:-1]):
        return points, None
    _, first = np.unique(points, axis=0, return_index=True)
    first = np.sort(first)
    return points[first], first


@dataclass(frozen=True)
class Target:
    """A target cloud (N, 3) and its distinct rows (``first``: their indices, None when all
    rows are distinct), found once; the k-d tree of the distinct rows is built on first use
    and shared by the Euclidean and the Manhattan queries."""

    points: np.ndarray
    distinct: np.ndarray
    first: np.ndarray | None

    @classmethod
    def of(cls, points: np.ndarray) -> "Target":
        points = np.asarray(points, np.float64)
        distinct, first = unique_rows(points)
        return cls(points, distinct, first)

    @cached_property
    def tree(self):
        """An :class:`evaluation.kdtree.KDTree` of the distinct points (numba: loaded on first use)."""
        from .kdtree import KDTree

        return KDTree(self.distinct)

    @property
    def order(self) -> np.ndarray | None:
        """A spatially coherent order of ``points`` to query them in (the tree's leaf order;
        None, for the default, when rows repeat)."""
        return self.tree.order if self.first is None else None

    def original(self, idx: np.ndarray) -> np.ndarray:
        """Indices into ``points`` of indices into ``distinct`` (first occurrences)."""
        return idx if self.first is None else self.first[idx]


def _queries(source: np.ndarray | Target) -> tuple[np.ndarray, np.ndarray | None]:
    if isinstance(source, Target):
        return source.points, source.order
    return np.asarray(source, np.float64), None


def nearest(source: np.ndarray | Target, target: np.ndarray | Target) -> tuple[np.ndarray, np.ndarray]:
    """Euclidean distance (N,) from each source point to its nearest target point and that
    point's index (N,): exact, in float64; among equally near points the first in ``target``
    (so never one of its later copies)."""
    tgt = target if isinstance(target, Target) else Target.of(target)
    source, order = _queries(source)
    idx = tgt.original(tgt.tree.nearest(source, order))
    # the distance from the coordinates (not from the squared distance) for exact ties with tau
    return np.linalg.norm(source - tgt.points[idx], axis=1), idx


def nearest_manhattan(source: np.ndarray | Target, target: np.ndarray | Target, nearest_idx: np.ndarray) -> np.ndarray:
    """Manhattan (L1) distance (N,) from each source point to its L1-nearest target point,
    exact (computed as scipy does: the same floats).

    ``nearest_idx`` (N,): the index of each source point's Euclidean nearest target point;
    the L1 distance to it bounds the answer from above, so the tree query prunes every cell
    farther than that (for a point far above the ground the bound is nearly tight)."""
    tgt = target if isinstance(target, Target) else Target.of(target)
    source, order = _queries(source)
    offset = np.abs(source - tgt.points[np.asarray(nearest_idx, dtype=np.int64)])
    bound = (offset[:, 0] + offset[:, 1]) + offset[:, 2]  # the tree's own order of the sum
    return tgt.tree.nearest_manhattan(source, bound, order)


@dataclass
class Neighbours:
    """Nearest neighbours both ways: distances (metres) and indices, prediction -> GT
    (``d_pg``, ``i_pg``, one per predicted point) and GT -> prediction (``d_gp``, ``i_gp``);
    ``pred`` and ``gt``: the two clouds as :class:`Target` (for the Manhattan figures)."""

    d_pg: np.ndarray
    i_pg: np.ndarray
    d_gp: np.ndarray
    i_gp: np.ndarray
    pred: Target | None = None
    gt: Target | None = None

    @classmethod
    def compute(cls, pred: np.ndarray, gt: np.ndarray) -> "Neighbours":
        p, g = Target.of(pred), Target.of(gt)
        with ThreadPoolExecutor(2) as pool:  # the two trees are built at once
            list(pool.map(lambda t: t.tree, (p, g)))
        d_pg, i_pg = nearest(p, g)
        d_gp, i_gp = nearest(g, p)
        return cls(d_pg, i_pg, d_gp, i_gp, p, g)


def _ratio(num: float, den: float) -> float:
    return float(num) / float(den) if den else 0.0


def fscore(precision: float, recall: float) -> float:
    """2PR / (P + R), 0 when both are 0."""
    return 2 * precision * recall / (precision + recall) if precision + recall > 0 else 0.0


def iou_per_class(gt: np.ndarray, pred: np.ndarray, num_classes: int) -> tuple[np.ndarray, np.ndarray]:
    """IoU (C,) per class from paired labels (pred -1 = missed, counts against recall only)
    and the union sizes (C,) (IoU is NaN where the union is empty)."""
    ok_gt = (gt >= 0) & (gt < num_classes)
    ok_pred = (pred >= 0) & (pred < num_classes)
    tp = np.bincount(gt[ok_gt & (gt == pred)], minlength=num_classes)
    gt_count = np.bincount(gt[ok_gt], minlength=num_classes)
    pred_count = np.bincount(pred[ok_pred], minlength=num_classes)
    union = gt_count + pred_count - tp
    with np.errstate(invalid="ignore", divide="ignore"):
        iou = np.where(union > 0, tp / np.maximum(union, 1), np.nan)
    return iou, union


def reconstruction_metrics(pred: np.ndarray, gt: np.ndarray, pred_labels: np.ndarray | None = None,
                           gt_labels: np.ndarray | None = None, tau: float = DEFAULT_TAU,
                           sweep: tuple[float, ...] = DEFAULT_SWEEP, class_names: list[str] | None = None,
                           paper_block: bool = True, neighbours: Neighbours | None = None) -> dict:
    """Score a predicted cloud (N, 3) against ground-truth samples (M, 3), both in metres.

    Returns a dict: accuracy, completeness, chamfer_l1, chamfer_l2 (metres, m^2 for L2),
    precision / recall / fscore at ``tau``, the same over ``sweep``; when both clouds have
    labels (ids into ``class_names``) also semantic_chamfer (pred->gt and gt->pred), per-class
    IoU and mIoU (GT points take the label of their nearest prediction within ``tau``),
    and the paper's mIoU variant (on predicted points within ``tau``); with ``paper_block``
    the paper's one-direction Chamfer-L1 figures (Manhattan norm). ``neighbours``: the
    nearest neighbours of these two clouds if already computed.
    """
    pred_cloud, gt_cloud = Cloud(pred, pred_labels, "pred"), Cloud(gt, gt_labels, "gt")  # checked: one-line errors
    pred, gt, pred_labels, gt_labels = pred_cloud.points, gt_cloud.points, pred_cloud.labels, gt_cloud.labels
    check_metres("tau", tau)
    sweep = check_sweep(sweep)
    if len(pred) == 0 or len(gt) == 0:
        raise InputError("both clouds need at least one point")
    nn = neighbours if neighbours is not None else Neighbours.compute(pred, gt)
    d_pg, i_pg, d_gp, i_gp = nn.d_pg, nn.i_pg, nn.d_gp, nn.i_gp
    out: dict = {
        "num_pred": int(len(pred)), "num_gt": int(len(gt)), "tau": float(tau),
        "accuracy": float(d_pg.mean()), "completeness": float(d_gp.mean()),
    }
    out["chamfer_l1"] = (out["accuracy"] + out["completeness"]) / 2
    out["chamfer_l2"] = float((np.mean(d_pg ** 2) + np.mean(d_gp ** 2)) / 2)
    prec, rec = _ratio(np.count_nonzero(d_pg < tau), len(pred)), _ratio(np.count_nonzero(d_gp < tau), len(gt))
    out |= {"precision": prec, "recall": rec, "fscore": fscore(prec, rec)}
    s_pg, s_gp = np.sort(d_pg), np.sort(d_gp)
    out["sweep"] = []
    for t in sweep:
        p = np.searchsorted(s_pg, t, side="left") / len(pred)  # share strictly below t
        r = np.searchsorted(s_gp, t, side="left") / len(gt)
        out["sweep"].append({"tau": float(t), "precision": float(p), "recall": float(r), "fscore": fscore(p, r)})
    if pred_labels is not None and gt_labels is not None:
        out["semantic"] = _semantic(np.asarray(pred_labels), np.asarray(gt_labels), d_pg, i_pg, d_gp, i_gp, tau,
                                    class_names)
    if paper_block:
        p = nn.pred if nn.pred is not None else pred
        g = nn.gt if nn.gt is not None else gt
        l1_pg = nearest_manhattan(p, g, i_pg)
        l1_gp = nearest_manhattan(g, p, i_gp)
        out["paper"] = {
            "note": "the paper's code: one direction at a time, Manhattan (L1) norm of the offset to the nearest "
                    "neighbour under that norm; not the symmetric Euclidean Chamfer-L1 above",
            "chamfer_l1_manhattan_pred_to_gt": float(l1_pg.mean()),
            "chamfer_l1_manhattan_gt_to_pred": float(l1_gp.mean())}
        if "semantic" in out:
            sem = out["semantic"]
            out["paper"] |= {"semantic_chamfer_pred_to_gt": sem["semantic_chamfer_pred_to_gt"],
                             "semantic_chamfer_gt_to_pred": sem["semantic_chamfer_gt_to_pred"],
                             "miou": sem["miou_paper"]}
    return out


def _semantic(pred_labels, gt_labels, d_pg, i_pg, d_gp, i_gp, tau, class_names) -> dict:
    num_classes = len(class_names) if class_names is not None else int(max(pred_labels.max(), gt_labels.max())) + 1
    names = class_names or [str(i) for i in range(num_classes)]
    close_p, close_g = d_pg < tau, d_gp < tau
    sem_pg = np.count_nonzero(close_p & (pred_labels == gt_labels[i_pg]) & (pred_labels >= 0)) / len(pred_labels)
    sem_gp = np.count_nonzero(close_g & (gt_labels == pred_labels[i_gp]) & (gt_labels >= 0)) / len(gt_labels)
    # our mIoU: every GT point gets the label of its nearest prediction within tau, else is missed
    transferred = np.where(close_g, pred_labels[i_gp], -1)
    iou, union = iou_per_class(gt_labels, transferred, num_classes)
    # the paper's variant: predicted points within tau, compared with their nearest GT point's label
    iou_paper, union_paper = iou_per_class(gt_labels[i_pg[close_p]], pred_labels[close_p], num_classes)
    present = union > 0
    present_paper = union_paper > 0
    return {
        "semantic_chamfer_pred_to_gt": float(sem_pg), "semantic_chamfer_gt_to_pred": float(sem_gp),
        "miou": float(np.mean(iou[present])) if present.any() else 0.0,
        "miou_paper": float(np.mean(iou_paper[present_paper])) if present_paper.any() else 0.0,
        "iou": {names[c]: float(iou[c]) for c in np.flatnonzero(present)},
        "iou_paper": {names[c]: float(iou_paper[c]) for c in np.flatnonzero(present_paper)},
        "classes_in_gt": [names[c] for c in np.unique(gt_labels[gt_labels >= 0]) if c < num_classes],
        "classes_missing_from_pred": [names[c] for c in np.unique(gt_labels[gt_labels >= 0])
                                      if c < num_classes and not np.any(pred_labels == c)],
    }


def match_categories(pred_labels: np.ndarray | None, gt_labels: np.ndarray | None, d_gp: np.ndarray,
                     i_gp: np.ndarray, tau: float) -> np.ndarray:
    """Per GT point, as in the paper's figure 9: 0 matched (a prediction within tau with the
    same label, or any within tau when unlabelled), 1 wrong label, 2 unmatched. A GT point
    labelled -1 is never matched (as in Semantic Chamfer: the share of 0 is GT -> pred's)."""
    cat = np.full(len(d_gp), 2, np.int8)
    close = d_gp < tau
    if pred_labels is None or gt_labels is None:
        cat[close] = 0
        return cat
    same = (pred_labels[i_gp] == gt_labels) & (gt_labels >= 0)
    cat[close & same] = 0
    cat[close & ~same] = 1
    return cat


def voxel_downsample(points: np.ndarray, labels: np.ndarray | None, voxel: float) -> tuple[np.ndarray, np.ndarray | None]:
    """One point per occupied voxel of size ``voxel`` (metres; cells [k v, (k+1) v)): the
    mean of its points, with their most frequent label (ties: the smallest id)."""
    keys = np.floor(points / voxel).astype(np.int64)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    n = len(counts)
    sums = np.zeros((n, 3))
    np.add.at(sums, inverse, points)
    centres = sums / counts[:, None]
    if labels is None:
        return centres, None
    return centres, majority_labels(inverse, labels, num_groups=n)
