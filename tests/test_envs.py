"""The geometric camera and the Gymnasium exploration environment, on small real scenes."""

import functools
import json
import math
import re

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import scenes
from generator import Simulator
from generator.envs import EXPLORATION_ID
from generator.envs.exploration import ExplorationEnv, check_keywords
from generator.envs.scenes import site_code_key
from generator.geometry.camera import pixel_rays

W, H = 48, 32


def room_scene(path, camera_y: float = -3.0, width: int = W, height: int = H):
    """A closed 12 m x 12 m room (floor, four walls 3 m high) with two crates and a pole;
    a level camera at (0, camera_y, 1.5) looking along +Y, tilted 10 degrees down."""
    scenes.new_scene(width, height)
    scenes.add_plane("Ground", (12, 12), (0, 0, 0))
    for name, size, loc in (("Wall", (12.4, 0.2, 3), (0, 6.1, 1.5)), ("Wall.001", (12.4, 0.2, 3), (0, -6.1, 1.5)),
                            ("Wall.002", (0.2, 12, 3), (6.1, 0, 1.5)), ("Wall.003", (0.2, 12, 3), (-6.1, 0, 1.5))):
        scenes.add_box(name, size, loc)
    scenes.add_box("Crate", (1.2, 1.2, 1.2), (1.5, 2.5, 0.6), rotation=(0, 0, 0.4))
    scenes.add_box("Crate.001", (0.8, 0.8, 0.8), (-2.0, 1.0, 0.4))
    scenes.add_cylinder("Pole", 0.15, 3.0, (-0.8, 4.0, 1.5), segments=12)
    scenes.add_sun()
    scenes.add_camera((0, camera_y, 1.5), (math.radians(80), 0.0, 0.0), lens=24)
    return scenes.save(path)


@pytest.fixture(scope="module")
def rooms(tmp_path_factory):
    d = tmp_path_factory.mktemp("envs")
    return room_scene(d / "room.blend"), room_scene(d / "room_near_wall.blend", camera_y=4.5)


def make(blend_files, **kw):
    kw = {"resolution": (24, 16), "points_density": 20.0, "max_steps": 30} | kw
    return ExplorationEnv(blend_files=list(blend_files), **kw)


# ---- geometric camera ------------------------------------------------------------------------
def test_geometric_camera_agrees_with_cycles_at_pixel_centres(rooms):
    sim = Simulator(rooms[0], segmentation_sensitivity=0.0, render_preset="preview", ground_truth="renderer")
    cyc = sim.render()  # Cycles' own Depth and Object Index passes
    geo = sim.render(engine="raycast")
    assert geo.rgb is None and geo.rgb_linear is None
    assert geo.depth.dtype == np.float32 and geo.depth.shape == (H, W)
    assert geo.seg.dtype == np.int32 and geo.instance.dtype == np.int32 and geo.normal.shape == (H, W, 3)
    rgb, depth, seg = geo  # unpacks as the paper's (rgb, depth, seg)
    assert rgb is None and depth is geo.depth and seg is geo.seg

    finite = np.isfinite(cyc.depth)
    assert np.array_equal(finite, np.isfinite(geo.depth))
    rel = np.abs(geo.depth[finite] - cyc.depth[finite]) / cyc.depth[finite]
    # Cycles' own depth drifts by up to ~1e-4 on faces seen at grazing angles (> 75 deg from
    # the normal), where ours stays exact (next test): the 1e-4 bound holds off those
    rays = pixel_rays(sim.K, W, H)
    cos = -np.einsum("ijk,ijk->ij", geo.normal, rays / np.linalg.norm(rays, axis=2, keepdims=True))[finite]
    assert (cos > 0.25).mean() > 0.9
    assert rel[cos > 0.25].max() < 1e-4, f"max relative depth difference {rel[cos > 0.25].max():.2e}"
    assert rel.max() < 5e-4
    # labels: everywhere off object edges (a 3x3 neighbourhood of one instance in Cycles' image)
    pad = np.pad(cyc.instance, 1, mode="edge")
    neigh = np.stack([pad[1 + di: 1 + di + H, 1 + dj: 1 + dj + W] for di in (-1, 0, 1) for dj in (-1, 0, 1)])
    interior = np.all(neigh == cyc.instance, axis=0)
    assert interior.mean() > 0.7
    assert (geo.seg == cyc.seg)[interior].mean() >= 0.999
    assert (geo.instance == cyc.instance)[interior].mean() >= 0.999
    assert {sim.labels[i] for i in np.unique(geo.seg)} == {"Ground", "Wall", "Crate", "Pole"}


