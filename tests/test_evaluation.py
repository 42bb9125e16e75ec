"""The evaluation package: metrics on hand-computed cases and properties, coverage recomputed
from the stored ground truth against the generator's own history, and bad input on the CLI."""

import json
import math
import shutil

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import run_evaluation
from evaluation import Cloud, load_gt_cloud, reconstruction_metrics, score_coverage, score_reconstruction, voxel_downsample
from evaluation.coverage import coverage_auc
from evaluation.inputs import InputError
from exporters.ply import read_ply, write_ply


def grid(n=20, spacing=1.0, z=0.0):
    """An n x n grid of points on the plane z, spacing metres apart."""
    x, y = np.meshgrid(np.arange(n) * spacing, np.arange(n) * spacing)
    return np.column_stack([x.ravel(), y.ravel(), np.full(n * n, z)])


# ---- analytic cases ----------------------------------------------------------------------------

def test_plane_offset_by_hand():
    gt = grid()
    pred = gt + [0.0, 0.0, 0.0625]  # exactly representable; far below the 1 m grid spacing
    m = reconstruction_metrics(pred, gt, tau=0.1, sweep=(0.0625, 0.07))
    assert m["accuracy"] == m["completeness"] == m["chamfer_l1"] == 0.0625
    assert m["chamfer_l2"] == 0.0625 ** 2
    assert m["precision"] == m["recall"] == m["fscore"] == 1.0
    at, above = m["sweep"]
    assert at["precision"] == at["recall"] == at["fscore"] == 0.0  # distance exactly tau is not < tau
    assert above["fscore"] == 1.0


def test_manhattan_block_by_hand():
    gt = grid()
    pred = gt + [0.03, 0.04, 0.0]  # Euclidean 0.05, Manhattan 0.07
    m = reconstruction_metrics(pred, gt)
    assert m["chamfer_l1"] == pytest.approx(0.05, abs=1e-12)
    assert m["paper"]["chamfer_l1_manhattan_pred_to_gt"] == pytest.approx(0.07, abs=1e-12)
    assert m["paper"]["chamfer_l1_manhattan_gt_to_pred"] == pytest.approx(0.07, abs=1e-12)


def test_cube_corners_partial_prediction_by_hand():
    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    pred = corners[:2]  # (0,0,0) and (0,0,1)
    m = reconstruction_metrics(pred, corners, tau=0.5, sweep=())
    # GT -> pred distances: 2 corners at 0, 4 at 1 (one edge away), 2 at sqrt(2)
    assert m["accuracy"] == 0.0
    assert m["completeness"] == pytest.approx((4 * 1 + 2 * np.sqrt(2)) / 8)
    assert m["chamfer_l2"] == pytest.approx((0 + (4 * 1 + 2 * 2) / 8) / 2)
    assert m["precision"] == 1.0 and m["recall"] == 0.25 and m["fscore"] == pytest.approx(0.4)


def test_label_swap_and_missing_class_by_hand():
    gt = grid()
    labels = np.repeat([0, 1, 2, 3], 100)
    pred_labels = labels.copy()
    pred_labels[labels == 0], pred_labels[labels == 1] = 1, 0  # swap classes 0 and 1
    pred_labels[labels == 3] = 2  # class 3 missing from the prediction
    names = ["a", "b", "c", "d"]
    s = reconstruction_metrics(gt, gt, pred_labels, labels, class_names=names)["semantic"]
    assert s["semantic_chamfer_pred_to_gt"] == s["semantic_chamfer_gt_to_pred"] == 0.25  # only class 2 right
    assert s["iou"] == {"a": 0.0, "b": 0.0, "c": 0.5, "d": 0.0}  # c: 100 right / (100 + 100 wrongly c)
    assert s["miou"] == pytest.approx(0.125)
    assert s["classes_missing_from_pred"] == ["d"]


