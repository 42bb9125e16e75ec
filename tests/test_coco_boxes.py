"""COCO instance masks, 3D boxes and tracks.h5 written by the real trajectory loop on a small real
scene (Blender renders, tiny resolution), read back with pycocotools and our readers and checked
against the stored instance maps, the tracked surface points and the scene's geometry; and the
datasets' annotations (Sequence, Resize / Crop) of that same flight. The box geometry and the
encoders on their own are in test_annotation_units.py."""

import math

import numpy as np
import pytest
from pycocotools import mask as mask_utils
from pycocotools.coco import COCO

import scenes
from exporters.boxes3d import Boxes3DReader
from exporters.coco import CocoReader, category_id
from exporters.frames import FrameReader
from exporters.tracks import read_tracks, world_positions
from generator import Simulator
from generator.batch.fly import fly
from generator.geometry.boxes import mask_box, part_world_matrices
from generator.geometry.camera import depth_to_world_points, look_at, project
from trajectories.base import Trajectory

W, H, T = 64, 48, 3
YAW = math.radians(30)


def site(path):
    """Ground, a yawed skip (2 x 1 x 0.8 m, 30 degrees), a crate, a truck driving 1 m per frame
    with a rolling wheel, and a long fence running out of the picture."""
    scenes.new_scene(W, H)
    scenes.add_plane("Ground", (80, 80), (0, 0, 0))
    scenes.add_box("Skip", (2, 1, 0.8), (-2, 3, 0.4), rotation=(0, 0, YAW))
    scenes.add_box("Crate", (1, 1, 1), (2.5, 4, 0.5))
    scenes.add_box("Fence", (40, 0.1, 1.2), (0, 9, 0.6))
    truck = scenes.add_box("Truck", (3, 2, 1.2), (-4, 6, 1.0))
    truck.keyframe_insert("location", frame=1)
    truck.location.x = 6.0
    truck.keyframe_insert("location", frame=11)
    scenes.make_linear(truck)
    wheel = scenes.add_cylinder("Wheel", 0.5, 0.2, (-4, 4.9, 0.5), rotation=(math.pi / 2, 0, 0), segments=12)
    wheel.parent = truck
    wheel.matrix_parent_inverse = truck.matrix_world.inverted()
    wheel.keyframe_insert("rotation_euler", frame=1)
    wheel.rotation_euler[1] = 20.0
    wheel.keyframe_insert("rotation_euler", frame=11)
    scenes.make_linear(wheel)
    scenes.look_along_y((0, -4, 2.0))
    scenes.add_sun()
    return scenes.save(path)


@pytest.fixture(scope="module")
def flown(tmp_path_factory):
    """(simulator, trajectory folder) after the real loop (generator/batch/fly.py) flew 3 frames."""
    tmp = tmp_path_factory.mktemp("coco")
    sim = Simulator(site(tmp / "site.blend"), points_density=40, seed=1)
    sim.configure_render("preview", samples=1, resolution=(W, H))
    poses = np.stack([look_at((x, -5.0, 2.5), (x * 0.5, 5.0, 0.5)) for x in (-1.0, 0.0, 1.5)])
    traj = Trajectory(poses, np.arange(T) / 10.0, "orbit")
    out = tmp / "orbit"
    fly(sim, traj, out, seed=1, outputs=["rgb", "depth", "label", "instance"])
    return sim, out


