"""The evaluation's input guards, case by case: damaged NPY/NPZ files, malformed PLY headers
and ASCII bodies, change predictions of the wrong kind, API arguments the CLI refuses, label
tables. Real files written and read back; the command line in real processes. No Blender:
the ground truth here is a small points.ply written with the exporters' own writer."""

import json
import re
import warnings

import numpy as np
import pytest

from conftest import assert_refused, run_evaluation
from evaluation import Cloud
from evaluation.inputs import InputError, read_cloud
from exporters import FORMAT_VERSION
from exporters.ground_truth import PLY_VERSION_COMMENT
from exporters.ply import PlyError, read_ply, write_ply
from trajectories import Trajectory, TrajectoryError

LABELS = ["ground", "building", "crane"]


cli = run_evaluation


def write_gt(folder, n=60):
    """A ground_truth/ folder whose points.ply has every property read_points needs (the
    mesh and scene files exist only as names: reconstruction reads points.ply alone)."""
    gt = folder / "ground_truth"
    gt.mkdir(parents=True)
    rng = np.random.default_rng(0)
    xyz = (rng.random((n, 3)) * 2).astype(np.float32)
    zeros = np.zeros(n, np.uint8)
    write_ply(gt / "points.ply", {"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], "red": zeros, "green": zeros,
                                  "blue": zeros, "label": rng.integers(0, 3, n).astype(np.int32),
                                  "instance": np.zeros(n, np.int32), "dynamic": zeros, "observable": zeros + 1},
              comments=[f"{PLY_VERSION_COMMENT} {FORMAT_VERSION}", "units metres", f"labels {json.dumps(LABELS)}"])
    (gt / "mesh.ply").write_bytes(b"unused")
    (gt / "scene.h5").write_bytes(b"unused")
    return gt, xyz.astype(np.float64)


@pytest.fixture
def gt(tmp_path):
    return write_gt(tmp_path / "seed")


