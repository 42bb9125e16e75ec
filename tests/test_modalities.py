"""The per-frame modalities on a small animated scene flown in-process through the real loop
(generator/batch/fly.py): optical flow carries tracked points (static and on a moving truck)
to where tracks.h5 puts them, backward flow inverts it, normals are the surfaces' normals,
transforms keep flow consistent, the frame EXR opens in imageio (FreeImage) and OpenCV, its
linear RGB is the display PNG after Blender's view transform, and a modality registered in
this file alone reaches the EXR, the datasets and the contact sheet."""

import json
import math
import os

import numpy as np
import pytest
from PIL import Image

import scenes
from datasets import Compose, Crop, Resize
from datasets.scene import Sequence
from exporters.modalities import MODALITIES, Modality, register_modality, unregister_modality
from generator import Simulator
from generator.batch.fly import fly
from generator.geometry.camera import look_at
from trajectories import Trajectory

W, H, T = 128, 96, 4
TOY = "height"


def animated_scene(path):
    scenes.new_scene(W, H)
    scenes.add_plane("Ground", (40, 40), (0, 0, 0))
    scenes.add_box("Wall", (8, 0.3, 3), (0, 6, 1.5))
    scenes.add_box("Crate", (1, 1, 1), (3, -2, 0.5))
    truck = scenes.add_box("Truck", (4, 2, 2), (-3, 0, 1.0))
    truck.keyframe_insert("location", frame=1)
    truck.keyframe_insert("rotation_euler", frame=1)
    truck.location.x = 2.0  # 0.5 m per frame
    truck.rotation_euler[2] = 0.5  # 0.05 rad per frame
    truck.keyframe_insert("location", frame=11)
    truck.keyframe_insert("rotation_euler", frame=11)
    scenes.make_linear(truck)
    scenes.add_sun()
    scenes.look_along_y((0, -12, 3))
    return scenes.save(path)


def toy_modality() -> Modality:
    """World height of the surface at the pixel centre: a modality this test alone declares."""
    return Modality(TOY, "world z of the surface at the pixel centre, metres; NaN = none", "geometry", ("height",),
                    "FLOAT", "data", "bilinear", preview=lambda a, labels: np.repeat(
                        (np.nan_to_num(np.clip(a / 4, 0, 1)) * 255).astype(np.uint8)[..., None], 3, axis=-1),
                    compute=lambda g: g.world_points[..., 2].astype(np.float32))


@pytest.fixture(scope="module")
def flown(tmp_path_factory):
    register_modality(toy_modality())
    try:
        tmp = tmp_path_factory.mktemp("modalities")
        sim = Simulator(animated_scene(tmp / "scene.blend"), points_density=20, render_preset="preview")
        sim.configure_render(samples=2)
        eyes = [(-2.0 + 1.0 * t, -12.0 + 0.3 * t, 3.0 + 0.2 * t) for t in range(T)]
        poses = np.stack([look_at(e, (0.0, 0.0, 1.0)) for e in eyes])
        traj = Trajectory(poses, np.arange(T) / 10.0, "test")
        folder = tmp / "test"
        fly(sim, traj, folder, seed=0)
        seq = Sequence(folder, sim.labels)
        yield sim, seq, folder
    finally:
        unregister_modality(TOY)


def bilinear(img, xy):
    """Values of ``img`` at positions ``xy`` (n, 2) by bilinear interpolation between pixel
    centres, and the (n, 4) flat indices of the four pixels used."""
    h, w = img.shape[:2]
    u, v = xy[:, 0] - 0.5, xy[:, 1] - 0.5
    j0 = np.clip(np.floor(u).astype(int), 0, w - 2)
    i0 = np.clip(np.floor(v).astype(int), 0, h - 2)
    tx, ty = (u - j0)[:, None], (v - i0)[:, None]
    flat = img.reshape(h * w, -1)
    idx = np.stack([i0 * w + j0, i0 * w + j0 + 1, (i0 + 1) * w + j0, (i0 + 1) * w + j0 + 1], 1)
    a, b, c, d = (flat[idx[:, k]] for k in range(4))
    with np.errstate(invalid="ignore"):  # inf depths next to surfaces
        return ((a * (1 - tx) + b * tx) * (1 - ty) + (c * (1 - tx) + d * tx) * ty), idx


