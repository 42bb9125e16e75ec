"""The annotation code without a flight of its own: the box geometry against brute force, COCO
RLE against pycocotools, the sinks without the instance modality, and the batch job's coco.json
and boxes3d.json through FrameDataset. The annotations of a real flight are in test_coco_boxes.py."""

import numpy as np
from pycocotools import mask as mask_utils

from generator.geometry.boxes import Box3D, amodal_box, mask_box, upright_box
from generator.geometry.camera import look_at, project


# ---- the geometry, without Blender -------------------------------------------------------------
def test_upright_box_is_the_minimum_footprint_box():
    rng = np.random.default_rng(5)
    for trial in range(20):
        yaw = rng.uniform(0, np.pi)
        size = rng.uniform(0.2, 5, 3)
        c, s = np.cos(yaw), np.sin(yaw)
        R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
        corners = Box3D(rng.uniform(-10, 10, 3), size, R).corners()
        inside = corners.mean(0) + (rng.uniform(-0.5, 0.5, (200, 3)) * size) @ R.T
        b = upright_box(np.concatenate([corners, inside]))
        np.testing.assert_allclose(b.size[2], size[2], atol=1e-9)
        np.testing.assert_allclose(np.sort(b.size[:2]), np.sort(size[:2]), atol=1e-9)
        assert b.contains(inside).all() and b.contains(corners, 1e-9).all()
        # no other yaw gives a smaller footprint (checked on a fine grid)
        pts = np.concatenate([corners, inside])[:, :2]
        for a in np.linspace(0, np.pi / 2, 91):
            u = pts @ [np.cos(a), np.sin(a)]
            v = pts @ [-np.sin(a), np.cos(a)]
            assert (np.ptp(u) * np.ptp(v)) >= b.size[0] * b.size[1] - 1e-9


def test_amodal_box_of_triangles_crossing_the_camera_plane():
    """A ground plane under the camera reaches the image's bottom edge, a triangle passing
    beside the camera stays exact: compared with dense sampling of the triangles."""
    K = np.array([[50.0, 0, 32], [0, 50.0, 24], [0, 0, 1]])
    pose = look_at((0, 0, 1.5), (0, 10, 1.0))
    verts = np.array([[-20, -20, 0], [20, -20, 0], [20, 40, 0], [-20, 40, 0.0]])
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    x0, y0, x1, y1 = amodal_box(verts, faces, pose, K, 64, 48)
    assert (x0, x1, y1) == (0, 64, 48) and 20 < y0 < 30  # below the horizon, to the bottom edge
    rng = np.random.default_rng(2)
    for trial in range(30):
        pose = look_at(rng.uniform(-2, 2, 3), rng.uniform(-1, 1, 3) + [0, 5, 0])
        verts = rng.uniform(-4, 4, (3, 3)) + [0, 3, 0]
        box = amodal_box(verts, np.array([[0, 1, 2]]), pose, K, 64, 48, near=0.05)
        r = rng.random((400000, 2))
        r = np.where(r.sum(1, keepdims=True) > 1, 1 - r, r)
        pts = verts[0] + r[:, :1] * (verts[1] - verts[0]) + r[:, 1:] * (verts[2] - verts[0])
        xy, z = project(pts, pose, K)
        keep = (z >= 0.05) & (xy[:, 0] >= 0) & (xy[:, 0] <= 64) & (xy[:, 1] >= 0) & (xy[:, 1] <= 48)
        if keep.sum() < 1000:
            continue
        lo, hi = xy[keep].min(0), xy[keep].max(0)
        assert box[0] <= lo[0] + 1e-9 and box[1] <= lo[1] + 1e-9 and box[2] >= hi[0] - 1e-9 and box[3] >= hi[1] - 1e-9
        assert max(lo[0] - box[0], lo[1] - box[1], box[2] - hi[0], box[3] - hi[1]) < 1.0