def truncated(path):
    """``path`` cut to half its size (a download or copy that stopped)."""
    data = path.read_bytes()
    path.write_bytes(data[:len(data) // 2])
    return path


def damaged_member(path):
    """``path`` (a compressed NPZ) with bytes flipped inside its first member's data."""
    data = bytearray(path.read_bytes())
    for k in range(60, 70):
        data[k] ^= 0xFF
    path.write_bytes(bytes(data))
    return path


def npz(path, damage=truncated, **arrays):
    with open(path, "wb") as f:  # the name kept as given (numpy.savez would add .npz)
        np.savez_compressed(f, **arrays)
    return damage(path)


def trajectory(path, **override):
    poses = np.repeat(np.eye(4)[None], 3, axis=0)
    arrays = {"poses": poses, "timestamps": np.arange(3.0), "actions": np.array(["forward", "left"]),
              "header": np.array(json.dumps({"format": "buildee-trajectory-1", "kind": "walk", "params": {}}))}
    np.savez(path, **(arrays | override))
    return path


# ---- 1, 2: damaged, empty or odd NPY/NPZ files: one line, every reader ----------------------

@pytest.mark.parametrize("damage", [truncated, damaged_member])
def test_damaged_npz_clouds_and_label_files_are_refused(gt, tmp_path, damage):
    rng = np.random.default_rng(1)
    pred = npz(tmp_path / "pred.npz", damage, points=rng.random((500, 3)), labels=rng.integers(0, 3, 500))
    assert_refused(cli("reconstruction", "--gt", gt[0], "--pred", pred), pred.name, "not a readable NPY/NPZ")
    ok = tmp_path / "ok.npy"
    np.save(ok, gt[1])
    labels = npz(tmp_path / "labels.npy", damage, labels=rng.integers(0, 3, 500))  # an NPZ under an .npy name
    assert_refused(cli("reconstruction", "--gt", gt[0], "--pred", ok, "--pred-labels", labels), labels.name)
    empty = tmp_path / "empty.npz"
    empty.write_bytes(b"")
    with pytest.raises(InputError, match="empty.npz: not a readable NPY/NPZ"):
        read_cloud(empty)


def test_an_npz_member_that_is_not_an_array_is_refused(tmp_path):
    import zipfile

    path = tmp_path / "raw.npz"
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("points", b"1 2 3")
    with pytest.raises(InputError, match="member 'points' is not a NumPy array"):
        read_cloud(path)


@pytest.mark.parametrize("kind", ["truncated", "empty"])
def test_damaged_or_empty_change_predictions_are_refused(tmp_path, kind):
    pred = tmp_path / "change.npz"
    if kind == "empty":
        pred.write_bytes(b"")
    else:
        npz(pred, xyz=np.random.default_rng(2).random((400, 3)), change=np.ones(400, np.int8))
    assert_refused(cli("change", "--gt", tmp_path, "--stages", 0, 1, "--pred", pred), pred.name,
                   "not a readable NPY/NPZ")


def test_damaged_predicted_tracks_are_refused(tmp_path):
    from evaluation.tracking import read_tracks_pred

    pred = npz(tmp_path / "tracks.npz", tracks=np.random.default_rng(3).random((40, 30, 2)),
               occluded=np.zeros((40, 30), bool))
    with pytest.raises(InputError, match="tracks.npz: not a readable NPY/NPZ"):
        read_tracks_pred(pred, 40, 30)


@pytest.mark.parametrize("make", [
    lambda p: truncated(trajectory(p, poses=np.repeat(np.eye(4)[None], 200, axis=0),
                                   timestamps=np.arange(200.0), actions=np.array(["forward"] * 199))),
    lambda p: (p.write_bytes(b""), p)[1],
    lambda p: trajectory(p, actions=np.array("forward")),
], ids=["truncated", "empty", "0-d actions"])
def test_damaged_trajectories_are_one_line_errors(tmp_path, make):
    from evaluation.coverage import read_poses

    path = make(tmp_path / "walk.npz")
    with pytest.raises(TrajectoryError, match="walk.npz"):
        Trajectory.load(path)
    with pytest.raises(InputError, match="walk.npz") as info:  # what `coverage --trajectory` prints
        read_poses(path, None, "first")
    assert "\n" not in str(info.value)


def test_a_good_trajectory_still_loads(tmp_path):
    back = Trajectory.load(trajectory(tmp_path / "walk.npz"))
    assert back.actions == ["forward", "left"] and back.poses.shape == (3, 4, 4)


# ---- 3: change clouds and masks of the wrong kind ---------------------------------------------

@pytest.mark.parametrize("arrays, words", [
    ({"xyz": np.array([["a", "b", "c"]]), "change": np.array([1])}, "real numbers"),
    ({"xyz": np.array([[1 + 1j, 0, 0]]), "change": np.array([1])}, "real numbers"),
    ({"xyz": np.zeros((1, 3)), "change": np.array([1 + 0j])}, "change must be"),
    ({"masks": np.zeros((0, 2, 2), "U1")}, "masks must be booleans"),
    ({"masks": np.zeros((1, 2, 2), "U1")}, "masks must be booleans"),
], ids=["text xyz", "complex xyz", "complex change", "empty text masks", "text masks"])
def test_change_predictions_of_the_wrong_kind_are_refused(tmp_path, arrays, words):
    from evaluation.change import read_change_prediction

    pred = tmp_path / "change.npz"
    np.savez(pred, **arrays)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no ComplexWarning: complex is refused, not cast
        with pytest.raises(InputError, match=words):
            read_change_prediction(pred)
    assert_refused(cli("change", "--gt", tmp_path, "--stages", 0, 1, "--pred", pred), words)


def test_good_change_predictions_still_read(tmp_path):
    from evaluation.change import read_change_prediction

    np.savez(tmp_path / "c.npz", xyz=np.zeros((2, 3), np.float32), change=np.array([1, 2], np.uint8))
    np.savez(tmp_path / "m.npz", masks=np.zeros((0, 2, 2), bool))
    got = read_change_prediction(tmp_path / "c.npz")
    assert got["xyz"].dtype == np.float64 and got["change"].tolist() == [1, 2]
    assert read_change_prediction(tmp_path / "m.npz")["masks"].shape == (0, 2, 2)


# ---- 4, 5: PLY headers with duplicate names; ASCII values their type cannot hold --------------

def ascii_ply(path, props, rows, elements="vertex"):
    header = ["ply", "format ascii 1.0", f"element {elements} {len(rows)}", *(f"property {p}" for p in props)]
    path.write_text("\n".join(header + ["end_header"] + rows) + "\n")
    return path


def test_duplicate_ground_truth_property_is_one_line(gt):
    path = gt[0] / "points.ply"
    data = path.read_bytes()
    path.write_bytes(data.replace(b"property float y\n", b"property float x\n", 1))
    assert_refused(cli("reconstruction", "--gt", gt[0], "--pred", path), "points.ply", "property 'x' of element 'vertex' twice")


def test_duplicate_names_are_refused_in_every_ply(tmp_path):
    with pytest.raises(PlyError, match="property 'x' of element 'vertex' twice"):
        read_ply(ascii_ply(tmp_path / "a.ply", ["float x", "float y", "float z", "float x"], ["0 1 2 3"]))
    binary = tmp_path / "b.ply"
    write_ply(binary, {"x": np.zeros(2, np.float32), "y": np.zeros(2, np.float32), "z": np.zeros(2, np.float32)})
    binary.write_bytes(binary.read_bytes().replace(b"property float z\n", b"property float y\n", 1))
    with pytest.raises(PlyError, match="property 'y' of element 'vertex' twice"):
        read_ply(binary)
    twice = tmp_path / "c.ply"
    twice.write_text("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                     "element vertex 1\nproperty float x\nend_header\n0 0 0\n5\n")
    with pytest.raises(PlyError, match="element 'vertex' twice"):
        read_ply(twice)


@pytest.mark.parametrize("label_type, value, words", [
    ("int", "1.7", "1.7"), ("uchar", "300", "300"), ("uchar", "-1", "-1"), ("int", "nan", "nan"),
    ("int", "3000000000", "3000000000"),
])
def test_ascii_values_their_type_cannot_hold_are_refused(tmp_path, label_type, value, words):
    props = ["float x", "float y", "float z", f"{label_type} label"]
    path = ascii_ply(tmp_path / "p.ply", props, ["0 0 0 1", f"1 1 1 {value}"])
    with pytest.raises(PlyError, match=f"'label' holds {re.escape(words)}.* \\(row 1\\)"):
        read_ply(path)
    path = ascii_ply(tmp_path / "l.ply", props + ["list uchar int vertex_indices"], ["0 0 0 1 0", f"1 1 1 {value} 0"])
    with pytest.raises(PlyError, match="'label'"):
        read_ply(path)


def test_float_beyond_float32_and_good_ascii(tmp_path):
    with pytest.raises(PlyError, match="'x'"):
        read_ply(ascii_ply(tmp_path / "f.ply", ["float x", "float y", "float z"], ["1e39 0 0"]))
    good = read_ply(ascii_ply(tmp_path / "g.ply", ["float x", "float y", "float z", "uchar label", "int i"],
                              ["0.5 0 0 255 -2147483648", "1 1 1 0 2147483647"]))
    assert good.vertex["label"].tolist() == [255, 0] and good.vertex["i"].tolist() == [-2 ** 31, 2 ** 31 - 1]
    assert good.vertex["x"].dtype == np.float32


# ---- 6: the API's sweep is checked as the CLI's ------------------------------------------------

@pytest.mark.parametrize("sweep, words", [
    ((float("nan"),), r"sweep\[0\] must be a positive number of metres"),
    ((0.1, float("inf")), r"sweep\[1\]"), ((-1.0,), r"sweep\[0\]"), ((0.0,), r"sweep\[0\]"),
    (("0.1",), r"sweep\[0\]"), ("0.1", "a sequence"), (0.1, "a sequence"),
])
def test_api_sweep_is_checked(sweep, words):
    from evaluation import reconstruction_metrics, score_reconstruction

    a = Cloud(np.zeros((3, 3)), None, "a")
    with pytest.raises(InputError, match=words):
        score_reconstruction(a, a, sweep=sweep)
    with pytest.raises(InputError, match=words):
        reconstruction_metrics(a.points, a.points, sweep=sweep)


def test_api_sweep_good_values_still_score():
    from evaluation import reconstruction_metrics

    m = reconstruction_metrics(np.zeros((2, 3)), np.zeros((2, 3)), sweep=np.array([0.1, 1]))
    assert [e["tau"] for e in m["sweep"]] == [0.1, 1.0]


# ---- 7: a PLY's own label table is compared whichever way its labels come ---------------------

def test_a_plys_label_table_is_checked_with_a_separate_label_file(gt, tmp_path):
    n = len(gt[1])
    xyz = gt[1].astype(np.float32)
    labels = tmp_path / "labels.npy"
    np.save(labels, np.zeros(n, np.int64))
    for name, table in (("other.ply", ["crane", "ground", "building"]), ("same.ply", LABELS)):
        write_ply(tmp_path / name, {"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2]},
                  comments=[f"labels {json.dumps(table)}"])
    assert_refused(cli("reconstruction", "--gt", gt[0], "--pred", tmp_path / "other.ply", "--pred-labels", labels),
                   "other.ply", "label table")
    r = cli("reconstruction", "--gt", gt[0], "--pred", tmp_path / "same.ply", "--pred-labels", labels)
    assert r.returncode == 0, r.stderr[-2000:]


# ---- 8: float16 labels: no overflow warning ---------------------------------------------------

def test_float16_label_column_reads_without_warnings(tmp_path):
    table = np.column_stack([np.zeros((4, 3)), [0, 1, 2, -1]]).astype(np.float16)
    np.save(tmp_path / "half.npy", table)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cloud = read_cloud(tmp_path / "half.npy")
    assert cloud.labels.tolist() == [0, 1, 2, -1]
    np.save(tmp_path / "half_bad.npy", np.column_stack([np.zeros((1, 3)), [0.5]]).astype(np.float16))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(InputError, match="integer ids"):
            read_cloud(tmp_path / "half_bad.npy")
