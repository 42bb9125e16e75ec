"""The output folder is the user's (issue 13, generator side): real processes on real files.

Most cases need no rendering: the seed already lies in the folder (a copy of the shared
tiny seed 4) or something else is in the way. Two tests render one tiny seed each."""

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import ROOT, TINY
from conftest import run_generator as run
from exporters.manifest import PARTIAL_MARKER, read_manifest, verify_manifest

SEED4 = ["--seeds", "4", "--colmap-text"]  # the parameters of the shared finished seed


def _env(**extra):
    return {k: v for k, v in os.environ.items() if k != "OCIO"} | extra


def _copy_seed(finished, out: Path) -> Path:
    src, _ = finished
    out.mkdir(parents=True, exist_ok=True)
    shutil.copytree(src / "seed_000004", out / "seed_000004", copy_function=shutil.copy2)  # keeps mtimes
    return out / "seed_000004"


def _snapshot(folder: Path) -> dict:
    return {p.relative_to(folder).as_posix(): (p.is_symlink(), p.read_bytes() if p.is_file() and not p.is_symlink() else None)
            for p in sorted(folder.rglob("*"))}


def _seed_lines(stdout: str, seed: int) -> list[str]:
    return [l for l in stdout.replace("\r", "\n").splitlines() if l.startswith(f"seed {seed}:")]


def _no_traceback(r):
    assert "Traceback" not in r.stdout + r.stderr, r.stderr[-2000:]


def test_things_in_the_way_are_left_alone_with_one_line_each(tmp_path, finished):
    """A user's folder, a file, a symlink, manifests that are not ours or not whole, a
    partial folder and a lock file that are not ours: one line per seed, exit 3, nothing
    touched, with or without --overwrite."""
    out = tmp_path / "out"
    (out / "seed_000001").mkdir(parents=True)
    (out / "seed_000001" / "a.txt").write_text("keep")
    (out / "seed_000002").write_text("a file")
    elsewhere = _copy_seed(finished, tmp_path / "elsewhere")
    (out / "seed_000003").symlink_to(elsewhere, target_is_directory=True)
    for seed, manifest in ((5, "[]"), (6, '{"seed": 6}'), (9, '{"format_version": "0.3", "seed": 9, "config": {}, '
                                                              '"files": {"../../x": {"bytes": 1, "sha256": ""}}}')):
        (out / f"seed_{seed:06d}").mkdir()
        (out / f"seed_{seed:06d}" / "manifest.json").write_text(manifest)
    (out / ".seed_000007.partial").mkdir()
    (out / ".seed_000007.partial" / "notes.txt").write_text("mine")
    (out / ".seed_000008.lock").mkdir()
    (tmp_path / "user.txt").write_text("never truncated")
    (out / ".seed_000010.lock").symlink_to(tmp_path / "user.txt")
    before, before_elsewhere = _snapshot(out), _snapshot(elsewhere)
    seeds = [1, 2, 3, 5, 6, 7, 8, 9, 10]
    for extra in ([], ["--overwrite"]):
        r = run(out, "--seeds", *map(str, seeds), *extra)
        _no_traceback(r)
        assert r.returncode == 3, r.stdout[-3000:] + r.stderr[-2000:]
        for seed in seeds:
            assert len(_seed_lines(r.stdout, seed)) == 1, (seed, r.stdout)
        lines = {seed: _seed_lines(r.stdout, seed)[0] for seed in seeds}
        assert "not a seed folder written by this tool" in lines[1]
        assert "is a file" in lines[2] and "is a symlink" in lines[3]
        assert "holds a JSON list" in lines[5] and "lacks format_version, config, files" in lines[6]
        assert "not made by this tool" in lines[7] and "lock file" in lines[8]
        assert "outside its folder" in lines[9] and "lock file" in lines[10]
        assert _snapshot(out) == before and _snapshot(elsewhere) == before_elsewhere
        assert (tmp_path / "user.txt").read_text() == "never truncated"