def test_geometric_depth_and_normals_are_exact_on_the_floor(rooms):
    sim = Simulator(rooms[0])
    sim.configure_render(resolution=(64, 48))
    geo = sim.render_geometry()
    pose = sim.get_world_from_camera()
    dirs = pixel_rays(sim.K, 64, 48) @ pose[:3, :3].T
    floor = geo.seg == sim.labels.index("Ground")
    assert floor.sum() > 100
    expected = -pose[2, 3] / dirs[..., 2]  # planar depth of the plane z = 0 (camera z of the ray is 1)
    assert np.abs(geo.depth[floor] - expected[floor]).max() < 1e-5 * expected[floor].max()
    up_in_camera = pose[:3, :3].T @ np.array([0.0, 0.0, 1.0])
    assert np.allclose(geo.normal[floor], up_in_camera, atol=1e-5)
    hit = np.isfinite(geo.depth)
    assert np.allclose(np.linalg.norm(geo.normal[hit], axis=1), 1.0, atol=1e-5)
    rays = pixel_rays(sim.K, 64, 48)
    assert np.all(np.einsum("ijk,ijk->ij", geo.normal, rays)[hit] < 0)  # facing the camera
    assert np.all(geo.normal[~hit] == 0) and np.all(geo.seg[~hit] == -1) and np.all(geo.instance[~hit] == -1)
    with pytest.raises(ValueError, match="engine"):
        sim.render(engine="eevee")


# ---- environment -----------------------------------------------------------------------------
@pytest.mark.parametrize("action_space", ["discrete", "continuous"])
def test_check_env_passes(rooms, action_space):
    env = make(rooms[:1], action_space=action_space, render_mode="rgb_array")
    check_env(env, skip_render_check=False)
    obs, info = env.reset(seed=0)
    assert set(obs) == {"depth", "label", "pose", "coverage"} and env.observation_space.contains(obs)
    assert info["steps"] == 0 and 0 < info["coverage"] < 1 and info["collided"] is False
    assert env.render().shape == (16, 48, 3)


def test_a_bad_discrete_action_is_one_line(rooms):
    env = make(rooms[:1])
    env.reset(seed=0)
    for bad in (5, -1, True, 1.0, "0"):
        with pytest.raises(ValueError, match=r"^action must be an integer in 0\.\.4 \(forward, left, right, turn_left, "
                                             rf"turn_right\), got {re.escape(repr(bad))}$"):
            env.step(bad)
    assert env.step(np.int64(3))[4]["steps"] == 1  # numpy integers are actions too
    with pytest.raises(ValueError, match=r"^reset\(\) takes no options, got \['x'\]; set the environment's keywords"):
        env.reset(seed=0, options={"x": 1})
    env.close()
    # an unknown keyword through gymnasium.make: the env's one line, not gymnasium's rewrapped TypeError
    with pytest.raises(ValueError, match=r"^ExplorationEnv has no keyword 'colour'; its keywords are seeds, "):
        gym.make(EXPLORATION_ID, blend_files=rooms[:1], colour="red")


def test_check_env_on_a_made_env_then_the_env_still_works(rooms):
    """check_env makes more environments from the spec (they replace the scene in Blender):
    the checked environment reloads its own scene at the next reset()."""
    env = gym.make(EXPLORATION_ID, blend_files=[str(rooms[0])], resolution=(24, 16), points_density=20.0)
    check_env(env.unwrapped, skip_render_check=False)
    check_env(env)
    obs, info = env.reset(seed=0)
    obs, reward, _, _, info = env.step(3)
    assert info["steps"] == 1 and reward > 0 and env.observation_space.contains(obs)
    env.close()


