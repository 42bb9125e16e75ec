"""The batch job end to end, in real processes, on tiny configurations."""

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from exporters.exr import read_frame_exr
from exporters.manifest import read_manifest, verify_manifest
from conftest import ROOT, TINY
from conftest import run_generator as run
from trajectories import Trajectory


def test_seed_folder_is_complete_and_matches_its_manifest(finished):
    out, r = finished
    folder = out / "seed_000004"
    assert verify_manifest(folder) == []
    manifest = read_manifest(folder)
    assert manifest["seed"] == 4 and manifest["config"]["frames"] == 3 and manifest["versions"]["bpy"]
    labels = json.loads((folder / "labels.json").read_text())
    for kind in ("orbit", "spline"):
        traj = Trajectory.load(folder / kind / "trajectory.npz")
        assert len(traj) == 3 and traj.kind == kind
        for i in range(3):
            f = read_frame_exr(folder / kind / f"frame_{i:06d}.exr")
            assert f["depth"].shape == (32, 48) and f["label"].max() < len(labels)
            png = np.asarray(Image.open(folder / kind / f"rgb_{i:06d}.png"))
            assert png.shape == (32, 48, 3) and f["rgb_linear"].shape == (32, 48, 3)
            assert np.isfinite(f["rgb_linear"]).all() and png.std() > 0  # the PNG from the EXR: tests/test_modalities.py
        # COLMAP model: poses equal the trajectory's, keypoints are exact projections
        from generator.geometry.camera import project
        import pycolmap

        rec = pycolmap.Reconstruction(str(folder / kind / "sparse" / "0"))
        assert rec.num_reg_images() == 3 and rec.num_points3D() > 10
        cam = rec.cameras[1]
        K = np.array([[cam.params[0], 0, cam.params[2]], [0, cam.params[1], cam.params[3]], [0, 0, 1]])
        for image in rec.images.values():
            t = int(image.name[4:10])
            m = np.eye(4)
            m[:3, :4] = image.cam_from_world().matrix()
            np.testing.assert_allclose(np.linalg.inv(m), traj.poses[t], atol=1e-6)
            for p2d in image.points2D:
                if p2d.has_point3D():
                    uv, _ = project(rec.points3D[p2d.point3D_id].xyz[None], traj.poses[t], K)
                    assert np.linalg.norm(uv[0] - p2d.xy) < 0.01
        assert all(p.track.length() >= 2 for p in rec.points3D.values())
        _check_tracks(folder / kind, traj)
        cov = json.loads((folder / kind / "coverage.json").read_text())["coverage"]
        assert len(cov) == 3 and all(b >= a for a, b in zip(cov, cov[1:]))
    assert (folder / "scene" / "site.blend").is_file() and (folder / "blender.log").is_file()
    assert not list(out.glob(".seed_*"))
    assert "seed 4: 6 frames" in r.stdout and "Read blend" not in r.stdout  # Blender's log stays out


