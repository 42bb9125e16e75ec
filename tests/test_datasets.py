"""Training loaders on the real pipeline's output: values read back equal what was written,
transforms keep projections consistent, several processes read at once, clear errors."""

import itertools
import json
import re
import multiprocessing as mp
import shutil
import subprocess
import sys

import h5py
import numpy as np
import pytest

from datasets import ClipDataset, Compose, Crop, DatasetError, FrameDataset, PointCloudDataset, Resize, Scene, ToLinear
from datasets.transforms import linear_to_srgb, srgb_to_linear
from exporters import FORMAT_VERSION
from exporters.exr import read_frame_exr
from exporters.frames import FrameReader
from exporters.hdf5 import DamagedFileError
from exporters.modalities import MODALITIES
from PIL import Image
from exporters.ply import read_ply
from exporters.tracks import read_tracks
from generator.geometry.camera import project
from trajectories import Trajectory


def test_scene_reads_back_what_was_written(seed_folder):
    scene = Scene(seed_folder)
    assert scene.seed == 4 and scene.trajectories == ["orbit", "spline"] and len(scene.frames) == 6
    assert scene.labels == json.loads((seed_folder / "labels.json").read_text())
    for kind in scene.trajectories:
        seq = scene[kind]
        written = read_tracks(seed_folder / kind / "tracks.h5")
        traj = Trajectory.load(seed_folder / kind / "trajectory.npz")
        assert seq.modalities == tuple(MODALITIES)  # the default writes every modality
        for i, frame in enumerate(seq[:]):
            exr = read_frame_exr(seed_folder / kind / f"frame_{i:06d}.exr")
            assert set(exr) == {"header"} | {n for n in MODALITIES if MODALITIES[n].part is not None}
            png = np.asarray(Image.open(seed_folder / kind / f"rgb_{i:06d}.png"))
            assert frame.rgb.dtype == np.float32
            np.testing.assert_array_equal(frame.rgb, png.astype(np.float32) / np.float32(255))
            for key in set(exr) - {"header"}:
                np.testing.assert_array_equal(getattr(frame, key), exr[key])
                np.testing.assert_array_equal(frame[key], exr[key])
            assert frame.rgb_linear.dtype == np.float16 and frame.normal.shape == frame.flow.shape[:2] + (3,)
            np.testing.assert_array_equal(frame.pose, traj.poses[i])
            np.testing.assert_array_equal(frame.K, written["K"])
            assert frame.timestamp == traj.timestamps[i]
            vis = seq.visible_tracks(i)
            a, b = written["offsets"][i], written["offsets"][i + 1]
            np.testing.assert_array_equal(vis["ids"], written["index"][a:b])
            np.testing.assert_array_equal(vis["xy"], written["xy"][a:b])
        np.testing.assert_array_equal(seq.coverage, written["coverage"])
        for key, value in written["tapvid"].items():
            np.testing.assert_array_equal(seq.tapvid[key], value)
    # global frame index runs over the trajectories in order
    np.testing.assert_array_equal(scene.frames[4].pose, scene["spline"][1].pose)
    cloud = scene.point_cloud()
    ply = read_ply(seed_folder / "ground_truth" / "points.ply")
    np.testing.assert_array_equal(cloud["label"], ply.vertex["label"])
    assert len(scene.point_cloud(static_only=True)["xyz"]) == int((ply.vertex["dynamic"] == 0).sum())


def test_reading_some_keys_gives_the_same_arrays_as_reading_all(seed_folder, tmp_path):
    seq = Scene(seed_folder)["orbit"]
    whole = seq.read(1).outputs
    names = list(whole)
    subsets = [(n,) for n in names] + list(itertools.combinations(names, 2)) + [("rgb", "label", "instance")]
    for keys in subsets:
        part = seq.read(1, keys).outputs
        assert list(part) == list(keys), keys
        for k in keys:
            assert part[k].dtype == whole[k].dtype and np.array_equal(part[k], whole[k], equal_nan=True), (keys, k)
    # ids alone come from their 16-bit PNGs (the same values; the EXR is not opened): shown by
    # a copy whose EXR is gone, where ids still read and an EXR-only modality names the file
    copy = tmp_path / "orbit"
    shutil.copytree(seed_folder / "orbit", copy)
    (copy / "frame_000001.exr").unlink()
    reader = FrameReader(copy)
    got = reader.read(1, ("label", "instance"))
    assert all(np.array_equal(got[k], whole[k]) for k in ("label", "instance"))
    with pytest.raises(DamagedFileError, match="frame_000001.exr: missing frame"):
        reader.read(1, ("label", "depth"))