def test_figure9_blue_share_is_semantic_chamfer_with_unlabelled_points():
    from evaluation.metrics import Neighbours, match_categories

    pts = np.array([[0, 0, 0], [5, 0, 0], [10, 0, 0.0]])
    labels = np.array([-1, 0, 1])  # one unlabelled GT point, predicted unlabelled too
    m = reconstruction_metrics(pts, pts, labels, labels, class_names=["a", "b"])
    nn = Neighbours.compute(pts, pts)
    cat = match_categories(labels, labels, nn.d_gp, nn.i_gp, 0.1)
    assert cat.tolist() == [1, 0, 0]
    assert np.mean(cat == 0) == pytest.approx(m["semantic"]["semantic_chamfer_gt_to_pred"]) == pytest.approx(2 / 3)


def test_empty_overlap_and_duplicates():
    gt = grid()
    m = reconstruction_metrics(gt + [100.0, 0, 0], gt, np.zeros(400, int), np.zeros(400, int), class_names=["x"])
    assert m["precision"] == m["recall"] == m["fscore"] == 0.0
    assert m["semantic"]["semantic_chamfer_pred_to_gt"] == 0.0 and m["semantic"]["miou"] == 0.0
    pred = gt[:150] + 0.01
    once = reconstruction_metrics(pred, gt)
    twice = reconstruction_metrics(np.concatenate([pred, pred]), gt)
    for key in ("accuracy", "completeness", "chamfer_l1", "chamfer_l2", "precision", "recall", "fscore"):
        assert once[key] == pytest.approx(twice[key], abs=1e-15)


def test_voxel_downsample_by_hand():
    pts = np.array([[0.01, 0.01, 0.01], [0.03, 0.03, 0.03], [0.04, 0.01, 0.02], [0.06, 0.0, 0.0]])
    centres, labels = voxel_downsample(pts, np.array([5, 7, 7, 1]), 0.05)
    order = np.argsort(centres[:, 0])
    np.testing.assert_allclose(centres[order], [[0.08 / 3, 0.05 / 3, 0.06 / 3], [0.06, 0.0, 0.0]])
    np.testing.assert_array_equal(labels[order], [7, 1])  # the majority label of the voxel


# ---- properties ---------------------------------------------------------------------------------

clouds = st.integers(1, 60).flatmap(lambda n: st.tuples(
    st.lists(st.tuples(*[st.floats(-5, 5, allow_nan=False)] * 3), min_size=n, max_size=n),
    st.lists(st.integers(0, 3), min_size=n, max_size=n)))


@settings(max_examples=40, deadline=None)
@given(clouds)
def test_identical_clouds_score_perfectly(cloud):
    pts, lab = np.array(cloud[0]), np.array(cloud[1])
    m = reconstruction_metrics(pts, pts, lab, lab, class_names=list("abcd"))
    assert m["accuracy"] == m["completeness"] == 0.0 and m["fscore"] == 1.0
    # points at distance 0 from each other (duplicates, or so close that the squared distance
    # underflows, e.g. 0 and 1e-271) with different labels are ambiguous: perfect only when no
    # two points are at distance 0
    d2 = ((pts[:, None] - pts[None]) ** 2).sum(-1)
    np.fill_diagonal(d2, np.inf)
    if (d2 > 0).all():
        assert m["semantic"]["semantic_chamfer_pred_to_gt"] == 1.0 and m["semantic"]["miou"] == 1.0


@settings(max_examples=40, deadline=None)
@given(clouds, clouds, st.randoms(use_true_random=False))
def test_order_invariance_and_direction_swap(a, b, rnd):
    pa, la, pb, lb = np.array(a[0]), np.array(a[1]), np.array(b[0]), np.array(b[1])
    names = list("abcd")
    m = reconstruction_metrics(pa, pb, la, lb, tau=0.5, class_names=names)
    perm_a, perm_b = list(range(len(pa))), list(range(len(pb)))
    rnd.shuffle(perm_a)
    rnd.shuffle(perm_b)
    m2 = reconstruction_metrics(pa[perm_a], pb[perm_b], la[perm_a], lb[perm_b], tau=0.5, class_names=names)
    for key in ("accuracy", "completeness", "chamfer_l2", "precision", "recall"):
        assert m[key] == pytest.approx(m2[key], abs=1e-12)
    swapped = reconstruction_metrics(pb, pa, lb, la, tau=0.5, class_names=names)
    assert swapped["accuracy"] == pytest.approx(m["completeness"], abs=1e-12)
    assert swapped["precision"] == m["recall"] and swapped["recall"] == m["precision"]
    if len(np.unique(pa, axis=0)) == len(pa) and len(np.unique(pb, axis=0)) == len(pb):
        s, t = m["semantic"], swapped["semantic"]
        assert s["semantic_chamfer_pred_to_gt"] == pytest.approx(t["semantic_chamfer_gt_to_pred"])


