"""The Rerun recording of the default seed (python -m datasets.view) read back with Rerun's
own RRD reader (rerun.chunk.RrdReader): entities, frame timeline, poses, intrinsics, tracks,
cloud size, class names and images equal what the seed's files hold (read with the
exporters' readers); the CLI's errors, Ctrl-C and SIGTERM, --spawn and tools/viewer_screenshot.py.
Seeds made otherwise: test_view_seeds.py; evaluation --rrd: test_view_evaluation.py."""

import math
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest
from rerun.chunk import RrdReader

from conftest import ROOT
from datasets.viewer import subsample_stride, subsampled_count
from exporters import FORMAT_VERSION
from exporters.ground_truth import PLY_VERSION_COMMENT
from exporters.palette import label_colors
from exporters.ply import read_ply
from exporters.tracks import read_tracks
from recordings import blueprint_views, column, read_rrd, run_module, view

KINDS = ("orbit", "spline")


def column_major(values) -> np.ndarray:
    """Rerun stores 3x3 matrices column-major."""
    return np.asarray(values, np.float64).reshape(3, 3).T


@pytest.fixture(scope="module")
def view_run(seed_folder, tmp_path_factory):
    out = tmp_path_factory.mktemp("view") / "seed4.rrd"
    return out, view(seed_folder, "--out", out, "--max-points", 300)


@pytest.fixture(scope="module")
def rrd_path(view_run):
    out, r = view_run
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


@pytest.mark.parametrize("cap", [0, 2.5, True])
def test_the_subsampling_rule_takes_a_whole_cap(cap):
    with pytest.raises(ValueError, match=rf"^max_points must be an integer >= 1, got {cap!r}$"):
        subsample_stride(10, cap)


def test_not_a_seed_folder_is_one_line_and_exit_2(tmp_path):
    (tmp_path / "notes.txt").write_text("not a seed")
    out = tmp_path / "x.rrd"
    r = run_module("datasets.view", str(tmp_path), "--out", str(out))
    assert r.returncode == 2
    assert r.stderr.startswith("error: ") and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert str(tmp_path) in r.stderr and not out.exists()


