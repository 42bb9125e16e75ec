"""Exports of the real pipeline read back with other libraries: transforms.json, depth PNGs,
the ground-truth cloud and mesh (open3d), scene.h5, COLMAP text, previews; and the PLY codec."""

import json
import re

import numpy as np
import pycolmap
import pytest
from PIL import Image

from exact_geometry import closest_point_on_triangles
from exporters.exr import read_frame_exr
from exporters.ground_truth import POINT_PROPERTIES, GroundTruthError, read_ground_truth, read_mesh, read_points
from exporters.nerfstudio import read_depth_png
from exporters.palette import label_colors
from exporters import FORMAT_VERSION
from exporters.ply import PlyError, read_ply, read_ply_comments, write_ply
from exporters.tracks import read_tracks
from generator.geometry.o3d import import_open3d


@pytest.mark.parametrize("kind", ["orbit", "spline"])
def test_transforms_json_reproduces_the_poses(seed_folder, kind):
    folder = seed_folder / kind
    doc = json.loads((folder / "transforms.json").read_text())
    tracks = read_tracks(folder / "tracks.h5")
    K = tracks["K"]
    assert (doc["w"], doc["h"]) == (48, 32)
    np.testing.assert_allclose([doc["fl_x"], doc["fl_y"], doc["cx"], doc["cy"]], [K[0, 0], K[1, 1], K[0, 2], K[1, 2]])
    assert len(doc["frames"]) == len(tracks["world_from_camera"]) == 3
    for t, frame in enumerate(doc["frames"]):
        c2w_gl = np.array(frame["transform_matrix"])
        # OpenGL camera: x right, y up, z backward -> flip y and z back to OpenCV
        np.testing.assert_allclose(c2w_gl @ np.diag([1, -1, -1, 1]), tracks["world_from_camera"][t], atol=1e-12)
        # the OpenGL camera looks down its -z: the OpenCV optical axis
        np.testing.assert_allclose(-c2w_gl[:3, 2], tracks["world_from_camera"][t][:3, 2], atol=1e-12)
        assert (folder / frame["file_path"]).is_file()
        assert frame["depth_path"] == frame["depth_file_path"]  # instant-NGP's key and nerfstudio's
        depth_png = read_depth_png(folder / frame["depth_file_path"])
        depth_exr = read_frame_exr(folder / f"frame_{t:06d}.exr")["depth"]
        surface = np.isfinite(depth_exr)
        assert surface.any() and np.isfinite(depth_png[surface]).all()  # no surface is ever dropped
        unit = doc["integer_depth_scale"]
        assert unit == doc["depth_unit_scale_factor"] and 65535 * unit >= depth_exr[surface].max()
        assert np.abs(depth_png[surface] - depth_exr[surface]).max() <= unit / 2 + 1e-6  # rounding to the unit
        assert np.isinf(depth_png[~surface]).all()
    # instant-NGP: the cameras' box fills its unit cube; splatting trainers start from the coloured COLMAP points
    centres = np.stack([np.array(f["transform_matrix"])[:3, 3] for f in doc["frames"]]) * doc["scale"] + doc["offset"]
    assert (centres > 0).all() and (centres < 1).all() and doc["aabb_scale"] in (1, 2, 4, 8, 16, 32, 64, 128)
    cloud = import_open3d().io.read_point_cloud(str(folder / doc["ply_file_path"]))
    rec = pycolmap.Reconstruction(str(folder / "sparse" / "0"))
    assert len(cloud.points) == rec.num_points3D() > 0 and cloud.has_colors()
    assert f"buildee format {FORMAT_VERSION}" in read_ply_comments(folder / doc["ply_file_path"])  # format.md