def _check_tracks(folder, traj):
    from exporters.tracks import read_tracks, world_positions
    from generator.geometry.camera import project

    d = read_tracks(folder / "tracks.h5")
    T = len(traj)
    np.testing.assert_allclose(d["world_from_camera"], traj.poses)
    np.testing.assert_allclose(d["timestamps"], traj.timestamps)
    assert len(d["offsets"]) == T + 1 and d["offsets"][-1] == len(d["index"]) > 0
    edge_ok = total = 0
    for t in range(T):
        sl = slice(d["offsets"][t], d["offsets"][t + 1])
        ids = d["index"][sl]
        pos = world_positions(d, t, ids)
        xy, z = project(pos, d["world_from_camera"][t], d["K"])
        np.testing.assert_allclose(d["xy"][sl], xy, atol=1e-3)  # stored pixels are projections
        np.testing.assert_allclose(d["depth"][sl], z, rtol=1e-5)
        depth = read_frame_exr(folder / f"frame_{t:06d}.exr")["depth"]
        # a point inside a pixel lies between the depths of the surrounding pixel centres;
        # pixels next to "no surface" (sky, beyond the ground's edge) span depths up to the
        # horizon and are edges, excluded as in test_render.py
        h, w = depth.shape
        pad = np.pad(depth, 1, mode="edge")
        neigh = np.stack([pad[1 + di: 1 + di + h, 1 + dj: 1 + dj + w] for di in (-1, 0, 1) for dj in (-1, 0, 1)])
        edge = ~np.all(np.isfinite(neigh), axis=0)
        lo, hi = np.min(neigh, axis=0), np.max(neigh, axis=0)
        px = np.floor(xy).astype(int)
        keep = ~edge[px[:, 1], px[:, 0]]
        agree = (z >= 0.98 * lo[px[:, 1], px[:, 0]]) & (z <= 1.02 * hi[px[:, 1], px[:, 0]])
        agree, total = agree[keep], total + keep.sum()
        # at 48x32, visible points on sub-pixel structures (fence wire, scaffold tubes, rebar)
        # sit in pixels whose centre sees what is behind them; the 99% agreement at useful
        # resolutions is tested in test_render.py
        assert agree.mean() >= 0.9, f"frame {t}: {agree.mean():.3f} of visible points agree with the depth map"
        edge_ok += agree.sum()
        # dynamic points: stored positions follow their object's matrix
        dyn = d["dynamic_ids"]
        np.testing.assert_allclose(d["dynamic_positions"][t], world_positions(d, t, dyn), atol=1e-3)
    assert edge_ok >= 0.95 * total
    tv = d["tapvid"]
    q = len(tv["point_ids"])
    assert q > 0 and tv["tracks"].shape == (q, T, 2) and tv["occluded"].shape == (q, T) and tv["tracks_3d"].shape == (q, T, 3)
    for k, p in enumerate(tv["point_ids"]):
        for t in range(T):
            sl = slice(d["offsets"][t], d["offsets"][t + 1])
            hit = np.flatnonzero(d["index"][sl] == p)
            assert tv["occluded"][k, t] == (len(hit) == 0)
            if len(hit):
                np.testing.assert_allclose(tv["tracks"][k, t], d["xy"][sl][hit[0]], atol=1e-3)
        t0 = int(tv["query_points"][k, 0])
        assert not tv["occluded"][k, t0] and tv["occluded"][k, :t0].all()
        np.testing.assert_allclose(tv["query_points"][k, 1:], tv["tracks"][k, t0, ::-1], atol=1e-3)


def test_rerun_skips_finished_seeds(finished):
    out, _ = finished
    before = (out / "seed_000004" / "manifest.json").stat().st_mtime_ns
    r = run(out, "--seeds", "4", "--colmap-text")
    assert r.returncode == 0 and "seed 4: already complete (sizes checked), skipped" in r.stdout
    assert (out / "seed_000004" / "manifest.json").stat().st_mtime_ns == before


def test_same_seed_gives_identical_arrays(finished, tmp_path):
    out, _ = finished
    r = run(tmp_path, "--seeds", "4", "--colmap-text")
    assert r.returncode == 0
    a, b = read_manifest(out / "seed_000004")["files"], read_manifest(tmp_path / "seed_000004")["files"]
    assert a.keys() == b.keys()
    for rel in a:
        if rel.endswith((".log", ".blend")):
            continue  # Blender's log has timings; .blend bytes are checked through site.json and the frames
        if a[rel]["sha256"] != b[rel]["sha256"]:
            assert rel.endswith(".exr"), f"{rel} differs between two runs"
            fa, fb = read_frame_exr(out / "seed_000004" / rel), read_frame_exr(tmp_path / "seed_000004" / rel)
            assert fa.keys() == fb.keys()
            for key in fa.keys() - {"header"}:
                np.testing.assert_array_equal(fa[key], fb[key])


@pytest.mark.pipeline
def test_failed_seed_is_reported_and_others_finish(tmp_path):
    r = run(tmp_path, "--seeds", "5", "6", env_extra={"BUILDEE_FAIL_SEEDS": "5"})
    assert r.returncode == 1
    assert "seed 5: FAILED" in r.stdout and "failed on purpose" in r.stdout
    assert read_manifest(tmp_path / "seed_000006") is not None
    assert not (tmp_path / "seed_000005").exists()  # never marked complete
    r2 = run(tmp_path, "--seeds", "5", "6", "--shard", "1/2")  # the shard holds only seed 6
    assert r2.returncode == 0 and "seed 6: already complete" in r2.stdout and "seed 5" not in r2.stdout


HOLD_WORK_LOCK = """
import subprocess, sys
from pathlib import Path
from generator.batch import folders
lock = folders.SeedLock.wait_for_work(Path(sys.argv[1]), int(sys.argv[2]), 0)
child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"], pass_fds=(lock.fd,),
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
print(child.pid, flush=True)  # and exit at once, without releasing: the child holds the lock on
"""


