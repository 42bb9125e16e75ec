"""``buildee/Exploration-v0``: next-best-view exploration as a Gymnasium environment.

Observations come from the geometric camera (``Simulator.render(engine="raycast")``, one
ray per pixel centre, no Blender render); the reward is the paper's coverage gain x 100.
Blender holds one scene per process: one environment per process (``gymnasium.make_vec``
runs each in its own process; see :mod:`.vector`). An environment whose scene another
Simulator replaced reloads it at ``reset()`` and refuses ``step()``. See docs/envs.md.
"""

from __future__ import annotations

import inspect
import math
import os
import sys

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from ..checks import check_integer, check_number
from ..render_settings import PRESETS as RENDER_PRESETS
from ..geometry.camera import heading_pose
from .actions import CONTINUOUS_FIELDS, DISCRETE_ACTIONS, continuous_targets, discrete_target, heading_and_pitch
from .keyword_values import MAX_RESOLUTION, choice, flag, lidar_sensor, resolution, sources
from .scenes import SceneSpec, blend_scene, check_cache_dir, site_is_intact, site_scene

MAX_LABEL_ID = 255  # upper bound of the label observation (ids index Simulator.labels)
COVERAGE_SETS = ("all", "observable")
STARTS = ("default", "random")


class ExplorationEnv(gym.Env):
    """Explore a construction site; reward = 100 x the share of surface points newly seen.

    Args (keywords):
        seeds: procedural site seeds (built once, cached in ``cache_dir``); and/or
        blend_files: paths of .blend scenes. Each episode uses one scene, drawn with the
            episode's random generator (so ``reset(seed=s)`` fixes it).
        scene_preset: preset of the procedural sites ('small', 'medium', 'large').
        resolution: (width, height) of the observations in pixels (default 128x128).
        action_space: 'discrete' (the paper's five actions) or 'continuous' (a Box of 5).
        step: metres per move; angle: degrees per turn (the paper's 3 m and 22.5 deg).
        max_steps: the episode is truncated after this many steps (the paper's 500).
        max_depth: surface points count as seen only within this planar depth (metres).
        points_density: surface points per square metre (the paper's 5).
        coverage: 'all' points (the paper's reward) or 'observable' ones only
            (``Simulator.observable_points_mask``).
        collision_penalty: subtracted from the reward of a refused move (default 0, the paper).
        start: 'default' (a site's entrance pose as in the baselines, or the .blend's
            camera) or 'random' (a free spawn point and heading drawn per episode).
        rgb: also observe 'rgb' (H, W, 3) uint8 from a Cycles ``render()`` (seconds per step).
        render_preset: Cycles preset for ``rgb`` ('preview', 'default', 'high').
        cache_dir: where built sites are kept (default ~/.cache/buildee/sites).
        render_mode: None or 'rgb_array' (depth and labels side by side, or the RGB).
        lidar: None, or a LiDAR (a preset's name, e.g. 'vlp16', or 'NAME@drone';
            docs/lidar.md) whose sweep from the camera (``Simulator.scan``) is also
            observed, per beam in the sensor's emission order: 'lidar_range' (N,) float32
            metres (0: no return) and 'lidar_label' (N,) int32 class ids (-1: no return).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(self, seeds=(), blend_files=(), scene_preset: str = "medium", resolution=(128, 128),
                 action_space: str = "discrete", step: float = 3.0, angle: float = 22.5, max_steps: int = 500,
                 max_depth: float = 20.0, points_density: float = 5.0, coverage: str = "all",
                 collision_penalty: float = 0.0, start: str = "default", rgb: bool = False,
                 render_preset: str = "preview", cache_dir: str | os.PathLike | None = None,
                 render_mode: str | None = None, lidar: str | None = None):
        # the arguments by name (locals() holds nothing else yet; __class__ is super()'s cell)
        options = check_keywords(**{k: v for k, v in locals().items() if k not in ("self", "__class__")})
        super().__init__()
        self.width, self.height = options["resolution"]
        self.step_m, self.angle, self.max_steps = options["step"], options["angle"], options["max_steps"]
        self.max_depth, self.points_density = options["max_depth"], options["points_density"]
        self.collision_penalty = options["collision_penalty"]
        self.coverage_set, self.start_rule = options["coverage"], options["start"]
        self.rgb, self.render_preset = options["rgb"], options["render_preset"]
        self.render_mode = options["render_mode"]
        self.lidar = options["lidar"]
        self.scene_preset, self.cache_dir = options["scene_preset"], options["cache_dir"]
        self._sources = options["sources"]
        self._scenes: dict[int, SceneSpec] = {}

        self.action_kind = options["action_space"]
        if self.action_kind == "discrete":
            self.action_space = spaces.Discrete(5)
        else:
            self.action_space = spaces.Box(-1.0, 1.0, shape=(len(CONTINUOUS_FIELDS),), dtype=np.float32)
        h, w = self.height, self.width
        obs = {
            "depth": spaces.Box(0.0, np.inf, shape=(h, w), dtype=np.float32),
            "label": spaces.Box(-1, MAX_LABEL_ID, shape=(h, w), dtype=np.int32),
            "pose": spaces.Box(-np.inf, np.inf, shape=(4, 4), dtype=np.float64),
            "coverage": spaces.Box(0.0, 1.0, shape=(1,), dtype=np.float64),
        }
        if self.rgb:
            obs["rgb"] = spaces.Box(0, 255, shape=(h, w, 3), dtype=np.uint8)
        if self.lidar is not None:
            beams = self.lidar.rays_per_sweep()
            obs["lidar_range"] = spaces.Box(0.0, np.inf, shape=(beams,), dtype=np.float32)
            obs["lidar_label"] = spaces.Box(-1, MAX_LABEL_ID, shape=(beams,), dtype=np.int32)
        self.observation_space = spaces.Dict(obs)

        self.sim = None  # the Simulator of the current scene
        self._generation = -1  # Blender's file generation when self.sim was loaded
        self.scene: SceneSpec | None = None
        self._subset: np.ndarray | None = None  # points the coverage counts (None: all)
        self._n_subset = 1
        self._seen = 0
        self._steps = 0
        self._last_obs: dict | None = None

    # ---- scenes ------------------------------------------------------------------------
    @property
    def num_scenes(self) -> int:
        return len(self._sources)

    def scene_spec(self, index: int) -> SceneSpec:
        """The scene ``index`` (building a procedural site on first use)."""
        if index not in self._scenes:
            kind, value = self._sources[index]
            self._scenes[index] = (site_scene(value, self.scene_preset, self.cache_dir) if kind == "seed"
                                   else blend_scene(value))
        return self._scenes[index]

    def _load(self, index: int) -> None:
        spec = self._scenes.get(index)
        if spec is not None and self.scene is spec and self.scene_is_loaded:
            return
        if spec is not None and self._sources[index][0] == "seed" and not site_is_intact(spec):
            self._scenes.pop(index)  # damaged since its first use: scene_spec rebuilds it (with a warning)
        spec = self.scene_spec(index)  # a site's first use checks its files and its code key (site_scene)
        Simulator = _simulator_class()
        self.sim = None  # Blender holds one scene: drop the old Simulator first
        from ..blender.session import BlendFileError  # bpy is loaded by now

        try:
            sim = Simulator(spec.blend, points_density=self.points_density, max_pcl_depth=self.max_depth,
                            seed=spec.seed)
        except BlendFileError as exc:
            if self._sources[index][0] != "seed":
                raise
            self._scenes.pop(index, None)  # the next reset looks at the cache again (and rebuilds it)
            raise BlendFileError(f"{exc}; the cached site is damaged: delete {spec.blend.parent} and it is rebuilt "
                                 "at the next reset") from None
        self._generation = _blender_generation()
        sim.configure_render(self.render_preset if self.rgb else None, resolution=(self.width, self.height))
        if len(sim.labels) > MAX_LABEL_ID + 1:
            raise ValueError(f"{spec.blend} has {len(sim.labels)} labels; the label observation holds at most "
                             f"{MAX_LABEL_ID + 1}")
        sim.set_frame(sim.frame_range[0])  # the scene stands still at its first animation frame
        if spec.start is None:
            spec = SceneSpec(spec.name, spec.blend, sim.get_world_from_camera(), spec.bounds, spec.seed)
            self._scenes[index] = spec
        if self.coverage_set == "observable":
            self._subset = sim.observable_points_mask
            self._n_subset = max(int(self._subset.sum()), 1)
        else:
            self._subset, self._n_subset = None, max(sim.num_points, 1)
        self.sim, self.scene = sim, spec

    @property
    def scene_is_loaded(self) -> bool:
        """False before the first ``reset()``, after ``close()``, and once another Simulator
        (another environment, in this process) has replaced this one's scene in Blender."""
        return self.sim is not None and self._generation == _blender_generation()

    def _start_pose(self) -> np.ndarray:
        spec, sim = self.scene, self.sim
        if self.start_rule == "default":
            return spec.start
        _, pitch = heading_and_pitch(spec.start)
        for _ in range(1000):
            p = sim.spawn_points[int(self.np_random.integers(len(sim.spawn_points)))]
            yaw = float(self.np_random.uniform(-math.pi, math.pi))
            if spec.inside(p) and sim.is_free(p):
                return heading_pose(p, yaw, pitch)
        raise RuntimeError(f"{spec.name}: no free spawn point found in 1000 draws; use start='default'")

    # ---- Gymnasium API ---------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        if options:  # none are defined: a typo must not pass unnoticed
            raise ValueError(f"reset() takes no options, got {sorted(options)}; set the environment's keywords "
                             "when making it")
        super().reset(seed=seed)
        self._load(int(self.np_random.integers(self.num_scenes)))
        sim = self.sim
        sim.set_world_from_camera(self._start_pose(), check_collisions=False)
        sim.reset_observations()
        self._steps = 0
        self._seen = 0
        self._observe_points()
        obs = self._observation()
        return obs, self._info(False)

    def step(self, action):
        if self.sim is None:
            raise RuntimeError("call reset() before step()")
        if not self.scene_is_loaded:
            raise RuntimeError(
                "another environment or Simulator in this process has replaced this environment's scene (Blender "
                "holds one scene per process): call reset() to reload it, and run one environment per process, e.g. "
                "gymnasium.make_vec(..., num_envs=N) or vectorization_mode='async' (gymnasium.vector.AsyncVectorEnv)")
        collided = self._act(action)
        self._steps += 1
        gain = self._observe_points()
        reward = 100.0 * gain / self._n_subset - (self.collision_penalty if collided else 0.0)
        obs = self._observation()
        truncated = self._steps >= self.max_steps
        return obs, float(reward), False, truncated, self._info(collided)

    def render(self):
        if self.render_mode != "rgb_array" or self._last_obs is None:
            return None
        if "rgb" in self._last_obs:
            return self._last_obs["rgb"].copy()
        return _preview(self._last_obs["depth"], self._last_obs["label"], self.max_depth)

    def close(self):
        self.sim = None

    # ---- steps -----------------------------------------------------------------------------
    def _act(self, action) -> bool:
        """Apply ``action``; True if its move was refused."""
        sim, pose = self.sim, self.sim.get_world_from_camera()
        if self.action_kind == "discrete":
            target, is_move = discrete_target(pose, _discrete(action), self.step_m, self.angle)
            if not is_move:
                return sim.set_world_from_camera(target, check_collisions=False)
            return not self.scene.inside(target[:3, 3]) or sim.set_world_from_camera(target)
        turned, moved = continuous_targets(pose, action, self.step_m, self.angle)
        sim.set_world_from_camera(turned, check_collisions=False)
        if np.array_equal(moved[:3, 3], turned[:3, 3]):
            return False
        return not self.scene.inside(moved[:3, 3]) or sim.set_world_from_camera(moved)

    def _observe_points(self) -> int:
        """Update the observed points from the current pose; returns how many points of the
        coverage set were seen for the first time."""
        sim = self.sim
        sim.compute_point_cloud(update_mask=True)
        seen = sim.observed_points_mask
        n = int(np.count_nonzero(seen if self._subset is None else seen & self._subset))
        gain, self._seen = n - self._seen, n
        return gain

    def _observation(self) -> dict:
        view = self.sim.render_geometry(normals=False)
        obs = {"depth": view.depth, "label": view.seg, "pose": view.world_from_camera,
               "coverage": np.array([self.coverage], dtype=np.float64)}
        if self.rgb:
            obs["rgb"] = (np.clip(self.sim.render().rgb, 0.0, 1.0) * 255 + 0.5).astype(np.uint8)
        if self.lidar is not None:
            obs |= self._lidar_observation()
        self._last_obs = obs
        return obs

    def _lidar_observation(self) -> dict:
        """The sweep from the camera, per beam: range (0: none) and class id (-1: none)."""
        sweep = self.sim.scan(self.lidar, index=self._steps)
        n = self.lidar.rays_per_sweep()
        ranges, labels = np.zeros(n, np.float32), np.full(n, -1, np.int32)
        xyz = sweep.scan.xyz.astype(np.float64)
        ranges[sweep.beam] = np.sqrt(xyz[:, 0] * xyz[:, 0] + xyz[:, 1] * xyz[:, 1] + xyz[:, 2] * xyz[:, 2])
        labels[sweep.beam] = sweep.scan.label
        return {"lidar_range": ranges, "lidar_label": labels}

    @property
    def coverage(self) -> float:
        """Share (0..1) of the coverage set's points seen so far in this episode."""
        return self._seen / self._n_subset

    def _info(self, collided: bool) -> dict:
        return {"collided": bool(collided), "coverage": self.coverage, "steps": self._steps,
                "scene": self.scene.name}