def off_edges(frame, xy, instance):
    """(n,) bool: the four pixels around each position see the point's own object, at depths
    within 1% of each other (no depth edge, no occluder)."""
    _, idx = bilinear(frame.depth[..., None], xy)
    inst = frame.instance.reshape(-1)[idx]
    depth = frame.depth.reshape(-1)[idx]
    inside = (xy[:, 0] > 0.5) & (xy[:, 1] > 0.5) & (xy[:, 0] < W - 0.5) & (xy[:, 1] < H - 0.5)
    return inside & (inst == instance[:, None]).all(1) & np.isfinite(depth).all(1) & (
        depth.max(1) <= 1.01 * depth.min(1))


def common_tracks(seq, t, slot):
    """Points visible at t and t + 1 on static surfaces (``slot`` -1) or on the dynamic object
    ``slot``, with their positions in both frames."""
    a, b = seq.visible_tracks(t), seq.visible_tracks(t + 1)
    ids, ia, ib = np.intersect1d(a["ids"], b["ids"], return_indices=True)
    keep = seq.points["dynamic_object"][ids] == slot
    return ids[keep], a["xy"][ia][keep].astype(np.float64), b["xy"][ib][keep].astype(np.float64)


@pytest.mark.parametrize("which", ["static", "truck"])
def test_flow_carries_tracked_points(flown, which):
    sim, seq, _ = flown
    slot = -1 if which == "static" else sim.dynamic_objects.index("Truck")
    checked = 0
    for t in range(T - 1):
        ids, xy0, xy1 = common_tracks(seq, t, slot)
        f0 = seq[t]
        ok = off_edges(f0, xy0, seq.points["instance"][ids])
        flow, _ = bilinear(f0.flow, xy0[ok])
        err = np.linalg.norm(xy0[ok] + flow - xy1[ok], axis=1)
        assert err.max() < 0.1, f"frame {t}: flow misses by {err.max():.3f} px"
        moved = np.linalg.norm(xy1[ok] - xy0[ok], axis=1)
        assert np.median(moved) > 1.0  # the check is not vacuous: points move by pixels
        checked += int(ok.sum())
    assert checked >= (200 if slot < 0 else 40)
    last = seq[T - 1]
    assert np.isnan(last.flow).all() and np.isnan(seq[0].backward_flow).all()  # no such frame


def test_backward_flow_inverts_forward_flow(flown):
    _, seq, _ = flown
    checked = 0
    for t in range(T - 1):
        a, b = seq[t], seq[t + 1]
        for slot in (-1, 0):  # static surfaces, the truck
            ids, xy0, xy1 = common_tracks(seq, t, slot)
            inst = seq.points["instance"][ids]
            ok = off_edges(a, xy0, inst) & off_edges(b, xy1, inst)
            fwd, _ = bilinear(a.flow, xy0[ok])
            bwd, _ = bilinear(b.backward_flow, xy1[ok])
            assert np.abs(fwd + bwd).max() < 0.1
            checked += int(ok.sum())
    assert checked > 100


def test_normals_are_the_surfaces_normals(flown):
    sim, seq, _ = flown
    surface = sim.surface_sample()  # outward unit normals on closed parts, in the part's frame
    dyn = seq.points["dynamic_object"]
    checked = 0
    for t in range(T):
        f = seq[t]
        n = f.normal
        hit = np.isfinite(f.depth)
        np.testing.assert_allclose(np.linalg.norm(n[hit], axis=-1), 1.0, atol=1e-5)
        assert (n[~hit] == 0).all()
        # facing the camera: the normal points back against the viewing ray
        from generator.geometry.camera import depth_to_world_points

        pts = depth_to_world_points(f.depth, f.K, f.pose)
        to_cam = f.pose[:3, 3] - pts[hit]
        assert (np.einsum("ij,ij->i", n[hit], to_cam) > 0).all()
        vis = seq.visible_tracks(t)
        ids = vis["ids"]
        local = surface["local_normals"][ids]
        closed = np.linalg.norm(local, axis=1) > 0
        rot = np.tile(np.eye(3), (len(ids), 1, 1))
        moving = dyn[ids] >= 0
        rot[moving] = seq.object_matrices[t, dyn[ids][moving], :3, :3]
        expected = np.einsum("nij,nj->ni", rot, local)
        xy = vis["xy"].astype(np.float64)
        _, idx = bilinear(f.depth[..., None], xy)
        taps = n.reshape(-1, 3)[idx]  # (m, 4, 3): one face around the point, not a box's edge
        one_face = (np.abs(taps - taps[:, :1]).max(axis=(1, 2)) < 1e-6)
        ok = closed & one_face & off_edges(f, xy, seq.points["instance"][ids])
        got = taps[ok, 0]
        dots = np.einsum("ij,ij->i", got, expected[ok])
        assert dots.min() > 1 - 1e-5
        checked += int(ok.sum())
    assert checked > 100