def test_ground_truth_cloud_opens_in_open3d_with_labels(seed_folder):
    o3d = import_open3d()
    gt = seed_folder / "ground_truth"
    ours = read_points(gt)
    assert tuple(ours.vertex) == POINT_PROPERTIES  # docs/format.md's table, in its order
    cloud = o3d.t.io.read_point_cloud(str(gt / "points.ply"))
    np.testing.assert_array_equal(cloud.point.positions.numpy(), np.stack([ours.vertex[c] for c in "xyz"], 1))
    np.testing.assert_array_equal(cloud.point.label.numpy().ravel(), ours.vertex["label"])
    np.testing.assert_array_equal(cloud.point.instance.numpy().ravel(), ours.vertex["instance"])
    labels = json.loads((seed_folder / "labels.json").read_text())
    assert set(np.unique(ours.vertex["label"])) <= set(range(len(labels)))
    # density: scoring_density points per square metre of surface (TINY: 5)
    scene = read_ground_truth(seed_folder)
    from generator.geometry.sampling import contact_faces, ground_height, triangle_areas

    ground_z = ground_height(scene.parts)  # faces resting on the ground carry no points, nor does scenery
    assert any(p.scenery for p in scene.parts) and not any(p.scenery for p in scene.parts if p.label == "Building")
    area = sum(triangle_areas(p.vertices, p.faces[~contact_faces(p, ground_z)]).sum() for p in scene.parts if not p.scenery)
    assert abs(len(ours.points) / area - 5.0) < 0.1
    # every point lies on a triangle of its own object, which carries its label (exact float64
    # distances to every triangle, for a random subset; open3d's float32 queries are off by mm)
    mesh = read_mesh(gt)
    corners = mesh.points[mesh.faces].transpose(1, 0, 2)
    rng = np.random.default_rng(0)
    on_own, labels_ok = 0, 0
    subset = rng.choice(len(ours.points), 300, replace=False)
    for i in subset:
        p = np.broadcast_to(ours.points[i], corners[0].shape)
        d = np.linalg.norm(closest_point_on_triangles(p, *corners) - p, axis=1)
        hit = np.flatnonzero(d < 1e-5)  # float32 coordinates in the files
        assert len(hit), f"point {i} is {d.min():.2e} m from the mesh"
        on_own += bool((mesh.face["instance"][hit] == ours.vertex["instance"][i]).any())
        labels_ok += bool((mesh.face["label"][hit] == ours.vertex["label"][i]).any())
    assert on_own == labels_ok == len(subset)

def test_ground_truth_mesh_opens_in_open3d_with_labels(seed_folder):
    o3d = import_open3d()
    gt = seed_folder / "ground_truth"
    ours = read_mesh(gt)
    mesh = o3d.io.read_triangle_mesh(str(gt / "mesh.ply"))
    np.testing.assert_array_equal(np.asarray(mesh.vertices), ours.points)
    np.testing.assert_array_equal(np.asarray(mesh.triangles), ours.faces)
    labels = json.loads((seed_folder / "labels.json").read_text())
    # labels survive open3d through the vertex colours (one distinct colour per class) ...
    colors = np.round(np.asarray(mesh.vertex_colors) * 255).astype(np.uint8)
    palette = label_colors(labels)
    vertex_label = np.array([np.flatnonzero((palette == c).all(1))[0] for c in np.unique(colors, axis=0)])
    assert len(vertex_label) == len(np.unique(ours.face["label"]))
    face_colour = colors[ours.faces[:, 0]]
    np.testing.assert_array_equal(face_colour, palette[ours.face["label"]])
    # ... and as face properties: they equal the labels of the parts in scene.h5
    scene = read_ground_truth(seed_folder)
    part_label = np.repeat([labels.index(p.label) for p in scene.parts], [len(p.faces) for p in scene.parts])
    np.testing.assert_array_equal(ours.face["label"], part_label)
    # geometry at the first frame equals the parts placed with their matrices
    world = np.concatenate([p.world_vertices() for p in scene.parts])
    np.testing.assert_allclose(ours.points, world, atol=1e-4)


def test_scene_h5_matches_the_tracks(seed_folder):
    scene = read_ground_truth(seed_folder)
    tracks = read_tracks(seed_folder / "orbit" / "tracks.h5")
    np.testing.assert_array_equal(scene.surface["local"], tracks["local"])
    np.testing.assert_array_equal(scene.surface["label"], tracks["label"])
    np.testing.assert_array_equal(scene.surface["part"], tracks["instance"])
    assert scene.frames[0] == 1 and len(scene.frames) >= 250 and scene.fps == 10.0
    np.testing.assert_allclose(scene.K, tracks["K"])
    assert scene.far == 60.0
    # frame t of a trajectory is animation frame t + 1: object matrices agree
    for t in range(3):
        m = scene.matrices_at(1 + t)
        for k, i in enumerate(scene.dynamic_parts):
            np.testing.assert_allclose(m[int(i)], tracks["world_from_object"][t, k], atol=1e-12)
    assert len(scene.dynamic_parts) == tracks["world_from_object"].shape[1] > 0
    moved = scene.matrices[:, :, :3, 3].std(axis=0).max()
    assert moved > 0.1  # something moves during the animation


