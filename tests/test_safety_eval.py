"""Issue #13, the readers' and the evaluation's side: outputs never overwrite inputs, damaged
files are noticed (checksums, structure) and named, hostile inputs are refused up front with
one line and exit code 2. Real files from the real pipeline (the session's tiny seed), real
processes for the command line."""

import hashlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from conftest import ROOT, assert_refused, run_evaluation
from datasets import ClipDataset, DatasetError, FrameDataset, PointCloudDataset, Scene
from evaluation import Cloud
from evaluation.coverage import Poses
from evaluation.inputs import InputError
from exporters.exr import read_frame_exr
from exporters.hdf5 import DamagedFileError
from exporters.ply import read_ply, write_ply
from exporters.tracks import read_tracks
from trajectories import Trajectory


@pytest.fixture(scope="module")
def perfect_tracks(seed_folder, tmp_path_factory):
    tv = read_tracks(seed_folder / "orbit" / "tracks.h5")["tapvid"]
    path = tmp_path_factory.mktemp("pred") / "perfect.npz"
    np.savez(path, tracks=tv["tracks"], occluded=tv["occluded"])
    return path


cli = run_evaluation


def tree_state(folder):
    """{relative path: sha256} of every file under ``folder``."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def flip(path, offset, count=1):
    data = bytearray(path.read_bytes())
    for k in range(offset, offset + count):
        data[k] ^= 0xFF
    path.write_bytes(bytes(data))


def chunk_offset(path, name):
    """Byte offset of the first stored chunk of dataset ``name`` (its data, after filters)."""
    with h5py.File(path, "r") as f:
        info = f[name].id.get_chunk_info(0)
        return info.byte_offset, info.size


# ---- case 3: outputs never overwrite inputs ---------------------------------------------------

def test_outputs_never_land_on_inputs_or_in_the_ground_truth(seed_folder, perfect_tracks, tmp_path):
    pred = tmp_path / "pred.npy"
    np.save(pred, read_ply(seed_folder / "ground_truth" / "points.ply").points[:500])
    gt_file = tmp_path / "gt.ply"
    shutil.copy(seed_folder / "ground_truth" / "points.ply", gt_file)
    link = tmp_path / "innocent.ply"
    link.symlink_to(seed_folder / "ground_truth" / "points.ply")
    before, before_tmp = tree_state(seed_folder), set(os.listdir(tmp_path))
    rec = ["reconstruction", "--gt", seed_folder, "--pred", pred]
    cases = [
        (rec + ["--ply", seed_folder / "ground_truth" / "points.ply"], "generated seed folder"),  # the case
        (rec + ["--json", seed_folder / "scores.json"], "generated seed folder"),
        (rec + ["--ply", link], "not a regular file"),  # a symbolic link (here into the ground truth)
        (rec + ["--json", pred], "is an input"),
        (["reconstruction", "--gt", gt_file, "--pred", pred, "--ply", gt_file], "is an input"),
        (rec + ["--json", tmp_path / "a.out", "--ply", tmp_path / "a.out"], "the same file as"),
        (rec + ["--json", tmp_path], "is a folder"),
        (rec + ["--ply", "/proc/fig9.ply"], "cannot write in /proc"),
        (rec + ["--json", "/dev/null"], "not a regular file"),  # as root, a rename would replace the device
        (rec + ["--json", tmp_path / "missing" / "r.json"], "does not exist"),
        (["coverage", "--gt", seed_folder, "--trajectory", seed_folder / "orbit" / "sparse" / "0", "--plot",
          seed_folder / "orbit" / "sparse" / "0" / "c.png"], "generated seed folder"),
        (["tracks", "--gt", seed_folder / "orbit", "--pred", perfect_tracks, "--json",
          seed_folder / "orbit" / "tracks.h5"], "--json"),
    ]
    for args, message in cases:
        assert_refused(cli(*args), message)
    assert tree_state(seed_folder) == before  # not one byte of the seed changed, nothing added
    assert set(os.listdir(tmp_path)) == before_tmp  # no output, no temporary file left anywhere
    # the refusal is about place, not about scoring: the same run elsewhere works
    r = cli(*rec, "--json", tmp_path / "ok.json", "--ply", tmp_path / "ok.ply")
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "ok.json").read_text())["task"] == "reconstruction"


# ---- case 4 and 8: damaged files are noticed, named, and never scored ---------------------------

def test_flipped_bytes_in_tracks_h5_are_refused_by_every_reader(seed_folder, perfect_tracks, tmp_path):
    copy = tmp_path / "seed"
    shutil.copytree(seed_folder, copy)
    h5 = copy / "orbit" / "tracks.h5"
    pristine = h5.read_bytes()
    assert cli("tracks", "--gt", h5, "--pred", perfect_tracks).returncode == 0
    # K (the "fx doubled") and the TAP-Vid tracks the scores are computed against
    for name in ("cameras/K", "tapvid/tracks", "tapvid/occluded", "visibility/xy"):
        h5.write_bytes(pristine)
        offset, size = chunk_offset(h5, name)
        flip(h5, offset + size // 2)
        with pytest.raises(DamagedFileError, match=r"tracks\.h5: damaged file .*regenerate"):
            read_tracks(h5)
        with pytest.raises(DatasetError, match=r"tracks\.h5: damaged file"):
            seq = Scene(copy)["orbit"]
            seq.visible_tracks(0), seq.tapvid, seq.points  # whichever reads the damaged dataset
            seq.visible_tracks(1), seq.visible_tracks(2)
        line = assert_refused(cli("tracks", "--gt", h5, "--pred", perfect_tracks), str(h5), "damaged", "regenerate")
        assert name in line


def test_another_of_our_files_given_as_tracks_h5_is_named_as_such(seed_folder, perfect_tracks):
    """scene.h5 has the same format version as tracks.h5: it is not a damaged tracks.h5, and
    regenerating the seed would not help (the message used to say both)."""
    scene = seed_folder / "ground_truth" / "scene.h5"
    with pytest.raises(DamagedFileError, match=r"scene\.h5: not a tracks\.h5 \(its top level holds .*surface_points"):
        read_tracks(scene)
    line = assert_refused(cli("tracks", "--gt", scene, "--pred", perfect_tracks), "not a tracks.h5")
    assert "regenerate" not in line and "damaged" not in line


def test_no_single_byte_flip_in_tracks_h5_reads_back_as_other_values(seed_folder, tmp_path):
    """Every byte flip either fails to read or changes nothing readable (free space, padding)."""
    src = seed_folder / "orbit" / "tracks.h5"
    pristine = src.read_bytes()
    reference = read_tracks(src)
    h5 = tmp_path / "tracks.h5"
    silent = []
    for offset in np.random.default_rng(13).choice(len(pristine), 150, replace=False):
        data = bytearray(pristine)
        data[offset] ^= 0x5A
        h5.write_bytes(bytes(data))
        try:
            got = read_tracks(h5)
        except DamagedFileError:
            continue
        if not _same(reference, got):
            silent.append(int(offset))
    assert silent == []


def _same(a, b) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b, equal_nan=a.dtype.kind == "f")
    return a == b


def test_flipped_bytes_in_scene_h5_stop_coverage_scoring(seed_folder, tmp_path):
    copy = tmp_path / "seed"
    shutil.copytree(seed_folder, copy)
    h5 = copy / "ground_truth" / "scene.h5"
    pristine = h5.read_bytes()
    for name in ("camera/K", "surface_points/local", "parts/vertices"):
        h5.write_bytes(pristine)
        offset, size = chunk_offset(h5, name)
        flip(h5, offset + size // 2)
        assert_refused(cli("coverage", "--gt", copy, "--trajectory", copy / "orbit" / "trajectory.npz"),
                       "scene.h5: damaged file", "regenerate")


def test_tracks_h5_checksums_cover_every_dataset(seed_folder):
    for path in (seed_folder / "orbit" / "tracks.h5", seed_folder / "ground_truth" / "scene.h5"):
        with h5py.File(path, "r") as f:
            unprotected = []
            f.visititems(lambda name, obj: unprotected.append(name)
                         if isinstance(obj, h5py.Dataset) and not obj.fletcher32 else None)
            assert unprotected == [], path
            assert isinstance(f.attrs["labels"], bytes)  # fixed-length: inside the checksummed object header


def test_damaged_exr_names_the_file_and_what_to_do(seed_folder, tmp_path):
    copy = tmp_path / "seed"
    shutil.copytree(seed_folder, copy)
    frame = copy / "orbit" / "frame_000001.exr"
    data = frame.read_bytes()
    frame.write_bytes(data[: len(data) // 2])  # truncated
    with pytest.raises(DamagedFileError, match=r"frame_000001\.exr: damaged file \(.*cut short.*regenerate"):
        read_frame_exr(frame)
    with pytest.raises(DatasetError, match=r"frame_000001\.exr: damaged file.*regenerate"):
        Scene(copy)["orbit"][1]
    frame.write_bytes(data[:-1])  # one byte short
    with pytest.raises(DatasetError, match="frame_000001.exr: damaged file"):
        Scene(copy)["orbit"][1]
    frame.write_bytes(b"")
    with pytest.raises(DatasetError, match="frame_000001.exr: damaged file"):
        Scene(copy)["orbit"][1]
    other = copy / "orbit" / "frame_000002.exr"
    flip(other, len(other.read_bytes()) - 200, 8)  # inside the last ZIP chunk: zlib's checksum fails
    with pytest.raises(DatasetError, match=r"frame_000002\.exr: damaged file \(OpenEXR cannot decode"):
        Scene(copy)["orbit"][2]
    np.testing.assert_array_equal(Scene(copy)["orbit"][0].depth, Scene(seed_folder)["orbit"][0].depth)


# ---- case 5: indexing and degenerate inputs ---------------------------------------------------

def test_every_accessor_follows_python_indexing(seed_folder):
    scene = Scene(seed_folder)
    seq = scene["orbit"]
    assert len(seq) == 3
    for neg, pos in ((-1, 2), (-3, 0)):
        assert seq[neg].index == pos
        for key, value in seq.visible_tracks(neg).items():
            np.testing.assert_array_equal(value, seq.visible_tracks(pos)[key])
        ids = seq.visible_tracks(pos)["ids"][:5]
        np.testing.assert_array_equal(seq.point_positions(neg, ids), seq.point_positions(pos, ids))
    assert len(seq.visible_tracks(-1)["ids"]) > 0
    assert scene.frames[-1].index == 2 and scene.frames[-1].trajectory == "spline"
    for call in (lambda: seq[-4], lambda: seq[3], lambda: seq.visible_tracks(-4), lambda: seq.visible_tracks(3),
                 lambda: seq.point_positions(3, [0])):
        with pytest.raises(IndexError, match=r"index (-4|3) out of range: valid indices are -3\.\.2"):
            call()
    with pytest.raises(IndexError, match=r"frame index -7 out of range: valid indices are -6\.\.5"):
        scene.frames[-7]
    with pytest.raises(TypeError, match="must be an integer"):
        seq[1.5]
    with pytest.raises(IndexError, match="point ids"):
        seq.point_positions(0, [10 ** 9])
    frames = FrameDataset(seed_folder)  # the training datasets index the same way
    assert frames[-1]["index"] == 2 and frames[-1]["trajectory"] == "spline"
    with pytest.raises(IndexError, match=r"FrameDataset item index 6 out of range: valid indices are -6\.\.5"):
        frames[6]
    for bad, message in ((lambda: ClipDataset(seed_folder, length=0), "^length must be an integer >= 1, got 0$"),
                         (lambda: ClipDataset(seed_folder, max_points=-1),
                          "^max_points must be None or an integer >= 1, got -1$"),
                         (lambda: ClipDataset(seed_folder, length=2.5), "^length must be an integer >= 1, got 2.5$"),
                         (lambda: ClipDataset(seed_folder, stride=True), "^stride must be an integer >= 1, got True$"),
                         (lambda: PointCloudDataset(seed_folder, num_points=0),
                          "^num_points must be None or an integer >= 1, got 0$")):
        with pytest.raises(ValueError, match=message):
            bad()


def _colmap_copy(src, dst):
    dst.mkdir()
    for p in src.iterdir():
        shutil.copy(p, dst / p.name)
    return dst


def test_coverage_refuses_broken_cameras_reflections_and_bad_timestamps(seed_folder, tmp_path):
    sparse = seed_folder / "orbit" / "sparse" / "0"
    bad = {}
    d = _colmap_copy(sparse, tmp_path / "cam_trunc")
    (d / "cameras.bin").write_bytes((d / "cameras.bin").read_bytes()[:20])  # pycolmap reads a camera of zeros
    bad[d] = "cameras.bin: damaged"
    d = _colmap_copy(sparse, tmp_path / "img_trunc")
    (d / "images.bin").write_bytes((d / "images.bin").read_bytes()[:100])
    bad[d] = "images.bin: damaged"
    d = _colmap_copy(sparse, tmp_path / "fx0")
    for name in ("cameras.bin", "images.bin", "points3D.bin", "rigs.bin", "frames.bin"):
        (d / name).unlink()
    cams = (d / "cameras.txt").read_text().splitlines()
    fields = cams[-1].split()
    fields[4] = "0"  # fx = 0
    (d / "cameras.txt").write_text("\n".join(cams[:-1] + [" ".join(fields)]) + "\n")
    bad[d] = "fx=0"
    traj = Trajectory.load(seed_folder / "orbit" / "trajectory.npz")
    reflected = traj.poses.copy()
    reflected[1, :3, 0] *= -1  # det(R) = -1: a mirror, not a camera
    skewed = traj.poses.copy()
    skewed[2, :3, :3] *= 1.5
    for name, poses, stamps, message in (("reflected", reflected, traj.timestamps, "determinant +1"),
                                         ("skewed", skewed, traj.timestamps, "pose 2 is not a rigid"),
                                         ("nan_time", traj.poses, np.array([0.0, np.nan, 1.0]), "NaN or infinite"),
                                         ("inf_time", traj.poses, np.array([0.0, 0.5, np.inf]), "NaN or infinite"),
                                         ("huge_time", traj.poses, np.array([0.0, 0.5, 1e300]), "seconds in 0..")):
        path = tmp_path / f"{name}.npz"
        np.savez(path, **{k: v for k, v in np.load(seed_folder / "orbit" / "trajectory.npz").items()}
                 | {"poses": poses, "timestamps": stamps})
        bad[path] = message
    for trajectory, message in bad.items():
        assert_refused(cli("coverage", "--gt", seed_folder, "--trajectory", trajectory), message)
    # the API refuses the same poses when given as arrays
    with pytest.raises(InputError, match="determinant"):
        Poses(reflected)
    with pytest.raises(InputError, match="positive focal"):
        Poses(traj.poses, K=np.zeros((3, 3)), width=48, height=32)


# ---- case 7: hostile inputs give one line and exit 2 -----------------------------------------

def test_hostile_inputs_one_line_exit_2(seed_folder, perfect_tracks, tmp_path):
    gt = read_ply(seed_folder / "ground_truth" / "points.ply")
    pts = gt.points[:300]
    t = tmp_path
    np.save(t / "tracks.npy", np.zeros((3, 3, 2)))
    np.savez(t / "short_labels.npz", points=gt.points, labels=gt.vertex["label"][:10])
    np.save(t / "far.npy", np.full((10, 3), 1e160))
    np.save(t / "complex.npy", pts.astype(np.complex128))
    np.save(t / "bools.npy", np.ones((5, 3), bool))
    np.savez(t / "uint_labels.npz", points=pts, labels=np.full(len(pts), 2 ** 64 - 1, np.uint64))
    write_ply(t / "empty.ply", {"x": np.zeros(0, np.float32), "y": np.zeros(0, np.float32), "z": np.zeros(0, np.float32)})
    write_ply(t / "foreign_table.ply", {"x": pts[:, 0], "y": pts[:, 1], "z": pts[:, 2],
                                        "label": np.zeros(len(pts), np.int32)}, comments=['labels ["Sky", "Sea"]'])
    (t / "negative.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex -5\nproperty float x\n"
                                     b"property float y\nproperty float z\nend_header\n")
    (t / "endless.ply").write_bytes(b"ply\nformat ascii 1.0\ncomment " + b"x" * (3 << 20) + b"\n")
    os.mkfifo(t / "pipe.ply")  # reading it would block forever
    (t / "dangling.ply").symlink_to(t / "nowhere.ply")
    (t / "list_x.ply").write_text("ply\nformat ascii 1.0\nelement vertex 1\nproperty list uchar float x\n"
                                  "property float y\nproperty float z\nend_header\n2 1 2 3 4\n")
    os.mkfifo(t / "pipe.npz")
    np.save(t / "far_one.npy", np.vstack([pts, [[1e5, 0, 0]]]))
    tv = read_tracks(seed_folder / "orbit" / "tracks.h5")["tapvid"]
    np.savez(t / "far_tracks.npz", tracks=np.full(tv["tracks"].shape, 1e160), occluded=np.zeros_like(tv["occluded"]))
    np.savez(t / "half_occluded.npz", tracks=tv["tracks"], occluded=np.full(tv["occluded"].shape, 0.5))
    np.savez(t / "text_tracks.npz", tracks=tv["tracks"].astype(str), occluded=tv["occluded"])
    gt_dir = t / "gt_file"  # a labelled cloud whose label table comes from the labels.json beside it
    gt_dir.mkdir()
    write_ply(gt_dir / "gt.ply", {"x": pts[:, 0], "y": pts[:, 1], "z": pts[:, 2], "label": gt.vertex["label"][:300]})
    (t / "images_trunc").mkdir()
    for p in (seed_folder / "orbit" / "sparse" / "0").glob("*.bin"):
        shutil.copy(p, t / "images_trunc" / p.name)
    (t / "images_trunc" / "images.bin").write_bytes((t / "images_trunc" / "images.bin").read_bytes()[:-3])
    rec = ["reconstruction", "--gt", seed_folder, "--pred"]
    trk = ["tracks", "--gt", seed_folder / "orbit", "--pred"]
    cases = [
        (trk + [t / "tracks.npy"], "must be an NPZ"),
        (trk + [t / "far_tracks.npz"], "pixels from the origin"),
        (trk + [t / "half_occluded.npz"], "occluded must be booleans"),
        (trk + [t / "text_tracks.npz"], "must be real numbers"),
        (rec + [t / "short_labels.npz"], "'labels' has shape (10,)"),
        (rec + [t / "far.npy"], "m from the origin"),
        (rec + [t / "complex.npy"], "not real numbers"),
        (rec + [t / "bools.npy"], "not real numbers"),
        (rec + [t / "uint_labels.npz"], "is not a class id"),
        (rec + [t / "empty.ply"], "empty point cloud"),
        (rec + [t / "foreign_table.ply"], "differs from the ground truth's"),
        (rec + [t / "negative.ply"], "negative.ply"),
        (rec + [t / "endless.ply"], "header"),
        (rec + [t / "pipe.ply"], "not a regular file"),
        (rec + [t / "dangling.ply"], "broken symbolic link"),
        (rec + [t / "list_x.ply"], "not lists"),
        (rec + [t / "far_one.npy", "--voxel", "1e-12"], "voxel 1e-12 m is too small"),
        (["coverage", "--gt", seed_folder, "--trajectory", t / "pipe.npz"], "not a regular file"),
        (trk + [t / "pipe.npz"], "not a regular file"),
        (rec + [perfect_tracks, "--json", t], "is a folder"),
        (rec + [perfect_tracks, "--ply", "/proc/x.ply"], "cannot write"),
        (["coverage", "--gt", seed_folder, "--trajectory", t / "images_trunc"], "images.bin: damaged"),
    ]
    for args, message in cases:
        assert_refused(cli(*args), message)
    (gt_dir / "labels.json").write_bytes(b"\xff\xfe not utf-8")
    assert_refused(cli("reconstruction", "--gt", gt_dir / "gt.ply", "--pred", perfect_tracks), "labels.json")
    assert not [p for p in t.iterdir() if p.name.startswith(".")]  # no temporary file left


def test_the_api_refuses_what_the_cli_refuses(seed_folder):
    with pytest.raises(InputError, match="10 labels for 20 points"):
        Cloud(np.zeros((20, 3)), np.zeros(10, int), "mine")
    with pytest.raises(InputError, match="NaN or infinite"):
        Cloud(np.array([[0, 0, np.nan]]), None, "mine")
    with pytest.raises(InputError, match="labels must be integers"):
        Cloud(np.zeros((2, 3)), np.array([0.5, 1.0]), "mine")
    from evaluation import reconstruction_metrics, score_reconstruction

    three = np.eye(3)
    for kwargs, words in ((dict(pred_labels=np.zeros(3), gt_labels=np.zeros(3, int)), "pred: labels must be integers"),
                          (dict(pred_labels=np.zeros(2, int), gt_labels=np.zeros(3, int)), "pred: 2 labels for 3 points"),
                          (dict(gt=np.array([[0, 0, np.nan]])), "gt: 1 points have NaN"), (dict(tau=-1.0), "tau")):
        with pytest.raises(InputError, match=words):
            reconstruction_metrics(**{"pred": three, "gt": three} | kwargs)
    with pytest.raises(InputError, match="crop_margin must be a non-negative"):
        score_reconstruction(seed_folder / "ground_truth" / "points.ply", seed_folder, crop=True, crop_margin=-3.0)
    from evaluation import score_tracks

    with pytest.raises(InputError, match="needs arrays 'tracks'"):
        score_tracks(seed_folder / "orbit", {"tracks": np.zeros(3)})
    with pytest.raises(InputError, match="resize_to"):
        tv = read_tracks(seed_folder / "orbit" / "tracks.h5")["tapvid"]
        score_tracks(seed_folder / "orbit", {"tracks": tv["tracks"], "occluded": tv["occluded"]}, resize_to=(0, 256))


def test_simulator_refuses_non_finite_positions_and_bounds_long_moves(tmp_path):
    """In its own process (bpy): is_free([nan] * 3) raises; a move of a billion metres is swept
    over the scene's bounds only (it used to allocate 25 GiB) and lands where asked."""
    script = f"""
import sys
from pathlib import Path
sys.path.insert(0, {str(ROOT / 'tests')!r})
import numpy as np
import scenes
from generator import Simulator
sim = Simulator(scenes.walls_scene(__import__('pathlib').Path({str(tmp_path)!r}) / 'walls.blend'), points_density=1,
                collision_radius=0.3)
try:
    sim.is_free([float('nan')] * 3)
    print('ACCEPTED')
except ValueError as exc:
    print('REFUSED', exc)
start = sim.get_world_from_camera()
assert sim.move_camera_forward(-1e9) is False  # the issue's call
moved = sim.get_world_from_camera()[:3, 3] - start[:3, 3]
print('MOVED', float(np.linalg.norm(moved)))
print('THROUGH_WALL', sim.can_move([0, -1e8, 1.5], [0, 10, 1.5]), sim.can_move([-1e8, 2, 1.5], [1e8, 2, 1.5]))
"""
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    out = dict(line.split(" ", 1) for line in r.stdout.splitlines() if line.split(" ")[0].isupper())
    assert out["REFUSED"].startswith("position must be finite")
    assert float(out["MOVED"]) == pytest.approx(1e9)
    assert out["THROUGH_WALL"] == "False True"  # the wall blocks the long sweep; a clear long line is free


def test_paths_that_cannot_be_looked_into_are_one_line_errors(tmp_path):
    """A path whose stat fails with an error other than 'not found' (a name too long, here on
    every machine; a folder this user may not enter, EACCES, where /proc/1/root makes one:
    even root may not enter it in a container): every CLI says so in one line and exits 2."""
    cases = [(tmp_path / ("x" * 300) / "nothing", "File name too long")]
    try:
        Path("/proc/1/root/nothing").exists()
    except PermissionError:
        cases.append((Path("/proc/1/root/nothing"), "Permission denied"))
    env = {k: v for k, v in os.environ.items() if k != "OCIO"}
    for hidden, says in cases:
        for args in (["evaluation", "reconstruction", "--gt", str(hidden), "--pred", str(hidden)],
                     ["datasets.view", str(hidden), "--out", str(tmp_path / "x.rrd")],
                     ["generator", "verify", str(hidden)],
                     ["generator", "--seeds", "1", "--out", str(hidden)]):
            r = subprocess.run([sys.executable, "-m", *args], capture_output=True, text=True, cwd=ROOT, env=env)
            assert r.returncode == 2 and says in r.stderr, (args, r.stderr)
            assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr, (args, r.stderr)
