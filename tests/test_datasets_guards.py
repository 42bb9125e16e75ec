"""The loaders' guards on real generated folders: timeline stages indexed like Python, damaged
label tables and unknown keys refused in one line where the dataset is made, no file held
open before it is read, a full descriptor table reported as such (not as damage), and
point ids that may be none."""

import json
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT

from datasets import DatasetError, Scene
from datasets.change import ChangePairDataset, Timeline
from exporters.frames import FrameReader
from exporters.modalities import MODALITIES


@pytest.fixture(scope="module")
def timeline(timeline_seed_folder):
    """A real timeline seed of 3 stages (python -m generator --phases 3), orbit only (conftest)."""
    return timeline_seed_folder


def test_a_stage_is_indexed_like_python(timeline):
    tl = Timeline(timeline)
    last = tl.sequence(-1, "orbit")
    assert last.folder == timeline / "phase_2" / "orbit" and last is tl.sequence(2, "orbit")
    written = FrameReader(timeline / "phase_2" / "orbit").read(0, ["depth"])
    np.testing.assert_array_equal(last[0].depth, written["depth"])
    assert tl.sequence(-3, "orbit").folder == timeline / "phase_0" / "orbit"
    with pytest.raises(IndexError, match=r"^stage index -4 out of range: valid indices are -3\.\.2$"):
        tl.sequence(-4, "orbit")