def test_two_envs_in_one_process_reload_at_reset_and_refuse_to_step(rooms):
    def episode(env, seed):
        obs, _ = env.reset(seed=seed)
        out = [obs]
        for a in (0, 3, 2):
            out.append(env.step(a))
        return out

    a = make(rooms[:1])
    first = episode(a, 5)
    b = make(rooms[1:])
    b.reset(seed=0)  # replaces a's scene in Blender
    with pytest.raises(RuntimeError, match=r"replaced this environment's scene.*call reset\(\).*one environment "
                                           r"per process.*make_vec") as err:
        a.step(0)
    assert "\n" not in str(err.value)
    again = episode(a, 5)  # reloads its own room: the same episode as a fresh environment's
    fresh = episode(make(rooms[:1]), 5)
    for other in (again, fresh):
        assert all(np.array_equal(first[0][k], other[0][k]) for k in first[0])
        for (o1, r1, *_, i1), (o2, r2, *_, i2) in zip(first[1:], other[1:]):
            assert r1 == r2 and i1 == i2 and all(np.array_equal(o1[k], o2[k]) for k in o1)
    assert str(rooms[0]) == again[-1][-1]["scene"]
    with pytest.raises(RuntimeError, match="replaced"):
        b.step(0)
    assert b.reset(seed=0)[1]["scene"] == str(rooms[1])


def test_same_seed_same_episode_and_rewards_sum_to_coverage(rooms):
    env = make(rooms, max_steps=12, coverage="all")
    actions = np.random.default_rng(7).integers(0, 5, 12)

    def episode(seed):
        obs, info = env.reset(seed=seed)
        out, rewards, infos = [obs], [], [info]
        for a in actions:
            obs, r, term, trunc, info = env.step(int(a))
            out.append(obs), rewards.append(r), infos.append(info)
            assert not term
        assert trunc and info["steps"] == 12
        return out, rewards, infos

    first, second = episode(11), episode(11)
    for a, b in zip(first[0], second[0]):
        assert all(np.array_equal(a[k], b[k]) for k in a)
    assert first[1] == second[1]
    infos = first[2]
    # rewards add up to 100 x the coverage gained after the start view (the paper's reward)
    assert math.isclose(sum(first[1]), 100 * (infos[-1]["coverage"] - infos[0]["coverage"]), abs_tol=1e-9)
    assert infos[-1]["coverage"] == pytest.approx(env.sim.coverage)  # the Simulator's own count
    assert first[0][-1]["coverage"][0] == infos[-1]["coverage"]
    assert sum(first[1]) > 0
    # the scene is drawn from the episode's seed: some seed picks the other room
    names = {env.reset(seed=s)[1]["scene"] for s in range(8)}
    assert names == {str(rooms[0]), str(rooms[1])}


def test_observable_coverage_counts_observable_points_only(rooms):
    env = make(rooms[:1], coverage="observable", max_steps=5)
    env.reset(seed=0)
    rewards = [env.step(a)[1] for a in (3, 3, 3, 3, 3)]
    observable = env.sim.observable_points_mask
    seen = env.sim.observed_points_mask
    assert env.coverage == pytest.approx((seen & observable).sum() / observable.sum())
    assert sum(rewards) >= 0


@pytest.mark.parametrize("action_space", ["discrete", "continuous"])
def test_move_into_a_wall_keeps_the_pose_and_sets_collided(rooms, action_space):
    env = make(rooms[1:], action_space=action_space, collision_penalty=0.5)
    obs, _ = env.reset(seed=0)
    pose = obs["pose"].copy()
    forward = 0 if action_space == "discrete" else np.array([1, 0, 0, 0, 0], np.float32)
    obs, reward, _, _, info = env.step(forward)  # the back wall is 1.5 m ahead, the move is 3 m
    assert info["collided"] and np.array_equal(obs["pose"], pose)
    assert reward == -0.5  # same view, nothing new seen
    if action_space == "discrete":
        for _ in range(8):  # turn around: 8 x 22.5 deg
            obs, reward, _, _, info = env.step(4)
            assert not info["collided"]
        obs, reward, _, _, info = env.step(0)
    else:
        obs, reward, _, _, info = env.step(np.array([-0.3, 0, 0, 0, 0], np.float32))
    assert not info["collided"] and np.linalg.norm(obs["pose"][:3, 3] - pose[:3, 3]) == pytest.approx(
        3.0 if action_space == "discrete" else 0.9)


