"""The registries of trajectory kinds, executors and exports (issue #37): found by scanning
their packages (a module dropped into one is found with no list to edit), one-line errors
for unknown and duplicate names, and each kind's fitting to a site as docs/trajectories.md
states it. bpy-free and fast: no test here launches the batch job."""

from __future__ import annotations

import argparse
import subprocess
import sys
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT, TINY
from exporters.sinks import SINKS, export_options, load_sinks, register_sink
from generator.batch.config import RunConfig, plan_trajectory
from generator.batch.executors import EXECUTORS, Executor, ExecutorError, make_executor, register_executor
from generator.geometry.camera import levelled, look_at
from generator.registry import Registry, RegistryError, import_modules, origin
from trajectories import KINDS, TRAJECTORY_KINDS, register_kind

# a spawn box 40 m x 40 m (size 40) from z 1 to 25 m, centred on (0, 10)
BOX = (np.array([-20.0, -10.0, 1.0]), np.array([20.0, 30.0, 25.0]))
SPAWN = np.array([[x, y, z] for x in (-20.0, 20.0) for y in (-10.0, 30.0) for z in (1.0, 25.0)])
START = look_at((-15.0, -5.0, 10.0), (0.0, 10.0, 0.0))  # pitched down: the walks level it


class FreeSpace:
    """A MotionChecker with nothing in the way."""

    def can_move(self, start, end) -> bool:
        return True

    def is_free(self, position) -> bool:
        return True


def one_line(exc: pytest.ExceptionInfo) -> str:
    text = str(exc.value)
    assert "\n" not in text and text
    return text


# ---- the registry utility ----------------------------------------------------------------

def test_registry_lists_names_in_name_order_whatever_the_registration_order(tmp_path, monkeypatch):
    make_package(tmp_path, monkeypatch, "zz_empty", {})
    reg = Registry("widget", "zz_empty")
    reg.add("beta", 2, "here.b")
    reg.add("alpha", 1, "here.a")
    assert reg.names() == ("alpha", "beta") and list(reg) == ["alpha", "beta"] and reg.get("beta") == 2
    assert reg.items() == [("alpha", 1), ("beta", 2)] and "alpha" in reg and "gamma" not in reg


def test_unknown_name_is_one_line_listing_the_known_ones(tmp_path, monkeypatch):
    make_package(tmp_path, monkeypatch, "zz_empty2", {})
    reg = Registry("widget", "zz_empty2")
    reg.add("beta", 2, "here.b")
    reg.add("alpha", 1, "here.a")
    with pytest.raises(RegistryError) as exc:
        reg.get("gamma")
    assert one_line(exc) == "unknown widget 'gamma'; known: alpha, beta"


def test_duplicate_and_malformed_names_are_refused(tmp_path, monkeypatch):
    make_package(tmp_path, monkeypatch, "zz_empty3", {})
    reg = Registry("widget", "zz_empty3")
    reg.add("alpha", 1, "here.a")
    reg.add("alpha", 3, "here.a")  # the same place again (a module imported twice): replaced
    assert reg.get("alpha") == 3
    with pytest.raises(RegistryError) as exc:
        reg.add("alpha", 2, "there.a")
    assert one_line(exc) == "widget 'alpha' is registered twice, in here.a and in there.a: rename one"
    assert reg.get("alpha") == 3
    for bad in ("Alpha", "two words", "", "9lives", 7):
        with pytest.raises(RegistryError, match="lowercase letters"):
            reg.add(bad, 0, "here.x")


def test_import_modules_imports_every_module_in_name_order_skipping_private_ones(tmp_path, monkeypatch):
    make_package(tmp_path, monkeypatch, "zz_scan", {
        "b_second.py": "from zz_scan import SEEN\nSEEN.append('b_second')\n",
        "a_first.py": "from zz_scan import SEEN\nSEEN.append('a_first')\n",
        "_helper.py": "from zz_scan import SEEN\nSEEN.append('_helper')\n",
    }, init="SEEN = []\n")
    assert import_modules("zz_scan") == ["zz_scan.a_first", "zz_scan.b_second"]
    assert sys.modules["zz_scan"].SEEN == ["a_first", "b_second"]