def test_resize_and_crop_keep_flow_carrying_points(flown):
    _, seq, _ = flown
    transform = Compose(Crop(8, 4, 112, 84), Resize(70, 63))  # x 0.625, y 0.75
    checked = 0
    for t in range(T - 1):
        ids, xy0, xy1 = common_tracks(seq, t, -1)
        a = seq[t]
        s0 = transform(a.as_dict() | {"tracks": {"xy": xy0}})
        s1 = transform({"depth": seq[t + 1].depth, "tracks": {"xy": xy1}})
        p0, p1 = s0["tracks"]["xy"], s1["tracks"]["xy"]
        inside = (p0 > 1).all(1) & (p0[:, 0] < 69) & (p0[:, 1] < 62)
        ok = inside & off_edges(_Resized(s0), p0, seq.points["instance"][ids])
        flow, _ = bilinear(s0["flow"], p0[ok])
        err = np.linalg.norm(p0[ok] + flow - p1[ok], axis=1)
        assert err.max() < 0.1, f"frame {t}: resized flow misses by {err.max():.3f} px"
        np.testing.assert_allclose(np.linalg.norm(s0["normal"][np.isfinite(s0["depth"])], axis=-1), 1.0, atol=1e-5)
        checked += int(ok.sum())
    assert checked > 100


class _Resized:
    """A transformed sample seen as a frame (depth, instance) by ``off_edges``."""

    def __init__(self, sample):
        self.depth, self.instance = sample["depth"], sample["instance"]


def test_frame_exr_opens_in_imageio_opencv_and_openimageio(flown):
    import OpenEXR

    _, seq, folder = flown
    path = folder / "frame_000001.exr"
    frame = seq[1]
    with OpenEXR.File(str(path), separate_channels=True) as f:
        parts = {p.name(): sorted(p.channels) for p in f.parts}
        chroma = f.parts[0].header["chromaticities"]
    assert parts == {"colour": ["B", "G", "R"],
                     "data": sorted(["Z", "normal.X", "normal.Y", "normal.Z", "flow.X", "flow.Y", "backward_flow.X",
                                     "backward_flow.Y", TOY]),
                     "ids": ["instance", "label"]}
    assert [p.name() for p in OpenEXR.File(str(path)).parts][0] == "colour"
    np.testing.assert_allclose(chroma, (0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290), atol=1e-6)
    linear = frame.rgb_linear.astype(np.float32)
    import imageio.v2 as imageio

    np.testing.assert_array_equal(np.asarray(imageio.imread(path, format="EXR-FI")), linear)
    os.environ["OPENCV_IO_ENABLE_OPENEXR"] = "1"
    import cv2

    np.testing.assert_array_equal(cv2.imread(str(path), cv2.IMREAD_UNCHANGED)[..., ::-1], linear)
    import OpenImageIO as oiio  # every part, as a subimage

    inp = oiio.ImageInput.open(str(path))
    try:
        seen = {}
        while inp.seek_subimage(len(seen), 0):
            spec = inp.spec()
            seen[spec.getattribute("name")] = list(spec.channelnames)
        assert {k: sorted(v) for k, v in seen.items()} == parts
        inp.seek_subimage(list(seen).index("ids"), 0)
        ids = inp.read_image(oiio.UINT32)
        np.testing.assert_array_equal(ids[..., seen["ids"].index("label")].view(np.int32), frame.label)
    finally:
        inp.close()
    # 16-bit id PNGs: id + 1, 0 = none
    for name in ("label", "instance"):
        png = np.asarray(Image.open(folder / f"{name}_000001.png"))
        assert png.dtype == np.uint16
        np.testing.assert_array_equal(png.astype(np.int32) - 1, frame[name])