# ---- the batch job's annotations, the RLE encoder and the sinks -----------------------------------
def test_frame_dataset_returns_objects_through_a_transform(finished):
    """The batch job writes coco.json and boxes3d.json per trajectory; FrameDataset returns them
    (annotations=True) and Resize keeps the visible boxes the tight boxes of the instance ids."""
    from datasets import FrameDataset, Resize
    from exporters.manifest import read_manifest

    seed = finished[0] / "seed_000004"
    files = read_manifest(seed)["files"]
    assert {"orbit/coco.json", "orbit/boxes3d.json", "spline/coco.json", "spline/boxes3d.json"} <= set(files)
    plain = FrameDataset(seed)
    assert "boxes2d" not in plain[0]  # opt-in: their lengths vary by frame
    data = FrameDataset(seed, keys=("rgb", "instance"), annotations=True, transform=Resize(24, 16))
    seen = 0
    for item in (data[0], data[len(data) - 1]):
        assert item["instance"].shape == (16, 24)
        b = item["boxes2d"]
        for k, iid in enumerate(b["instance_id"]):
            assert tuple(b["bbox"][k]) == mask_box(item["instance"] == iid)
            seen += 1
        assert len(item["boxes3d"]["instance"]) >= len(b["instance_id"])
    assert seen > 0


def test_rle_from_runs_is_pycocotools_own_encoding():
    from exporters.coco import encode_masks

    rng = np.random.default_rng(4)
    for trial in range(40):
        h, w = rng.integers(1, 40, 2)
        inst = rng.integers(-1, 5, (h, w)) if trial % 2 else np.kron(rng.integers(-1, 4, (5, 5)), np.ones((9, 9), int))[:h, :w]
        ids = np.unique(inst)
        ids = ids[ids >= 0]
        ours = encode_masks(inst, ids)
        theirs = mask_utils.encode(np.asfortranarray((inst[:, :, None] == ids[None, None]).astype(np.uint8)))
        assert [r["counts"] for r in ours] == [r["counts"].decode() for r in theirs]
        assert all(r["size"] == [h, w] for r in ours)


def test_sinks_write_nothing_without_the_instance_modality(tmp_path):
    from exporters.boxes3d import Boxes3DWriter
    from exporters.coco import CocoWriter
    from exporters.sinks import FrameRecord, TrajectoryContext
    from generator.geometry.parts import MeshPart

    part = MeshPart("Crate", "Crate", np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]]), np.array([[0, 1, 2]]))
    ctx = TrajectoryContext(tmp_path, "orbit", 0, np.eye(3), 8, 6, np.eye(4)[None], np.zeros(1), ["Crate"],
                            [{"id": 0, "object": "Crate", "label": "Crate", "label_id": 0}], [part], [],
                            {"local": np.zeros((0, 3))}, ("rgb", "depth"))
    frame = FrameRecord(0, 0.0, np.eye(4), {"rgb": np.zeros((6, 8, 3))}, np.zeros((0, 3)), np.zeros(0, bool),
                        np.zeros((0, 4, 4)), 0.0)
    for sink in (CocoWriter(ctx), Boxes3DWriter(ctx)):
        sink.add_frame(frame)
        assert sink.close() is None
    assert not list(tmp_path.iterdir())


def test_a_moving_box_holds_its_part_under_any_axis_scale():
    """A slab turned 30 degrees in its object frame, moved by matrices of uniform and
    non-uniform axis scale: the box holds every world vertex and is no larger than the
    upright box of the moved vertices (the tightest box, when the matrix keeps Z up)."""
    from generator.geometry.boxes import moved_box

    slab = Box3D(np.array([0.5, -0.2, 0.3]), np.array([4.0, 1.0, 1.0]),
                 np.array([[np.cos(0.5236), -np.sin(0.5236), 0], [np.sin(0.5236), np.cos(0.5236), 0], [0, 0, 1]]))
    rng = np.random.default_rng(3)
    verts = np.concatenate([slab.corners(), slab.centre + (rng.uniform(-0.5, 0.5, (100, 3)) * slab.size) @ slab.rotation.T])
    local = upright_box(verts)
    yaw = 0.7
    turn = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    for scale in ([1.0, 1.0, 1.0], [1.5, 1.5, 1.5], [2.0, 1.0, 1.0], [0.5, 3.0, 1.2]):
        m = np.eye(4)
        m[:3, :3] = turn @ np.diag(scale)
        m[:3, 3] = (10.0, -4.0, 2.0)
        world = verts @ m[:3, :3].T + m[:3, 3]
        box = moved_box(local, verts, m)
        assert box.contains(world, 1e-9).all(), scale
        np.testing.assert_allclose(box.rotation.T @ box.rotation, np.eye(3), atol=1e-12)
        assert np.prod(box.size) <= np.prod(upright_box(world).size) * (1 + 1e-9), scale
        if len(set(scale)) == 1:  # uniform: the local box carried as it is
            carried = local.transformed(m)
            np.testing.assert_array_equal(box.size, carried.size)
            np.testing.assert_array_equal(box.centre, carried.centre)
