"""Timelines (#19, docs/phases.md): one real tiny run of ``python -m generator --phases 3``,
checked against independent computations from the stages' own files."""

import json
import re
import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT, run_generator
from exact_geometry import exact_distance

from evaluation.change import gt_change_cloud, score_change_cloud, score_change_masks
from exporters.changes import STATUS, read_changes
from exporters.frames import FrameReader
from exporters.ground_truth import read_ground_truth
from exporters.ply import read_ply

STAGES = 3
SEED = 1
TOL = 0.01  # docs/phases.md: point and depth tolerances


@pytest.fixture(scope="module")
def timeline(timeline_seed_folder):
    """The session's timeline seed (conftest: seed SEED, STAGES stages, orbit only), its
    changes and each stage's ground truth."""
    seed = timeline_seed_folder
    assert seed.name == f"seed_{SEED:06d}"
    return seed, read_changes(seed), [read_ground_truth(seed / f"phase_{k}") for k in range(STAGES)]


def test_layout_and_manifest(timeline):
    seed, changes, _ = timeline
    manifest = json.loads((seed / "manifest.json").read_text())
    files = set(manifest["files"])
    assert {"changes.h5", "changes.png"} <= files
    for k in range(STAGES):
        assert {f"phase_{k}/labels.json", f"phase_{k}/scene/site.blend", f"phase_{k}/ground_truth/points.ply",
                f"phase_{k}/orbit/trajectory.npz", f"phase_{k}/orbit/frame_000000.exr"} <= files
    assert manifest["config"]["phases"] == STAGES and changes.stages == STAGES
    poses = [np.load(seed / f"phase_{k}" / "orbit" / "trajectory.npz")["poses"] for k in range(STAGES)]
    assert all(np.array_equal(poses[0], p) for p in poses[1:])  # the same trajectory in every stage


def test_unchanged_instances_are_identical_with_stable_ids(timeline):
    seed, changes, gts = timeline
    seen = set()
    for k in range(1, STAGES):
        pair, a, b = changes.pair(k - 1, k), gts[k - 1], gts[k]
        ta, tb = changes.stage_tables[k - 1], changes.stage_tables[k]
        # the union table maps each stage's instance ids by object name
        assert [changes.names[u] for u in ta] == [p.name for p in a.parts]
        assert [changes.names[u] for u in tb] == [p.name for p in b.parts]
        # the objects each stage has (the others are empty entries of the shared object table)
        pa = {p.name: (i, p) for i, p in enumerate(a.parts) if len(p.faces)}
        pb = {p.name: (i, p) for i, p in enumerate(b.parts) if len(p.faces)}
        ca, cb = read_ply(seed / f"phase_{k - 1}/ground_truth/points.ply"), read_ply(seed / f"phase_{k}/ground_truth/points.ply")
        for u, code in enumerate(pair.status):
            if code < 0:
                continue
            name, status = changes.names[u], STATUS[code]
            seen.add(status)
            assert (name in pa) == (status != "added") and (name in pb) == (status != "removed"), (name, status)
            if status in ("unchanged", "moved", "grown"):
                (ia, p), (ib, q) = pa[name], pb[name]
                va, vb = p.world_vertices(), q.world_vertices()
                if status == "unchanged":
                    assert np.array_equal(p.faces, q.faces) and np.array_equal(va, vb), name
                    if not p.dynamic:  # its scoring points too, bit for bit
                        xa = ca.points[ca.vertex["instance"] == ia]
                        xb = cb.points[cb.vertex["instance"] == ib]
                        assert np.array_equal(xa, xb), name
                elif status == "moved":
                    t = pair.transform[u]
                    assert np.array_equal(p.faces, q.faces)
                    assert np.abs(va @ t[:3, :3].T + t[:3, 3] - vb).max() < 1e-4
                    assert not np.allclose(va, vb)
                else:
                    assert va.shape != vb.shape or not np.array_equal(va, vb)
        # the fence and the ground never change
        for u, name in enumerate(changes.names):
            if name.startswith(("Fence.", "Ground.")):
                assert STATUS[pair.status[u]] == "unchanged", name
    assert {"unchanged", "added", "removed", "moved", "grown"} <= seen  # the timeline exercises every kind