def make_package(tmp_path: Path, monkeypatch, name: str, modules: dict[str, str], init: str = "") -> Path:
    """A package ``name`` of ``modules`` (file name -> source) under tmp_path, importable."""
    folder = tmp_path / name
    folder.mkdir()
    (folder / "__init__.py").write_text(init)
    for file, source in modules.items():
        (folder / file).write_text(source)
    monkeypatch.syspath_prepend(str(tmp_path))
    for module in [m for m in sys.modules if m == name or m.startswith(name + ".")]:
        monkeypatch.delitem(sys.modules, module)
    return folder


@contextmanager
def dropped_in(package: str, registry: Registry, name: str, source: str, folder: Path, monkeypatch):
    """``source`` as a module of the real ``package`` (a folder added to its ``__path__``),
    the package's registry scanned again; afterwards the module and its entry are gone."""
    pkg = sys.modules[package]
    module = f"{package}.zz_dropped_{name}"
    folder.mkdir()
    (folder / f"zz_dropped_{name}.py").write_text(source)
    monkeypatch.setattr(pkg, "__path__", [*pkg.__path__, str(folder)])
    try:
        registry.scan()
        yield sys.modules[module]
    finally:
        registry.entries.pop(name, None)
        registry.origins.pop(name, None)
        sys.modules.pop(module, None)


# ---- trajectory kinds -----------------------------------------------------------------------

def test_every_kind_is_registered_beside_its_planner():
    assert set(KINDS) == {"random_walk", "modified_random_walk", "orbit", "lawnmower", "spline"}
    assert KINDS == TRAJECTORY_KINDS.names() == tuple(sorted(KINDS))
    home = {"orbit": "survey", "lawnmower": "survey", "spline": "spline", "random_walk": "walks",
            "modified_random_walk": "walks"}
    for kind, module in home.items():
        assert TRAJECTORY_KINDS.origins[kind].startswith(f"trajectories.{module}."), TRAJECTORY_KINDS.origins[kind]


def test_unknown_kind_is_one_line_listing_the_kinds():
    says = f"unknown trajectory kind 'zigzag_none'; known: {', '.join(KINDS)}"
    with pytest.raises(ValueError) as exc:
        plan_trajectory("zigzag_none", FreeSpace(), SPAWN, START, 0, 4, 10.0)
    assert one_line(exc) == says
    with pytest.raises(ValueError) as exc:
        RunConfig(trajectories=("orbit", "zigzag_none")).validated()
    assert one_line(exc) == says


def test_a_kind_registered_twice_is_refused():
    fit = TRAJECTORY_KINDS.get("orbit")
    with pytest.raises(RegistryError) as exc:
        register_kind("orbit")(lambda site: None)
    assert "trajectory kind 'orbit' is registered twice, in trajectories.survey.fit_orbit and in" in one_line(exc)
    assert TRAJECTORY_KINDS.get("orbit") is fit


ZIGZAG = """
from trajectories import orbit, register_kind


@register_kind("zz_probe")
def fit(site):
    return orbit(site.checker, site.centre[:2], 5.0, 20.0, site.frames, fps=site.fps)
"""


def test_a_kind_dropped_into_the_package_is_found_and_flown(tmp_path, monkeypatch):
    from generator.__main__ import parse_args

    with dropped_in("trajectories", TRAJECTORY_KINDS, "zz_probe", ZIGZAG, tmp_path / "more", monkeypatch):
        traj = plan_trajectory("zz_probe", FreeSpace(), SPAWN, START, 0, 4, 10.0)
        assert len(traj) == 4 and traj.params["radius_m"] == 5.0 and traj.params["center"] == [0.0, 10.0]
        args = parse_args(["--out", str(tmp_path / "out"), *TINY, "--trajectory", "zz_probe"])
        assert args.config.to_dict()["trajectories"] == ["zz_probe"]
    assert "zz_probe" not in TRAJECTORY_KINDS


def plan(kind: str, seed: int = 0, frames: int = 12, spawn: np.ndarray = SPAWN):
    return plan_trajectory(kind, FreeSpace(), spawn, START, seed, frames, 10.0)


