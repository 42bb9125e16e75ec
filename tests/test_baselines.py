"""The paper's baselines on tiny configurations: voxel fusion by hand, reproducible tables,
reconstructed points on the scene's surfaces."""

import json
import math
import re
import subprocess
import sys

import numpy as np
import pytest

from conftest import ROOT
from generator.geometry.camera import look_at
from generator.geometry.voxels import VoxelMap
from trajectories import modified_random_walk


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


def test_paper_voxel_rule_corners_and_first_label():
    from generator.baselines.paper_voxels import FirstSeenVoxels

    vm = FirstSeenVoxels(0.5)
    # frame 1: three points in voxel (0, 0, 0), the first labelled 2 (the majority is 4)
    vm.add(np.array([[0.1, 0.1, 0.1], [0.2, 0.4, 0.3], [0.3, 0.2, 0.1], [np.nan, 0, 0], [9.0, 9.0, 9.0]]),
           np.array([2, 4, 4, 1, -1]))  # NaN and -1 are ignored
    # frame 2: voxel (0, 0, 0) again (it keeps label 2) and a new voxel (-1, 0, 0)
    vm.add(np.array([[0.45, 0.1, 0.2], [-0.1, 0.0, 0.0]]), np.array([5, 7]))
    corners, labels = vm.points()
    order = np.lexsort(corners.T[::-1])
    np.testing.assert_allclose(corners[order], [[-0.5, 0.0, 0.0], [0.0, 0.0, 0.0]])
    np.testing.assert_array_equal(labels[order], [7, 2])
    assert len(vm) == 2


@pytest.mark.parametrize("voxel", [0, -0.5, math.inf, math.nan, "0.5", True])
def test_voxel_sizes_are_checked(voxel):
    from generator.baselines.paper_voxels import FirstSeenVoxels

    for fusion in (FirstSeenVoxels, VoxelMap):
        with pytest.raises(ValueError, match=f"^voxel size must be a positive number of metres, got {re.escape(repr(voxel))}$"):
            fusion(voxel)


def baselines(*args):
    return subprocess.run([sys.executable, "-m", "generator.baselines", *map(str, args)], capture_output=True,
                          text=True, cwd=ROOT)


class Box:
    """A MotionChecker: free space is the box ``lo <= p <= hi`` (the end of a move decides)."""

    def __init__(self, lo, hi):
        self.lo, self.hi = np.asarray(lo, float), np.asarray(hi, float)

    def can_move(self, a, b):
        return bool(np.all(np.asarray(b) >= self.lo) and np.all(np.asarray(b) <= self.hi))

    def is_free(self, p):
        return self.can_move(p, p)


def _heading(pose):
    return math.degrees(math.atan2(pose[1, 2], pose[0, 2]))


def test_modified_walk_draws_headings_inside_one_step():
    start = look_at((0.0, 0.0, 1.5), (0.0, 10.0, 1.5))  # looking along +Y, a wall 1 m ahead
    box = Box((-20, -20, 0), (20, 1.0, 3))
    traj = modified_random_walk(box, start, 6, np.random.default_rng(7))
    assert len(traj.poses) == 7 and len(traj.actions) == 6
    assert traj.actions[0] == "turn_forward" and traj.params["heading_draws"][0] >= 1
    # replay the draws: the heading turned by the sum of n uniform angles in [-180, 180) degrees
    rng = np.random.default_rng(7)
    turned = sum(rng.uniform(-180.0, 180.0) for _ in range(traj.params["heading_draws"][0]))
    after = traj.poses[1]
    assert (_heading(after) - _heading(start) + turned + 180) % 360 - 180 == pytest.approx(0, abs=1e-9)
    # and moved 3 m along that new heading, in the same step
    np.testing.assert_allclose(after[:3, 3] - start[:3, 3], 3.0 * after[:3, 2], atol=1e-9)
    for k, action in enumerate(traj.actions):  # every step is one 3 m move (forward or after turning)
        assert np.linalg.norm(traj.poses[k + 1][:3, 3] - traj.poses[k][:3, 3]) == pytest.approx(3.0)
        if action == "forward":
            np.testing.assert_array_equal(traj.poses[k + 1][:3, :3], traj.poses[k][:3, :3])
            assert traj.params["heading_draws"][k] == 0


def test_modified_walk_boxed_in_stays_after_max_draws():
    start = look_at((0.0, 0.0, 1.5), (0.0, 10.0, 1.5))
    traj = modified_random_walk(Box((-1, -1, 0), (1, 1, 3)), start, 3, np.random.default_rng(0), max_draws=25)
    assert traj.actions == ["stuck"] * 3 and traj.params["heading_draws"] == [25] * 3
    np.testing.assert_allclose(traj.positions, np.broadcast_to(start[:3, 3], (4, 3)))


