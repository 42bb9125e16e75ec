"""The observability mask (generator/geometry/observability.py): what it marks on scenes
built in code, that the stored masks of a real generation equal the Simulator's, and the
observable-only figures of the evaluation."""

import json

import numpy as np
import pytest

from generator import Simulator  # bpy before open3d
from evaluation import Cloud, score_reconstruction
from evaluation.report import coverage_table, reconstruction_table
from exporters.ground_truth import read_ground_truth, sample_scoring_points
from exporters.ply import read_ply, write_ply
from generator.geometry.observability import (cube_map_visible, default_viewpoints, observable_mask,
                                              visible_from)
from generator.geometry.raycast import SceneGeometry
from generator.geometry.sampling import sample_triangles
from generator.scene.meshes import MeshBuilder
from part_builder import mesh_part


@pytest.fixture(scope="module")
def sealed_scene():
    """An open ground plane; a closed box shell (a 6 m room, inner walls facing the room)
    with a crate inside; a wall standing in the open."""
    ground = mesh_part("Ground", MeshBuilder().add([(-30, -30, 0), (30, -30, 0), (30, 30, 0), (-30, 30, 0)], [(0, 1, 2, 3)]))
    shell = MeshBuilder().box((6.4, 6.4, 6.4), (0, 0, 3.2))
    inner = MeshBuilder().box((6.0, 6.0, 6.0), (0, 0, 3.2)).build()
    inner.quads = inner.quads[:, ::-1]  # facing into the room: the shell is a closed solid with a cavity
    shell.merge(inner)
    room = mesh_part("Room", shell)
    crate = mesh_part("Crate", MeshBuilder().box((1.0, 1.0, 1.0), (0.5, -0.5, 0.7)))
    wall = mesh_part("Wall", MeshBuilder().box((0.3, 8.0, 3.0), (15.0, 0.0, 1.5)))
    assert room.closed and crate.closed and wall.closed and not ground.closed
    parts = [ground, room, crate, wall]
    rng = np.random.default_rng(0)
    pts, normals, index = [], [], []
    for i, p in enumerate(parts):
        xyz, face = sample_triangles(p.vertices, p.faces, 4.0, rng)
        n = np.cross(*(p.vertices[p.faces[face, k]] - p.vertices[p.faces[face, 0]] for k in (1, 2)))
        n = n / np.linalg.norm(n, axis=1, keepdims=True) * p.outward if p.closed else np.zeros_like(xyz)
        pts.append(xyz), normals.append(n), index.append(np.full(len(xyz), i))
    # viewpoints above and around the room, never inside it
    views = np.array([[x, y, z] for x in (-20.0, 0.0, 20.0) for y in (-20.0, 20.0) for z in (2.0, 12.0)])
    return parts, np.concatenate(pts), np.concatenate(normals), np.concatenate(index), views


def test_open_ground_is_observable_and_a_sealed_room_is_not(sealed_scene):
    parts, pts, normals, part, views = sealed_scene
    geometry = SceneGeometry(parts)
    counts = []
    bottom = (part == 3) & (normals[:, 2] < -0.99)  # the wall's underside, on the ground
    mask = observable_mask(geometry, pts, normals, part, views, counts)
    ground_open = (part == 0) & (np.abs(pts[:, 0]) > 8) & (np.abs(pts[:, 0] - 15) > 3)  # away from room and wall
    assert ground_open.sum() > 1000 and mask[ground_open].all()
    assert not mask[part == 2].any()  # the crate in the sealed room
    inside = (part == 1) & (np.abs(pts[:, :2]).max(axis=1) < 3.05) & (pts[:, 2] > 0.15) & (pts[:, 2] < 6.25)
    assert inside.sum() > 100 and not mask[inside].any()  # the room's inner walls
    under = (part == 0) & (np.abs(pts[:, :2]).max(axis=1) < 3.1)  # the ground under the room
    assert under.sum() > 50 and not mask[under].any()
    roof = (part == 1) & (pts[:, 2] > 6.39)
    assert mask[roof].mean() > 0.99  # its roof is seen from the high viewpoints
    assert counts == sorted(counts) and counts[-1] == mask.sum()
    assert bottom.sum() > 3 and not mask[bottom].any()
    # one viewpoint on the wall's west side cannot see its east face; the mask is from below
    west = observable_mask(geometry, pts, normals, part, np.array([[5.0, 0.0, 1.5]]))
    east_face = (part == 3) & (normals[:, 0] > 0.99)
    assert east_face.sum() > 10 and not west[east_face].any() and mask[east_face].all()