@pytest.mark.pipeline
def test_an_attempt_waits_for_the_worker_of_an_earlier_one_before_touching_the_seed(tmp_path):
    """The worker of an earlier attempt that outlives the process that started it, holding the
    seed's work lock it inherited (as a Ray task's worker does for 1-3 s after its driver is
    killed with SIGKILL, when the driver's own lock is already released), keeps a new run away
    from the seed's partial folder until it has exited; then the new run redoes the seed
    (docs/scale.md)."""
    from exporters.manifest import PARTIAL_MARKER
    from generator.batch import folders

    env = {k: v for k, v in os.environ.items() if k != "OCIO"}
    partial, _ = folders.start_partial(tmp_path, 5)  # the earlier attempt's partial folder
    marker = (partial / PARTIAL_MARKER).read_text()
    held = subprocess.run([sys.executable, "-c", HOLD_WORK_LOCK, str(tmp_path), "5"], cwd=ROOT, env=env,
                          capture_output=True, text=True, check=True)
    orphan = int(held.stdout)
    try:
        run_ = subprocess.Popen([sys.executable, "-m", "generator", "--out", str(tmp_path), *TINY, "--seeds", "5"],
                                cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        deadline = time.time() + 60
        while not folders.lock_file(tmp_path, 5).exists():  # the new run has claimed the seed
            assert time.time() < deadline and run_.poll() is None, "the new run never claimed the seed"
            time.sleep(0.02)
        until = time.time() + 3.0  # it is now waiting for the work lock: the old folder stays as it was
        while time.time() < until:
            assert (partial / PARTIAL_MARKER).read_text() == marker and run_.poll() is None
            time.sleep(0.02)
    finally:
        os.kill(orphan, signal.SIGKILL)
    stdout, stderr = run_.communicate(timeout=300)
    assert run_.returncode == 0, stderr[-2000:]
    assert "seed 5: unfinished output from an earlier run removed; redoing it" in stdout
    assert verify_manifest(tmp_path / "seed_000005") == []
    assert not list(tmp_path.glob(".seed_*"))  # partial folder and both lock files gone


PRODUCE_AND_WAIT_FOR_SIGTERM = """
import json, signal, sys, time
from generator.batch.config import RunConfig
from generator.batch.executors.seed import SeedJob, produce_seed
signal.signal(signal.SIGTERM, lambda *a: sys.exit(143))  # what a Ray worker process does
config = RunConfig("small", resolution=(48, 32), frames=40, points_density=0.3, scoring_density=5).to_dict()
try:
    produce_seed(SeedJob(6, sys.argv[1], config), lambda e: print(json.dumps(e), flush=True))
except SystemExit:  # a process that lives on after its task ended: its worker must not
    print("ended", flush=True)
    time.sleep(60)
"""


@pytest.mark.pipeline
def test_a_seed_ended_by_sigterm_leaves_no_worker_behind_its_work_lock(tmp_path):
    """produce_seed stopped by an exception (Ray turns SIGTERM into SystemExit) kills its worker
    process before it lets go of the seed's work lock, so no worker writes on unprotected."""
    env = {k: v for k, v in os.environ.items() if k != "OCIO"}
    proc = subprocess.Popen([sys.executable, "-c", PRODUCE_AND_WAIT_FOR_SIGTERM, str(tmp_path)], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert '"start"' in proc.stdout.readline() or '"start"' in proc.stdout.readline()  # the worker is under way
    workers = [int(d.name) for d in Path("/proc").iterdir() if d.name.isdigit() and _is_worker_of(d, tmp_path)]
    assert len(workers) == 1
    proc.send_signal(signal.SIGTERM)
    try:
        while (line := proc.stdout.readline()) and line.strip() != "ended":
            pass
        assert line.strip() == "ended", proc.stderr.read()[-2000:]
        # the process lives on, its work lock released: its worker must be gone already
        assert not (tmp_path / ".seed_000006.work.lock").exists()
        stat = Path(f"/proc/{workers[0]}/stat")
        assert not stat.exists() or stat.read_text().rsplit(")", 1)[1].split()[0] == "Z", "the worker outlived its lock"
    finally:
        proc.kill()
        proc.wait()


def _is_worker_of(proc_dir: Path, out: Path) -> bool:
    try:
        argv = (proc_dir / "cmdline").read_bytes().decode(errors="replace").split("\0")
    except OSError:
        return False
    return argv[1:3] == ["-m", "generator.batch.worker"] and len(argv) > 5 and argv[5].startswith(f"{out}/")


@pytest.mark.pipeline
def test_killed_run_resumes(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "OCIO"}
    args = [sys.executable, "-m", "generator", "--out", str(tmp_path), *TINY, "--frames", "12", "--trajectory", "orbit",
            "--seeds", "8", "9"]
    proc = subprocess.Popen(args, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    deadline = time.time() + 240
    while time.time() < deadline:  # wait until seed 8 is done and seed 9 is under way
        if (tmp_path / "seed_000008").exists() and list((tmp_path / ".seed_000009.partial").glob("*/frame_*.exr")):
            break
        time.sleep(0.2)
    else:
        proc.kill()
        pytest.fail("the run never reached the second seed")
    os.killpg(proc.pid, signal.SIGKILL)  # a real kill: no cleanup in the runner
    proc.wait()
    time.sleep(1.0)  # the worker dies with its parent
    assert (tmp_path / ".seed_000009.partial").exists() and not (tmp_path / "seed_000009").exists()
    r = subprocess.run(args, cwd=ROOT, env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "seed 8: already complete" in r.stdout
    assert "seed 9: unfinished output from an earlier run removed; redoing it" in r.stdout
    assert verify_manifest(tmp_path / "seed_000009") == []
    assert not list(tmp_path.glob(".seed_*"))  # partial folder and lock files gone


def test_a_worker_whose_runner_died_during_its_start_up_exits_before_working(tmp_path):
    """A runner killed while its worker's interpreter was still starting (before the worker
    could ask to die with it) leaves the worker to init: it must notice and exit (3) without
    touching the seed's folder, not run on as an orphan. Control: the same worker with its
    true parent named goes on to the seed (and fails there on a bad configuration)."""
    from generator.batch.executors.seed import PARENT_ENV

    env = {k: v for k, v in os.environ.items() if k != "OCIO"}
    cmd = [sys.executable, "-m", "generator.batch.worker", json.dumps({"bad": True}), "4"]
    orphan = subprocess.run(cmd + [str(tmp_path / "a")], cwd=ROOT, env=env | {PARENT_ENV: "1"}, capture_output=True,
                            text=True, timeout=120)
    assert orphan.returncode == 3 and orphan.stdout == "" and not (tmp_path / "a").exists()
    child = subprocess.run(cmd + [str(tmp_path / "b")], cwd=ROOT, env=env | {PARENT_ENV: str(os.getpid())},
                           capture_output=True, text=True, timeout=120)
    assert child.returncode == 1 and '"event": "error"' in child.stdout


@pytest.mark.pipeline
def test_a_trajectory_that_cannot_be_planned_fails_before_any_frame_is_rendered(tmp_path):
    """A 1.4 km fly-through (3,600 frames) fits nowhere on small seed 3
    (docs/trajectories.md): the seed fails with the planner's one-line error before
    the orbit, planned and flown first, renders anything (it used to render all the orbit's
    frames, then fail)."""
    r = run(tmp_path, "--seeds", "3", "--frames", "3600", "--resolution", "8x6", "--outputs", "rgb", timeout=300)
    assert r.returncode == 1
    assert "seed 3: FAILED" in r.stdout and "TrajectoryError: no collision-free fly-through of 1440 m" in r.stdout
    partial = tmp_path / ".seed_000003.partial"
    assert "TrajectoryError" in (partial / "error.log").read_text()
    assert (partial / "scene" / "site.blend").is_file()  # the site was built...
    assert not (partial / "orbit").exists() and not list(partial.rglob("rgb_*.png"))  # ...no frame rendered
    assert not (tmp_path / "seed_000003").exists()


@pytest.mark.parametrize(
    "args,message",
    [
        (["--seeds", "-3"], "seed must be an integer from 0 to 9223372036854775807"),
        (["--seeds", "1.5"], "seed must be an integer from 0"),
        (["--seeds", str(2**64)], "seed must be an integer from 0 to 9223372036854775807"),
        (["--seeds", "9" * 5000], "seed must be an integer from 0"),
        (["--resolution", "3x2"], "resolution width must be an integer from 4 to 16,384 pixels "
                                      "(Blender renders smaller sides as 4), got 3"),
        (["--resolution", "70000x4"], "resolution width must be an integer from 4 to 16,384 pixels "
                                      "(Blender renders smaller sides as 4), got 70000"),
        (["--resolution", "100000x100000"], "resolution width must be an integer from 4 to 16,384 pixels "
                                      "(Blender renders smaller sides as 4), got 100000"),
        (["--resolution", "4000x2200"], "the limit is 8,294,400"),
        (["--frames", "100000"], "frames must be an integer from 2 to 10000"),
        (["--scoring-density", "1e7"], "--scoring-density 1e+07: a small site has more than 2,500 m^2"),
        (["--points-density", "1e5"], "--points-density 100000: a small site"),
        (["--scoring-density", "nan"], "expected a positive number"),
        (["--scoring-density", "1e-300"], "under 100 points; give at least 0.04"),
        (["--points-density", "0.01"], "--points-density 0.01: a small site may have only 2,500 m^2"),
        (["--trajectory", "orbit", "--trajectory", "orbit"], "--trajectory orbit is given twice"),
        (["--scene-preset", "huge"], "invalid choice"),
        (["--render-preset", "ultra"], "invalid choice"),
        (["--trajectory", "zigzag"], "invalid choice"),
        (["--shard", "3/2"], "shard must be K/N"),
        (["--shard", "x"], "shard must be K/N"),
        (["--resolution", "0x10"], "resolution must be WxH"),
        (["--resolution", "-64x48"], "a value that starts with '-' must be written --option=VALUE"),
        (["--resolution=-64x48"], "resolution must be WxH with positive integers"),
        (["--seeds", "3", "4", "3"], "--seeds lists seed 3 twice"),
        (["--outputs", ""], "--outputs names no modality"),
        (["--outputs", " , "], "--outputs names no modality"),
        (["--outputs", "rgb,depth,rgb"], "--outputs lists rgb twice"),
        (["--out", ""], "--out: must name a folder, got an empty path"),
        (["--out", __file__], "exists and is not a folder; name a folder"),
    ],
)
def test_bad_input_exits_2_with_one_line(tmp_path, args, message):
    r = run(tmp_path, *args)
    assert r.returncode == 2 and message in r.stderr and "Traceback" not in r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ")


@pytest.mark.parametrize("change, message", [
    ({"frames": 2.5}, "^frames must be an integer from 2 to 10,000, got 2.5$"),
    ({"phases": True}, "^phases must be an integer from 1 to 16, got True$"),
    ({"points_density": math.nan}, "^--points-density must be a finite number > 0, got nan$"),
    ({"scoring_density": -1.0}, "^--scoring-density must be a finite number > 0, got -1.0$"),
    ({"resolution": (640.0, 480)}, r"^resolution width must be an integer from 4 to 16,384 pixels \(Blender renders "
                                   r"smaller sides as 4\), got 640.0$"),
])
def test_run_config_numbers_are_one_line_errors(change, message):
    """The API's RunConfig refuses what the CLI's parser cannot give it (floats, bools, NaN)."""
    from generator.batch.config import RunConfig

    with pytest.raises(ValueError, match=message):
        RunConfig(**change).validated()


def test_unwritable_output_folder(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    r = run(blocker / "sub", "--seeds", "1")
    assert r.returncode == 2 and r.stderr.startswith("error: cannot write to output folder") and "Traceback" not in r.stderr


def test_seed_folders_of_an_older_format_are_left_alone(tmp_path):
    """A complete seed of another format version is the user's data: reported, not replaced
    (--overwrite replaces it)."""
    from exporters import FORMAT_VERSION
    from exporters.manifest import write_manifest
    from generator.batch.config import RunConfig
    from generator.batch.folders import decide

    cfg = RunConfig().to_dict()
    for seed, version in ((1, "0.2"), (2, FORMAT_VERSION)):
        (tmp_path / f"seed_{seed:06d}").mkdir()
        write_manifest(tmp_path / f"seed_{seed:06d}", {"format_version": version, "seed": seed, "config": cfg, "summary": {}})
    old = decide(tmp_path, 1, cfg, overwrite=False, repair=False, hashes=None)
    assert old.action == "conflict" and f"format_version '0.2' (now '{FORMAT_VERSION}')" in old.message
    assert decide(tmp_path, 2, cfg, overwrite=False, repair=False, hashes=None).action == "skip"
    assert decide(tmp_path, 1, cfg, overwrite=True, repair=False, hashes=None).action == "run"
    assert read_manifest(tmp_path / "seed_000001")["format_version"] == "0.2"  # deciding touches nothing


def test_a_second_signal_does_not_cut_the_clean_up_short():
    """The first Ctrl-C or SIGTERM stops the run (KeyboardInterrupt) and decides the exit code;
    one more while the executor cancels its tasks and removes their folders is only noted."""
    import signal

    from generator.batch import runner

    runner.INTERRUPTED.clear()
    runner.SIGNALS.clear()
    try:
        with pytest.raises(KeyboardInterrupt):
            runner.interrupt(signal.SIGTERM)
        assert runner.interrupt(signal.SIGINT) is None  # no exception in the clean-up
        assert runner.stopped_by() == (143, "terminated (SIGTERM)")
        assert runner.SIGNALS == [signal.SIGTERM, signal.SIGINT]
    finally:
        runner.INTERRUPTED.clear()
        runner.SIGNALS.clear()
