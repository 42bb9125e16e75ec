"""Seeds made otherwise than the default, recorded with python -m datasets.view and read back
with Rerun's own RRD reader: with --outputs leaving modalities out, and one stage of a
timeline seed (--phases)."""

import numpy as np
import pytest

pytestmark = pytest.mark.pipeline  # every test views a seed made by the batch job
from rerun.chunk import RrdReader

from conftest import ROOT, run_generator
from datasets.viewer import subsample_stride, subsampled_count
from exporters.ply import read_ply
from exporters.tracks import read_tracks
from recordings import STRICT, blueprint_views, column, read_rrd, view


@pytest.fixture(scope="module", params=["rgb", "depth"])
def partial_seed(request, tmp_path_factory):
    """A seed made with --outputs leaving most modalities out."""
    out = tmp_path_factory.mktemp(f"only_{request.param}")
    r = run_generator(out, "--seeds", "4", "--trajectory", "orbit", "--outputs", request.param)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    return request.param, out / "seed_000004"


def test_a_seed_with_some_outputs_is_viewed(partial_seed, tmp_path):
    only, folder = partial_seed
    out = tmp_path / "partial.rrd"
    r = view(folder, "--out", out)
    assert r.returncode == 0, r.stderr[-2000:]
    rec = read_rrd(out)
    images = {e.rsplit("/", 1)[1] for e in rec if e.startswith("/world/orbit/camera/")} - {"tracks"}
    assert images == {only}
    written = read_tracks(folder / "orbit" / "tracks.h5")
    frames = list(range(len(written["world_from_camera"])))
    for entity in ("/world/orbit/camera", f"/world/orbit/camera/{only}", "/world/orbit/camera/tracks",
                   "/world/orbit/tracks", "/coverage/orbit"):
        assert sorted(rec[entity]["temporal"].column("frame").to_pylist()) == frames, entity
    translation = column(rec["/world/orbit/camera"]["temporal"], "Transform3D:translation", "frame")
    np.testing.assert_allclose(translation, written["world_from_camera"][:, :3, 3], rtol=0, atol=1e-4)
    xy2d = column(rec["/world/orbit/camera/tracks"]["temporal"], "Points2D:positions", "frame")
    assert sum(len(v) for v in xy2d) == len(written["xy"])
    n = len(read_ply(folder / "ground_truth" / "points.ply").vertex["x"])
    points = rec["/world/ground_truth/points"]["static"].column("Points3D:positions").to_pylist()[0]
    assert len(points) == subsampled_count(n, 1_000_000)
    for v in blueprint_views(out):  # the 2D views name only what was logged
        if v["class"] == "2D":
            assert {q.removeprefix("$origin/") for q in v["query"]} <= images | {"tracks"}, v


@pytest.fixture(scope="module")
def timeline_seed(timeline_seed_folder):
    """The session's timeline seed (conftest: seed 1, 3 stages, orbit only)."""
    return timeline_seed_folder


def test_one_stage_of_a_timeline_is_viewed(timeline_seed, tmp_path):
    r = view(timeline_seed / "phase_1", cwd=tmp_path, env=STRICT | {"PYTHONPATH": str(ROOT)})  # default --out: here
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.strip() == "seed_000001_phase_1.rrd"  # the default name says which stage
    out = tmp_path / "seed_000001_phase_1.rrd"
    assert [s.recording_id for s in RrdReader(out).recordings()] == ["seed_000001_phase_1"]
    rec = read_rrd(out)
    stage = {k: read_ply(timeline_seed / f"phase_{k}" / "ground_truth" / "points.ply").vertex for k in (0, 1)}
    xyz = {k: np.stack([v[c] for c in "xyz"], 1) for k, v in stage.items()}
    assert xyz[0].shape != xyz[1].shape or not np.array_equal(xyz[0], xyz[1])  # the stages differ
    k = subsample_stride(len(xyz[1]), 1_000_000)
    points = rec["/world/ground_truth/points"]["static"].column("Points3D:positions").to_pylist()[0]
    np.testing.assert_array_equal(np.asarray(points, np.float32), xyz[1][::k])
    written = read_tracks(timeline_seed / "phase_1" / "orbit" / "tracks.h5")
    coverage = column(rec["/coverage/orbit"]["temporal"], "Scalars:scalars", "frame")
    np.testing.assert_allclose(coverage, written["coverage"], rtol=0, atol=1e-12)
    xy2d = column(rec["/world/orbit/camera/tracks"]["temporal"], "Points2D:positions", "frame")
    np.testing.assert_array_equal(np.concatenate([np.asarray(v, np.float32).reshape(-1, 2) for v in xy2d]),
                                  written["xy"])


def test_a_timeline_seed_folder_names_the_stage_to_view(timeline_seed, tmp_path):
    r = view(timeline_seed, "--out", tmp_path / "x.rrd")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert f"python -m datasets.view {timeline_seed / 'phase_K'} (K = 0 to 2)" in r.stderr
    assert not (tmp_path / "x.rrd").exists()