def test_any_direction_equals_a_cube_map_through_the_visibility_rules(sealed_scene):
    parts, pts, normals, part, views = sealed_scene
    geometry = SceneGeometry(parts)
    for centre in np.vstack([views, [[14.0, 0.5, 1.0], [-2.0, 9.0, 0.4]]]):
        a = visible_from(geometry, pts, normals, part, centre)
        b = cube_map_visible(geometry, pts, normals, part, centre)
        assert a.any() and np.array_equal(a, b)
    # without normals (no rule 3): rays alone
    a, b = (f(geometry, pts, None, None, views[0]) for f in (visible_from, cube_map_visible))
    assert a.any() and not a.all() and np.array_equal(a, b)


def test_bad_inputs_are_refused_before_the_kernel(sealed_scene):
    parts, pts, normals, part, views = sealed_scene
    geometry = SceneGeometry(parts)
    with pytest.raises(ValueError, match="normals must have shape"):
        visible_from(geometry, pts, normals[:-1], part, views[0])
    with pytest.raises(ValueError, match="part_index goes up to 4"):
        visible_from(geometry, pts, normals, np.where(part == 3, 4, part), views[0])
    with pytest.raises(ValueError, match="part indices >= 0"):
        observable_mask(geometry, pts, normals, part - 1, views)
    with pytest.raises(ValueError, match="points must have shape"):
        visible_from(geometry, pts[:, :2], None, None, views[0])


def test_viewpoints_are_a_spread_deterministic_prefix():
    rng = np.random.default_rng(1)
    pool = rng.uniform(0, 10, (500, 3))
    a, b = default_viewpoints(pool, 20), default_viewpoints(pool.copy(), 50)
    assert np.array_equal(a, b[:20]) and np.array_equal(a[0], pool[0])
    gaps = [np.linalg.norm(pool[:, None] - v[None], axis=2).min(axis=1).max() for v in (pool[:20], a)]
    assert gaps[1] < gaps[0]  # farthest-point order covers the pool better than the first 20 drawn
    with pytest.raises(ValueError, match="at least one viewpoint"):
        default_viewpoints(pool, 0)


def test_stored_masks_equal_the_simulators(seed_folder):
    gt = seed_folder / "ground_truth"
    sim = Simulator(seed_folder / "scene" / "site.blend", points_density=0.3, seed=4)  # the tiny run's settings
    mask = sim.observable_points_mask
    assert 0.3 < mask.mean() < 1.0 and sim.frame == sim.frame_range[0]
    stored_gt = read_ground_truth(gt)  # the one reader of scene.h5
    stored, views = stored_gt.surface["observable"], stored_gt.viewpoints
    assert stored.dtype == bool and np.array_equal(stored, mask)
    assert np.array_equal(views, default_viewpoints(sim.spawn_points))
    # the scoring cloud: the same rule on its own samples
    ply = read_ply(gt / "points.ply")
    assert ply.vertex["observable"].dtype == np.uint8
    parts = sim.scene_parts()
    pts = sample_scoring_points(parts, sim.label_ids, 5.0, 4)  # --scoring-density 5
    expected = observable_mask(SceneGeometry(parts), pts["xyz"], pts["normals"], pts["instance"], views)
    assert np.array_equal(ply.vertex["observable"].astype(bool), expected)
    ground = ply.vertex["label"] == sim.label_ids["Ground"]
    half = json.loads((seed_folder / "scene" / "site.json").read_text())["params"]["size"] / 2
    inside = np.maximum(np.abs(ply.vertex["x"]), np.abs(ply.vertex["y"])) < half
    assert ply.vertex["observable"][ground & inside].mean() > 0.85  # the site's ground is seen from above (not under its assets)
    assert not (ground & ~inside).any()  # the ground beyond the site's edge is scenery: no points