def test_procedural_site_is_built_once_cached_and_rebuilt_after_a_code_change(tmp_path):
    kw = dict(seeds=[4], scene_preset="small", cache_dir=tmp_path, resolution=(16, 16), points_density=0.3,
              max_steps=3)
    env = gym.make(EXPLORATION_ID, **kw)
    obs, info = env.reset(seed=1)
    folder = tmp_path / "small_seed4"
    meta = json.loads((folder / "scene.json").read_text())
    assert np.allclose(obs["pose"], np.array(meta["start"]))
    assert info["scene"] == "small_seed4" and meta["code_key"] == site_code_key()
    stamp = (folder / "site.blend").stat().st_mtime_ns
    env.close()
    env = gym.make(EXPLORATION_ID, **kw)
    obs2, _ = env.reset(seed=1)
    assert (folder / "site.blend").stat().st_mtime_ns == stamp and np.array_equal(obs2["depth"], obs["depth"])
    env.close()
    # a site built by other code (another key, or the format before keys) is rebuilt in place
    for stale in (meta | {"code_key": "0" * 64}, {k: v for k, v in meta.items() if k != "code_key"} | {"format": 1}):
        (folder / "scene.json").write_text(json.dumps(stale))
        env = gym.make(EXPLORATION_ID, **kw)
        obs3, _ = env.reset(seed=1)
        env.close()
        assert (folder / "site.blend").stat().st_mtime_ns != stamp
        assert json.loads((folder / "scene.json").read_text()) == meta  # the same site again (deterministic)
        assert np.array_equal(obs3["depth"], obs["depth"])
        stamp = (folder / "site.blend").stat().st_mtime_ns
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.endswith(".lock")) == ["small_seed4"]
    # a damaged cached .blend is rebuilt, with a one-line warning naming it
    blend = folder / "site.blend"
    blend.write_bytes(blend.read_bytes()[: blend.stat().st_size // 2])
    env = gym.make(EXPLORATION_ID, **kw)
    with pytest.warns(UserWarning, match=rf"^{re.escape(str(folder))}: the cached site is damaged \(site.blend has "
                                         r"\d+ bytes"):
        obs4, _ = env.reset(seed=1)
    env.close()
    assert np.array_equal(obs4["depth"], obs["depth"])


def test_make_vec_default_runs_one_process_per_env(rooms):
    kw = {"blend_files": [str(rooms[0])], "resolution": (24, 16), "points_density": 20.0, "max_steps": 3}
    envs = gym.make_vec(EXPLORATION_ID, num_envs=2, **kw)  # no vectorization_mode: the id's vector entry point
    try:
        assert isinstance(envs, gym.vector.AsyncVectorEnv)
        obs, infos = envs.reset(seed=[3, 3])
        assert obs["depth"].shape == (2, 16, 24) and np.array_equal(obs["depth"][0], obs["depth"][1])
        obs, rewards, term, trunc, infos = envs.step(np.array([3, 4]))
        assert not np.array_equal(obs["pose"][0], obs["pose"][1]) and np.all(infos["steps"] == 1)
        assert np.all(rewards > 0)
    finally:
        envs.close()
    with pytest.raises(ValueError, match="^rgb must be True or False"):
        gym.make_vec(EXPLORATION_ID, num_envs=2, **kw, rgb="False")  # checked here, before any worker starts


def test_make_vec_checks_keywords_without_building_an_environment(monkeypatch, tmp_path):
    """make_vec's bad keywords fail in the calling process, in one line, before any environment
    (or worker) is made: the checks run on the keywords alone."""
    built = []
    original = ExplorationEnv.__init__

    @functools.wraps(original)
    def counted(self, *args, **kwargs):
        built.append(kwargs)
        original(self, *args, **kwargs)

    monkeypatch.setattr(ExplorationEnv, "__init__", counted)
    for kw, words in ((dict(seeds=[0], colour="red"), r"^ExplorationEnv has no keyword 'colour'; its keywords are "),
                      (dict(seeds=[0], rgb="False"), "^rgb must be True or False, got 'False'"),
                      (dict(seeds=[0], step=0, max_episode_steps=5),
                       "^step must be a finite number of metres > 0, got 0"),
                      (dict(seeds=[0], num_envs=0), "^num_envs must be an integer >= 1, got 0"),
                      (dict(blend_files=[tmp_path / "missing.blend"]), "missing.blend")):
        with pytest.raises((ValueError, FileNotFoundError), match=words) as err:
            gym.make_vec(EXPLORATION_ID, **({"num_envs": 2} | kw))
        assert "\n" not in str(err.value)
    assert built == []
    ExplorationEnv(seeds=[0], cache_dir=tmp_path)  # the spy sees a constructor call
    assert len(built) == 1


def test_async_vector_env_steps_and_resets(rooms):
    kw = {"blend_files": [str(rooms[0])], "resolution": (24, 16), "points_density": 20.0, "max_steps": 3}
    envs = gym.vector.AsyncVectorEnv([lambda: gym.make("generator.envs:" + EXPLORATION_ID, **kw)] * 2,
                                     context="spawn")
    try:
        obs, infos = envs.reset(seed=[3, 3])
        assert obs["depth"].shape == (2, 16, 24) and np.array_equal(obs["depth"][0], obs["depth"][1])
        for a in ([0, 0], [3, 4], [1, 2]):
            obs, rewards, term, trunc, infos = envs.step(np.array(a))
        assert np.all(trunc) and not np.any(term)
        assert not np.array_equal(obs["pose"][0], obs["pose"][1])
        obs, rewards, term, trunc, infos = envs.step(np.array([0, 0]))  # autoreset: a fresh episode
        assert np.all(infos["steps"] == 0)
    finally:
        envs.close()


@pytest.mark.parametrize("angle", [0, -10.0, 180.5, math.nan, "22.5"])
def test_modified_random_walk_checks_its_angle(angle):
    from generator.envs.policies import ModifiedRandomWalk

    with pytest.raises(ValueError, match=rf"^angle must be a number of degrees in \(0, 180\], got {re.escape(repr(angle))}$"):
        ModifiedRandomWalk(angle=angle)


def test_modified_random_walk_turns_only_after_a_blocked_forward_move(rooms):
    from generator.envs.policies import FORWARD, TURN_LEFT, TURN_RIGHT, ModifiedRandomWalk

    env = make(rooms[1:], max_steps=20)
    obs, info = env.reset(seed=0)
    policy, actions, collided = ModifiedRandomWalk(angle=22.5, seed=3), [], []
    for _ in range(20):
        actions.append(policy(obs, info))
        obs, _, _, _, info = env.step(actions[-1])
        collided.append(info["collided"])
    assert actions[0] == FORWARD and collided[0]  # the wall is 1.5 m ahead
    for k in range(1, 20):
        if actions[k] != FORWARD:
            assert actions[k] in (TURN_LEFT, TURN_RIGHT) and (collided[k - 1] or actions[k - 1] == actions[k])
    assert actions[1] != FORWARD and FORWARD in actions[2:]


def test_modified_random_walk_draws_every_turn_count_alike():
    """After a refused forward move the walk turns k times, k = round(uniform(-180, 180) / 22.5)
    redrawn while 0: each k in +-1..+-7 equally likely, +-8 half as likely (rounding), never 0."""
    from generator.envs.policies import FORWARD, TURN_RIGHT, ModifiedRandomWalk

    policy, counts = ModifiedRandomWalk(angle=22.5, seed=1), {}
    for _ in range(40000):
        policy.last, policy.turns_left = FORWARD, 0
        first = policy(None, {"collided": True})
        k = policy.turns_left + 1 if first == TURN_RIGHT else policy.turns_left - 1
        counts[k] = counts.get(k, 0) + 1
    assert 0 not in counts and set(counts) == set(range(-8, 0)) | set(range(1, 9))
    share = {k: v / 40000 * 15 for k, v in counts.items()}  # 15 units: 14 whole counts + 2 halves
    assert all(abs(share[k] - 1) < 0.08 for k in counts if abs(k) < 8)
    assert all(abs(share[k] - 0.5) < 0.06 for k in (-8, 8))


def test_env_and_raycam_modules_do_not_import_blender():
    import os
    import subprocess
    import sys

    code = ("import sys, gymnasium, generator.envs, generator.envs.exploration, generator.envs.policies, "
            "generator.envs.actions, generator.envs.scenes, generator.envs.vector, generator.geometry.raycam\n"
            "assert 'bpy' not in sys.modules, 'bpy was imported'\n"
            "import bpy\n"
            "print('ok')")
    env = {k: v for k, v in os.environ.items() if k != "OCIO"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         cwd=str(__import__("pathlib").Path(__file__).resolve().parents[1]))
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-2000:]


def test_bad_arguments_name_the_argument(tmp_path):
    file = tmp_path / "a_file"
    file.write_text("")
    for kw, words in ((dict(seeds=[0], scene_preset="huge"), "scene_preset"), (dict(), "no scenes"),
                      (dict(seeds=[0], resolution=(0, 3)), "resolution"), (dict(seeds=[0], action_space="x"), "action_space"),
                      (dict(seeds=5), "lists"), (dict(seeds=[0, -1]), r"seeds\[1\] must be an integer from 0 to 9223372036854775807"),
                      (dict(seeds=[0], step=-1), "step"), (dict(seeds=[0], max_steps=0), "max_steps"),
                      (dict(blend_files=[tmp_path / "missing.blend"]), "missing.blend"),
                      (dict(seeds=[0], rgb="False"), "^rgb must be True or False"), (dict(seeds=[0], rgb=1), "^rgb"),
                      (dict(seeds=[0], render_preset="fast"), "^render_preset must be one of 'preview'"),
                      (dict(seeds=[0], collision_penalty=-1), "^collision_penalty"),
                      (dict(seeds=[0], collision_penalty=math.inf), "^collision_penalty"),
                      (dict(seeds=[0], cache_dir=5), "^cache_dir"), (dict(seeds=[0], cache_dir=file), "^cache_dir"),
                      (dict(seeds="01"), "lists"), (dict(blend_files=[3]), r"^blend_files\[0\]"),
                      (dict(seeds=[0], coverage="seen"), "^coverage"), (dict(seeds=[0], start="x"), "^start"),
                      (dict(seeds=[0], angle=200), "^angle"), (dict(seeds=[0], max_depth=0), "^max_depth"),
                      (dict(seeds=[0], points_density=math.inf), "^points_density"),
                      (dict(seeds=[0], render_mode="human"), "^render_mode"),
                      (dict(seeds=[0], max_depth=math.nan), r"^max_depth must be a number of metres > 0 \(math.inf"),
                      (dict(seeds=[0], resolution=(64, 5000)),
                       "^resolution height must be an integer from 4 to 4,096 pixels \\(Blender renders smaller sides as 4\\), got 5000"),
                      (dict(seeds=[0], max_steps=2.0), "^max_steps must be an integer >= 1, got 2.0"),
                      (dict(seeds=[0], points_density="5"), "^points_density must be a finite number > 0, got '5'"),
                      (dict(seeds=[0], lidar=16), "^lidar must be None or a LiDAR's name"),
                      (dict(seeds=[0], lidar="vlp17"), "^unknown LiDAR 'vlp17'")):
        with pytest.raises((ValueError, FileNotFoundError), match=words) as err:
            ExplorationEnv(**kw)
        assert "\n" not in str(err.value)
        with pytest.raises(type(err.value)) as direct:
            check_keywords(**kw)  # the constructor's checks are these, declared once
        assert str(direct.value) == str(err.value)
    with pytest.raises(ValueError, match=r"^ExplorationEnv has no keyword 'colour'; its keywords are seeds, "
                                         r"blend_files, .*, render_mode, lidar$"):
        check_keywords(seeds=[0], colour="red")
    assert check_keywords(seeds=[0])["max_depth"] == 20.0  # the constructor's defaults
    assert ExplorationEnv(seeds=[0], max_depth=math.inf, cache_dir=tmp_path).max_depth == math.inf
    assert ExplorationEnv(seeds=[0], rgb=np.bool_(True), render_preset="default").rgb is True


def test_a_lidar_is_observed_per_beam_and_agrees_with_the_depth_image(rooms):
    """lidar='vlp16': each beam's range (0: none) and class; the beam fired straight ahead
    (half a turn after the start behind, ring 8 at +1 degree) meets the far wall."""
    env = make(rooms[:1], lidar="vlp16")
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    ranges, labels = obs["lidar_range"], obs["lidar_label"]
    assert ranges.shape == labels.shape == (16 * 1800,)
    assert ((ranges > 0) == (labels >= 0)).all() and (ranges > 0).mean() > 0.5  # walls all round, the floor below
    assert set(np.unique(labels[labels >= 0])) <= set(range(len(env.sim.labels)))
    # in the room of 12 m, every return lies within the room's diagonal of the camera
    assert ranges.max() < np.hypot(np.hypot(12.4, 12.4), 3.0)
    ahead = 900 * 16 + 8  # column 900 of 1800, ring 8: azimuth 0 (the heading, +y), elevation +1 degree
    far_wall = (6.0 - (-3.0)) / np.cos(np.radians(1.0))  # its inner face at y = 6, the camera at y = -3
    assert abs(ranges[ahead] - far_wall) < 0.1 and env.sim.labels[labels[ahead]] == "Wall"
    with pytest.raises(ValueError, match="unknown LiDAR 'radar'"):
        make(rooms[:1], lidar="radar")
    env.close()
