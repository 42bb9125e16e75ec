"""python -m evaluation reconstruction --rrd: the figure-9 classes read back with Rerun's own
RRD reader equal those of a prediction built with known matches, wrong labels and misses;
a recording inside the seed folder is refused."""

import numpy as np

from datasets.viewer import subsample_stride
from exporters.ply import read_ply
from recordings import read_rrd, run_module


def test_figure9_recording_classes(seed_folder, tmp_path):
    ply = read_ply(seed_folder / "ground_truth" / "points.ply")
    xyz = np.stack([ply.vertex[c] for c in "xyz"], 1).astype(np.float64)
    labels = ply.vertex["label"].astype(np.int64)
    n = len(xyz)
    from scipy.spatial import cKDTree

    isolated = cKDTree(xyz).query(xyz, k=2)[0][:, 1] > 0.002  # no other GT point within 2 mm
    removed = (np.arange(n) % 5 == 4) & isolated  # no prediction within tau = 1 mm: unmatched (2)
    relabelled = np.arange(n) % 5 == 1    # predicted with another label: wrong label (1)
    pred_labels = np.where(relabelled, (labels + 1) % (labels.max() + 1), labels)
    _, first = np.unique(xyz, axis=0, return_index=True)
    assert len(first) == n  # no duplicate points, so each kept GT point's nearest prediction is itself
    np.savetxt(tmp_path / "pred.txt", np.c_[xyz[~removed], pred_labels[~removed]], fmt="%.6f %.6f %.6f %d")
    out = tmp_path / "fig9.rrd"
    r = run_module("evaluation", "reconstruction", "--gt", str(seed_folder), "--pred", str(tmp_path / "pred.txt"),
                   "--tau", "0.001", "--rrd", str(out))
    assert r.returncode == 0, r.stderr[-2000:]
    rec = read_rrd(out)
    assert {"/world/prediction", "/world/ground_truth", "/world/figure9"} <= set(rec)
    table = rec["/world/figure9"]["static"]
    ids = [v for v in table.column("Points3D:class_ids").to_pylist() if v is not None][0]
    expected = np.where(removed, 2, np.where(relabelled & (pred_labels != labels), 1, 0))
    k = subsample_stride(n, 1_000_000)
    np.testing.assert_array_equal(ids, expected[::k])
    assert len(rec["/world/prediction"]["static"].column("Points3D:positions").to_pylist()[0]) == int((~removed).sum())


def test_evaluation_rrd_inside_the_seed_folder_is_refused(seed_folder, tmp_path):
    ply = read_ply(seed_folder / "ground_truth" / "points.ply")
    np.save(tmp_path / "pred.npy", np.stack([ply.vertex[c] for c in "xyz"], 1)[:100])
    r = run_module("evaluation", "reconstruction", "--gt", str(seed_folder), "--pred", str(tmp_path / "pred.npy"),
                   "--rrd", str(seed_folder / "result.rrd"))
    assert r.returncode == 2 and "--rrd" in r.stderr and r.stderr.count("\n") == 1
    assert not (seed_folder / "result.rrd").exists()