@pytest.mark.parametrize("kwargs, message", [
    ({"tau": 0.0}, "^tau must be a positive number of metres, got 0.0$"),
    ({"tau": math.nan}, "^tau must be a positive number of metres, got nan$"),
    ({"tau": "0.05"}, "^tau must be a positive number of metres, got '0.05'$"),
    ({"crop_margin": -3.0}, "^crop_margin must be a non-negative number of metres, got -3.0$"),
    ({"voxel": math.inf}, "^voxel must be a positive number of metres, got inf$"),
])
def test_scoring_numbers_are_one_line_input_errors(kwargs, message):
    """Checked before any file is read (the paths here do not exist)."""
    with pytest.raises(InputError, match=message):
        score_reconstruction("missing.ply", "missing", **kwargs)
    if "tau" in kwargs:
        with pytest.raises(InputError, match=message):
            reconstruction_metrics(np.eye(3), np.eye(3), tau=kwargs["tau"])


# ---- on the real pipeline's output ----------------------------------------------------------------

@pytest.mark.parametrize("kind", ["orbit", "spline"])
def test_coverage_from_stored_mesh_equals_the_simulators_history(seed_folder, kind):
    expected = json.loads((seed_folder / kind / "coverage.json").read_text())
    r = score_coverage(seed_folder, seed_folder / kind / "trajectory.npz")
    assert r["num_poses"] == 3 and r["final_coverage"] > 0
    np.testing.assert_allclose(r["coverage"], expected["coverage"], rtol=0, atol=1e-12)
    assert r["auc"] == pytest.approx(expected["auc"], abs=1e-12)
    assert r["auc"] == pytest.approx(coverage_auc(r["coverage"]))
    # the COLMAP model of the same flight gives the same poses (scored at the first frame)
    a = score_coverage(seed_folder, seed_folder / kind / "sparse" / "0", frames="first")
    b = score_coverage(seed_folder, seed_folder / kind / "trajectory.npz", frames="first")
    np.testing.assert_allclose(a["coverage"], b["coverage"], atol=1e-12)
    with pytest.raises(InputError, match=r"^max_depth must be a number of metres above 0\.\d+, got 0\.01$"):
        score_coverage(seed_folder, seed_folder / kind / "trajectory.npz", max_depth=0.01)


def test_perfect_and_noisy_reconstruction_of_the_real_gt(seed_folder):
    gt = read_ply(seed_folder / "ground_truth" / "points.ply")
    r, _ = score_reconstruction(Cloud(gt.points, gt.vertex["label"].astype(np.int64), "same"), seed_folder)
    m = r["metrics"]
    assert m["chamfer_l1"] == 0 and m["semantic"]["miou"] == 1.0
    assert r["labels"] == json.loads((seed_folder / "labels.json").read_text())


cli = run_evaluation