def test_task_datasets(seed_folder):
    frames = FrameDataset([seed_folder, seed_folder], trajectories=["orbit"])
    assert len(frames) == 6
    item = frames[5]
    assert item["rgb"].shape == (32, 48, 3) and item["scene"] == 4 and item["index"] == 2
    clips = ClipDataset(seed_folder, length=3)
    assert len(clips) == 2  # one 3-frame clip per trajectory
    clip = clips[0]
    tr = clip["tracks"]
    assert tr["visible"][0].all() and tr["xy"].shape == (3, len(tr["ids"]), 2)
    seq = Scene(seed_folder)["orbit"]
    for k in range(3):  # visible stored positions equal the clip's projections
        vis = seq.visible_tracks(k)
        common, a, b = np.intersect1d(tr["ids"], vis["ids"], return_indices=True)
        np.testing.assert_array_equal(tr["visible"][k], np.isin(tr["ids"], vis["ids"]))
        np.testing.assert_allclose(tr["xy"][k][a], vis["xy"][b], atol=1e-3)
    clouds = PointCloudDataset(seed_folder, num_points=1000)
    assert clouds[0]["xyz"].shape == (1000, 3) and clouds[0]["label"].shape == (1000,)


@pytest.mark.parametrize("keys", [("flow", "depth"), ("flow", "instance"), ("flow",)])
def test_resize_never_blends_flow_across_an_object_edge(keys):
    """Background flow 0 (columns 0-2, 30 m, object 0) and foreground flow 40 px (columns
    3-7, 10 m, object 1), shrunk 8 -> 6 px: every value is one of the two surfaces' (scaled),
    whether the edge is known from depth, from instance ids, or not at all."""
    fg = np.arange(8) >= 3
    full = {"flow": np.zeros((4, 8, 2), np.float32), "depth": np.where(fg, 10.0, 30.0)[None].repeat(4, 0).astype(np.float32),
            "instance": np.where(fg, 1, 0)[None].repeat(4, 0).astype(np.int32)}
    full["flow"][:, fg, 0] = 40.0
    out = Resize(6, 4)({k: full[k] for k in keys})
    assert set(np.unique(out["flow"][..., 0])) <= {0.0, np.float32(40.0 * 6 / 8)}
    assert np.any(out["flow"][..., 0] == 0) and np.any(out["flow"][..., 0] > 0)


