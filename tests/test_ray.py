"""The Ray executor on a real two-node Ray cluster on loopback (issue 17): a head node and a
second node started with the venv's `ray start` (tests/loopback_ray.py: 127.0.0.2 and
127.0.0.3), each with one CPU, so two seeds run on two nodes at once. No mocks."""

import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT, TINY
from conftest import run_generator as run
from loopback_ray import RAY_ENV, env, free_ports, loopback_cluster, node_ip, processes_of
from exporters.exr import read_frame_exr
from exporters.manifest import read_manifest, verify_manifest

HEAD_IP, NODE_IP = node_ip(0), node_ip(1)
SEEDS = ["4", "7"]  # seed 4 as in the shared local run (conftest.finished), seed 7 run locally here
ARGS = ["--colmap-text", "--executor", "ray", "--cpus-per-seed", "1"]


@pytest.fixture(scope="module")
def cluster():
    """HOST:PORT of a head node and a second node, both on loopback, one CPU each; stopped
    (and checked that none of its processes is left) in a finally block."""
    with loopback_cluster(nodes=2, cpus=1) as address:
        yield address


@pytest.fixture(scope="module")
def local_seed7(tmp_path_factory):
    out = tmp_path_factory.mktemp("local7")
    r = run(out, "--seeds", "7", "--colmap-text")
    assert r.returncode == 0, r.stderr[-2000:]
    return out


def _same_as_local(ray_out: Path, local: dict[str, Path]) -> None:
    """Every file of each seed equals the local run's (by the manifests' sha256), except
    Blender's log (timings) and site.blend (Blender writes its own bytes; the scene is
    site.json, and the frames); EXRs whose bytes differ must hold equal arrays."""
    for seed, local_out in local.items():
        name = f"seed_{int(seed):06d}"
        a, b = read_manifest(local_out / name), read_manifest(ray_out / name)
        assert a["config"] == b["config"] and a["summary"] == b["summary"] and a["versions"] == b["versions"]
        assert a["files"].keys() == b["files"].keys()
        for rel in a["files"]:
            if rel.endswith((".log", ".blend")) or a["files"][rel]["sha256"] == b["files"][rel]["sha256"]:
                continue
            assert rel.endswith(".exr"), f"seed {seed}: {rel} differs between the local and the Ray run"
            fa, fb = read_frame_exr(local_out / name / rel), read_frame_exr(ray_out / name / rel)
            assert fa.keys() == fb.keys()
            for key in fa.keys() - {"header"}:
                np.testing.assert_array_equal(fa[key], fb[key])


