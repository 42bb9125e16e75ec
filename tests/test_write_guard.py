"""Issue #36, items 1 and 10: every path the tools write outside a seed goes through one guard
(exporters.write_guard): never inside a generated dataset (a seed, a timeline seed, a stage, a
folder being generated), never over a file the project did not write, never a traceback when
the disk refuses the bytes. Real seeds from the real pipeline, real processes."""

import hashlib
import json
import os
import resource
import shutil
import signal
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from conftest import ROOT, assert_refused, run_evaluation
from exporters.manifest import PARTIAL_MARKER, verify_manifest
from exporters.ply import read_ply, write_ply
from exporters.write_guard import (FOLDER_MARKER, SIGNATURE, WriteRefused, check_output_file, claim_folder, is_ours,
                                   signed_json)


def tree_state(folder):
    """{relative path: sha256} of every file under ``folder``."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def stage_pred(timeline_seed_folder, tmp_path_factory):
    """A predicted cloud: the first 500 ground-truth points of stage 0."""
    path = tmp_path_factory.mktemp("pred") / "p.npy"
    np.save(path, read_ply(timeline_seed_folder / "phase_0" / "ground_truth" / "points.ply").points[:500])
    return path


def test_evaluation_never_writes_into_a_timeline_seed(timeline_seed_folder, seed_folder, stage_pred, tmp_path):
    """The issue's case 1 and its variants: over changes.h5 or a manifest, a new file at the
    seed's top, in a stage, in another seed, in a folder being generated; every output flag.
    On copies of the shared seeds (code that failed this test would damage them)."""
    seed, plain = tmp_path / "timeline" / timeline_seed_folder.name, tmp_path / "plain" / seed_folder.name
    shutil.copytree(timeline_seed_folder, seed)
    shutil.copytree(seed_folder, plain)
    seed_folder = plain
    partial = tmp_path / ".seed_000009.partial"
    partial.mkdir()
    (partial / PARTIAL_MARKER).write_text("")
    rec = ["reconstruction", "--gt", seed / "phase_0", "--pred", stage_pred]
    targets = [("--json", seed / "changes.h5"), ("--json", seed / "manifest.json"), ("--json", seed / "r.json"),
               ("--json", seed / "phase_1" / "r.json"), ("--ply", seed / "phase_1" / "orbit" / "fig9.ply"),
               ("--json", seed_folder / "manifest.json"), ("--rrd", seed_folder / "orbit" / "m.rrd"),
               ("--json", partial / "r.json")]
    before = {s: tree_state(s) for s in (seed, seed_folder, partial)}
    for flag, target in targets:
        assert_refused(run_evaluation(*rec, flag, target), flag, "lies inside the generated seed folder")
    change = ["change", "--gt", seed, "--stages", 0, 1, "--pred", stage_pred]
    assert_refused(run_evaluation(*change, "--json", seed / "phase_0" / "c.json"), "generated seed folder")
    assert {s: tree_state(s) for s in before} == before  # not one byte changed, nothing added
    assert verify_manifest(seed) == [] and verify_manifest(seed_folder) == []


def test_outputs_never_replace_a_file_the_project_did_not_write(seed_folder, tmp_path):
    pred = tmp_path / "pred.npy"
    np.save(pred, read_ply(seed_folder / "ground_truth" / "points.ply").points[:300])
    users = {"--json": ("paper.json", b'{"my": "results"}'),
             "--ply": ("scan.ply", b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nend_header\n"),
             "--rrd": ("mine.rrd", b"RRF2 someone else's recording")}
    rec = ["reconstruction", "--gt", seed_folder, "--pred", pred]
    for flag, (name, data) in users.items():
        (tmp_path / name).write_bytes(data)
        assert_refused(run_evaluation(*rec, flag, tmp_path / name), flag, "was not written by this project")
        assert (tmp_path / name).read_bytes() == data
    photo = tmp_path / "photo.png"
    Image.new("RGB", (4, 4), "red").save(photo)
    walk = seed_folder / "orbit" / "trajectory.npz"
    cov = ["coverage", "--gt", seed_folder, "--trajectory", walk]
    assert_refused(run_evaluation(*cov, "--plot", photo), "--plot", "was not written by this project")
    # the project's own outputs are replaced by a rerun: every kind carries its signature
    ours = {"--json": tmp_path / "r.json", "--ply": tmp_path / "fig9.ply", "--rrd": tmp_path / "m.rrd"}
    for _ in range(2):
        r = run_evaluation(*rec, *[a for kv in ours.items() for a in map(str, kv)])
        assert r.returncode == 0, r.stderr
        r = run_evaluation(*cov, "--plot", tmp_path / "c.png", "--json", tmp_path / "c.json")
        assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "r.json").read_text())["written_by"] == SIGNATURE
    for path, kind in [(tmp_path / "r.json", "json"), (tmp_path / "fig9.ply", "ply"), (tmp_path / "m.rrd", "rrd"),
                       (tmp_path / "c.png", "png")]:
        assert is_ours(path, kind), path
    assert not is_ours(photo, "png") and not is_ours(tmp_path / "paper.json", "json")


def test_the_guard_refuses_links_folders_devices_and_inputs(tmp_path):
    user = tmp_path / "user.json"
    user.write_text(json.dumps(signed_json({"a": 1})))
    link = tmp_path / "link.json"
    link.symlink_to(user)
    cases = [(tmp_path, "is a folder"), (link, "not a regular file"), ("/dev/null", "not a regular file"),
             (tmp_path / "no" / "r.json", "does not exist"), ("/proc/r.json", "cannot write in /proc")]
    for path, words in cases:
        with pytest.raises(WriteRefused, match=words):
            check_output_file(path, "--json", "json")
    with pytest.raises(WriteRefused, match="is an input"):
        check_output_file(user, "--json", "json", inputs=(user,))
    with pytest.raises(WriteRefused, match="inside the input folder"):
        check_output_file(tmp_path / "r.json", "--json", "json", inputs=(tmp_path,))
    check_output_file(user, "--json", "json")  # signed by the project: may be replaced


def view_limited(seed, out, max_bytes):
    """``python -m datasets.view SEED --out OUT`` whose process may not write files past
    ``max_bytes`` (RLIMIT_FSIZE): what a full disk does to it."""
    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails (EFBIG) instead of killing
        resource.setrlimit(resource.RLIMIT_FSIZE, (max_bytes, max_bytes))

    return subprocess.run([sys.executable, "-m", "datasets.view", str(seed), "--out", str(out)], capture_output=True,
                          text=True, cwd=ROOT, preexec_fn=limit, timeout=300)


def test_the_viewer_reports_write_failures_in_one_line(seed_folder, timeline_seed_folder, tmp_path):
    """The issue's case 10: a place nothing can be written to, a write cut short, a user's
    recording, a stage of a timeline seed: one error line, exit 2, nothing left behind."""
    warm = subprocess.run([sys.executable, "-m", "datasets.view", str(seed_folder), "--out", str(tmp_path / "ok.rrd")],
                          capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert warm.returncode == 0, warm.stderr[-2000:]  # and numba's and Python's caches are written (not under the limit)
    (tmp_path / "ok.rrd").unlink()
    out = tmp_path / "seed.rrd"
    r = view_limited(seed_folder, out, 20_000)
    errors = [line for line in r.stderr.splitlines() if line.startswith("error:")]
    assert r.returncode == 2 and "Traceback" not in r.stderr and "ERROR" not in r.stderr, r.stderr[-2000:]
    assert errors == [r.stderr.strip().splitlines()[-1]] and "cannot write it" in errors[0], r.stderr[-2000:]
    assert os.listdir(tmp_path) == []  # no recording, no temporary file
    mine = tmp_path / "mine.rrd"
    mine.write_bytes(b"RRF2 not ours")
    for target, words in [("/proc/x.rrd", "cannot write in /proc"), (mine, "was not written by this project"),
                          (timeline_seed_folder / "phase_1" / "v.rrd", "generated seed folder")]:
        r = subprocess.run([sys.executable, "-m", "datasets.view", str(seed_folder), "--out", str(target)],
                           capture_output=True, text=True, cwd=ROOT, timeout=300)
        assert_refused(r, words)
    assert mine.read_bytes() == b"RRF2 not ours"


def test_a_folder_tool_claims_only_new_empty_or_its_own_folders(tmp_path, seed_folder):
    """generator.baselines and generator.scene write sets of files into --out: a folder holding
    a user's file, another tool's outputs, or an output changed since is refused before any
    work; after a completed run, the tool's own files may be replaced."""
    tool = "python -m generator.baselines"
    out = tmp_path / "run"
    claimed = claim_folder(out, "--out", tool)  # new: created
    (out / "exploration.json").write_text("{}")
    (out / "site_0").mkdir()
    (out / "site_0" / "walk.npz").write_bytes(b"x")
    claimed.seal()
    claim_folder(out, "--out", tool).seal()  # a rerun over its own files
    (out / "site_0" / "walk.npz").write_bytes(b"y")  # changed since
    with pytest.raises(WriteRefused, match="site_0/walk.npz was not written by"):
        claim_folder(out, "--out", tool)
    (out / "site_0" / "walk.npz").write_bytes(b"x")
    (out / "notes.txt").write_text("mine")  # a user's file added
    with pytest.raises(WriteRefused, match="notes.txt was not written by"):
        claim_folder(out, "--out", tool)
    with pytest.raises(WriteRefused, match="holds the outputs of"):
        claim_folder(out, "--out", "python -m generator.scene")
    users = tmp_path / "users"
    users.mkdir()
    (users / "thesis.tex").write_text("x")
    with pytest.raises(WriteRefused, match="holds files this project did not write"):
        claim_folder(users, "--out", tool)
    with pytest.raises(WriteRefused, match="generated seed folder"):
        claim_folder(seed_folder / "baselines", "--out", tool)
    assert not (seed_folder / "baselines").exists()
    # a run that did not finish: its files are taken as the tool's by the next run
    killed = tmp_path / "killed"
    claim_folder(killed, "--out", tool)
    (killed / "trajectory.npz").write_bytes(b"half")
    claim_folder(killed, "--out", tool).seal()
    assert json.loads((killed / FOLDER_MARKER).read_text())["files"]["trajectory.npz"]["bytes"] == 4


@pytest.mark.parametrize("module", ["generator.baselines", "generator.scene"])
def test_folder_tools_refuse_a_users_folder_before_any_work(module, tmp_path):
    (tmp_path / "thesis.tex").write_text("mine")
    args = ["exploration", "--seeds", "0", "--out", tmp_path] if module == "generator.baselines" else [
        "--seed", "0", "--out", tmp_path]
    r = subprocess.run([sys.executable, "-m", module, *map(str, args)], capture_output=True, text=True, cwd=ROOT,
                       timeout=120)
    assert_refused(r, "holds files this project did not write")
    assert sorted(os.listdir(tmp_path)) == ["thesis.tex"]


def test_ply_and_json_writers_sign_what_they_write(tmp_path):
    path = write_ply(tmp_path / "a.ply", {"x": np.zeros(2, np.float32), "y": np.zeros(2, np.float32),
                                          "z": np.zeros(2, np.float32)})
    assert read_ply(path).comments[0] == f"written by {SIGNATURE}" and is_ours(path, "ply")
    assert list(signed_json({"task": 1, "written_by": "x"})) == ["written_by", "task"]
    shutil.copy(path, tmp_path / "b.json")
    assert not is_ours(tmp_path / "b.json", "json")  # a signature of another kind does not count