def test_a_damaged_or_missing_label_table_is_one_line(timeline, tmp_path):
    copy = tmp_path / timeline.name
    shutil.copytree(timeline, copy)
    labels = copy / "phase_0" / "labels.json"
    labels.write_text('["ground", "wall"')  # cut short
    damaged = rf"^{re.escape(str(labels))}: damaged file \(its sha256 differs from the seed's manifest\)"
    with pytest.raises(DatasetError, match=damaged):
        Timeline(copy)
    r = subprocess.run([sys.executable, "-m", "datasets.view", str(copy / "phase_1"), "--out", str(tmp_path / "x.rrd")],
                       capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr[-2000:]
    assert f"error: {labels}: damaged file" in r.stderr and not (tmp_path / "x.rrd").exists()
    labels.write_text(json.dumps({"ground": 0}))  # valid JSON, not a label table: its bytes are not the manifest's
    with pytest.raises(DatasetError, match=damaged):
        Timeline(copy)
    labels.unlink()
    with pytest.raises(DatasetError, match=rf"^{re.escape(str(labels))}: missing; the seed folder is incomplete"):
        ChangePairDataset(copy)


def test_change_pairs_check_keys_and_trajectories_when_made(timeline):
    everything = ChangePairDataset(timeline)
    one = ChangePairDataset(timeline, trajectories="orbit", keys="depth")
    assert len(one) == len(everything) == 2 * 3  # pairs (0, 1) and (1, 2), 3 frames each
    item = one[-1]
    assert set(item["before"]) & set(MODALITIES) == set(item["after"]) & set(MODALITIES) == {"depth"}
    np.testing.assert_array_equal(item["after"]["depth"], everything[-1]["after"]["depth"])
    with pytest.raises(DatasetError, match=rf"^{re.escape(str(timeline / 'phase_0' / 'orbit'))}: no modality bogus "
                                          r"\(written: rgb, "):
        ChangePairDataset(timeline, keys=("depth", "bogus"))
    with pytest.raises(DatasetError, match=rf"^{re.escape(str(timeline))}: no trajectory 'lawnmower' \(has orbit\)$"):
        ChangePairDataset(timeline, trajectories=["lawnmower"])
    with pytest.raises(DatasetError) as err:
        ChangePairDataset(timeline, trajectories="spline")
    assert not isinstance(err.value, KeyError)


def test_point_positions_of_no_ids(seed_folder):
    seq = Scene(seed_folder)["orbit"]
    some = seq.point_positions(-1, seq.visible_tracks(-1)["ids"][:3])
    for none in ([], np.array([], np.int32), ()):
        got = seq.point_positions(-1, none)
        assert got.shape == (0, 3) and got.dtype == some.dtype == np.float64
    with pytest.raises(IndexError, match="point ids must be integers"):
        seq.point_positions(0, [0.5])


# In a fresh process: 20 copies of a seed (40 trajectories) are opened under a limit of 16
# descriptors beyond those already open, and read; then the table is filled and every reader
# says so (not "damaged file").
_DESCRIPTORS = """
import os, resource, sys
from pathlib import Path
from datasets import FrameDataset, Scene
from exporters.frames import FrameReader

copies = sorted(Path(sys.argv[1]).iterdir())
Scene(copies[0])["orbit"].read(0), Scene(copies[0])["orbit"].visible_tracks(0)  # imports done, codecs loaded
before = len(os.listdir("/proc/self/fd"))
resource.setrlimit(resource.RLIMIT_NOFILE, (before + 16, resource.getrlimit(resource.RLIMIT_NOFILE)[1]))
ds = FrameDataset(copies, keys=("depth", "rgb"))
held = len(os.listdir("/proc/self/fd")) - before
assert len(ds) == 6 * len(copies) and ds[0]["depth"].shape == ds[-1]["depth"].shape == (32, 48)
print("held", held)
scene = Scene(copies[1])
seq = scene["orbit"]
fill = []
try:
    while True:
        fill.append(os.open(os.devnull, os.O_RDONLY))
except OSError:
    pass
for name, call in (("tracks.h5 header", lambda: scene["spline"]), ("tracks.h5 read", lambda: seq.visible_tracks(0)),
                   ("frame EXR", lambda: seq.read(0, ["depth"])), ("frame PNG", lambda: seq.read(0, ["rgb"])),
                   ("frames.json", lambda: FrameReader(seq.folder))):
    try:
        call()
        print(name, "ok")
    except Exception as exc:
        print(name, type(exc).__name__, exc)
"""


def test_no_file_is_held_open_before_it_is_read_and_a_full_table_is_no_damage(seed_folder, tmp_path):
    for k in range(20):  # real copies: HDF5 shares one descriptor among opens of the same file
        shutil.copytree(seed_folder, tmp_path / "copies" / f"seed_{k:06d}",
                        ignore=shutil.ignore_patterns("scene", "ground_truth"))
    r = subprocess.run([sys.executable, "-c", _DESCRIPTORS, str(tmp_path / "copies")], capture_output=True, text=True,
                       cwd=ROOT, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr[-3000:]
    lines = r.stdout.strip().splitlines()
    assert lines[0] == "held 0", lines
    assert len(lines) == 6 and not any(line.endswith(" ok") or "damaged file" in line for line in lines), lines
    for line in lines[1:]:
        assert re.search(r"(DatasetError|AccessError) /\S+: cannot read it \(Too many open files; the file itself is "
                         r"not damaged\); raise this process's open-file limit \(ulimit -n\)", line), line
    assert lines[-1].startswith("frames.json AccessError") and "frames.json" in lines[-1]


_FORKED = """
import multiprocessing as mp, sys
import numpy as np
from datasets import ClipDataset
clips = ClipDataset(sys.argv[1], length=2)
def tracks(i):
    t = clips[i]["tracks"]
    return t["ids"].tolist(), t["xy"].tolist(), t["visible"].tolist()
expected = [tracks(i) for i in range(len(clips))]  # tracks.h5 open in this process now
with mp.get_context("fork").Pool(2) as pool:
    got = pool.map_async(tracks, list(range(len(clips))) * 2).get(timeout=120)
print("same" if got == expected * 2 else "differ")
"""


def test_forked_workers_read_tracks_opened_in_the_parent(seed_folder):
    """DataLoader's default start method on Linux is fork: each worker opens tracks.h5 itself,
    even when the parent has it open. In a fresh process (this one runs open3d's threads)."""
    r = subprocess.run([sys.executable, "-c", _FORKED, str(seed_folder)], capture_output=True, text=True, cwd=ROOT,
                       timeout=300)
    assert r.returncode == 0 and r.stdout.strip() == "same", r.stdout + r.stderr[-2000:]