def test_instance_ids_are_the_same_in_every_stage(timeline):
    """One object table for the whole timeline: an object's instance id is its index in it in
    every stage's instance maps, tracks.h5 point table and coco.json; objects a stage lacks
    are empty entries (no triangles, no points, never seen)."""
    from exporters.coco import CocoReader
    from exporters.tracks import TrackReader

    seed, changes, gts = timeline
    names = [p.name for p in gts[0].parts]
    assert names == sorted(names) and names == changes.names
    for k, gt in enumerate(gts):
        assert [p.name for p in gt.parts] == names
        assert np.array_equal(changes.stage_tables[k], np.arange(len(names)))
    present = [{i for i, p in enumerate(gt.parts) if len(p.faces)} for gt in gts]
    assert any(len(s) < len(names) for s in present)  # some stage lacks some object
    tracks = [TrackReader(seed / f"phase_{k}/orbit/tracks.h5").points for k in range(STAGES)]
    cocos = [CocoReader(seed / f"phase_{k}/orbit/coco.json") for k in range(STAGES)]
    frames = [FrameReader(seed / f"phase_{k}/orbit") for k in range(STAGES)]
    for k in range(STAGES):
        assert set(np.unique(tracks[k]["instance"]).tolist()) <= present[k]  # no point on an absent object
        for t in range(frames[k].frames):
            seen = np.unique(frames[k].read(t, ["instance"])["instance"])
            assert set(seen[seen >= 0].tolist()) <= present[k]  # an absent object is never seen
            for ann in cocos[k].annotations(t):  # coco.json names each id by the same table
                assert names[ann["instance_id"]] == ann["object"]
    maps = [[frames[k].read(t, ["instance"])["instance"] for t in range(frames[k].frames)] for k in range(STAGES)]
    checked = 0
    for k in range(1, STAGES):
        pair = changes.pair(k - 1, k)
        for i in np.flatnonzero(pair.status == STATUS.index("unchanged")):
            a, b = tracks[k - 1], tracks[k]
            ma, mb = a["instance"] == i, b["instance"] == i
            # the same tracked points under the same id (sampling is seeded by name)
            assert np.array_equal(a["local"][ma], b["local"][mb]), names[i]
            checked += int(ma.sum() > 0)
            for t, (ia, ib) in enumerate(zip(maps[k - 1], maps[k])):  # same pose: unchanged pixels keep the id
                assert np.all(ib[(ia == i) & ~pair.masks["orbit"][t]] == i), names[i]
    assert checked > 0


def _dense_surface(parts, density: float, rng) -> np.ndarray:
    """Area-weighted samples (plus vertices) on every part but the ground (independent of the code under test)."""
    out = []
    for p in parts:
        if p.label == "Ground" or len(p.faces) == 0:
            continue
        v = p.world_vertices()
        tri = v[p.faces]
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        n = rng.poisson(area * density)
        idx = np.repeat(np.arange(len(tri)), n)
        r1, r2 = rng.random(len(idx)), rng.random(len(idx))
        s = np.sqrt(r1)
        t = tri[idx]
        out += [v, t[:, 0] * (1 - s)[:, None] + t[:, 1] * (s * (1 - r2))[:, None] + t[:, 2] * (s * r2)[:, None]]
    return np.concatenate(out)


def _ground_distance(points, parts) -> np.ndarray:
    """Distance (m) of ``points`` to the parts labelled Ground (the ground with its relief, the
    spoil heaps), by open3d's point-to-triangle distance (float32)."""
    from generator.geometry.o3d import import_open3d

    o3d = import_open3d()

    scene = o3d.t.geometry.RaycastingScene()
    for p in parts:
        if p.label == "Ground" and len(p.faces):
            scene.add_triangles(o3d.core.Tensor(p.world_vertices().astype(np.float32)),
                                o3d.core.Tensor(np.asarray(p.faces, dtype=np.uint32)))
    return scene.compute_distance(o3d.core.Tensor(points.astype(np.float32))).numpy().astype(np.float64)


def _exact_distances(points, parts, reach):
    tri = np.concatenate([p.world_vertices()[p.faces] for p in parts if len(p.faces)])
    lo, hi = tri.min(axis=1) - reach, tri.max(axis=1) + reach
    out = np.full(len(points), np.inf)
    for i, x in enumerate(points):
        near = np.all((lo <= x) & (x <= hi), axis=1)
        if near.any():
            out[i] = exact_distance(x, tri[near])
    return out