def camera_forward(pose: np.ndarray) -> np.ndarray:
    return pose[:3, 2]  # OpenCV: the camera looks along its z axis


@pytest.mark.parametrize("scale, altitude", [(1.0, 15.0), (2.5, 30.0)])
def test_orbit_fitting(scale, altitude):
    """Around the spawn box's centre at 0.45 x its size, at max(0.3 x size, 15 m), looking at
    the point 2 m above the centre."""
    spawn = (SPAWN - [0.0, 10.0, 0.0]) * [scale, scale, 1.0] + [0.0, 10.0, 0.0]  # size 40 x scale, same centre
    size = 40.0 * scale
    traj = plan("orbit", spawn=spawn)
    p = traj.positions
    assert len(traj) == 12 and np.allclose(np.hypot(p[:, 0], p[:, 1] - 10.0), 0.45 * size)
    assert np.all(p[:, 2] == altitude) and traj.params["altitude_m"] == altitude == max(0.3 * size, 15.0)
    to_target = np.array([0.0, 10.0, 2.0]) - p
    forward = np.array([camera_forward(pose) for pose in traj.poses])
    assert np.allclose(forward, to_target / np.linalg.norm(to_target, axis=1, keepdims=True))
    assert np.allclose(traj.timestamps, np.arange(12) / 10.0)


def test_lawnmower_fitting():
    """Over the spawn box less 0.1 x size on every side, lines size / 4 apart, at
    max(0.25 x size, 15 m)."""
    traj = plan("lawnmower")
    assert traj.params["bounds"] == [[-16.0, -6.0], [16.0, 26.0]] and traj.params["spacing_m"] == 10.0
    assert traj.params["altitude_m"] == 15.0
    p = traj.positions
    assert np.allclose(p[0], [-16.0, -6.0, 15.0]) and np.all(p[:, 2] == 15.0)
    assert np.all((p[:, :2] >= [-16.0 - 1e-9, -6.0 - 1e-9]) & (p[:, :2] <= [16.0 + 1e-9, 26.0 + 1e-9]))


def test_spline_fitting():
    """Inside the spawn box between max(floor, 2 m) and min(top, max(floor + 5 m, 0.2 x size)),
    at 4 m/s, looking at a target gliding between two points within 0.15 x size of the box's
    centre (1.5-6 m up), never within 4 m of it; the path turns and climbs (parallax, not a
    forward glide); deterministic for a seed, another seed another path."""
    traj = plan("spline", frames=40)
    p = traj.positions
    assert np.all((p >= [-20.0, -10.0, 2.0]) & (p <= [20.0, 30.0, 8.0]))  # 8 = max(1 + 5, 0.2 x 40)
    steps = np.linalg.norm(np.diff(p, axis=0), axis=1)
    assert np.all(steps <= 0.4 + 1e-9) and traj.params["speed_m_s"] == 4.0
    a, b = np.array(traj.params["look_at"])
    for t in (a, b):
        assert np.all(np.abs(t[:2] - [0.0, 10.0]) <= 0.15 * 40) and 1.5 <= t[2] <= 6.0
    w = np.linspace(0.0, 1.0, 40)[:, None]  # the target moves in step with the distance flown (equal steps)
    to_target = a * (1 - w) + b * w - p
    assert np.all(np.hypot(to_target[:, 0], to_target[:, 1]) >= 4.0)
    forward = np.array([camera_forward(pose) for pose in traj.poses])
    np.testing.assert_allclose(forward, to_target / np.linalg.norm(to_target, axis=1, keepdims=True), atol=1e-9)
    assert np.allclose(traj.poses[:, 2, 0], 0.0)  # no roll: the camera's x axis stays level
    travel = np.diff(p, axis=0) / steps[:, None]
    assert np.linalg.norm(p[-1] - p[0]) < 0.95 * steps.sum()  # it turns
    assert np.median(np.degrees(np.arccos(np.clip((travel * forward[:-1]).sum(1), -1, 1)))) > 20  # not forward only
    assert np.array_equal(plan("spline", frames=40).poses, traj.poses)
    assert not np.array_equal(plan("spline", seed=1, frames=40).poses, traj.poses)