@pytest.mark.parametrize("args, says", [
    (["--trajectory", "zigzag"], "zigzag"),
    (["--out", "{seed}/inside.rrd"], "inside the generated seed folder"),
    (["--out", "{tmp}/missing/x.rrd"], "does not exist"),
    (["--max-points", "0"], "--max-points"),
    (["--spawn"], "no display"),
    (["--trajectory", "orbit", "--trajectory", "spline", "--trajectory", "orbit"], "more than once"),
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


def test_a_mesh_of_another_format_version_is_one_line_and_exit_2(seed_folder, tmp_path):
    """The viewer reads mesh.ply with the exporters' reader (exporters.ground_truth.read_mesh),
    which refuses a header that states another format version."""
    seed = shutil.copytree(seed_folder, tmp_path / seed_folder.name)
    mesh = seed / "ground_truth" / "mesh.ply"
    data = mesh.read_bytes()
    stated = f"comment {PLY_VERSION_COMMENT} {FORMAT_VERSION}\n".encode()
    assert data.count(stated) == 1
    mesh.write_bytes(data.replace(stated, f"comment {PLY_VERSION_COMMENT} 0.0\n".encode()))
    out = tmp_path / "x.rrd"
    r = run_module("datasets.view", str(seed), "--out", str(out))
    assert r.returncode == 2 and r.stderr.startswith("error: ")
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert f"{mesh}: ground-truth format 0.0, this reader reads {FORMAT_VERSION}" in r.stderr and not out.exists()


# ---- Ctrl-C, SIGTERM and what killed runs left behind ---------------------------------------------

# python -m datasets.view, stopped where the .rrd's temporary file is open and nothing is logged yet
PAUSED_WHILE_WRITING = """
import os, runpy, signal, sys, time

signal.signal(signal.SIGINT, signal.default_int_handler)  # a background job inherits SIGINT ignored

def paused(fd):
    time.sleep(60)  # the recording's bytes are in its temporary file: the test's signal comes here
    raise SystemExit("error: no signal came")

os.fsync = paused
runpy.run_module("datasets.view", run_name="__main__", alter_sys=True)
"""


def dead_pid() -> int:
    proc = subprocess.Popen(["true"])
    proc.wait()  # reaped: no process has this id now (ids are not reused at once)
    return proc.pid


@pytest.mark.parametrize("sig, code, says", [(signal.SIGTERM, 143, "terminated (SIGTERM)"),
                                             (signal.SIGINT, 130, "interrupted")])
def test_a_signal_leaves_no_temporary_file(seed_folder, tmp_path, sig, code, says):
    out = tmp_path / "x.rrd"
    proc = subprocess.Popen([sys.executable, "-c", PAUSED_WHILE_WRITING, str(seed_folder), "--out", str(out)],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not list(tmp_path.glob(".x.rrd.*.partial")):  # the recording is being written
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "no temporary file within 120 s"
            time.sleep(0.02)
        proc.send_signal(sig)
        stdout, stderr = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == code, stderr[-2000:]
    assert stderr.endswith(f"\nerror: {says}; no recording was written\n") and stdout == ""  # after the progress bars
    assert "Traceback" not in stderr
    assert list(tmp_path.iterdir()) == []  # neither the .rrd nor its temporary file


def test_a_run_removes_the_temporary_files_that_killed_runs_left(seed_folder, tmp_path):
    """Only of its own --out, and only those whose process is gone: a running one's is left alone."""
    live = subprocess.Popen(["sleep", "60"])
    try:
        gone = tmp_path / f".x.rrd.{dead_pid()}.partial"
        running = tmp_path / f".x.rrd.{live.pid}.partial"
        other = tmp_path / f".y.rrd.{dead_pid()}.partial"
        for path in (gone, running, other):
            path.write_bytes(b"half a recording")
        r = view(seed_folder, "--out", tmp_path / "x.rrd", "--trajectory", "orbit", "--max-points", 100)
        assert r.returncode == 0, r.stderr[-2000:]
        assert sorted(p.name for p in tmp_path.iterdir()) == sorted([running.name, other.name, "x.rrd"])
    finally:
        live.kill()
        live.wait()


# ---- what a seed holds and how Rerun shows it ---------------------------------------------------

IMAGES = ("rgb", "rgb_linear", "depth", "label", "instance", "normal", "flow", "backward_flow")


def image_pixels(table: pa.Table, t: int) -> np.ndarray:
    """The (H, W, C) uint8 pixels of an rr.Image logged at frame t."""
    table = table.sort_by("frame")
    fmt = table.column("Image:format").to_pylist()[t][0]
    return np.asarray(table.column("Image:buffer").to_pylist()[t][0], np.uint8).reshape(fmt["height"], fmt["width"], -1)


def test_default_seed_logs_without_rerun_warnings(view_run):
    _, r = view_run  # RERUN_STRICT=1: a component Rerun cannot show would have raised
    assert r.returncode == 0, r.stderr[-2000:]
    assert "Warning" not in r.stderr and "Traceback" not in r.stderr


def hue_saturation(rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """HSV hue (0..1), saturation and value of 8-bit RGB pixels."""
    c = rgb.astype(np.float64) / 255
    mx, mn = c.max(-1), c.min(-1)
    d = np.where(mx > mn, mx - mn, 1)
    r, g, b = c[..., 0], c[..., 1], c[..., 2]
    h = np.where(mx == r, (g - b) / d, np.where(mx == g, 2 + (b - r) / d, 4 + (r - g) / d)) / 6 % 1.0
    return h, np.where(mx > 0, (mx - mn) / np.where(mx > 0, mx, 1), 0), mx


def test_flow_is_shown_on_the_colour_wheel(recording, seed_folder):
    from datasets import Scene

    seq = Scene(seed_folder)["orbit"]
    coloured = 0
    for name in ("flow", "backward_flow"):
        table = recording[f"/world/orbit/camera/{name}"]["temporal"]
        for t in range(len(seq)):
            flow = seq[t][name].astype(np.float64)
            rgb = image_pixels(table, t)
            assert rgb.shape == flow.shape[:2] + (3,)
            ok = np.isfinite(flow).all(-1)
            assert (rgb[~ok] == 0).all()  # no flow: black
            if not ok.any():
                continue
            hue, sat, value = hue_saturation(rgb[ok])
            assert (value == 1).all()
            mag = np.hypot(flow[ok][:, 0], flow[ok][:, 1])
            # saturation = magnitude / the frame's 98th percentile magnitude, clipped to 1
            np.testing.assert_allclose(sat, np.clip(mag / np.percentile(mag, 98), 0, 1), rtol=0, atol=0.01)
            # hue = direction in image axes (x right, y down), 0 = +x, counted towards +y
            direction = np.arctan2(flow[ok][:, 1], flow[ok][:, 0]) / (2 * np.pi) % 1.0
            strong = sat > 0.3
            off = np.abs((hue[strong] - direction[strong] + 0.5) % 1.0 - 0.5)
            assert off.max() < 0.01
            coloured += int(strong.sum())
    assert coloured > 100  # the wheel was exercised on real motion


def test_only_the_rgb_image_is_drawn_in_3d(rrd_path, recording):
    views = blueprint_views(rrd_path)
    (site,) = [v for v in views if v["class"] == "3D"]
    assert site["origin"] == "world" and "$origin/**" in site["query"]
    for kind in KINDS:
        for name in IMAGES:
            assert f"/world/{kind}/camera/{name}" in recording  # every modality of the default seed is logged
            assert (f"- $origin/{kind}/camera/{name}" in site["query"]) == (name != "rgb"), name


# ---- --spawn where the virtual environment is not activated ---------------------------------------

NO_X_SERVER = ":87"


def without_rerun_on_path() -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("WAYLAND_DISPLAY", "VIRTUAL_ENV")}
    env |= {"PATH": "/usr/bin:/bin", "DISPLAY": NO_X_SERVER}
    assert shutil.which("rerun", path=env["PATH"]) is None and not Path(f"/tmp/.X11-unix/X{NO_X_SERVER[1:]}").exists()
    return env


def viewer_port_free() -> bool:
    """rr.spawn starts no viewer when something listens on its port 9876 already (it connects to that)."""
    with socket.socket() as s:
        return s.connect_ex(("127.0.0.1", 9876)) != 0


@pytest.mark.skipif(not viewer_port_free(), reason="a Rerun viewer (or something else) listens on port 9876")
def test_spawn_runs_the_viewer_beside_the_interpreter(seed_folder):
    """The viewer finds no X server at $DISPLAY and exits: one line, exit 2, in seconds, found before
    anything is logged (rerun-sdk 0.41 buffers a recording for a viewer that is gone, and its flush
    can wait for it forever: it did with one stage of a small timeline seed)."""
    start = time.monotonic()
    r = view(seed_folder, "--spawn", "--trajectory", "orbit", env=without_rerun_on_path(), timeout=45)
    # the viewer of sys.executable's environment was started (PATH has none); it finds no X server
    assert "Failed to open connection to X server" in r.stderr
    viewer = Path(sys.executable).with_name("rerun")
    assert r.returncode == 2 and "Traceback" not in r.stderr and r.stdout == ""
    errors = [line for line in r.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and r.stderr.strip().splitlines()[-1] == errors[0]  # the last line, after Rerun's
    assert errors[0].startswith(f"error: --spawn: the Rerun viewer {viewer} did not start")
    assert f"DISPLAY={NO_X_SERVER}" in errors[0] and "--out seed.rrd" in errors[0]
    assert "orbit frames" not in r.stderr  # no progress bar: nothing was logged for the missing viewer
    assert time.monotonic() - start < 40


def test_spawn_without_a_viewer_is_one_line_and_exit_2(seed_folder, tmp_path):
    venv = tmp_path / "venv"  # an environment with the packages of this one but no rerun executable
    (venv / "bin").mkdir(parents=True)
    (venv / "bin" / "python").symlink_to(Path(sys.executable).resolve())
    (venv / "lib").symlink_to(Path(sys.prefix) / "lib")
    shutil.copy(Path(sys.prefix) / "pyvenv.cfg", venv / "pyvenv.cfg")
    r = subprocess.run([str(venv / "bin" / "python"), "-m", "datasets.view", str(seed_folder), "--spawn"],
                       capture_output=True, text=True, cwd=ROOT, env=without_rerun_on_path())
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr[-2000:]
    assert "no Rerun viewer" in r.stderr and str(venv / "bin" / "python") in r.stderr


# ---- tools/viewer_screenshot.py ---------------------------------------------------------------------

def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def listening(port: int) -> bool:
    with socket.socket() as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return True
    return False


def screenshot(rrd, png, *args) -> subprocess.CompletedProcess:
    command = [sys.executable, str(ROOT / "tools" / "viewer_screenshot.py"), str(rrd), str(png), *map(str, args)]
    return subprocess.run(command, capture_output=True, text=True, timeout=240)


@pytest.mark.skipif(shutil.which("chromium") is None and shutil.which("chromium-browser") is None,
                    reason="tools/viewer_screenshot.py needs chromium (apt-get install chromium)")
def test_screenshot_tool_stops_the_viewer_it_started(rrd_path, tmp_path):
    ports = [free_port() for _ in range(3)]
    png = tmp_path / "shot.png"
    r = screenshot(rrd_path, png, "--size", "400x300", "--wait", "3", "--web-port", ports[0],
                   "--grpc-port", ports[1], "--debug-port", ports[2])
    assert r.returncode == 0, r.stderr[-2000:]
    from PIL import Image

    assert Image.open(png).size == (400, 300)
    assert [p for p in ports if listening(p)] == []  # the rerun_cli binary, too, is gone


def test_screenshot_tool_refuses_a_port_in_use(rrd_path, tmp_path):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        r = screenshot(rrd_path, tmp_path / "shot.png", "--web-port", port)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert f"--web-port {port}" in r.stderr and "already in use" in r.stderr
    assert not (tmp_path / "shot.png").exists()