def test_complete_seed_made_with_other_parameters_is_left_alone(tmp_path, finished):
    folder = _copy_seed(finished, tmp_path)
    before = _snapshot(folder)
    r = run(tmp_path, "--seeds", "4")  # no --colmap-text
    _no_traceback(r)
    assert r.returncode == 3
    [line] = _seed_lines(r.stdout, 4)
    assert "complete with other parameters: colmap_text True (now False)" in line and "--overwrite" in line
    assert _snapshot(folder) == before


def test_failed_overwrite_keeps_the_old_seed(tmp_path, finished):
    """--overwrite replaces a seed only once the new one is committed."""
    folder = _copy_seed(finished, tmp_path)
    before = _snapshot(folder)
    r = run(tmp_path, *SEED4, "--overwrite", env_extra={"BUILDEE_FAIL_SEEDS": "4"})
    assert r.returncode == 1 and "seed 4: FAILED" in r.stdout
    assert _snapshot(folder) == before and verify_manifest(folder) == []


def _truncate(path: Path):
    with open(path, "r+b") as f:
        f.truncate(path.stat().st_size // 2)


def _flip(path: Path, keep_time: bool = False):
    st = path.stat()
    with open(path, "r+b") as f:
        f.seek(st.st_size // 2)
        b = f.read(16)
        f.seek(st.st_size // 2)
        f.write(bytes(x ^ 0xFF for x in b))
    if keep_time:
        os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))


def _verify(path: Path):
    return subprocess.run([sys.executable, "-m", "generator", "verify", str(path)], capture_output=True, text=True,
                          cwd=ROOT, env=_env())


@pytest.mark.parametrize("damage,file,says", [
    (_truncate, "orbit/frame_000001.exr", "bytes, the manifest says"),
    (_flip, "spline/tracks.h5", "contents changed"),
    (lambda p: p.unlink(), "ground_truth/points.ply", "missing"),
])
def test_corrupted_seed_is_noticed_on_rerun_and_by_verify(tmp_path, finished, damage, file, says):
    folder = _copy_seed(finished, tmp_path)
    damage(folder / file)
    before = _snapshot(folder)
    r = run(tmp_path, *SEED4)
    _no_traceback(r)
    assert r.returncode == 3
    [line] = _seed_lines(r.stdout, 4)
    assert f"complete but {file}: " in line and says in line and "--repair" in line
    assert _snapshot(folder) == before  # reported, not deleted
    v = _verify(tmp_path)
    lines = v.stdout.splitlines()
    assert v.returncode == 1 and len(lines) == 1 and lines[0].startswith(f"{folder / file}: ") and says in lines[0]
    assert _verify(folder).returncode == 1  # a seed folder works as DIR too


def test_same_size_change_with_the_old_time_needs_verify(tmp_path, finished):
    """The documented limit of the quick check: bytes changed in place with the
    modification time put back pass the size check; --verify hashes and notices."""
    folder = _copy_seed(finished, tmp_path)
    _flip(folder / "orbit" / "tracks.h5", keep_time=True)
    assert run(tmp_path, *SEED4).returncode == 0
    r = run(tmp_path, *SEED4, "--verify")
    assert r.returncode == 3 and "orbit/tracks.h5: contents changed" in r.stdout
    assert _verify(tmp_path).returncode == 1
    # what verify reports, --repair redoes (it hashes every file, as --verify)
    r = run(tmp_path, *SEED4, "--repair")
    assert r.returncode == 0 and "seed 4: redoing it (orbit/tracks.h5: contents changed" in r.stdout, r.stdout[-2000:]
    assert _verify(tmp_path).returncode == 0


def test_repair_redoes_a_corrupted_seed(tmp_path, finished):
    folder = _copy_seed(finished, tmp_path)
    _truncate(folder / "spline" / "frame_000000.exr")
    (folder / "notes.txt").write_text("a file the manifest does not list")
    r = run(tmp_path, *SEED4, "--repair")
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert "seed 4: redoing it (spline/frame_000000.exr" in r.stdout
    assert verify_manifest(folder) == [] and _verify(tmp_path).returncode == 0
    assert not list(tmp_path.glob(".seed_*"))


def test_interrupted_replacement_puts_the_old_seed_back(tmp_path, finished):
    """Killed between the two renames of --overwrite: the old seed is aside, no seed folder.
    The next run puts it back (it is never taken for debris)."""
    from generator.batch.folders import partial_folder, replaced_folder

    folder = _copy_seed(finished, tmp_path)
    before = _snapshot(folder)
    folder.rename(replaced_folder(tmp_path, 4))
    partial_folder(tmp_path, 4).mkdir()
    (partial_folder(tmp_path, 4) / PARTIAL_MARKER).write_text("{}")
    r = run(tmp_path, *SEED4)
    assert r.returncode == 0, r.stdout[-2000:]
    assert "seed 4: the complete seed an interrupted replacement had set aside" in r.stdout
    assert "seed 4: already complete" in r.stdout and _snapshot(folder) == before
    assert not list(tmp_path.glob(".seed_*"))


def test_verify_bad_input_and_clean(tmp_path, finished):
    folder = _copy_seed(finished, tmp_path / "data")
    assert _verify(tmp_path / "data").returncode == 0 and _verify(folder).returncode == 0
    (tmp_path / "empty").mkdir()
    (tmp_path / "file").write_text("x")
    for bad, says in ((tmp_path / "empty", "holds no seed folders"), (tmp_path / "file", "is not a folder"),
                      (tmp_path / "missing", "is not a folder")):
        v = _verify(bad)
        assert v.returncode == 2 and says in v.stderr and len(v.stderr.strip().splitlines()) == 1


@pytest.mark.pipeline
def test_two_runs_of_one_seed_end_with_one_complete_seed(tmp_path):
    """Two identical runs started together (both --wait), and a third one started while
    the seed is being written (no --wait): one renders and commits, the second waits and
    finds the seed complete, the third skips it with exit code 4."""
    args = [sys.executable, "-m", "generator", "--out", str(tmp_path), *TINY, "--seeds", "11"]
    procs = [subprocess.Popen(args + ["--wait"], cwd=ROOT, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True) for _ in range(2)]
    deadline = time.time() + 120
    while not (tmp_path / ".seed_000011.partial").exists() and time.time() < deadline:
        time.sleep(0.05)
    third = subprocess.run(args, cwd=ROOT, env=_env(), capture_output=True, text=True)
    outs = [p.communicate(timeout=240) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [e[-2000:] for _, e in outs]
    lines = [_seed_lines(o, 11)[-1] for o, _ in outs]
    assert sorted("already complete" in l for l in lines) == [False, True], lines
    assert sorted("6 frames" in l for l in lines) == [False, True], lines
    assert third.returncode == 4 and "being written by another run (pid" in third.stdout
    assert verify_manifest(tmp_path / "seed_000011") == []
    assert not list(tmp_path.glob(".seed_*"))


@pytest.mark.pipeline
def test_terminated_run_removes_what_it_started(tmp_path):
    """SIGTERM (a scheduler's polite kill) cleans up like Ctrl-C: the seed in progress is
    removed, its lock is gone, nothing is marked complete."""
    args = [sys.executable, "-m", "generator", "--out", str(tmp_path), *TINY, "--seeds", "13"]
    proc = subprocess.Popen(args, cwd=ROOT, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while not (tmp_path / ".seed_000013.partial" / "blender.log").exists() and time.time() < deadline:
        time.sleep(0.05)
    proc.terminate()
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143 and err.strip().splitlines()[-1] == (
        "terminated (SIGTERM): unfinished seeds were removed; rerun the same command to finish them"), err[-2000:]
    assert "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def test_commit_checks_the_partial_folder_against_its_manifest(tmp_path, finished):
    """Nothing half-written is marked complete: a file that grew after the manifest, an
    unlisted file or a missing one stop the commit; an intact folder commits atomically."""
    from generator.batch.folders import commit, partial_folder, seed_folder

    src = _copy_seed(finished, tmp_path / "src")
    config = read_manifest(src)["config"]
    partial = partial_folder(tmp_path, 4)
    cases = [(lambda p: (p / "blender.log").open("a").write("late line\n"), "blender.log: "),
             (lambda p: (p / "extra.txt").write_text("x"), "extra.txt: not listed"),
             (lambda p: (p / "scene" / "preview.png").unlink(), "scene/preview.png: missing"),
             (lambda p: (p / "manifest.json").write_text("[]"), "holds a JSON list")]
    for damage, says in cases:
        shutil.copytree(src, partial)
        (partial / PARTIAL_MARKER).write_text("{}")
        damage(partial)
        assert says in commit(tmp_path, 4, config, replace=False)
        assert partial.exists() and not seed_folder(tmp_path, 4).exists()
        shutil.rmtree(partial)
    shutil.copytree(src, partial)
    (partial / PARTIAL_MARKER).write_text("{}")
    assert "another seed or configuration" in commit(tmp_path, 4, config | {"frames": 9}, replace=False)
    assert commit(tmp_path, 4, config, replace=False) == ""
    assert verify_manifest(seed_folder(tmp_path, 4)) == [] and not partial.exists()


def test_scoring_density_is_refused_before_rendering(tmp_path):
    """A density that passes the quick bound at parse time but not the site's real surface:
    refused once the site is built, before any frame."""
    r = run(tmp_path, "--seeds", "12", "--scoring-density", "8000")
    assert r.returncode == 1 and "--scoring-density 8000 on this site" in r.stdout, r.stdout[-2000:]
    assert not (tmp_path / "seed_000012").exists()
    assert not list((tmp_path / ".seed_000012.partial").rglob("*.exr"))


def test_points_density_is_refused_before_rendering(tmp_path):
    """The same for the simulator's points: 1,200 per m^2 passes the small preset's 2,500 m^2
    bound (3 M) but the built site has about 7.7 M (6,430 m^2 of surface: scenery carries no
    points); the limit is 5 M."""
    r = run(tmp_path, "--seeds", "12", "--points-density", "1200")
    assert r.returncode == 1 and "--points-density 1200 on this site gives" in r.stdout, r.stdout[-2000:]
    assert "the limit is 5,000,000: lower it, e.g. to " in r.stdout
    assert not (tmp_path / "seed_000012").exists()
    assert not list((tmp_path / ".seed_000012.partial").rglob("*.exr"))


def test_out_inside_a_seed_folder_is_refused(tmp_path, finished):
    folder = _copy_seed(finished, tmp_path)
    before = _snapshot(folder)
    for out in (folder, folder / "orbit", folder / "new" / "deeper"):
        r = run(out, "--seeds", "1")
        assert r.returncode == 2 and "is inside the seed folder" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    # the other CLIs that write files refuse it too: the site builder, the baselines and the viewer
    # (viewing the original seed, recording into the copy)
    for cmd in (["generator.scene", "--seed", "1", "--preset", "small", "--no-preview", "--out", str(folder / "scene2")],
                ["generator.baselines", "exploration", "--scene-preset", "small", "--out", str(folder / "b")],
                ["generator.baselines", "reconstruction", "--scene-preset", "small", "--out", str(folder)],
                ["datasets.view", str(finished[0] / "seed_000004"), "--out", str(folder / "view.rrd")]):
        r = subprocess.run([sys.executable, "-m", *cmd], capture_output=True, text=True, cwd=ROOT, env=_env())
        assert r.returncode == 2 and "inside the" in r.stderr and "seed folder" in r.stderr, r.stderr
        assert len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert _snapshot(folder) == before
    # a seed folder whose manifest is damaged is still a seed folder
    (tmp_path / "broken" / "seed_000002").mkdir(parents=True)
    (tmp_path / "broken" / "seed_000002" / "manifest.json").write_text("{not json")
    r = run(tmp_path / "broken" / "seed_000002" / "x", "--seeds", "1")
    assert r.returncode == 2 and "is inside the seed folder" in r.stderr


def test_overwrite_refused_while_a_half_deleted_old_seed_is_set_aside(tmp_path, finished):
    """A replacement whose deletion of the old seed failed leaves .seed_N.replaced without its
    manifest: the next --overwrite says so at once (it used to render the whole seed, then
    fail to commit, every time)."""
    folder = _copy_seed(finished, tmp_path)
    leftover = tmp_path / ".seed_000004.replaced" / "orbit"
    leftover.mkdir(parents=True)
    (leftover / "frame_000000.exr").write_bytes(b"left")
    before = _snapshot(folder)
    r = run(tmp_path, "--seeds", "4", "--overwrite")
    assert r.returncode == 3 and ".seed_000004.replaced is left from an earlier replacement" in r.stdout, r.stdout[-2000:]
    assert _snapshot(folder) == before and not (tmp_path / ".seed_000004.partial").exists()


def test_scene_cli_out_naming_a_file(tmp_path):
    f = tmp_path / "site"
    f.write_text("x")
    for out in (f, f / "sub"):
        r = subprocess.run([sys.executable, "-m", "generator.scene", "--seed", "1", "--preset", "small", "--no-preview",
                            "--out", str(out)], capture_output=True, text=True, cwd=ROOT, env=_env())
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and r.stderr.startswith("error: ")
    assert f.read_text() == "x"


def test_blender_clamps_sides_below_4(tmp_path):
    """Why --resolution and configure_render refuse sides below 4: Blender renders them as 4
    (a real render, asked of Blender directly), so K and the images would not match."""
    import scenes
    from PIL import Image

    from generator import Simulator
    from generator.blender import session

    sim = Simulator(scenes.walls_scene(tmp_path / "walls.blend"), points_density=1.0)
    sim.configure_render("preview", resolution=(4, 6))
    assert sim.render().rgb.shape[:2] == (6, 4)
    with pytest.raises(ValueError, match="resolution width must be an integer from 4 .*got 3"):
        sim.configure_render("preview", resolution=(3, 2))
    render = sim.scene.render
    render.resolution_x, render.resolution_y, render.filepath = 3, 2, str(tmp_path / "tiny.png")
    render.image_settings.media_type = "IMAGE"
    render.image_settings.file_format = "PNG"
    with session.quiet():
        session.bpy.ops.render.render(write_still=True)
    assert Image.open(tmp_path / "tiny.png").size != (3, 2)


def test_ctrl_c_swallowed_inside_a_blocking_wait_still_stops_the_run(tmp_path):
    """A library may catch the KeyboardInterrupt raised inside one of its blocking calls (Ray's
    waits check signals from C++). The CLI's handler remembers the signal, so the run loop
    stops at its next turn anyway: the executor is cancelled and the seed's lock released."""
    import signal

    from generator.batch import folders
    from generator.batch.config import RunConfig
    from generator.batch.executors import Executor, Outcome
    from generator.batch.runner import Options, interrupt, run_seeds

    class SwallowingExecutor(Executor):
        """Takes the seed, then gets Ctrl-C during a wait that swallows it (never finishes)."""
        name = "swallowing"

        def __init__(self):
            self.jobs, self.cancelled, self.waits = [], False, 0

        def room(self):
            return 1 - len(self.jobs)

        def submit(self, job):
            self.jobs.append(job)

        def events(self, timeout):
            self.waits += 1
            if self.waits > 3:  # the interrupt was lost: let the seed end (and the test fail)
                return [{"seed": 5, "event": "result", "outcome": Outcome(5, "failed", "never interrupted"),
                         "attempts": 1}]
            try:
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(timeout)  # the handler runs here and raises...
            except KeyboardInterrupt:
                pass  # ...and the library swallows it
            return []

        def cancel_all(self):
            self.cancelled = True

    previous = signal.signal(signal.SIGINT, interrupt)
    executor = SwallowingExecutor()
    try:
        with pytest.raises(KeyboardInterrupt):
            run_seeds(tmp_path, [5], RunConfig(), Options(), executor)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert executor.waits == 1 and executor.cancelled and [j.seed for j in executor.jobs] == [5]
    lock = folders.SeedLock.try_acquire(tmp_path, 5)  # the run let go of the seed
    assert lock is not None
    lock.release()
