"""Test configuration: real Blender (bpy) scenes built in code, saved to temporary files."""

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))
os.environ.setdefault("BUILDEE_BLENDER_LOG", str(Path(os.environ.get("TMPDIR", "/tmp")) / f"buildee-tests-{os.getpid()}.log"))

import fcntl  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402

import pytest  # noqa: E402

# the batch job's tiniest useful configuration (a small site, 3 frames of 48x32 pixels)
TINY = ["--scene-preset", "small", "--frames", "3", "--resolution", "48x32", "--points-density", "0.3",
        "--scoring-density", "5"]


# tests that use these fixtures launch the whole batch job (or a Ray cluster): marked
# ``pipeline``; ``pytest -m "not pipeline"`` is the fast tier (docs/architecture.md, "Tests")
PIPELINE_FIXTURES = {"finished", "seed_folder", "timeline_seed_folder", "cluster"}


def pytest_collection_modifyitems(config, items):
    for item in items:
        if PIPELINE_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.pipeline)


def cpu_flags() -> set[str]:
    """The CPU's feature flags (/proc/cpuinfo), for tests that make this machine stand in for
    other CPUs: a stand-in can only be a CPU with no more than this one has."""
    try:
        with open("/proc/cpuinfo") as f:
            return set(next(line for line in f if line.startswith("flags")).split(":")[1].split())
    except (OSError, StopIteration):
        return set()


def run_generator(out, *args, env_extra=None, **kw) -> subprocess.CompletedProcess:
    """``python -m generator --out OUT <TINY> *args`` in a real process."""
    env = {k: v for k, v in os.environ.items() if k != "OCIO"} | (env_extra or {})
    kw.setdefault("cwd", ROOT)
    return subprocess.run([sys.executable, "-m", "generator", "--out", str(out), *TINY, *args],
                          capture_output=True, text=True, env=env, **kw)


def run_evaluation(*args, timeout: float = 300) -> subprocess.CompletedProcess:
    """``python -m evaluation *args`` in a real process."""
    return subprocess.run([sys.executable, "-m", "evaluation", *map(str, args)], capture_output=True, text=True,
                          cwd=ROOT, timeout=timeout)


def assert_refused(r: subprocess.CompletedProcess, *words) -> str:
    """Exit code 2, one line on stderr holding ``words``, no traceback; returns the line."""
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2, (r.returncode, r.stderr[-2000:])
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr[-2000:]
    for w in words:
        assert str(w) in lines[0], (w, lines[0])
    return lines[0]


def built_once(tmp_path_factory, name: str, build) -> tuple[Path, subprocess.CompletedProcess]:
    """``build(folder)`` (a run of the batch job) done once per test session, however many
    pytest-xdist workers ask: the first to take the lock builds in the session's shared
    temporary folder and records the finished process; the others wait and reuse the folder.
    Returns (folder, the completed process)."""
    base = tmp_path_factory.getbasetemp()
    root = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base
    folder, record = root / name, root / f"{name}.done.json"
    with open(root / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not record.is_file():
            folder.mkdir(exist_ok=True)
            r = build(folder)
            assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
            record.write_text(json.dumps({"args": r.args, "stdout": r.stdout, "stderr": r.stderr}))
        done = json.loads(record.read_text())
    return folder, subprocess.CompletedProcess(done["args"], 0, done["stdout"], done["stderr"])


@pytest.fixture(scope="session")
def medium_plans():
    """{seed: plan} of medium seeds 0-11 (20 frames; nothing rendered), planned once per
    worker and shared read-only by the tests of the relief, the machinery and the classes."""
    from generator.scene.site import plan_site, site_params

    return {seed: plan_site(seed, site_params("medium", frames=20)) for seed in range(12)}


@pytest.fixture(scope="session")
def finished(tmp_path_factory):
    """(output folder, completed process) of one tiny run of seed 4, written by the real pipeline;
    shared by the tests of the exports, the evaluation and the loaders."""
    # a relative --out, from a folder that is not the repository (workers run elsewhere)
    return built_once(tmp_path_factory, "batch",
                      lambda out: run_generator(out.name, "--seeds", "4", "--colmap-text", cwd=out.parent))


@pytest.fixture(scope="session")
def plane_blend(tmp_path_factory):
    """tests/scenes.py's tilted plane as a .blend, built once for test_render.py and
    test_render_settings.py."""
    import scenes  # imports bpy: only when a test asks for the scene

    return scenes.tilted_plane_scene(tmp_path_factory.mktemp("render") / "plane.blend")


@pytest.fixture(scope="session")
def walls_blend(tmp_path_factory):
    """tests/scenes.py's walls scene (64x48 camera) as a .blend, built once for the
    Simulator's and the visibility's tests."""
    import scenes  # imports bpy: only when a test asks for the scene

    return scenes.walls_scene(tmp_path_factory.mktemp("walls") / "walls.blend")


@pytest.fixture(scope="session")
def seed_folder(finished):
    """The seed folder of :func:`finished` (seed 4)."""
    return finished[0] / "seed_000004"


@pytest.fixture(scope="session")
def timeline_seed_folder(tmp_path_factory):
    """A real timeline seed of 3 stages (python -m generator --phases 3, seed 1, orbit only, with
    a VLP-16's sweeps),
    built once and shared read-only by the tests of the timeline, its readers, the viewer and
    the write guard (a test that changes it works on a copy)."""
    out, _ = built_once(tmp_path_factory, "timeline",
                        lambda out: run_generator(out, "--seeds", "1", "--phases", "3", "--trajectory", "orbit",
                                                              "--lidar", "vlp16"))
    return out / "seed_000001"
