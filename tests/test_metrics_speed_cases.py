"""Reconstruction metrics on degenerate inputs (duplicates, a single point) and their exact
agreement with a plain scipy cKDTree computation (issue #13 case 6, #15)."""

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from evaluation.kdtree import KDTree
from evaluation.metrics import Neighbours, nearest, nearest_manhattan, reconstruction_metrics, unique_rows

ROOT = Path(__file__).resolve().parents[1]


def _clouds(rng, n, m, duplicates):
    # coordinates on a 0.1 m lattice: many exact ties and repeated points
    pred = np.round(rng.uniform(0, 2, (n, 3)), 1)
    gt = np.round(rng.uniform(0, 2, (m, 3)), 1)
    if duplicates == "pred":
        pred = np.repeat(pred[:1], n, axis=0)
    elif duplicates == "gt":
        gt = np.repeat(gt[:3], -(-m // 3), axis=0)[:m]
    return pred, gt


@pytest.mark.parametrize("duplicates", [None, "pred", "gt"])
def test_neighbours_and_manhattan_equal_ckdtree(duplicates):
    rng = np.random.default_rng(7)
    for _ in range(15):
        n, m = (int(v) for v in rng.integers(1, 400, 2))
        pred, gt = _clouds(rng, n, m, duplicates)
        nn = Neighbours.compute(pred, gt)
        for src, tgt, d, i in ((pred, gt, nn.d_pg, nn.i_pg), (gt, pred, nn.d_gp, nn.i_gp)):
            tree = cKDTree(tgt)
            d_ref = tree.query(src)[0]
            np.testing.assert_allclose(d, d_ref, rtol=0, atol=1e-12)
            # the returned index is a nearest point (ties: any of them)
            np.testing.assert_allclose(np.linalg.norm(src - tgt[i], axis=1), d_ref, rtol=0, atol=1e-12)
            l1_ref = tree.query(src, p=1)[0]
            np.testing.assert_allclose(nearest_manhattan(src, tgt, i), l1_ref, rtol=0, atol=1e-12)


def test_unique_rows_and_nearest_never_return_a_later_copy():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 0, 0], [1, 0, 0], [2, 0, 0.0]])
    distinct, first = unique_rows(pts)
    assert first.tolist() == [0, 1, 4]
    assert distinct.tolist() == [[0, 0, 0], [1, 0, 0], [2, 0, 0]]
    assert unique_rows(distinct)[1] is None
    d, idx = nearest(np.array([[0.1, 0, 0], [1.2, 0, 0], [0.5, 0, 0], [1.5, 0, 0]]), pts)
    assert idx.tolist() == [0, 1, 0, 1]  # first occurrences; equally near: the first point
    np.testing.assert_allclose(d, [0.1, 0.2, 0.5, 0.5], rtol=0, atol=1e-15)


@pytest.mark.parametrize("layout", ["lattice", "scales", "one"])
def test_kdtree_equals_brute_force(layout):
    """Euclidean index (ties: the lowest index) and L1 distance of every query equal a brute
    force over all points, on a lattice full of ties, on points at very different scales
    (a deep tree) and on a single point."""
    rng = np.random.default_rng(5)
    if layout == "lattice":
        pts = np.unique(np.round(rng.uniform(0, 1, (600, 3)), 1), axis=0)
        queries = np.round(rng.uniform(-0.5, 1.5, (500, 3)), 2)
    elif layout == "scales":
        pts = np.concatenate([rng.uniform(-1, 1, (300, 3)) * 10.0 ** rng.integers(-9, 4, (300, 1)),
                              [[5e3, 0, 0], [0, -5e3, 0]]])
        queries = np.concatenate([rng.normal(0, 1e-6, (200, 3)), rng.normal(0, 1e3, (200, 3))])
    else:
        pts = np.array([[1.0, 2.0, 3.0]])
        queries = rng.uniform(-5, 5, (50, 3))
    tree = KDTree(pts, leaf_size=2)
    idx = tree.nearest(queries)
    d2 = ((queries[:, None, :] - pts[None]) ** 2).sum(axis=-1)
    np.testing.assert_array_equal(idx, np.argmin(d2, axis=1))
    l1 = np.abs(queries[:, None, :] - pts[None]).sum(axis=-1).min(axis=1)
    bound = np.abs(queries - pts[idx]).sum(axis=1)
    np.testing.assert_array_equal(tree.nearest_manhattan(queries, bound), l1)
    np.testing.assert_array_equal(tree.nearest_manhattan(queries, np.full(len(queries), np.inf)), l1)