def test_incomplete_ground_truth_is_refused(seed_folder, tmp_path):
    import shutil

    copy = tmp_path / "gt"
    shutil.copytree(seed_folder / "ground_truth", copy)
    (copy / "scene.h5").unlink()
    with pytest.raises(GroundTruthError, match="missing scene.h5"):
        read_ground_truth(copy)
    cloud = read_points(copy)  # a scoring cloud of this version without a property of docs/format.md
    write_ply(copy / "points.ply", {k: v for k, v in cloud.vertex.items() if k != "observable"}, comments=cloud.comments)
    with pytest.raises(GroundTruthError, match=f"^{re.escape(str(copy / 'points.ply'))}: no observable property;"):
        read_points(copy)


def test_colmap_text_on_request_and_previews(seed_folder):
    sparse = seed_folder / "orbit" / "sparse" / "0"
    assert {"cameras.txt", "images.txt", "points3D.txt", "cameras.bin"} <= {p.name for p in sparse.iterdir()}
    binary = pycolmap.Reconstruction(str(sparse))
    text = pycolmap.Reconstruction()
    text.read_text(str(sparse))
    assert text.num_points3D() == binary.num_points3D() > 0
    for pid, p in binary.points3D.items():
        np.testing.assert_allclose(text.points3D[pid].xyz, p.xyz, atol=1e-9)
    sheet = np.asarray(Image.open(seed_folder / "orbit" / "contact_sheet.png"))
    assert sheet.shape[0] >= 3 * 32 and sheet.shape[1] >= 3 * 48  # 3 frames x (RGB, depth, labels)
    # the label tile of the first row shows the label map in class colours
    labels = json.loads((seed_folder / "labels.json").read_text())
    lab = read_frame_exr(seed_folder / "orbit" / "frame_000000.exr")["label"]
    tile = sheet[14:14 + 32, 4 + 2 * (48 + 4):4 + 2 * (48 + 4) + 48]  # columns: rgb, depth, label, ...
    np.testing.assert_array_equal(tile[lab >= 0], label_colors(labels)[lab[lab >= 0]])
    normal = read_frame_exr(seed_folder / "orbit" / "frame_000000.exr")["normal"]
    tile = sheet[14:14 + 32, 4 + 4 * (48 + 4):4 + 4 * (48 + 4) + 48]  # ... instance, normal
    hit = np.abs(normal).sum(-1) > 0
    np.testing.assert_allclose(tile[hit], (normal[hit] + 1) / 2 * 255, atol=0.51)
    assert Image.open(seed_folder / "orbit" / "map.png").size[0] > 100