def _blender_generation() -> int:
    """Counter of .blend files loaded in this process (Blender is already imported)."""
    from ..blender import session

    return session.generation()


def _simulator_class():
    """``generator.Simulator``, importable in a process started by multiprocessing's spawn or
    forkserver (``AsyncVectorEnv`` workers): such a process inherits its parent's sys.path,
    where an imported Blender put its scripts folders, whose ``bpy`` package shadows the real
    module until Blender is loaded. Blender adds them back when it loads."""
    if "bpy" not in sys.modules:
        marker = f"{os.sep}bpy{os.sep}"
        sys.path[:] = [p for p in sys.path if not (marker in p and f"{os.sep}scripts" in p)]
    from .. import Simulator

    return Simulator


# ---- argument checks ----------------------------------------------------------------------
def check_known(keywords: dict) -> list[inspect.Parameter]:
    """``ExplorationEnv``'s parameters; an unknown name in ``keywords`` is a one-line ValueError
    listing them."""
    params = list(inspect.signature(ExplorationEnv).parameters.values())
    unknown = [k for k in keywords if k not in {p.name for p in params}]
    if unknown:
        raise ValueError(f"ExplorationEnv has no keyword {unknown[0]!r}; its keywords are "
                         f"{', '.join(p.name for p in params)}")
    return params