def test_cli_writes_json_and_figure9_ply(seed_folder, tmp_path):
    gt = read_ply(seed_folder / "ground_truth" / "points.ply")
    labels = gt.vertex["label"].copy()
    labels[:10] = (labels[:10] + 1) % 5  # ten wrong labels
    np.savetxt(tmp_path / "pred.txt", np.column_stack([gt.points, labels]), fmt="%.9g")
    r = cli("reconstruction", "--gt", seed_folder, "--pred", tmp_path / "pred.txt", "--json", tmp_path / "r.json",
            "--ply", tmp_path / "fig9.ply", "--crop")
    assert r.returncode == 0, r.stderr
    assert "Semantic Chamfer pred -> GT" in r.stdout and "Read blend" not in r.stdout
    doc = json.loads((tmp_path / "r.json").read_text())
    assert doc["parameters"]["crop"] and doc["parameters"]["tau"] == 0.1 and doc["versions"]["numpy"] and doc["versions"]["numba"]
    assert doc["metrics"]["semantic"]["semantic_chamfer_gt_to_pred"] == pytest.approx(1 - 10 / len(labels))
    fig = read_ply(tmp_path / "fig9.ply")
    assert np.count_nonzero(fig.vertex["match"] == 1) == 10 and np.count_nonzero(fig.vertex["match"] == 2) == 0
    np.testing.assert_array_equal(fig.vertex["match"] == 1, labels != gt.vertex["label"])
    r = cli("coverage", "--gt", seed_folder, "--trajectory", seed_folder / "orbit" / "trajectory.npz",
            "--json", tmp_path / "c.json", "--plot", tmp_path / "c.png")
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "c.json").read_text())["num_poses"] == 3 and (tmp_path / "c.png").stat().st_size > 0
    # same inputs, same bytes (no wall-clock values in the results)
    assert cli("reconstruction", "--gt", seed_folder, "--pred", tmp_path / "pred.txt", "--json", tmp_path / "r2.json",
               "--crop").returncode == 0
    assert cli("coverage", "--gt", seed_folder, "--trajectory", seed_folder / "orbit" / "trajectory.npz",
               "--json", tmp_path / "c2.json").returncode == 0
    for a, b in (("r.json", "r2.json"), ("c.json", "c2.json")):
        assert (tmp_path / a).read_bytes() == (tmp_path / b).read_bytes(), a


def _bad_inputs(folder, tmp):
    good = tmp / "good.txt"
    np.savetxt(good, np.random.default_rng(0).uniform(0, 1, (20, 3)))
    (tmp / "nan.txt").write_text("0 0 0\nnan 1 1\n")
    (tmp / "inf.npy").write_bytes(b"")
    np.save(tmp / "inf.npy", np.array([[0, 0, 0], [np.inf, 0, 0]]))
    (tmp / "cols.txt").write_text("0 0 0 0 0\n1 1 1 1 1\n")
    (tmp / "empty.txt").write_text("# nothing\n")
    (tmp / "label.txt").write_text("0 0 0 3\n1 1 1 99\n")
    (tmp / "labels_short.txt").write_text("1\n2\n")
    (tmp / "names.txt").write_text("0 0 0 Building\n1 1 1 Unicorn\n")
    (tmp / "huge_label.txt").write_text("0 0 0 1e40\n")
    (tmp / "a_folder").mkdir()
    write_ply(tmp / "trunc.ply", {"x": np.zeros(10, np.float32), "y": np.zeros(10, np.float32), "z": np.zeros(10, np.float32)})
    data = (tmp / "trunc.ply").read_bytes()
    (tmp / "trunc.ply").write_bytes(data[:-7])
    (tmp / "garbage.ply").write_bytes(b"\x00\x01garbage")
    incomplete = tmp / "incomplete"
    shutil.copytree(folder, incomplete)
    (incomplete / "ground_truth" / "scene.h5").unlink()
    no_manifest = tmp / "no_manifest"
    shutil.copytree(folder, no_manifest)
    (no_manifest / "manifest.json").unlink()
    rec = ["reconstruction", "--gt", folder, "--pred"]
    return [
        (rec + [tmp / "missing.ply"], "no such file"),
        (rec + [tmp / "trunc.ply"], "truncated"),
        (rec + [tmp / "garbage.ply"], "not a PLY file"),
        (rec + [tmp / "nan.txt"], "NaN or infinite"),
        (rec + [tmp / "inf.npy"], "NaN or infinite"),
        (rec + [tmp / "cols.txt"], "expected (N, 3)"),
        (rec + [tmp / "empty.txt"], "empty point cloud"),
        (rec + [tmp / "label.txt"], "outside the taxonomy"),
        (rec + [good, "--pred-labels", tmp / "labels_short.txt"], "2 labels for 20 points"),
        (rec + [tmp / "names.txt"], "unknown class name 'Unicorn'"),
        (rec + [tmp / "huge_label.txt"], "labels must be integer ids"),
        (rec + [tmp / "a_folder"], "is a folder"),
        (["reconstruction", "--gt", incomplete, "--pred", good], "missing scene.h5"),
        (["reconstruction", "--gt", no_manifest, "--pred", good], "incomplete seed folder"),
        (["reconstruction", "--gt", folder, "--pred", good, "--tau", "-1"], "positive number"),
        (["reconstruction", "--gt", folder, "--pred", good, "--crop-margin", "0.2"], "--crop-margin applies to --crop"),
        (["change", "--gt", folder, "--pred", good, "--stages", "0", "1", "2"],
         "unrecognized arguments: 2 (see python -m evaluation change --help)"),
        (["reconstruction", "--gt", folder, "--pred", good, "--crop", "--crop-margin", "-1"], "a number of metres >= 0"),
        (["coverage", "--gt", incomplete, "--trajectory", folder / "orbit" / "trajectory.npz"], "missing scene.h5"),
        (["coverage", "--gt", folder, "--trajectory", good], "trajectory"),
    ]