@pytest.mark.parametrize("kind", ["random_walk", "modified_random_walk"])
def test_walk_fitting(kind):
    """From the levelled spawn pose, 1 m steps and 15 degree turns, inside the spawn box."""
    traj = plan(kind, frames=30)
    assert len(traj) == 30 and np.allclose(traj.poses[0], levelled(START))
    forward = np.array([camera_forward(pose) for pose in traj.poses])
    assert np.allclose(forward[:, 2], 0.0)  # a level camera
    steps = np.linalg.norm(np.diff(traj.positions, axis=0), axis=1)
    assert np.all(np.isclose(steps, 0.0) | np.isclose(steps, 1.0)) and traj.params["step_m"] == 1.0
    assert np.all((traj.positions >= BOX[0] - 1e-9) & (traj.positions <= BOX[1] + 1e-9))
    if kind == "random_walk":
        assert traj.params["angle_deg"] == 15.0
    assert np.array_equal(plan(kind, frames=30).poses, traj.poses)


# ---- executors ------------------------------------------------------------------------------

def test_executors_are_registered_with_their_options():
    assert EXECUTORS.names()[:2] == ("local", "ray")
    assert [o.flag for o in EXECUTORS.get("local").options] == ["--workers"]
    assert [o.flag for o in EXECUTORS.get("ray").options] == ["--ray-address", "--cpus-per-seed", "--retries"]
    # listing them (every run does) does not import Ray, a second's work: ray_cluster imports it where it is used
    listing = ("import sys; from generator.batch.executors import EXECUTORS; assert 'ray' in EXECUTORS; "
               "assert 'ray' not in sys.modules, 'Ray was imported'")
    r = subprocess.run([sys.executable, "-c", listing], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr[-2000:]


def test_unknown_executor_is_one_line_listing_the_executors(tmp_path):
    with pytest.raises(ExecutorError) as exc:
        make_executor("slurm_none", tmp_path, argparse.Namespace())
    assert one_line(exc) == f"unknown executor 'slurm_none'; known: {', '.join(EXECUTORS.names())}"


def test_an_executor_registered_twice_is_refused():
    with pytest.raises(RegistryError) as exc:
        @register_executor("local", "another local")
        class Other(Executor):  # noqa: F841
            pass
    assert "executor 'local' is registered twice, in generator.batch.executors.local.LocalExecutor" in one_line(exc)
    assert EXECUTORS.get("local").factory.__self__.__name__ == "LocalExecutor"


PROBE_EXECUTOR = """
from generator.batch.executors import Executor, register_executor
from generator.cli_args import Option, int_at_least


@register_executor("zz_probe", "a probe", options=(Option("--zz-level", "zz_probe: a level",
                                                          type=int_at_least(0, "zz-level")),))
class Probe(Executor):
    def __init__(self, level):
        self.level = level

    @classmethod
    def from_options(cls, out, options):
        return cls(options.zz_level or 0)

    def room(self):
        return 0

    def submit(self, job):
        pass

    def events(self, timeout):
        return []

    def cancel_all(self):
        pass
"""


def test_an_executor_dropped_into_the_package_brings_its_options(tmp_path, monkeypatch, capsys):
    from generator.__main__ import parse_args

    with dropped_in("generator.batch.executors", EXECUTORS, "zz_probe", PROBE_EXECUTOR, tmp_path / "more",
                    monkeypatch):
        args = parse_args(["--out", str(tmp_path / "out"), *TINY, "--executor", "zz_probe", "--zz-level", "3"])
        executor = make_executor(args.executor, args.out, args)
        assert executor.name == "zz_probe" and executor.level == 3
        with pytest.raises(SystemExit) as exit_:
            parse_args(["--out", str(tmp_path / "out"), *TINY, "--zz-level", "3"])  # with the local executor
        assert exit_.value.code == 2
        assert capsys.readouterr().err.startswith("error: --zz-level applies to --executor zz_probe")
    assert "zz_probe" not in EXECUTORS


# ---- exports (sinks) ------------------------------------------------------------------------

def test_every_export_lives_beside_its_format():
    home = {"boxes3d": "boxes3d", "coco": "coco", "colmap": "colmap", "coverage": "coverage", "frames": "frames",
            "map": "previews", "nerfstudio": "nerfstudio", "previews": "previews", "tracks": "tracks",
            "lidar": "lidar_scans"}
    assert set(home) <= set(load_sinks())
    for sink, module in home.items():
        assert SINKS.origins[sink].startswith(f"exporters.{module}."), SINKS.origins[sink]
    assert [o.flag for o in export_options()] == ["--colmap-text", "--lidar"]


def test_unknown_export_and_export_option_are_one_line():
    with pytest.raises(RegistryError) as exc:
        SINKS.get("csv_none")
    assert one_line(exc) == f"unknown export 'csv_none'; known: {', '.join(SINKS.names())}"
    with pytest.raises(ValueError) as exc:
        RunConfig(exports={"csv_none": True}).validated()
    assert one_line(exc) == "unknown export option 'csv_none'; the exports' options are: colmap_text, lidar"
    with pytest.raises(ValueError) as exc:
        RunConfig(exports={"colmap_text": "yes"}).validated()
    assert one_line(exc) == "--colmap-text (colmap_text) must be True or False, got 'yes'"
    with pytest.raises(ValueError) as exc:
        RunConfig(exports={"lidar": ["vlp16", "nope"]}).validated()
    assert one_line(exc).startswith("--lidar (lidar): unknown LiDAR 'nope'")
    with pytest.raises(ValueError) as exc:
        RunConfig(exports={"lidar": "vlp16"}).validated()
    assert one_line(exc) == "--lidar (lidar) must be a list of names, got 'vlp16'"
    assert RunConfig(exports={"lidar": ["vlp16", "tls"]}).validated().exports["lidar"] == ["vlp16", "tls"]


def test_a_sink_registered_twice_is_refused():
    with pytest.raises(RegistryError) as exc:
        @register_sink("frames")
        class Other:  # noqa: F841
            pass
    assert "export 'frames' is registered twice, in exporters.frames.FramesSink and in" in one_line(exc)


def test_export_options_keep_the_manifest_config_keys():
    """A seed's parameters keep their keys and values: colmap_text sits beside the others."""
    keys = {"scene_preset", "render_preset", "resolution", "frames", "trajectories", "points_density", "max_depth",
            "scoring_density", "colmap_text", "lidar", "device", "outputs"}
    assert set(RunConfig().to_dict()) == keys and RunConfig().to_dict()["colmap_text"] is False
    config = RunConfig("small", exports={"colmap_text": True}).to_dict()
    assert config["colmap_text"] is True and RunConfig.from_dict(config).to_dict() == config
    assert RunConfig.from_dict(config).exports == {"colmap_text": True, "lidar": None}


PROBE_SINK = """
from exporters.sinks import register_sink
from generator.cli_args import Option


@register_sink("zz_probe", options=(Option("--zz-probe-rows", "zz_probe: rows too", action="store_true",
                                           default=False),))
class ProbeSink:
    def __init__(self, context):
        self.rows = context.options["zz_probe_rows"]

    def add_frame(self, frame):
        pass

    def close(self):
        pass
"""


def test_an_export_dropped_into_the_package_is_found_with_its_option(tmp_path, monkeypatch):
    from generator.__main__ import parse_args

    with dropped_in("exporters", SINKS, "zz_probe", PROBE_SINK, tmp_path / "more", monkeypatch) as module:
        assert load_sinks()["zz_probe"] is module.ProbeSink
        config = parse_args(["--out", str(tmp_path / "out"), *TINY, "--zz-probe-rows"]).config
        assert config.to_dict()["zz_probe_rows"] is True and config.to_dict()["colmap_text"] is False
        assert RunConfig.from_dict(config.to_dict()) == config
    assert "zz_probe" not in SINKS and [o.flag for o in export_options()] == ["--colmap-text", "--lidar"]


def test_origin_names_module_and_qualified_name():
    assert origin(FreeSpace.can_move) == f"{__name__}.FreeSpace.can_move"