def test_coco_json_opens_with_pycocotools_and_masks_equal_the_instance_maps(flown):
    sim, out = flown
    coco = COCO(str(out / "coco.json"))
    frames = FrameReader(out)
    assert sorted(coco.getImgIds()) == [1, 2, 3]
    cats = {c["id"]: c for c in coco.loadCats(coco.getCatIds())}
    assert [cats[category_id(i)]["name"] for i in range(len(sim.labels))] == sim.labels
    total = 0
    for t in range(T):
        instance = frames.read(t, ["instance"])["instance"]
        image = coco.loadImgs(t + 1)[0]
        assert (image["width"], image["height"], image["file_name"]) == (W, H, f"rgb_{t:06d}.png")
        anns = coco.loadAnns(coco.getAnnIds(imgIds=t + 1))
        ids = sorted(a["instance_id"] for a in anns)
        assert ids == sorted(set(np.unique(instance).tolist()) - {-1}), "one annotation per instance in the frame"
        for a in anns:
            mask = instance == a["instance_id"]
            np.testing.assert_array_equal(coco.annToMask(a).astype(bool), mask)
            assert a["area"] == int(mask.sum()) and a["iscrowd"] == 0
            rows, cols = np.nonzero(mask)
            x0, y0, x1, y1 = cols.min(), rows.min(), cols.max() + 1, rows.max() + 1
            assert a["bbox"] == [x0, y0, x1 - x0, y1 - y0], "bbox is the mask's tight box (pixel edges)"
            np.testing.assert_array_equal(mask_utils.toBbox(a["segmentation"]), a["bbox"])
            row = sim.instance_table[a["instance_id"]]
            assert a["category_id"] == category_id(row["label_id"]) and a["object"] == row["object"]
            # the amodal box holds every visible pixel centre of the object
            ax, ay, aw, ah = a["amodal_bbox"]
            assert ax <= x0 + 0.5 and ay <= y0 + 0.5 and ax + aw >= x1 - 0.5 and ay + ah >= y1 - 0.5
            assert 0 <= ax and 0 <= ay and ax + aw <= W and ay + ah <= H
            total += 1
    assert total >= 12
    # the readers' arrays agree with pycocotools
    reader = CocoReader(out / "coco.json")
    d = reader.frame(1)
    masks = reader.masks(1)
    inst1 = frames.read(1, ["instance"])["instance"]
    for k, iid in enumerate(d["instance_id"]):
        np.testing.assert_array_equal(masks[k], inst1 == iid)
        assert tuple(d["bbox"][k]) == mask_box(inst1 == iid)


def test_amodal_boxes_are_the_projection_of_the_whole_object(flown):
    """Densely sampled surface of each annotated object, projected: the samples in view lie in
    its amodal box; and rays through the box's edges, half a pixel inside, meet the object
    (the box is tight). The fence runs out of the picture
    (its amodal box spans the image); the wheel is partly hidden (its amodal box is taller
    than its visible box)."""
    sim, out = flown
    coco = COCO(str(out / "coco.json"))
    parts = sim.scene_parts()
    tracks = read_tracks(out / "tracks.h5")
    names = sim.object_names
    fence, wheel = names.index("Fence"), names.index("Wheel")
    hidden = []
    rng = np.random.default_rng(0)
    for t in range(T):
        pose = tracks["world_from_camera"][t]
        matrices = part_world_matrices(parts, sim.dynamic_objects, tracks["world_from_object"][t])
        for a in coco.loadAnns(coco.getAnnIds(imgIds=t + 1)):
            part, m = parts[a["instance_id"]], matrices[a["instance_id"]]
            world = part.vertices @ m[:3, :3].T + m[:3, 3]
            tri = world[part.faces]
            r = rng.random((len(tri), 4000, 2))
            r = np.where(r.sum(-1, keepdims=True) > 1, 1 - r, r)
            pts = (tri[:, None, 0] + r[..., :1] * (tri[:, None, 1] - tri[:, None, 0])
                   + r[..., 1:] * (tri[:, None, 2] - tri[:, None, 0])).reshape(-1, 3)
            xy, z = project(np.concatenate([pts, world]), pose, tracks["K"])
            keep = (z >= sim.clip_start) & (xy[:, 0] >= 0) & (xy[:, 0] <= W) & (xy[:, 1] >= 0) & (xy[:, 1] <= H)
            ax, ay, aw, ah = a["amodal_bbox"]
            lo, hi = xy[keep].min(0), xy[keep].max(0)
            assert ax <= lo[0] + 1e-6 and ay <= lo[1] + 1e-6 and ax + aw >= hi[0] - 1e-6 and ay + ah >= hi[1] - 1e-6
            for edge in _edge_pixels(ax, ay, ax + aw, ay + ah):
                assert _rays_hit(edge, tri, pose, tracks["K"], sim.clip_start), (a["object"], t)
        by_id = {a["instance_id"]: a for a in coco.loadAnns(coco.getAnnIds(imgIds=t + 1))}
        assert by_id[fence]["amodal_bbox"][0] == 0 and by_id[fence]["amodal_bbox"][2] == W
        if wheel in by_id:
            hidden.append(by_id[wheel]["amodal_bbox"][3] - by_id[wheel]["bbox"][3])
    assert max(hidden) > 2.0


def _edge_pixels(x0, y0, x1, y1, n=2000, inset=0.5):
    """Pixel positions along each side of a box, ``inset`` pixels inside it."""
    xs, ys = np.linspace(x0 + inset, x1 - inset, n), np.linspace(y0 + inset, y1 - inset, n)
    return [np.column_stack([np.full(n, x0 + inset), ys]), np.column_stack([np.full(n, x1 - inset), ys]),
            np.column_stack([xs, np.full(n, y0 + inset)]), np.column_stack([xs, np.full(n, y1 - inset)])]