def test_bad_input_one_line_exit_2_nothing_written(seed_folder, tmp_path):
    for args, message in _bad_inputs(seed_folder, tmp_path):
        out = tmp_path / "out.json"
        r = cli(*args, "--json", out)
        assert r.returncode == 2, (args, r.stdout, r.stderr)
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and message in lines[0], (args, r.stderr)
        assert "Traceback" not in r.stderr and not out.exists()


def test_coverage_max_depth_override(seed_folder):
    traj = seed_folder / "orbit" / "trajectory.npz"
    full = score_coverage(seed_folder, traj)
    near = score_coverage(seed_folder, traj, max_depth=25.0)
    assert near["parameters"]["far"] == 25.0 and full["parameters"]["far"] == 60.0
    assert np.all(np.array(near["coverage"]) <= np.array(full["coverage"]))
    assert near["final_coverage"] < full["final_coverage"]


# ---- point tracks (TAP-Vid conventions) -------------------------------------------------------

def test_coverage_auc_is_the_papers_trapezoid():
    # the paper: np.trapz(coverages, np.linspace(0, 1, len(coverages))); one pose has no width
    assert coverage_auc([0.4]) == 0.0
    assert coverage_auc([0.0, 1.0]) == 0.5
    assert coverage_auc([0.2, 0.4, 1.0]) == pytest.approx((0.2 + 0.4) / 4 + (0.4 + 1.0) / 4)


def test_text_ground_truth_with_class_names(tmp_path):
    """A third-party GT cloud in text with class names: read with labels.json beside it
    (a custom table), else with the generator's taxonomy (the documented fallback)."""
    rows = "0 0 0 Tower\n1 0 0 Fence\n0 1 0 Tower\n"
    (tmp_path / "custom").mkdir()
    (tmp_path / "custom" / "gt.xyz").write_text(rows)
    (tmp_path / "custom" / "labels.json").write_text(json.dumps(["Fence", "Tower"]))
    pred = Cloud(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]]), np.array([1, 0, 0]), "pred")
    results, _ = score_reconstruction(pred, tmp_path / "custom" / "gt.xyz")
    assert results["labels"] == ["Fence", "Tower"]
    assert results["metrics"]["semantic"]["semantic_chamfer_gt_to_pred"] == pytest.approx(2 / 3)
    (tmp_path / "taxonomy").mkdir()
    (tmp_path / "taxonomy" / "gt.txt").write_text("0 0 0 Building\n1 0 0 ground\n")
    cloud, names = load_gt_cloud(tmp_path / "taxonomy" / "gt.txt")
    assert names[:2] == ["Ground", "Building"] and cloud.labels.tolist() == [1, 0]