def test_point_labels_agree_with_an_independent_distance_check(timeline):
    from scipy.spatial import cKDTree

    seed, changes, gts = timeline
    rng = np.random.default_rng(0)
    for k in range(1, STAGES):
        pair = changes.pair(k - 1, k)
        for flags, cloud_stage, other in ((pair.points_added, k, gts[k - 1]), (pair.points_removed, k - 1, gts[k])):
            xyz = read_ply(seed / f"phase_{cloud_stage}/ground_truth/points.ply").points
            assert len(flags) == len(xyz) and flags.any() and (~flags).any()
            dense = cKDTree(_dense_surface(other.parts, 400.0, rng))
            d = np.minimum(dense.query(xyz)[0], _ground_distance(xyz, other.parts))
            # a changed point is farther than the tolerance from every sample of the other surface
            assert (d[flags] > TOL - 1e-4).all()
            # most unchanged points have a sample of the other surface within the samples' spacing;
            # the others (thin wires, sparse samples) and the changed points near the other surface
            # are settled by exact point-to-triangle distances
            assert np.mean(d[~flags] < 0.05) > 0.97  # 0.979 since the ground beyond the site (easy) carries none
            check = np.flatnonzero((~flags & (d >= 0.05)) | (flags & (d < 0.1)))
            check = rng.choice(check, min(len(check), 300), replace=False)  # the test's time
            exact = _exact_distances(xyz[check], other.parts, 0.2)
            wrong = (exact > TOL) != flags[check]
            assert (np.abs(exact[wrong] - TOL) < 1e-4).all(), (exact[wrong], flags[check][wrong])
            # the stored distances are the float64 distances (to float32) wherever a tolerance up
            # to 0.11 m could use them (Embree's float32 was off by up to 1 mm on needle faces)
            stored = pair.distance_added if cloud_stage == k else pair.distance_removed
            band = np.flatnonzero((stored > 0) & (stored <= TOL + 0.1))  # 0: unchanged objects' points
            assert len(band) > 300
            band = rng.choice(band, 300, replace=False)
            exact = _exact_distances(xyz[band], other.parts, 0.2)
            bad = np.abs(stored[band] - exact) > 1e-8 + 1e-6 * exact
            assert not bad.any(), (stored[band][bad], exact[bad], xyz[band][bad])
            # no surface is built at the tolerance from the other stage's, where a flag is a coin
            # toss (formwork panels stood 1 cm off the columns poured into them: 27 and 26 points
            # within 1e-5 m of it here); a point may land there by chance, a surface may not
            assert np.sum(np.abs(stored - TOL) < 1e-5) <= 2
            # changed points lie on objects whose status is not "unchanged"
            inst = read_ply(seed / f"phase_{cloud_stage}/ground_truth/points.ply").vertex["instance"]
            union = changes.stage_tables[cloud_stage][inst[flags]]
            assert not np.any(pair.status[union] == STATUS.index("unchanged"))


def test_frame_masks_agree_with_depth_and_instance_maps(timeline):
    seed, changes, gts = timeline
    for k in range(1, STAGES):
        na, nb = [p.name for p in gts[k - 1].parts], [p.name for p in gts[k].parts]
        ra, rb = FrameReader(seed / f"phase_{k - 1}/orbit"), FrameReader(seed / f"phase_{k}/orbit")
        masks = changes.pair(k - 1, k).masks["orbit"]
        assert masks.shape == (ra.frames, ra.height, ra.width)
        for i in range(ra.frames):
            fa, fb = ra.read(i, ["depth", "instance"]), rb.read(i, ["depth", "instance"])
            obj_a = np.array([na[j] if j >= 0 else "" for j in fa["instance"].ravel()]).reshape(fa["instance"].shape)
            obj_b = np.array([nb[j] if j >= 0 else "" for j in fb["instance"].ravel()]).reshape(fb["instance"].shape)
            za, zb = fa["depth"].astype(np.float64), fb["depth"].astype(np.float64)
            with np.errstate(invalid="ignore"):  # inf - inf where neither sees a surface
                close = np.abs(za - zb) <= TOL
            same_depth = (np.isinf(za) & np.isinf(zb)) | (np.isfinite(za) & np.isfinite(zb) & close)
            expected = (obj_a != obj_b) | ~same_depth
            assert np.array_equal(masks[i], expected), (k, i)
    assert any(m.any() for p in changes.pairs.values() for m in p.masks.values())
    assert any((~m).any() for p in changes.pairs.values() for m in p.masks.values())