def test_coverage_reports_the_observable_share(seed_folder):
    from evaluation import score_coverage

    r = score_coverage(seed_folder, seed_folder / "orbit" / "trajectory.npz")
    o = r["observable"]
    assert o["available"] and len(o["coverage"]) == len(r["coverage"])
    assert o["num_points"] == int(read_ground_truth(seed_folder).surface["observable"].sum())
    assert 0 < o["final_coverage"] <= 1 and o["auc"] > 0
    assert "observable points" in coverage_table(r)


def _half_observable_gt():
    """200 GT points on two lines 1 m apart, labels 0/1; the first line (labels 0) is observable."""
    x = np.linspace(0, 9.95, 100)
    a = np.column_stack([x, np.zeros(100), np.zeros(100)])
    b = a + [0.0, 1.0, 0.0]
    points = np.vstack([a, b])
    labels = np.repeat([0, 1], 100)
    return points, labels, np.repeat([True, False], 100)


def test_evaluation_over_observable_points(tmp_path):
    points, labels, observable = _half_observable_gt()
    gt = tmp_path / "points.ply"
    write_ply(gt, {"x": points[:, 0].astype(np.float32), "y": points[:, 1].astype(np.float32),
                   "z": points[:, 2].astype(np.float32), "label": labels.astype(np.int32),
                   "observable": observable.astype(np.uint8)}, comments=['labels ["A", "B"]'])
    # the prediction: the observable line, 2 cm off, labelled right
    pred = Cloud(points[:100] + [0.0, 0.02, 0.0], np.zeros(100, np.int64), "pred")
    r, _ = score_reconstruction(pred, gt, tau=0.1)
    m, o = r["metrics"], r["metrics"]["observable"]
    assert m["recall"] == pytest.approx(0.5) and o["recall"] == pytest.approx(1.0)
    assert o["gt_points"] == 100 and o["share_of_gt"] == pytest.approx(0.5)
    assert o["completeness"] == pytest.approx(0.02, abs=1e-6)
    assert m["completeness"] == pytest.approx((0.02 + np.sqrt(0.98 ** 2)) / 2, abs=1e-6)
    assert o["fscore"] == pytest.approx(1.0) and m["fscore"] == pytest.approx(2 / 3)
    assert o["semantic"]["semantic_chamfer_gt_to_pred"] == pytest.approx(1.0)
    assert o["semantic"]["miou"] == pytest.approx(1.0) and m["semantic"]["miou"] == pytest.approx(0.5)
    assert [e["recall"] for e in o["sweep"] if e["tau"] > 0.02] == pytest.approx([1.0] * 4)
    table = reconstruction_table(r)
    assert "observable" in table and "100 of the ground-truth points (50.0%)" in table
    json.dumps(r)  # the results stay JSON
    # without a mask: said so, in the JSON and the table
    r2, _ = score_reconstruction(pred, Cloud(points, labels, "old gt"), tau=0.1)
    assert r2["metrics"]["observable"]["available"] is False
    assert "not available" in reconstruction_table(r2)
    # voxel downsampling keeps the mask (a voxel is observable when most of its points are)
    r3, _ = score_reconstruction(pred, gt, tau=0.1, voxel=0.05)
    assert r3["metrics"]["observable"]["recall"] == pytest.approx(1.0)