def test_ply_round_trip_ascii_big_endian_and_polygons(tmp_path):
    rng = np.random.default_rng(1)
    xyz = rng.normal(size=(50, 3))
    lab = rng.integers(0, 9, 50).astype(np.int32)
    write_ply(tmp_path / "a.ply", {"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], "label": lab},
              faces=np.array([[0, 1, 2], [2, 3, 4]]), face={"label": np.array([7, 8], np.int32)})
    d = read_ply(tmp_path / "a.ply")
    np.testing.assert_array_equal(d.points, xyz)
    np.testing.assert_array_equal(d.vertex["label"], lab)
    np.testing.assert_array_equal(d.faces, [[0, 1, 2], [2, 3, 4]])
    np.testing.assert_array_equal(d.face["label"], [7, 8])
    # ASCII with a quad (split into two triangles) and a big-endian binary file
    rows = "\n".join(f"{a} {b} {c} {l}" for (a, b, c), l in zip(xyz[:5], lab[:5]))
    (tmp_path / "b.ply").write_text("ply\nformat ascii 1.0\nelement vertex 5\nproperty double x\nproperty double y\n"
                                    "property double z\nproperty int label\nelement face 1\n"
                                    "property list uchar int vertex_indices\nend_header\n" + rows + "\n4 0 1 2 3\n")
    d = read_ply(tmp_path / "b.ply")
    np.testing.assert_allclose(d.points, xyz[:5])
    np.testing.assert_array_equal(d.faces, [[0, 1, 2], [0, 2, 3]])
    header = b"ply\nformat binary_big_endian 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
    (tmp_path / "c.ply").write_bytes(header + xyz[:5].astype(">f4").tobytes())
    np.testing.assert_allclose(read_ply(tmp_path / "c.ply").points, xyz[:5].astype(np.float32))
    # a truncated file is refused with a one-line message
    (tmp_path / "d.ply").write_bytes(header + xyz[:4].astype(">f4").tobytes())
    with pytest.raises(PlyError, match="truncated"):
        read_ply(tmp_path / "d.ply")
    (tmp_path / "e.ply").write_bytes(b"solid cube\n")
    with pytest.raises(PlyError, match="not a PLY file"):
        read_ply(tmp_path / "e.ply")


def test_frame_exr_bytes_do_not_depend_on_openexr_threads(tmp_path):
    """exporters.exr turns on OpenEXR's thread pool (one thread per core); the files written
    must be byte-identical to single-threaded ones, and read back exactly, for every compression."""
    import OpenEXR

    from exporters.exr import COMPRESSIONS, use_all_cores, write_frame

    rng = np.random.default_rng(3)
    h, w = 97, 61  # several line blocks of every compression, odd sizes
    outs = {"rgb_linear": rng.random((h, w, 3)).astype(np.float32), "depth": rng.random((h, w)).astype(np.float32),
            "flow": rng.normal(size=(h, w, 2)).astype(np.float32), "label": rng.integers(-1, 9, (h, w)).astype(np.int32)}
    use_all_cores()  # what the first write or read does (importing exporters.exr starts no pool)
    before = OpenEXR.global_thread_count()
    assert before >= 1
    try:
        for compression in COMPRESSIONS:
            files = {}
            for threads in (0, 3):
                OpenEXR.set_global_thread_count(threads)
                files[threads] = write_frame(tmp_path / f"{compression}-{threads}.exr", outs, compression=compression)
            assert files[0].read_bytes() == files[3].read_bytes(), compression
            back = read_frame_exr(files[3])
            np.testing.assert_array_equal(back["depth"], outs["depth"])
            np.testing.assert_array_equal(back["flow"], outs["flow"])
            np.testing.assert_array_equal(back["label"], outs["label"])
            np.testing.assert_array_equal(back["rgb_linear"], outs["rgb_linear"].astype(np.float16))
        OpenEXR.set_global_thread_count(5)
        use_all_cores()  # a count the caller chose is kept
        assert OpenEXR.global_thread_count() == 5
    finally:
        OpenEXR.set_global_thread_count(before)


def test_tracks_show_every_depth_coverage_keeps_the_depth_limit(tmp_path):
    """tracks.h5 and TAP-Vid list what the image shows at any depth; coverage counts only the
    points within the Simulator's max_pcl_depth (the paper's depth-sensor range). Each frame's
    visible set equals a fresh Simulator's (no cache) at the same pose."""
    import math

    import scenes
    from generator import Simulator
    from generator.batch.fly import fly
    from generator.geometry.camera import look_at
    from trajectories import Trajectory

    scenes.new_scene(48, 36)
    scenes.add_plane("Ground", (200, 200), (0, 60, 0))
    scenes.add_box("Wall", (10, 0.3, 4), (0, 40, 2))
    scenes.add_sun()
    scenes.look_along_y((0, 0, 2))
    blend = scenes.save(tmp_path / "far.blend")
    poses = np.stack([look_at((x, 0.0, 2.0), (x, 30.0, 1.0)) for x in (0.0, 1.0, 2.0)])
    sim = Simulator(blend, points_density=2, max_pcl_depth=10.0, render_preset="preview")
    fly(sim, Trajectory(poses, np.arange(3) / 10.0, "test"), tmp_path / "test", seed=0, outputs=("depth",))
    tr = read_tracks(tmp_path / "test" / "tracks.h5")
    assert tr["depth"].max() > 30 and tr["depth"].min() < 10  # the wall at ~40 m is in the tracks
    observed = np.zeros(len(tr["local"]), bool)
    fresh = Simulator(blend, points_density=2, max_pcl_depth=10.0)
    for t in range(3):
        ids = tr["index"][tr["offsets"][t]:tr["offsets"][t + 1]]
        observed[ids[tr["depth"][tr["offsets"][t]:tr["offsets"][t + 1]] <= 10.0]] = True
        assert tr["coverage"][t] == observed.mean()
        fresh.set_world_from_camera(poses[t], check_collisions=False)
        np.testing.assert_array_equal(np.flatnonzero(fresh.compute_point_cloud(max_depth=math.inf)[2]), ids)
    tap = tr["tapvid"]
    far_visible = ~tap["occluded"] & (np.linalg.norm(tap["tracks_3d"] - poses[:, None, :3, 3].swapaxes(0, 1), axis=-1) > 15)
    assert far_visible.any()  # TAP-Vid marks far points visible too


def test_png_readers_refuse_pngs_of_another_kind(seed_folder, tmp_path):
    """A colour PNG where a depth or id PNG belongs (or the reverse) is refused with one line
    naming the file; a truncated one too (it used to be read as 'metres' or as ids)."""
    from datasets import DatasetError, Scene

    orbit = seed_folder / "orbit"
    with pytest.raises(ValueError, match="rgb_000000.png: a uint8 PNG of shape .* not a 16-bit grey depth image"):
        read_depth_png(orbit / "rgb_000000.png", 0.002)
    cut = tmp_path / "depth_000000.png"
    cut.write_bytes((orbit / "depth_000000.png").read_bytes()[:60])
    with pytest.raises(ValueError, match="depth_000000.png: (unreadable|damaged) PNG"):
        read_depth_png(cut, 0.002)
    with pytest.raises(ValueError, match="no depth unit"):
        read_depth_png(cut)
    import shutil

    copy = tmp_path / "seed"
    shutil.copytree(seed_folder, copy)
    shutil.copy(orbit / "rgb_000001.png", copy / "orbit" / "label_000001.png")
    with pytest.raises(DatasetError, match="label_000001.png: a RGB PNG, not the 16-bit grey id image"):
        Scene(copy)["orbit"].read(1, ["label"])


def test_manifest_hashes_on_every_core_keep_the_order_and_find_each_damage(tmp_path):
    """write_manifest and check_files hash files in parallel: each digest is hashlib's of its
    own file, and the problems come one per damaged file, in the manifest's order."""
    import hashlib

    from exporters.manifest import check_files, load_manifest, sha256_many, write_manifest

    folder = tmp_path / "seed_000001"
    (folder / "a").mkdir(parents=True)
    rng = np.random.default_rng(0)
    sizes = [0, 1, 4095, 1 << 20, 3 << 20, 17]
    for k, n in enumerate(sizes):
        (folder / "a" / f"f{k}.bin").write_bytes(rng.integers(0, 256, n, dtype=np.uint8).tobytes())
    paths = sorted((folder / "a").iterdir())
    assert sha256_many(paths) == [hashlib.sha256(p.read_bytes()).hexdigest() for p in paths]
    write_manifest(folder, {"format_version": "x", "seed": 1, "config": {}, "summary": {}})
    manifest = load_manifest(folder)
    assert check_files(folder, manifest) == []
    for k in (4, 1):  # damage two files, in reverse order of the manifest
        data = bytearray((folder / "a" / f"f{k}.bin").read_bytes())
        data[0] ^= 1
        (folder / "a" / f"f{k}.bin").write_bytes(bytes(data))
    (folder / "a" / "f5.bin").unlink()
    assert check_files(folder, manifest) == ["a/f1.bin: contents changed (sha256 differs from the manifest)",
                                             "a/f4.bin: contents changed (sha256 differs from the manifest)",
                                             "a/f5.bin: missing"]