def test_ground_truth_as_prediction_scores_perfectly(timeline, tmp_path):
    seed, changes, _ = timeline
    xyz, code, _ = gt_change_cloud(seed, 0, 1)
    s = score_change_cloud(xyz, code, xyz, code, 0.1)
    assert s["added"]["iou"] == s["removed"]["iou"] == s["mean_iou"] == 1.0
    np.savez(tmp_path / "pred.npz", masks=changes.pair(0, 1).masks["orbit"])
    r = subprocess.run([sys.executable, "-m", "evaluation", "change", "--gt", str(seed), "--stages", "0", "1",
                        "--pred", str(tmp_path / "pred.npz"), "--json", str(tmp_path / "r.json")],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    res = json.loads((tmp_path / "r.json").read_text())
    assert res["scores"]["changed"]["iou"] == res["scores"]["unchanged"]["iou"] == 1.0
    assert res["parameters"]["kind"] == "orbit" and res["parameters"]["depth_tolerance_m"] == TOL
    for stages in (["0", "2"], ["2", "3"], ["-1", "0"]):
        r = subprocess.run([sys.executable, "-m", "evaluation", "change", "--gt", str(seed), "--stages", *stages,
                            "--pred", str(tmp_path / "pred.npz")], capture_output=True, text=True, cwd=ROOT)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "stages" in r.stderr, r.stderr


def test_a_stage_cloud_of_another_format_is_refused_in_one_line(timeline, tmp_path):
    """The change scoring and change_clouds read the stages' points.ply with
    exporters.ground_truth.read_points: another format version is one line naming the file
    and the version (the CLI exits 2), not a score against a cloud this reader may misread."""
    import shutil

    from datasets import DatasetError
    from datasets.change import change_clouds
    from exporters import FORMAT_VERSION

    seed = tmp_path / timeline[0].name
    shutil.copytree(timeline[0], seed)
    ply = seed / "phase_1" / "ground_truth" / "points.ply"
    stated = f"buildee ground truth format {FORMAT_VERSION}".encode()
    ply.write_bytes(ply.read_bytes().replace(stated, b"buildee ground truth format 0.3".ljust(len(stated))))
    np.savez(tmp_path / "pred.npz", xyz=np.zeros((3, 3)), change=np.array([1, 2, 1]))
    r = subprocess.run([sys.executable, "-m", "evaluation", "change", "--gt", str(seed), "--stages", "0", "1",
                        "--pred", str(tmp_path / "pred.npz")], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert f"{ply}: ground-truth format 0.3, this reader reads {FORMAT_VERSION}" in r.stderr, r.stderr
    with pytest.raises(DatasetError, match=f"^{re.escape(str(ply))}: ground-truth format 0.3"):
        change_clouds(seed, 0, 1)


def test_a_timeline_seed_is_read_stage_by_stage(timeline, tmp_path):
    """The whole seed and a phase_K folder get messages that say how to read them; a stage's
    folder is a valid --gt for the evaluation (its ground truth scores itself perfectly)."""
    from datasets import DatasetError, Scene
    from evaluation import score_reconstruction
    from evaluation.inputs import InputError

    seed, _, _ = timeline
    with pytest.raises(InputError, match=r"a timeline of 3 stages \(--phases\); score one stage"):
        score_reconstruction(seed / "phase_1" / "ground_truth" / "points.ply", seed)
    results, _ = score_reconstruction(seed / "phase_1" / "ground_truth" / "points.ply", seed / "phase_1")
    assert results["metrics"]["fscore"] == 1.0
    with pytest.raises(DatasetError, match="read it with datasets.change.Timeline"):
        Scene(seed)
    with pytest.raises(DatasetError, match=r"stage 1 of the timeline seed .*sequence\(1, kind\)"):
        Scene(seed / "phase_1")


def test_change_predictions_are_checked(tmp_path):
    from evaluation.change import read_change_prediction
    from evaluation.inputs import InputError

    np.savez(tmp_path / "probs.npz", masks=np.full((2, 4, 6), 0.3, np.float32))
    np.savez(tmp_path / "ints.npz", masks=np.eye(4, 6, dtype=np.int8)[None])
    np.save(tmp_path / "masks.npy", np.zeros((2, 4, 6), bool))
    for name, words in (("probs.npz", "masks must be booleans"), ("masks.npy", "holds one array")):
        with pytest.raises(InputError, match=words):
            read_change_prediction(tmp_path / name)
    assert read_change_prediction(tmp_path / "ints.npz")["masks"].sum() == 4  # 0/1 integers are booleans


def test_hand_built_scores():
    gt = np.array([[0.0, 0, 0], [1, 0, 0], [5, 0, 0]])
    gt_code = np.array([1, 1, 2])
    pred = np.array([[0.0, 0, 0.05], [3, 0, 0], [5, 0, 0.2]])
    pred_code = np.array([1, 1, 1])
    s = score_change_cloud(gt, gt_code, pred, pred_code, tau=0.1)
    # added: pred (0,0,.05) matches (0,0,0); (3,0,0) and (5,0,.2) match no added GT point -> P = 1/3;
    # GT (0,0,0) matched, (1,0,0) not -> R = 1/2; IoU = PR / (P + R - PR) = (1/6) / (2/3) = 1/4
    assert s["added"]["precision"] == pytest.approx(1 / 3) and s["added"]["recall"] == pytest.approx(0.5)
    assert s["added"]["iou"] == pytest.approx(0.25) and s["added"]["fscore"] == pytest.approx(0.4)
    # removed: nothing predicted -> precision undefined, recall 0, IoU 0
    assert s["removed"]["precision"] is None and s["removed"]["recall"] == 0 and s["removed"]["iou"] == 0
    assert s["mean_iou"] == pytest.approx(0.125)
    m = score_change_masks(np.array([[[1, 0], [1, 0]]], bool), np.array([[[1, 1], [0, 0]]], bool))
    assert (m["changed"]["tp"], m["changed"]["fp"], m["changed"]["fn"]) == (1, 1, 1)
    assert m["changed"]["iou"] == pytest.approx(1 / 3) and m["unchanged"]["precision"] == pytest.approx(0.5)


def test_bad_phases_get_one_line_and_exit_2(tmp_path):
    for args in (["--phases", "0"], ["--phases", "17"], ["--phases", "x"], ["--phases", "2", "--outputs", "rgb,depth"]):
        r = run_generator(tmp_path, "--seeds", "1", *args)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "phases" in r.stderr, r.stderr
        assert "Traceback" not in r.stderr
    from generator.scene import plan_site, site_params

    with pytest.raises(ValueError, match="^stage must be an integer from 0 to 2, got 3$"):
        plan_site(0, site_params("small"), 3, 3)


def test_loaders_pair_frames_with_their_masks(timeline):
    from datasets import Compose, Crop, Resize
    from datasets.change import ChangePairDataset, change_clouds

    seed, changes, _ = timeline
    pairs = ChangePairDataset(seed)
    frames = changes.pair(0, 1).masks["orbit"].shape[0]
    assert len(pairs) == (STAGES - 1) * frames
    item = pairs[frames + 1]  # pair (1, 2), frame 1
    assert list(item["stages"]) == [1, 2] and item["index"] == 1
    assert np.array_equal(item["before"]["pose"], item["after"]["pose"])
    assert np.array_equal(item["change"], changes.pair(1, 2).masks["orbit"][1])
    reader = FrameReader(seed / "phase_2" / "orbit")
    assert np.array_equal(item["after"]["depth"], reader.read(1, ["depth"])["depth"])
    small = ChangePairDataset(seed, pairs=[1], transform=Resize(24, 16))[0]
    assert small["change"].shape == small["before"]["depth"].shape == (16, 24)
    full = changes.pair(0, 1).masks["orbit"][0]
    cropped = ChangePairDataset(seed, pairs=[1], transform=Crop(12, 8, 24, 16))[0]
    assert np.array_equal(cropped["change"], full[8:24, 12:36])  # the mask is cropped with the frames
    both = ChangePairDataset(seed, pairs=[1], transform=Compose(Crop(12, 8, 24, 16), Resize(48, 32)))[0]
    assert np.array_equal(both["change"], np.repeat(np.repeat(full[8:24, 12:36], 2, axis=0), 2, axis=1))
    clouds = change_clouds(seed, 0, 1)
    assert np.array_equal(clouds["after"]["added"], changes.pair(0, 1).points_added)
    assert [changes.names[u] for u in clouds["before"]["union_instance"][:5]] == \
        [changes.names[changes.stage_tables[0][i]] for i in clouds["before"]["instance"][:5]]
    for bad in (3, 0, 1.0):
        with pytest.raises(ValueError, match=rf"^pair must be an integer from 1 to 2 for {re.escape(str(seed))} "
                                             rf"\(stage k-1 to stage k\), got {bad!r}$"):
            ChangePairDataset(seed, pairs=[bad])