def make_env(**keywords) -> "ExplorationEnv":
    """gymnasium's entry point: an unknown keyword raises the one-line ValueError of
    :func:`check_known` (Python's TypeError would reach the user rewrapped by gymnasium)."""
    check_known(keywords)
    return ExplorationEnv(**keywords)


make_env.metadata = ExplorationEnv.metadata  # gymnasium reads the render modes from its entry point


def check_keywords(**keywords) -> dict:
    """``ExplorationEnv``'s keywords checked as its constructor checks them (it calls this), without
    building an environment: ``gymnasium.make_vec`` checks them here before starting workers.
    An unknown keyword or a bad value raises a one-line ValueError naming the keyword (a missing
    .blend: FileNotFoundError). Returns every keyword, defaults filled in, as the environment
    keeps it; ``seeds`` and ``blend_files`` become ``sources``, the list of scenes."""
    params = check_known(keywords)
    kw = {p.name: p.default for p in params} | keywords
    from ..scene.site import PRESETS

    return {
        "resolution": resolution(kw["resolution"]),
        "step": check_number("step", kw["step"], 0, open_low=True, valid="a finite number of metres > 0"),
        "angle": check_number("angle", kw["angle"], 0, 180, open_low=True, valid="a number of degrees in (0, 180]"),
        "max_steps": check_integer("max_steps", kw["max_steps"], 1),
        "max_depth": check_number("max_depth", kw["max_depth"], 0, open_low=True, finite=False,
                                  valid="a number of metres > 0 (math.inf: no limit)"),
        "points_density": check_number("points_density", kw["points_density"], 0, open_low=True),
        "collision_penalty": check_number("collision_penalty", kw["collision_penalty"], 0),
        "coverage": choice("coverage", kw["coverage"], COVERAGE_SETS),
        "start": choice("start", kw["start"], STARTS),
        "rgb": flag("rgb", kw["rgb"]),
        "render_preset": choice("render_preset", kw["render_preset"], tuple(RENDER_PRESETS)),
        "render_mode": choice("render_mode", kw["render_mode"], (None, *ExplorationEnv.metadata["render_modes"])),
        "scene_preset": choice("scene_preset", kw["scene_preset"], tuple(PRESETS)),
        "cache_dir": check_cache_dir(kw["cache_dir"]),
        "sources": sources(kw["seeds"], kw["blend_files"]),
        "action_space": choice("action_space", kw["action_space"], ("discrete", "continuous")),
        "lidar": lidar_sensor(kw["lidar"]),
    }