def test_random_walk_with_the_paper_codes_actions():
    from trajectories import PAPER_CODE_ACTIONS, random_walk

    start = look_at((0.0, 0.0, 1.5), (0.0, 10.0, 1.5))
    free = Box((-1e4, -1e4, 0), (1e4, 1e4, 3))
    ours = random_walk(free, start, 400, np.random.default_rng(1))
    paper = random_walk(free, start, 400, np.random.default_rng(1), actions=PAPER_CODE_ACTIONS)
    assert "right" in ours.actions and "right" not in paper.actions
    assert paper.actions.count("left") > 1.5 * paper.actions.count("forward")  # two of the five draws
    assert paper.params["actions"] == list(PAPER_CODE_ACTIONS) and "actions" not in ours.params
    with pytest.raises(ValueError, match="actions"):
        random_walk(free, start, 3, np.random.default_rng(1), actions=("jump",))


def test_entrance_start_pose_rule():
    from generator.baselines.start_pose import entrance_start_pose, find_gate, site_start
    from generator.scene import plan_site, site_params

    # a 20 m square fence with a 4 m gate in the middle of its east side
    f = 10.0
    runs = [((-f, -f), (f, -f)), ((f, -f), (f, -2.0)), ((f, 2.0), (f, f)), ((f, f), (-f, f)), ((-f, f), (-f, -f))]
    gate = find_gate(runs)
    np.testing.assert_allclose(gate.midpoint, [f, 0.0])
    np.testing.assert_allclose(gate.inward, [-1.0, 0.0], atol=1e-12)
    assert gate.width == pytest.approx(4.0)
    pose = entrance_start_pose(runs, ((-8, -8, 1.5), (8, 8, 20)))
    np.testing.assert_allclose(pose[:3, 3], [8, 0, 1.5])  # on the spawn volume's east face, lowest height
    np.testing.assert_allclose(pose[:3, 2], [-1, 0, 0], atol=1e-12)  # looking west, into the site, level
    assert abs(pose[2, 0]) < 1e-12  # no roll
    with pytest.raises(ValueError, match="no gap"):
        find_gate(runs[:1] + [((f, -f), (f, f))] + runs[3:])
    for seed in (0, 137, 281):  # our sites: the gate on the south side, at x in [-4, 4]
        plan = plan_site(seed, site_params("medium"))
        pose, (lo, hi) = site_start(plan)
        assert -4 <= pose[0, 3] <= 4 and pose[1, 3] == lo[1] and pose[2, 3] == lo[2]
        np.testing.assert_allclose(pose[:3, 2], [0, 1, 0], atol=1e-12)


def test_exploration_table_is_reproducible(tmp_path):
    from generator.baselines.start_pose import site_start
    from generator.scene import plan_site, site_params
    from trajectories import Trajectory

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
    # every run of the seed starts from the one entrance pose; the runs then differ
    start, _ = site_start(plan_site(3, site_params("small")))
    trajs = [Trajectory.load(tmp_path / "a" / "site_3" / f"{m}_run{r:02d}.npz")
             for m in ("random_walk", "modified_random_walk") for r in range(2)]
    for t in trajs:
        np.testing.assert_array_equal(t.poses[0], start)
        steps = np.linalg.norm(np.diff(t.positions, axis=0), axis=1)
        assert np.all(np.isclose(steps, 0) | np.isclose(steps, 3.0))  # 3 m moves (or refused)
    assert not np.array_equal(trajs[0].poses, trajs[1].poses)
    assert (tmp_path / "a" / "figure8_seed_3.png").is_file() and (tmp_path / "a" / "coverage_seed_3.png").is_file()
    assert "| 3 |" in a.stdout and "Read blend" not in a.stdout
    # a rerun into the same folder with fewer runs leaves none of the first run's walks, and no
    # Blender backup of the site it replaced
    c = baselines("exploration", "--seeds", "3", "--steps", "5", "--runs", "1", "--scene-preset", "small",
                  "--points-density", "1", "--out", tmp_path / "a")
    assert c.returncode == 0, c.stderr[-2000:]
    assert sorted(p.name for p in (tmp_path / "a" / "site_3").glob("*.npz")) == [
        "coverage_curves.npz", "modified_random_walk_run00.npz", "random_walk_run00.npz"]
    assert not list((tmp_path / "a" / "site_3").glob("*.blend1"))


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
    assert res2["paper_voxel_rule"]["result"]["metrics"] == res["paper_voxel_rule"]["result"]["metrics"]
    assert res["parameters"]["frames"] == 3 and res["paper_voxel_rule"]["predicted_points"] > 100
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
    (["exploration", "--seeds", "1", "1", "--out", "x"], "lists seed 1 twice"),
    (["exploration", "--seeds", str(2**63), "--out", "x"], "seed must be an integer from 0 to 9223372036854775807"),
    (["reconstruction", "--seed", str(2**64), "--out", "x"], "seed must be an integer from 0 to 9223372036854775807"),
    (["exploration", "--out", ""], "must name a folder, got an empty path"),
    (["reconstruction", "--out", __file__], "exists and is not a folder; name a folder"),
    (["reconstruction", "--resolution", "3x2", "--out", "x"], "resolution width must be an integer from 4"),
    (["exploration", "--scene-preset", "small", "--points-density", "1e5", "--out", "x"], "the limit is 25,000,000"),
    (["reconstruction", "--gt-density", "1e12", "--out", "x"], "the limit is 25,000,000"),
])
def test_bad_arguments(args, message):
    r = baselines(*args)
    assert r.returncode == 2 and message in r.stderr and len(r.stderr.strip().splitlines()) == 1
