"""The paper's baselines on tiny configurations: voxel fusion by hand, reproducible tables,
reconstructed points on the scene's surfaces."""

import json
import subprocess
import sys

import numpy as np
import pytest

from conftest import ROOT
from generator.geometry.voxels import VoxelMap


def test_voxel_map_centres_and_majority_labels():
    vm = VoxelMap(0.5)
    vm.add(np.array([[0.1, 0.1, 0.1], [0.2, 0.4, 0.3], [0.3, 0.2, 0.1], [-0.1, 0.0, 0.0], [np.nan, 0, 0]]),
           np.array([4, 2, 2, 7, 1]))
    vm.add(np.array([[0.4, 0.4, 0.4], [0.45, 0.1, 0.2], [9.0, 9.0, 9.0]]), np.array([4, 4, -1]))  # -1 ignored
    centres, labels = vm.points()
    order = np.lexsort(centres.T[::-1])
    np.testing.assert_allclose(centres[order], [[-0.25, 0.25, 0.25], [0.25, 0.25, 0.25]])
    np.testing.assert_array_equal(labels[order], [7, 4])  # label 4: three points against two
    tie = VoxelMap(1.0)
    tie.add(np.array([[0.5, 0.5, 0.5], [0.6, 0.6, 0.6]]), np.array([3, 1]))
    assert tie.points()[1].tolist() == [1]  # ties go to the smallest id


def baselines(*args):
    return subprocess.run([sys.executable, "-m", "generator.baselines", *map(str, args)], capture_output=True,
                          text=True, cwd=ROOT)


def test_exploration_table_is_reproducible(tmp_path):
    args = ["exploration", "--seeds", "3", "--steps", "15", "--runs", "2", "--scene-preset", "small",
            "--points-density", "1"]
    a, b = baselines(*args, "--out", tmp_path / "a"), baselines(*args, "--out", tmp_path / "b")
    assert a.returncode == 0 and b.returncode == 0, a.stderr[-2000:]
    ra, rb = (json.loads((tmp_path / x / "exploration.json").read_text()) for x in "ab")
    for method in ("random_walk", "modified_random_walk"):
        assert ra["seeds"]["3"][method]["auc_runs"] == rb["seeds"]["3"][method]["auc_runs"]
        assert len(ra["seeds"]["3"][method]["auc_runs"]) == 2
    curves = np.load(tmp_path / "a" / "site_3" / "coverage_curves.npz")
    assert curves["random_walk"].shape == (2, 16) and np.all(np.diff(curves["random_walk"], axis=1) >= 0)
    assert (tmp_path / "a" / "figure8_seed_3.png").is_file() and (tmp_path / "a" / "coverage_seed_3.png").is_file()
    assert "| 3 |" in a.stdout and "Read blend" not in a.stdout


def test_reconstruction_points_lie_on_the_scene(tmp_path):
    from exporters.ground_truth import read_ground_truth
    from exporters.ply import read_ply
    from generator.geometry.o3d import import_open3d

    args = ["reconstruction", "--seed", "3", "--steps", "3", "--scene-preset", "small", "--resolution", "64x48",
            "--gt-density", "20"]
    r = baselines(*args, "--out", tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    res = json.loads((tmp_path / "reconstruction.json").read_text())
    again = baselines(*args, "--out", tmp_path / "again")
    assert again.returncode == 0
    res2 = json.loads((tmp_path / "again" / "reconstruction.json").read_text())
    assert res2["scores"]["gt_density_20"]["metrics"] == res["scores"]["gt_density_20"]["metrics"]  # reproducible
    m = res["scores"]["gt_density_20"]["metrics"]
    assert res["predicted_points"] > 100 and 0 < m["semantic"]["semantic_chamfer_pred_to_gt"] <= 1
    pred = read_ply(tmp_path / "prediction.ply")
    assert len(pred.points) == res["predicted_points"]
    # every voxel centre is within half a voxel diagonal of a surface (plus float32 slack)
    scene = read_ground_truth(tmp_path)
    o3d = import_open3d()
    rc = o3d.t.geometry.RaycastingScene()
    for p in scene.parts:
        rc.add_triangles(o3d.core.Tensor(p.world_vertices().astype(np.float32)), o3d.core.Tensor(p.faces.astype(np.uint32)))
    dist = rc.compute_distance(o3d.core.Tensor(pred.points.astype(np.float32))).numpy()
    assert np.quantile(dist, 0.999) <= 0.05 * np.sqrt(3) / 2 + 0.005
    assert (tmp_path / "figure9.ply").is_file() and (tmp_path / "figure9.png").is_file()


@pytest.mark.parametrize("args,message", [
    (["exploration", "--steps", "0", "--out", "x"], "integer >= 1"),
    (["reconstruction", "--voxel", "-1", "--out", "x"], "positive number of metres"),
    (["exploration", "--seeds", "1", "1", "--out", "x"], "lists a seed twice"),
])
def test_bad_arguments(args, message):
    r = baselines(*args)
    assert r.returncode == 2 and message in r.stderr and len(r.stderr.strip().splitlines()) == 1