def _rays_hit(xy, tri, pose, K, near) -> bool:
    """Whether a ray through any of the pixel positions meets a triangle (world) at planar depth >= near."""
    d = np.column_stack([xy, np.ones(len(xy))]) @ np.linalg.inv(K).T      # camera frame, z = 1
    a, b, c = ((tri[:, k] - pose[:3, 3]) @ pose[:3, :3] for k in range(3))
    e1, e2 = b - a, c - a
    p = np.cross(d[:, None], e2[None])                                    # (rays, tris, 3)
    det = np.einsum("tj,rtj->rt", e1, p)
    inv = np.divide(1.0, det, out=np.zeros_like(det), where=np.abs(det) > 1e-15)
    u = np.einsum("tj,rtj->rt", -a, p) * inv
    q = np.cross(-a, e1)
    v = np.einsum("rj,tj->rt", d, q) * inv
    t = np.einsum("tj,tj->t", e2, q)[None] * inv
    return bool(np.any((u >= 0) & (v >= 0) & (u + v <= 1) & (t >= near)))


def test_3d_boxes_contain_every_visible_surface_point_of_their_instance(flown):
    sim, out = flown
    boxes = Boxes3DReader(out / "boxes3d.json")
    frames = FrameReader(out)
    tracks = read_tracks(out / "tracks.h5")
    assert len(boxes) == T and boxes.units["centre"].startswith("metres")
    checked = 0
    for t in range(T):
        d = boxes.frame(t)
        f = frames.read(t, ["depth", "instance"])
        instance, depth = f["instance"], f["depth"]
        ids, counts = np.unique(instance[instance >= 0], return_counts=True)
        np.testing.assert_array_equal(d["instance"], ids)  # one box per instance in view
        np.testing.assert_array_equal(d["pixels"], counts)
        np.testing.assert_allclose(d["pixel_share"], counts / (W * H))
        # surface points seen by the pixels (depth back-projected) and the tracked visible points
        surface = depth_to_world_points(depth, tracks["K"], tracks["world_from_camera"][t])
        vis = tracks["index"][tracks["offsets"][t]:tracks["offsets"][t + 1]]
        tracked = world_positions(tracks, t, vis)
        for k, box in enumerate(boxes.boxes(t)):
            iid = d["instance"][k]
            assert d["label"][k] == sim.instance_table[iid]["label_id"]
            np.testing.assert_allclose(box.rotation.T @ box.rotation, np.eye(3), atol=1e-9)
            pix, z = surface[instance == iid], depth[instance == iid]
            pix, z = pix[np.isfinite(z)], z[np.isfinite(z)]
            # Cycles' depth pass comes from float32 ray intersections: measured within 2e-5 of the depth
            tol = 5e-5 * float(z.max(initial=1.0))
            assert box.contains(pix, tolerance=tol).all(), (sim.object_names[iid], t)
            pts = tracked[tracks["instance"][vis] == iid]
            assert box.contains(pts, tolerance=1e-6).all()
            checked += len(pts) + len(pix)
    assert checked > 1000


def test_3d_boxes_are_tight_upright_and_follow_moving_objects(flown):
    sim, out = flown
    boxes = Boxes3DReader(out / "boxes3d.json")
    names = sim.object_names
    skip, truck, wheel = (names.index(n) for n in ("Skip", "Truck", "Wheel"))
    seen = {}
    for t in range(T):
        d = boxes.frame(t)
        for k, box in enumerate(boxes.boxes(t)):
            seen.setdefault(int(d["instance"][k]), []).append((t, box))
    (_, b), = seen[skip][:1]
    # the minimum footprint is the skip's own (Blender stores the yaw and vertices as float32)
    np.testing.assert_allclose(np.sort(b.size), [0.8, 1.0, 2.0], atol=1e-6)
    yaw = math.atan2(b.rotation[1, 0], b.rotation[0, 0])
    assert abs((yaw - YAW + math.pi / 4) % (math.pi / 2) - math.pi / 4) < 1e-6
    np.testing.assert_allclose(b.centre, [-2, 3, 0.4], atol=1e-6)
    np.testing.assert_allclose(b.rotation[:, 2], [0, 0, 1])
    # the truck's box translates 1 m along x per frame and keeps its size
    tb = seen[truck]
    assert len(tb) >= 2
    for (t0, b0), (t1, b1) in zip(tb, tb[1:]):
        np.testing.assert_allclose(b1.centre - b0.centre, [t1 - t0, 0, 0], atol=1e-6)
        np.testing.assert_allclose(np.sort(b1.size), [1.2, 2.0, 3.0], atol=1e-6)
    # the wheel's box turns with the wheel about the axle (world y)
    wb = seen[wheel]
    if len(wb) >= 2:
        (t0, b0), (t1, b1) = wb[0], wb[1]
        rel = b1.rotation @ b0.rotation.T
        angle = math.acos(np.clip((np.trace(rel) - 1) / 2, -1, 1))
        assert abs(angle - (2.0 * (t1 - t0)) % (2 * math.pi)) < 1e-6 or abs(2 * math.pi - angle - (2.0 * (t1 - t0)) % (2 * math.pi)) < 1e-6