def _discrete(action) -> int:
    if isinstance(action, np.ndarray) and action.shape == ():
        action = action.item()
    return check_integer("action", action, 0, len(DISCRETE_ACTIONS) - 1,
                         valid=f"an integer in 0..4 ({', '.join(DISCRETE_ACTIONS)})")


def _preview(depth: np.ndarray, label: np.ndarray, max_depth: float) -> np.ndarray:
    """(H, 2W, 3) uint8: depth (near bright, black past ``max_depth`` or no surface) beside
    the labels in fixed colours (black: unlabelled)."""
    far = max_depth if math.isfinite(max_depth) else float(np.nanmax(np.where(np.isfinite(depth), depth, np.nan), initial=1.0))
    d = np.where(np.isfinite(depth) & (depth <= far), 1.0 - depth / max(far, 1e-9), 0.0)
    grey = np.repeat((d * 255 + 0.5).astype(np.uint8)[..., None], 3, axis=2)
    hue = (np.arange(MAX_LABEL_ID + 1) * 0.618034) % 1.0
    palette = (np.stack([np.abs(hue * 6 - 3) - 1, 2 - np.abs(hue * 6 - 2), 2 - np.abs(hue * 6 - 4)], 1).clip(0, 1) * 255)
    colours = np.where(label[..., None] >= 0, palette.astype(np.uint8)[np.clip(label, 0, MAX_LABEL_ID)], 0).astype(np.uint8)
    return np.concatenate([grey, colours], axis=1)