def test_resize_and_crop_keep_projections(seed_folder):
    scene = Scene(seed_folder)
    plain = ClipDataset(seed_folder, length=2)[0]
    labels = scene["orbit"].points["label"][plain["tracks"]["ids"]]
    for transform, (w, h) in ((Resize(96, 64), (96, 64)), (Resize(24, 16), (24, 16)),
                              (Compose(Crop(8, 4, 32, 24), Resize(64, 48)), (64, 48))):
        clip = ClipDataset(seed_folder, length=2, transform=transform)[0]
        tr = clip["tracks"]
        for k, frame in enumerate(clip["frames"]):
            assert frame["depth"].shape == (h, w) and frame["rgb"].shape == (h, w, 3)
            # a tracked point projected with the new intrinsics lands where the transformed track says
            uv, _ = project(tr["xyz"][k], frame["pose"], frame["K"])
            np.testing.assert_allclose(uv, tr["xy"][k], atol=1e-6)
            # off label edges (3x3 uniform in the original), the transformed label map shows the
            # point's label at its transformed pixel
            orig = plain["frames"][k]["label"]
            x, y = np.floor(plain["tracks"]["xy"][k]).astype(int).T
            ok = tr["visible"][k] & (x >= 1) & (x < 47) & (y >= 1) & (y < 31)
            ok &= (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
            for dx in (-1, 0, 1):
                for dy in (-1, 0, 1):
                    ok[ok] &= orig[y[ok] + dy, x[ok] + dx] == labels[ok]
            px = np.floor(uv[ok]).astype(int)
            assert ok.sum() >= 5  # tracked points off label edges in view (the tiny run: 48x32 px, 0.3 points/m^2)
            np.testing.assert_array_equal(frame["label"][px[:, 1], px[:, 0]], labels[ok])
            # a point is visible only inside the new image (a crop drops the others)
            inside = (tr["xy"][k][:, 0] >= 0) & (tr["xy"][k][:, 0] < w) & (tr["xy"][k][:, 1] >= 0) & (tr["xy"][k][:, 1] < h)
            np.testing.assert_array_equal(tr["visible"][k], plain["tracks"]["visible"][k] & inside)
    cropped = ClipDataset(seed_folder, length=2, transform=Crop(8, 4, 16, 12))[0]["tracks"]
    assert plain["tracks"]["visible"].sum() > cropped["visible"].sum() > 0
    with pytest.raises(ValueError, match="Resize needs an image"):  # no image: the scale is unknown
        ClipDataset(seed_folder, length=2, keys=(), transform=Resize(24, 16))[0]
    rgb = np.random.default_rng(0).uniform(0, 1, (4, 4, 3)).astype(np.float32)
    np.testing.assert_allclose(linear_to_srgb(srgb_to_linear(rgb)), rgb, atol=1e-5)
    assert ToLinear()({"rgb": np.full((1, 1, 3), 0.5, np.float32)})["rgb"][0, 0, 0] == pytest.approx(0.21404, abs=1e-4)


@pytest.mark.parametrize("make, message", [
    (lambda: Crop(-1, 0, 8, 8), "^Crop x0 must be an integer >= 0, got -1$"),
    (lambda: Crop(0, 0.5, 8, 8), "^Crop y0 must be an integer >= 0, got 0.5$"),
    (lambda: Crop(0, 0, 8, 0), "^Crop height must be an integer >= 1, got 0$"),
    (lambda: Resize(24.0, 16), "^Resize width must be an integer >= 1, got 24.0$"),
    (lambda: Resize(24, -16), "^Resize height must be an integer >= 1, got -16$"),
])
def test_transform_sizes_are_one_line_errors(make, message):
    """A fractional window used to be truncated silently; now it is refused."""
    with pytest.raises(ValueError, match=message):
        make()


def _read_items(args):
    folder, indices = args
    ds = FrameDataset(folder)
    return [float(ds[i]["depth"][np.isfinite(ds[i]["depth"])].sum()) for i in indices]


def test_forked_workers_read_exr_frames(seed_folder):
    """DataLoader's default start method on Linux is fork: workers forked from a process that
    imported the readers (OpenEXR's thread pool started) read EXR frames. In a fresh process
    (this one runs open3d's threads, which fork must not copy)."""
    code = f"""
import multiprocessing as mp, sys
import numpy as np
from datasets import FrameDataset
ds = FrameDataset({str(seed_folder)!r}, keys=("depth",))
def total(i):
    return float(np.where(np.isfinite(ds[i]["depth"]), ds[i]["depth"], 0).sum())
expected = [total(i) for i in range(len(ds))]
with mp.get_context("fork").Pool(2) as pool:
    got = pool.map_async(total, range(len(ds))).get(timeout=60)
print("same" if got == expected else f"differ {{got}} {{expected}}")
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "same", r.stdout + r.stderr[-2000:]


def test_a_process_with_an_exr_pool_forks_subprocesses_with_a_preexec_fn(seed_folder):
    """A process that has read EXR frames (its pool running) starts 30 subprocesses with a
    preexec_fn (Python runs its fork hooks in the child then): none crashes or hangs, and
    the parent still reads the same frames after, with its pool of 8 threads back. (A pool stopped in the child, as before,
    joined threads that do not exist there: a segmentation fault in CI.)"""
    code = f"""
import subprocess, sys
import numpy as np, OpenEXR
from datasets import FrameDataset
ds = FrameDataset({str(seed_folder)!r}, keys=("depth",))
OpenEXR.set_global_thread_count(8)  # more threads than this machine's cores: the crash was certain
before = [float(np.nansum(np.where(np.isinf(ds[i]["depth"]), 0, ds[i]["depth"]))) for i in range(len(ds))]
codes = [subprocess.run([sys.executable, "-c", "pass"], preexec_fn=lambda: None, timeout=60).returncode
         for _ in range(30)]
after = [float(np.nansum(np.where(np.isinf(ds[i]["depth"]), 0, ds[i]["depth"]))) for i in range(len(ds))]
print(codes.count(0), before == after, OpenEXR.global_thread_count())
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and r.stdout.split() == ["30", "True", "8"], r.stdout + r.stderr[-2000:]


def test_concurrent_reads_from_several_processes(seed_folder):
    ds = FrameDataset(seed_folder)
    expected = [float(ds[i]["depth"][np.isfinite(ds[i]["depth"])].sum()) for i in range(len(ds))]
    ds.scenes[0]["orbit"].visible_tracks(0)  # the HDF5 handle is open in this process
    # spawn, not fork: this test process runs threads (open3d), and forking it may deadlock
    with mp.get_context("spawn").Pool(3) as pool:
        got = pool.map(_read_items, [(seed_folder, list(range(len(ds))))] * 6)
    assert all(g == expected for g in got)
    # a dataset object made here, used here (files open), then pickled to workers (as DataLoader does)
    clips = ClipDataset(seed_folder, length=2)
    clips[0]
    with mp.get_context("spawn").Pool(2) as pool:
        counts = pool.map(_clip_ids, [(clips, i) for i in range(len(clips))] * 2)
    assert counts == [len(clips[i]["tracks"]["ids"]) for i in range(len(clips))] * 2


def _clip_ids(args):
    ds, i = args
    return len(ds[i]["tracks"]["ids"])


def test_clear_errors(seed_folder, tmp_path):
    with pytest.raises(DatasetError, match="no such folder"):
        Scene(tmp_path / "nothing")
    copy = tmp_path / "copy"
    shutil.copytree(seed_folder, copy)
    manifest = json.loads((copy / "manifest.json").read_text())
    other = {k: v for k, v in manifest.items() if k != "checksum"}  # as a manifest without a checksum of its own
    (copy / "manifest.json").write_text(json.dumps(other | {"format_version": "9.0"}))
    with pytest.raises(DatasetError, match=rf"format_version '9.0'; this reader reads {re.escape(FORMAT_VERSION)}.*"
                                          r"python -m generator --seeds N --overwrite"):
        Scene(copy)
    (copy / "manifest.json").write_text(json.dumps(manifest))
    with h5py.File(copy / "orbit" / "tracks.h5", "r+") as f:
        f.attrs["format_version"] = "1.7"
    with pytest.raises(DatasetError, match="format_version '1.7'"):
        Scene(copy)["orbit"]
    (copy / "spline" / "frame_000001.exr").unlink()
    with pytest.raises(DatasetError, match="missing frame"):
        Scene(copy)["spline"][1]
    (copy / "manifest.json").unlink()
    with pytest.raises(DatasetError, match="not a complete seed folder"):
        Scene(copy)


def test_as_tensor_needs_torch_or_gives_tensors(seed_folder):
    ds = FrameDataset(seed_folder, as_tensor=True)
    try:
        import torch
    except ImportError:
        with pytest.raises(DatasetError, match="needs PyTorch"):
            ds[0]
        return
    item = ds[0]
    assert isinstance(item["rgb"], torch.Tensor) and item["rgb"].dtype == torch.float32


@pytest.mark.pipeline
def test_annotations_of_a_seed_made_without_instances(tmp_path):
    """coco.json and boxes3d.json are written only with the instance output: asking such a
    seed for annotations says so (not 'damaged, regenerate' with the same options)."""
    from conftest import run_generator

    r = run_generator(tmp_path, "--seeds", "2", "--outputs", "rgb,depth", "--trajectory", "orbit", "--frames", "2")
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert FrameDataset(tmp_path / "seed_000002")[0]["depth"].shape == (32, 48)
    with pytest.raises(DatasetError, match="without instance, so it has no coco.json; regenerate it with instance"):
        FrameDataset(tmp_path / "seed_000002", annotations=True)  # when made, not at the first item


def test_a_ground_truth_cloud_of_another_format_is_refused(seed_folder, tmp_path):
    """points.ply states its format version in a header comment (docs/format.md); the loader
    and the evaluation refuse another version, or none, saying how to regenerate."""
    from evaluation import score_reconstruction
    from evaluation.inputs import InputError

    copy = tmp_path / seed_folder.name
    shutil.copytree(seed_folder, copy)
    ply = copy / "ground_truth" / "points.ply"
    original = ply.read_bytes()
    stated = f"buildee ground truth format {FORMAT_VERSION}".encode()
    assert original.count(stated) == 1
    for replacement, says in ((b"buildee ground truth format 0.3", "format 0.3"), (b"x" * len(stated), "not stated")):
        ply.write_bytes(original.replace(stated, replacement.ljust(len(stated))))
        with pytest.raises(DatasetError, match=f"ground-truth {says}|ground-truth format {says}"):
            Scene(copy).point_cloud()
        with pytest.raises(InputError, match=says):
            score_reconstruction(seed_folder / "ground_truth" / "points.ply", copy)


def test_frame_keys_and_both_forms_of_compose(seed_folder):
    """frame["K"] as frame.K (the docs list K, pose and timestamp among a frame's contents), a
    clear KeyError otherwise; Compose takes a list too (as torchvision's does)."""
    frame = Scene(seed_folder)["orbit"][0]
    assert frame["K"] is frame.K and frame["pose"] is frame.pose and frame["timestamp"] == frame.timestamp
    with pytest.raises(KeyError, match="frame has no 'nope'; it holds .*depth.* and K, pose"):
        frame["nope"]
    with pytest.raises(KeyError, match="frame has no 'depth'; it holds no modalities \\(none read\\) and K, pose"):
        Scene(seed_folder)["orbit"].read(0, keys=[])["depth"]
    as_args = FrameDataset(seed_folder, transform=Compose(Crop(8, 4, 32, 24), Resize(64, 48)))[0]
    as_list = FrameDataset(seed_folder, transform=Compose([Crop(8, 4, 32, 24), Resize(64, 48)]))[0]
    assert as_args.keys() == as_list.keys() and as_args["rgb"].shape == (48, 64, 3)
    for key, value in as_args.items():  # (NaN flow where there is none: equal as NaN)
        np.testing.assert_array_equal(value, as_list[key], err_msg=key)
    with pytest.raises(TypeError, match="Compose takes callables"):
        Compose([Crop(8, 4, 32, 24), "resize"])


def test_dataset_arguments_are_checked_when_the_dataset_is_made(seed_folder):
    """Keys, trajectories and clip lengths are checked at construction (in the main process,
    not in a DataLoader worker at the first item); one key may be given as a string."""
    with pytest.raises(DatasetError, match=r"orbit: no modality bogus \(written: rgb, "):
        FrameDataset(seed_folder, keys=("depth", "bogus"))
    with pytest.raises(DatasetError, match=r"no trajectory 'lawnmower' \(has orbit, spline\)$"):
        FrameDataset(seed_folder, trajectories=["lawnmower"])
    with pytest.raises(DatasetError, match=r"^a clip of length 5 with stride 1 spans 5 frames; the longest trajectory has 3: use a shorter length or a smaller stride$"):
        ClipDataset(seed_folder, length=5)
    with pytest.raises(DatasetError, match="no modality bogus"):
        ClipDataset(seed_folder, keys=["bogus"])
    one = FrameDataset(seed_folder, keys="depth", trajectories="spline")
    assert len(one) == 3 and set(one[0]) & set(MODALITIES) == {"depth"} and one[0]["trajectory"] == "spline"
    # KeyErrors print their message as written (a plain KeyError prints its repr), and a file
    # given for a seed folder says so
    with pytest.raises(KeyError) as err:
        Scene(seed_folder)["bogus"]
    assert str(err.value) == f"no trajectory 'bogus' in {seed_folder} (has orbit, spline)"
    with pytest.raises(DatasetError, match="manifest.json: a file, not a seed folder; pass the folder that holds it$"):
        Scene(seed_folder / "manifest.json")