def test_linear_exr_rgb_is_the_display_png_after_the_view_transform(flown, tmp_path):
    import bpy
    import OpenEXR

    from generator.blender import session

    _, seq, folder = flown
    linear = seq[1].rgb_linear
    single = tmp_path / "linear.exr"  # the EXR's colour alone, as any EXR tool would export it
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                      {c: np.ascontiguousarray(linear[..., k]) for k, c in enumerate("RGB")}) as f:
        f.write(str(single))
    img = bpy.data.images.load(str(single))
    scene = bpy.context.scene
    fmt = scene.render.image_settings
    saved = fmt.media_type, fmt.file_format, fmt.color_depth, fmt.color_mode
    fmt.media_type, fmt.file_format, fmt.color_depth, fmt.color_mode = "IMAGE", "PNG", "16", "RGB"
    try:
        with session.quiet():
            img.save_render(str(tmp_path / "display.png"), scene=scene)  # the scene's view transform
    finally:
        fmt.media_type, fmt.file_format, fmt.color_depth, fmt.color_mode = saved
    ours = np.asarray(Image.open(folder / "rgb_000001.png").convert("RGB"), np.float64) / 255
    blender = np.asarray(Image.open(tmp_path / "display.png"), np.float64)
    blender = blender[..., :3] / (65535 if blender.max() > 255 else 255)
    diff = np.abs(ours - blender)
    assert diff.mean() < 0.5 / 255 and diff.max() <= 2.5 / 255  # half-float colour, 8-bit rounding


def test_toy_modality_reaches_exr_datasets_and_contact_sheet(flown):
    _, seq, folder = flown
    doc = json.loads((folder / "frames.json").read_text())
    assert list(doc["modalities"]) == list(MODALITIES) and TOY in doc["modalities"]
    f = seq[2]
    pts = np.where(np.isfinite(f.depth)[..., None], 0, np.nan)
    from generator.geometry.camera import depth_to_world_points

    z = depth_to_world_points(f.depth, f.K, f.pose)[..., 2] + pts[..., 0]
    hit = np.isfinite(f.depth)
    assert f[TOY].dtype == np.float32 and np.isnan(f[TOY][~hit]).all()
    # the ray caster's surface vs Cycles' depth: equal off silhouettes, where either may see the other side
    assert np.mean(np.abs(f[TOY][hit] - z[hit]) < 2e-3) > 0.98
    resized = Resize(64, 48)(f.as_dict())
    assert resized[TOY].shape == (48, 64)
    sheet = Image.open(folder / "contact_sheet.png")
    columns = [n for n in MODALITIES if MODALITIES[n].preview is not None]
    assert TOY in columns and sheet.size[0] >= len(columns) * (W + 4)


def test_frames_json_names_how_each_modality_was_made(flown):
    """frames.json says depth, labels and ids came from the ray cast (the Simulator's default
    ground truth), and they do: a frame's depth and ids equal render_geometry's at its pose,
    bit for bit; the clip it records bounds the depth."""
    sim, seq, folder = flown
    doc = json.loads((folder / "frames.json").read_text())
    entries = doc["modalities"]
    assert doc["ground_truth"] == sim.ground_truth == "geometry"
    assert doc["segmentation_sensitivity"] == sim.segmentation_sensitivity
    for name in ("depth", "label", "instance", "normal", "flow"):
        assert entries[name]["source"].startswith("geometry:"), (name, entries[name]["source"])
    assert entries["rgb"]["source"].startswith("renderer:")
    assert ("segmentation_sensitivity" in entries["label"]["source"]) == (sim.segmentation_sensitivity > 0)
    assert (doc["clip"]["near"], doc["clip"]["far"]) == (sim.clip_start, sim.clip_end)
    f = seq[2]
    sim.set_frame(1 + 2)
    sim.set_world_from_camera(f.pose, check_collisions=False)
    cast = sim.render_geometry(normals=False)
    assert np.array_equal(cast.depth, f.depth) and np.array_equal(cast.instance, f["instance"])
    finite = f.depth[np.isfinite(f.depth)]
    assert finite.size and finite.min() >= doc["clip"]["near"] and finite.max() <= doc["clip"]["far"]