def test_tapvid_metrics_by_hand():
    from evaluation import tapvid_metrics

    # 2 queries, 4 frames; query frames 0 and 1 ('first' mode evaluates the frames after them)
    gt = np.zeros((2, 4, 2))
    occ = np.array([[False, False, True, False], [True, False, False, False]])
    pred = gt + [3.0, 0.0]  # every prediction 3 px off
    pred_occ = occ.copy()
    m = tapvid_metrics(gt, occ, pred, pred_occ, np.array([0, 1]))
    # evaluated: q0 frames 1, 2, 3 (2 visible), q1 frames 2, 3 (both visible): 4 visible pairs
    assert m["occlusion_accuracy"] == 1.0
    assert m["pts_within"] == {"1": 0.0, "2": 0.0, "4": 1.0, "8": 1.0, "16": 1.0}
    assert m["average_pts_within"] == pytest.approx(0.6)
    # delta <= 2: 0 TP, 4 FN, 4 FP (visible but too far) -> 0; delta >= 4: 4 TP -> 1
    assert m["jaccard"] == {"1": 0.0, "2": 0.0, "4": 1.0, "8": 1.0, "16": 1.0}
    # predict q1 occluded at frame 3 (it is visible): one FN at every delta
    pred_occ[1, 3] = True
    m = tapvid_metrics(gt, occ, pred, pred_occ, np.array([0, 1]))
    assert m["occlusion_accuracy"] == pytest.approx(4 / 5)
    assert m["jaccard"]["4"] == pytest.approx(3 / 4)  # TP 3, FN 1, FP 0
    assert m["pts_within"]["4"] == 1.0  # <delta ignores predicted occlusion
    # strided mode also evaluates the frames before the query; TAP-Vid's 256x256 scaling halves the offsets here
    s = tapvid_metrics(gt, occ, pred, occ, np.array([0, 1]), mode="strided", image_size=(512, 512), resize_to=(256, 256))
    assert s["pts_within"]["2"] == 1.0 and s["pts_within"]["1"] == 0.0


def test_tracks_cli_on_the_real_subset(seed_folder, tmp_path):
    from exporters.tracks import read_tracks

    tv = read_tracks(seed_folder / "orbit" / "tracks.h5")["tapvid"]
    np.savez(tmp_path / "perfect.npz", tracks=tv["tracks"], occluded=tv["occluded"])
    r = cli("tracks", "--gt", seed_folder / "orbit", "--pred", tmp_path / "perfect.npz", "--json", tmp_path / "t.json")
    assert r.returncode == 0, r.stderr
    m = json.loads((tmp_path / "t.json").read_text())["metrics"]
    assert m["occlusion_accuracy"] == m["average_jaccard"] == m["average_pts_within"] == 1.0
    # exact positions all flagged occluded (NaN where the GT point is hidden): <delta is
    # TAP-Vid's, whatever the predicted flag, so still 1; no true positive for the Jaccard
    hidden_nan = np.where(tv["occluded"][..., None], np.nan, tv["tracks"])
    np.savez(tmp_path / "flagged.npz", tracks=hidden_nan, occluded=np.ones_like(tv["occluded"]))
    r = cli("tracks", "--gt", seed_folder / "orbit", "--pred", tmp_path / "flagged.npz", "--json", tmp_path / "f.json")
    assert r.returncode == 0 and "Warning" not in r.stderr, r.stderr
    m = json.loads((tmp_path / "f.json").read_text())["metrics"]
    assert m["average_pts_within"] == 1.0 and m["average_jaccard"] == 0.0 and m["occlusion_accuracy"] < 1.0
    np.savez(tmp_path / "short.npz", tracks=tv["tracks"][:, :2], occluded=tv["occluded"][:, :2])
    r = cli("tracks", "--gt", seed_folder / "orbit", "--pred", tmp_path / "short.npz", "--json", tmp_path / "bad.json")
    assert r.returncode == 2 and "expected" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "bad.json").exists()