# ---- tracks.h5: units and its one reader ---------------------------------------------------------
def test_tracks_reader_round_trip_with_units(flown, tmp_path):
    import pickle

    import h5py

    from exporters.tracks import UNITS, TrackReader, TrackWriter

    sim, out = flown
    reader = TrackReader(out / "tracks.h5")
    np.testing.assert_array_equal(reader.K, sim.K)
    assert (reader.width, reader.height, len(reader)) == (W, H, T) and reader.labels == sim.labels
    with h5py.File(out / "tracks.h5", "r") as f:
        datasets = []
        f.visititems(lambda name, obj: datasets.append(name) if isinstance(obj, h5py.Dataset) else None)
        assert set(f["cameras"].attrs) >= {"width", "height", "units"} and "width" not in f["cameras/K"].attrs
    assert sorted(datasets) == sorted(k for k in UNITS if k != "cameras"), "every dataset has its unit declared"
    assert {k: reader.units[k] for k in UNITS} == UNITS, "every dataset (and the cameras group) carries its unit"
    assert "metres" in reader.units["visibility/depth"] and "pixels" in reader.units["visibility/xy"]
    # a synthetic writer -> reader round trip, no Blender
    rng = np.random.default_rng(0)
    table = {"local": rng.uniform(-5, 5, (50, 3)), "labels": rng.integers(0, 3, 50), "instance": rng.integers(0, 4, 50),
             "dynamic_object": np.where(np.arange(50) < 10, 0, -1)}
    K = np.array([[40.0, 0, 16], [0, 40.0, 12], [0, 0, 1]])
    w = TrackWriter(tmp_path / "t.h5", table, ["Truck"], ["A", "B", "C"], K, 32, 24, queries=8, seed=3)
    poses, mats, vis = [], [], []
    for t in range(4):
        pose = look_at((0, -12 + t, 2), (0, 0, 0))
        m = np.eye(4)
        m[:3, 3] = [t, 0, 0]
        v = rng.random(50) < 0.5
        pts = table["local"].copy()
        pts[:10] += [t, 0, 0]
        w.add_frame(0.1 * t, pose, pts, v, m[None], 0.25 * t)
        poses.append(pose), mats.append(m), vis.append(v)
    w.close()
    with TrackReader(tmp_path / "t.h5") as original:
        r = pickle.loads(pickle.dumps(original))  # DataLoader workers get a copy, which opens the file itself
    np.testing.assert_array_equal(r.poses, np.stack(poses))
    np.testing.assert_array_equal(r.timestamps, 0.1 * np.arange(4))
    np.testing.assert_array_equal(r.coverage, 0.25 * np.arange(4))
    np.testing.assert_array_equal(r.object_matrices[:, 0], np.stack(mats))
    for t in range(4):
        v = r.visible(t)
        np.testing.assert_array_equal(v["ids"], np.flatnonzero(vis[t]))
        xy, z = project(r.positions(t, v["ids"]), poses[t], K)
        np.testing.assert_allclose(v["xy"], xy, atol=1e-4)
        np.testing.assert_allclose(v["depth"], z, rtol=1e-6)
    assert r.units == reader.units
    assert r.tapvid(verify_checksums=True)["tracks"].shape == (8, 4, 2)
    r.close()
    # another format version is refused with the command that regenerates the seed
    with h5py.File(tmp_path / "t.h5", "r+") as f:
        f.attrs["format_version"] = "0.1"
    from exporters.hdf5 import DamagedFileError

    with pytest.raises(DamagedFileError, match=r"format_version '0.1'.*python -m generator --seeds N --overwrite"):
        TrackReader(tmp_path / "t.h5")