def test_outputs_choose_what_is_written(flown, tmp_path):
    sim, seq, _ = flown
    traj = Trajectory(seq.poses[:2].copy(), seq.timestamps[:2].copy(), "test")
    sim.last_render_timings = {}
    fly(sim, traj, tmp_path / "few", seed=0, outputs=("normal", "depth"))
    assert sim.last_render_timings  # depth needs the Blender render ...
    few = Sequence(tmp_path / "few", sim.labels)
    assert few.modalities == ("depth", "normal")  # ... and the table's order is kept
    assert not list((tmp_path / "few").glob("rgb_*.png")) and not list((tmp_path / "few").glob("label_*.png"))
    np.testing.assert_array_equal(few[1].normal, seq[1].normal)
    with pytest.raises(KeyError, match="no modality flow"):
        few.read(0, ["flow"])
    sim.last_render_timings = {}
    geometry_only = sim.render_outputs(("normal", "flow"), traj.poses, np.stack([sim.dynamic_object_matrices()] * 2), 1)
    assert not sim.last_render_timings and set(geometry_only.outputs) == {"normal", "flow"}  # no Blender render
    plain = sim.render()  # the paper's tuple, also keyed by modality name
    rgb, depth, seg = plain
    assert plain["label"] is seg and plain["depth"] is depth and plain["instance"] is plain.instance
    assert set(plain.outputs) == {"rgb", "rgb_linear", "depth", "label", "instance"}
    with pytest.raises(KeyError, match="no 'flow'"):
        plain["flow"]
    with pytest.raises(ValueError, match="unknown output colour: choose from rgb"):
        fly(sim, traj, tmp_path / "bad", seed=0, outputs=("colour",))


def test_outputs_option_is_checked_up_front(tmp_path):
    from conftest import run_generator

    r = run_generator(tmp_path, "--seeds", "1", "--outputs", "depth,colour")
    assert r.returncode == 2 and "unknown output colour" in r.stderr and "Traceback" not in r.stderr
    assert not list(tmp_path.iterdir())


def test_filtered_objects_keep_depth_and_normals_and_have_no_flow(tmp_path):
    """A filtered object is an unlabelled surface: depth and normal as any surface (render()
    and render_outputs() agree), flow NaN (its motion is not tracked); other surfaces keep
    their flow (0 for a still camera on a static scene)."""
    scenes.new_scene(64, 48)
    scenes.add_plane("Ground", (100, 100), (0, 0, 0))
    scenes.add_box("Wall", (3, 0.2, 3), (-1, -5, 1.5))
    scenes.add_sun()
    scenes.add_camera((0, -15, 3), (math.radians(80), 0, 0))
    sim = Simulator(scenes.save(tmp_path / "filtered.blend"), segmentation_sensitivity=0.0, filter_object_names=["Wall"])
    pose = sim.get_world_from_camera()
    out = sim.render_outputs(["depth", "label", "normal", "flow"], np.stack([pose, pose]), np.zeros((2, 0, 4, 4)), 0)
    wall = np.isfinite(out["depth"]) & (out["label"] == -1)
    ground = np.isfinite(out["depth"]) & (out["label"] >= 0)
    assert wall.sum() > 100 and ground.sum() > 100
    np.testing.assert_allclose(np.linalg.norm(out["normal"][wall], axis=-1), 1.0, atol=1e-5)
    wall_normal = out["normal"][wall].mean(axis=0)  # the wall faces the camera: -y in the world
    assert wall_normal[1] < -0.99
    assert np.isnan(out["flow"][wall]).all() and np.abs(out["flow"][ground]).max() < 1e-6
