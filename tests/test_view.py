"""The Rerun recordings (python -m datasets.view, evaluation --rrd) read back with Rerun's own
RRD reader (rerun.chunk.RrdReader): entities, frame timeline, poses, intrinsics, cloud sizes
and the figure-9 classes equal what the seed's files hold (read with the exporters' readers)."""

import math
import os
import subprocess
import sys
from collections import defaultdict

import numpy as np
import pyarrow as pa
import pytest
from rerun.chunk import RrdReader

from conftest import ROOT
from datasets.viewer import subsample_stride, subsampled_count
from exporters.palette import label_colors
from exporters.ply import read_ply
from exporters.tracks import read_tracks

KINDS = ("orbit", "spline")


@pytest.fixture(scope="module")
def seed_folder(finished):
    return finished[0] / "seed_000004"


def run_module(*args, env=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", *args], capture_output=True, text=True, cwd=ROOT, env=env)


def read_rrd(path) -> dict:
    """entity path -> {"static": pyarrow Table or None, "temporal": pyarrow Table or None}."""
    batches = defaultdict(lambda: defaultdict(list))
    for chunk in RrdReader(path).stream():
        batches[chunk.entity_path]["static" if chunk.is_static else "temporal"].append(chunk.to_record_batch())
    def table(parts):  # chunks of one entity may hold different components: missing ones are null
        return pa.concat_tables([pa.Table.from_batches([b]) for b in parts], promote_options="default")

    return {e: {k: (table(v) if v else None) for k, v in
                (("static", parts.get("static", [])), ("temporal", parts.get("temporal", [])))}
            for e, parts in batches.items()}


def column(table: pa.Table, name: str, sort_by: str | None = None) -> list:
    """A component column as Python values, rows sorted by a timeline (one logged value per row)."""
    if sort_by is not None:
        table = table.sort_by(sort_by)
    return [None if v is None else v[0] if len(v) == 1 else v for v in table.column(name).to_pylist()]


def column_major(values) -> np.ndarray:
    """Rerun stores 3x3 matrices column-major."""
    return np.asarray(values, np.float64).reshape(3, 3).T


@pytest.fixture(scope="module")
def rrd_path(seed_folder, tmp_path_factory):
    out = tmp_path_factory.mktemp("view") / "seed4.rrd"
    r = run_module("datasets.view", str(seed_folder), "--out", str(out), "--max-points", "300")
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.strip() == str(out)
    assert [p.name for p in out.parent.iterdir()] == ["seed4.rrd"]  # no temporary file left beside it
    return out


@pytest.fixture(scope="module")
def recording(rrd_path):
    return read_rrd(rrd_path)


def test_expected_entities_exist(recording, rrd_path):
    reader = RrdReader(rrd_path)
    assert len(reader.recordings()) == 1 and len(reader.blueprints()) == 1  # the data and its default layout
    expected = {"/world/ground_truth/points", "/world/ground_truth/mesh"}
    for kind in KINDS:
        expected |= {f"/world/{kind}/camera", f"/world/{kind}/path", f"/world/{kind}/tracks", f"/coverage/{kind}"}
        expected |= {f"/world/{kind}/camera/{name}" for name in ("rgb", "depth", "label", "instance", "tracks")}
    assert expected <= set(recording)


def test_frame_timeline_and_poses_equal_tracks_h5(recording, seed_folder):
    for kind in KINDS:
        written = read_tracks(seed_folder / kind / "tracks.h5")
        T = len(written["world_from_camera"])
        camera = recording[f"/world/{kind}/camera"]
        frames = sorted(camera["temporal"].column("frame").to_pylist())
        assert frames == list(range(T))
        for name in ("rgb", "depth", "label", "instance", "tracks"):
            assert sorted(recording[f"/world/{kind}/camera/{name}"]["temporal"].column("frame").to_pylist()) == frames
        translation = column(camera["temporal"], "Transform3D:translation", "frame")
        rotation = column(camera["temporal"], "Transform3D:mat3x3", "frame")
        for t in range(T):
            pose = written["world_from_camera"][t]
            np.testing.assert_allclose(translation[t], pose[:3, 3], rtol=0, atol=1e-4)  # float32 in Rerun
            np.testing.assert_allclose(column_major(rotation[t]), pose[:3, :3], rtol=0, atol=1e-6)
        K = column_major(column(camera["static"], "Pinhole:image_from_camera")[0])
        np.testing.assert_allclose(K, written["K"], rtol=1e-6)
        coverage = column(recording[f"/coverage/{kind}"]["temporal"], "Scalars:scalars", "frame")
        np.testing.assert_allclose(coverage, written["coverage"], rtol=0, atol=1e-12)


def test_tracks_are_the_visible_points(recording, seed_folder):
    written = read_tracks(seed_folder / "orbit" / "tracks.h5")
    offsets = written["offsets"]
    xy2d = column(recording["/world/orbit/camera/tracks"]["temporal"], "Points2D:positions", "frame")
    for t in range(len(offsets) - 1):
        expected = written["xy"][offsets[t]:offsets[t + 1]]
        got = np.asarray(xy2d[t] if len(expected) != 1 else [xy2d[t]], np.float32).reshape(-1, 2)
        np.testing.assert_array_equal(got, expected)


def test_cloud_follows_the_subsampling_rule(recording, seed_folder):
    ply = read_ply(seed_folder / "ground_truth" / "points.ply")
    n = len(ply.vertex["x"])
    k = math.ceil(n / 300)
    assert n > 300 and k > 1  # the tiny seed's cloud is larger than the cap: the rule is exercised
    table = recording["/world/ground_truth/points"]["static"]
    positions = np.asarray(table.column("Points3D:positions").to_pylist()[0], np.float32)
    assert len(positions) == subsampled_count(n, 300) == math.ceil(n / k)
    expected = np.stack([ply.vertex[c] for c in "xyz"], 1)[::k]
    np.testing.assert_array_equal(positions, expected)
    ids = np.asarray(table.column("Points3D:class_ids").to_pylist()[0])
    np.testing.assert_array_equal(ids, ply.vertex["label"][::k])
    assert subsample_stride(10, 20) == 1 and subsampled_count(10, 20) == 10


def test_class_names_are_the_label_table(recording, seed_folder):
    import json

    labels = json.loads((seed_folder / "labels.json").read_text())
    context = recording["/"]["static"].column("AnnotationContext:context").to_pylist()[0][0]
    infos = {entry["class_id"]: entry["class_description"]["info"] for entry in context}
    assert {i: infos[i]["label"] for i in range(len(labels))} == dict(enumerate(labels))
    assert infos[65535]["label"] == "unlabelled"
    colors = label_colors(labels)
    for i in range(len(labels)):  # Rerun packs colours as 0xRRGGBBAA
        rgba = infos[i]["color"]
        assert (rgba >> 24, (rgba >> 16) & 255, (rgba >> 8) & 255) == tuple(int(c) for c in colors[i])


def test_figure9_recording_classes(seed_folder, tmp_path):
    ply = read_ply(seed_folder / "ground_truth" / "points.ply")
    xyz = np.stack([ply.vertex[c] for c in "xyz"], 1).astype(np.float64)
    labels = ply.vertex["label"].astype(np.int64)
    n = len(xyz)
    from scipy.spatial import cKDTree

    isolated = cKDTree(xyz).query(xyz, k=2)[0][:, 1] > 0.002  # no other GT point within 2 mm
    removed = (np.arange(n) % 5 == 4) & isolated  # no prediction within tau = 1 mm: unmatched (2)
    relabelled = np.arange(n) % 5 == 1    # predicted with another label: wrong label (1)
    pred_labels = np.where(relabelled, (labels + 1) % (labels.max() + 1), labels)
    _, first = np.unique(xyz, axis=0, return_index=True)
    assert len(first) == n  # no duplicate points, so each kept GT point's nearest prediction is itself
    np.savetxt(tmp_path / "pred.txt", np.c_[xyz[~removed], pred_labels[~removed]], fmt="%.6f %.6f %.6f %d")
    out = tmp_path / "fig9.rrd"
    r = run_module("evaluation", "reconstruction", "--gt", str(seed_folder), "--pred", str(tmp_path / "pred.txt"),
                   "--tau", "0.001", "--rrd", str(out))
    assert r.returncode == 0, r.stderr[-2000:]
    rec = read_rrd(out)
    assert {"/world/prediction", "/world/ground_truth", "/world/figure9"} <= set(rec)
    table = rec["/world/figure9"]["static"]
    ids = [v for v in table.column("Points3D:class_ids").to_pylist() if v is not None][0]
    expected = np.where(removed, 2, np.where(relabelled & (pred_labels != labels), 1, 0))
    k = subsample_stride(n, 1_000_000)
    np.testing.assert_array_equal(ids, expected[::k])
    assert len(rec["/world/prediction"]["static"].column("Points3D:positions").to_pylist()[0]) == int((~removed).sum())


def test_not_a_seed_folder_is_one_line_and_exit_2(tmp_path):
    (tmp_path / "notes.txt").write_text("not a seed")
    out = tmp_path / "x.rrd"
    r = run_module("datasets.view", str(tmp_path), "--out", str(out))
    assert r.returncode == 2
    assert r.stderr.startswith("error: ") and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert str(tmp_path) in r.stderr and not out.exists()


@pytest.mark.parametrize("args, says", [
    (["--trajectory", "zigzag"], "zigzag"),
    (["--out", "{seed}/inside.rrd"], "inside the seed folder"),
    (["--out", "{tmp}/missing/x.rrd"], "does not exist"),
    (["--max-points", "0"], "--max-points"),
    (["--spawn"], "no display"),
])
def test_bad_arguments_are_one_line_and_exit_2(seed_folder, tmp_path, args, says):
    args = [a.format(seed=seed_folder, tmp=tmp_path) for a in args]
    if "--out" not in args and "--spawn" not in args:
        args += ["--out", str(tmp_path / "x.rrd")]
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    r = run_module("datasets.view", str(seed_folder), *args, env=env)
    assert r.returncode == 2 and says in r.stderr
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert not list(tmp_path.rglob("*.rrd")) and not list(seed_folder.glob("*.rrd"))


def test_evaluation_rrd_inside_the_seed_folder_is_refused(seed_folder, tmp_path):
    ply = read_ply(seed_folder / "ground_truth" / "points.ply")
    np.save(tmp_path / "pred.npy", np.stack([ply.vertex[c] for c in "xyz"], 1)[:100])
    r = run_module("evaluation", "reconstruction", "--gt", str(seed_folder), "--pred", str(tmp_path / "pred.npy"),
                   "--rrd", str(seed_folder / "result.rrd"))
    assert r.returncode == 2 and "--rrd" in r.stderr and r.stderr.count("\n") == 1
    assert not (seed_folder / "result.rrd").exists()