# ---- datasets: annotations per frame, and Resize / Crop ------------------------------------------
def test_sequence_returns_the_annotations_of_each_frame(flown):
    from datasets.scene import Sequence

    sim, out = flown
    seq = Sequence(out, sim.labels)
    coco, boxes = CocoReader(out / "coco.json"), Boxes3DReader(out / "boxes3d.json")
    for t in range(T):
        a = seq.annotations(t)
        instance = seq.read(t, ["instance"]).instance
        for key, value in coco.frame(t).items():
            np.testing.assert_array_equal(a["boxes2d"][key], value)
        for key, value in boxes.frame(t).items():
            np.testing.assert_array_equal(a["boxes3d"][key], value)
        for k, iid in enumerate(a["boxes2d"]["instance_id"]):
            assert tuple(a["boxes2d"]["bbox"][k]) == mask_box(instance == iid)
    assert seq.annotations(-1)["boxes2d"]["instance_id"].tolist() == coco.frame(T - 1)["instance_id"].tolist()


def test_damaged_annotation_files_are_one_line_errors(flown, tmp_path):
    """Files that parse but lack a frame or a field: DamagedFileError naming the file (was a
    bare KeyError from deep inside the reader)."""
    import json

    from exporters.hdf5 import DamagedFileError

    _, out = flown
    cases = {"category": lambda d: d["annotations"][0].__setitem__("category_id", 999),
             "area": lambda d: [a.pop("area") for a in d["annotations"]],
             "image": lambda d: d.update(images=[im for im in d["images"] if im["frame"] != 1],
                                         annotations=[a for a in d["annotations"] if a["image_id"] != 2])}
    for name, damage in cases.items():
        doc = json.loads((out / "coco.json").read_text())
        damage(doc)
        (tmp_path / f"{name}.json").write_text(json.dumps(doc))
        with pytest.raises(DamagedFileError, match=f"{name}.json: (frame|has no image)"):
            [CocoReader(tmp_path / f"{name}.json").frame(t) for t in range(T)]
    doc = json.loads((out / "boxes3d.json").read_text())
    doc["frames"] = doc["frames"][:1]
    (tmp_path / "boxes.json").write_text(json.dumps(doc))
    with pytest.raises(DamagedFileError, match="boxes.json: has no frame 1"):
        Boxes3DReader(tmp_path / "boxes.json").frame(1)


@pytest.mark.parametrize("transform", ["crop", "shrink", "enlarge"])
def test_resize_and_crop_keep_boxes_the_tight_boxes_of_the_masks(flown, transform):
    from datasets.scene import Sequence
    from datasets.transforms import Crop, Resize

    sim, out = flown
    seq = Sequence(out, sim.labels)
    op = {"crop": Crop(20, 10, 30, 20), "shrink": Resize(32, 20), "enlarge": Resize(100, 77)}[transform]
    for t in range(T):
        f = seq.read(t, ["rgb", "depth", "instance"])
        a = seq.annotations(t)
        masks = CocoReader(out / "coco.json").masks(t)
        sample = {"rgb": f.rgb, "depth": f.depth, "instance": f.instance, "K": f.K} | a
        new = op(sample)
        new_masks = op(sample | {"masks": masks})
        instance = new["instance"]
        b = new["boxes2d"]
        ids = b["instance_id"]
        assert sorted(ids.tolist()) == sorted(set(np.unique(instance).tolist()) - {-1}), "objects without pixels dropped"
        for k, iid in enumerate(ids):
            assert tuple(b["bbox"][k]) == mask_box(instance == iid) and b["area"][k] == (instance == iid).sum()
        # masks follow the ids exactly, and give the same boxes
        np.testing.assert_array_equal(new_masks["masks"], instance[None] == ids[:, None, None])
        np.testing.assert_array_equal(new_masks["boxes2d"]["bbox"], b["bbox"])
        # amodal boxes: moved with the image (as K moves pixel positions) and clipped to it
        old = dict(zip(a["boxes2d"]["instance_id"].tolist(), a["boxes2d"]["amodal_bbox"]))
        Kn, Ko = new["K"], f.K
        h, w = instance.shape
        for k, iid in enumerate(ids.tolist()):
            x0, y0, x1, y1 = old[iid]
            corners = np.array([[x0, y0, 1], [x1, y1, 1]]) @ np.linalg.inv(Ko).T @ Kn.T
            expected = np.clip(corners[:, :2].ravel(), 0, [w, h, w, h])
            np.testing.assert_allclose(b["amodal_bbox"][k], expected, atol=1e-9)
        np.testing.assert_array_equal(new["boxes3d"]["centre"], a["boxes3d"]["centre"])  # world frame: unchanged
    with pytest.raises(ValueError, match="instance map"):
        op({"depth": f.depth} | a)