def test_manhattan_equals_ckdtree_on_a_site_like_cloud_with_far_outliers():
    """The bounded L1 queries give exactly scipy's unbounded L1 answer, also for points far
    from the target (outliers above a ground plane: the case with the loosest bounds) and
    for offsets along an axis (settled without a query)."""
    rng = np.random.default_rng(11)
    ground = np.column_stack([rng.uniform(0, 20, (20_000, 2)), np.zeros(20_000)])
    boxes = rng.uniform(0, 20, (5_000, 3)) * [1, 1, 0.2]
    gt = np.concatenate([ground, boxes])
    pred = np.concatenate([gt[:8_000] + rng.normal(0, 0.03, (8_000, 3)), rng.uniform(0, 20, (2_000, 3)),
                           gt[:50] + [0, 0, 1.5]])  # straight above a GT point: B == R
    nn = Neighbours.compute(pred, gt)
    for src, tgt, i in ((pred, gt, nn.i_pg), (gt, pred, nn.i_gp)):
        ref = cKDTree(tgt).query(src, p=1, workers=-1)[0]
        np.testing.assert_array_equal(nearest_manhattan(src, tgt, i), ref)
    out = reconstruction_metrics(pred, gt)
    assert out["paper"]["chamfer_l1_manhattan_pred_to_gt"] == cKDTree(gt).query(pred, p=1)[0].mean()


def test_single_point_against_a_cloud():
    rng = np.random.default_rng(3)
    gt = rng.uniform(-5, 5, (500, 3))
    one = np.array([[0.5, -0.25, 1.0]])
    out = reconstruction_metrics(one, gt)
    d = np.linalg.norm(gt - one, axis=1)
    assert out["accuracy"] == pytest.approx(d.min(), abs=1e-12)
    assert out["completeness"] == pytest.approx(d.mean(), abs=1e-12)
    l1 = np.abs(gt - one).sum(axis=1)
    assert out["paper"]["chamfer_l1_manhattan_pred_to_gt"] == pytest.approx(l1.min(), abs=1e-12)
    assert out["paper"]["chamfer_l1_manhattan_gt_to_pred"] == pytest.approx(l1.mean(), abs=1e-12)


def test_100k_duplicate_points_score_in_seconds():
    """100,000 copies of one point against 200,000 GT points, in a fresh process with a
    generous time limit (the scoring used to take minutes: linear in the copies)."""
    code = textwrap.dedent("""
        import json, sys
        import numpy as np
        sys.path.insert(0, sys.argv[1])
        from evaluation.metrics import reconstruction_metrics
        rng = np.random.default_rng(0)
        gt = rng.uniform(0, 10, (200_000, 3))
        pred = np.repeat([[1.0, 2.0, 3.0]], 100_000, axis=0)
        labels = rng.integers(0, 3, 200_000)
        out = reconstruction_metrics(pred, gt, np.zeros(100_000, int), labels, class_names=["a", "b", "c"])
        d = np.linalg.norm(gt - [1.0, 2.0, 3.0], axis=1)
        l1 = np.abs(gt - [1.0, 2.0, 3.0]).sum(axis=1)
        print(json.dumps([out["accuracy"], d.min(), out["completeness"], d.mean(),
                          out["paper"]["chamfer_l1_manhattan_gt_to_pred"], l1.mean()]))
    """)
    res = subprocess.run([sys.executable, "-c", code, str(ROOT)], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr[-2000:]
    acc, acc_ref, comp, comp_ref, l1, l1_ref = json.loads(res.stdout.strip().splitlines()[-1])
    assert acc == pytest.approx(acc_ref, abs=1e-12)
    assert comp == pytest.approx(comp_ref, rel=1e-12)
    assert l1 == pytest.approx(l1_ref, rel=1e-12)


def test_kdtree_on_extents_beyond_the_float_range():
    """Boxes wider than the largest float (their midpoints must not overflow) still split."""
    pts = np.array([[-1e308, 0, 0], [1e308, 0, 0], [0, 1e308, -1e308], [5.0, 5.0, 5.0], [0, 0, 1e300]])
    tree = KDTree(pts, leaf_size=1)
    queries = np.array([[4.0, 4.0, 4.0], [6.0, 5.0, 5.0]])
    assert tree.nearest(queries).tolist() == [3, 3]
    assert tree.nearest_manhattan(queries, np.full(2, np.inf)).tolist() == [3.0, 1.0]


def test_kdtree_refuses_non_finite_coordinates():
    tree = KDTree(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="queries contain NaN"):
        tree.nearest(np.array([[0.0, np.nan, 0.0]]))
    with pytest.raises(ValueError, match="points contain NaN"):
        KDTree(np.array([[0.0, 0.0, np.inf]]))
    with pytest.raises(ValueError, match="shape"):
        KDTree(np.zeros((4, 2)))