def _alive(pid: int) -> bool:
    """A process that still runs (a zombie waiting for its parent to collect it does not)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat[stat.rindex(")") + 2] != "Z"


def _worker_pids(out: Path) -> dict[int, tuple[int, int]]:
    """{seed: (pid of its worker process, pid of that process's parent)} for workers writing into ``out``."""
    found = {}
    for d in Path("/proc").iterdir():
        try:
            argv = (d / "cmdline").read_bytes().decode(errors="replace").split("\0")
            ppid = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            continue
        # python -m generator.batch.worker CONFIG SEED FOLDER
        if argv[1:3] == ["-m", "generator.batch.worker"] and len(argv) > 5 and argv[5].startswith(f"{out}/"):
            found[int(argv[4])] = (int(d.name), ppid)
    return found


def test_two_seeds_on_two_nodes_equal_a_local_run(cluster, finished, local_seed7, tmp_path):
    r = run(tmp_path, "--seeds", *SEEDS, *ARGS, "--ray-address", cluster, env_extra=RAY_ENV)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-3000:]
    lines = {s: [l for l in r.stdout.splitlines() if l.startswith(f"seed {s}: 6 frames")] for s in SEEDS}
    assert all(len(v) == 1 for v in lines.values()), r.stdout
    assert {l[0].rsplit(" on node ", 1)[1] for l in lines.values()} == {HEAD_IP, NODE_IP}  # one seed on each node
    for s in SEEDS:  # the bars were fed by the tasks' events, frame by frame
        assert re.search(rf"seed {s} frames: +\d+%\|[^|]*\| [1-6]/6", r.stderr), r.stderr
        assert verify_manifest(tmp_path / f"seed_{int(s):06d}") == []
    assert not list(tmp_path.glob(".*"))  # no partial folder, lock or probe file left
    _same_as_local(tmp_path, {"4": finished[0], "7": local_seed7})


def test_lost_workers_are_retried_and_equal_a_local_run(cluster, finished, local_seed7, tmp_path):
    """Seed 4's worker process is killed (SIGKILL) mid-run, and seed 7's Ray worker process
    (the task running it; its worker process dies with it): both are run again, their
    partial folders removed first, and both end complete and identical to a local run."""
    args = [sys.executable, "-m", "generator", "--out", str(tmp_path), *TINY, "--seeds", *SEEDS, *ARGS]
    proc = subprocess.Popen(args, cwd=ROOT, env=env(RAY_ADDRESS=cluster),  # the cluster named by RAY_ADDRESS
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    killed: dict[int, int] = {}
    try:
        deadline = time.time() + 90
        while len(killed) < 2 and time.time() < deadline and proc.poll() is None:
            for seed, (pid, parent) in _worker_pids(tmp_path).items():
                partial = tmp_path / f".seed_{seed:06d}.partial"
                if seed in killed or not (partial / "scene" / "site.json").exists():
                    continue
                assert not (partial / "manifest.json").exists()  # mid-run: the seed is not written yet
                os.kill(pid if seed == 4 else parent, signal.SIGKILL)
                killed[seed] = pid
            time.sleep(0.05)
        out, err = proc.communicate(timeout=150)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert sorted(killed) == [4, 7], f"the workers were not caught mid-run: {killed}"
    assert proc.returncode == 0, out[-2000:] + err[-3000:]
    assert "seed 4: attempt 1 lost (worker process killed by SIGKILL" in out
    assert "seed 7: attempt 1 lost (its Ray worker process or node died)" in out
    assert out.count("retrying: attempt 2 of 3, its partial folder removed first") == 2
    table = out[out.index("status"):]
    assert table.count("retried: complete on attempt 2") == 2
    for s in SEEDS:
        assert verify_manifest(tmp_path / f"seed_{int(s):06d}") == []
    assert not list(tmp_path.glob(".*"))
    assert not _worker_pids(tmp_path) and not any(_alive(pid) for pid in killed.values())
    _same_as_local(tmp_path, {"4": finished[0], "7": local_seed7})


def test_seed_lost_on_every_attempt_fails_for_good(cluster, tmp_path):
    """--retries 0: a lost worker is not run again; the seed is failed (exit 1), its partial
    folder kept and never marked complete; the other seed completes."""
    args = [sys.executable, "-m", "generator", "--out", str(tmp_path), *TINY, "--seeds", "3", "7", "--colmap-text",
            "--executor", "ray", "--cpus-per-seed", "1", "--retries", "0", "--ray-address", cluster]
    proc = subprocess.Popen(args, cwd=ROOT, env=env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.time() + 90
        while time.time() < deadline and proc.poll() is None:
            pid = _worker_pids(tmp_path).get(3, (None,))[0]
            if pid and (tmp_path / ".seed_000003.partial" / "scene" / "site.json").exists():
                os.kill(pid, signal.SIGKILL)
                break
            time.sleep(0.05)
        out, err = proc.communicate(timeout=150)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 1, out[-2000:] + err[-3000:]
    assert "seed 3: FAILED" in out and "worker process killed by SIGKILL" in out and "retrying" not in out
    assert not (tmp_path / "seed_000003").exists() and (tmp_path / ".seed_000003.partial").is_dir()
    assert verify_manifest(tmp_path / "seed_000007") == []
    table = out[out.index("status"):].splitlines()
    assert any(l.split()[:2] == ["3", "failed"] for l in table) and any(l.split()[:2] == ["7", "done"] for l in table)


def test_interrupt_cancels_the_tasks_and_cleans_up(cluster, tmp_path):
    args = [sys.executable, "-m", "generator", "--out", str(tmp_path), *TINY, "--seeds", "11", "12",
            "--executor", "ray", "--cpus-per-seed", "1", "--ray-address", cluster]
    proc = subprocess.Popen(args, cwd=ROOT, env=env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 90
    while len(_worker_pids(tmp_path)) < 2 and time.time() < deadline:
        time.sleep(0.05)
    workers = _worker_pids(tmp_path)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert len(workers) == 2
    assert proc.returncode == 130 and "interrupted" in err and "Traceback" not in err
    time.sleep(0.5)
    assert not any(_alive(pid) for pid, _ in workers.values())  # the seeds' processes are gone
    assert list(tmp_path.iterdir()) == []  # partial folders and locks removed


def test_without_an_address_a_local_ray_is_started_and_stopped(finished, tmp_path):
    """No --ray-address and no RAY_ADDRESS: the run starts a Ray of its own (here in a
    temporary folder of its own, RAY_TMPDIR), computes the seed as a local run does, and
    stops that Ray when it ends."""
    temp = Path(tempfile.mkdtemp(prefix="bray", dir="/tmp"))
    try:
        r = run(tmp_path, "--seeds", "4", "--colmap-text", "--executor", "ray", timeout=240,
                env_extra=RAY_ENV | {"RAY_TMPDIR": str(temp)})
        assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-3000:]
        assert "seed 4: 6 frames" in r.stdout and list(temp.iterdir())  # the Ray it started lived in temp
        _same_as_local(tmp_path, {"4": finished[0]})
        time.sleep(1.0)
        assert not processes_of(set(), str(temp)), "the run left its Ray running"
    finally:
        subprocess.run(["rm", "-rf", str(temp)])


@pytest.mark.pipeline
def test_local_ray_without_a_node_big_enough_is_exit_2(tmp_path):
    """No node can join the Ray a run starts for itself: --cpus-per-seed above its CPUs is a
    one-line error, not a wait that never ends (it was a warning, then a wait)."""
    temp = Path(tempfile.mkdtemp(prefix="bray", dir="/tmp"))
    try:
        r = run(tmp_path, "--seeds", "1", "--executor", "ray", "--cpus-per-seed", "1000", timeout=120,
                env_extra=RAY_ENV | {"RAY_TMPDIR": str(temp)})
        assert r.returncode == 2 and "--cpus-per-seed 1000: this machine has" in r.stderr, r.stderr[-2000:]
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in r.stderr
        assert not [p for p in tmp_path.iterdir() if p.name.startswith(("seed_", ".seed_"))]
        time.sleep(1.0)
        assert not processes_of(set(), str(temp)), "the run left its Ray running"
    finally:
        subprocess.run(["rm", "-rf", str(temp)])


HANGING_INIT = """
import os, socket, sys, time
import ray
from generator.batch.executors import ray_cluster

ray_cluster.INIT_TIMEOUT_S = 1.0


def init(**kwargs):  # a cluster that accepts the connection, says something, then never answers
    os.write(2, b"[2026-11-23] logging.cc:303: Set ray log level from environment variable RAY_BACKEND_LOG_LEVEL to 2\\n")
    os.write(2, b"C++ WARNING: the GCS did not answer\\n")
    time.sleep(60)


ray.init = init
server = socket.socket()
server.bind(("127.0.0.1", 0))
server.listen()
ray_cluster.RayExecutor(sys.argv[1], address=f"127.0.0.1:{server.getsockname()[1]}", cpus_per_seed=1.0, retries=0)
"""


def test_a_hanging_cluster_gives_up_with_what_ray_said(tmp_path):
    """The start-up watchdog: exit 2 with its line, after what Ray wrote while it hung (stderr
    is caught during ray.init to drop Ray's log-level info line, and must not swallow the rest)."""
    r = subprocess.run([sys.executable, "-c", HANGING_INIT, str(tmp_path)], capture_output=True, text=True, cwd=ROOT,
                       timeout=60, env=env())
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and lines[0] == "C++ WARNING: the GCS did not answer", r.stderr
    assert lines[1].startswith("error: the Ray cluster at 127.0.0.1:") and "did not answer within 1 s" in lines[1]
    assert len(lines) == 2 and "Set ray log level" not in r.stderr


def test_unreachable_address_is_one_line_and_exit_2(tmp_path):
    [port] = free_ports(1)
    for address, says in ((f"{HEAD_IP}:{port}", "no Ray cluster answers at"), ("nowhere", "HOST:PORT"),
                          ("ray://127.0.0.2:10001", "Ray Client addresses")):
        t0 = time.time()
        r = run(tmp_path, "--seeds", "1", "--executor", "ray", "--ray-address", address, timeout=60, env_extra=RAY_ENV)
        assert time.time() - t0 < 30
        assert r.returncode == 2 and says in r.stderr and "Traceback" not in r.stderr, r.stderr
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: ")
    assert list(tmp_path.iterdir()) == []


def test_node_check_of_out_says_what_is_wrong(tmp_path):
    """What each node runs at start (in this process here): it must see the driver's file
    with its contents, and write beside it."""
    from generator.batch.executors.ray_cluster import probe_out

    token = tmp_path / ".ray-probe-1-abc"
    assert "does not see the file the driver wrote" in probe_out(str(token), "s3cret")
    token.write_text("other")
    assert "sees another file" in probe_out(str(token), "s3cret")
    token.write_text("s3cret")
    assert probe_out(str(token), "s3cret") == "" and [p.name for p in tmp_path.iterdir()] == [token.name]


def test_ray_options_need_the_ray_executor(tmp_path):
    for args, says in ((["--ray-address", "127.0.0.2:1"], "--ray-address applies to --executor ray"),
                       (["--retries", "1"], "--retries applies to --executor ray"),
                       (["--executor", "ray", "--workers", "2"], "--workers applies to the local executor"),
                       (["--executor", "ray", "--cpus-per-seed", "0"], "expected a positive number")):
        r = run(tmp_path, "--seeds", "1", *args)
        assert r.returncode == 2 and says in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert list(tmp_path.iterdir()) == []
